import json
import math
import os
import signal
import subprocess
import sys
import time

import pandas as pd
import pytest

from hound_id.dyno.acquire import ReadError, RetryPolicy, record, sidecar_path
from hound_id.errors import DynoDataError


def sine_sampler():
    t0 = time.monotonic()

    def read():
        t = time.monotonic() - t0
        return {"current": 10 * math.sin(t), "torque": math.sin(t)}

    return read


def test_paced_recording_writes_every_sample(tmp_path):
    out = tmp_path / "run.csv"
    result = record(sine_sampler(), ["current", "torque"], out, rate_hz=200.0, duration=0.5, flush_interval=0.05)
    frame = pd.read_csv(out)
    assert list(frame.columns) == ["time", "current", "torque"]
    assert len(frame) == result.samples
    assert result.samples + result.missed == 100
    assert result.status == "complete" and result.achieved_rate == pytest.approx(200, rel=0.25)
    assert frame["time"].is_monotonic_increasing
    meta = json.loads(sidecar_path(out).read_text())
    assert meta["schema"] == "hound-id/record/1" and meta["status"] == "complete"
    assert meta["samples"] == result.samples and meta["rate_requested"] == 200.0


def test_failures_become_gaps_and_a_dead_device_stops_the_run(tmp_path):
    calls = {"n": 0}

    def flaky():
        calls["n"] += 1
        if 30 <= calls["n"] < 60:
            raise ReadError("timeout reading unit 1")
        return {"current": 1.0, "torque": 0.1}

    out = tmp_path / "gaps.csv"
    result = record(flaky, ["current", "torque"], out, rate_hz=500.0, duration=0.2, policy=RetryPolicy(retries=0))
    assert result.status == "complete" and result.failed > 0
    assert len(result.gaps) == 1 and "timeout" in result.gaps[0].reason
    assert len(pd.read_csv(out)) == result.samples

    def dead():
        raise ReadError("connection refused")

    result = record(
        dead,
        ["current", "torque"],
        tmp_path / "dead.csv",
        rate_hz=100.0,
        policy=RetryPolicy(retries=1, give_up_after=0.2),
    )
    assert result.status == "failed" and "connection refused" in result.message
    meta = json.loads(sidecar_path(tmp_path / "dead.csv").read_text())
    assert meta["status"] == "failed" and meta["gaps"]


def test_bad_arguments(tmp_path):
    with pytest.raises(DynoDataError, match="--rate"):
        record(sine_sampler(), ["current"], tmp_path / "a.csv", rate_hz=0)
    with pytest.raises(DynoDataError, match="--duration"):
        record(sine_sampler(), ["current"], tmp_path / "a.csv", rate_hz=10, duration=-1)


SCRIPT = """
import math, sys, time
from pathlib import Path
from hound_id.dyno.acquire import record
t0 = time.monotonic()
def read():
    t = time.monotonic() - t0
    return {"current": 10 * math.sin(t), "torque": math.sin(t)}
print("ready", flush=True)
record(read, ["current", "torque"], Path(sys.argv[1]), rate_hz=500.0, flush_interval=0.1)
"""


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGKILL])
def test_ctrl_c_keeps_everything_and_sigkill_loses_at_most_a_flush(tmp_path, sig):
    out = tmp_path / "killed.csv"
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT, str(out)], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "ready"
        ready_at = time.monotonic()
        time.sleep(1.0)
        killed_at = time.monotonic()
        proc.send_signal(sig)
        proc.wait(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
    frame = pd.read_csv(out)
    assert len(frame) > 100 and not frame.isna().any().any()  # whole rows only
    meta = json.loads(sidecar_path(out).read_text())
    if sig == signal.SIGINT:
        assert meta["status"] == "interrupted" and meta["samples"] == len(frame)
    else:
        assert meta["status"] == "recording"  # never finished; the CSV holds what was flushed
        # the last row on disk is at most a flush interval (0.1 s) before the kill, plus scheduling slack
        lost = (killed_at - ready_at) - float(frame["time"].iloc[-1])
        assert lost < 0.1 + 0.15
    assert os.path.getsize(out) > 0


def test_a_run_without_a_single_sample_has_failed(tmp_path):
    def dead():
        raise ReadError("Modbus 127.0.0.1:1 unit 1: connection refused; serial /dev/ttyUSB9: cannot open")

    result = record(
        dead,
        ["current", "torque"],
        tmp_path / "none.csv",
        rate_hz=50.0,
        duration=0.3,
        policy=RetryPolicy(retries=0, give_up_after=10.0),
    )
    assert result.status == "failed" and "no sample was read" in result.message and "ttyUSB9" in result.message
    with pytest.raises(DynoDataError, match="--flush"):
        record(dead, ["current"], tmp_path / "x.csv", rate_hz=10, flush_interval=0)
