"""The torque channel's own dynamics (hound_id.dyno.current.transducer): the discrete filters against the continuous
transfer functions they stand for."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hound_id.dyno.current.transducer import apply, overshoot
from hound_id.errors import FitError

RATE = 1000.0


def gain_and_phase(name: str, hypers: dict[str, float], f: float) -> tuple[float, float]:
    """Steady-state gain and phase [rad] of the discrete filter for a sine at f [Hz] (the last whole periods)."""
    t = np.arange(0.0, 4.0, 1.0 / RATE)
    y = apply(name, hypers, t, np.sin(2 * np.pi * f * t))
    keep = t >= 2.0
    basis = np.column_stack([np.sin(2 * np.pi * f * t[keep]), np.cos(2 * np.pi * f * t[keep])])
    (a, b), *_ = np.linalg.lstsq(basis, y[keep], rcond=None)
    return math.hypot(a, b), math.atan2(b, a)


@pytest.mark.parametrize("f", [2.0, 20.0, 60.0, 150.0])
def test_the_filters_follow_their_transfer_functions(f):
    # the samples joined by straight lines pass a sine with the gain sinc^2(f / rate) and no phase (a triangular hold)
    # (near the Nyquist rate the sine's images add a little: a looser tolerance there)
    w, hold = 2 * np.pi * f, float(np.sinc(f / RATE)) ** 2
    tol = 1e-4 if f < 0.1 * RATE else 5e-3
    tau = 0.004
    lag = 1.0 / (1.0 + 1j * w * tau)
    gain, phase = gain_and_phase("lag", {"lag_tau": tau}, f)
    assert gain == pytest.approx(hold * abs(lag), rel=tol) and phase == pytest.approx(np.angle(lag), abs=tol)
    f0, zeta = 40.0, 0.2
    w0 = 2 * np.pi * f0
    mode = w0**2 / (w0**2 - w**2 + 2j * zeta * w0 * w)
    gain, phase = gain_and_phase("resonance", {"resonance_f0": f0, "resonance_zeta": zeta}, f)
    assert gain == pytest.approx(hold * abs(mode), rel=tol) and phase == pytest.approx(np.angle(mode), abs=tol)


@settings(max_examples=25, deadline=None)
@given(
    f0=st.floats(5.0, 200.0),
    zeta=st.floats(0.05, 1.5),
    level=st.floats(-50.0, 50.0),
)
def test_unit_gain_at_rest_and_the_step_overshoot(f0, zeta, level):
    t = np.arange(0.0, 3.0, 1.0 / RATE)
    u = np.full_like(t, level)
    # at rest at the first value: a constant passes unchanged
    assert np.allclose(apply("resonance", {"resonance_f0": f0, "resonance_zeta": zeta}, t, u), level, atol=1e-9)
    step = np.where(t >= 0.5, 1.0, 0.0)
    y = apply("resonance", {"resonance_f0": f0, "resonance_zeta": zeta}, t, step)
    ringing = math.exp(-zeta * 2 * math.pi * f0 * 2.5)  # what is left of the ringing 2.5 s after the step
    assert y[-1] == pytest.approx(1.0, abs=ringing + 1e-3)
    # the peak of the sampled response: the continuous overshoot, less what the samples miss of the peak
    assert max(float(y.max()) - 1.0, 0.0) <= overshoot(zeta) + 1e-3
    if zeta < 0.5 and f0 < 50.0:  # a peak wide against the samples
        assert float(y.max()) - 1.0 == pytest.approx(overshoot(zeta), abs=0.02)


def test_a_jittered_log_is_filtered_as_a_uniform_one_would_be():
    rng = np.random.default_rng(3)
    t = np.cumsum(np.full(4000, 1.0 / RATE) * (1 + 0.15 * rng.uniform(-1, 1, 4000)))
    x = np.sin(2 * np.pi * 3.0 * t) + 0.5 * np.sign(np.sin(2 * np.pi * 0.7 * t))
    hypers = {"resonance_f0": 30.0, "resonance_zeta": 0.3}
    fine = np.arange(t[0], t[-1], 1e-4)
    reference = np.interp(t, fine, apply("resonance", hypers, fine, np.interp(fine, t, x)))
    y = apply("resonance", hypers, t, x)
    # resampling costs the interpolation of a 1 kHz log: far below the steps' own size
    assert np.sqrt(np.mean((y - reference) ** 2)) < 0.01


def test_impossible_filter_values_are_refused():
    t = np.arange(0.0, 1.0, 1e-3)
    with pytest.raises(FitError, match="time constant must be positive"):
        apply("lag", {"lag_tau": 0.0}, t, t)
    with pytest.raises(FitError, match="f0 > 0 and zeta > 0"):
        apply("resonance", {"resonance_f0": 20.0, "resonance_zeta": -0.1}, t, t)
    with pytest.raises(FitError, match="not a filter"):
        apply("delay", {}, t, t)
