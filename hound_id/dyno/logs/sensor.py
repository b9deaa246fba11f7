"""The sensor artefacts of a dyno log's current and torque channels, found and undone: single-sample glitches
(Hampel-type), wrap-around, clamped replies and driver limits, ADC clipping; each writes its :class:`CleaningNote`."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from hound_id.dyno.artefacts import (
    Plateau,
    asked_at_boundary,
    at_boundary,
    find_plateaus,
    find_wraps,
    flipped_at_boundary,
    quantum,
)
from hound_id.dyno.logs.columns import CleaningNote, keep_rows, plural, row_list, unit_label

if TYPE_CHECKING:  # pragma: no cover
    pass


#: Channels checked for glitches.
SENSOR_CHANNELS: tuple[str, ...] = ("current", "torque")
#: Glitches (a Hampel filter): a centred window of seven samples, whose median outvotes a run of up to three; a
#: threshold of 8 noise standard deviations (no Gaussian sample of a million-row log gets there), floored at this share
#: of the channel's 99th-percentile magnitude (for nearly noise-free channels); runs of at most two flagged samples are
#: glitches, a longer run is a real step (a staircase of steps of four samples or more loses no row). Calibrated on
#: test_logs::test_a_165_amp_spike_in_a_13_amp_test_is_removed_and_reported,
#: test_logs::test_a_torque_glitch_and_a_two_sample_glitch_are_removed,
#: test_logs::test_a_three_sample_pulse_is_a_real_step_not_a_glitch,
#: test_logs::test_no_staircase_with_steps_of_four_samples_or_more_loses_a_row,
#: test_logs::test_a_spike_anywhere_is_removed_and_nothing_else and (the floor: the polled rig's coarse reply)
#: test_polled_rig::test_a_clean_polled_log_recovers_the_truth_and_names_the_late_current.
GLITCH_WINDOW = 7
GLITCH_SIGMAS = 8.0
GLITCH_FLOOR = 0.05
GLITCH_MAX_RUN = 2
#: Gaussian consistency constant of the median absolute deviation.
MAD_TO_SIGMA = 1.4826
#: ADC saturation of the torque: a noisy channel stuck exactly at its extreme for at least this many samples (longer
#: than any glitch, GLITCH_MAX_RUN), looked for only where the noise exceeds this many quanta of the channel (with
#: fewer, a coarse channel repeats values exactly wherever it is flat), on at least this share of the rows (one in a
#: thousand), at a level of at least this share of the channel's largest |value| (an idle stretch at exactly 0 is not
#: ADC saturation). Calibrated on test_logs::test_a_clipped_torque_channel_loses_its_clipped_rows,
#: test_logs::test_a_noisy_torque_clipped_during_flat_current_steps_is_caught and
#: test_logs::test_an_idle_stretch_at_exactly_zero_is_not_clipping.
CLIP_MIN_RUN = 5
CLIP_QUANTA = 3.0
CLIP_MIN_FRACTION = 0.001
CLIP_MIN_LEVEL = 0.5


def _runs(index: NDArray[np.intp]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Starts (positions in ``index``) and lengths of the runs of consecutive integers in sorted ``index``."""
    if index.size == 0:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty
    breaks = np.flatnonzero(np.diff(index) != 1) + 1
    starts = np.concatenate(([0], breaks))
    lengths = np.diff(np.concatenate((starts, [index.size])))
    return starts, lengths


def _noise_sigma(diffs: NDArray[np.float64]) -> float:
    """Noise standard deviation of a channel from its first differences, robustly; ``diffs`` is overwritten.

    1.4826 MAD makes the median absolute deviation a standard deviation for Gaussian noise, and the difference
    of two samples has sqrt(2) times the noise of one. Steps and glitches barely move the median.
    """
    if diffs.size == 0:
        return 0.0
    centre = float(np.median(diffs, overwrite_input=True))  # reorders diffs, which the MAD does not mind
    np.abs(np.subtract(diffs, centre, out=diffs), out=diffs)
    return MAD_TO_SIGMA * float(np.median(diffs, overwrite_input=True)) / math.sqrt(2.0)


