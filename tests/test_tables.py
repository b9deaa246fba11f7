"""The CSV reader: pyarrow's fast path for plain numeric files gives what pandas gives; anything else is pandas'."""

import numpy as np
import pandas as pd
import pytest

from hound_id.tables import _read_numeric_csv, read_table_info

NUMERIC = (
    "time,current,torque,count\n"
    "0.0,1.5,0.2071,3\n"
    "0.001,-2.25e1,1e-3,4\n"
    "0.002,,-0.125,5\n"
    "0.003,inf,nan,6\n"
    "0.004,0.1,0.30000000000000004,7\n"
)


def _same(a: pd.DataFrame, b: pd.DataFrame) -> None:
    assert list(a.columns) == list(b.columns)
    assert list(a.dtypes) == list(b.dtypes)
    np.testing.assert_array_equal(a.to_numpy(), b.to_numpy())


@pytest.mark.parametrize("bom", ["", "\ufeff"])
def test_a_plain_numeric_csv_is_read_fast_and_as_pandas_reads_it(tmp_path, bom):
    path = tmp_path / "log.csv"
    path.write_text(bom + NUMERIC, encoding="utf-8")
    fast = _read_numeric_csv(path)
    assert fast is not None
    _same(fast, pd.read_csv(path, comment="#", index_col=False))
    _same(read_table_info(path).frame, fast)


@pytest.mark.parametrize(
    "text",
    [
        "time,current,torque\n0,1,2\n# paused\n1,2,3\n",  # a comment line
        "time,current,torque\n0,1,2 # note\n1,2,3\n",  # an inline comment
        "time,current,torque\n0,1,abc\n1,2,3\n",  # a text cell
        "time,current,torque\n2024-01-01T00:00:00,1,2\n2024-01-01T00:00:01,2,3\n",  # timestamps
        "time,current,current\n0,1,2\n1,2,3\n",  # a name twice
        "time,,torque\n0,1,2\n1,2,3\n",  # an empty name
        "time,current,torque\n0,1,2\n1,2\n",  # a short row
        "time,current,torque\n0,true,2\n1,false,3\n",  # booleans
    ],
)
def test_anything_but_a_plain_numeric_csv_is_left_to_pandas(tmp_path, text):
    path = tmp_path / "log.csv"
    path.write_text(text)
    assert _read_numeric_csv(path) is None
    _same(read_table_info(path).frame, pd.read_csv(path, comment="#", index_col=False))


def test_a_numeric_csv_with_a_text_cell_far_down_is_left_to_pandas(tmp_path):
    # pyarrow infers types from its first block; a bad cell past it must not crash or be read as a number
    path = tmp_path / "log.csv"
    rows = [f"{k * 1e-3},{k % 7},{k % 5}" for k in range(200_000)]
    rows[-3] = "199.997,oops,2"
    path.write_text("time,current,torque\n" + "\n".join(rows) + "\n")
    assert _read_numeric_csv(path) is None
    frame = read_table_info(path).frame
    assert not pd.api.types.is_numeric_dtype(frame["current"])
    assert frame["current"].iloc[-3] == "oops"
    assert len(frame) == 200_000
