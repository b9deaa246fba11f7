"""The fused clip (numba) gives the numpy steps' result bit for bit, on the inputs the property tests draw."""

import os

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from hound_id.mor import fused
from hound_id.mor.saturation import saturation_for
from tests.mor.test_saturation import (
    MOTOR_OVERSPEED,
    ROBOT_SAT,
    N,
    commands,
    small_motor_robot,
    uncoupled_robot,
    uncoupled_saturation,
)

DTYPES = [np.float32, np.float64]


def both(sat, tau, qd):
    """(numpy steps, fused loop) on the same inputs, and whether the fused loop ran."""
    import hound_id.mor.saturation as saturation

    calls = []
    original = saturation.clip_correction

    def counted(*args):
        calls.append(1)
        return original(*args)

    before = os.environ.get(fused.ENV)
    try:
        os.environ[fused.ENV] = "0"
        plain = sat(tau, qd)
        os.environ[fused.ENV] = "1"
        saturation.clip_correction = counted
        fast = sat(tau, qd)
    finally:
        saturation.clip_correction = original
        if before is None:
            os.environ.pop(fused.ENV, None)
        else:
            os.environ[fused.ENV] = before
    return plain, fast, bool(calls)


def bits(x):
    x = x.numpy() if isinstance(x, torch.Tensor) else np.asarray(x)
    return x.view(np.int32 if x.dtype == np.float32 else np.int64)


def test_numba_is_installed_with_the_test_extra():
    # the comparisons below are void without it: the test extra must bring it
    assert fused.available()


@pytest.mark.parametrize("dtype", DTYPES)
@settings(max_examples=150, deadline=None)
@given(cmd=commands(scale_tau=1.0, scale_qd=1.0, batch=16))
def test_coupled_robot_bit_for_bit(dtype, cmd):
    # drawn in motor space, so that every edge is hit: the torque limit, the curved voltage lines, past overspeed
    u_tau, u_w = cmd
    qd = (u_w * 1.3 * MOTOR_OVERSPEED) @ ROBOT_SAT.A.T
    tau = (u_tau * 1.5 * ROBOT_SAT.torque_limit.max()) @ ROBOT_SAT.A_inv
    tau, qd = tau.astype(dtype), qd.astype(dtype)
    plain, fast, ran = both(ROBOT_SAT, tau, qd)
    assert ran
    assert np.array_equal(bits(plain), bits(fast))


@pytest.mark.parametrize("curve", ["linear", "quadratic"])
@settings(max_examples=60, deadline=None)
@given(robot_def=st.data())
def test_uncoupled_robots_of_any_motor_bit_for_bit(curve, robot_def):
    sat, _ = uncoupled_saturation(robot_def.draw(uncoupled_robot(curve=curve)))
    unit = st.floats(-1.0, 1.0, allow_nan=False)
    u = robot_def.draw(arrays(float, (2, 8, sat.n), elements=unit))
    for dtype in DTYPES:
        tau = (u[0] * 3 * sat.stall_torque.max()).astype(dtype)
        qd = (u[1] * 2 * (sat.stall_torque / sat.back_emf_damping).max()).astype(dtype)
        plain, fast, ran = both(sat, tau, qd)
        assert ran
        assert np.array_equal(bits(plain), bits(fast))


def test_rated_speed_signed_zeros_and_torch_views_bit_for_bit():
    robot = small_motor_robot()
    sat = saturation_for(robot)
    assert sat._constants(np.zeros((1, 1))).has_max_speed
    w = float(sat.max_speed[0])
    speeds = np.array([-2 * w, -1.001 * w, -w, -0.0, 0.0, 0.5 * w, w, 1.001 * w, 2 * w])
    torques = np.array([-3.0, -1.0, -0.0, 0.0, 1e-30, 1.0, 3.0])
    tau, qd = (a.reshape(-1, 1) for a in np.meshgrid(torques, speeds))
    for dtype in DTYPES:
        plain, fast, ran = both(sat, tau.astype(dtype), qd.astype(dtype))
        assert ran and np.array_equal(bits(plain), bits(fast))
    rng = np.random.default_rng(3)
    tau = torch.tensor(rng.normal(0, 20, (64, N)), dtype=torch.float32)
    qd = torch.tensor(rng.normal(0, 30, (64, N)), dtype=torch.float32)
    tau[0, 0] = -0.0
    plain, fast, ran = both(ROBOT_SAT, tau, qd)
    assert ran and isinstance(fast, torch.Tensor)
    assert np.array_equal(bits(plain), bits(fast))


def test_what_the_loop_does_not_take_goes_the_numpy_way():
    rng = np.random.default_rng(4)
    tau, qd = rng.normal(0, 20, (32, N)), rng.normal(0, 30, (32, N))
    # a NaN, a command past the ordinary range, a strided view, mixed dtypes: no fused call, same result
    nan = tau.copy()
    nan[3, 2] = np.nan
    for t, q in ((nan, qd), (tau * 1e6, qd), (tau[::2], qd[::2]), (tau.astype(np.float32), qd)):
        plain, fast, ran = both(ROBOT_SAT, t, q)
        assert not ran or t.dtype != q.dtype
        np.testing.assert_array_equal(plain, fast)
