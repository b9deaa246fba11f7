"""``fleet --reports DIR``: all reports or none, and the same run again into the same folder.

Logs that share a file name in different folders (``a/m.csv``, ``b/m.csv``) are named by their paths
(:func:`~hound_id.dyno.fleet.engine.actuator_names`: ``a/m``, ``b/m``), so their reports sit in subfolders of the
reports folder (``a/m.json``). Writing them into a folder that already has those subfolders (the same command run
twice) once failed after all the fitting with "Directory not empty", leaving part of the reports.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from hound_id.dyno.current.run import FitCurrentOptions
from hound_id.dyno.fleet.analyse import analyse
from hound_id.dyno.fleet.engine import FleetRun, actuator_names, fit_log
from hound_id.dyno.fleet.run import FleetOptions, FleetResult, write_outputs
from hound_id.dyno.simulate.fleet import FLEET_MODEL
from hound_id.errors import OutputError
from hound_id.samples import samples_dir
from tests.conftest import run_cli

SAMPLE = samples_dir() / "fleet"
OPTIONS = FitCurrentOptions(model=FLEET_MODEL)


@pytest.fixture(scope="module")
def twins(tmp_path_factory) -> list[Path]:
    """Two logs of one file name in two folders: ``a/m.csv`` and ``b/m.csv`` (two actuators of the sample fleet)."""
    root = tmp_path_factory.mktemp("twins")
    paths = []
    for folder, source in (("a", "FL_hip.csv"), ("b", "FL_knee.csv")):
        (root / folder).mkdir()
        paths.append(Path(shutil.copy(SAMPLE / source, root / folder / "m.csv")))
    return paths


@pytest.fixture(scope="module")
def result_for(twins):
    """The fleet result of the twins (fitted in this process) with ``--reports`` set to a given folder."""
    fits = tuple(fit_log(n, str(p), p.read_bytes(), OPTIONS) for n, p in zip(actuator_names(twins), twins, strict=True))
    assert [f.name for f in fits] == ["a/m", "b/m"] and all(f.ok for f in fits)
    run = FleetRun(actuators=fits, model=tuple(FLEET_MODEL.split("+")), scheduler="in process", workers=1, seconds=0)
    report = analyse(fits)

    def make(reports: Path) -> FleetResult:
        return FleetResult(run, report, FleetOptions(reports=reports))

    return make


def tree(folder: Path) -> dict[str, str | None]:
    """Every entry under ``folder``: a file's text, None for a folder."""
    return {str(p.relative_to(folder)): None if p.is_dir() else p.read_text() for p in sorted(folder.rglob("*"))}


def assert_reports(reports: Path, twins: list[Path]) -> None:
    for name, log in zip(("a", "b"), twins, strict=True):
        written = json.loads((reports / name / "m.json").read_text())
        assert written["schema"] == "hound-id/fit/3" and written["source"] == str(log)


def test_the_reports_of_logs_sharing_a_file_name_are_written_again_into_the_same_folder(tmp_path, twins, result_for):
    reports = tmp_path / "reports"
    (reports / "a").mkdir(parents=True)
    (reports / "other.json").write_text('{"kept": 1}\n')  # another run's files stay
    (reports / "a" / "keep.txt").write_text("mine\n")
    write_outputs(result_for(reports))
    assert_reports(reports, twins)
    (reports / "a" / "m.json").write_text("stale\n")
    write_outputs(result_for(reports))  # the same run again: its reports replaced, the rest kept
    assert_reports(reports, twins)
    assert (reports / "other.json").read_text() == '{"kept": 1}\n'
    assert (reports / "a" / "keep.txt").read_text() == "mine\n"
    assert sorted(tree(reports)) == ["a", "a/keep.txt", "a/m.json", "b", "b/m.json", "other.json"]
    assert [p.name for p in tmp_path.iterdir()] == ["reports"]  # no staging folder left beside it


def test_a_report_that_cannot_go_in_leaves_the_reports_folder_as_it_was(tmp_path, result_for):
    reports = tmp_path / "reports"
    (reports / "b" / "m.json").mkdir(parents=True)  # a folder where b/m's report goes
    (reports / "b" / "m.json" / "x.txt").write_text("x\n")
    before = tree(reports)
    with pytest.raises(OutputError, match="--reports") as err:
        write_outputs(result_for(reports))
    assert len(str(err.value).splitlines()) == 1
    assert tree(reports) == before  # a/m's report did not go in alone
    assert [p.name for p in tmp_path.iterdir()] == ["reports"]


def test_the_same_fleet_command_twice_into_one_reports_folder(tmp_path, twins):
    """The user's case: ``fleet a/m.csv b/m.csv --reports reports``, run twice."""
    args = ("fleet", *map(str, twins), "--model", FLEET_MODEL, "--workers", "1", "--reports", "reports")
    for _ in range(2):
        proc = run_cli(*args, cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
        assert "reports written to reports" in proc.stdout
        assert_reports(tmp_path / "reports", twins)
    assert sorted(tree(tmp_path / "reports")) == ["a", "a/m.json", "b", "b/m.json"]
    assert [p.name for p in tmp_path.iterdir()] == ["reports"]
