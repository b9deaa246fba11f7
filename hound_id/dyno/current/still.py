"""The noise floor's first two readings (:mod:`hound_id.dyno.current.noise`): the sample-to-sample scatter of the torque
(white noise) and its scatter over the stretches where the inputs hold still, with their tolerances, the load
strata both are taken in, and the channel's rounding."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hound_id.dyno.artefacts import noise_sigma, quantum
from hound_id.dyno.current.effects import Signals

Array = NDArray[np.float64]


#: 1.4826 MAD is the standard deviation of a normal distribution.
MAD_TO_SIGMA = 1.4826
#: Fewest residual samples a sample-to-sample floor is estimated from. Calibrated on
#: test_diagnose::test_noise_floor_of_white_noise and test_noise::test_white_floor_needs_ten_rows.
MIN_FLOOR_ROWS = 10
#: A channel holds still while it stays within this many of its own noise standard deviations (first differences,
#: robust) of where the stretch began: 4 sigma leaves one false break in about 16,000 samples of white noise.
#: Calibrated on test_noise::test_still_stretches_are_found_on_a_held_plan_and_not_on_a_sweep.
STILL_SIGMAS = 4.0
#: ... or within this share of the channel's range, whichever is wider (a channel whose noise reads as zero
#: between quantisation steps still holds still while it moves less than this). Calibrated on
#: test_noise::test_still_stretches_are_found_on_a_held_plan_and_not_on_a_sweep.
STILL_SHARE = 0.005
#: ... and never wider than this share of the channel's range: a 1.5 Hz sweep logged at 20 Hz moves amps from one
#: sample to the next, which a noise estimate from first differences takes for noise (a tolerance of 8 A on a 30 A
#: sweep paired moments a missing saturation told apart). Calibrated on
#: test_noise::test_a_sweep_logged_slowly_pairs_only_moments_whose_currents_agree.
TOLERANCE_CAP = 0.02
#: The rotor angle holds still while it moves less than this [rad] (1/400 turn: an eighth of a period of cogging up
#: to order 50 per revolution), so that cogging is never counted as noise on a log that can show it. Calibrated on
#: test_noise::test_a_rotating_rotor_is_never_still_when_the_log_has_its_angle.
STILL_ANGLE = 2 * math.pi / 400
#: Rows left out at the start of a still stretch: the transducer and the current loop settling after a step (three
#: samples: 30 ms at 100 Hz, longer than the AK80-9 logs' settling and the polled rig's 80 Hz transducer).
#: Calibrated on test_noise::test_the_still_floor_of_filtered_noise_is_its_standard_deviation.
SETTLE_ROWS = 3
#: Fewest rows in a still piece after the settling rows (a piece's mean costs one degree of freedom); longest still
#: piece [rows]: the mean is taken piece by piece, so a slow drift within a long hold counts as a drift. Calibrated on
#: test_noise::test_still_stretches_are_found_on_a_held_plan_and_not_on_a_sweep.
MIN_PIECE_ROWS = 10
CHUNK_ROWS = 100
#: Fewest still rows for a still floor: 200 rows of noise correlated over five samples still leave about 40 independent
#: values, a standard deviation known to about 11 %. Calibrated on
#: test_noise::test_the_still_floor_of_filtered_noise_is_its_standard_deviation.
MIN_STILL_ROWS = 200
#: A channel is rounded when this share of its values lie within ON_GRID_TOLERANCE steps of its grid (a real ADC
#: puts every value there; noise puts a tenth of them there by chance). Calibrated on
#: test_noise::test_a_coarsely_rounded_torque_channel_sets_the_floor and
#: test_noise::test_the_smallest_step_of_a_table_is_no_resolution.
ON_GRID_SHARE = 0.9
ON_GRID_TOLERANCE = 0.05


#: Pieces' deviations beyond this many robust sigmas are left out of the still floor (a glitch or an unsettled step).
#: Calibrated on test_noise::test_white_noise_gives_both_estimates_alike.
TRIM_SIGMAS = 5.0


#: Strata of the current's magnitude (equal row counts) in which the noise's size is read, and the rows (or still
#: rows) each needs; a neighbour stratum needs a quarter of the pairs the whole log does. Four strata of 100
#: rows tell a noise growing with the load from one of a single size on the synthetic logs and on the polled rig.
#: Calibrated on test_noise::test_a_noise_that_grows_with_the_load_is_counted_by_its_root_mean_square and
#: test_polled_rig::test_a_gear_mesh_ripple_is_noise_that_grows_with_the_load_and_the_floor_counts_it.
LOAD_STRATA = 4
LOAD_STRATUM_ROWS = 100
#: The noise is said to change with the load when its largest stratum's size is this many times its smallest (no
#: noise of one size was so called in 120 synthetic logs, white, filtered at 20 and 8 Hz, and AR(1)). Calibrated on
#: test_noise::test_a_noise_that_grows_with_the_load_is_counted_by_its_root_mean_square and
#: test_noise::test_a_noise_of_one_size_is_not_called_load_dependent.
LOAD_FACTOR = 1.5


@dataclass(frozen=True)
class Strata:
    """The log's rows in strata of the current's magnitude, of equal row counts (:data:`LOAD_STRATA`)."""

    label: NDArray[np.intp]
    """Each row's stratum."""
    edges: tuple[float, ...]
    """The strata's bounds in |current| [A] (one more than the strata)."""
    share: tuple[float, ...]
    """Each stratum's share of the rows."""

    @classmethod
    def of(cls, current: Array) -> Strata | None:
        """None when the log cannot fill two strata of :data:`LOAD_STRATUM_ROWS` rows."""
        i = np.abs(np.asarray(current, float))
        cuts = np.unique(np.quantile(i, np.linspace(0.0, 1.0, LOAD_STRATA + 1)[1:-1])) if i.size else np.empty(0)
        label = np.searchsorted(cuts, i, side="right")
        counts = np.bincount(label, minlength=cuts.size + 1)
        while counts.size > 1 and counts.min() < LOAD_STRATUM_ROWS:  # a thin stratum joins its smaller neighbour
            j = int(np.argmin(counts))
            into = j - 1 if j == counts.size - 1 or (j > 0 and counts[j - 1] <= counts[j + 1]) else j + 1
            cuts = np.delete(cuts, min(j, into))
            label = np.searchsorted(cuts, i, side="right")
            counts = np.bincount(label, minlength=cuts.size + 1)
        if counts.size < 2:
            return None
        edges = (0.0, *(float(c) for c in cuts), float(i.max()))
        return cls(label, edges, tuple(float(c) / i.size for c in counts))

    def profile(self, method: str, sigma: dict[int, float]) -> LoadProfile | None:
        """The noise's size by stratum when it changes with the load: two strata or more read, the largest
        :data:`LOAD_FACTOR` times the smallest or more; None otherwise (noise of one size)."""
        if len(sigma) < 2 or max(sigma.values()) < LOAD_FACTOR * min(sigma.values()) or not max(sigma.values()) > 0:
            return None
        keys = sorted(sigma)
        return LoadProfile(
            method,
            tuple((self.edges[k], self.edges[k + 1]) for k in keys),
            tuple(sigma[k] for k in keys),
            tuple(self.share[k] for k in keys),
        )


