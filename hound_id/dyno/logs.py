"""Dynamometer logs in: a CSV or Parquet table to a clean, SI :class:`DynoLog`.

Real logs are dirty. This module finds the channels, converts their units and
cleans the rows, and it reports every change it makes as a :class:`CleaningNote`.
Nothing is changed silently.

**Reading.** CSV files may have a title or date line above the header, a units row under
it (``N.mm``, ``rad.s``, ``Deg C``, ``mA``), ``,``/``, ``/``;``/tab separators and a
trailing separator on every row (:mod:`hound_id.tables`); what the reader did is a
``format`` note.

**Channels.** :data:`CANONICAL` names the channels; :data:`REQUIRED` must be present.
Without a time column the table is a steady-state table: each row is an operating point,
time is the row number (:attr:`DynoLog.timed` is False), and the time-based cleaning steps
(2, 3 below) are skipped. A time column without a unit whose steps look like milliseconds
or microseconds is a ``time_unit`` warning that names the likely unit.
Without a mapping, a channel is the column with its exact name, or its name with a unit
suffix in square brackets (``velocity[rpm]``, ``torque [mN*m]``). A mapping
(``--columns torque=adc_torque``) names the file column instead, with or without its
bracketed suffix.

**Units.** Units come from the header suffix or from ``--units`` (which wins). They are
converted with pint to :data:`UNITS`: SI, except temperature, which stays in degC because
only ``T - 20 degC`` is used. ``Nm`` is newton metre, and ``Hz`` is refused for speeds as
ambiguous, as in :mod:`hound_id.units`.

**Cleaning**, in this order. Row numbers in the notes count data rows of the file from 1:

1. Rows with NaN or inf in a required channel are dropped. An optional channel with
   non-finite values in fewer than 5 % of the rows loses those rows. Otherwise the
   channel itself is dropped.
2. If time ever goes backwards, the rows are sorted by time (stable). Rows that repeat
   the previous timestamp are dropped; the first one is kept.
3. Wrap-around of the current channel is undone, and clamped replies and driver current
   limits are found (:mod:`hound_id.dyno.artefacts`): ``wrap``, ``clamp`` and
   ``current_limit`` notes. Rows whose current is unknown (at the wrap boundary, or clamped
   while the torque keeps moving) are removed; rows at a driver limit are data and kept.
4. Single-sample glitches in current and torque are removed with a Hampel-type test
   (Davies & Gather 1993; Pearson 2002): the deviation from the median of a centred
   window of 7 samples, against max(8 sigma, 5 % of the 99th-percentile magnitude).
   sigma = 1.4826 MAD(diff(x)) / sqrt(2) is the noise level. 1.4826 makes the MAD a
   standard deviation for Gaussian noise; the difference of two samples has sqrt(2)
   times the noise of one. Only runs of at most 2 flagged samples count as glitches.
   A longer run is a real step. A glitch is in one channel only: a transient that the
   other channel shares (within one sample) is data and kept.
5. ADC saturation of the torque: a channel with measurable noise elsewhere sits exactly at its own
   extreme, a large magnitude, for 5 or more consecutive samples, and at that extreme in at least 0.1 % of the rows. The
   channel is noisy elsewhere, so repeating one value exactly for whole runs is not a measured
   signal. A channel without measurable noise (a logged set-point, a simulation) is not tested:
   its flat steps are data.
   Every row at the extreme is removed.
6. A torque that falls as current rises (least-squares slope < 0, correlation < -0.5)
   means a reversed sensor. That is an error unless ``flip_torque`` negates the torque, or ``auto_sign`` lets each
   log's own slope decide (and says so in a note).

At least :data:`MIN_ROWS` rows must remain.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen
from hound_id.dyno.artefacts import (
    LIVE_SHARE,
    align_stale,
    asked_at_boundary,
    at_boundary,
    find_plateaus,
    find_wraps,
    flipped_at_boundary,
    quantum,
    repeated_share,
    stale_hold,
)
from hound_id.errors import DynoDataError, SpecError

Array = NDArray[np.float64]

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

#: Channel names, in the order of :class:`DynoLog`'s fields.
CANONICAL: tuple[str, ...] = (
    "time",
    "current",
    "torque",
    "velocity",
    "position",
    "temperature",
    "bus_voltage",
    "torque_cmd",
    "current_cmd",
)
#: Channels a log must have.
REQUIRED: tuple[str, ...] = ("current", "torque")
#: Channels every cleaning step carries (time is the row number in a steady-state table).
CORE: tuple[str, ...] = ("time", "current", "torque")
#: Unit of each channel inside hound-id (pint spelling). SI, except temperature in degC (used only as T - 20 degC).
UNITS: dict[str, str] = {
    "time": "s",
    "current": "A",
    "torque": "N*m",
    "velocity": "rad/s",
    "position": "rad",
    "temperature": "degC",
    "bus_voltage": "V",
    "torque_cmd": "N*m",
    "current_cmd": "A",
}
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
#: The kinds of :class:`CleaningNote`.
NOTE_KINDS: tuple[str, ...] = (
    "nan_rows",
    "glitch",
    "duplicate_time",
    "unsorted_time",
    "adc_saturation",
    "flipped_torque",
    "unit",
    "format",
    "steady_state",
    "time_unit",
    "wrap",
    "clamp",
    "current_limit",
    "reply_clamp",
    "reply_flip",
    "duplicate_rows",
    "stale",
)

#: Fewest rows a cleaned log may have: ten operating points of a steady-state table, or a burst of ten samples, each a
#: block of their own (hound_id.dyno.current.fit.Blocks), the least that blocked cross-validation over ten folds can
#: hold out. Calibrated on test_logs::test_too_few_rows_are_refused and
#: test_logs::test_a_table_of_26_operating_points_and_a_burst_written_16_times_are_read.
MIN_ROWS = 10
#: An optional channel with non-finite values in at least this share of rows is dropped instead of its rows (5 %: a few
#: gaps cost a few rows, a channel that is often missing would cost the log). Calibrated on
#: test_logs::test_a_few_nans_in_an_optional_channel_drop_their_rows and
#: test_logs::test_many_nans_in_an_optional_channel_drop_the_channel_not_the_rows.
OPTIONAL_NAN_FRACTION = 0.05
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
#: Correlation of torque with current below which a negative slope means a reversed sensor: a clearly falling torque,
#: not a noisy or unloaded one (the fit's own slope checks judge those). Calibrated on
#: test_logs::test_a_reversed_torque_sensor_is_refused_with_the_fix and
#: test_logs::test_flip_torque_on_a_sensor_mounted_the_right_way_is_refused.
FLIP_CORRELATION = -0.5

# channel -> (what it is, example units) for messages.
_LABELS: dict[str, tuple[str, str]] = {
    "time": ("a time", "s, ms, us"),
    "current": ("a current", "A, mA"),
    "torque": ("a torque", "N*m, mN*m, Nm"),
    "velocity": ("an angular speed", "rad/s, rpm, deg/s"),
    "position": ("an angle", "rad, deg, turn"),
    "temperature": ("a temperature", "degC, degF, K"),
    "bus_voltage": ("a voltage", "V, mV"),
    "torque_cmd": ("a torque", "N*m, mN*m, Nm"),
    "current_cmd": ("a current", "A, mA"),
}
_EXAMPLES = {"--columns": "torque=adc_torque,current=iq", "--units": "velocity=rpm,position=deg"}
_HEADER = re.compile(r"^\s*(?P<base>.*?)\s*\[\s*(?P<unit>[^\[\]]*?)\s*\]\s*$")
_ITEM = re.compile(r"^\s*(?P<key>[A-Za-z_][A-Za-z0-9_]*)\s*=\s*(?P<value>\S(?:.*\S)?)\s*$")


@dataclass(frozen=True)
class CleaningNote:
    """One change made to a log while loading it, for the user to read."""

    kind: str
    """What was done: one of :data:`NOTE_KINDS`."""
    rows: int
    """Rows affected: removed (nan_rows, glitch, duplicate_time, adc_saturation), out of order, converted or
    negated. 0 when a whole channel was dropped instead (its message gives the count of bad values)."""
    message: str
    """One sentence with the numbers, e.g. "removed 1 single-sample glitch in 'current' ... at row 5012"."""
    channel: str | None = None
    """Canonical channel the note is about, if it concerns one."""


# eq=False: the fields are arrays, whose == is element-wise.
@dataclass(frozen=True, eq=False)
class DynoLog:
    """A cleaned dynamometer log: one row per sample, strictly increasing time, SI units.

    The arrays are read-only copies of equal length. An optional channel is ``None`` when
    the file lacks it or it was dropped while cleaning (see :attr:`notes`).
    """

    time: NDArray[np.float64]
    """Sample times [s], strictly increasing; the row numbers 0, 1, 2, ... when :attr:`timed` is False."""
    current: NDArray[np.float64]
    """Motor current [A]."""
    torque: NDArray[np.float64]
    """Shaft torque measured by the dyno [N m]."""
    velocity: NDArray[np.float64] | None = None
    """Shaft angular speed [rad/s]."""
    position: NDArray[np.float64] | None = None
    """Shaft angle [rad]."""
    temperature: NDArray[np.float64] | None = None
    """Winding or housing temperature [degC] (not SI: only T - 20 degC is used)."""
    bus_voltage: NDArray[np.float64] | None = None
    """Supply (bus) voltage [V]."""
    torque_cmd: NDArray[np.float64] | None = None
    """Commanded torque [N m] (either side of a gearbox: only its trend is used)."""
    current_cmd: NDArray[np.float64] | None = None
    """Commanded current [A]."""
    source: str = "log"
    """Where the log came from (file name), for messages."""
    notes: tuple[CleaningNote, ...] = ()
    """Every change made while loading, in order."""
    rows_read: int = 0
    """Rows in the table before cleaning (0 when the log was not read from a table)."""
    timed: bool = True
    """False for a steady-state table without a time column: each row is an operating point."""
    current_limit: float | None = None
    """The driver's current limit [A] where the log shows the current held at a level while the command rose."""
    current_range: float | None = None
    """The range the current channel is encoded in [A], where the log shows it: half the period of a wrap-around,
    the level a reply is clamped at, or else the level it is held at (a driver limit, or a clamp the log cannot tell
    from one). Logs of one actuator on different current scales show it in different ranges."""

    def __post_init__(self) -> None:
        n = None
        for name in CANONICAL:
            value = getattr(self, name)
            if value is None:
                if name in REQUIRED or name == "time":
                    raise DynoDataError(f"{self.source}: the '{name}' channel is required", channel=name)
                continue
            # Arrays the loader made are sealed already (read-only, owning their data): no second copy of 1M rows.
            sealed = isinstance(value, np.ndarray) and value.dtype == np.float64 and value.flags.owndata
            array = value if sealed and not value.flags.writeable else frozen(value)
            if array.ndim != 1 or (n is not None and array.size != n):
                raise DynoDataError(
                    f"{self.source}: channel '{name}' has shape {array.shape}, "
                    f"expected ({'n' if n is None else n},) like the time channel",
                    channel=name,
                )
            n = array.size
            object.__setattr__(self, name, array)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.time.size)

    @property
    def sample_rate(self) -> float:
        """Median of the per-sample rates 1/dt [Hz]."""
        if not self.timed:
            raise DynoDataError(f"{self.source}: a steady-state table (no time column) has no sample rate")
        if self.n < 2:
            raise DynoDataError(f"{self.source}: {self.n} sample(s), expected at least 2 for a sample rate")
        return float(np.median(1.0 / np.diff(self.time)))

    def has(self, name: str) -> bool:
        """Whether the log holds the channel ``name`` (one of :data:`CANONICAL`).

        Raises:
            DynoDataError: ``name`` is not a channel name (a typo should not read as "absent").
        """
        return getattr(self, _check_channel(name, self.source)) is not None

    def column(self, name: str) -> NDArray[np.float64]:
        """The channel ``name`` (read-only, in the unit of :data:`UNITS`).

        Raises:
            DynoDataError: ``name`` is not a channel name, or the log lacks that channel.
        """
        values: NDArray[np.float64] | None = getattr(self, _check_channel(name, self.source))
        if values is not None:
            return values
        dropped = [note for note in self.notes if note.channel == name and note.message.startswith("dropped column")]
        if dropped:
            raise DynoDataError(
                f"{self.source}: the '{name}' channel was dropped while loading ({dropped[0].message}); "
                f"fill those values in the file or map another column with --columns {name}=<your column>",
                channel=name,
            )
        raise DynoDataError(
            f"{self.source}: no '{name}' channel; expected a column named '{name}' or '{name}[unit]', "
            f"or map yours with --columns {name}=<your column>",
            channel=name,
        )

    def without(self, rows: NDArray[np.intp], message: str) -> DynoLog:
        """The log less ``rows``, with a note (kind ``window``) saying why.

        Raises:
            DynoDataError: Fewer than :data:`MIN_ROWS` rows would be left.
        """
        keep = np.ones(self.n, dtype=bool)
        keep[np.asarray(rows, dtype=np.intp)] = False
        if int(keep.sum()) < MIN_ROWS:
            raise DynoDataError(
                f"{self.source}: leaving out {self.n - int(keep.sum())} rows keeps {int(keep.sum())}, expected at "
                f"least {MIN_ROWS}"
            )
        arrays: dict[str, Any] = {
            name: (None if getattr(self, name) is None else getattr(self, name)[keep]) for name in CANONICAL
        }
        note = CleaningNote("window", int(self.n - keep.sum()), message)
        return dataclasses.replace(self, **arrays, notes=(*self.notes, note))

    def window(self, start: float | None, stop: float | None) -> DynoLog:
        """The rows with start <= t <= stop [s] (for a steady-state table, 1-based data rows); None is open.

        Raises:
            DynoDataError: Fewer than :data:`MIN_ROWS` rows lie in the window.
        """
        return self.windows([(start, stop)])

    def windows(self, ranges: Sequence[tuple[float | None, float | None]]) -> DynoLog:
        """The rows inside any of the (start, stop) ranges (:meth:`window`'s bounds), in log order.

        Raises:
            DynoDataError: Fewer than :data:`MIN_ROWS` rows lie in the ranges.
        """
        key = self.time if self.timed else self.time + 1.0
        keep = np.zeros(self.n, dtype=bool)
        unit = "s" if self.timed else "(data rows)"
        text = ",".join(f"{_bound(start)}:{_bound(stop)}" for start, stop in ranges)
        for start, stop in ranges:
            inside = np.ones(self.n, dtype=bool)
            if start is not None:
                inside &= key >= start
            if stop is not None:
                inside &= key <= stop
            if len(ranges) > 1 and not inside.any():
                raise DynoDataError(
                    f"{self.source}: --window {text}: the range {_bound(start)}:{_bound(stop)} holds no row; the log "
                    f"spans {float(key[0]):.6g} to {float(key[-1]):.6g} {unit}",
                    option="--window",
                )
            keep |= inside
        if int(keep.sum()) < MIN_ROWS:
            lo, hi = float(key[0]), float(key[-1])
            raise DynoDataError(
                f"{self.source}: --window {text} keeps {int(keep.sum())} rows, expected at "
                f"least {MIN_ROWS}; the log spans {lo:.6g} to {hi:.6g} {unit}",
                option="--window",
            )
        arrays: dict[str, Any] = {
            name: (None if getattr(self, name) is None else getattr(self, name)[keep]) for name in CANONICAL
        }
        kept = ", ".join(
            f"{'the start' if start is None else f'{start:g}'} to {'the end' if stop is None else f'{stop:g}'}"
            for start, stop in ranges
        )
        note = CleaningNote(
            "window", int(self.n - keep.sum()), f"kept {kept} {unit} (--window): {int(keep.sum())} of {self.n} rows"
        )
        return dataclasses.replace(self, **arrays, notes=(*self.notes, note))


