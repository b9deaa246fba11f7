"""Tables read and written in batches of rows (``hound-id saturate`` on long logs): CSV and Parquet in, the same
format out, memory bounded by the batch, with the same checks as :mod:`hound_id.tables`' whole-table reader."""

from __future__ import annotations

import csv
import sys
from collections.abc import Iterator
from io import BytesIO, StringIO
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hound_id import io
from hound_id.errors import OutputError, TableError
from hound_id.tables import (
    SUFFIXES,
    CsvLayout,
    check_line_lengths,
    check_nul_tail,
    plural_count,
    refuse_repeats,
    sniff_csv,
    split_cells,
    unique_names,
    unit_names,
    unreadable,
)

if TYPE_CHECKING:  # pragma: no cover
    import pyarrow as pa


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
        check_nul_tail(p)
        check_line_lengths(p)
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
            raise unreadable(p, err) from err
        refuse_repeats(p, list(self.layout.names) if self.layout is not None else list(names))
        self.names: tuple[str, ...] = tuple(names)
        """Column names, as :func:`read_table` would name them (extra unnamed fields left out)."""

    def _csv_names(self) -> list[str]:
        layout = self.layout
        assert layout is not None
        names, notes = unit_names(layout)
        if layout.title_lines:
            shown = "; ".join(repr(t[:60]) for t in layout.title_lines[:3])
            notes.insert(0, f"skipped {plural_count(len(layout.title_lines), 'line')} above the header: {shown}")
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
        names = unique_names(names)
        self._extra = tuple(f"field_{len(names) + k + 1}" for k in range(extra))
        return names

    def _first_row_fields(self) -> int:
        """Number of fields of the first data row (0 if there is none)."""
        assert self.layout is not None
        with open(self.path, encoding="utf-8", errors="replace", newline="") as handle:
            for number, text in enumerate(handle):
                if number >= self.layout.first_data_line and text.strip() and not text.lstrip().startswith("#"):
                    return len(split_cells(text, self.layout.separator))
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
            raise unreadable(self.path, err) from err

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
            raise unreadable(self.path, err) from err

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
            raise unreadable(self.path, err) from err

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
            return unreadable(self.path, err)
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
            return unreadable(self.path, err)
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
                if match(text, split_cells(text, self.layout.separator)):
                    return number, data_row
        return 0, 0


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