def _glitches(x: NDArray[np.float64]) -> tuple[NDArray[np.intp], NDArray[np.float64], float, float]:
    """Isolated Hampel outliers of ``x``: their indices, their local medians, the threshold and the noise sigma."""
    n = x.size
    half = GLITCH_WINDOW // 2
    if n < GLITCH_WINDOW:
        return np.zeros(0, dtype=np.intp), np.zeros(0), 0.0, _noise_sigma(np.diff(x))
    padded = np.pad(x, half, mode="reflect")
    steps = np.diff(padded)  # steps[i + half - 1] = x[i] - x[i - 1]
    sigma = _noise_sigma(steps[half : half + n - 1].copy())
    none = np.zeros(0, dtype=np.intp), np.zeros(0), 0.0, sigma
    floor = GLITCH_FLOOR * float(np.percentile(np.abs(x), 99, overwrite_input=True))
    threshold = max(GLITCH_SIGMAS * sigma, floor)
    if not threshold > 0:
        return none
    none = np.zeros(0, dtype=np.intp), np.zeros(0), threshold, sigma
    # Exact, without a rolling median over all samples: if x[i] is more than the threshold away from its window
    # median, at least half + 1 of its 2 * half neighbours are more than the threshold away from it. So at most
    # half - 1 are not, and among any `half` neighbours one is. Only samples passing that cheap test (few: the
    # glitches and the step edges) get their median computed. Here the neighbours are i - 1, i + 1, i + 2, ...
    far = np.abs(steps, out=steps) > threshold
    candidate = far[half - 1 : half - 1 + n] | far[half : half + n]
    gap = np.empty(n)
    for k in range(2, half + 1):
        np.subtract(padded[half + k : half + k + n], x, out=gap)
        candidate |= np.abs(gap, out=gap) > threshold
    candidates = np.flatnonzero(candidate)
    if candidates.size == 0:
        return none
    windows = np.lib.stride_tricks.sliding_window_view(padded, GLITCH_WINDOW)[candidates]
    medians = np.median(windows, axis=1)
    hit = np.abs(x[candidates] - medians) > threshold
    index, medians = candidates[hit], medians[hit]
    found: list[int] = []
    found_medians: list[float] = []
    starts, lengths = _runs(index)
    for start, length in zip(starts, lengths, strict=True):
        run = index[start : start + length]
        picked = _isolate(padded, half, run, threshold)
        found.extend(picked)
        found_medians.extend(float(np.median(padded[i : i + GLITCH_WINDOW])) for i in picked)
    # neighbouring runs share samples of their windows: each sample once
    unique, first = np.unique(np.asarray(found, dtype=np.intp), return_index=True)
    return unique, np.asarray(found_medians)[first], threshold, sigma


def _isolate(padded: NDArray[np.float64], half: int, run: NDArray[np.intp], threshold: float) -> list[int]:
    """The glitch samples of a run of Hampel hits, or none if the run is a real step.

    A large spike also drags its neighbours' window medians, so they are flagged too and
    the run looks longer than the spike. Take out the worst sample (set it to its window
    median) and test the neighbourhood again, at most GLITCH_MAX_RUN times: if the hits
    are then gone, the samples taken out were glitches; if not, the run is a real step.
    """
    n = padded.size - 2 * half
    first, last = max(int(run[0]) - half, 0), min(int(run[-1]) + half, n - 1)
    # a local copy: sample i of x sits at work[i - first + half]; its window is work[i - first : i - first + 2h + 1]
    work = padded[first : last + 2 * half + 1].copy()
    region = np.arange(first, last + 1)

    def deviation(i: int) -> float:
        j = i - first
        return float(abs(work[j + half] - np.median(work[j : j + 2 * half + 1])))

    picked: list[int] = []
    while True:
        current = [int(i) for i in region if deviation(int(i)) > threshold]
        if not current:
            return sorted(picked)
        if len(picked) == GLITCH_MAX_RUN:
            return []
        worst = max(current, key=deviation)
        j = worst - first
        work[j + half] = np.median(work[j : j + 2 * half + 1])
        picked.append(worst)


def _deviation(x: NDArray[np.float64], index: NDArray[np.intp]) -> NDArray[np.float64]:
    """|x - its centred window median| at ``index`` (window GLITCH_WINDOW, reflected at the ends)."""
    half = GLITCH_WINDOW // 2
    if x.size < GLITCH_WINDOW or index.size == 0:
        return np.zeros(index.size)
    padded = np.pad(x, half, mode="reflect")
    windows = np.lib.stride_tricks.sliding_window_view(padded, GLITCH_WINDOW)[index]
    return np.abs(x[index] - np.median(windows, axis=1))  # type: ignore[no-any-return]