def _bound(value: float | None) -> str:
    return "" if value is None else f"{value:g}"


def parse_window(text: str | None) -> tuple[float | None, float | None]:
    """Read ``--window START:STOP`` (either end may be left out): (start, stop), None for an open end.

    Raises:
        DynoDataError: Not two numbers around a colon, or start after stop.
    """
    if text is None:
        return None, None
    parts = text.split(":")
    example = "--window 0:39.5 (seconds; data rows for a steady-state table), --window 12: or --window :40"
    try:
        if len(parts) != 2:
            raise ValueError
        start, stop = (float(p) if p.strip() else None for p in parts)
        if any(v is not None and not math.isfinite(v) for v in (start, stop)):
            raise ValueError
    except ValueError:
        raise DynoDataError(
            f"--window: found {text!r}, expected START:STOP, for example {example}", option="--window"
        ) from None
    if start is not None and stop is not None and start >= stop:
        raise DynoDataError(f"--window: start {start:g} is not before stop {stop:g}", option="--window")
    return start, stop


def parse_windows(text: str | None) -> list[tuple[float | None, float | None]]:
    """Read ``--window START:STOP[,START:STOP...]``: the ranges in order (none given: one open range).

    Raises:
        DynoDataError: A range that :func:`parse_window` refuses, or ranges out of order or overlapping.
    """
    if text is None:
        return [(None, None)]
    ranges = [parse_window(part) for part in text.split(",")]
    for (_, a1), (b0, _) in zip(ranges[:-1], ranges[1:], strict=True):
        if a1 is None or b0 is None or b0 <= a1:
            raise DynoDataError(
                f"--window: found {text!r}; several ranges must be in order and apart, for example "
                "--window 0:14.5,15.2:27",
                option="--window",
            )
    return ranges


