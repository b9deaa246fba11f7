"""Cleaning a dyno log's rows: non-finite rows, time order and repeats, stale channels, the time and current units,
values no instrument logs, the torque's sign; each step writes its :class:`CleaningNote` (the sensor artefacts are in
:mod:`hound_id.dyno.logs.sensor`)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from hound_id.dyno.artefacts import (
    LIVE_SHARE,
    align_stale,
    repeated_share,
    stale_hold,
)
from hound_id.dyno.logs.columns import CANONICAL, CORE, UNITS, CleaningNote, keep_rows, plural, row_list
from hound_id.errors import DynoDataError

if TYPE_CHECKING:  # pragma: no cover
    pass


#: Largest magnitude of each channel (SI) that any dynamometer can log; a value beyond is no measurement (an overflowed
#: register, a garbage row) and is read as missing. A channel whose typical value lies beyond is in another unit or is
#: the wrong column, and is refused.
BEYOND: dict[str, float] = {
    "current": 1e5,  # A
    "torque": 1e6,  # N m
    "velocity": 1e6,  # rad/s
    "position": 1e9,  # rad: an angle counted up over days of running
    "temperature": 1e4,  # degC
    "bus_voltage": 1e5,  # V
    "torque_cmd": 1e6,  # N m
    "current_cmd": 1e5,  # A
}


#: Fewest rows a cleaned log may have: ten operating points of a steady-state table, or a burst of ten samples, each a
#: block of their own (hound_id.dyno.current.stats.Blocks), the least that blocked cross-validation over ten folds can
#: hold out. Calibrated on test_logs::test_too_few_rows_are_refused and
#: test_logs::test_a_table_of_26_operating_points_and_a_burst_written_16_times_are_read.
MIN_ROWS = 10
#: An optional channel with non-finite values in at least this share of rows is dropped instead of its rows (5 %: a few
#: gaps cost a few rows, a channel that is often missing would cost the log). Calibrated on
#: test_logs::test_a_few_nans_in_an_optional_channel_drop_their_rows and
#: test_logs::test_many_nans_in_an_optional_channel_drop_the_channel_not_the_rows.
OPTIONAL_NAN_FRACTION = 0.05


#: Correlation of torque with current below which a negative slope means a reversed sensor: a clearly falling torque,
#: not a noisy or unloaded one (the fit's own slope checks judge those). Calibrated on
#: test_logs::test_a_reversed_torque_sensor_is_refused_with_the_fix and
#: test_logs::test_flip_torque_on_a_sensor_mounted_the_right_way_is_refused.
FLIP_CORRELATION = -0.5


def check_varies(core: dict[str, NDArray[np.float64]], source: str) -> None:
    """Refuse a torque channel that holds one value (to float precision) on every row.

    (A current held at one value is a test a rig can run; the fit says what it cannot identify.)
    """
    x = core["torque"]
    top = float(np.max(np.abs(x)))
    if float(np.ptp(x)) <= 1e-9 * top or top == 0.0:
        raise DynoDataError(
            f"{source}: the torque channel holds one value ({float(x[0]):.6g} N m) on every row; expected a torque "
            "that varies: the sensor is not connected or not read, or --columns maps the wrong column",
            channel="torque",
        )


def beyond_reason(
    data: dict[str, NDArray[np.float64]], found: Mapping[str, str], source: str, notes: list[CleaningNote]
) -> None:
    """Values beyond :data:`BEYOND` become NaN (noted); a channel typically beyond it is refused."""
    for name, values in list(data.items()):
        limit = BEYOND.get(name)
        if limit is None:
            continue
        with np.errstate(invalid="ignore"):
            beyond = np.isfinite(values) & (np.abs(values) > limit)  # inf and NaN are noted as such
        count = int(np.count_nonzero(beyond))
        if not count:
            continue
        unit = UNITS[name].replace("*", " ")
        finite = values[np.isfinite(values)]
        typical = float(np.median(np.abs(finite))) if finite.size else 0.0
        if typical > limit and finite.size and float(np.ptp(finite)) == 0.0:
            raise DynoDataError(
                f"{source}: the {name} channel holds one value ({float(finite[0]):.6g} {unit}) on every row, beyond "
                f"the {limit:g} {unit} any dyno logs: the sensor is not connected or not read, or --columns maps "
                "the wrong column",
                channel=name,
            )
        if typical > limit:
            raise DynoDataError(
                f"{source}: column '{found[name]}' ({name}): typical |value| {typical:.3g} {unit}, beyond the "
                f"{limit:g} {unit} any dyno logs; expected a {name} in its unit: give the unit in the header "
                f"('{name}[...]') or with --units {name}=..., or map the right column with --columns",
                channel=name,
            )
        rows = np.flatnonzero(beyond) + 1
        data[name] = np.where(beyond, np.nan, values)
        notes.append(
            CleaningNote(
                "nan_rows",
                0,
                f"read {plural(count, 'value')} of '{name}' beyond {limit:g} {unit} as missing (no dyno measures "
                f"that: an overflowed register or a garbage row) at rows {row_list(rows)}",
                name,
            )
        )


def check_enough(n: int, rows_read: int, notes: list[CleaningNote], source: str) -> None:
    if n >= MIN_ROWS:
        return
    removed = [f"{note.kind} {note.rows}" for note in notes if note.kind not in ("unit", "unsorted_time")]
    why = f" (removed: {', '.join(removed)})" if removed else ""
    raise DynoDataError(
        f"{source}: only {n} of {rows_read} rows are usable after cleaning{why}; expected at least {MIN_ROWS} rows; "
        "record a longer log or fix the rows reported",
        rows=n,
    )


def repeated_rows(
    data: dict[str, NDArray[np.float64]], found: Mapping[str, str], timed: bool, notes: list[CleaningNote]
) -> NDArray[np.bool_]:
    """Rows that repeat the row before in every column read (a logger that writes each sample several times): each
    sample counts once. Marked, with a note; an operating point measured twice has some column that differs."""
    names = [name for name in found if name in data]
    n = data[names[0]].size if names else 0
    same = np.zeros(n, dtype=bool)
    if n < 2:
        return same
    same[1:] = True
    for name in names:
        x = data[name]
        same[1:] &= (x[1:] == x[:-1]) | (np.isnan(x[1:]) & np.isnan(x[:-1]))
    count = int(same.sum())
    if count:
        # how many times the most repeated row was written
        starts = np.flatnonzero(~same)
        times = int(np.max(np.diff(np.concatenate((starts, [n])))))
        what = "sample" if timed else "row"
        notes.append(
            CleaningNote(
                "duplicate_rows",
                count,
                f"collapsed {plural(count, 'row')} that {'repeats' if count == 1 else 'repeat'} the row before in "
                f"every column (each {what} written up to {times} times): each counts once, at "
                f"{'row' if count == 1 else 'rows'} {row_list(np.flatnonzero(same) + 1)}",
            )
        )
    return same


def finite_rows(
    data: dict[str, NDArray[np.float64]], bad_cells: dict[str, tuple[int, str, int]], notes: list[CleaningNote]
) -> NDArray[np.bool_]:
    """The rows to keep; optional channels with too many non-finite values are deleted from ``data``."""

    def detail(name: str, count: int) -> str:
        text = f"'{name}': {count}"
        if name in bad_cells:
            n_bad, cell, row = bad_cells[name]
            text += f" ({n_bad} not a number, such as {cell} at row {row})"
        return text

    finite = {name: np.isfinite(values) for name, values in data.items()}
    good = np.logical_and.reduce([finite[name] for name in CORE])
    lost = int(good.size - np.count_nonzero(good))
    if lost:
        counts = [
            detail(name, int(finite[name].size - np.count_nonzero(finite[name])))
            for name in CORE
            if not finite[name].all()
        ]
        notes.append(
            CleaningNote(
                "nan_rows",
                lost,
                f"dropped {plural(lost, 'row')} with NaN or inf in a required channel ({'; '.join(counts)}) "
                f"at rows {row_list(np.flatnonzero(~good) + 1)}",
            )
        )
    n_left = int(np.count_nonzero(good))
    for name in CANONICAL:
        if name in CORE or name not in data:
            continue
        bad = good & ~finite[name]
        count = int(np.count_nonzero(bad))
        if not count:
            continue
        share = count / max(n_left, 1)
        if share < OPTIONAL_NAN_FRACTION:
            notes.append(
                CleaningNote(
                    "nan_rows",
                    count,
                    f"dropped {plural(count, 'row')} with NaN or inf in {detail(name, count)} "
                    f"({100 * share:.2g} % of rows, under {100 * OPTIONAL_NAN_FRACTION:g} %) "
                    f"at rows {row_list(np.flatnonzero(bad) + 1)}",
                    name,
                )
            )
            good &= finite[name]
        else:
            del data[name]
            notes.append(
                CleaningNote(
                    "nan_rows",
                    0,
                    f"dropped column '{name}': {100 * share:.3g} % of its values are NaN or inf "
                    f"({count} of {n_left}; more than {100 * OPTIONAL_NAN_FRACTION:g} %), so its rows were kept",
                    name,
                )
            )
    return good


#: Optional channels checked for staleness (temperature changes slowly by nature, and commands are held by design).
STALE_OPTIONAL = ("velocity", "position")


def align_stale_channels(
    channels: dict[str, NDArray[np.float64]],
    rows: NDArray[np.int64],
    log: Mapping[str, NDArray[np.float64]],
    notes: list[CleaningNote],
    names: Sequence[str] = ("current", "torque"),
    time: NDArray[np.float64] | None = None,
) -> dict[str, NDArray[np.float64]]:
    """Channels that update at a lower rate than the log, placed at their update instants (:mod:`.artefacts`), with a
    note each; the others unchanged. A channel is stale only while another channel of the log is live."""
    t = channels["time"] if time is None else time
    out = dict(channels)
    measured = [c for c in ("current", "torque", "velocity", "position") if c in log]
    for name in names:
        if name not in channels:
            continue
        hold = stale_hold(channels[name])
        if hold is None:
            continue
        live = [c for c in measured if c != name and repeated_share(log[c]) <= LIVE_SHARE]
        if not live:
            continue
        out[name] = align_stale(t, channels[name])
        dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
        rate = f" ({1.0 / (hold * dt):.3g} Hz in a {1.0 / dt:.3g} Hz log)" if dt > 0 else ""
        notes.append(
            CleaningNote(
                "stale",
                0,
                f"the {name} channel updates every {hold:.3g} samples on average{rate} while {live[0]} changes at "
                f"every sample: its held values were placed at their update instants and joined by straight lines "
                f"(it may still lag by up to one update; the 'delay' effect measures what remains)",
                name,
            )
        )
    return out


def clean_time(
    data: dict[str, NDArray[np.float64]], rows: NDArray[np.int64], notes: list[CleaningNote]
) -> tuple[dict[str, NDArray[np.float64]], NDArray[np.int64]]:
    t = data["time"]
    back = np.flatnonzero(t[1:] < t[:-1]) + 1
    if back.size:
        # A sample is out of order when an earlier row already had a later time.
        late = np.flatnonzero(t[1:] < np.maximum.accumulate(t)[:-1]) + 1
        first = int(back[0])
        order = np.argsort(t, kind="stable")
        data = {k: v[order] for k, v in data.items()}
        notes.append(
            CleaningNote(
                "unsorted_time",
                int(late.size),
                f"time goes backwards: {plural(int(late.size), 'row')} came after a later timestamp (first at row "
                f"{int(rows[first])}: {t[first]:.6g} s after {t[first - 1]:.6g} s); sorted the rows by time",
            )
        )
        rows = rows[order]
        t = data["time"]
    repeat = np.empty(t.size, dtype=bool)
    repeat[0] = False
    np.equal(t[1:], t[:-1], out=repeat[1:])
    count = int(np.count_nonzero(repeat))
    if count:
        first = int(np.flatnonzero(repeat)[0])
        notes.append(
            CleaningNote(
                "duplicate_time",
                count,
                f"dropped {plural(count, 'row')} repeating the previous timestamp, keeping the first of each "
                f"(first at row {int(rows[first])}, t = {t[first]:.6g} s; rows {row_list(rows[repeat])})",
            )
        )
        data, rows = keep_rows(data, rows, ~repeat)
    return data, rows


#: Sample rates a time column is expected to have [Hz]: a log outside them with no unit may be in ms or us (10 Hz to 10
#: kHz spans the dynamometers' logging rates). Calibrated on
#: test_polled_rig::test_time_in_ms_without_a_unit_is_a_warning_and_no_delay_is_fitted.
TIME_RATES = (10.0, 10_000.0)


#: A current column without a unit whose typical large value (99.9th percentile of |i|) is above CURRENT_SLIP_A while
#: the torque's is under CURRENT_SLIP_RATIO N m per amp of it is in mA: kiloamps that make a few N m are no motor (a
#: robot actuator's Kt is 0.02 to 2 N m/A; a 1 kA drive makes tens of N m or more). Calibrated on
#: test_bad_input_structures::test_a_current_in_ma_under_a_plain_header_is_named.
CURRENT_SLIP_A = 1000.0
CURRENT_SLIP_RATIO = 0.01


def check_current_unit(current: NDArray[np.float64], torque: NDArray[np.float64], source: str) -> None:
    """Refuse, naming mA, a current column without a unit that holds kiloamps for a few N m."""
    i = np.abs(current[np.isfinite(current)])
    tau = np.abs(torque[np.isfinite(torque)])
    if i.size < 10 or tau.size < 10:
        return
    i_big, tau_big = float(np.percentile(i, 99.9)), float(np.percentile(tau, 99.9))
    if i_big > CURRENT_SLIP_A and tau_big < CURRENT_SLIP_RATIO * i_big:
        raise DynoDataError(
            f"{source}: the current column has no unit and reaches {i_big:,.0f} A for torques up to {tau_big:.3g} N m "
            f"(about {tau_big / i_big:.2g} N m/A): no motor makes so little torque from kiloamps; it reads like mA "
            f"({i_big / 1e3:.3g} A, about {1e3 * tau_big / i_big:.2g} N m/A): pass --units current=mA or write "
            "'current[mA]' in the header (or --units current=A if it really is in amps)",
            channel="current",
        )


def check_time_unit(time: NDArray[np.float64], stated: bool, notes: list[CleaningNote]) -> None:
    """Warn when a time column without a unit looks like milliseconds or microseconds."""
    if stated:
        return
    t = time[np.isfinite(time)]
    if t.size < 20:
        return
    steps = np.diff(t)
    steps = steps[steps > 0]
    if steps.size == 0:
        return
    dt = float(np.median(steps))
    if dt * TIME_RATES[0] <= 1.0:
        return  # at least 10 Hz in seconds: plausible
    for unit, factor in (("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9)):
        if 1.0 / TIME_RATES[1] <= dt * factor <= 1.0 / TIME_RATES[0]:
            span = float(t.max() - t.min())
            notes.append(
                CleaningNote(
                    "time_unit",
                    0,
                    f"the time column has no unit and steps of {dt:.4g}: read as seconds this is a {1 / dt:.3g} Hz "
                    f"log lasting {span / 3600:.3g} h; if it is in {unit} ({1 / (dt * factor):.4g} Hz), pass "
                    f"--units time={unit} or write 'time[{unit}]' in the header",
                    "time",
                )
            )
            return


def orient_torque(
    current: NDArray[np.float64],
    torque: NDArray[np.float64],
    flip_torque: bool,
    notes: list[CleaningNote],
    source: str,
    auto_sign: bool = False,
) -> NDArray[np.float64]:
    if auto_sign:
        flip_torque = False
    if flip_torque:
        torque = -torque
    # Centred sums from raw dot products: no 1M-row temporaries; the cancellation is harmless for dyno magnitudes.
    n = current.size
    mean_i, mean_t = float(current.mean()), float(torque.mean())
    ii, tt = float(current @ current), float(torque @ torque)
    sxx, syy = ii - n * mean_i * mean_i, tt - n * mean_t * mean_t
    sxy = float(current @ torque) - n * mean_i * mean_t
    # A (nearly) constant channel has no slope: what is left of its sum of squares is rounding.
    sxx = sxx if sxx > 1e-9 * ii else 0.0
    syy = syy if syy > 1e-9 * tt else 0.0
    slope = sxy / sxx if sxx > 0 else 0.0
    if sxx > 0 and syy > 0 and slope < 0 and sxy / math.sqrt(sxx * syy) < FLIP_CORRELATION:
        correlation = sxy / math.sqrt(sxx * syy)
        if auto_sign:
            notes.append(
                CleaningNote(
                    "flipped_torque",
                    int(torque.size),
                    f"negated the torque: it falls as current rises (slope {slope:.3g} N m/A, correlation "
                    f"{correlation:.2f}), so this log's sensor is mounted the other way round (--auto-sign)",
                    "torque",
                )
            )
            return -torque
        if flip_torque:
            raise DynoDataError(
                f"{source}: torque falls as current rises after --flip-torque negated it (slope {slope:.3g} N m/A, "
                f"correlation {correlation:.2f}): the sensor is mounted the right way round; rerun without "
                "--flip-torque",
                slope=slope,
                correlation=correlation,
            )
        raise DynoDataError(
            f"{source}: torque falls as current rises (slope {slope:.3g} N m/A, correlation {correlation:.2f}): "
            "the torque sensor looks mounted reversed; rerun with --flip-torque",
            slope=slope,
            correlation=correlation,
        )
    if flip_torque:
        notes.append(
            CleaningNote(
                "flipped_torque",
                int(torque.size),
                f"negated the torque as asked by --flip-torque (slope now {slope:.3g} N m/A)",
                "torque",
            )
        )
    elif auto_sign:
        notes.append(
            CleaningNote(
                "format",
                0,
                f"kept the torque's sign: it rises with the current (slope {slope:.3g} N m/A; --auto-sign)",
                "torque",
            )
        )
    return torque
