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
import os
import sys
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from io import BytesIO, StringIO
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hound_id import io
from hound_id.errors import OutputError, TableError

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd
    import pyarrow as pa

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
    _check_nul_tail(p)
    _check_line_lengths(p)
    notes: tuple[str, ...] = ()
    try:
        if suffix != ".csv":
            frame = pd.read_parquet(p)
        else:
            layout = sniff_csv(p)
            frame, notes = _read_csv(p, layout) if layout is not None else (pd.read_csv(p, comment="#"), ())
    except (OSError, ValueError, pd.errors.ParserError, pd.errors.EmptyDataError) as err:
        raise _unreadable(p, err) from err
    if frame.empty:
        raise TableError(f"{p}: the table has no rows", path=str(p))
    _refuse_repeats(p, list(layout.names) if suffix == ".csv" and layout is not None else list(frame.columns))
    return Table(frame, notes)


def _refuse_repeats(path: Path, header: list[Any]) -> None:
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


def _check_line_lengths(path: Path) -> None:
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


def _check_nul_tail(path: Path) -> None:
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


def _unit_names(layout: CsvLayout) -> tuple[list[str], list[str]]:
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
    names, notes = _unit_names(layout)
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


# --- Streaming: tables read and written in batches of rows (``hound-id saturate``) ---------------------------

#: Rows per batch of a streamed Parquet file (or a CSV read through pandas).
BATCH_ROWS = 16_384
#: Bytes of CSV text parsed per batch (about 5,000 rows of 25 numbers; pyarrow holds ~40 blocks in flight).
CSV_BLOCK_BYTES = 1 << 20
#: What a column whose values do not fit the type read from the first rows is read as next.
_WIDER = {"null": "double", "int64": "double", "bool": "string", "double": "string"}


class TableRetype(Exception):
    """Raised by :meth:`TableBatches.__iter__` when a column's type had to be widened part-way through
    the file (the first rows read as integers, a later one holds 0.5): start again, the next pass
    reads the column with the wider type. Not an error the user sees."""


