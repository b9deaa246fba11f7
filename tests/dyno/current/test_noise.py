"""The noise floor: sample-to-sample for white noise, the scatter at still inputs for correlated noise."""

import math

import numpy as np
import pytest
from scipy.signal import butter, lfilter

from hound_id.dyno.current.diagnose import diagnose
from hound_id.dyno.current.effects import Signals
from hound_id.dyno.current.fit import fit_model
from hound_id.dyno.current.noise import (
    CHUNK_ROWS,
    MIN_STILL_ROWS,
    SETTLE_ROWS,
    estimate,
    still_segments,
    white_floor,
)

RATE = 200.0
KT = 0.9


def held_plan(seconds: float = 40.0, hold: float = 0.8, seed: int = 0) -> tuple[Signals, np.ndarray]:
    """Current levels held for ``hold`` seconds each, the speed held at levels too: (signals, true torque)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 1.0 / RATE)
    k = np.arange(t.size) // int(round(hold * RATE))
    levels = rng.permutation(np.linspace(-10, 10, k.max() + 1))  # one level per hold, each its own
    speeds = rng.choice([-2.0, -0.5, 0.5, 2.0], k.max() + 1)
    i = levels[k] + rng.normal(0, 0.01, t.size)
    w = speeds[k] + rng.normal(0, 0.02, t.size)
    return Signals(time=t, current=i, velocity=w), KT * levels[k]


def filtered_noise(n: int, sigma: float, cutoff_hz: float, seed: int = 1) -> np.ndarray:
    """Noise through a second-order low-pass transducer, scaled to standard deviation ``sigma``."""
    b, a = butter(2, cutoff_hz / (RATE / 2))
    x = lfilter(b, a, np.random.default_rng(seed).normal(size=n + 2000))[2000:]
    return sigma * x / x.std()


def test_still_stretches_are_found_on_a_held_plan_and_not_on_a_sweep():
    signals, _ = held_plan()
    pieces = still_segments(signals)
    rows = sum(b - a for a, b in pieces)
    held = int(0.8 * RATE)  # rows per hold
    assert rows > 0.8 * (held - SETTLE_ROWS) / held * signals.current.size
    assert all(b - a <= CHUNK_ROWS for a, b in pieces)
    # no piece crosses a change of level (levels change every `held` rows)
    assert all(a // held == (b - 1) // held for a, b in pieces)
    # every piece starts SETTLE_ROWS or more after its hold began
    assert all(a % held >= SETTLE_ROWS for a, b in pieces)

    t = signals.time
    sweep = Signals(time=t, current=10 * np.sin(2 * np.pi * 0.3 * t), velocity=2 * np.sin(2 * np.pi * 0.17 * t))
    assert still_segments(sweep) == []
    # a slow ramp, each step within the noise, is not still either
    ramp = Signals(time=t, current=np.linspace(-10, 10, t.size) + np.random.default_rng(3).normal(0, 0.01, t.size))
    assert sum(b - a for a, b in still_segments(ramp)) < MIN_STILL_ROWS


def test_a_rotating_rotor_is_never_still_when_the_log_has_its_angle():
    signals, _ = held_plan()
    angle = np.cumsum(signals.velocity) / RATE
    rotating = Signals(time=signals.time, current=signals.current, velocity=signals.velocity, position=angle)
    assert still_segments(rotating) == []  # cogging could be in the torque there: it is not noise


def test_a_steady_state_table_has_no_still_rows():
    signals, _ = held_plan()
    table = Signals(time=np.arange(signals.time.size, dtype=float), current=signals.current, timed=False)
    assert still_segments(table) == []


@pytest.mark.parametrize("cutoff_hz", [8.0, 20.0])
def test_the_still_floor_of_filtered_noise_is_its_standard_deviation(cutoff_hz):
    signals, clean = held_plan()
    sigma = 0.05
    noise = filtered_noise(clean.size, sigma, cutoff_hz)
    floor = estimate(signals, clean + noise, noise)
    assert floor.method == "still" and floor.still == pytest.approx(sigma, rel=0.15)
    assert floor.white < 0.5 * sigma  # second differences of filtered noise read low
    assert floor.correlation > 2 and "correlated" in floor.sentence()


def test_white_noise_gives_both_estimates_alike():
    signals, clean = held_plan()
    noise = np.random.default_rng(4).normal(0, 0.05, clean.size)
    floor = estimate(signals, clean + noise, noise)
    assert floor.white == pytest.approx(0.05, rel=0.1) and floor.still == pytest.approx(0.05, rel=0.1)
    assert floor.value == pytest.approx(0.05, rel=0.1)


def test_a_sweep_falls_back_to_sample_to_sample_and_says_what_to_record():
    t = np.arange(0.0, 30.0, 1.0 / RATE)
    sweep = Signals(time=t, current=10 * np.sin(2 * np.pi * 0.3 * t))
    noise = np.random.default_rng(5).normal(0, 0.05, t.size)
    floor = estimate(sweep, KT * sweep.current + noise, noise)
    assert floor.method == "sample-to-sample" and floor.still is None
    assert "hold the current and speed still" in floor.sentence()


def test_a_coarsely_rounded_torque_channel_sets_the_floor():
    signals, clean = held_plan()
    q = 0.5  # N m per count
    measured = np.round((clean + np.random.default_rng(6).normal(0, 0.01, clean.size)) / q) * q
    floor = estimate(signals, measured, measured - clean)
    assert floor.value >= q / math.sqrt(12) - 1e-12
    assert floor.quantisation == pytest.approx(q / math.sqrt(12))


def test_the_smallest_step_of_a_table_is_no_resolution():
    from hound_id.dyno.current.noise import resolution

    points = np.random.default_rng(9).uniform(-5, 5, 40)  # operating points: their smallest step is no ADC count
    assert resolution(points) == 0.0
    assert resolution(np.round(points / 0.25) * 0.25) == pytest.approx(0.25)
    assert resolution(np.round(points, 1)) == pytest.approx(0.1)


def test_white_floor_needs_ten_rows():
    assert math.isnan(white_floor(np.zeros(9)))
    assert white_floor(np.zeros(50)) == 0.0


def test_a_model_that_explains_the_log_is_at_the_floor_of_filtered_noise():
    """The verdict the floor exists for: a right model on a filtered transducer is at the floor, and the report says
    how the floor was found; judged by the sample-to-sample floor alone it would be 'missing' something."""
    signals, clean = held_plan(seed=7)
    noise = filtered_noise(clean.size, 0.05, 8.0, seed=8)
    torque = clean + noise
    fit = fit_model(signals, torque, ("linear",))
    d = diagnose(signals, torque, fit)
    assert d.noise is not None and d.noise.method == "still"
    assert fit.rmse_test > 2.5 * d.noise.white  # the old floor would call this far from the noise
    assert d.at_noise_floor, d.summary()
    assert "hold still" in d.summary()