def parse_mapping(text: str | None, option: str) -> dict[str, str]:
    """Read a ``name=value,name=value`` option, e.g. ``"torque=adc_torque,current=iq[mA]"``.

    Args:
        text: The option's text; ``None`` or blank gives an empty mapping.
        option: The option's name (``"--columns"``, ``"--units"``), for messages.

    Returns:
        The pairs in the order given, keys and values stripped.

    Raises:
        DynoDataError: An item is not ``name=value`` or a name is given twice.
    """
    result: dict[str, str] = {}
    if text is None or not text.strip():
        return result
    example = _EXAMPLES.get(option, "name=value,name=value")
    for item in text.split(","):
        if not item.strip():
            continue
        match = _ITEM.match(item)
        if match is None:
            raise DynoDataError(
                f"{option}: cannot read {item.strip()!r} in {text!r}; expected name=value pairs separated by commas, "
                f"e.g. {option} {example}",
                option=option,
                found=item,
            )
        key, value = match["key"], match["value"]
        if key in result:
            raise DynoDataError(
                f"{option}: '{key}' is given twice in {text!r} ({result[key]!r} and {value!r}); give it once",
                option=option,
                found=key,
            )
        result[key] = value
    return result


def load_log(
    path: str | Path,
    columns: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    flip_torque: bool = False,
    auto_sign: bool = False,
) -> DynoLog:
    """Read a dyno log from CSV or Parquet and clean it (see :func:`log_from_frame`).

    Raises:
        TableError: The file is missing, of unknown format, unreadable or empty.
        DynoDataError: The log is unusable as given (see :func:`log_from_frame`).
    """
    from hound_id.tables import read_table_info

    table = read_table_info(path)
    found = tuple(CleaningNote("format", 0, message) for message in table.notes)
    return log_from_frame(
        table.frame,
        source=str(path),
        columns=columns,
        units=units,
        flip_torque=flip_torque,
        format_notes=found,
        auto_sign=auto_sign,
    )


