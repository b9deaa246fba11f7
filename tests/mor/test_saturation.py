import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from hound_id.errors import SaturationError
from hound_id.mor.region import operating_region
from hound_id.mor.robot import load_robot, robot_from_mapping
from hound_id.mor.saturation import dc_motor_clip, saturation_for
from hound_id.mor.spec import MotorSpec
from tests.conftest import ROBOT, SMALL_MOTOR

ROBOT_SAT = saturation_for(load_robot(ROBOT))
N = ROBOT_SAT.n
MOTOR_OVERSPEED = float(np.min(ROBOT_SAT.stall_torque + ROBOT_SAT.torque_limit) / np.max(ROBOT_SAT.back_emf_damping))
DEVICES = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])

unit = st.floats(-1.0, 1.0, allow_nan=False)


def commands(scale_tau=250.0, scale_qd=120.0, batch=8):
    return st.tuples(
        arrays(float, (batch, N), elements=unit).map(lambda u: u * scale_tau),
        arrays(float, (batch, N), elements=unit).map(lambda u: u * scale_qd),
    )


def within_overspeed(qd):
    _, omega = ROBOT_SAT.motor_state(np.zeros_like(qd), qd)
    return np.abs(omega) <= MOTOR_OVERSPEED


@settings(max_examples=150, deadline=None)
@given(commands())
def test_output_is_feasible(cmd):
    tau, qd = cmd
    out = ROBOT_SAT(tau, qd)
    violation = ROBOT_SAT.violation(out, qd)
    assert np.all(violation <= 1e-9 * 250)
    tau_m, omega = ROBOT_SAT.motor_state(out, qd)
    # feasibility against the region itself, motor by motor, inside overspeed
    mask = within_overspeed(qd)
    assert np.all(np.abs(tau_m) <= ROBOT_SAT.torque_limit * (1 + 1e-12))
    # the voltage band (R/Kt) tau + omega/Kv in [-V, V], divided by V/stall-torque units
    line = (tau_m + omega * ROBOT_SAT.back_emf_damping) / ROBOT_SAT.stall_torque
    assert np.all(np.abs(line[mask]) <= 1 + 1e-9)


@settings(max_examples=150, deadline=None)
@given(commands())
def test_idempotent(cmd):
    tau, qd = cmd
    once = ROBOT_SAT(tau, qd)
    assert np.allclose(ROBOT_SAT(once, qd), once, rtol=1e-12, atol=1e-9)


@settings(max_examples=150, deadline=None)
@given(commands(scale_tau=1.0, scale_qd=1.0))
def test_commands_inside_the_region_pass_unchanged(cmd):
    u_tau, u_qd = cmd
    # scale into the inner boxes: everything there is feasible
    regions = _regions()
    T = np.array([j.inner_box.effort for j in regions.joints]) * 0.999
    W = np.array([j.inner_box.velocity for j in regions.joints]) * 0.999
    tau, qd = u_tau * T, u_qd * W
    assert np.array_equal(ROBOT_SAT.violation(tau, qd), np.zeros_like(tau))
    assert np.allclose(ROBOT_SAT(tau, qd), tau, rtol=1e-12, atol=1e-12)


_cache = {}


def _regions():
    if "r" not in _cache:
        from hound_id.mor.joint_space import robot_regions

        _cache["r"] = robot_regions(load_robot(ROBOT))
    return _cache["r"]


@st.composite
def uncoupled_robot(draw):
    k = draw(st.integers(1, 4))
    specs, transmissions, ratios = {}, [], []
    for i in range(k):
        kt = draw(st.floats(0.02, 1.0))
        specs[f"m{i}"] = MotorSpec(
            name=f"m{i}",
            kt=kt,
            kv=draw(st.floats(0.85, 1.1)) / kt,
            resistance=draw(st.floats(0.02, 3.0)),
            bus_voltage=draw(st.floats(12.0, 100.0)),
            peak_torque=draw(st.floats(0.2, 20.0)),
            max_current=draw(st.one_of(st.none(), st.floats(2.0, 100.0))),
        )
        g = draw(st.floats(1.0, 30.0)) * draw(st.sampled_from([1.0, -1.0]))
        ratios.append(g)
        transmissions.append(
            {"type": "ratio", "joints": [f"j{i}"], "motors": [f"m{i}"], "motor_spec": f"m{i}", "ratios": [g]}
        )
    return specs, transmissions, np.array(ratios)


@settings(max_examples=100, deadline=None)
@given(uncoupled_robot(), st.data())
def test_uncoupled_joints_equal_the_per_joint_dc_motor_clip(robot_def, data):
    specs, transmissions, ratios = robot_def
    import hound_id.mor.robot as robot_mod

    k = len(ratios)
    robot = robot_mod.Robot(
        name="u",
        joints=tuple(f"j{i}" for i in range(k)),
        transmissions=tuple(robot_mod.from_ratios(t["joints"], t["motors"], t["ratios"]) for t in transmissions),
        motor_specs={f"m{i}": specs[f"m{i}"] for i in range(k)},
    )
    sat = saturation_for(robot)
    regions = [operating_region(specs[f"m{i}"]) for i in range(k)]
    g = np.abs(ratios)
    saturation_effort = np.array([r.stall_torque for r in regions]) * g
    velocity_limit = np.array([r.no_load_speed for r in regions]) / g
    effort_limit = np.array([r.torque_limit for r in regions]) * g
    # speeds up to twice the overspeed, so past-overspeed behaviour is compared too
    u = data.draw(arrays(float, (2, 16, k), elements=unit))
    tau = u[0] * effort_limit * 2.0
    qd = u[1] * np.array([r.overspeed for r in regions]) / g * 2.0
    ours = sat(tau, qd)
    # a reversing gear (negative ratio) flips torque and speed together
    theirs = np.where(
        ratios < 0,
        -dc_motor_clip(-tau, -qd, saturation_effort, velocity_limit, effort_limit),
        dc_motor_clip(tau, qd, saturation_effort, velocity_limit, effort_limit),
    )
    assert np.allclose(ours, theirs, rtol=1e-9, atol=1e-9 * effort_limit.max())


