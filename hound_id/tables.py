"""Tabular files (CSV, Parquet) in and out, with one-line errors and atomic writes."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from hound_id import io
from hound_id.errors import OutputError, TableError

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

SUFFIXES = (".csv", ".parquet", ".pq")


def read_table(path: str | Path) -> pd.DataFrame:
    """Read a CSV or Parquet file into a DataFrame.

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
    try:
        frame = pd.read_csv(p, comment="#") if suffix == ".csv" else pd.read_parquet(p)
    except (OSError, ValueError, pd.errors.ParserError, pd.errors.EmptyDataError) as err:
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise TableError(f"{p}: cannot read the table ({first})", path=str(p)) from err
    if frame.empty:
        raise TableError(f"{p}: the table has no rows", path=str(p))
    return frame


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