def remove_glitches(
    data: dict[str, NDArray[np.float64]], rows: NDArray[np.int64], notes: list[CleaningNote]
) -> tuple[dict[str, NDArray[np.float64]], NDArray[np.int64], dict[str, float]]:
    """Remove the glitches of :data:`SENSOR_CHANNELS`; also returns each channel's noise sigma.

    A glitch is a spike in one channel. Where the other channel moves too, within one sample
    either side (a reply read one loop late), the transient is real and kept.
    """
    keep = np.ones(rows.size, dtype=bool)
    noise: dict[str, float] = {}
    found = {name: _glitches(data[name]) for name in SENSOR_CHANNELS}
    for name in SENSOR_CHANNELS:
        noise[name] = found[name][3]
    for name in SENSOR_CHANNELS:
        x = data[name]
        index, medians, threshold, _ = found[name]
        if index.size == 0:
            continue
        (other,) = [c for c in SENSOR_CHANNELS if c != name]
        partner_threshold = found[other][2] / 2.0
        if partner_threshold > 0:
            near = np.clip(index[:, None] + np.arange(-1, 2)[None, :], 0, x.size - 1)
            moved = _deviation(data[other], near.ravel()).reshape(near.shape).max(axis=1) > partner_threshold
            index, medians = index[~moved], medians[~moved]
        if index.size == 0:
            continue
        keep[index] = False
        u = unit_label(name)
        worst = int(np.argmax(np.abs(x[index] - medians)))
        at, value, median = int(rows[index[worst]]), x[index[worst]], medians[worst]
        if index.size == 1:
            message = (
                f"removed 1 single-sample glitch in '{name}' ({value:.4g} {u} against a local median of "
                f"{median:.4g} {u}) at row {at}"
            )
        else:
            message = (
                f"removed {index.size} glitch samples in '{name}' (runs of at most {GLITCH_MAX_RUN} samples "
                f"deviating more than {threshold:.3g} {u} from the local median; largest {value:.4g} {u} against "
                f"{median:.4g} {u} at row {at}) at rows {row_list(rows[index])}"
            )
        notes.append(CleaningNote("glitch", int(index.size), message, name))
    return (*keep_rows(data, rows, keep), noise)


def undo_wraps(
    data: dict[str, NDArray[np.float64]],
    rows: NDArray[np.int64],
    command: NDArray[np.float64] | None,
    notes: list[CleaningNote],
    ranges: list[float] | None = None,
) -> tuple[dict[str, NDArray[np.float64]], NDArray[np.int64]]:
    """Undo wrap-around of the current (:mod:`hound_id.dyno.artefacts`); the note says when the command asks past the
    range. The encoding range found (half the period) is appended to ``ranges``."""
    time = data["time"]
    unwrapped, wrap = find_wraps(data["current"], data["torque"])
    if wrap is None:
        return data, rows
    data = {**data, "current": unwrapped}
    half = wrap.period / 2.0
    if ranges is not None:
        ranges.append(half)
    head = (
        f"the current channel wraps around: {wrap.jumps} jumps of +-{wrap.period:.4g} A (an encoding range of "
        f"+-{half:.4g} A) that the torque does not share, first at row {int(rows[wrap.first])} "
        f"(t = {time[wrap.first]:.4g} s); "
    )
    if wrap.unwrapped:
        top = float(np.max(np.abs(unwrapped)))
        where = f"went past the range (to {top:.3g} A)" if top > 1.02 * half else "sat at the edge of the range"
        notes.append(
            CleaningNote(
                "wrap",
                0,
                f"{head}each row got back the whole periods that put it nearest torque / Kt (the torque does not "
                f"wrap) and every row was kept; the current {where}; a reply with a wider range avoids this",
                "current",
            )
        )
        return data, rows
    boundary = at_boundary(unwrapped, wrap)
    count = int(np.count_nonzero(boundary))
    asked = asked_at_boundary(unwrapped, None if command is None else command[rows - 1], boundary, half)
    capped = ""
    if asked is not None and asked > 1.05 * half:
        # the reply cannot say more than its range, whatever the driver gives: no driver limit is claimed
        capped = (
            f"; there the command asks for {asked:.3g} A (median, from the command-current relation elsewhere), "
            f"and the reply cannot say more than {half:.4g} A (its range; the driver may give more)"
        )
    notes.append(
        CleaningNote(
            "wrap",
            count,
            f"{head}folded back into +-{half:.4g} A, and the {plural(count, 'row')} at the boundary, where the sign "
            f"of the current cannot be known, were removed{capped}",
            "current",
        )
    )
    data, rows = keep_rows(data, rows, ~boundary)
    return data, rows


