"""The channels of a dyno log: canonical names, SI units, the column and unit mapping, unit conversion, and the
notes every step of reading writes (:class:`CleaningNote`)."""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from hound_id.errors import DynoDataError

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd


Array = NDArray[np.float64]


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


def check_channel(name: str, source: str, option: str | None = None) -> str:
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


def listing(names: list[str], limit: int = 20) -> str:
    shown = ", ".join(repr(n) for n in names[:limit])
    return shown + (f", ... ({len(names) - limit} more)" if len(names) > limit else "")


def _pick(candidates: list[str], name: str, source: str) -> str | None:
    if len(candidates) > 1 and len(set(candidates)) == 1:
        raise DynoDataError(
            f"{source}: the file has more than one column named '{candidates[0]}'; rename one", column=candidates[0]
        )
    if len(candidates) > 1:
        raise DynoDataError(
            f"{source}: columns {listing(candidates)} all look like the '{name}' channel; "
            f"pick one with --columns {name}=<column>",
            channel=name,
            found=candidates,
        )
    return candidates[0] if candidates else None


def resolve_columns(names: list[str], columns: dict[str, str], source: str) -> dict[str, str]:
    """Channel -> file column, from the mapping first, then by name."""
    bases = [split_header(c)[0] for c in names]
    found: dict[str, str] = {}
    for name, wanted in columns.items():
        check_channel(name, source, "--columns")
        wanted = wanted.strip()
        column = _pick([c for c in names if c.strip() == wanted], name, source) or _pick(
            [c for c, b in zip(names, bases, strict=True) if b == wanted], name, source
        )
        if column is None:
            close = difflib.get_close_matches(wanted, names, n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise DynoDataError(
                f"{source}: --columns maps {name} to '{wanted}', which is not a column of the file{hint}; "
                f"the file has columns {listing(names)}",
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
            f"{listing(names)}; name them {', '.join(REQUIRED)} (optionally with a unit such as 'torque[N*m]') "
            f"or map yours with --columns {suggestion}",
            missing=missing,
        )
    return {name: found[name] for name in CANONICAL if name in found}


def resolve_units(
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
        check_channel(name, source, "--units")
        if name not in found:
            raise DynoDataError(
                f"{source}: --units gives a unit for '{name}', but the file has no {name} column "
                f"(columns {listing(names)}); map it with --columns {name}=<your column> or drop it from --units",
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


def keep_rows(
    data: dict[str, NDArray[np.float64]], rows: NDArray[np.int64], mask: NDArray[np.bool_]
) -> tuple[dict[str, NDArray[np.float64]], NDArray[np.int64]]:
    if mask.all():
        return data, rows
    return {k: v[mask] for k, v in data.items()}, rows[mask]


def row_list(rows: NDArray[np.int64], limit: int = 5) -> str:
    shown = ", ".join(str(int(r)) for r in rows[:limit])
    return shown + (f" and {rows.size - limit} more" if rows.size > limit else "")


def plural(count: int, word: str) -> str:
    return f"{count} {word}" + ("" if count == 1 else "s")


def unit_label(name: str) -> str:
    return UNITS[name].replace("*", " ")