@dataclass(frozen=True)
class LoadProfile:
    """How the noise's size follows the current's magnitude, in the strata an estimate could read."""

    method: str
    """The estimate read in strata (``sample-to-sample``, ``still`` or ``neighbours``)."""
    current: tuple[tuple[float, float], ...]
    """Each stratum's |current| [A]."""
    sigma: tuple[float, ...]
    """Each stratum's noise [N m]."""
    share: tuple[float, ...]
    """Each stratum's share of the log's rows."""

    def variance(self, current: Array) -> Array:
        """Each row's noise variance by its stratum (a row outside the strata read takes the nearest) [N m^2]."""
        upper = np.asarray([hi for _, hi in self.current[:-1]])
        k = np.searchsorted(upper, np.abs(np.asarray(current, float)), side="right")
        return np.asarray(self.sigma)[k] ** 2

    @property
    def value(self) -> float:
        """The noise's root mean square over the rows of the strata read [N m]."""
        w = np.asarray(self.share)
        return math.sqrt(float(w @ np.asarray(self.sigma) ** 2 / w.sum()))

    def to_dict(self) -> dict[str, object]:
        return {
            "method": self.method,
            "current": [list(c) for c in self.current],
            "sigma": list(self.sigma),
            "share_of_rows": list(self.share),
        }