def current_plateaus(
    data: dict[str, NDArray[np.float64]],
    rows: NDArray[np.int64],
    command: NDArray[np.float64] | None,
    notes: list[CleaningNote],
    ranges: list[float] | None = None,
) -> tuple[dict[str, NDArray[np.float64]], NDArray[np.int64], float | None]:
    """Remove clamped rows and find a driver current limit (:mod:`hound_id.dyno.artefacts`); the level of a clamped
    reply is appended to ``ranges``."""
    current, torque = data["current"], data["torque"]
    limit: float | None = None
    cmd = None if command is None else command[rows - 1]
    keep = np.ones(rows.size, dtype=bool)
    plateaus = find_plateaus(current, torque, cmd, ranges[0] if ranges else None)
    for plateau in plateaus:
        if plateau.kind == "reply_clamp":
            exact = int(np.count_nonzero(current[plateau.rows] == plateau.level))
            if ranges is not None:
                ranges.append(abs(plateau.level))
            if not plateau.usable:
                keep[plateau.rows] = False
            notes.append(_reply_clamp_note(plateau, exact, ranges))
        elif plateau.kind == "clamp":
            keep[plateau.rows] = False
            if ranges is not None:
                ranges.append(abs(plateau.level))
            notes.append(_clamp_note(plateau))
        else:
            limit = max(limit or 0.0, abs(plateau.level))
            notes.append(_limit_note(plateau))
    ends = [abs(p.level) for p in plateaus if p.kind in ("clamp", "reply_clamp")]
    if ends:
        keep = _without_flipped(data, rows, min(ends), keep, notes)
    data, rows = keep_rows(data, rows, keep)
    return data, rows, limit


def _reply_clamp_note(plateau: Plateau, exact: int, ranges: list[float] | None) -> CleaningNote:
    """The note of a current reply held at the top of its range (its rows kept if the torque stays with it)."""
    lo, hi = plateau.torque_span
    count = int(plateau.rows.size)
    if plateau.asked is not None:
        why = (
            f"while the command asks for {plateau.asked:.3g} A (median there, from the command-current "
            "relation elsewhere in the log)"
        )
    elif plateau.at_range_end and ranges:
        why = f"at the end of the range its wrap-around shows (+-{ranges[0]:.4g} A)"
    else:
        why = "while it is noisy elsewhere (a pile at the top of the readings, none beyond)"
    head = (
        f"the current reply is held at {plateau.level:.4g} A, the top of its range, in {plural(count, 'row')} "
        f"({exact} on exactly that value) {why}: the reply's encoding range ends there (a protocol clamp), not "
        "the driver; "
    )
    beyond = "" if plateau.excess is None else f" ({100 * plateau.excess:+.2g} % of what the level makes)"
    if plateau.usable:
        tail = f"the torque there ({lo:.3g} to {hi:.3g} N m) stays with the level{beyond}, so the rows are data"
        tail += " and kept"
    else:
        tail = (
            f"the torque there ({lo:.3g} to {hi:.3g} N m) goes past what the level makes"
            f"{beyond or ' (no ramp to compare with)'}, so the current there is unknown and those rows were "
            "removed"
        )
    return CleaningNote(
        "reply_clamp",
        0 if plateau.usable else count,
        f"{head}{tail}; to test beyond {abs(plateau.level):.3g} A, widen the reply's current range or log "
        "the current from a sensor of its own",
        "current",
    )


