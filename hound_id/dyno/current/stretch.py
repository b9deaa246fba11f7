"""What a stretch of a dyno log is, read from its channels: which part of a log the headline fit should use.

When blocks of a log disagree (:mod:`hound_id.dyno.current.diagnose`), the headline fit is the longest stretch
that agrees and exercises the current (:func:`candidates`), and every stretch left out is named from what its
channels do (:func:`read`), never guessed:

* **replies frozen**: the current (and the speed, when logged) repeat one value while the torque moves: the drive
  stopped answering and its last reply repeats;
* **current frozen**: the current repeats one value while the torque moves;
* **motor off**: the current sits at zero: nothing there shows torque per amp;
* **torque saturated**: the torque channel sits at its extreme while the current moves: the transducer or its ADC
  is at the end of its range;
* **step transient**: most of the stretch's error lies within a few samples after current steps: the transducer and
  the coupling ring or lag after a step;
* **torque ignores the current**: the current moves and the torque does not follow it (a current reading that
  runs away, a drive that does not drive the motor);
* otherwise **another regime**: the channels look ordinary there, and the torque follows another law (an effect
  acting only there, or a changed set-up).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hound_id.dyno.artefacts import noise_sigma
from hound_id.dyno.current.effects import Signals

Array = NDArray[np.float64]

#: A channel is frozen over a stretch when at least this share of its steps there are exactly zero (a repeated
#: reply), and the model of the repeated current misses the torque there by more than FROZEN_TORQUE_SIGMAS of its
#: noise (RMS): a held zero of a pulse test, which the model explains, is no frozen reply. Calibrated on
#: test_stretch::test_each_kind_of_stretch_is_read_from_its_channels.
FROZEN_SHARE = 0.8
FROZEN_TORQUE_SIGMAS = 4.0
#: The motor is off over a stretch when the current stays within this share of the log's largest current (or 4x its
#: noise) on at least OFF_SHARE of the rows. Calibrated on
#: test_stretch::test_each_kind_of_stretch_is_read_from_its_channels.
OFF_CURRENT = 0.03
OFF_SHARE = 0.9
#: The torque is saturated when at least this share of a stretch's rows sit within SATURATED_BAND of the log's torque
#: span from its extreme. Calibrated on test_stretch::test_each_kind_of_stretch_is_read_from_its_channels.
SATURATED_SHARE = 0.3
SATURATED_BAND = 0.005
#: Kinds of stretch that show no torque per amp (leaving them out of a fit loses nothing).
UNINFORMATIVE = ("replies frozen", "current frozen", "motor off")
#: Kinds of stretch whose channels show a fault of the log (not of the model): the headline leaves them out first. A
#: motor switched off, a step transient or another regime may be what a missing effect looks like: the headline leaves
#: them out only after, and the whole log's fit beside it keeps them.
FAULTS = ("replies frozen", "current frozen", "torque saturated", "torque ignores the current")
#: A step is a change of current by this share of its span between two samples; the rows up to STEP_ROWS after it
#: are its transient, which must hold TRANSIENT_SHARE of the stretch's squared error. Calibrated on
#: test_stretch::test_each_kind_of_stretch_is_read_from_its_channels.
STEP_SHARE = 0.2
STEP_ROWS = 5
TRANSIENT_SHARE = 0.5
#: The torque ignores the current over a stretch where the current moves by more than IGNORES_SPAN of its span and
#: the torque follows it by less than IGNORES_SHARE of the fitted Kt. Calibrated on
#: test_polled_rig::test_a_log_that_breaks_midway_is_flagged_with_its_times.
IGNORES_SPAN = 0.05
IGNORES_SHARE = 0.5
#: A stretch exercises the current when its current spans this share of the log's span: enough to show torque per
#: amp on its own. Calibrated on test_stretch::test_candidates_vary_the_current_and_are_longest_first.
VARIES_SHARE = 0.25


@dataclass(frozen=True)
class Stretch:
    """A stretch of rows and what it is."""

    start: int
    """First row."""
    stop: int
    """One past the last row."""
    kind: str
    """``replies frozen``, ``current frozen``, ``motor off``, ``torque saturated``, ``step transient`` or
    ``another regime``."""
    reading: str
    """What the channels show there, in one clause."""

    def to_dict(self, signals: Signals) -> dict[str, object]:
        out: dict[str, object] = {"rows": [self.start, self.stop - 1], "kind": self.kind, "reading": self.reading}
        if signals.timed:
            out["time"] = [float(signals.time[self.start]), float(signals.time[self.stop - 1])]
        return out


def _repeats(x: Array) -> bool:
    """Whether a channel repeats its value on half as many steps as a frozen one does (it has no noise to speak of)."""
    d = np.diff(x)
    return bool(d.size > 0 and np.mean(d == 0) >= FROZEN_SHARE / 2)


def _frozen(x: Array) -> bool:
    d = np.diff(x)
    return bool(d.size > 0 and np.mean(d == 0) >= FROZEN_SHARE)


def read(signals: Signals, torque: Array, residual: Array, start: int, stop: int, kt: float | None = None) -> Stretch:
    """What rows ``start:stop`` of a log are (module docstring); ``kt`` [N m/A] is the fit's, to tell a torque that
    ignores the current."""
    i = signals.current
    rows = slice(start, stop)
    y = np.asarray(torque, float)
    # frozen: the current repeats and the model of it misses the torque there (a held pulse-test zero does not)
    repeats = np.concatenate(([False], np.diff(i[rows]) == 0))
    r_rows = np.asarray(residual, float)[rows]
    missed = bool(repeats.any()) and float(np.sqrt(np.mean(r_rows[repeats] ** 2))) > FROZEN_TORQUE_SIGMAS * max(
        noise_sigma(y), 1e-300
    )
    # ... in a channel that does not repeat elsewhere (a noise-free channel, a simulation, repeats at every hold)
    elsewhere = np.concatenate((i[:start], i[stop:]))
    if _frozen(i[rows]) and missed and not _repeats(elsewhere):
        level = float(np.median(i[rows]))
        if signals.velocity is not None and _frozen(signals.velocity[rows]):
            return Stretch(
                start,
                stop,
                "replies frozen",
                f"the current and the speed repeat one value ({level:.4g} A) while the torque moves: the drive "
                "stopped answering and its last reply repeats",
            )
        return Stretch(
            start, stop, "current frozen", f"the current repeats one value ({level:.4g} A) while the torque moves"
        )
    small = max(OFF_CURRENT * float(np.max(np.abs(i))), 4.0 * noise_sigma(i))
    if np.mean(np.abs(i[rows]) <= small) >= OFF_SHARE:
        return Stretch(
            start,
            stop,
            "motor off",
            f"the current stays within {small:.2g} A of zero: nothing there shows torque per amp",
        )
    lo, hi = float(np.min(y)), float(np.max(y))
    band = SATURATED_BAND * max(hi - lo, 1e-300)
    for end, word in ((hi, "top"), (lo, "bottom")):
        if np.mean(np.abs(y[rows] - end) <= band) >= SATURATED_SHARE:
            return Stretch(
                start,
                stop,
                "torque saturated",
                f"the torque sits at the {word} of its range ({end:.4g} N m) while the current moves: the transducer "
                "or its ADC is at the end of its range",
            )
    r = np.asarray(residual, float)[rows]
    steps = np.flatnonzero(np.abs(np.diff(i[rows])) > STEP_SHARE * max(float(np.ptp(i)), 1e-300)) + 1
    if steps.size and r @ r > 0:
        near = np.zeros(r.size, dtype=bool)
        for s in steps:
            near[s : s + STEP_ROWS] = True
        share = float(r[near] @ r[near] / (r @ r))
        if share >= TRANSIENT_SHARE:
            peak = float(np.max(np.abs(r[near])))
            return Stretch(
                start,
                stop,
                "step transient",
                f"{share:.0%} of the error lies within {STEP_ROWS} samples after {steps.size} current step(s) (up "
                f"to {peak:.3g} N m): the transducer and the coupling ring or lag after a step",
            )
    if kt is not None and kt > 0 and float(np.ptp(i[rows])) > IGNORES_SPAN * float(np.ptp(i)):
        slope = float(np.polyfit(i[rows], y[rows], 1)[0])
        if slope < IGNORES_SHARE * kt:
            return Stretch(
                start,
                stop,
                "torque ignores the current",
                f"the current moves by {float(np.ptp(i[rows])):.3g} A and the torque follows it by {slope:.3g} N m/A, "
                f"against Kt = {kt:.4g} N m/A elsewhere: the current reading runs away, or the drive does not drive "
                "the motor there",
            )
    return Stretch(
        start,
        stop,
        "another regime",
        "the channels look ordinary there and the torque follows another law (an effect acting only there, or a "
        "changed set-up)",
    )


def varies(signals: Signals, start: int, stop: int) -> bool:
    """Whether rows ``start:stop`` exercise the current enough to show torque per amp on their own."""
    i = signals.current
    return bool(float(np.ptp(i[start:stop])) >= VARIES_SHARE * float(np.ptp(i)) and not _frozen(i[start:stop]))


def runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """(start, stop) of the runs of True in a boolean array."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.astype(np.int8), [0]))))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def candidates(
    signals: Signals, edges: NDArray[np.intp], disagreeing: NDArray[np.bool_], min_rows: int
) -> list[tuple[int, int]]:
    """Row ranges the headline may be fitted to, best first.

    The runs of agreeing blocks (less a block either side of a disagreeing run, where the change may begin; then
    whole) come first, then the disagreeing runs (on a log whose majority is a motor switched off, the part where it
    runs is the minority); within each, the longest first. Only runs that exercise the current (:func:`varies`) and hold
    ``min_rows`` rows count.
    """
    bad = np.asarray(disagreeing, bool)
    margin = ~bad & ~np.concatenate(([False], bad[:-1])) & ~np.concatenate((bad[1:], [False]))
    out: list[tuple[int, int]] = []
    for mask in (margin, ~bad, bad):
        found = [(int(edges[a]), int(edges[b])) for a, b in runs(mask)]
        found.sort(key=lambda ab: ab[0] - ab[1])
        out += [(a, b) for a, b in found if b - a >= min_rows and varies(signals, a, b) and (a, b) not in out]
    return out


__all__ = ["FAULTS", "UNINFORMATIVE", "Stretch", "candidates", "read", "runs", "varies"]