def log_from_frame(
    frame: pd.DataFrame,
    source: str = "log",
    columns: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    flip_torque: bool = False,
    format_notes: tuple[CleaningNote, ...] = (),
    auto_sign: bool = False,
) -> DynoLog:
    """Find the channels of a table, convert them to SI and clean the rows.

    Args:
        frame: The table as read, one row per sample.
        source: File name, for messages.
        columns: Channel name -> file column (``--columns``), for columns not named after the channel.
        units: Channel name -> unit (``--units``), overriding any ``[unit]`` header suffix.
        flip_torque: Negate the torque (a dyno torque sensor mounted reversed).
        auto_sign: Negate the torque when it falls as current rises (this log's sensor is mounted reversed), with
            a note either way; ``flip_torque`` is then ignored.
        format_notes: Notes made before (by the file reader), kept first.

    Returns:
        The clean log; :attr:`DynoLog.notes` lists every change made.

    Raises:
        DynoDataError: A required channel is missing, a mapping or unit is wrong, a channel
            is not numeric, fewer than :data:`MIN_ROWS` rows remain, or the torque sensor
            looks reversed.
    """
    names = [str(c) for c in frame.columns]
    frame = frame.set_axis(names, axis=1)
    rows_read = len(frame)
    found = _resolve_columns(names, dict(columns or {}), source)
    unit_of = _resolve_units(found, dict(units or {}), names, source)
    notes = list(format_notes)
    data: dict[str, NDArray[np.float64]] = {}
    bad_cells: dict[str, tuple[int, str, int]] = {}
    for name, column in found.items():
        values, timestamp, bad = numeric_column(frame, column, name, source)
        if bad is not None:
            bad_cells[name] = bad
        if timestamp is not None:
            notes.append(CleaningNote("unit", rows_read, f"time converted from {timestamp}", name))
        elif unit_of.get(name):
            text, origin = unit_of[name]
            values, note = convert_units(values, text, origin, name, column, source)
            if note is not None:
                notes.append(note)
        data[name] = values

    if "current" in data and "torque" in data and "current" not in unit_of:
        _check_current_unit(data["current"], data["torque"], source)
    timed = "time" in data
    if timed:
        _check_time_unit(data["time"], "time" in unit_of or any(n.channel == "time" for n in notes), notes)
    else:
        data["time"] = np.arange(rows_read, dtype=np.float64)
        notes.append(
            CleaningNote(
                "steady_state",
                rows_read,
                f"no time column (the file has columns {_listing(names)}): each row is read as an operating point of "
                "a steady-state table, held-out blocks follow the row order and the delay is not tried; if the file "
                "has a time column, map it with --columns time=<column>",
                "time",
            )
        )
    _beyond_reason(data, found, source, notes)
    good = _finite_rows(data, bad_cells, notes)
    good &= ~_repeated_rows(data, found, timed, notes)
    # The cleaning steps carry only the core channels and the 1-based file row of each sample; the optional
    # channels are gathered once at the end (copying seven 1M-row arrays at every step is most of the run time).
    rows = np.flatnonzero(good).astype(np.int64) + 1
    core = {name: data[name] if good.all() else data[name][good] for name in CORE}
    _check_enough(rows.size, rows_read, notes, source)
    if timed:
        core, rows = _clean_time(core, rows, notes)
        _check_enough(rows.size, rows_read, notes, source)
        core = _align_stale(core, rows, data, notes)
    command = next((data[c] for c in ("current_cmd", "torque_cmd") if c in data), None)
    ranges: list[float] = []
    if timed:  # a wrap is a jump in time; the rows of a steady-state table are separate operating points
        core, rows = _undo_wraps(core, rows, command, notes, ranges)
    _check_enough(rows.size, rows_read, notes, source)
    noise: dict[str, float] = {}
    if timed:  # a glitch is a spike in time; the rows of a steady-state table are separate operating points
        # before clamps are cut out: a row next to a removed stretch is no spike
        core, rows, noise = _remove_glitches(core, rows, notes)
    core, rows, current_limit = _current_plateaus(core, rows, command, notes, ranges)
    _check_enough(rows.size, rows_read, notes, source)
    core, rows = _remove_clipping(core, rows, noise, notes)
    _check_enough(rows.size, rows_read, notes, source)
    _check_varies(core, source)
    torque = _orient_torque(core["current"], core["torque"], flip_torque, notes, source, auto_sign)
    positions = rows - 1
    optional = {name: np.take(values, positions) for name, values in data.items() if name not in CORE}
    if timed:
        optional = _align_stale(optional, rows, {**data, **core}, notes, STALE_OPTIONAL, core["time"])
    for array, name in ((core["time"], "time"), (core["current"], "current"), (torque, "torque")):
        if array is not data[name]:  # made by the cleaning, so referenced nowhere else (not a view of the frame)
            array.setflags(write=False)
    for array in optional.values():
        array.setflags(write=False)
    return DynoLog(
        time=core["time"],
        current=core["current"],
        torque=torque,
        velocity=optional.get("velocity"),
        position=optional.get("position"),
        temperature=optional.get("temperature"),
        bus_voltage=optional.get("bus_voltage"),
        torque_cmd=optional.get("torque_cmd"),
        current_cmd=optional.get("current_cmd"),
        source=source,
        notes=tuple(notes),
        rows_read=rows_read,
        timed=timed,
        current_limit=current_limit,
        current_range=ranges[0] if ranges else current_limit,
    )