def _second(x: Array) -> Array:
    """Second differences of a series."""
    return x[2:] - 2.0 * x[1:-1] + x[:-2]


def _robust_sd(d: Array) -> float:
    """Standard deviation from the median absolute deviation (steps and spikes barely move it)."""
    return MAD_TO_SIGMA * float(np.median(np.abs(d - np.median(d))))


def white_floor(residual: Array) -> float:
    """Standard deviation of white measurement noise in a residual series [N m] (module docstring)."""
    r = np.asarray(residual, float)
    if r.size < MIN_FLOOR_ROWS:
        return float("nan")
    return _robust_sd(_second(r)) / math.sqrt(6.0)


def white_by_stratum(residual: Array, strata: Strata, model: Array | None = None) -> dict[int, float]:
    """:func:`white_floor` in each stratum with :data:`LOAD_STRATUM_ROWS` rows or more (second differences centred
    on the stratum's rows) [N m].

    With ``model`` (the fitted torque), a stratum where the model's own second differences are larger than the
    residual's is not read: the torque moves faster there than its noise from sample to sample, and a small error of
    the model's shape (a knee it lacks) shows in the residual's second differences as if it were noise."""
    r = np.asarray(residual, float)
    if r.size < 3:
        return {}
    d2 = _second(r)
    m2 = None if model is None else _second(np.asarray(model, float))
    label = strata.label[1:-1]
    out = {}
    for k in range(len(strata.share)):
        inside = label == k
        d = d2[inside]
        if d.size < LOAD_STRATUM_ROWS:
            continue
        sigma = _robust_sd(d)
        if m2 is not None and _robust_sd(m2[inside]) > sigma:
            continue
        out[k] = sigma / math.sqrt(6.0)
    return out


def resolution(x: Array) -> float:
    """The step a rounded channel takes (its ADC count or printed digit) [its unit], 0 when it is not rounded.

    A channel is rounded to q when at least :data:`ON_GRID_SHARE` of its values lie within
    :data:`ON_GRID_TOLERANCE` q of a multiple of q, with q the smallest gap between its distinct values (1st
    percentile); the gaps between the operating points of a table, or between noisy samples, make no such grid.
    """
    gaps = np.diff(np.unique(np.asarray(x, float)))
    q = float(np.percentile(gaps, 1)) if gaps.size else 0.0
    if not q > 0:
        return 0.0
    k = x / q
    return q if float(np.mean(np.abs(k - np.round(k)) <= ON_GRID_TOLERANCE)) >= ON_GRID_SHARE else 0.0


def _tolerance(x: Array, floor: float = 0.0, cap: bool = False) -> float:
    """How far a channel may move and still hold still: its own noise, its quantum, or a share of its range; with
    ``cap`` (the current, for pairing far-apart moments) never more than :data:`TOLERANCE_CAP` of its range (on a
    sweep logged slowly, the sample-to-sample motion that :func:`noise_sigma` reads is the signal, not its noise).
    Holding still is judged uncapped, and the speed is never capped: on a held rotor its whole range is its noise."""
    width = max(STILL_SIGMAS * noise_sigma(x), 2.0 * quantum(x), floor)
    span = float(np.ptp(x)) if x.size else 0.0
    return min(width, TOLERANCE_CAP * span) if cap and span > 0 else width