class TableBatches:
    """A CSV or Parquet file read as pyarrow record batches, so that memory is bounded by a batch
    whatever the length of the file (:data:`BATCH_ROWS` rows of Parquet, :data:`CSV_BLOCK_BYTES` of CSV).

    CSV layouts are found as by :func:`read_table_info` (:func:`sniff_csv`). Columns named in
    ``numeric`` are read as float64 (empty cells and ``nan``/``NA`` as NaN). With ``text``, every CSV
    column is read as its text instead, to be written back unchanged (numbers are then converted by
    the caller); ``only`` reads just those columns (nothing to pass through). Stricter than
    :func:`read_table` where the layout is doubtful, since a batch cannot be read again:

    * a row whose number of fields differs from the others is refused, naming its line
      (a trailing or doubled separator on some rows);
    * rows with more fields than the header has names are accepted only when the extra fields
      are empty or constant (a trailing separator on every row); extra fields that vary mean
      the values are shifted against the names (a leading separator), and are refused.

    Raises:
        TableError: Missing file, folder, unknown format, unreadable table (at open or while iterating).
    """

    def __init__(
        self, path: str | Path, numeric: tuple[str, ...] = (), text: bool = False, only: tuple[str, ...] | None = None
    ) -> None:
        p = Path(path)
        suffix = p.suffix.lower()
        if p.is_dir():
            raise TableError(f"{p}: is a folder; expected a .csv or .parquet file", path=str(p))
        if suffix not in SUFFIXES:
            raise TableError(
                f"{p}: unknown table format {suffix or '(no suffix)'}; expected .csv or .parquet", path=str(p)
            )
        io.check_input(p, "table (.csv or .parquet)", TableError)
        _check_nul_tail(p)
        _check_line_lengths(p)
        self.path = p
        self.numeric = tuple(numeric)
        self.text = text
        self.only = only
        self.notes: tuple[str, ...] = ()
        self.layout: CsvLayout | None = None
        self._types: dict[str, str] = {}
        self._extra: tuple[str, ...] = ()
        try:
            if suffix != ".csv":
                import pyarrow.parquet as pq

                # pages read as needed (1 MB buffers), not whole row groups: memory bounded whatever their size
                self._parquet = pq.ParquetFile(p, pre_buffer=False, buffer_size=1 << 20)
                names = [n for n in self._parquet.schema_arrow.names if not n.startswith("__index_level_")]
                if self._parquet.metadata.num_rows == 0:
                    raise TableError(f"{p}: the table has no rows", path=str(p))
            else:
                self.layout = sniff_csv(p)
                names = self._csv_names() if self.layout is not None else self._pandas_names()
        except (OSError, ValueError) as err:
            if isinstance(err, TableError):
                raise
            raise _unreadable(p, err) from err
        _refuse_repeats(p, list(self.layout.names) if self.layout is not None else list(names))
        self.names: tuple[str, ...] = tuple(names)
        """Column names, as :func:`read_table` would name them (extra unnamed fields left out)."""

    def _csv_names(self) -> list[str]:
        layout = self.layout
        assert layout is not None
        names, notes = _unit_names(layout)
        if layout.title_lines:
            shown = "; ".join(repr(t[:60]) for t in layout.title_lines[:3])
            notes.insert(0, f"skipped {_count(len(layout.title_lines), 'line')} above the header: {shown}")
        if layout.separator != ",":
            shown = "a tab" if layout.separator == chr(9) else repr(layout.separator)
            notes.insert(0, f"fields are separated by {shown}")
        first = self._first_row_fields()
        if 0 < first < len(names) and not any(names[first:]):  # "a,b,c," over "1,2,3": the header's separator
            names = names[:first]
            notes.append("the header ends with a separator; its empty last name was dropped")
        extra = layout.extra_fields
        if extra:
            notes.append(
                f"every row has {len(names) + extra} fields but the header names {len(names)} "
                "(a trailing separator): the extra fields are empty or constant and were dropped"
            )
        self.notes = tuple(notes)
        names = _unique(names)
        self._extra = tuple(f"field_{len(names) + k + 1}" for k in range(extra))
        return names

    def _first_row_fields(self) -> int:
        """Number of fields of the first data row (0 if there is none)."""
        assert self.layout is not None
        with open(self.path, encoding="utf-8", errors="replace", newline="") as handle:
            for number, text in enumerate(handle):
                if number >= self.layout.first_data_line and text.strip() and not text.lstrip().startswith("#"):
                    return len(_split(text, self.layout.separator))
        return 0

    def _pandas_names(self) -> list[str]:
        import pandas as pd

        head = pd.read_csv(self.path, comment="#", index_col=False, nrows=0)
        return [str(c) for c in head.columns]

    def __iter__(self) -> Iterator[pa.RecordBatch]:
        """The batches in file order. Raises :class:`TableRetype` (start again) or :class:`TableError`."""
        if self.layout is None and self.path.suffix.lower() == ".csv":
            return self._pandas_batches()
        if self.layout is None:
            return self._parquet_batches()
        return self._csv_batches()

    def _parquet_batches(self) -> Iterator[pa.RecordBatch]:
        try:
            # one thread, here and in the CSV reader: the caller's numpy work runs between batches
            yield from self._parquet.iter_batches(
                batch_size=BATCH_ROWS, columns=list(self.only or self.names), use_threads=False
            )
        except (OSError, ValueError) as err:
            raise _unreadable(self.path, err) from err

    def _pandas_batches(self) -> Iterator[pa.RecordBatch]:
        import pandas as pd
        import pyarrow as pa

        schema = None
        try:
            for chunk in pd.read_csv(self.path, comment="#", index_col=False, chunksize=BATCH_ROWS):
                if schema is None:
                    schema = pa.Schema.from_pandas(chunk, preserve_index=False)
                yield pa.RecordBatch.from_pandas(chunk, schema=schema, preserve_index=False)
        except (OSError, ValueError, pa.ArrowException, pd.errors.ParserError, pd.errors.EmptyDataError) as err:
            raise _unreadable(self.path, err) from err

    def _csv_batches(self) -> Iterator[pa.RecordBatch]:
        import pyarrow as pa
        import pyarrow.csv as pcsv

        layout = self.layout
        assert layout is not None
        columns = [*self.names, *self._extra]
        bad_rows: list[Any] = []

        def invalid(row: Any) -> str:
            if not row.text.strip() or row.text.lstrip().startswith("#"):
                return "skip"  # blank and comment lines, as pandas' comment="#"
            bad_rows.append(row)
            return "error"

        if self.text:
            types = {name: pa.string() for name in columns}
        else:
            types = {name: pa.float64() for name in self.numeric if name in self.names}
            types.update({name: pa.type_for_alias(t) for name, t in self._types.items()})
        keep = list(self.only or self.names)
        try:
            reader = pcsv.open_csv(
                self.path,
                read_options=pcsv.ReadOptions(
                    skip_rows=layout.first_data_line,
                    column_names=columns,
                    block_size=CSV_BLOCK_BYTES,
                    use_threads=False,
                ),
                parse_options=pcsv.ParseOptions(delimiter=layout.separator, invalid_row_handler=invalid),
                convert_options=pcsv.ConvertOptions(
                    column_types=types, include_columns=keep + list(self._extra), strings_can_be_null=not self.text
                ),
            )
            constant: dict[str, Any] = {}
            rows = 0
            for batch in reader:
                for name in self._extra:
                    self._check_extra(batch, name, constant, rows)
                rows += batch.num_rows
                yield batch.select(keep) if self._extra else batch
        except pa.ArrowInvalid as err:
            if "Empty CSV file" in str(err):
                return  # a header and no rows: the caller says so
            raise self._csv_error(err, bad_rows, columns) from err
        except OSError as err:
            raise _unreadable(self.path, err) from err

    def _check_extra(self, batch: Any, name: str, constant: dict[str, Any], rows: int) -> None:
        """Refuse an unnamed extra field that varies: the values are then shifted against the names."""
        values = batch.column(name).to_pylist()
        for k, value in enumerate(values):
            if value is None or (isinstance(value, str) and not value.strip()):
                continue  # an empty trailing field
            first = constant.setdefault(name, value)
            if value != first:
                n = len(self.names)
                raise TableError(
                    f"{self.path}: the rows have {n + len(self._extra)} fields but the header names {n}, and the "
                    f"extra field varies ({first!r}, then {value!r} in data row {rows + k + 1}): the values are "
                    "shifted against the column names (a leading or doubled separator?); make every row have one "
                    "field per name",
                    path=str(self.path),
                    row=rows + k + 1,
                )

    def _csv_error(self, err: Exception, bad_rows: list[Any], columns: list[str]) -> Exception:
        """The one-line error (or :class:`TableRetype`) for a pyarrow CSV error."""
        import re

        message = str(err)
        if bad_rows:
            row = bad_rows[0]
            line, data_row = self._find_line(lambda text, _: text.rstrip("\r\n") == row.text)
            where_ = f"line {line} (data row {data_row})" if line else "a row"
            names = len(self.names)
            others = (
                f"the header has {names}"
                if not self._extra
                else f"the other rows have {row.expected_columns} (the header names {names})"
            )
            hint = "a trailing separator?" if row.actual_columns > row.expected_columns else "a missing field?"
            return TableError(
                f"{self.path}: {where_} has {row.actual_columns} fields, {others}; {hint} Give every row "
                "the same fields as the header",
                path=str(self.path),
                row=data_row,
            )
        found = re.search(
            r"In CSV column #(\d+): (?:Row #\d+: )?CSV conversion error to (\w+): invalid value '(.*)'", message
        )
        if found is None:
            return _unreadable(self.path, err)
        index, to_type, value = int(found.group(1)), found.group(2), found.group(3)
        name = columns[index]
        if name in self.numeric:
            _, data_row = self._find_line(lambda _, cells: len(cells) > index and cells[index].strip() == value.strip())
            return TableError(
                f"{self.path}: column '{name}' data row {data_row} holds {value.strip()!r}; expected a number",
                column=name,
                row=data_row,
            )
        wider = _WIDER.get(to_type)
        if wider is None:
            return _unreadable(self.path, err)
        self._types[name] = wider
        return TableRetype(name)

    def _find_line(self, match: Any) -> tuple[int, int]:
        """(line, data row) counted from 1 of the first data line for which ``match(text, cells)`` holds,
        blank and comment lines skipped as the reader skips them; (0, 0) if none (error path only)."""
        assert self.layout is not None
        data_row = 0
        with open(self.path, encoding="utf-8", errors="replace", newline="") as handle:
            for number, text in enumerate(handle, start=1):
                if number <= self.layout.first_data_line:
                    continue
                if not text.strip() or text.lstrip().startswith("#"):
                    continue
                data_row += 1
                if match(text, _split(text, self.layout.separator)):
                    return number, data_row
        return 0, 0