# --- channels and units ----------------------------------------------------------------------------------------


def _check_channel(name: str, source: str, option: str | None = None) -> str:
    if name in CANONICAL:
        return name
    close = difflib.get_close_matches(name, CANONICAL, n=1)
    hint = f" (did you mean '{close[0]}'?)" if close else ""
    prefix = f"{source}: {option} names an" if option else f"{source}: no such channel: an"
    raise DynoDataError(
        f"{prefix} unknown channel '{name}'{hint}; expected one of {', '.join(CANONICAL)}", channel=name
    )


def split_header(column: str) -> tuple[str, str | None]:
    """``"torque [mN*m]"`` -> ``("torque", "mN*m")``; a column without a bracketed suffix -> ``(column, None)``."""
    match = _HEADER.match(column)
    if match is None:
        return column.strip(), None
    return match["base"], (match["unit"] or None)


def _listing(names: list[str], limit: int = 20) -> str:
    shown = ", ".join(repr(n) for n in names[:limit])
    return shown + (f", ... ({len(names) - limit} more)" if len(names) > limit else "")


def _pick(candidates: list[str], name: str, source: str) -> str | None:
    if len(candidates) > 1 and len(set(candidates)) == 1:
        raise DynoDataError(
            f"{source}: the file has more than one column named '{candidates[0]}'; rename one", column=candidates[0]
        )
    if len(candidates) > 1:
        raise DynoDataError(
            f"{source}: columns {_listing(candidates)} all look like the '{name}' channel; "
            f"pick one with --columns {name}=<column>",
            channel=name,
            found=candidates,
        )
    return candidates[0] if candidates else None


