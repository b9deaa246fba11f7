"""The noise floor: sample-to-sample for white noise, the scatter at still inputs or between far-apart moments with
the same inputs for correlated noise."""

import math

import numpy as np
import pytest
from scipy.signal import butter, lfilter

from hound_id.dyno.current.diagnose import auto, diagnose
from hound_id.dyno.current.effects import Signals
from hound_id.dyno.current.fit import fit_model
from hound_id.dyno.current.noise import (
    CHUNK_ROWS,
    MIN_NEIGHBOUR_PAIRS,
    MIN_STILL_ROWS,
    NEIGHBOUR_GAP_S,
    SETTLE_ROWS,
    estimate,
    neighbour_scatter,
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
    assert floor.still == pytest.approx(sigma, rel=0.15)
    # the holds come back to no level, but the speeds do: pairs of moments far apart see the noise too
    assert floor.method in ("still", "neighbours") and floor.value == pytest.approx(sigma, rel=0.15)
    assert floor.white < 0.5 * sigma  # second differences of filtered noise read low
    assert floor.correlation > 2 and "correlated" in floor.sentence()


def test_white_noise_gives_both_estimates_alike():
    signals, clean = held_plan()
    noise = np.random.default_rng(4).normal(0, 0.05, clean.size)
    floor = estimate(signals, clean + noise, noise)
    assert floor.white == pytest.approx(0.05, rel=0.1) and floor.still == pytest.approx(0.05, rel=0.1)
    assert floor.value == pytest.approx(0.05, rel=0.1)


def test_a_log_that_never_comes_back_falls_back_to_sample_to_sample_and_says_what_to_record():
    t = np.arange(0.0, 30.0, 1.0 / RATE)
    ramp = Signals(time=t, current=np.linspace(-10.0, 10.0, t.size), velocity=2 * np.sin(2 * np.pi * 0.17 * t))
    noise = np.random.default_rng(5).normal(0, 0.05, t.size)
    floor = estimate(ramp, KT * ramp.current + noise, noise)
    assert floor.method == "sample-to-sample" and floor.still is None and floor.neighbours is None
    assert "hold the current and speed still" in floor.sentence() and "repeat the excitation" in floor.sentence()


def sweep(seconds: float = 30.0) -> Signals:
    """A sweep that never holds still: current and speed sines at unrelated frequencies."""
    t = np.arange(0.0, seconds, 1.0 / RATE)
    rng = np.random.default_rng(7)
    return Signals(
        time=t,
        current=10 * np.sin(2 * np.pi * 0.3 * t) + rng.normal(0, 0.01, t.size),
        velocity=2 * np.sin(2 * np.pi * 0.17 * t) + rng.normal(0, 0.02, t.size),
    )


def ar1(n: int, sigma: float, rho: float, seed: int = 8) -> np.ndarray:
    """AR(1) noise of marginal standard deviation ``sigma`` and correlation ``rho`` per sample."""
    e = np.random.default_rng(seed).normal(0, sigma * math.sqrt(1 - rho**2), n)
    x = np.empty(n)
    x[0] = np.random.default_rng(seed + 1).normal(0, sigma)
    for k in range(1, n):
        x[k] = rho * x[k - 1] + e[k]
    return x


@pytest.mark.parametrize(
    "noise_of",
    [
        pytest.param(lambda n: filtered_noise(n, 0.05, 8.0), id="transducer-8Hz"),
        pytest.param(lambda n: filtered_noise(n, 0.05, 20.0), id="transducer-20Hz"),
        pytest.param(lambda n: ar1(n, 0.05, 0.95), id="ar1-0.95"),
        pytest.param(lambda n: np.random.default_rng(4).normal(0, 0.05, n), id="white"),
    ],
)
def test_the_neighbour_floor_of_correlated_noise_on_a_sweep_is_its_standard_deviation(noise_of):
    signals = sweep()
    noise = noise_of(signals.current.size)
    sigma = float(noise.std())
    floor = estimate(signals, KT * signals.current + noise, noise)
    assert floor.still is None  # nothing holds still in a sweep
    assert floor.neighbours == pytest.approx(sigma, rel=0.1) and floor.paired.pairs >= MIN_NEIGHBOUR_PAIRS
    assert floor.value == pytest.approx(sigma, rel=0.1)
    assert "whose inputs coincide" in floor.sentence() and floor.paired.within[0] >= NEIGHBOUR_GAP_S
    assert floor.paired.drift is None and "drifts" not in floor.sentence()
    if floor.white < 0.8 * sigma:  # correlated: second differences read low, the pairs set the floor
        assert floor.method == "neighbours" and "correlated" in floor.sentence()


def test_the_neighbour_floor_does_not_take_a_missing_effect_for_noise():
    signals = sweep()
    sigma = 0.05
    noise = ar1(signals.current.size, sigma, 0.9)
    i, w = signals.current, signals.velocity
    # saturation, friction of the sign of the speed and a torque one loop late: none of it in the model below
    late = np.concatenate(([i[0]], i[:-1]))
    truth = KT * late - 0.004 * late * np.abs(late) - 0.3 * np.tanh(w / 0.05) - 0.05 * w
    measured = truth + noise
    fit = fit_model(signals, measured, ("linear",))
    assert fit.rmse_test > 4 * sigma  # the model misses a lot
    floor = estimate(signals, measured, np.asarray(fit.residual))
    assert floor.method == "neighbours" and floor.value == pytest.approx(float(noise.std()), rel=0.1)


def test_a_drift_over_the_log_is_reported_and_not_counted_as_noise():
    """A motor heating over the run: Kt falls 10 % in 30 s. No model of current and speed follows it; pairs of moments
    with the same inputs far apart differ by it, pairs close in time do not, and the floor is theirs."""
    signals = sweep()
    sigma = 0.05
    noise = ar1(signals.current.size, sigma, 0.9)
    heating = 1.0 - 0.1 * signals.time / signals.time[-1]
    measured = KT * heating * signals.current + noise
    fit = fit_model(signals, measured, ("linear",))
    d = diagnose(signals, measured, fit)
    assert d.noise is not None and d.noise.paired is not None
    assert d.noise.paired.drift is not None and d.noise.paired.far > 3 * sigma
    assert d.noise_floor == pytest.approx(float(noise.std()), rel=0.25)  # not the drift
    assert "the torque drifts over the log" in d.noise.sentence()
    assert not d.at_noise_floor and fit.rmse_test > 2 * d.noise_floor


def test_cogging_is_never_noise_between_far_apart_moments_when_the_log_has_the_angle():
    signals = sweep()
    angle = np.cumsum(signals.velocity) / RATE
    rotating = Signals(time=signals.time, current=signals.current, velocity=signals.velocity, position=angle)
    noise = np.random.default_rng(10).normal(0, 0.02, angle.size)
    cogging = 0.2 * np.sin(21 * angle)
    paired = neighbour_scatter(rotating, cogging + noise)
    # the pairs must share the angle: what they leave is the noise, not the 0.14 N m RMS cogging
    assert paired is None or paired.value < 0.03


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
    assert d.noise is not None and d.noise.method in ("still", "neighbours")
    assert fit.rmse_test > 2.5 * d.noise.white  # the old floor would call this far from the noise
    assert d.at_noise_floor, d.summary()
    assert "hold still" in d.summary() or "same inputs" in d.summary()


def _review_sweep(rate: float, seconds: float, period: float | None = None) -> Signals:
    """A sweep whose frequency rises from 0.05 to 1.5 Hz (or a periodic excitation of ``period`` seconds)."""
    t = np.arange(0.0, seconds, 1.0 / rate)
    if period:
        i = 15 * np.sin(2 * np.pi * t / period) + 4 * np.sin(6 * np.pi * t / period)
        w = 20 * np.sin(4 * np.pi * t / period + 0.3)
    else:
        i = 15 * np.sin(2 * np.pi * np.cumsum(0.05 + 1.45 * t / seconds) / rate) + 3 * np.sin(2 * np.pi * 0.037 * t + 1)
        w = 20 * np.sin(2 * np.pi * 0.11 * t) + 5 * np.sin(2 * np.pi * 0.43 * t)
    return Signals(time=t, current=i, velocity=w + np.random.default_rng(11).normal(0, 0.05, t.size))


def test_a_sweep_logged_slowly_pairs_only_moments_whose_currents_agree():
    """At 20 Hz a 1.5 Hz sweep moves amps from sample to sample; first differences read that as the current's noise.
    Paired within such a tolerance, a missing saturation (tanh) was taken for noise and the log called at its floor."""
    signals = _review_sweep(20.0, 60.0)
    i = signals.current
    noise = np.random.default_rng(12).normal(0, 0.02, i.size)
    measured = 1.12 * np.tanh(i / 8) + noise
    fit = fit_model(signals, measured, ("linear",))
    d = diagnose(signals, measured, fit)
    assert not d.at_noise_floor and fit.rmse_test > 3 * d.noise_floor
    # no pair of moments whose currents differ by amps: the neighbour estimate does not take the saturation for noise
    assert d.noise is not None and (d.noise.paired is None or d.noise.paired.value < 1.3 * 0.02)


@pytest.mark.parametrize("period", [2.0, 4.0, 5.0])
def test_a_periodic_excitation_of_any_period_gives_pairs(period):
    """A period that is a multiple of the pairing's spans must not hide every partner."""
    signals = _review_sweep(100.0, 40.0, period)
    noise = ar1(signals.current.size, 0.02, 0.95, seed=13)
    floor = estimate(signals, 0.14 * signals.current + noise, noise)
    assert floor.paired is not None and floor.method == "neighbours"
    assert floor.value == pytest.approx(float(noise.std()), rel=0.15)


@pytest.mark.parametrize("plan", ["held", "sweep"])
@pytest.mark.parametrize("cutoff_hz", [None, 20.0])
def test_a_noise_that_grows_with_the_load_is_counted_by_its_root_mean_square(plan, cutoff_hz):
    """A torque ripple sampled too slowly to follow grows with the current: the median row's noise is then far below
    the root mean square that a cross-validated RMSE is compared with, and every estimate has to read the latter."""
    signals, clean = held_plan(seed=3) if plan == "held" else (sweep(), KT * sweep().current)
    n = clean.size
    unit = np.random.default_rng(11).normal(size=n) if cutoff_hz is None else filtered_noise(n, 1.0, cutoff_hz, seed=12)
    noise = (0.01 + 0.02 * np.abs(signals.current)) * unit
    rms = float(np.sqrt(np.mean(noise**2)))
    floor = estimate(signals, clean + noise, noise)
    assert floor.load is not None and floor.load.sigma[-1] > 3 * floor.load.sigma[0]
    assert floor.value == pytest.approx(rms, rel=0.15), floor.sentence()
    assert "grows with the load" in floor.sentence() and floor.to_dict()["load"]["sigma"] == list(floor.load.sigma)
    # the same noise read as one size: the median row's noise, well below its root mean square
    if cutoff_hz is None:
        assert white_floor(noise) < 0.85 * rms


def test_a_noise_of_one_size_is_not_called_load_dependent():
    for seed in range(10):
        signals, clean = held_plan(seed=seed)
        for noise in (
            np.random.default_rng(100 + seed).normal(0, 0.05, clean.size),
            filtered_noise(clean.size, 0.05, 20.0, seed=200 + seed),
        ):
            floor = estimate(signals, clean + noise, noise)
            assert floor.load is None, (seed, floor.sentence())
        swept = sweep()
        noise = ar1(swept.current.size, 0.05, 0.9, seed=300 + seed)
        assert estimate(swept, KT * swept.current + noise, noise).load is None


def test_a_right_model_on_a_load_dependent_noise_is_at_the_floor():
    signals, clean = held_plan(seed=5)
    noise = (0.01 + 0.02 * np.abs(signals.current)) * filtered_noise(clean.size, 1.0, 20.0, seed=6)
    torque = clean + noise
    fit = fit_model(signals, torque, ("linear",))
    d = diagnose(signals, torque, fit)
    assert d.noise is not None and d.noise.load is not None
    assert fit.rmse_test > 1.3 * white_floor(noise)  # judged by the median row's noise it would miss something
    assert d.at_noise_floor, d.summary()


def test_a_fold_of_quiet_rows_is_not_a_fold_the_model_fits_better():
    """The motor rests for the first tenth of the log, where a noise that grows with the load is small: the fit
    without that fold is far worse on its own (loud) training rows than on the quiet fold, and that is the noise, not
    rows the model does not follow."""
    signals, clean = held_plan(seed=9)
    rest = signals.time < 4.5
    current = np.where(rest, np.random.default_rng(1).normal(0, 0.01, rest.size), signals.current)
    velocity = np.where(rest, np.random.default_rng(2).normal(0, 0.02, rest.size), signals.velocity)
    signals = Signals(time=signals.time, current=current, velocity=velocity)
    clean = np.where(rest, 0.0, clean)
    noise = (0.005 + 0.03 * np.abs(current)) * np.random.default_rng(3).normal(size=current.size)
    torque = clean + noise
    fit = fit_model(signals, torque, ("linear",))
    d = diagnose(signals, torque, fit)
    train, test = np.asarray(fit.fold_rmse_train), np.asarray(fit.fold_rmse_test)
    assert train[0] > 3 * test[0]  # judged against one floor for every row, the quiet fold would be flagged
    assert d.noise is not None and d.noise.load is not None
    assert not any("worse on its own training rows" in f for f in d.flags), d.flags
    assert d.at_noise_floor, d.summary()


def _lowpass(x: np.ndarray, a: float) -> np.ndarray:
    return lfilter([1.0 - a], [1.0, -a], x)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_knee_the_model_lacks_on_a_fast_current_is_not_read_as_noise_that_grows_with_the_load(seed):
    """The current moves amps from sample to sample, and the torque flattens above 6 A in a way no effect of the
    model follows: the residual's second differences there are the model's error. Read as noise that grows with the
    load, they called the model at its floor."""
    rng = np.random.default_rng(seed)
    n = int(30 * RATE)
    i = _lowpass(rng.uniform(-10, 10, n), 0.3) * 1.6
    t = np.arange(n) / RATE
    signals = Signals(time=t, current=i, velocity=0.01 * rng.standard_normal(n))
    over = np.clip(np.abs(i) - 6, 0, None)
    torque = 0.9 * i - np.sign(i) * 0.25 * over**2 + 0.03 * rng.standard_normal(n)
    d = auto(signals, torque, fit_model(signals, torque, ("linear", "saturation")))[-1].diagnosis
    assert d.noise is not None and (d.noise.load is None or d.noise.load.method != "sample-to-sample")
    assert not d.at_noise_floor, d.summary()


def test_a_noise_that_falls_with_the_load_is_said_to_fall():
    """A backlash that rattles while the gears are unloaded: loud near zero current, quiet under load."""
    t = np.arange(0.0, 60.0, 1.0 / RATE)
    i = 8 * np.sin(2 * np.pi * 0.3 * t)
    signals = Signals(time=t, current=i, velocity=2 * np.cos(2 * np.pi * 0.3 * t))
    noise = np.where(np.abs(i) < 2, 0.10, 0.03) * np.random.default_rng(5).standard_normal(t.size)
    floor = estimate(signals, 0.9 * i + noise, noise)
    assert floor.load is not None and "falls with the load" in floor.sentence(), floor.sentence()
    assert "grows" not in floor.sentence()
    assert floor.value == pytest.approx(float(np.sqrt(np.mean(noise**2))), rel=0.15)


def test_a_rounded_torque_at_rest_is_not_noise_that_grows_with_the_load():
    """The drive reports exactly 0 A at rest and the torque ADC rounds to 0.05 N m: second differences read nothing
    at rest and rounding under load. That is the rounding, not a noise that grows with the load."""
    t = np.arange(0.0, 60.0, 1.0 / RATE)
    i = np.where((t % 10) < 5, 0.0, 8 * np.sin(2 * np.pi * 0.2 * (t % 10 - 5)))
    signals = Signals(time=t, current=i, velocity=0.5 * i)
    torque = np.round((0.9 * i + 0.005 * np.random.default_rng(6).standard_normal(t.size)) / 0.05) * 0.05
    floor = estimate(signals, torque, torque - 0.9 * i)
    assert floor.load is None and floor.method == "quantisation", floor.sentence()
