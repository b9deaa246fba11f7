"""The noise floor of a dyno log: the torque error no model of the logged channels can remove.

Two estimates, and the floor says which it used:

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

The floor is the larger of the two when the log has enough still rows, and never below the torque channel's
quantisation q / sqrt(12) (a rounded channel cannot be matched closer).
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


@dataclass(frozen=True)
class NoiseFloor:
    """The noise floor of a log and how it was found [N m]."""

    value: float
    """The floor the verdicts use [N m]."""
    method: str
    """``still``, ``sample-to-sample`` or ``quantisation``: which estimate set the value."""
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
    timed: bool = True
    """False for a steady-state table (no still stretches there: its rows are operating points)."""

    @property
    def correlation(self) -> float | None:
        """still / sample-to-sample: about 1 for white noise, larger when the noise is correlated or filtered."""
        if self.still is None or not self.white > 0:
            return None
        return self.still / self.white

    def sentence(self) -> str:
        """How the floor was found, in one sentence."""
        if self.method == "quantisation":
            return (
                f"noise floor {self.value:.3g} N m: the torque channel's rounding (q / sqrt(12)), above the "
                f"sample-to-sample noise ({self.white:.3g} N m)"
            )
        if self.still is None and not self.timed:
            return (
                f"noise floor {self.value:.3g} N m from differences between neighbouring operating points of the table"
            )
        if self.still is None:
            return (
                f"noise floor {self.value:.3g} N m from sample-to-sample differences (the log has fewer than "
                f"{MIN_STILL_ROWS} rows in stretches of {MIN_PIECE_ROWS + SETTLE_ROWS} samples or more where current "
                "and speed hold still); it reads low if the transducer filters its noise: hold the current and speed "
                "still now and then to measure it"
            )
        ratio = self.correlation
        head = (
            f"noise floor {self.value:.3g} N m: the torque's scatter where the inputs hold still ({self.still_rows} "
            f"rows in {self.still_pieces} pieces) is {self.still:.3g} N m"
        )
        if ratio is not None and ratio > 1.2:
            return (
                f"{head}, {ratio:.2g}x its sample-to-sample noise ({self.white:.3g} N m): the noise is correlated "
                "(a filtered transducer, a vibration, or a ripple from a channel the log lacks)"
            )
        return f"{head}; sample-to-sample {self.white:.3g} N m"

    def to_dict(self) -> dict[str, object]:
        return {
            "floor": self.value,
            "method": self.method,
            "sample_to_sample": None if math.isnan(self.white) else self.white,
            "still": self.still,
            "still_rows": self.still_rows,
            "still_pieces": self.still_pieces,
            "quantisation": self.quantisation,
            "sentence": self.sentence(),
        }


def white_floor(residual: Array) -> float:
    """Standard deviation of white measurement noise in a residual series [N m] (module docstring)."""
    r = np.asarray(residual, float)
    if r.size < MIN_FLOOR_ROWS:
        return float("nan")
    d2 = r[2:] - 2.0 * r[1:-1] + r[:-2]
    return float(MAD_TO_SIGMA * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


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


def _tolerance(x: Array, floor: float = 0.0) -> float:
    """How far a channel may move and still hold still: its own noise, its quantum, or a share of its range."""
    return max(STILL_SIGMAS * noise_sigma(x), 2.0 * quantum(x), floor)


def still_segments(signals: Signals) -> list[tuple[int, int]]:
    """(start, stop) row ranges where every input channel holds still, settling rows left out, cut into pieces.

    A row continues a stretch while no channel steps by more than twice its tolerance from the row before; a piece
    of a stretch counts when no channel spans more than twice its tolerance over it (a slow ramp passes the first test
    and fails the second). A steady-state table (no sample times) has none: its rows are operating points.
    """
    n = signals.current.size
    if not signals.timed or n < SETTLE_ROWS + MIN_PIECE_ROWS:
        return []
    channels = [(signals.current, _tolerance(signals.current, STILL_SHARE * float(np.ptp(signals.current))))]
    if signals.velocity is not None:
        channels.append((signals.velocity, _tolerance(signals.velocity, STILL_SHARE * float(np.ptp(signals.velocity)))))
    if signals.position is not None:  # cogging is never noise on a log that can show it
        channels.append((signals.position, _tolerance(signals.position, STILL_ANGLE / 2)))
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


def still_scatter(residual: Array, pieces: list[tuple[int, int]]) -> tuple[float, int] | None:
    """Pooled standard deviation of the residual about each piece's mean [N m] and the rows used; None below
    :data:`MIN_STILL_ROWS` rows."""
    if not pieces:
        return None
    r = np.asarray(residual, float)
    dev = np.concatenate([r[a:b] - r[a:b].mean() for a, b in pieces])
    if dev.size < MIN_STILL_ROWS:
        return None
    robust = MAD_TO_SIGMA * float(np.median(np.abs(dev)))
    keep = np.abs(dev) <= TRIM_SIGMAS * robust if robust > 0 else np.ones(dev.size, dtype=bool)
    dof = int(keep.sum()) - len(pieces)
    if dof <= 0:
        return None
    return math.sqrt(float(dev[keep] @ dev[keep]) / dof), int(keep.sum())


def estimate(
    signals: Signals, torque: Array, residual: Array, pieces: list[tuple[int, int]] | None = None
) -> NoiseFloor:
    """The noise floor of a fit's residual on a log (module docstring).

    Args:
        signals: The log's input channels.
        torque: The measured torque [N m] (for its quantisation).
        residual: Measured minus model torque [N m].
        pieces: The still pieces (:func:`still_segments`), when already found.
    """
    white = white_floor(residual)
    q = resolution(np.asarray(torque, float)) / math.sqrt(12.0)
    if pieces is None:
        pieces = still_segments(signals)
    found = still_scatter(residual, pieces)
    # the rounding counts only where it shows in the residual (a model that matches values on the grid exactly has none)
    r = np.asarray(residual, float)
    spread = float(np.std(r)) if r.size else 0.0
    visible = q if spread >= QUANTISATION_SHOWS * q else 0.0
    candidates = [("sample-to-sample", white if math.isfinite(white) else 0.0), ("quantisation", visible)]
    still, rows = (None, 0) if found is None else found
    if still is not None:
        candidates.append(("still", still))
    method, value = max(candidates, key=lambda mv: mv[1])
    if not value > 0:
        value, method = (white if not math.isfinite(white) else 0.0), "sample-to-sample"
    return NoiseFloor(value, method, white, still, rows, len(pieces) if still is not None else 0, q, signals.timed)


__all__ = [
    "CHUNK_ROWS",
    "MIN_STILL_ROWS",
    "NoiseFloor",
    "SETTLE_ROWS",
    "estimate",
    "resolution",
    "still_scatter",
    "still_segments",
    "white_floor",
]
