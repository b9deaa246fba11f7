import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest
import yaml

from hound_id.dyno.acquire.plan import load_plan
from tests.cli.test_mor_cli import assert_one_line_error
from tests.conftest import restore_sigint, run_cli

# a 12 s plan: four plateaus, short pauses; enough for friction, quick enough for a test
SHORT_PLAN = [
    "--speeds=-10,-2,2,10",
    "--plateau",
    "1.2",
    "--pause",
    "1",
    "--hold",
    "0.6",
    "--transition",
    "0.4",
    "--levels",
    "3",
]


def start_rig(tmp_path, *args):
    rig_file = tmp_path / "sim-rig.yaml"
    proc = subprocess.Popen(
        [sys.executable, "-m", "hound_id", "dyno", "simulate-rig", "--port", "0", "--rig-out", str(rig_file), *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=restore_sigint,
    )
    deadline = time.monotonic() + 30
    while not rig_file.exists() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    assert rig_file.exists(), proc.stderr.read() if proc.poll() is not None else "rig file not written"
    return proc, rig_file


def stop(proc):
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()


def test_plan_command(tmp_path):
    out = tmp_path / "plan.yaml"
    proc = run_cli(
        "dyno",
        "plan",
        "--max-current",
        "40",
        "--out",
        str(out),
        *SHORT_PLAN,
        "--schedule",
        str(tmp_path / "setpoints.csv"),
        "--json",
    )
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["schema"] == "hound-id/plan/1" and data["speeds"] == [-10.0, -2.0, 2.0, 10.0]
    assert set(data["why"]) >= {"speeds", "overdrive", "hold_time", "pause_time"}
    plan, max_current = load_plan(out)
    assert max_current == 40.0 and plan.current_levels == 3
    setpoints = pd.read_csv(tmp_path / "setpoints.csv")
    assert setpoints["current"].abs().max() == pytest.approx(1.3 * 40.0)
    assert set(setpoints["velocity"].round(6)) >= {-10.0, -2.0, 2.0, 10.0}
    assert_one_line_error(
        run_cli("dyno", "plan", "--max-current", "40", "--speeds", "fast", "--out", str(tmp_path / "p.yaml")),
        "--speeds",
    )


def test_simulate_record_fit_names_the_hidden_effect(tmp_path):
    plan = tmp_path / "plan.yaml"
    assert (
        run_cli(
            "dyno",
            "plan",
            "--max-current",
            "70",
            "--out",
            str(plan),
            *SHORT_PLAN,
            "--rise",  # 10 ms edges, which a 500 Hz recording resolves
            "0.01",
        ).returncode
        == 0
    )
    rig, rig_file = start_rig(
        tmp_path, "--effects", "linear,saturation,coulomb", "--seed", "3", "--plan", str(plan), "--duration", "40"
    )
    try:
        out = tmp_path / "run.csv"
        proc = run_cli(
            "dyno", "record", "--rig", str(rig_file), "--out", str(out), "--duration", "11", "--rate", "500", "--json"
        )
        assert proc.returncode == 0, proc.stderr
        meta = json.loads(proc.stdout)
        assert meta["schema"] == "hound-id/record/2" and meta["status"] == "complete"
        assert meta["samples"] == len(pd.read_csv(out)) > 2000
    finally:
        stop(rig)
    fit = run_cli("fit-current", str(out), "--auto", "--json")
    assert fit.returncode == 0, fit.stderr
    data = json.loads(fit.stdout)
    added = [step["added"] for step in data["ladder"][1:]]
    # The hidden effect is found with its size. (The two devices are read one round trip apart, a real skew
    # between the channels that the fit may also pick up as a small 'delay'; on a loaded machine the timing
    # jitter of the polls can add a friction-like term too, so only the hidden effect is required.)
    assert "coulomb" in added
    assert abs(data["parameters"]["coulomb"]["value"] - 0.0773) < 0.02


def test_ctrl_c_stops_recording_with_the_file_valid(tmp_path):
    rig, rig_file = start_rig(tmp_path, "--duration", "30")
    out = tmp_path / "run.csv"
    try:
        rec = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "hound_id",
                "dyno",
                "record",
                "--rig",
                str(rig_file),
                "--out",
                str(out),
                "--rate",
                "200",
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=restore_sigint,
        )
        # wait until the recorder runs (its sidecar appears; slow to start on a loaded machine), then record a while
        deadline = time.monotonic() + 60
        while not (tmp_path / "run.csv.meta.json").exists() and time.monotonic() < deadline and rec.poll() is None:
            time.sleep(0.1)
        time.sleep(1.5)
        rec.send_signal(signal.SIGINT)
        rec.wait(timeout=15)
    finally:
        stop(rig)
    meta = json.loads((tmp_path / "run.csv.meta.json").read_text())
    assert meta["status"] == "interrupted"
    frame = pd.read_csv(out)
    assert len(frame) == meta["samples"] > 50 and not frame.isna().any().any()
    assert os.path.getsize(out) > 0


def test_bad_rig_file_is_one_line(tmp_path):
    rig_file = tmp_path / "rig.yaml"
    rig_file.write_text(yaml.safe_dump({"schema": "hound-id/rig/1", "name": "x", "devices": {}, "channels": []}))
    assert_one_line_error(
        run_cli("dyno", "record", "--rig", str(rig_file), "--out", str(tmp_path / "r.csv"), "--duration", "1"),
        "rig.yaml",
    )
    assert not (tmp_path / "r.csv").exists()


