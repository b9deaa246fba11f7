"""The residual's time scale (hound_id.dyno.current.wander) on seeded series whose slow and fast parts are known."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter

from hound_id.dyno.current.wander import MIN_SAMPLES, MIN_WINDOWS, WINDOW, wander

RATE = 200.0


def gauss_markov(rng: np.random.Generator, n: int, rms: float, seconds: float) -> np.ndarray:
    a = math.exp(-1.0 / (RATE * seconds))
    x = lfilter([math.sqrt(1 - a * a)], [1.0, -a], rng.normal(0.0, 1.0, n))
    return rms * x / np.std(x)  # exactly the asked RMS


@pytest.mark.parametrize("seed", range(5))
def test_a_slow_wander_is_measured_and_named(seed):
    """White noise of 0.05 N m and a 2-s Gauss-Markov wander of 0.2 N m: the slow part is the wander's RMS within 10 %,
    the fast part is the noise's and the wander's own roughness within the window (sqrt(0.05^2 + 0.2^2 W/3 tau) =
    0.065 N m), and the excess over a floor at the noise is called slow."""
    rng = np.random.default_rng(seed)
    n = int(60 * RATE)
    t = np.arange(n) / RATE
    slow = gauss_markov(rng, n, 0.2, 2.0)
    r = slow + rng.normal(0.0, 0.05, n)
    w = wander(t, r, 0.05)
    assert w is not None and w.is_slow and w.floor_is_wander
    assert w.slow == pytest.approx(0.2, rel=0.1)
    assert 0.05 <= w.fast <= 0.07
    assert w.share > 0.9
    assert w.crossing is not None and 0.5 < w.crossing < 8.0
    assert w.sentence().startswith(f"{w.share:.0%} of the excess over the floor is slow")
    assert "the rotor's angle" in w.sentence()


@pytest.mark.parametrize("rho", [0.0, 0.8, 0.9, 0.95])
def test_correlated_fast_noise_is_not_called_a_wander(rho):
    """AR(1) noise with a correlation time up to 20 samples (0.1 s, a 1.6 Hz transducer) and a floor that reads it low
    (sample-to-sample differences of correlated noise): the excess is fast, and at its own level no wander is claimed.
    A 0.25 s window would keep half of the slowest noise: the window widens to eight of its correlation lengths."""
    rng = np.random.default_rng(7)
    n = int(60 * RATE)
    t = np.arange(n) / RATE
    x = lfilter([math.sqrt(1 - rho * rho)], [1.0, -rho], rng.normal(0.0, 0.1, n))
    low = 0.1 * math.sqrt(1 - rho) if rho > 0 else 0.05  # what second differences read
    w = wander(t, x, low)
    assert w is not None and not w.is_slow, w
    assert f"faster than {w.window:.2g} s" in w.sentence() and w.slow < 0.5 * w.fast
    assert w.window >= 0.25 and (rho < 0.9 or w.window > 0.3)  # widened past a quarter second
    at_floor = wander(t, x, float(np.std(x)))
    assert at_floor is not None and not at_floor.floor_is_wander and at_floor.share == 0.0


def test_flagged_rows_and_gaps_are_left_out_with_their_windows():
    """A broken stretch (keep False) and a gap in time never enter a window: the wander is the rest's."""
    rng = np.random.default_rng(3)
    n = int(40 * RATE)
    t = np.arange(n) / RATE
    t[n // 2 :] += 5.0  # five seconds missing
    r = rng.normal(0.0, 0.05, n)
    keep = np.ones(n, dtype=bool)
    keep[1000:1400] = False
    r[1000:1400] += 3.0  # what a motor switched off leaves in the residual
    w = wander(t, r, 0.05, keep)
    assert w is not None and w.slow < 0.02 and w.rows < n - 400 - 2 * int(WINDOW * RATE)


def test_a_short_log_has_no_time_scale():
    t = np.arange(MIN_WINDOWS * MIN_SAMPLES - 1) / 20.0  # a 20 Hz log shorter than twenty windows
    assert wander(t, np.ones(t.size), 0.1) is None
    assert wander(np.zeros(500), np.ones(500), 0.1) is None  # untimed: every row at one instant
    assert wander(np.arange(500.0), np.ones(500), 0.0) is None  # no floor to speak against
    # a burst of 40 rows a millisecond apart: the quarter-second window is longer than the log
    assert wander(np.arange(40) * 1e-3, np.random.default_rng(0).normal(size=40), 0.1) is None


@settings(max_examples=30, deadline=None)
@given(
    scale=st.floats(1e-3, 1e3),
    shift=st.floats(-100.0, 100.0),
    seed=st.integers(0, 2**16),
)
def test_the_split_scales_with_the_torque_and_ignores_when_the_log_starts(scale, shift, seed):
    """The time scale is the residual's, whatever its unit or the clock's origin: slow and fast scale with it, the
    share and the crossing do not move."""
    rng = np.random.default_rng(seed)
    n = 4000
    t = np.arange(n) / RATE
    r = gauss_markov(rng, n, 1.0, 1.0) + rng.normal(0.0, 0.3, n)
    a, b = wander(t, r, 0.3), wander(t + shift, scale * r, 0.3 * scale)
    assert a is not None and b is not None
    assert b.slow == pytest.approx(scale * a.slow, rel=1e-6)
    assert b.fast == pytest.approx(scale * a.fast, rel=1e-6)
    assert b.share == pytest.approx(a.share, abs=1e-9)
    assert b.crossing == pytest.approx(a.crossing, rel=1e-6)


def test_an_offset_the_model_lacks_is_called_an_offset():
    """A residual that sits 0.6 N m off zero (a transducer's zero the model does not carry) is not a wander."""
    rng = np.random.default_rng(11)
    n = int(20 * RATE)
    t = np.arange(n) / RATE
    w = wander(t, 0.6 + rng.normal(0.0, 0.1, n), 0.1)
    assert w is not None and w.is_slow and w.mean == pytest.approx(0.6, abs=0.01)
    assert "sits +0.601 N m off zero throughout" in w.sentence() and "wander" not in w.sentence()
    moving = wander(t, gauss_markov(rng, n, 0.5, 1.0) + rng.normal(0.0, 0.1, n), 0.1)
    assert moving is not None and "wanders by" in moving.sentence()


def _sweep(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(n) / RATE
    return t, 8 * np.sin(2 * np.pi * 0.23 * t), 3 * np.sin(2 * np.pi * 0.13 * t)


@pytest.mark.parametrize("seed", range(3))
def test_a_wander_that_follows_the_current_is_not_blamed_on_a_channel_the_log_lacks(seed):
    """A ripple of 0.2 N m in the current (period 4 A) on a sweep that comes back to every current: moments with the
    same current and speed far apart in time predict it, so the sentence says it follows the inputs. A wander in time
    of the same size on the same sweep is predicted by none of them; on a one-way ramp the log cannot tell."""
    rng = np.random.default_rng(seed)
    n = int(60 * RATE)
    t, i, w = _sweep(n)
    noise = rng.normal(0.0, 0.05, n)
    ripple = wander(t, 0.2 * np.sin(2 * np.pi * i / 4.0) + noise, 0.05, None, [i, w])
    assert ripple is not None and ripple.follows_inputs and ripple.follows > 0.9, ripple
    assert "follows the inputs" in ripple.sentence() or "shape of the curve" in ripple.sentence()
    assert "something the log lacks" not in ripple.sentence()
    drifting = wander(t, gauss_markov(rng, n, 0.2, 2.0) + noise, 0.05, None, [i, w])
    assert drifting is not None and drifting.follows is not None and drifting.follows < 0.2, drifting
    assert "no logged channel follows it" in drifting.sentence()
    ramp = wander(t, gauss_markov(rng, n, 0.2, 2.0) + noise, 0.05, None, [np.linspace(0.0, 18.0, n)])
    assert ramp is not None and ramp.follows is None
    assert "cannot tell a curve bumpier than the model's terms from something the log lacks" in ramp.sentence()


@pytest.mark.parametrize("seconds", [0.5, 1.0, 2.0])
def test_a_transducer_filter_is_not_a_long_memory(seconds):
    """Noise through a second-order 20 Hz filter at 200 Hz correlates neighbouring samples at 0.9 but only over a few
    lags: the window stays near a quarter second and a wander of 0.2 N m reads within 15 %."""
    from scipy.signal import butter

    rng = np.random.default_rng(5)
    n = int(60 * RATE)
    t = np.arange(n) / RATE
    b, a = butter(2, 20.0 / (RATE / 2))
    filtered = lfilter(b, a, rng.normal(0.0, 1.0, n))
    noise = 0.05 * filtered / np.std(filtered)
    w = wander(t, gauss_markov(rng, n, 0.2, seconds) + noise, 0.02)
    assert w is not None and w.window < 0.5, w
    assert w.slow == pytest.approx(0.2, rel=0.15) and w.is_slow
