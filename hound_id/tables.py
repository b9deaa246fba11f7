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
"""

from __future__ import annotations

import csv
import math
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

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
    if not p.is_file():
        raise TableError(f"{p}: file not found", path=str(p))
    notes: tuple[str, ...] = ()
    try:
        if suffix != ".csv":
            frame = pd.read_parquet(p)
        else:
            layout = sniff_csv(p)
            frame, notes = _read_csv(p, layout) if layout is not None else (pd.read_csv(p, comment="#"), ())
    except (OSError, ValueError, pd.errors.ParserError, pd.errors.EmptyDataError) as err:
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise TableError(f"{p}: cannot read the table ({first})", path=str(p)) from err
    if frame.empty:
        raise TableError(f"{p}: the table has no rows", path=str(p))
    return Table(frame, notes)


def _read_csv(path: Path, layout: CsvLayout) -> tuple[pd.DataFrame, tuple[str, ...]]:
    import pandas as pd

    if layout.plain:
        return pd.read_csv(path, comment="#", index_col=False), ()
    names = list(layout.names)
    notes: list[str] = []
    if layout.units is not None:
        cells = list(layout.units) + [""] * (len(names) - len(layout.units))
        names = [f"{n} [{u}]" if u and "[" not in n else n for n, u in zip(names, cells, strict=False)]
        pairs = [f"{n!r}: {u!r}" for n, u in zip(layout.names, cells, strict=False) if u]
        shown = ", ".join(pairs[:8]) + (f" and {len(pairs) - 8} more" if len(pairs) > 8 else "")
        notes.append(f"read the units row under the header (line {layout.header_line + 2}): {shown}")
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
        notes.insert(0, f"skipped {_count(len(layout.title_lines), 'line')} above the header: {shown}")
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


def _count(n: int, word: str) -> str:
    return f"{n} {word}" + ("" if n == 1 else "s")


def _split(line: str, separator: str) -> list[str]:
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
        counts = Counter(len(_split(line, sep)) for _, line in content)
        fields, covered = max(counts.items(), key=lambda kv: (kv[1], kv[0]))
        if fields > 1 and (best is None or covered > best[0]):
            best = (covered, fields, sep)
    if best is None:
        return None
    _, fields, sep = best
    rows = [(k, _split(line, sep)) for k, line in content]
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


__all__ = ["CsvLayout", "SUFFIXES", "Table", "read_table", "read_table_info", "sniff_csv", "write_table"]