def run_cli_limited(*args, fsize):
    """The command line with a file size limit: writes past ``fsize`` bytes fail (EFBIG), as on a full disk."""
    import resource

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))

    env = dict(os.environ, COLUMNS="200", PYTHONDONTWRITEBYTECODE="1")
    return subprocess.run(
        [sys.executable, "-m", "hound_id", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
        preexec_fn=limit,
    )


def test_plan_applies_rise(tmp_path):
    out, setpoints = tmp_path / "plan.yaml", tmp_path / "setpoints.csv"
    proc = run_cli("dyno", "plan", "--max-current", "40", "--out", str(out), *SHORT_PLAN, "--rise", "0.02")
    assert proc.returncode == 0, proc.stderr
    assert "edges of 0.02 s" in proc.stdout
    plan, _ = load_plan(out)
    assert plan.current_rise_time == 0.02
    run_cli(
        "dyno",
        "plan",
        "--max-current",
        "40",
        "--out",
        str(out),
        *SHORT_PLAN,
        "--rise",
        "0.02",
        "--schedule",
        str(setpoints),
    )
    current = pd.read_csv(setpoints)["current"].to_numpy()
    # the first edge (0 -> the top of the ramp's first leg is slow; the first step is fast): its samples between
    # two levels last the rise time at the schedule's 1 kHz
    steps = np.flatnonzero(np.abs(np.diff(current)) > 0.3)  # > 0.3 A per ms: only the edges of the steps
    runs = np.split(steps, np.flatnonzero(np.diff(steps) > 1) + 1)
    assert np.median([len(r) for r in runs]) == pytest.approx(20, abs=1)


@pytest.mark.parametrize(
    ("option", "value", "fragment"),
    [
        ("--rise", "-0.01", "--rise: found -0.01, expected a positive number of seconds"),
        ("--rise", "0", "--rise: found 0"),
        ("--rise", "0.5", "expected more than --rise 0.5 s"),
        ("--overdrive", "0.5", "--overdrive: found 0.5, expected a number > 1"),
        ("--overdrive", "1", "--overdrive: found 1,"),
        ("--overdrive", "inf", "--overdrive: found inf"),
        ("--levels", "0", "--levels: found 0"),
        ("--plateau", "nan", "--plateau: found nan"),
        ("--pause", "-1", "--pause: found -1, expected a number of seconds >= 0"),
        ("--speeds", "1,nan", "--speeds: found '1,nan'"),
        ("--plateau", "1e6", "the plan lasts"),
        ("--max-current", "-5", "--max-current: found -5"),
    ],
)
def test_plan_options_out_of_range_are_one_line(tmp_path, option, value, fragment):
    args = ["--max-current", "40", "--out", str(tmp_path / "p.yaml")]
    if option == "--max-current":
        args = args[2:]
    assert_one_line_error(run_cli("dyno", "plan", *args, option, value), fragment)
    assert list(tmp_path.iterdir()) == []


def test_plan_outputs_are_all_or_nothing(tmp_path):
    out, setpoints = tmp_path / "plan.yaml", tmp_path / "setpoints.csv"
    # the YAML (2 kB) fits under the limit, the schedule (12 s at 1 kHz) does not
    proc = run_cli_limited(
        "dyno",
        "plan",
        "--max-current",
        "40",
        "--out",
        str(out),
        *SHORT_PLAN,
        "--schedule",
        str(setpoints),
        fsize=20_000,
    )
    assert_one_line_error(proc, f"{setpoints}: cannot write", "File too large", "no plan file was written")
    assert list(tmp_path.iterdir()) == []  # neither output, no temporary file


@pytest.mark.parametrize(
    ("option", "value", "fragment"),
    [
        ("--duration", "-1", "--duration: found -1, expected a positive number of seconds"),
        ("--duration", "0", "--duration: found 0"),
        ("--duration", "nan", "--duration: found nan"),
        ("--duration", "inf", "--duration: found inf"),
        ("--speedup", "0", "--speedup: found 0, expected 0.001 to 1000"),
        ("--speedup", "1e308", "--speedup: found 1e+308"),
        ("--port", "70000", "--port: found 70000"),
        ("--seed", "-1", "--seed: found -1"),
    ],
)
def test_simulate_rig_options_out_of_range_are_one_line(tmp_path, option, value, fragment):
    rig_file = tmp_path / "rig.yaml"
    proc = run_cli("dyno", "simulate-rig", "--port", "0", "--rig-out", str(rig_file), "--no-serial", option, value)
    assert_one_line_error(proc, fragment)
    assert not rig_file.exists()


@pytest.mark.parametrize(
    ("option", "value", "fragment"),
    [
        ("--rate", "1e9", "--rate: found 1e+09 Hz, expected 0.01 to 10000 Hz"),
        ("--rate", "0", "--rate: found 0 Hz"),
        ("--rate", "nan", "--rate: found nan"),
        ("--duration", "-1", "--duration: found -1"),
        ("--flush", "0", "--flush: found 0 s"),
    ],
)
def test_record_options_out_of_range_are_one_line_before_connecting(tmp_path, option, value, fragment):
    rig_file = tmp_path / "rig.yaml"
    rig_file.write_text(
        yaml.safe_dump(
            {
                "schema": "hound-id/rig/1",
                "name": "x",
                "devices": {"d": {"type": "modbus_tcp", "host": "127.0.0.1", "port": 1}},
                "channels": [
                    {"column": "current", "device": "d", "register": 0, "dtype": "int16", "unit": "A"},
                    {"column": "torque", "device": "d", "register": 1, "dtype": "int16", "unit": "N*m"},
                ],
            }
        )
    )
    out = tmp_path / "r.csv"
    assert_one_line_error(run_cli("dyno", "record", "--rig", str(rig_file), "--out", str(out), option, value), fragment)
    assert not out.exists() and not (tmp_path / "r.csv.meta.json").exists()