def _unique(names: list[str]) -> list[str]:
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


def _unreadable(path: Path, err: Exception) -> TableError:
    if isinstance(err, UnicodeDecodeError):
        return TableError(
            f"{path}: is not UTF-8 text (byte {err.object[err.start]:#04x} at {err.start}); save it as UTF-8 (iconv "
            f"-t UTF-8 {path.name} > utf8-{path.name}) and read the copy",
            path=str(path),
        )
    first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
    return TableError(f"{path}: cannot read the table ({first})", path=str(path))


class TableSink:
    """Record batches written to a CSV or Parquet file as they come (by suffix), through a temporary file
    beside it that replaces the target only when :meth:`close` is reached: a failure part-way leaves
    nothing behind. Use as a context manager.

    CSV: text columns are written as they are (quoted only where a cell needs it), numbers in their
    shortest round-trip form.
    """

    def __init__(self, path: str | Path) -> None:
        p = Path(path)
        if p.suffix.lower() not in SUFFIXES:
            raise OutputError(
                f"{p}: unknown table format {p.suffix or '(no suffix)'}; use .csv or .parquet", path=str(p)
            )
        self.path = p
        self._atomic: Any = None
        self._handle: Any = None
        self._writer: Any = None
        self._started = False

    def __enter__(self) -> TableSink:
        self._atomic = io.atomic_path(self.path)
        tmp = self._atomic.__enter__()
        try:
            self._handle = open(tmp, "wb")  # noqa: SIM115 - closed in __exit__
        except BaseException:
            self._atomic.__exit__(*sys.exc_info())
            raise
        return self

    def write(self, batch: pa.RecordBatch) -> None:
        """Append a batch (every batch with the schema of the first)."""
        try:
            if self.path.suffix.lower() == ".csv":
                self._write_csv(batch)
                return
            if self._writer is None:
                import pyarrow as pa
                import pyarrow.parquet as pq

                # no dictionaries for float columns: measured values rarely repeat, and trying costs 2.5x the time
                coded = [f.name for f in batch.schema if not pa.types.is_floating(f.type)]
                self._writer = pq.ParquetWriter(self._handle, batch.schema.remove_metadata(), use_dictionary=coded)
            self._writer.write_batch(batch)
        except OSError as err:
            raise OutputError(f"{self.path}: cannot write ({err.strerror or err})", path=str(self.path)) from err

    def _write_csv(self, batch: pa.RecordBatch) -> None:
        """Text cells go out as they came in (unquoted, so a CSV read as text is copied unchanged) unless
        one needs quotes; numbers in their shortest round-trip form."""
        import pyarrow as pa
        import pyarrow.csv as pcsv

        if not self._started:
            self._handle.write(_csv_line(batch.schema.names).encode("utf-8"))
            self._started = True
        text = io_buffer = BytesIO()
        try:
            pcsv.write_csv(batch, io_buffer, pcsv.WriteOptions(include_header=False, quoting_style="none"))
        except pa.ArrowInvalid:  # a cell holds the separator, a quote or a line break
            text = BytesIO()
            pcsv.write_csv(batch, text, pcsv.WriteOptions(include_header=False))
        self._handle.write(text.getbuffer())

    def __exit__(self, kind: Any, value: Any, traceback: Any) -> None:
        try:
            if self._writer is not None:
                self._writer.close()
            self._handle.close()
        except OSError as err:
            if kind is None:
                kind, value, traceback = type(err), err, err.__traceback__
        finally:
            self._atomic.__exit__(kind, value, traceback)


def _csv_line(cells: list[str]) -> str:
    """One CSV line with the csv module's minimal quoting."""
    buffer = StringIO()
    csv.writer(buffer, lineterminator="\n").writerow(cells)
    return buffer.getvalue()
