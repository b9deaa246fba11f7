"""hound_id.export.run.run_export: the export verb the CLI and the demo call."""

import json

import pytest

from hound_id.errors import SpecError
from hound_id.export.run import ExportOptions, run_export, write_outputs
from tests.conftest import ROBOT
from tests.export.conftest import fitted_motor


def test_the_verb_builds_the_formats_with_the_fit_and_write_outputs_writes_them(tmp_path):
    """The verb writes nothing: its frozen result holds every file's text; write_outputs writes exactly those."""
    fit = fitted_motor(tmp_path)
    result = run_export(ROBOT, tmp_path / "out", ExportOptions("bundle,urdf", (fit,)))
    assert not (tmp_path / "out").exists()
    write_outputs(result)
    for written in result.formats.values():
        for name, text in written.files.items():
            assert (tmp_path / "out" / name).read_text() == text
    report = result.to_json()
    assert report["schema"] == "hound-id/export/1" and list(report["formats"]) == ["bundle", "urdf"]
    assert report["fitted_motors"] == ["hound_ilm85"]
    files = [f for part in report["formats"].values() for f in part["files"]]
    assert files and all((tmp_path / "out" / f.split("/")[-1]).is_file() for f in files)
    bundle = next(f for f in files if f.endswith(".json") or f.endswith(".yaml"))
    assert "hound_ilm85" in (tmp_path / "out" / bundle.split("/")[-1]).read_text()
    json.dumps(report)  # the report is plain JSON


def test_bad_options_are_refused_before_anything_is_written(tmp_path):
    with pytest.raises(SpecError, match="--format: found 'stl'"):
        run_export(ROBOT, tmp_path / "out", ExportOptions("stl"))
    with pytest.raises(SpecError, match="--mujoco-actuator"):
        run_export(ROBOT, tmp_path / "out", ExportOptions("bundle", mujoco_actuator="position"))
    assert not (tmp_path / "out").exists()