def test_past_overspeed_full_braking_and_past_max_speed_braking_only(write_yaml):
    robot = robot_from_mapping(
        {
            "name": "s",
            "motor_specs": {"s": str(SMALL_MOTOR)},
            "joints": ["j"],
            "transmissions": [{"type": "ratio", "joints": ["j"], "motors": ["m"], "motor_spec": "s", "ratios": [1.0]}],
        },
        source="inline",
        base=SMALL_MOTOR.parent,
    )
    sat = saturation_for(robot)
    region = operating_region(robot.motor_specs["m"])
    far = np.array([[region.overspeed * 1.5]])
    assert sat(np.array([[5.0]]), far)[0, 0] == pytest.approx(-region.torque_limit)
    assert sat(np.array([[-5.0]]), -far)[0, 0] == pytest.approx(region.torque_limit)
    # between max_speed and no-load speed the voltage line would allow motoring; the speed limit does not
    w = np.array([[region.max_speed * 1.05]])
    assert region.max_speed * 1.05 < region.no_load_speed
    assert sat(np.array([[1.0]]), w)[0, 0] == 0.0
    assert sat(np.array([[-1.0]]), w)[0, 0] == -1.0


@pytest.mark.parametrize("device", DEVICES)
def test_torch_matches_numpy_and_stays_in_torch(device):
    rng = np.random.default_rng(1)
    tau = rng.uniform(-250, 250, size=(64, N))
    qd = rng.uniform(-120, 120, size=(64, N))
    expected = ROBOT_SAT(tau, qd)
    t_tau = torch.tensor(tau, device=device, requires_grad=True)
    t_qd = torch.tensor(qd, device=device)
    out = ROBOT_SAT(t_tau, t_qd)
    assert isinstance(out, torch.Tensor) and out.device.type == device and out.dtype == torch.float64
    assert np.allclose(out.detach().cpu().numpy(), expected, rtol=1e-12, atol=1e-9)
    # autograd flows through: proof that no numpy round trip happened
    out.sum().backward()
    assert t_tau.grad is not None and torch.isfinite(t_tau.grad).all()
    out32 = ROBOT_SAT(t_tau.detach().float(), t_qd.float())
    assert out32.dtype == torch.float32
    assert np.allclose(out32.cpu().numpy(), expected, rtol=1e-4, atol=1e-3)


def test_batch_shapes_and_errors():
    tau = np.zeros((3, 5, N))
    assert ROBOT_SAT(tau, tau).shape == (3, 5, N)
    assert ROBOT_SAT(np.zeros(N, dtype=int), np.zeros(N)).dtype == np.float64
    with pytest.raises(SaturationError, match=r"expected both \(\.\.\., 12\), the same shape"):
        ROBOT_SAT(np.zeros((4, 11)), np.zeros((4, 11)))
    with pytest.raises(SaturationError, match=r"tau has shape \(10, 12\) and qd \(5, 12\)"):
        ROBOT_SAT(np.zeros((10, N)), np.zeros((5, N)))
    with pytest.raises(SaturationError, match="both be numpy arrays or both torch"):
        ROBOT_SAT(torch.zeros(N), np.zeros(N))


def test_results_are_not_aliased_and_threads_do_not_share_scratch():
    import threading

    rng = np.random.default_rng(3)
    inputs = [(rng.uniform(-250, 250, (256, N)), rng.uniform(-120, 120, (256, N))) for _ in range(8)]
    expected = [ROBOT_SAT(t, q).copy() for t, q in inputs]
    first = ROBOT_SAT(*inputs[0])
    ROBOT_SAT(*inputs[1])
    assert np.array_equal(first, expected[0])  # a later call does not overwrite an earlier result
    results: dict[int, list[np.ndarray]] = {}

    def work(k: int) -> None:
        results[k] = [ROBOT_SAT(t, q) for _ in range(50) for t, q in [inputs[k]]]

    threads = [threading.Thread(target=work, args=(k,)) for k in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for k in range(8):
        assert all(np.array_equal(r, expected[k]) for r in results[k])


def test_float32_numpy_path():
    rng = np.random.default_rng(4)
    tau = rng.uniform(-250, 250, (128, N))
    qd = rng.uniform(-120, 120, (128, N))
    out32 = ROBOT_SAT(tau.astype(np.float32), qd.astype(np.float32))
    assert out32.dtype == np.float32
    assert np.allclose(out32, ROBOT_SAT(tau, qd), rtol=1e-4, atol=1e-3)


def test_torque_bounds_are_the_motor_intervals():
    from hound_id.mor.region import torque_interval

    rng = np.random.default_rng(5)
    qd = rng.uniform(-80, 80, (32, N))
    lo, hi = ROBOT_SAT.torque_bounds(qd)
    _, omega = ROBOT_SAT.motor_state(np.zeros_like(qd), qd)
    robot = load_robot(ROBOT)
    for m, motor in enumerate(robot.motors):
        want_lo, want_hi = torque_interval(omega[:, m], operating_region(robot.motor_specs[motor]))
        assert np.allclose(lo[:, m], want_lo) and np.allclose(hi[:, m], want_hi)
