"""The fit-current verb on seeded logs with known truth: the ladder, the plot's fits, the outputs."""

import pytest
import yaml

from hound_id.dyno.current.run import FitCurrentOptions, fit_current, write_outputs
from hound_id.dyno.simulate.current import simulate
from hound_id.errors import FitError, HoundIdError
from tests.conftest import SAMPLES

HIDDEN = ("linear", "saturation", "coulomb")


@pytest.fixture(scope="module")
def seeded(tmp_path_factory):
    sim = simulate(HIDDEN, seed=3)
    path = tmp_path_factory.mktemp("logs") / "coulomb_log.csv"
    sim.frame.to_csv(path, index=False)
    return path, sim.truth


def test_auto_finds_the_hidden_effect_and_the_true_kt(seeded):
    path, truth = seeded
    result = fit_current(path, FitCurrentOptions(auto=True))
    assert result.ladder is not None
    assert result.ladder[0].model == ("linear", "saturation") and result.start.model == ("linear", "saturation")
    assert "coulomb" in result.fit.model and [s.added for s in result.ladder[1:]][0] == "coulomb"
    kt = result.fit.parameters["kt"]
    assert abs(kt.value - truth["kt"]) < 5 * kt.stderr + 1e-3 * truth["kt"]
    assert result.diagnosis.at_noise_floor
    assert result.report.kt == kt.value and result.report.warnings == result.warnings
    assert list(result.report_json())[-1] == "warnings"
    assert result.motor is None and result.figure is None  # neither --out nor --plot asked for


def test_add_without_auto_diagnoses_once_and_the_plot_compares_with_the_start(seeded, tmp_path):
    path, _ = seeded
    options = FitCurrentOptions(add=("coulomb",), plot=tmp_path / "fit.png")
    result = fit_current(path, options)
    assert result.ladder is None and result.fit.model == HIDDEN
    assert result.figure is not None
    (label0, before), (label1, after) = result.figure.pairs
    assert (label0, label1) == ("before: linear+saturation", "after: linear+saturation+coulomb")
    assert before.model == ("linear", "saturation") and after is result.fit
    assert before.rmse_test > after.rmse_test  # the missing Coulomb friction is in the residual before


def test_progress_names_each_stage(seeded):
    path, _ = seeded
    seen: list[str] = []
    fit_current(path, FitCurrentOptions(model="linear+saturation+coulomb"), on_progress=seen.append)
    assert seen == ["fitting linear+saturation+coulomb", "diagnosing"]


def test_adding_an_effect_the_model_has_is_refused(seeded):
    path, _ = seeded
    with pytest.raises(FitError, match="--add saturation: the model already has it"):
        fit_current(path, FitCurrentOptions(add=("saturation",)))


def test_outputs_are_written_plot_first_and_the_plot_removed_when_out_fails(seeded, tmp_path):
    path, _ = seeded
    plot, sub = tmp_path / "fit.png", tmp_path / "sub"
    sub.mkdir()
    out = sub / "fitted.yaml"
    result = fit_current(path, FitCurrentOptions(auto=True, plot=plot, out=out))
    assert result.motor is not None and result.motor["kt"] == result.fit.parameters["kt"].value
    assert result.motor["name"] == path.stem  # no spec sheet: the motor is named after the log
    write_outputs(result)
    assert plot.read_bytes()[:4] == b"\x89PNG" and yaml.safe_load(out.read_text()) == result.motor
    plot.unlink()
    out.unlink()
    sub.rmdir()  # --out cannot be written any more
    with pytest.raises(HoundIdError):
        write_outputs(result)
    assert not plot.exists()  # both or neither


def _two_regimes(path, high_from: float):
    """A sweep whose last stretch (from ``high_from`` s) goes to twice the current and follows another Kt there."""
    import numpy as np

    rng = np.random.default_rng(4)
    t = np.arange(0.0, 60.0, 1.0 / 200.0)
    late = t >= high_from
    i = np.where(late, 12.0, 5.0) * np.sin(2 * np.pi * 0.4 * t) + rng.normal(0, 0.01, t.size)
    w = 2.0 * np.sin(2 * np.pi * 0.13 * t)
    torque = np.where(late, 0.7, 0.9) * i + rng.normal(0, 0.03, t.size)
    rows = np.column_stack((t, i, torque, w))
    np.savetxt(path, rows, delimiter=",", header="time,current,torque,velocity", comments="", fmt="%.5f")
    return path


def test_a_stretch_that_holds_the_highest_currents_stays_in_the_headline(tmp_path):
    """Left out, the stretch that reaches 12 A would leave a headline of currents up to 5 A and a curve extrapolated
    beyond them; it stays in, flagged, and the whole log is the headline."""
    result = fit_current(_two_regimes(tmp_path / "top.csv", 50.0), FitCurrentOptions(auto=True))
    assert result.report.headline is None, result.report.headline
    assert any(f.startswith("blocks") for f in result.report.flags), result.report.flags


