"""The noise floor's third reading: the torque's scatter between rows whose inputs are near neighbours (the same
current, speed, angle and temperature at other times), where the log never holds still."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hound_id.dyno.current.effects import Signals
from hound_id.dyno.current.still import LOAD_STRATA, MAD_TO_SIGMA, STILL_ANGLE, Array, LoadProfile, Strata, Tolerances

#: Two moments pair only when this far apart in time [s] and :data:`NEIGHBOUR_GAP_ROWS` rows (the noise of a filtered
#: transducer, AR(1) with a correlation of 0.95 per sample, is correlated by 0.08 after 50 samples). Calibrated on
#: test_noise::test_the_neighbour_floor_of_correlated_noise_on_a_sweep_is_its_standard_deviation.
NEIGHBOUR_GAP_S = 0.5
NEIGHBOUR_GAP_ROWS = 50
#: Past samples of the current two paired moments must share (the recent history a delay or a lag reads). Calibrated
#: on test_noise::test_the_neighbour_floor_does_not_take_a_missing_effect_for_noise.
NEIGHBOUR_LAGS = 2
#: Fewest pairs for a neighbour floor: each difference holds two independent noise values, so 100 pairs know the
#: standard deviation to about 7 %. Calibrated on
#: test_noise::test_the_neighbour_floor_of_correlated_noise_on_a_sweep_is_its_standard_deviation.
MIN_NEIGHBOUR_PAIRS = 100
#: Partners taken per searched row (more pairs at more separations); share of the pairs, nearest in time, the floor
#: comes from; the farthest as many again show a drift when they differ by more than DRIFT_FACTOR times as much.
#: Calibrated on test_noise::test_a_drift_over_the_log_is_reported_and_not_counted_as_noise.
NEIGHBOUR_K = 4
#: Nearest rows in the inputs' space a searched row looks through for partners far enough in time (a long hold fills
#: the nearest with rows of the same hold). Calibrated on
#: test_noise::test_a_periodic_excitation_of_any_period_gives_pairs.
NEIGHBOUR_SEARCH = 32
NEAR_SHARE = 0.25
DRIFT_FACTOR = 1.5
#: Pair differences beyond this many robust standard deviations are left out of the neighbour estimate (its mean
#: square is then divided by what a normal distribution keeps). Calibrated on
#: test_noise::test_the_neighbour_floor_of_correlated_noise_on_a_sweep_is_its_standard_deviation.
PAIR_TRIM_SIGMAS = 3.0
#: Standard deviation of a unit normal cut at +-c = PAIR_TRIM_SIGMAS: sqrt(1 - 2 c phi(c) / (2 Phi(c) - 1)).
_TRIMMED_SD = math.sqrt(
    1.0
    - 2.0
    * PAIR_TRIM_SIGMAS
    * math.exp(-(PAIR_TRIM_SIGMAS**2) / 2)
    / math.sqrt(2 * math.pi)
    / math.erf(PAIR_TRIM_SIGMAS / math.sqrt(2))
)
#: Most rows searched for partners (evenly spaced); most rows partners are searched among: the estimate needs
#: hundreds of pairs, not millions, and the search stays linear in the log's length (0.10-0.14 s for a million rows:
#: benchmarks/noise_floor.py).
#: Calibrated on test_noise::test_the_neighbour_floor_of_correlated_noise_on_a_sweep_is_its_standard_deviation (its
#: 6,000 rows are all searched).
NEIGHBOUR_QUERIES = 20_000
NEIGHBOUR_POOL = 50_000


def _neighbour_inputs(signals: Signals, rows: NDArray[np.intp], tol: Tolerances) -> Array:
    """The paired channels at ``rows`` (counted from row :data:`NEIGHBOUR_LAGS`), each divided by its still tolerance
    (two moments coincide within 1 on every column): the current now and its last samples, the speed, the
    temperature, the angle."""
    at = rows + NEIGHBOUR_LAGS
    amps = tol.current_paired if tol.current_paired > 0 else tol.current
    columns = [signals.current[at - k] / amps for k in range(NEIGHBOUR_LAGS + 1)]
    for x, width in ((signals.velocity, tol.velocity), (signals.temperature, tol.temperature)):
        if x is not None and width is not None and width > 0:  # a zero width: a channel that never moves
            columns.append(x[at] / width)
    if signals.position is not None:  # cogging is never noise on a log that can show it
        columns.append(np.mod(signals.position[at], 2 * math.pi) / (STILL_ANGLE / 2))
    return np.column_stack([np.where(np.isfinite(c), c, 0.0) for c in columns])


@dataclass(frozen=True)
class Neighbours:
    """The residual's scatter between far-apart moments whose inputs coincide, near and far apart in time."""

    value: float
    """Standard deviation from the pairs nearest in time [N m]: the noise floor's estimate."""
    pairs: int
    """Pairs it used."""
    within: tuple[float, float]
    """Their separations in time, least and most [s]."""
    far: float
    """Standard deviation from the pairs farthest apart in time [N m]."""
    far_within: tuple[float, float]
    """Their separations [s]."""
    stderr: float = 0.0
    """Standard error of :attr:`value` (a jackknife over the spans of the log) [N m]; 0 when the pairs come from too
    few spans to say."""
    far_stderr: float = 0.0
    """Standard error of :attr:`far` [N m]."""
    near_raw: float = 0.0
    """The nearest pairs' scatter before a drift linear in time is taken out [N m] (:attr:`far` is compared with it)."""
    load: LoadProfile | None = None
    """The scatter in strata of the current's magnitude when it changes with the load (:attr:`value` is then their
    root mean square over the rows)."""

    @property
    def drift(self) -> float | None:
        """far / value when the far pairs differ by more than :data:`DRIFT_FACTOR` times the floor's pairs."""
        near = self.near_raw if self.near_raw > 0 else self.value
        ratio = self.far / near if near > 0 else math.inf
        return ratio if ratio > DRIFT_FACTOR else None


