"""``hound-id fleet`` as a user runs it: the sample fleet on the local cluster and on an existing two-worker one."""

from __future__ import annotations

import json
import logging
import shutil

import pandas as pd
import pytest

from hound_id.samples import samples_dir
from tests.cli.test_mor_cli import PNG_MAGIC
from tests.conftest import restore_sigint, run_cli

SAMPLE = samples_dir() / "fleet"
PLANTED = {
    ("FR_thigh", "kt"),
    ("FR_thigh", "peak_torque"),
    ("RL_hip", "coulomb"),
    ("RL_knee", "gear_friction"),
    ("RR_thigh", "cogging_order"),
}


@pytest.fixture(scope="module")
def sample_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("fleet")
    proc = run_cli(
        "fleet", str(SAMPLE), "--auto", "--workers", "2", "--json", "--csv", "fleet.csv", "--plot", "fleet.png",
        "--reports", "reports", cwd=out,
    )  # fmt: skip
    return out, proc


def test_the_sample_fleet_from_the_command_line(sample_run):
    out, proc = sample_run
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["schema"] == "hound-id/fleet/2" and data["fitted"] == 12 and data["failed"] == []
    assert {(f["actuator"], f["metric"]) for f in data["flags"]} == PLANTED
    assert data["engine"]["local_cluster"] and data["engine"]["workers"] == 2
    assert set(data["model"]) == {"linear", "saturation", "offset", "coulomb", "viscous", "gear_friction", "cogging"}
    assert data["fleet"]["kt"]["unit"] == "N m/A" and data["fleet"]["kt"]["n"] == 12
    # each log's line on stderr as it arrives
    assert sum(line.startswith("ok ") for line in proc.stderr.splitlines()) >= 12
    table = pd.read_csv(out / "fleet.csv")
    assert list(table["actuator"]) == sorted(p.stem for p in SAMPLE.glob("*.csv"))
    assert table.loc[table["actuator"] == "RL_hip", "status"].item() == "flagged"
    assert "bearing" in table.loc[table["actuator"] == "RL_hip", "flags"].item()
    assert (out / "fleet.png").read_bytes().startswith(PNG_MAGIC)
    reports = sorted((out / "reports").glob("*.json"))
    assert len(reports) == 12 and json.loads(reports[0].read_text())["schema"] == "hound-id/fit/3"


def test_the_table_names_each_fault_with_its_reading(tmp_path):
    proc = run_cli("fleet", str(SAMPLE), "--model", "linear+saturation+offset+coulomb+viscous+gear_friction+cogging")
    assert proc.returncode == 0, proc.stderr
    assert "flagged (4 actuators)" in proc.stdout
    for text in (
        "FR_thigh: Kt low: a weakened (demagnetised) magnet or a wrong winding",
        "RL_hip: friction high: a bearing or gearbox problem",
        "RL_knee: load-dependent friction high: a gearbox problem",
        "RR_thigh: cogging order 28/rev against the fleet's 24/rev: a different motor",
    ):
        assert text in proc.stdout


