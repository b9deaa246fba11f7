"""The noise floor of a dyno log: the torque error no model of the logged channels can remove.

Three estimates, and the floor says which it used:

* **sample-to-sample** (:func:`white_floor`): for white measurement noise of standard deviation sigma, second
  differences of the residual have variance 6 sigma^2 while effects smooth at the sample rate nearly cancel; the
  median absolute deviation keeps steps and spikes from inflating it. A transducer that low-pass filters its noise
  (or noise that is otherwise correlated from sample to sample) makes second differences small: this reads low, by
  a factor 3 for AR(1) noise with a correlation of 0.85 per sample.
* **still** (:func:`still_segments`): where every input channel a model could use holds still (current and speed
  within their own noise, and the rotor angle too when the log has one), no function of those channels changes, so
  the residual's scatter about its own mean there is noise, whatever its colour (a filtered transducer, a vibration,
  a ripple from a channel the log lacks). The first :data:`SETTLE_ROWS` rows of a still stretch are left out (the
  transducer settling after a step) and stretches are cut into pieces of at most :data:`CHUNK_ROWS` rows (a slow
  drift within a long hold is a drift, not noise). It needs :data:`MIN_STILL_ROWS` still rows.
* **neighbours** (:func:`neighbour_scatter`): two moments far apart in time whose inputs coincide get the same value
  from any model of those channels, and their noise is independent whatever its colour; half the mean square of
  the residual's difference between them is the noise variance (the Gamma test's estimate, restricted to pairs
  whose noise cannot be correlated). A drift over the log is taken out by its slope and named.

The floor is the largest estimate the log supports, and never below the torque channel's quantisation
q / sqrt(12) (a rounded channel cannot be matched closer).

Noise that changes with the load (a ripple with an angle the log lacks, a transducer whose noise scales with its
reading) is read by each estimate in strata of the current's magnitude (:class:`Strata`) as well as over the whole
log. When the strata differ by :data:`LOAD_FACTOR` or more, the estimate is their root mean square over the rows:
what a cross-validated RMSE is compared with (a median over the log gives the typical row's noise instead, and a
cut at a few robust standard deviations throws the loud rows away).
"""

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
#: The rounding sets the floor only where the residual's standard deviation reaches this share of q / sqrt(12).
#: Calibrated on test_noise::test_a_coarsely_rounded_torque_channel_sets_the_floor.
QUANTISATION_SHOWS = 0.3
#: Pieces' deviations beyond this many robust sigmas are left out of the still floor (a glitch or an unsettled step).
#: Calibrated on test_noise::test_white_noise_gives_both_estimates_alike.
TRIM_SIGMAS = 5.0
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
#: The strata of second differences are not read when the largest is within this many times the torque's rounding
#: q / sqrt(12) (second differences of rounded values read rounding, more of it where the reading moves). Calibrated on
#: test_noise::test_a_rounded_torque_at_rest_is_not_noise_that_grows_with_the_load.
ROUNDING_DOMINATES = 3.0


