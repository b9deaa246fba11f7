"""Tabular files (CSV, Parquet) in and out, with one-line errors and atomic writes.

Real CSV exports are rarely plain. Before pandas reads a CSV, :func:`sniff_csv` looks at
its first lines and finds:

* the separator: ``,`` (also ``, ``), ``;`` or tab, whichever splits the lines into the
  same number of fields;
* title or date lines above the header (fewer fields than the header), which are skipped;
* a units row under the header (``N.mm``, ``rad.s``, ``Deg C``, ``mA``): a row of short
  texts most of which are units. Its units are put into the column names as a bracketed
  suffix (``Output Torque [N.mm]``), the convention every reader of hound-id understands,
  so a units row is never read as data nor lost;
* rows with more fields than the header has names (a trailing separator on every row):
  an empty or constant trailing field is dropped, any other gets the name ``field_<k>``.

Every such finding is a note for the user (:attr:`Table.notes`).

Tables read and written in batches of rows are in :mod:`hound_id.table_stream`.
"""

from __future__ import annotations

import csv
import math
import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hound_id import io
from hound_id.errors import OutputError, TableError

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd


SUFFIXES = (".csv", ".parquet", ".pq")
#: Separators tried, in order of preference when several fit.
SEPARATORS = (",", ";", "\t")
#: Bytes read to find the layout of a CSV.
SNIFF_BYTES = 65_536
#: Longest text of a units-row cell.
UNIT_CELL_LENGTH = 16
#: Share of a row's non-empty cells that must read as units for it to be a units row.
UNITS_ROW_SHARE = 0.6


@dataclass(frozen=True)
class CsvLayout:
    """Where the parts of a CSV file are (lines counted from 0, comment and blank lines included)."""

    separator: str
    """Field separator (spaces after it are skipped)."""
    header_line: int
    """Line of the column names."""
    names: tuple[str, ...]
    """Column names as written (stripped)."""
    title_lines: tuple[str, ...] = ()
    """Lines above the header (title, date), skipped."""
    units: tuple[str, ...] | None = None
    """The units row under the header, one cell per name, or None."""
    extra_fields: int = 0
    """How many more fields the data rows have than the header has names."""

    @property
    def first_data_line(self) -> int:
        """Line of the first data row."""
        return self.header_line + 1 + (self.units is not None)

    @property
    def plain(self) -> bool:
        """A comma-separated file with the header on its first line and nothing else unusual."""
        return self.separator == "," and not self.title_lines and self.units is None and self.extra_fields == 0


@dataclass(frozen=True)
class Table:
    """A table as read, with what the reader did to read it."""

    frame: pd.DataFrame
    """The rows; columns of a units row carry their unit as a ``[unit]`` suffix."""
    notes: tuple[str, ...] = ()
    """One sentence per finding (skipped title lines, units row, trailing field, separator)."""


#: The longest line of a CSV [bytes]: a row of a hundred channels is a few kB.
MAX_LINE_BYTES = 1 << 20
#: How much of a CSV's end is read for NUL padding [bytes].
NUL_TAIL_BYTES = 1 << 16


def read_table(path: str | Path) -> pd.DataFrame:
    """Read a CSV or Parquet file into a DataFrame (see :func:`read_table_info` for the notes).

    Raises:
        TableError: Missing file, unknown format, unreadable or empty table.
    """
    return read_table_info(path).frame


def read_table_info(path: str | Path) -> Table:
    """Read a CSV or Parquet file, with notes on the layout found (module docstring).

    Raises:
        TableError: Missing file, unknown format, unreadable or empty table.
    """
    import pandas as pd

    p = Path(path)
    suffix = p.suffix.lower()
    if p.is_dir():
        raise TableError(f"{p}: is a folder; expected a .csv or .parquet file", path=str(p))
    if suffix not in SUFFIXES:
        raise TableError(f"{p}: unknown table format {suffix or '(no suffix)'}; expected .csv or .parquet", path=str(p))
    io.check_input(p, "table (.csv or .parquet)", TableError)
    check_nul_tail(p)
    check_line_lengths(p)
    notes: tuple[str, ...] = ()
    try:
        if suffix != ".csv":
            frame = pd.read_parquet(p)
        else:
            layout = sniff_csv(p)
            frame, notes = _read_csv(p, layout) if layout is not None else (pd.read_csv(p, comment="#"), ())
    except (OSError, ValueError, pd.errors.ParserError, pd.errors.EmptyDataError) as err:
        raise unreadable(p, err) from err
    if frame.empty:
        raise TableError(f"{p}: the table has no rows", path=str(p))
    refuse_repeats(p, list(layout.names) if suffix == ".csv" and layout is not None else list(frame.columns))
    return Table(frame, notes)


def refuse_repeats(path: Path, header: list[Any]) -> None:
    """Refuse a header that names a column twice (pandas would rename the copy 'x.1'; which one is meant cannot be
    told)."""
    repeated = sorted({str(n) for n in header if n and header.count(n) > 1})
    if repeated:
        raise TableError(
            f"{path}: column {repeated[0]!r} appears {header.count(repeated[0])} times; which one is meant cannot be "
            "told: rename or drop the copies",
            path=str(path),
            column=repeated[0],
        )


