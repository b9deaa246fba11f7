"""The dyno log reader: a CSV or Parquet table (or a DataFrame) through the channels and the cleaning to a
:class:`DynoLog`."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen
from hound_id.dyno.logs.clean import (
    MIN_ROWS,
    STALE_OPTIONAL,
    align_stale_channels,
    beyond_reason,
    check_current_unit,
    check_enough,
    check_time_unit,
    check_varies,
    clean_time,
    finite_rows,
    orient_torque,
    repeated_rows,
)
from hound_id.dyno.logs.columns import (
    CANONICAL,
    CORE,
    REQUIRED,
    CleaningNote,
    check_channel,
    convert_units,
    listing,
    numeric_column,
    resolve_columns,
    resolve_units,
)
from hound_id.dyno.logs.sensor import current_plateaus, remove_clipping, remove_glitches, undo_wraps
from hound_id.errors import DynoDataError

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd


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
        return getattr(self, check_channel(name, self.source)) is not None

    def column(self, name: str) -> NDArray[np.float64]:
        """The channel ``name`` (read-only, in the unit of :data:`UNITS`).

        Raises:
            DynoDataError: ``name`` is not a channel name, or the log lacks that channel.
        """
        values: NDArray[np.float64] | None = getattr(self, check_channel(name, self.source))
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
    found = resolve_columns(names, dict(columns or {}), source)
    unit_of = resolve_units(found, dict(units or {}), names, source)
    notes = list(format_notes)
    data, bad_cells = _read_channels(frame, found, unit_of, notes, source)
    timed = _check_units(data, unit_of, names, rows_read, notes, source)
    core, rows, current_limit, ranges = _clean_rows(data, found, bad_cells, timed, rows_read, notes, source)
    torque = orient_torque(core["current"], core["torque"], flip_torque, notes, source, auto_sign)
    optional = _optional_channels(data, core, rows, timed, notes)
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


def _read_channels(
    frame: pd.DataFrame,
    found: Mapping[str, str],
    unit_of: Mapping[str, tuple[str, str]],
    notes: list[CleaningNote],
    source: str,
) -> tuple[dict[str, NDArray[np.float64]], dict[str, tuple[int, str, int]]]:
    """Each found channel as numbers in SI (timestamps to seconds, stated units converted), and its first bad cell."""
    data: dict[str, NDArray[np.float64]] = {}
    bad_cells: dict[str, tuple[int, str, int]] = {}
    rows_read = len(frame)
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
    return data, bad_cells


def _check_units(
    data: dict[str, NDArray[np.float64]],
    unit_of: Mapping[str, tuple[str, str]],
    names: list[str],
    rows_read: int,
    notes: list[CleaningNote],
    source: str,
) -> bool:
    """Check the current's and time's units (numbering the rows of an untimed log); whether the log is timed."""
    if "current" in data and "torque" in data and "current" not in unit_of:
        check_current_unit(data["current"], data["torque"], source)
    timed = "time" in data
    if timed:
        check_time_unit(data["time"], "time" in unit_of or any(n.channel == "time" for n in notes), notes)
    else:
        data["time"] = np.arange(rows_read, dtype=np.float64)
        notes.append(
            CleaningNote(
                "steady_state",
                rows_read,
                f"no time column (the file has columns {listing(names)}): each row is read as an operating point of "
                "a steady-state table, held-out blocks follow the row order and the delay is not tried; if the file "
                "has a time column, map it with --columns time=<column>",
                "time",
            )
        )
    return timed


def _clean_rows(
    data: dict[str, NDArray[np.float64]],
    found: Mapping[str, str],
    bad_cells: dict[str, tuple[int, str, int]],
    timed: bool,
    rows_read: int,
    notes: list[CleaningNote],
    source: str,
) -> tuple[dict[str, NDArray[np.float64]], NDArray[np.int64], float | None, list[float]]:
    """(core channels cleaned, 1-based file rows left, driver current limit, current ranges) of the log."""
    beyond_reason(data, found, source, notes)
    good = finite_rows(data, bad_cells, notes)
    good &= ~repeated_rows(data, found, timed, notes)
    # The cleaning steps carry only the core channels and the 1-based file row of each sample; the optional
    # channels are gathered once at the end (copying seven 1M-row arrays at every step is most of the run time).
    rows = np.flatnonzero(good).astype(np.int64) + 1
    core = {name: data[name] if good.all() else data[name][good] for name in CORE}
    check_enough(rows.size, rows_read, notes, source)
    if timed:
        core, rows = clean_time(core, rows, notes)
        check_enough(rows.size, rows_read, notes, source)
        core = align_stale_channels(core, rows, data, notes)
    command = next((data[c] for c in ("current_cmd", "torque_cmd") if c in data), None)
    ranges: list[float] = []
    if timed:  # a wrap is a jump in time; the rows of a steady-state table are separate operating points
        core, rows = undo_wraps(core, rows, command, notes, ranges)
    check_enough(rows.size, rows_read, notes, source)
    noise: dict[str, float] = {}
    if timed:  # a glitch is a spike in time; the rows of a steady-state table are separate operating points
        # before clamps are cut out: a row next to a removed stretch is no spike
        core, rows, noise = remove_glitches(core, rows, notes)
    core, rows, current_limit = current_plateaus(core, rows, command, notes, ranges)
    check_enough(rows.size, rows_read, notes, source)
    core, rows = remove_clipping(core, rows, noise, notes)
    check_enough(rows.size, rows_read, notes, source)
    check_varies(core, source)
    return core, rows, current_limit, ranges


def _optional_channels(
    data: dict[str, NDArray[np.float64]],
    core: dict[str, NDArray[np.float64]],
    rows: NDArray[np.int64],
    timed: bool,
    notes: list[CleaningNote],
) -> dict[str, NDArray[np.float64]]:
    """The optional channels at the rows the cleaning kept (stale ones aligned in a timed log)."""
    positions = rows - 1
    optional = {name: np.take(values, positions) for name, values in data.items() if name not in CORE}
    if timed:
        optional = align_stale_channels(optional, rows, {**data, **core}, notes, STALE_OPTIONAL, core["time"])
    return optional
