import pytest

from hound_id import io
from hound_id.errors import OutputError


def test_atomic_write_leaves_nothing_half_written(tmp_path):
    target = tmp_path / "out.json"
    target.write_text("old")

    def boom(handle):
        handle.write(b"partial")
        raise RuntimeError("crash while writing")

    with pytest.raises(RuntimeError):
        io.write_with(target, boom)
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.json"]


def test_atomic_write_replaces(tmp_path):
    io.write_json(tmp_path / "a.json", {"schema": "x"})
    assert (tmp_path / "a.json").read_text().startswith("{")
    with pytest.raises(OutputError, match="does not exist"):
        io.write_text(tmp_path / "missing" / "a.txt", "x")