def _resolve_columns(names: list[str], columns: dict[str, str], source: str) -> dict[str, str]:
    """Channel -> file column, from the mapping first, then by name."""
    bases = [split_header(c)[0] for c in names]
    found: dict[str, str] = {}
    for name, wanted in columns.items():
        _check_channel(name, source, "--columns")
        wanted = wanted.strip()
        column = _pick([c for c in names if c.strip() == wanted], name, source) or _pick(
            [c for c, b in zip(names, bases, strict=True) if b == wanted], name, source
        )
        if column is None:
            close = difflib.get_close_matches(wanted, names, n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise DynoDataError(
                f"{source}: --columns maps {name} to '{wanted}', which is not a column of the file{hint}; "
                f"the file has columns {_listing(names)}",
                channel=name,
                found=wanted,
            )
        if column in found.values():
            other = next(k for k, v in found.items() if v == column)
            raise DynoDataError(
                f"{source}: --columns maps both {other} and {name} to column '{column}'; map each channel to its own",
                channel=name,
                found=column,
            )
        found[name] = column
    taken = set(found.values())
    for name in CANONICAL:
        if name in found:
            continue
        free = [(c, b) for c, b in zip(names, bases, strict=True) if c not in taken]
        column = (
            _pick([c for c, _ in free if c == name], name, source)
            or _pick([c for c, b in free if b == name], name, source)
            or _pick([c for c, b in free if b.lower() == name], name, source)
        )
        if column is not None:
            found[name] = column
            taken.add(column)
    missing = [name for name in REQUIRED if name not in found]
    if missing:
        suggestion = ",".join(f"{m}=<your column>" for m in missing)
        raise DynoDataError(
            f"{source}: missing required column(s) {', '.join(repr(m) for m in missing)}; the file has columns "
            f"{_listing(names)}; name them {', '.join(REQUIRED)} (optionally with a unit such as 'torque[N*m]') "
            f"or map yours with --columns {suggestion}",
            missing=missing,
        )
    return {name: found[name] for name in CANONICAL if name in found}


def _resolve_units(
    found: dict[str, str], units: dict[str, str], names: list[str], source: str
) -> dict[str, tuple[str, str]]:
    """Channel -> (unit text, where it came from), for channels that state a unit."""
    result: dict[str, tuple[str, str]] = {}
    for name, column in found.items():
        header = split_header(column)[1]
        if header:
            result[name] = (header, f"the header '{column}'")
    for name, given in units.items():
        text = given.strip()
        _check_channel(name, source, "--units")
        if name not in found:
            raise DynoDataError(
                f"{source}: --units gives a unit for '{name}', but the file has no {name} column "
                f"(columns {_listing(names)}); map it with --columns {name}=<your column> or drop it from --units",
                channel=name,
            )
        stated = result.get(name)
        origin = "--units" + (f", overriding the header unit '{stated[0]}'" if stated and stated[0] != text else "")
        result[name] = (text, origin)
    return result


def numeric_column(
    frame: pd.DataFrame, column: str, name: str, source: str
) -> tuple[NDArray[np.float64], str | None, tuple[int, str, int] | None]:
    """A column as float64.

    Returns:
        The values (non-numeric cells as NaN); for timestamps or durations what was converted, else None;
        and (count, first bad cell, its row) of the non-numeric cells, or None.
    """
    import pandas as pd

    series = frame[column]
    if isinstance(series, pd.DataFrame):
        raise DynoDataError(f"{source}: the file has more than one column named '{column}'; rename one", column=column)
    if name == "time" and pd.api.types.is_timedelta64_dtype(series):
        return series.dt.total_seconds().to_numpy(dtype=np.float64, na_value=np.nan), "durations to seconds", None
    if name == "time" and pd.api.types.is_datetime64_any_dtype(series):
        start = series.min()
        seconds = (series - start).dt.total_seconds().to_numpy(dtype=np.float64, na_value=np.nan)
        return seconds, f"timestamps to seconds after {start}", None
    if pd.api.types.is_bool_dtype(series):  # pandas counts booleans as numbers; no sensor logs True/False
        raise DynoDataError(
            f"{source}: column '{column}' holds true/false values (a {series.dtype} column); expected numbers for "
            f"the {name} channel: map the right column with --columns {name}=<column>",
            column=column,
        )
    if pd.api.types.is_numeric_dtype(series):
        return series.to_numpy(dtype=np.float64, na_value=np.nan), None, None
    numbers = pd.to_numeric(series, errors="coerce")
    bad = (numbers.isna() & series.notna()).to_numpy()
    present = int(series.notna().sum())
    if name == "time" and 2 * int(bad.sum()) > present:
        stamps = pd.to_datetime(series, errors="coerce", format="ISO8601", utc=True)
        stamp_bad = (stamps.isna() & series.notna()).to_numpy()
        if 2 * int(stamp_bad.sum()) <= present:
            values, start, _ = numeric_column(stamps.to_frame(column), column, name, source)
            return values, start, _bad_cells(series, stamp_bad)
    if 2 * int(bad.sum()) > present:
        first = int(np.flatnonzero(bad)[0])
        kind = "seconds or ISO 8601 timestamps" if name == "time" else "numbers"
        raise DynoDataError(
            f"{source}: column '{column}' is not numeric (row {first + 1} holds {series.iloc[first]!r}); "
            f"expected {kind} for the {name} channel",
            column=column,
            row=first + 1,
        )
    return numbers.to_numpy(dtype=np.float64, na_value=np.nan), None, _bad_cells(series, bad)


def _bad_cells(series: pd.Series, bad: NDArray[np.bool_]) -> tuple[int, str, int] | None:
    if not bad.any():
        return None
    first = int(np.flatnonzero(bad)[0])
    return int(bad.sum()), repr(series.iloc[first]), first + 1


def convert_units(
    values: NDArray[np.float64], text: str, origin: str, name: str, column: str, source: str
) -> tuple[NDArray[np.float64], CleaningNote | None]:
    """Convert ``values`` from the unit ``text`` to :data:`UNITS` ``[name]`` with pint."""
    import pint

    from hound_id.units import (
        QUANTITY_MAX_CHARS,
        check_unit_text,
        normalise,
        registry,
        slash_reading,
        unit_text_errors,
    )

    ureg = registry()
    label, examples = _LABELS[name]
    target = ureg.Unit(UNITS[name])
    fix = f"fix the header or pass --units {name}=<unit>"
    try:
        if len(text) > QUANTITY_MAX_CHARS:
            raise ValueError(f"{len(text):,} characters, too long for a unit")
        check_unit_text(text)
        unit = ureg.Unit(normalise(text))
    except unit_text_errors() as err:
        raise DynoDataError(
            f"{source}: column '{column}': cannot read the unit {text!r} (from {origin}; {err}); "
            f"expected {label} in a unit such as {examples}; {fix}",
            column=column,
            unit=text,
        ) from err
    if name == "velocity" and ("hertz" in str(unit) or "Hz" in text):
        raise DynoDataError(
            f"{source}: column '{column}': the unit {text!r} uses Hz, which is ambiguous for an angular speed "
            f"(rev/s or rad/s?); write rps, rpm or rad/s ({fix})",
            column=column,
            unit=text,
        )
    # Root units, not just dimensions: pint takes rad as dimensionless, so 'count' or Hz would pass a dimension check.
    root = ureg.get_root_units(unit)[1]
    expected = ureg.get_root_units(target)[1]
    slash = slash_reading(text)
    read_as = ""
    if root != expected and slash is not None:
        # 'rad.s' in a units row means rad/s: the product reading has the wrong dimension, the quotient the right one
        try:
            other = ureg.Unit(slash)
        except unit_text_errors():
            other = None
        if other is not None and ureg.get_root_units(other)[1] == expected:
            unit, root, read_as = other, expected, f" (read {text!r} as {slash}: a dot for the slash)"
    if root != expected:
        what = f"dimension {unit.dimensionality}" if unit.dimensionality != target.dimensionality else f"unit {root:~}"
        raise DynoDataError(
            f"{source}: column '{column}' has the unit {text!r} (from {origin}), of {what}; "
            f"expected {label} in a unit such as {examples}; {fix}",
            column=column,
            unit=text,
        )
    if unit == target:
        if "overriding" in origin or read_as:  # say so: the header claimed another unit, or a dot was a slash
            said = f"{name} read as {text} (from {origin}){read_as}"
            return values, CleaningNote("unit", int(values.size), said, name)
        return values, None
    try:
        converted = np.asarray(ureg.Quantity(values, unit).to(target).magnitude, dtype=np.float64)
    except pint.errors.PintError as err:
        raise DynoDataError(
            f"{source}: column '{column}': cannot convert {text!r} to {UNITS[name]} ({err}); {fix}",
            column=column,
            unit=text,
        ) from err
    message = f"{name} converted from {text} to {UNITS[name]} (unit from {origin}){read_as}"
    return converted, CleaningNote("unit", int(values.size), message, name)


# --- cleaning ----------------------------------------------------------------------------------------------------


def _keep(
    data: dict[str, NDArray[np.float64]], rows: NDArray[np.int64], mask: NDArray[np.bool_]
) -> tuple[dict[str, NDArray[np.float64]], NDArray[np.int64]]:
    if mask.all():
        return data, rows
    return {k: v[mask] for k, v in data.items()}, rows[mask]


def _row_list(rows: NDArray[np.int64], limit: int = 5) -> str:
    shown = ", ".join(str(int(r)) for r in rows[:limit])
    return shown + (f" and {rows.size - limit} more" if rows.size > limit else "")


def _plural(count: int, word: str) -> str:
    return f"{count} {word}" + ("" if count == 1 else "s")


def _unit_label(name: str) -> str:
    return UNITS[name].replace("*", " ")


def _check_varies(core: dict[str, NDArray[np.float64]], source: str) -> None:
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


def _beyond_reason(
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
                f"read {_plural(count, 'value')} of '{name}' beyond {limit:g} {unit} as missing (no dyno measures "
                f"that: an overflowed register or a garbage row) at rows {_row_list(rows)}",
                name,
            )
        )


def _check_enough(n: int, rows_read: int, notes: list[CleaningNote], source: str) -> None:
    if n >= MIN_ROWS:
        return
    removed = [f"{note.kind} {note.rows}" for note in notes if note.kind not in ("unit", "unsorted_time")]
    why = f" (removed: {', '.join(removed)})" if removed else ""
    raise DynoDataError(
        f"{source}: only {n} of {rows_read} rows are usable after cleaning{why}; expected at least {MIN_ROWS} rows; "
        "record a longer log or fix the rows reported",
        rows=n,
    )


