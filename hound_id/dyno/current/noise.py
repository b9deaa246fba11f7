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

The white and still readings are in :mod:`hound_id.dyno.current.still`, the neighbours' in
:mod:`hound_id.dyno.current.neighbours`; this module combines them (:func:`estimate`) and re-exports them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hound_id.dyno.current.effects import Signals
from hound_id.dyno.current.neighbours import MIN_NEIGHBOUR_PAIRS, NEIGHBOUR_GAP_S, Neighbours, neighbour_scatter
from hound_id.dyno.current.still import (
    CHUNK_ROWS,
    MIN_PIECE_ROWS,
    MIN_STILL_ROWS,
    SETTLE_ROWS,
    Array,
    LoadProfile,
    Strata,
    Tolerances,
    resolution,
    still_by_stratum,
    still_scatter,
    still_segments,
    white_by_stratum,
    white_floor,
)

#: The rounding sets the floor only where the residual's standard deviation reaches this share of q / sqrt(12).
#: Calibrated on test_noise::test_a_coarsely_rounded_torque_channel_sets_the_floor.
QUANTISATION_SHOWS = 0.3


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