def far_partners(
    pool: Array, queries: Array, pool_time: Array, query_time: Array, gap: float, search: int, keep: int
) -> tuple[NDArray[np.intp], NDArray[np.bool_]]:
    """For each query row, among its ``search`` nearest ``pool`` rows in the inputs (Chebyshev distance at most 1: the
    columns already divided by their tolerances), the first ``keep`` at least ``gap`` away in time: the pool index of
    every candidate (queries, search) and True where it is one of those."""
    from scipy.spatial import cKDTree

    k = min(search, len(pool))
    dist, idx = cKDTree(pool).query(queries, k=k, p=np.inf, distance_upper_bound=1.0)
    dist, idx = dist.reshape(len(queries), k), np.minimum(idx.reshape(len(queries), k), len(pool) - 1)
    usable = np.isfinite(dist) & (np.abs(pool_time[idx] - query_time[:, None]) >= gap)
    usable &= np.cumsum(usable, axis=1) <= keep  # the first ``keep`` far enough in time
    return idx, usable


def neighbour_scatter(
    signals: Signals,
    residual: Array,
    rows: NDArray[np.bool_] | None = None,
    tolerances: Tolerances | None = None,
    strata: Strata | None = None,
) -> Neighbours | None:
    """The residual's scatter from pairs of far-apart moments whose inputs coincide (module docstring); None below
    :data:`MIN_NEIGHBOUR_PAIRS` pairs.

    ``rows`` (True where a row may be paired) keeps a broken stretch out: paired with the rest of the log, a motor
    switched off or a torque amplifier gone wrong would read as noise, and the floor would hide it.

    Each searched row takes, among its :data:`NEIGHBOUR_SEARCH` nearest rows (Chebyshev distance in tolerances, at
    most 1), the first :data:`NEIGHBOUR_K` at least the gap away in time. What the pair's channels still differ by,
    within tolerance, moves a missing effect's torque: that is taken out of the differences by its slope over all
    pairs (a delay the model lacks is linear in the current's last samples). The scatter is a trimmed root mean
    square (:func:`_pair_sigma`).

    The floor comes from the pairs nearest in time (the nearest :data:`NEAR_SHARE`, at least
    :data:`MIN_NEIGHBOUR_PAIRS`): a drift over the log (a motor heating, an offset creeping) grows with the
    separation, so pairs close in time carry least of it. When the pairs farthest apart scatter more than
    :data:`DRIFT_FACTOR` times those, the drift is reported beside the floor.

    With ``strata``, the scatter is read in each stratum of the current's magnitude too, and when it changes with the
    load (:meth:`Strata.profile`) the floor is its root mean square over the log's rows.

    Blind spot: an error that depends on the channels' history further back than :data:`NEIGHBOUR_LAGS` samples (a
    slow lag or a resonance the model lacks) varies between the pairs and counts as noise here; the still estimate
    and the diagnosis's own tests of those effects do not share it.
    """
    if not signals.timed or signals.current.size < 4 * NEIGHBOUR_GAP_ROWS:
        return None
    r = np.asarray(residual, float)[NEIGHBOUR_LAGS:]
    t = signals.time[NEIGHBOUR_LAGS:]
    step = float(np.median(np.diff(t)))
    gap = max(NEIGHBOUR_GAP_S, NEIGHBOUR_GAP_ROWS * step)
    spans = np.floor((t - t[0]) / gap).astype(np.int64)
    found = _pairs(signals, r.size, t, gap, rows, tolerances)
    if found is None:
        return None
    a_rows, b_rows, tol = found
    diff, drifting = _differences(signals, r, t, step, a_rows, b_rows, tol)
    sep = np.abs(t[a_rows] - t[b_rows])
    episode = (spans[a_rows], spans[b_rows])
    order = np.argsort(sep, kind="stable")
    count = max(MIN_NEIGHBOUR_PAIRS, int(NEAR_SHARE * order.size))
    near, far = order[:count], order[-count:]

    def scatter(values: Array, which: NDArray[np.intp], least: int = MIN_NEIGHBOUR_PAIRS) -> tuple[float, float] | None:
        return _pair_sigma(values[which], (episode[0][which], episode[1][which]), least)

    every, near_fit, far_fit = scatter(diff, order), scatter(diff, near), scatter(diff, far)
    # the drift is judged before its linear part is taken out: the near and far pairs as the inputs leave them
    near_raw, far_raw = scatter(drifting, near), scatter(drifting, far)
    if any(f is None for f in (every, near_fit, far_fit, near_raw, far_raw)):
        return None
    assert every and near_fit and far_fit and near_raw and far_raw  # for the type checker
    within = (float(sep.min()), float(sep.max()))
    value, error, used = every[0], every[1], order
    # a drift named, or one that is not linear in time left after the slope: the nearest pairs alone set the floor
    if far_raw[0] > DRIFT_FACTOR * near_raw[0] or far_fit[0] > DRIFT_FACTOR * near_fit[0]:
        value, error, used = near_fit[0], near_fit[1], near
        within = (float(sep[near].min()), float(sep[near].max()))
    load = None
    if strata is not None:
        label = strata.label[NEIGHBOUR_LAGS:][a_rows[used]]
        by = {k: scatter(diff, used[label == k], MIN_NEIGHBOUR_PAIRS // LOAD_STRATA) for k in range(len(strata.share))}
        value, error, load = _by_load(strata, {k: v for k, v in by.items() if v is not None}, value, error)
    if not value > 0:
        return None
    far_within = (float(sep[far].min()), float(sep[far].max()))
    return Neighbours(value, int(used.size), within, far_raw[0], far_within, error, far_raw[1], near_raw[0], load)


def _pairs(
    signals: Signals,
    size: int,
    t: Array,
    gap: float,
    rows: NDArray[np.bool_] | None,
    tolerances: Tolerances | None,
) -> tuple[NDArray[np.int64], NDArray[np.int64], Tolerances] | None:
    """(first rows, second rows, tolerances) of far-apart eligible rows whose inputs coincide; None if too few."""
    eligible = np.arange(size) if rows is None else np.flatnonzero(np.asarray(rows, bool)[NEIGHBOUR_LAGS:])
    if eligible.size < 2:
        return None
    tol = Tolerances.of(signals) if tolerances is None else tolerances
    pool = eligible[:: -(-eligible.size // NEIGHBOUR_POOL)]
    queries = eligible[:: -(-eligible.size // NEIGHBOUR_QUERIES)]
    idx, usable = far_partners(
        _neighbour_inputs(signals, pool, tol),
        _neighbour_inputs(signals, queries, tol),
        t[pool],
        t[queries],
        gap,
        NEIGHBOUR_SEARCH,
        NEIGHBOUR_K,
    )
    partner = pool[idx]
    a_rows, b_rows = np.broadcast_to(queries[:, None], usable.shape)[usable], partner[usable]
    code = np.unique(np.minimum(a_rows, b_rows) * np.int64(size) + np.maximum(a_rows, b_rows))  # each pair once
    if code.size < MIN_NEIGHBOUR_PAIRS:
        return None
    return code // size, code % size, tol


def _differences(
    signals: Signals,
    r: Array,
    t: Array,
    step: float,
    a_rows: NDArray[np.int64],
    b_rows: NDArray[np.int64],
    tol: Tolerances,
) -> tuple[Array, Array]:
    """(residual differences less the inputs' part and a drift linear in time, less the inputs' part only)."""
    diff = r[a_rows] - r[b_rows]
    dx = _neighbour_inputs(signals, a_rows, tol) - _neighbour_inputs(signals, b_rows, tol)
    slope, *_ = np.linalg.lstsq(dx, diff, rcond=None)
    drifting = diff - dx @ slope
    # a drift linear in time (an offset creeping, Kt sagging as the motor warms) taken out as well, for the floor
    dt = (t[a_rows] - t[b_rows]) / max(float(t[-1] - t[0]), step)
    amps = 0.5 * (signals.current[a_rows + NEIGHBOUR_LAGS] + signals.current[b_rows + NEIGHBOUR_LAGS])
    amps = amps / max(float(np.max(np.abs(amps))), 1e-300)
    full = np.column_stack((dx, dt, dt * amps))
    slope, *_ = np.linalg.lstsq(full, diff, rcond=None)
    return diff - full @ slope, drifting


def _by_load(
    strata: Strata, read: dict[int, tuple[float, float]], value: float, error: float
) -> tuple[float, float, LoadProfile | None]:
    """(floor [N m], relative error, load profile): the per-stratum scatters' RMS over rows where load moves it."""
    load = strata.profile("neighbours", {k: v[0] for k, v in read.items()})
    if load is not None:
        value = load.value
        w = np.asarray(load.share) / sum(load.share)
        terms = [wk * v[0] * v[1] for wk, (_, v) in zip(w, sorted(read.items()), strict=True)]
        error = math.sqrt(sum(x * x for x in terms)) / value if value > 0 else 0.0
    return value, error, load


def _pair_sigma(
    diff: Array, ends: tuple[NDArray[np.int64], NDArray[np.int64]], least: int = MIN_NEIGHBOUR_PAIRS
) -> tuple[float, float] | None:
    """Noise standard deviation from pair differences (a difference holds two noise values) and its standard error
    [N m]; None below ``least`` pairs.

    The root mean square within :data:`PAIR_TRIM_SIGMAS` robust standard deviations of zero, corrected for the
    normal distribution's tails so cut. Cut closer than the still estimate's trim on purpose: where the torque's error
    depends on more of the current's history than the pairs share (the instants after a step on a rig that rings), a
    few pairs differ by far more than the noise, and a plain mean square would count that error as noise. About zero,
    not about the median: a drift shifts every far pair's difference the same way, and is no noise. The standard
    error is a jackknife over the spans of the log (``ends``: the span of each pair's two moments), leaving out every
    pair that touches a span in turn: correlated noise makes the pairs from one stretch alike, and a log holds only
    so many independent ones."""
    if diff.size < least:
        return None
    robust = MAD_TO_SIGMA * float(np.median(np.abs(diff)))
    if not robust > 0:
        return 0.0, 0.0
    keep = np.abs(diff) <= PAIR_TRIM_SIGMAS * robust
    q = diff[keep] ** 2 / (2.0 * _TRIMMED_SD**2)
    first, second = ends[0][keep], ends[1][keep]
    size = int(max(first.max(), second.max())) + 1
    touched = np.bincount(first, minlength=size) + np.bincount(second, minlength=size)
    weight = np.bincount(first, weights=q, minlength=size) + np.bincount(second, weights=q, minlength=size)
    spans = np.flatnonzero((touched > 0) & (touched < q.size))
    sigma = math.sqrt(float(q.mean()))
    if spans.size < 2 or not sigma > 0:
        return sigma, 0.0
    left = (float(q.sum()) - weight[spans]) / (q.size - touched[spans])
    variance = (spans.size - 1) / spans.size * float(np.sum((left - left.mean()) ** 2))
    return sigma, math.sqrt(variance) / (2.0 * sigma)