@dataclass(frozen=True)
class Tolerances:
    """How far each input channel may move and still hold still [its unit]; None for a channel the log lacks."""

    current: float
    velocity: float | None
    temperature: float | None
    position: float | None
    current_paired: float = 0.0
    """The current's tolerance for pairing far-apart moments: capped at :data:`TOLERANCE_CAP` of its range."""

    @classmethod
    def of(cls, signals: Signals) -> Tolerances:
        """Each channel's own noise, its quantum, or a share of its range, whichever is widest (module constants)."""

        def share(x: Array | None) -> float | None:
            return None if x is None else _tolerance(x, STILL_SHARE * float(np.ptp(x)))

        position = None if signals.position is None else _tolerance(signals.position, STILL_ANGLE / 2)
        return cls(
            _tolerance(signals.current, STILL_SHARE * float(np.ptp(signals.current))),
            share(signals.velocity),
            share(signals.temperature),
            position,
            _tolerance(signals.current, STILL_SHARE * float(np.ptp(signals.current)), cap=True),
        )


def still_segments(signals: Signals, tolerances: Tolerances | None = None) -> list[tuple[int, int]]:
    """(start, stop) row ranges where every input channel holds still, settling rows left out, cut into pieces.

    A row continues a stretch while no channel steps by more than twice its tolerance from the row before; a piece
    of a stretch counts when no channel spans more than twice its tolerance over it (a slow ramp passes the first test
    and fails the second). A steady-state table (no sample times) has none: its rows are operating points.
    """
    n = signals.current.size
    if not signals.timed or n < SETTLE_ROWS + MIN_PIECE_ROWS:
        return []
    widths = Tolerances.of(signals) if tolerances is None else tolerances
    channels = [(signals.current, widths.current)]
    if signals.velocity is not None and widths.velocity is not None:
        channels.append((signals.velocity, widths.velocity))
    if signals.position is not None and widths.position is not None:  # cogging is never noise on a log showing it
        channels.append((signals.position, widths.position))
    steady = np.ones(n - 1, dtype=bool)
    for x, tol in channels:
        steady &= np.abs(np.diff(x)) <= 2.0 * tol
    breaks = np.flatnonzero(~steady) + 1
    starts = np.concatenate(([0], breaks)) + SETTLE_ROWS
    stops = np.concatenate((breaks, [n]))
    long = stops - starts >= MIN_PIECE_ROWS
    out = []
    for a, b in zip(starts[long].tolist(), stops[long].tolist(), strict=True):
        count = -(-(b - a) // CHUNK_ROWS)  # pieces of at most CHUNK_ROWS rows
        edges = a + (np.arange(count + 1) * (b - a)) // count
        for lo, hi in zip(edges[:-1].tolist(), edges[1:].tolist(), strict=True):
            if all(float(np.ptp(x[lo:hi])) <= 2.0 * tol for x, tol in channels):
                out.append((lo, hi))
    return out


def still_scatter(
    residual: Array, pieces: list[tuple[int, int]], least: int = MIN_STILL_ROWS
) -> tuple[float, int] | None:
    """Pooled standard deviation of the residual about each piece's mean [N m] and the rows used; None below
    ``least`` rows."""
    if not pieces:
        return None
    r = np.asarray(residual, float)
    dev = np.concatenate([r[a:b] - r[a:b].mean() for a, b in pieces])
    if dev.size < least:
        return None
    robust = MAD_TO_SIGMA * float(np.median(np.abs(dev)))
    keep = np.abs(dev) <= TRIM_SIGMAS * robust if robust > 0 else np.ones(dev.size, dtype=bool)
    dof = int(keep.sum()) - len(pieces)
    if dof <= 0:
        return None
    return math.sqrt(float(dev[keep] @ dev[keep]) / dof), int(keep.sum())


def still_by_stratum(residual: Array, pieces: list[tuple[int, int]], strata: Strata) -> dict[int, float]:
    """:func:`still_scatter` in each stratum (a piece counts in the stratum of its middle row) with
    :data:`LOAD_STRATUM_ROWS` still rows or more [N m]."""
    out = {}
    for k in range(len(strata.share)):
        found = still_scatter(
            residual, [(a, b) for a, b in pieces if strata.label[(a + b) // 2] == k], LOAD_STRATUM_ROWS
        )
        if found is not None:
            out[k] = found[0]
    return out