@dataclass(frozen=True)
class NoiseFloor:
    """The noise floor of a log and how it was found [N m]."""

    value: float
    """The floor the verdicts use [N m]."""
    method: str
    """``still``, ``neighbours``, ``sample-to-sample`` or ``quantisation``: which estimate set the value."""
    white: float
    """Sample-to-sample estimate from second differences of the residual [N m] (NaN on too few rows)."""
    still: float | None = None
    """Scatter of the residual about its mean where every input holds still [N m]; None without enough still rows."""
    still_rows: int = 0
    """Rows the still estimate used."""
    still_pieces: int = 0
    """Pieces (still stretches, cut at :data:`CHUNK_ROWS`) it used."""
    quantisation: float = 0.0
    """The torque channel's rounding, q / sqrt(12) [N m]."""
    paired: Neighbours | None = None
    """The residual's scatter between far-apart moments whose inputs coincide; None without enough pairs."""
    timed: bool = True
    """False for a steady-state table (no still stretches there: its rows are operating points)."""
    load: LoadProfile | None = None
    """How the noise changes with the current's magnitude, when it does (every estimate is then the noise's root mean
    square over the rows); None for noise of one size."""

    def expected(self, current: Array, rows: NDArray[np.bool_]) -> float:
        """The noise's root mean square over ``rows`` [N m]: the floor, shaped by the load when the noise changes with
        it (quiet rows expect less than the log's floor, loud rows more)."""
        if self.load is None or not rows.any():
            return self.value
        v = self.load.variance(current)
        return self.value * math.sqrt(float(v[rows].mean()) / max(float(v.mean()), 1e-300))

    @property
    def neighbours(self) -> float | None:
        """The neighbour estimate [N m] (pairs nearest in time); None without enough pairs."""
        return None if self.paired is None else self.paired.value

    @property
    def correlation(self) -> float | None:
        """floor / sample-to-sample when a still or neighbour estimate set it: about 1 for white noise, larger when
        the noise is correlated or filtered."""
        direct = {"still": self.still, "neighbours": self.neighbours}.get(self.method)
        if direct is None or not self.white > 0:
            return None
        return direct / self.white

    def sentence(self) -> str:
        """How the floor was found, in one sentence (and the drift, when far-apart moments show one)."""
        return self._how() + self._load() + self._drift()

    def _load(self) -> str:
        if self.load is None:
            return ""
        sg = self.load.sigma
        lo, hi = int(np.argmin(sg)), int(np.argmax(sg))
        quiet, loud = self.load.current[lo], self.load.current[hi]
        grows = hi > lo
        why = (
            "a ripple with an angle the log lacks, or a transducer's noise that scales with its reading"
            if grows
            else "a backlash that rattles while the gears carry no load, or a vibration the load damps"
        )
        return (
            f"; the noise {'grows' if grows else 'falls'} with the load ({self.load.method}: {sg[lo]:.2g} N m at "
            f"|i| {quiet[0]:.3g}-{quiet[1]:.3g} A, {sg[hi]:.2g} N m at {loud[0]:.3g}-{loud[1]:.3g} A; {why}): "
            "the floor is its root mean square over the rows"
        )

    def _how(self) -> str:
        if self.method == "quantisation":
            return (
                f"noise floor {self.value:.3g} N m: the torque channel's rounding (q / sqrt(12)), above the "
                f"sample-to-sample noise ({self.white:.3g} N m)"
            )
        if self.still is None and not self.timed:
            return (
                f"noise floor {self.value:.3g} N m from differences between neighbouring operating points of the table"
            )
        if self.method == "sample-to-sample" and self.still is None and self.paired is None:
            return (
                f"noise floor {self.value:.3g} N m from sample-to-sample differences (the log has fewer than "
                f"{MIN_STILL_ROWS} rows in stretches of {MIN_PIECE_ROWS + SETTLE_ROWS} samples or more where current "
                f"and speed hold still, and fewer than {MIN_NEIGHBOUR_PAIRS} pairs of moments {NEIGHBOUR_GAP_S:g} s "
                "apart with the same inputs); it reads low if the transducer filters its noise: hold the current and "
                "speed still now and then, or repeat the excitation, to measure it"
            )
        still = (
            f"the torque's scatter where the inputs hold still ({self.still_rows} rows in {self.still_pieces} pieces)"
        )
        paired = ""
        if self.paired is not None:
            lo, hi = self.paired.within
            error = f"+- {self.paired.stderr:.1g} N m, " if self.paired.stderr > 0 else ""
            paired = (
                f"the torque's scatter between moments {lo:.2g}-{hi:.2g} s apart whose inputs coincide "
                f"({error}{self.paired.pairs} pairs)"
            )
        if self.method == "sample-to-sample":
            others = [f"{what} is {v:.3g} N m" for what, v in ((still, self.still), (paired, self.neighbours)) if v]
            return (
                f"noise floor {self.value:.3g} N m from sample-to-sample differences (right for white noise); "
                + ", ".join(others)
            )
        head = f"noise floor {self.value:.3g} N m: {still if self.method == 'still' else paired}"
        ratio = self.correlation
        if ratio is not None and ratio > 1.2:
            return (
                f"{head}, {ratio:.2g}x its sample-to-sample noise ({self.white:.3g} N m): the noise is correlated "
                "(a filtered transducer, a vibration, or a ripple from a channel the log lacks)"
            )
        return f"{head}; sample-to-sample {self.white:.3g} N m"

    def _drift(self) -> str:
        if self.paired is None or self.paired.drift is None:
            return ""
        p = self.paired
        lo, hi = p.far_within
        error = f" +- {p.far_stderr:.1g}" if p.far_stderr > 0 else ""
        return (
            f"; moments with the same inputs {lo:.2g}-{hi:.2g} s apart differ by {p.far:.2g}{error} N m, "
            f"{p.far / self.value:.2g}x the floor: the torque drifts over the log (a motor heating, an offset "
            "creeping), remembers more than its last samples, or follows a channel the log lacks; no model of these "
            "channels follows it"
        )

    def to_dict(self) -> dict[str, object]:
        p = self.paired
        return {
            "floor": self.value,
            "method": self.method,
            "sample_to_sample": None if math.isnan(self.white) else self.white,
            "still": self.still,
            "still_rows": self.still_rows,
            "still_pieces": self.still_pieces,
            "neighbours": None if p is None else p.value,
            "neighbours_stderr": None if p is None else p.stderr,
            "neighbour_pairs": 0 if p is None else p.pairs,
            "neighbour_separation": None if p is None else list(p.within),
            "far_apart": None if p is None else p.far,
            "far_apart_stderr": None if p is None else p.far_stderr,
            "far_apart_separation": None if p is None else list(p.far_within),
            "drift": None if p is None else p.drift,
            "quantisation": self.quantisation,
            "load": None if self.load is None else self.load.to_dict(),
            "sentence": self.sentence(),
        }


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
    eligible = np.arange(r.size) if rows is None else np.flatnonzero(np.asarray(rows, bool)[NEIGHBOUR_LAGS:])
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
    code = np.unique(np.minimum(a_rows, b_rows) * np.int64(r.size) + np.maximum(a_rows, b_rows))  # each pair once
    if code.size < MIN_NEIGHBOUR_PAIRS:
        return None
    a_rows, b_rows = code // r.size, code % r.size
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
    diff = diff - full @ slope
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
        read = {k: v for k, v in by.items() if v is not None}
        load = strata.profile("neighbours", {k: v[0] for k, v in read.items()})
        if load is not None:
            value = load.value
            w = np.asarray(load.share) / sum(load.share)
            terms = [wk * v[0] * v[1] for wk, (_, v) in zip(w, sorted(read.items()), strict=True)]
            error = math.sqrt(sum(x * x for x in terms)) / value if value > 0 else 0.0
    if not value > 0:
        return None
    far_within = (float(sep[far].min()), float(sep[far].max()))
    return Neighbours(value, int(used.size), within, far_raw[0], far_within, error, far_raw[1], near_raw[0], load)


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