def check_line_lengths(path: Path) -> None:
    """Refuse a CSV with a line longer than :data:`MAX_LINE_BYTES`: no log's row is that long, and pandas' reader
    takes minutes and gigabytes over one (a row of three million fields). One pass over the bytes with numpy."""
    import numpy as np

    if path.suffix.lower() != ".csv":
        return
    line_start, offset, lines = 0, 0, 0
    try:
        with open(path, "rb") as handle:
            while chunk := handle.read(1 << 24):
                ends = np.flatnonzero(np.frombuffer(chunk, np.uint8) == 10) + offset
                starts = np.concatenate(([line_start], ends[:-1] + 1))
                long = np.flatnonzero(ends - starts > MAX_LINE_BYTES)
                offset += len(chunk)
                if long.size:
                    k = int(long[0])
                    _long_line(path, lines + k + 1, int(ends[k] - starts[k]), "")
                if ends.size:
                    lines += ends.size
                    line_start = int(ends[-1]) + 1
                if offset - line_start > MAX_LINE_BYTES:
                    _long_line(path, lines + 1, offset - line_start, "at least ")
    except OSError:
        return  # the reader says what is wrong


def _long_line(path: Path, line: int, size: int, bound: str) -> None:
    raise TableError(
        f"{path}: line {line} is {bound}{size:,} bytes long; a row of a log is at most "
        f"{MAX_LINE_BYTES:,}: the file is not a table of samples (or a row lost its line ends); fix or cut that line",
        path=str(path),
        line=line,
    )


def check_nul_tail(path: Path) -> None:
    """Refuse a CSV that ends in NUL bytes: a file pre-allocated, or cut short by a crash, before its writer filled
    it (read whole, gigabytes of NULs would be one endless field)."""
    if path.suffix.lower() != ".csv":
        return
    try:
        with open(path, "rb") as handle:
            if handle.read(2) in (b"\xff\xfe", b"\xfe\xff"):  # a BOM: each character of UTF-16 holds a NUL
                raise TableError(
                    f"{path}: is UTF-16 text; save it as UTF-8 (iconv -t UTF-8 {path.name} > utf8-{path.name}) and "
                    "read the copy",
                    path=str(path),
                )
            size = handle.seek(0, os.SEEK_END)
            handle.seek(max(size - NUL_TAIL_BYTES, 0))
            tail = handle.read(NUL_TAIL_BYTES)
    except OSError:
        return  # the reader says what is wrong
    if tail and tail[-1] == 0:
        run = len(tail) - len(tail.rstrip(b"\0"))
        at_least = "at least " if run == len(tail) else ""
        raise TableError(
            f"{path}: ends in {at_least}{run:,} NUL bytes (a file pre-allocated, or cut short by a crash, before its "
            f"writer filled it): copy it without them (tr -d '\\000' < {path.name} > fixed.csv) and read the copy",
            path=str(path),
        )


def unit_names(layout: CsvLayout) -> tuple[list[str], list[str]]:
    """Column names with the units row folded in ("speed [rpm]"), and the note that says so."""
    names = list(layout.names)
    notes: list[str] = []
    if layout.units is not None:
        cells = list(layout.units) + [""] * (len(names) - len(layout.units))
        names = [f"{n} [{u}]" if u and "[" not in n else n for n, u in zip(names, cells, strict=False)]
        pairs = [f"{n!r}: {u!r}" for n, u in zip(layout.names, cells, strict=False) if u]
        shown = ", ".join(pairs[:8]) + (f" and {len(pairs) - 8} more" if len(pairs) > 8 else "")
        notes.append(f"read the units row under the header (line {layout.header_line + 2}): {shown}")
    return names, notes


def _read_csv(path: Path, layout: CsvLayout) -> tuple[pd.DataFrame, tuple[str, ...]]:
    import pandas as pd

    if layout.plain:
        return pd.read_csv(path, comment="#", index_col=False), ()
    names, notes = unit_names(layout)
    extra = [f"field_{len(names) + k + 1}" for k in range(layout.extra_fields)]
    frame = pd.read_csv(
        path,
        sep=layout.separator,
        skipinitialspace=True,
        header=None,
        names=names + extra,
        skiprows=layout.first_data_line,
        comment="#",
        index_col=False,
    )
    if layout.title_lines:
        shown = "; ".join(repr(t[:60]) for t in layout.title_lines[:3])
        notes.insert(0, f"skipped {plural_count(len(layout.title_lines), 'line')} above the header: {shown}")
    if layout.separator != ",":
        notes.insert(0, f"fields are separated by {'a tab' if layout.separator == chr(9) else repr(layout.separator)}")
    for column in extra:
        values = frame[column]
        finite = values.dropna()
        if finite.empty or finite.nunique() == 1:
            what = "empty" if finite.empty else f"always {str(finite.iloc[0])!r}"
            notes.append(
                f"every row has {len(layout.names) + len(extra)} fields but the header names "
                f"{len(layout.names)} (a trailing separator): the last field is {what} and was dropped"
            )
            frame = frame.drop(columns=column)
        else:
            notes.append(
                f"rows have more fields than the header has names: the unnamed field {column[6:]} varies, "
                f"so it is kept as column '{column}'"
            )
    return frame, tuple(notes)