def _repeated_rows(
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
                f"collapsed {_plural(count, 'row')} that {'repeats' if count == 1 else 'repeat'} the row before in "
                f"every column (each {what} written up to {times} times): each counts once, at "
                f"{'row' if count == 1 else 'rows'} {_row_list(np.flatnonzero(same) + 1)}",
            )
        )
    return same


def _finite_rows(
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
                f"dropped {_plural(lost, 'row')} with NaN or inf in a required channel ({'; '.join(counts)}) "
                f"at rows {_row_list(np.flatnonzero(~good) + 1)}",
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
                    f"dropped {_plural(count, 'row')} with NaN or inf in {detail(name, count)} "
                    f"({100 * share:.2g} % of rows, under {100 * OPTIONAL_NAN_FRACTION:g} %) "
                    f"at rows {_row_list(np.flatnonzero(bad) + 1)}",
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


def _align_stale(
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


def _clean_time(
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
                f"time goes backwards: {_plural(int(late.size), 'row')} came after a later timestamp (first at row "
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
                f"dropped {_plural(count, 'row')} repeating the previous timestamp, keeping the first of each "
                f"(first at row {int(rows[first])}, t = {t[first]:.6g} s; rows {_row_list(rows[repeat])})",
            )
        )
        data, rows = _keep(data, rows, ~repeat)
    return data, rows


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


def _remove_glitches(
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
        u = _unit_label(name)
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
                f"{median:.4g} {u} at row {at}) at rows {_row_list(rows[index])}"
            )
        notes.append(CleaningNote("glitch", int(index.size), message, name))
    return (*_keep(data, rows, keep), noise)


def _undo_wraps(
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
            f"{head}folded back into +-{half:.4g} A, and the {_plural(count, 'row')} at the boundary, where the sign "
            f"of the current cannot be known, were removed{capped}",
            "current",
        )
    )
    data, rows = _keep(data, rows, ~boundary)
    return data, rows


def _current_plateaus(
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
        lo, hi = plateau.torque_span
        count = int(plateau.rows.size)
        if plateau.kind == "reply_clamp":
            exact = int(np.count_nonzero(current[plateau.rows] == plateau.level))
            if ranges is not None:
                ranges.append(abs(plateau.level))
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
                f"the current reply is held at {plateau.level:.4g} A, the top of its range, in {_plural(count, 'row')} "
                f"({exact} on exactly that value) {why}: the reply's encoding range ends there (a protocol clamp), not "
                "the driver; "
            )
            beyond = "" if plateau.excess is None else f" ({100 * plateau.excess:+.2g} % of what the level makes)"
            if plateau.usable:
                tail = f"the torque there ({lo:.3g} to {hi:.3g} N m) stays with the level{beyond}, so the rows are data"
                tail += " and kept"
            else:
                keep[plateau.rows] = False
                tail = (
                    f"the torque there ({lo:.3g} to {hi:.3g} N m) goes past what the level makes"
                    f"{beyond or ' (no ramp to compare with)'}, so the current there is unknown and those rows were "
                    "removed"
                )
            notes.append(
                CleaningNote(
                    "reply_clamp",
                    0 if plateau.usable else count,
                    f"{head}{tail}; to test beyond {abs(plateau.level):.3g} A, widen the reply's current range or log "
                    "the current from a sensor of its own",
                    "current",
                )
            )
        elif plateau.kind == "clamp":
            keep[plateau.rows] = False
            if ranges is not None:
                ranges.append(abs(plateau.level))
            notes.append(
                CleaningNote(
                    "clamp",
                    count,
                    f"the reported current is clamped at {plateau.level:.4g} A in {_plural(count, 'row')} (the reply's "
                    f"encoding range or a saturated ADC): it stays there while the torque keeps moving ({lo:.3g} to "
                    f"{hi:.3g} N m), so the true current is unknown and those rows were removed",
                    "current",
                )
            )
        else:
            limit = max(limit or 0.0, abs(plateau.level))
            notes.append(
                CleaningNote(
                    "current_limit",
                    0,
                    f"driver current limit at {plateau.level:.4g} A: the current holds there in "
                    f"{_plural(count, 'row')} while the command asks for {plateau.asked:.3g} A (median there, from the "
                    f"command-current relation elsewhere in the log) and the torque stays at {lo:.3g} to {hi:.3g} N m; "
                    f"the rows are data and kept, and a peak torque beyond {abs(plateau.level):.3g} A needs a higher "
                    "driver limit",
                    "current",
                )
            )
    ends = [abs(p.level) for p in plateaus if p.kind in ("clamp", "reply_clamp")]
    if ends:
        end = min(ends)
        flipped = flipped_at_boundary(current, torque, end) & keep
        count = int(np.count_nonzero(flipped))
        if count:
            keep &= ~flipped
            first = int(np.argmax(flipped))
            notes.append(
                CleaningNote(
                    "reply_flip",
                    count,
                    f"{_plural(count, 'row')} read the current at the other end of the reply's range (+-{end:.4g} A) "
                    f"from the torque, first at row {int(rows[first])} (t = {data['time'][first]:.4g} s): the reply "
                    "crossed the end of its range and came back from the other, so its sign is wrong and its size "
                    "unknown; those rows were removed",
                    "current",
                )
            )
    data, rows = _keep(data, rows, keep)
    return data, rows, limit


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


def _check_current_unit(current: NDArray[np.float64], torque: NDArray[np.float64], source: str) -> None:
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


def _check_time_unit(time: NDArray[np.float64], stated: bool, notes: list[CleaningNote]) -> None:
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