def _clamp_note(plateau: Plateau) -> CleaningNote:
    """The note of a current clamped while the torque moves (its rows removed)."""
    lo, hi = plateau.torque_span
    count = int(plateau.rows.size)
    return CleaningNote(
        "clamp",
        count,
        f"the reported current is clamped at {plateau.level:.4g} A in {plural(count, 'row')} (the reply's "
        f"encoding range or a saturated ADC): it stays there while the torque keeps moving ({lo:.3g} to "
        f"{hi:.3g} N m), so the true current is unknown and those rows were removed",
        "current",
    )


def _limit_note(plateau: Plateau) -> CleaningNote:
    """The note of a driver current limit (its rows kept: they are data)."""
    lo, hi = plateau.torque_span
    count = int(plateau.rows.size)
    return CleaningNote(
        "current_limit",
        0,
        f"driver current limit at {plateau.level:.4g} A: the current holds there in "
        f"{plural(count, 'row')} while the command asks for {plateau.asked:.3g} A (median there, from the "
        f"command-current relation elsewhere in the log) and the torque stays at {lo:.3g} to {hi:.3g} N m; "
        f"the rows are data and kept, and a peak torque beyond {abs(plateau.level):.3g} A needs a higher "
        "driver limit",
        "current",
    )


def _without_flipped(
    data: dict[str, NDArray[np.float64]],
    rows: NDArray[np.int64],
    end: float,
    keep: NDArray[np.bool_],
    notes: list[CleaningNote],
) -> NDArray[np.bool_]:
    """``keep`` less the rows whose reply crossed the end of its range and came back from the other (noted)."""
    flipped = flipped_at_boundary(data["current"], data["torque"], end) & keep
    count = int(np.count_nonzero(flipped))
    if count:
        keep = keep & ~flipped
        first = int(np.argmax(flipped))
        notes.append(
            CleaningNote(
                "reply_flip",
                count,
                f"{plural(count, 'row')} read the current at the other end of the reply's range (+-{end:.4g} A) "
                f"from the torque, first at row {int(rows[first])} (t = {data['time'][first]:.4g} s): the reply "
                "crossed the end of its range and came back from the other, so its sign is wrong and its size "
                "unknown; those rows were removed",
                "current",
            )
        )
    return keep


def remove_clipping(
    data: dict[str, NDArray[np.float64]], rows: NDArray[np.int64], noise: dict[str, float], notes: list[CleaningNote]
) -> tuple[dict[str, NDArray[np.float64]], NDArray[np.int64]]:
    """Remove the rows where the torque is stuck at its extreme (the current: :func:`current_plateaus`).

    ``noise``: sigma of each channel.
    """
    keep = np.ones(rows.size, dtype=bool)
    for name in ("torque",):
        x = data[name]
        high, low = float(x.max()), float(x.min())
        if name not in noise:  # a steady-state table skips the glitch step that measures it
            noise[name] = _noise_sigma(np.diff(x))
        if high == low or not noise[name] > CLIP_QUANTA * quantum(x):
            # A channel without measurable noise (a logged set-point, a simulation), or with noise of a few
            # quanta (a coarse reply), repeats values exactly wherever it is flat; only a finely resolved, noisy
            # channel sitting exactly at one value betrays a clipped ADC.
            continue
        peak = max(abs(high), abs(low))
        for level in (high, low):
            if abs(level) < CLIP_MIN_LEVEL * peak:
                continue
            at = x == level
            count = int(np.count_nonzero(at))
            if count < CLIP_MIN_RUN or count < CLIP_MIN_FRACTION * x.size:
                continue
            index = np.flatnonzero(at)
            starts, lengths = _runs(index)
            if lengths.max() < CLIP_MIN_RUN:
                continue
            # The channel is noisy elsewhere (checked above), yet repeats exactly this value for whole runs: a
            # measured signal does not do that, a saturated ADC does. (A flat commanded step of a noise-free
            # channel, or a logged set-point, never gets here.)
            keep &= ~at
            u = unit_label(name)
            notes.append(
                CleaningNote(
                    "adc_saturation",
                    count,
                    f"{name} channel clipped at {level:.4g} {u} in {count} rows (ADC saturation: stuck exactly at "
                    f"its extreme for up to {int(lengths.max())} samples although it is noisy elsewhere, "
                    f"noise {noise[name]:.2g} {u}); those rows were removed",
                    name,
                )
            )
    return keep_rows(data, rows, keep)
