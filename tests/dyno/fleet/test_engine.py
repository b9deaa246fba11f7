"""The engine: which files a fleet takes, actuator names, and the same fits on a two-worker Dask cluster."""

from __future__ import annotations

import shutil

import pytest

from hound_id.dyno.current.run import FitCurrentOptions
from hound_id.dyno.fleet.analyse import ActuatorFit
from hound_id.dyno.fleet.engine import actuator_names, common_model, find_logs, fit_log, run_fleet
from hound_id.dyno.simulate.fleet import FLEET_MODEL
from hound_id.errors import FleetError
from hound_id.samples import samples_dir
from tests.dyno.fleet.conftest import typed_report

SAMPLE = samples_dir() / "fleet"


def test_files_folders_and_patterns_without_repeats(tmp_path):
    for name in ("a.csv", "b.parquet", "c.txt", "d.CSV"):
        (tmp_path / name).write_text("x")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "e.csv").write_text("x")
    found = find_logs([tmp_path, tmp_path / "a.csv", str(tmp_path / "**" / "*.csv")])
    assert [p.name for p in found] == ["a.csv", "b.parquet", "d.CSV", "e.csv"]


@pytest.mark.parametrize(
    ("item", "message"),
    [
        ("missing.csv", "no such file or folder"),
        ("nothing-*.csv", "no file matches the pattern"),
        ("empty", "the folder holds no log"),
    ],
)
def test_an_item_that_names_no_log_is_one_clear_error(tmp_path, item, message):
    (tmp_path / "empty").mkdir()
    with pytest.raises(FleetError, match=message):
        find_logs([str(tmp_path / item)])


def test_names_are_file_stems_or_paths_when_stems_repeat(tmp_path):
    (tmp_path / "left").mkdir()
    (tmp_path / "right").mkdir()
    paths = [tmp_path / "left" / "knee.csv", tmp_path / "right" / "knee.csv"]
    assert actuator_names(paths) == ["left/knee", "right/knee"]
    assert actuator_names([tmp_path / "hip.csv", tmp_path / "knee.parquet"]) == ["hip", "knee"]
    assert actuator_names([tmp_path / "a.csv", tmp_path / "a.parquet"]) == ["a.csv", "a.parquet"]


def test_a_bad_log_fails_alone_with_the_message_fit_current_gives(tmp_path):
    bad = tmp_path / "broken.csv"
    bad.write_text("time,current\n0,1\n1,2\n")
    fit = fit_log("broken", str(bad), bad.read_bytes(), FitCurrentOptions())
    assert not fit.ok and not fit.bug
    assert fit.error is not None and fit.error.startswith(str(bad)) and "torque" in fit.error
    assert "hound-id-fleet-" not in fit.error  # the worker's copy is never named


def test_a_two_worker_cluster_gives_the_fits_of_this_process(tmp_path, cluster):
    logs = sorted(SAMPLE.glob("*.csv"))[:4]
    for path in logs[:2]:
        shutil.copy(path, tmp_path / path.name)
    bad = tmp_path / "broken.csv"
    bad.write_text("time,current,torque\n0,1,oops\n")
    options = FitCurrentOptions(model=FLEET_MODEL)
    seen = []
    run = run_fleet(
        [*logs, bad], options, scheduler=cluster.scheduler_address, on_result=lambda f, k, n: seen.append((k, n))
    )
    assert run.workers == 2 and run.scheduler == cluster.scheduler_address
    assert sorted(seen) == [(k, 5) for k in range(1, 6)]
    by_name = {a.name: a for a in run.actuators}
    assert not by_name["broken"].ok and "oops" in (by_name["broken"].error or "")
    assert len({a.worker for a in run.actuators if a.ok}) == 2  # both workers fitted logs
    for path in logs:  # the same code as in this process: the same numbers
        here = fit_log(path.stem, str(path), path.read_bytes(), options)
        there = by_name[path.stem]
        assert there.report is not None and here.report is not None
        assert there.report.to_json()["parameters"] == here.report.to_json()["parameters"]  # NaN errors as null
        assert there.report.source == str(path)


def test_auto_compares_the_fleet_on_the_effects_most_logs_need(cluster):
    logs = sorted(SAMPLE.glob("*.csv"))
    run = run_fleet(logs, FitCurrentOptions(auto=True), scheduler=cluster.scheduler_address)
    assert set(run.model) == set(FLEET_MODEL.split("+"))
    assert all(a.report is not None and set(a.report.model) == set(run.model) for a in run.actuators)


def _fit(name, model):
    return ActuatorFit(name, f"{name}.csv", typed_report(model, {}))


def test_the_fleet_model_takes_what_more_than_half_of_the_logs_added():
    fits = [
        _fit("a", ["linear", "saturation", "coulomb", "viscous"]),
        _fit("b", ["linear", "saturation", "viscous", "coulomb"]),
        _fit("c", ["linear", "saturation", "coulomb", "stribeck"]),  # one bearing needs more
        _fit("d", ["linear", "saturation", "coulomb"]),
        ActuatorFit("e", "e.csv", None, "failed"),  # not counted
    ]
    assert common_model(fits, ["linear", "saturation"]) == ("linear", "saturation", "coulomb")
    assert common_model(fits[:2], ["linear", "saturation"]) == ("linear", "saturation", "coulomb", "viscous")
    assert common_model([], ["linear"]) == ("linear",)


def test_options_a_fleet_cannot_take_fail_before_any_work(tmp_path):
    for options, message in (
        (FitCurrentOptions(plot=tmp_path / "x.png"), "--plot"),
        (FitCurrentOptions(spec=tmp_path / "m.yaml"), "--spec"),
        (FitCurrentOptions(effects_files=(tmp_path / "e.py",)), "--effects-file"),
    ):
        with pytest.raises(FleetError, match=message):
            run_fleet([SAMPLE / "FL_hip.csv"], options, scheduler="tcp://127.0.0.1:1")


def test_an_unreachable_scheduler_is_one_clear_error(monkeypatch):
    monkeypatch.setattr("hound_id.dyno.fleet.engine.CONNECT_TIMEOUT", 1.0)
    with pytest.raises(FleetError, match="cannot reach a Dask scheduler"):
        run_fleet([SAMPLE / "FL_hip.csv"], FitCurrentOptions(), scheduler="tcp://127.0.0.1:9")


def test_workers_and_scheduler_together_are_refused(cluster):
    with pytest.raises(FleetError, match="give one or the other"):
        run_fleet([SAMPLE / "FL_hip.csv"], FitCurrentOptions(), scheduler=cluster.scheduler_address, workers=2)
    with pytest.raises(FleetError, match="expected 1 or more"):
        run_fleet([SAMPLE / "FL_hip.csv"], FitCurrentOptions(), workers=0)


def test_logs_scattered_ahead_of_their_task_give_the_same_fits(cluster, monkeypatch):
    monkeypatch.setattr("hound_id.dyno.fleet.engine.SCATTER_BYTES", 0)  # every log takes the large-log path
    logs = sorted(SAMPLE.glob("*.csv"))[:2]
    options = FitCurrentOptions(model=FLEET_MODEL)
    run = run_fleet(logs, options, scheduler=cluster.scheduler_address)
    for path, there in zip(logs, run.actuators, strict=True):
        here = fit_log(path.stem, str(path), path.read_bytes(), options)
        assert there.report is not None and there.report.to_json()["parameters"] == here.report.to_json()["parameters"]