def estimate(
    signals: Signals,
    torque: Array,
    residual: Array,
    pieces: list[tuple[int, int]] | None = None,
    rows: NDArray[np.bool_] | None = None,
) -> NoiseFloor:
    """The noise floor of a fit's residual on a log (module docstring).

    Args:
        signals: The log's input channels.
        torque: The measured torque [N m] (for its quantisation).
        residual: Measured minus model torque [N m].
        pieces: The still pieces (:func:`still_segments`), when already found.
        rows: Rows the neighbour estimate may pair (None: all); the diagnosis leaves out blocks far worse than the
            typical one.
    """
    r = np.asarray(residual, float)
    # noise that changes with the load: each estimate read in strata of |current| too, and their root mean square over
    # the rows taken when they differ (what a cross-validated RMSE is compared with, not the typical row's noise)
    strata = Strata.of(signals.current) if signals.timed else None
    white = white_floor(r)
    profiles: dict[str, LoadProfile] = {}
    q = resolution(np.asarray(torque, float)) / math.sqrt(12.0)
    # the rounding counts only where it shows in the residual (a model that matches values on the grid exactly has none)
    spread = float(np.std(r)) if r.size else 0.0
    visible = q if spread >= QUANTISATION_SHOWS * q else 0.0
    by_stratum = {} if strata is None else white_by_stratum(r, strata, np.asarray(torque, float) - r)
    # where the rounding is what second differences read (a reading exactly on the grid at rest, rounded under load),
    # the strata would tell rounding from rounding: not read
    if by_stratum and max(by_stratum.values()) <= ROUNDING_DOMINATES * visible:
        by_stratum = {}
    white_load = None if strata is None else strata.profile("sample-to-sample", by_stratum)
    tolerances = Tolerances.of(signals) if signals.timed else None
    if pieces is None:
        pieces = still_segments(signals, tolerances)
    found = still_scatter(r, pieces)
    still, still_rows = (None, 0) if found is None else found
    if still is not None and strata is not None:
        still_load = strata.profile("still", still_by_stratum(r, pieces, strata))
        if still_load is not None:
            still, profiles["still"] = still_load.value, still_load
    paired = neighbour_scatter(signals, r, rows, tolerances, strata)
    agnostic = [v for v in (still, None if paired is None else paired.value) if v is not None]
    if white_load is not None:
        # second differences read noise of any colour low: read in strata above every estimate that is blind to the
        # noise's colour, they carry the model's error, and the log's own second differences stand
        ceiling = max([white, *agnostic]) if agnostic else math.inf
        if white_load.value <= ceiling:
            white, profiles["sample-to-sample"] = white_load.value, white_load
    candidates = [("sample-to-sample", white if math.isfinite(white) else 0.0), ("quantisation", visible)]
    if still is not None:
        candidates.append(("still", still))
    if paired is not None:
        candidates.append(("neighbours", paired.value))
        if paired.load is not None:
            profiles["neighbours"] = paired.load
    method, value = max(candidates, key=lambda mv: mv[1])
    if not value > 0:
        value, method = (white if not math.isfinite(white) else 0.0), "sample-to-sample"
    return NoiseFloor(
        value,
        method,
        white,
        still,
        still_rows,
        len(pieces) if still is not None else 0,
        q,
        paired,
        signals.timed,
        profiles.get(method),
    )


__all__ = [
    "CHUNK_ROWS",
    "LoadProfile",
    "Strata",
    "MIN_STILL_ROWS",
    "Neighbours",
    "NoiseFloor",
    "SETTLE_ROWS",
    "estimate",
    "still_by_stratum",
    "white_by_stratum",
    "neighbour_scatter",
    "resolution",
    "still_scatter",
    "still_segments",
    "white_floor",
]