def plural_count(n: int, word: str) -> str:
    return f"{n} {word}" + ("" if n == 1 else "s")


def split_cells(line: str, separator: str) -> list[str]:
    row = next(csv.reader([line], delimiter=separator, skipinitialspace=True), [])
    return [cell.strip() for cell in row]


def _is_number(cell: str) -> bool:
    try:
        return math.isfinite(float(cell)) or cell.lower() in ("nan", "inf", "-inf")
    except ValueError:
        return cell.lower() in ("nan", "inf", "-inf", "")


def _numeric_share(cells: list[str]) -> float:
    filled = [c for c in cells if c]
    return sum(_is_number(c) for c in filled) / len(filled) if filled else 0.0


def _is_units_row(cells: list[str]) -> bool:
    """Most non-empty cells are short texts that read as units (``N.mm``, ``Deg C``, ``mA``)."""
    from hound_id.units import is_unit

    filled = [c for c in cells if c]
    if not filled or any(len(c) > UNIT_CELL_LENGTH or _is_number(c) for c in filled):
        return False
    return sum(is_unit(c) for c in filled) >= UNITS_ROW_SHARE * len(filled)


def sniff_csv(path: Path) -> CsvLayout | None:
    """The layout of a CSV file from its first lines, or None when nothing looks like a table.

    Raises:
        OSError: The file cannot be read.
    """
    with open(path, "rb") as handle:
        head = handle.read(SNIFF_BYTES)
    text = head.decode("utf-8-sig", errors="replace")
    lines = text.splitlines()
    if len(head) == SNIFF_BYTES and lines:
        lines = lines[:-1]  # the last line may be cut
    content = [(k, line) for k, line in enumerate(lines) if line.strip() and not line.lstrip().startswith("#")]
    if not content:
        return None
    best: tuple[int, int, str] | None = None  # (covered lines, fields, separator)
    for sep in SEPARATORS:
        counts = Counter(len(split_cells(line, sep)) for _, line in content)
        fields, covered = max(counts.items(), key=lambda kv: (kv[1], kv[0]))
        if fields > 1 and (best is None or covered > best[0]):
            best = (covered, fields, sep)
    if best is None:
        return None
    _, fields, sep = best
    rows = [(k, split_cells(line, sep)) for k, line in content]
    data = [j for j, (_, cells) in enumerate(rows) if len(cells) >= 2 and _numeric_share(cells) > 0.5]
    if not data:
        return None
    start = data[0]
    above = [j for j in range(start) if len(rows[j][1]) >= 2]
    if not above:
        return None  # no header: let pandas say what it finds
    header = above[-1]
    units: tuple[str, ...] | None = None
    if len(above) >= 2 and _is_units_row(rows[header][1]):
        units, header = tuple(rows[header][1]), above[-2]
    names = tuple(rows[header][1])
    title = tuple(line.strip() for k, line in content[:header])
    extra = max(fields - len(names), 0)
    return CsvLayout(
        separator=sep,
        header_line=rows[header][0],
        names=names,
        title_lines=title,
        units=units,
        extra_fields=extra,
    )


def write_table(frame: pd.DataFrame, path: str | Path) -> None:
    """Write a DataFrame as CSV or Parquet (by suffix), atomically."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in SUFFIXES:
        raise OutputError(f"{p}: unknown table format {suffix or '(no suffix)'}; use .csv or .parquet", path=str(p))
    if suffix == ".csv":
        io.write_with(p, lambda handle: frame.to_csv(handle, index=False))
    else:
        io.write_with(p, lambda handle: frame.to_parquet(handle, index=False))


def unique_names(names: list[str]) -> list[str]:
    """Column names as pandas makes them: 'Unnamed: k' for empty ones, '.1', '.2' after repeats."""
    out: list[str] = []
    seen: Counter[str] = Counter()
    for k, name in enumerate(names):
        name = name or f"Unnamed: {k}"
        base = name
        while name in seen:
            name = f"{base}.{seen[base]}"
            seen[base] += 1
        seen[name] += 1
        out.append(name)
    return out


def unreadable(path: Path, err: Exception) -> TableError:
    if isinstance(err, UnicodeDecodeError):
        return TableError(
            f"{path}: is not UTF-8 text (byte {err.object[err.start]:#04x} at {err.start}); save it as UTF-8 (iconv "
            f"-t UTF-8 {path.name} > utf8-{path.name}) and read the copy",
            path=str(path),
        )
    first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
    return TableError(f"{path}: cannot read the table ({first})", path=str(path))


__all__ = ["CsvLayout", "SUFFIXES", "Table", "read_table", "read_table_info", "sniff_csv", "write_table"]