def test_a_flagged_stretch_within_the_current_range_is_left_out_of_the_headline(tmp_path):
    """The same other regime at the currents the rest reaches: the headline is the part that agrees (Kt 0.9), and the
    whole log's fit is beside it."""
    import numpy as np

    path = _two_regimes(tmp_path / "mid.csv", 50.0)
    rows = np.loadtxt(path, delimiter=",", skiprows=1)
    rows[:, 1] = np.where(rows[:, 0] >= 50.0, rows[:, 1] * 5.0 / 12.0, rows[:, 1])  # the late stretch back to 5 A
    rows[:, 2] = np.where(rows[:, 0] >= 50.0, 0.7 * rows[:, 1], rows[:, 2])
    np.savetxt(path, rows, delimiter=",", header="time,current,torque,velocity", comments="", fmt="%.5f")
    result = fit_current(path, FitCurrentOptions(auto=True))
    report = result.report_json()
    assert report["left_out"] and all(s["time"][0] >= 49.0 for s in report["left_out"]), report.get("left_out")
    assert result.fit.value("kt") == pytest.approx(0.9, rel=0.01)
    assert report["whole_log"]["parameters"]["kt"]["value"] < 0.89 and "--whole-log" in report["headline"]["sentence"]
    # the verdict says it holds for the rest of the log only
    assert report["summary"].startswith("the log as a whole does not follow one model: the headline leaves out t = ")
    assert "another regime" in report["summary"] and "on the rest: " in report["summary"]


def test_a_stretch_that_holds_most_of_the_high_currents_stays_in_the_headline(tmp_path):
    """One early cycle reaches the top current, but the rows at high current are nearly all in the stretch that
    follows another law: leaving it out would fit the curve's top to a handful of rows."""
    import numpy as np

    path = _two_regimes(tmp_path / "most.csv", 40.0)
    rows = np.loadtxt(path, delimiter=",", skiprows=1)
    t = rows[:, 0]
    one = (t >= 10.0) & (t < 12.5)  # one cycle at 12 A early on, with the first law
    rows[:, 1] = np.where(one, rows[:, 1] * 12.0 / 5.0, rows[:, 1])
    rows[:, 2] = np.where(one, 0.9 * rows[:, 1], rows[:, 2])
    np.savetxt(path, rows, delimiter=",", header="time,current,torque,velocity", comments="", fmt="%.5f")
    result = fit_current(path, FitCurrentOptions(auto=True))
    left_out = result.report_json().get("left_out", [])
    assert not any(s["time"][0] >= 39.0 for s in left_out), left_out


def test_the_printed_verdict_says_the_headline_left_a_stretch_out(tmp_path):
    """The last line a user reads is the report's summary: 'at the noise floor' is said of the rest of the log."""
    import subprocess
    import sys
    from pathlib import Path

    import numpy as np

    path = _two_regimes(tmp_path / "mid.csv", 50.0)
    rows = np.loadtxt(path, delimiter=",", skiprows=1)
    rows[:, 1] = np.where(rows[:, 0] >= 50.0, rows[:, 1] * 5.0 / 12.0, rows[:, 1])
    rows[:, 2] = np.where(rows[:, 0] >= 50.0, 0.7 * rows[:, 1], rows[:, 2])
    np.savetxt(path, rows, delimiter=",", header="time,current,torque,velocity", comments="", fmt="%.5f")
    exe = Path(sys.executable).with_name("hound-id")
    proc = subprocess.run([str(exe), "fit-current", str(path), "--auto"], capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    tail = " ".join(proc.stdout.split()[-80:])
    assert "the log as a whole does not follow one model" in tail and "on the rest:" in tail, tail


def test_a_wandering_torque_is_named_in_the_printed_verdict_and_the_json(tmp_path):
    """A user's log whose torque zero wanders over seconds (written by the independent polled rig, read through the
    CLI as a user runs it): the last line says the excess is a slow wander with its size, --json carries it."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    from tests.dyno.acquire.polledrig import COLUMNS, Rig, Truth, run, write

    rig = Rig(truth=Truth(coulomb=0.25, gear_friction=0.05), zero_wander=0.3, zero_wander_s=1.5, seed=1, seconds=30.0)
    path = write(run(rig), tmp_path / "wandering.csv")
    exe = str(Path(sys.executable).with_name("hound-id"))
    args = [exe, "fit-current", str(path), "--auto", "--columns", COLUMNS]
    proc = subprocess.run(args, capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    tail = " ".join(proc.stdout.split()[-120:])
    assert "wander" in tail and "N m RMS" in tail, tail
    out = subprocess.run([*args, "--json"], capture_output=True, text=True, check=False)
    report = json.loads(out.stdout)
    assert report["schema"] == "hound-id/fit/3"
    w = report["wander"]
    assert w["kind"] == "slow" or w["floor_is_wander"]
    assert 0.2 < w["slow_rms"] < 0.4 and w["units"]["slow_rms"] == "N m"


def test_the_report_is_typed_pickles_small_and_relabels_every_text(tmp_path):
    """The fleet's workers return the typed report: it pickles back to the same JSON, carries no log arrays (a few
    kB, not the log's size), and a relabelled report names the log as the user gave it everywhere."""
    import json
    import pickle
    import shutil

    from hound_id.dyno.current.fit_report import FitReport

    local = tmp_path / "worker_copy.csv"
    shutil.copy(SAMPLES / "fleet" / "FL_hip.csv", local)
    result = fit_current(local, FitCurrentOptions(auto=True))
    report = result.report
    assert isinstance(report, FitReport)
    blob = pickle.dumps(report)
    assert pickle.loads(blob).to_json() == report.to_json() == result.report_json()
    assert len(blob) < 0.1 * local.stat().st_size
    moved = report.relabel(str(local), "FL_hip.csv")
    text = json.dumps(moved.to_json())
    assert str(local) in json.dumps(report.to_json()) and str(local) not in text and "FL_hip.csv" in text
    assert moved.to_json()["parameters"] == report.to_json()["parameters"] and moved.kt == report.kt