def _remove_clipping(
    data: dict[str, NDArray[np.float64]], rows: NDArray[np.int64], noise: dict[str, float], notes: list[CleaningNote]
) -> tuple[dict[str, NDArray[np.float64]], NDArray[np.int64]]:
    """Remove the rows where the torque is stuck at its extreme (the current: :func:`_current_plateaus`).

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
            u = _unit_label(name)
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
    return _keep(data, rows, keep)


def _orient_torque(
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


# --- torque-speed logs for the envelope comparison (hound-id mor --compare) ---

#: Usable rows a comparison needs: ten speed bins' worth of samples (hound_id.dyno.envelope.walls.MIN_SAMPLES each).
#: Calibrated on test_logs::test_an_envelope_log_needs_envelope_min_rows.
ENVELOPE_MIN_ROWS = 400
#: Channels of a comparison log; the first two are required.
ENVELOPE_CHANNELS = ("torque", "velocity", "torque_cmd", "current", "temperature", "bus_voltage")


@dataclass(frozen=True)
class EnvelopeLog:
    """A torque-speed log on the motor side, SI."""

    torque: Array
    velocity: Array
    torque_cmd: Array | None = None
    current: Array | None = None
    temperature: Array | None = None
    """Winding temperature [degC]."""
    bus_voltage: Array | None = None
    source: str = "log"
    side: str = "motor"
    """``motor``, or how joint-side data was mapped (joint, transmission)."""
    dropped: int = 0
    """Rows dropped for a non-finite value in any channel used."""
    ignored: tuple[str, ...] = ()
    """Optional channels left out because they hold no finite value."""

    @property
    def n(self) -> int:
        return int(self.torque.size)


def load_envelope_log(
    path: str | Path,
    columns: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    robot: Any = None,
    joint: str | None = None,
) -> EnvelopeLog:
    """Read a CSV/Parquet torque-speed log (motor side, or joint side mapped through ``robot``'s
    transmission of ``joint``). Columns are named after :data:`ENVELOPE_CHANNELS` (``[unit]`` suffixes
    converted), or mapped with ``columns``; ``units`` overrides the suffixes.

    For a coupled joint the log needs ``<joint>_torque`` and ``<joint>_velocity`` for every joint
    of its transmission group; the result is the motor paired with ``joint``.
    """
    from hound_id.tables import read_table

    source = str(path)
    frame = read_table(path)
    names = [str(c) for c in frame.columns]
    frame = frame.set_axis(names, axis=1)
    by_base = {split_header(n)[0]: n for n in names}
    columns, units = dict(columns or {}), dict(units or {})
    for key in columns:
        if key not in ENVELOPE_CHANNELS and not key.endswith(("_torque", "_velocity")):
            raise DynoDataError(f"--columns: unknown channel '{key}'; channels are {', '.join(ENVELOPE_CHANNELS)}")

    def channel(name: str, required: bool) -> Array | None:
        column = columns.get(name) or by_base.get(name)
        if column is not None and column not in frame.columns:
            column = by_base.get(column)  # a mapped name without its [unit] suffix
            if column is None:
                raise DynoDataError(f"{source}: --columns {name}={columns[name]}: no such column; columns are {names}")
        if column is None:
            if required:
                raise DynoDataError(
                    f"{source}: column '{name}' missing; a comparison log needs torque and velocity (optionally "
                    f"torque_cmd, current, temperature, bus_voltage); the file has {names}; map with --columns"
                )
            return None
        values, _, bad = numeric_column(frame, column, name, source)
        if bad is not None:
            count, cell, row = bad
            raise DynoDataError(f"{source}: column '{column}' row {row} is {cell!r}, expected a number")
        unit = units.get(name) or split_header(column)[1]
        kind = "torque" if name.endswith("torque") or name == "torque_cmd" else name
        kind = "velocity" if name.endswith("_velocity") else kind
        if unit:
            values, _ = convert_units(values, unit, "header or --units", kind, column, source)
        return np.asarray(values, dtype=float)

    if robot is None or joint is None:
        if (robot is None) != (joint is None):
            raise SpecError("--compare: --robot and --joint go together (joint-side logs)")
        torque, velocity = channel("torque", True), channel("velocity", True)
        side = "motor"
        assert torque is not None and velocity is not None
    else:
        tx = robot.transmission_of(joint)
        if not tx.coupled:
            tau_j, qd_j = channel("torque", True), channel("velocity", True)
            assert tau_j is not None and qd_j is not None
            torque, velocity = tau_j * float(tx.A[0, 0]), qd_j / float(tx.A[0, 0])
        else:
            taus = [channel(f"{j}_torque", True) for j in tx.joints]
            qds = [channel(f"{j}_velocity", True) for j in tx.joints]
            k = tx.joints.index(joint)
            tau_m = np.column_stack([np.asarray(t) for t in taus]) @ tx.A  # tau_m = A^T tau_j, row form
            omega_m = np.column_stack([np.asarray(q) for q in qds]) @ tx.A_inv.T
            torque, velocity = tau_m[:, k], omega_m[:, k]
        side = f"joint {joint} through the {tx.kind} transmission of {', '.join(tx.joints)}"
    rest = {name: channel(name, False) for name in ENVELOPE_CHANNELS[2:]}
    if robot is not None and joint is not None and rest["torque_cmd"] is not None:
        tx = robot.transmission_of(joint)
        if tx.coupled:  # a joint-side command cannot be mapped without the other joints' commands
            rest["torque_cmd"] = None
        else:
            rest["torque_cmd"] = rest["torque_cmd"] * float(tx.A[0, 0])
    ignored = tuple(k for k, v in rest.items() if v is not None and not np.isfinite(v).any())
    rest = {k: (None if k in ignored else v) for k, v in rest.items()}  # an empty optional channel is no channel
    data = {"torque": torque, "velocity": velocity, **rest}
    good = np.ones(torque.size, dtype=bool)
    for values in data.values():
        if values is not None:
            good &= np.isfinite(values)
    if good.sum() < ENVELOPE_MIN_ROWS:
        gaps = {k: int((~np.isfinite(v)).sum()) for k, v in data.items() if v is not None}
        worst = max(gaps, key=lambda k: gaps[k])
        raise DynoDataError(
            f"{source}: {int(good.sum())} usable rows; an envelope comparison needs at least {ENVELOPE_MIN_ROWS} "
            f"(rows with NaN or inf are dropped; most in {worst}: {gaps[worst]})"
        )
    picked = {k: (v[good] if v is not None else None) for k, v in data.items()}
    return EnvelopeLog(source=source, side=side, dropped=int((~good).sum()), ignored=ignored, **picked)  # type: ignore[arg-type]