def test_a_failing_log_is_reported_and_the_rest_go_on(tmp_path):
    for path in sorted(SAMPLE.glob("*.csv"))[:6]:
        shutil.copy(path, tmp_path / path.name)
    (tmp_path / "broken.csv").write_text("time,current,torque\n0,1,2\n")
    proc = run_cli("fleet", str(tmp_path), "--workers", "2", "--json")
    assert proc.returncode == 1, proc.stderr
    data = json.loads(proc.stdout)
    assert data["fitted"] == 6 and [f["name"] for f in data["failed"]] == ["broken"]
    assert "FAILED broken:" in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["missing.csv"], "missing.csv: no such file or folder"),
        ([str(SAMPLE), "--tolerance", "kt"], "--tolerance: found 'kt', expected METRIC=FRACTION"),
        ([str(SAMPLE), "--model", "linear+magic"], "magic"),
        ([str(SAMPLE), "--plot", "fleet.jpg"], "plot files end in .png"),
        ([str(SAMPLE), "--csv", "fleet.txt"], "fleet table files end in .csv"),
        ([str(SAMPLE), "--z", "0"], "--z: found 0.0"),
        ([str(SAMPLE), "--workers", "0"], "--workers: found 0"),
        ([str(SAMPLE), "--window", "5:1"], "window"),
    ],
)
def test_bad_input_is_one_line_and_exit_2_before_any_work(tmp_path, args, message):
    proc = run_cli("fleet", *args, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hound-id: error:") and message in lines[0], proc.stderr
    assert list(tmp_path.iterdir()) == []


def test_fit_current_points_a_folder_or_many_logs_to_fleet():
    proc = run_cli("fit-current", str(SAMPLE))
    assert proc.returncode == 2 and f"run 'hound-id fleet {SAMPLE}'" in proc.stderr
    proc = run_cli("fit-current", str(SAMPLE / "FL_hip.csv"), str(SAMPLE / "FL_knee.csv"))
    assert proc.returncode == 2 and "run 'hound-id fleet LOG...'" in proc.stderr


def test_the_same_run_on_an_existing_two_worker_cluster(sample_run):
    from dask.distributed import LocalCluster

    _, local = sample_run
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=logging.ERROR
    ) as cluster:
        proc = run_cli("fleet", str(SAMPLE), "--auto", "--json", "--scheduler", cluster.scheduler_address)
    assert proc.returncode == 0, proc.stderr
    data, before = json.loads(proc.stdout), json.loads(local.stdout)
    assert data["engine"]["scheduler"] == cluster.scheduler_address and not data["engine"]["local_cluster"]
    assert data["engine"]["workers"] == 2
    assert data["flags"] == before["flags"] and data["fleet"] == before["fleet"]


def test_ctrl_c_stops_the_workers_and_writes_nothing(tmp_path):
    import signal
    import subprocess
    import sys
    import time

    import psutil

    proc = subprocess.Popen(
        [sys.executable, "-m", "hound_id", "fleet", str(SAMPLE), "--auto", "--workers", "1", "--csv", "fleet.csv"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=restore_sigint,
    )
    deadline = time.monotonic() + 60
    while not psutil.Process(proc.pid).children(recursive=True) and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(2.0)  # the cluster is up and fitting
    children = psutil.Process(proc.pid).children(recursive=True)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert err.strip().splitlines()[-1] == "hound-id: interrupted"
    assert not (tmp_path / "fleet.csv").exists() and list(tmp_path.iterdir()) == []
    gone, alive = psutil.wait_procs(children, timeout=20)
    assert alive == []  # the local cluster's workers went with it


def test_when_no_log_fits_each_reason_is_given_and_the_exit_is_2(tmp_path):
    (tmp_path / "a.csv").write_text("time,current,torque\n0,1,2\n")
    (tmp_path / "b.csv").write_text("x,y\n1,2\n")
    proc = run_cli("fleet", str(tmp_path), "--workers", "1")
    assert proc.returncode == 2 and proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert lines[-1] == "hound-id: error: none of the 2 logs could be fitted (each one's reason is above)"
    assert sum(line.startswith(("FAILED a:", "FAILED b:")) for line in lines) == 2 and "Traceback" not in proc.stderr


def test_auto_sign_lets_each_log_of_a_fleet_decide_its_torque_sign(tmp_path):
    """Two actuators' sensors mounted the other way: without --auto-sign they fail with the reason, with it every log
    is fitted, the two say 'torque negated', and the fleet flags what it flagged before."""
    folder = tmp_path / "fleet"
    shutil.copytree(SAMPLE, folder, ignore=shutil.ignore_patterns("*.py", "*.json"))
    for name in ("FL_hip", "RR_knee"):
        path = folder / f"{name}.csv"
        frame = pd.read_csv(path)
        frame["torque"] = -frame["torque"]
        frame.to_csv(path, index=False, float_format="%.6g")
    model = "linear+saturation+offset+coulomb+viscous+gear_friction+cogging"
    plain = run_cli("fleet", str(folder), "--model", model, "--workers", "1", "--json")
    assert plain.returncode == 1 and len(json.loads(plain.stdout)["failed"]) == 2
    proc = run_cli("fleet", str(folder), "--model", model, "--auto-sign", "--workers", "1", "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["fitted"] == 12 and {(f["actuator"], f["metric"]) for f in data["flags"]} == PLANTED
    negated = {line.split()[1].rstrip(":") for line in proc.stderr.splitlines() if "torque negated" in line}
    assert negated == {"FL_hip", "RR_knee"}
