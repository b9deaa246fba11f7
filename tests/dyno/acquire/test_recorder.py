import json
import math
import os
import signal
import subprocess
import sys
import threading
import time

import pandas as pd
import pytest
import yaml

from hound_id.dyno.acquire.log_file import CsvLog, sidecar_path
from hound_id.dyno.acquire.recorder import ReadError, RetryPolicy, record
from hound_id.errors import DynoDataError, OutputError
from tests.conftest import restore_sigint


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
    assert meta["schema"] == "hound-id/record/2" and meta["status"] == "complete"
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
    meta = result.metadata  # what the sidecar said: a run with no sample leaves no file
    assert meta["status"] == "failed" and meta["gaps"]
    assert not (tmp_path / "dead.csv").exists() and not sidecar_path(tmp_path / "dead.csv").exists()


def test_bad_arguments(tmp_path):
    with pytest.raises(DynoDataError, match="--rate"):
        record(sine_sampler(), ["current"], tmp_path / "a.csv", rate_hz=0)
    with pytest.raises(DynoDataError, match="--duration"):
        record(sine_sampler(), ["current"], tmp_path / "a.csv", rate_hz=10, duration=-1)


SCRIPT = """
import math, sys, time
from pathlib import Path
from hound_id.dyno.acquire.recorder import record
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
    proc = subprocess.Popen(
        [sys.executable, "-c", SCRIPT, str(out)], stdout=subprocess.PIPE, text=True, preexec_fn=restore_sigint
    )
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


# --- ticks: samples, gaps and missed ticks ----------------------------------------------------------------------


def test_every_tick_is_a_sample_a_gap_tick_or_a_missed_tick_and_lines_end_in_lf(tmp_path):
    calls = {"n": 0}

    def flaky():
        calls["n"] += 1
        if 20 <= calls["n"] < 40:
            raise ReadError("timeout reading unit 1")
        return {"current": 1.0, "torque": 0.1}

    out = tmp_path / "run.csv"
    result = record(flaky, ["current", "torque"], out, rate_hz=200.0, duration=0.5, policy=RetryPolicy(retries=0))
    assert result.samples + result.missed + result.failed == 100
    data = out.read_bytes()
    assert b"\r" not in data and data.endswith(b"\n") and data.startswith(b"time,current,torque\n")
    (gap,) = result.gaps
    frame = pd.read_csv(out)
    # the gap runs from the last good sample to the next one: exactly the hole in the file
    k = int(frame["time"].diff().idxmax())
    assert gap.start == pytest.approx(frame["time"][k - 1], abs=1e-6)
    assert gap.end == pytest.approx(frame["time"][k], abs=1e-6)
    assert gap.ticks == result.failed >= 20


def test_a_late_loop_with_good_reads_misses_ticks_and_makes_no_gap(tmp_path):
    def slow():  # 1.5 ms a read at 1 kHz: the loop cannot keep up, but the device answers every time
        time.sleep(0.0015)
        return {"current": 1.0, "torque": 0.1}

    result = record(slow, ["current", "torque"], tmp_path / "late.csv", rate_hz=1000.0, duration=0.5)
    assert result.missed > 100 and result.failed == 0 and result.gaps == ()
    assert result.samples + result.missed == 500


def test_a_read_that_blocks_is_a_gap_and_the_sidecar_shows_it_while_it_blocks(tmp_path):
    calls = {"n": 0}

    def hangs_once():
        calls["n"] += 1
        if calls["n"] == 20:
            time.sleep(1.2)  # a peer that hangs, then answers
        return {"current": 1.0, "torque": 0.1}

    out = tmp_path / "hang.csv"
    seen = {}

    def look():  # 0.9 s into the hang, from another thread: the sidecar was rewritten meanwhile
        deadline = time.monotonic() + 10
        while calls["n"] < 20 and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(0.9)
        seen.update(json.loads(sidecar_path(out).read_text()))

    watcher = threading.Thread(target=look)
    watcher.start()
    result = record(hangs_once, ["current", "torque"], out, rate_hz=100.0, duration=2.0, flush_interval=0.1)
    watcher.join()
    assert seen["status"] == "recording"
    (open_gap,) = seen["gaps"]
    assert open_gap["end"] is None and "blocked" in open_gap["reason"] and open_gap["ticks"] >= 50
    assert seen["failed_ticks"] == open_gap["ticks"]
    (gap,) = result.gaps
    assert gap.end - gap.start == pytest.approx(1.2, abs=0.1)
    assert 110 <= gap.ticks <= 125 and result.missed < 10
    assert result.samples + result.missed + result.failed == 200


def test_settings_out_of_range_are_refused_before_anything_is_written(tmp_path):
    out = tmp_path / "a.csv"
    started = time.monotonic()
    with pytest.raises(DynoDataError, match=r"--rate: found 1e\+09 Hz, expected 0.01 to 10000 Hz"):
        record(sine_sampler(), ["current"], out, rate_hz=1e9, duration=1.0)
    assert time.monotonic() - started < 0.5
    for kwargs, match in (
        ({"rate_hz": math.nan}, "--rate"),
        ({"rate_hz": 10.0, "duration": math.inf}, "--duration"),
        ({"rate_hz": 10.0, "duration": math.nan}, "--duration"),
        ({"rate_hz": 10.0, "flush_interval": 1e-4}, "--flush"),
    ):
        with pytest.raises(DynoDataError, match=match):
            record(sine_sampler(), ["current"], out, **kwargs)
    assert list(tmp_path.iterdir()) == []


# --- the output file: a lock, a full disk ------------------------------------------------------------------------


def test_a_file_being_recorded_is_refused_to_a_second_recorder(tmp_path):
    out = tmp_path / "run.csv"
    first = CsvLog(out, ["current"])
    sidecar_path(out).write_text(json.dumps({"status": "recording", "pid": 4242}))
    first.append(["0.0,1.0\n"])
    try:
        with pytest.raises(OutputError, match=r"run.csv: another recorder \(PID 4242\) is writing this file"):
            record(sine_sampler(), ["current"], out, rate_hz=10.0, duration=0.2)
        assert out.read_bytes() == b"time,current\n0.0,1.0\n"  # untouched: not even truncated
    finally:
        first.close()
    record(sine_sampler(), ["current"], out, rate_hz=10.0, duration=0.2, overwrite=True)  # free again


def test_a_device_as_the_output_is_refused_before_it_is_opened(tmp_path):
    """/dev/full (or a FIFO, which would block the open until a reader came) is not a log file."""
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full")
    out = tmp_path / "full.csv"
    out.symlink_to("/dev/full")
    with pytest.raises(OutputError, match="full.csv: is a character device, not a regular file"):
        record(sine_sampler(), ["current"], out, rate_hz=10.0, duration=0.2)
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    with pytest.raises(OutputError, match=r"pipe.csv: is a FIFO \(named pipe\), not a regular file"):
        record(sine_sampler(), ["current"], fifo, rate_hz=10.0, duration=0.2)


def test_a_write_error_cuts_the_file_back_to_whole_rows(tmp_path):
    """RLIMIT_FSIZE makes write() stop at the limit (a short write, then EFBIG), as a disk that fills up."""
    out = tmp_path / "limited.csv"
    script = f"""
import resource, sys
from pathlib import Path
from hound_id.dyno.acquire.recorder import record
resource.setrlimit(resource.RLIMIT_FSIZE, (5000, 5000))
def read():
    return {{"current": 1.2345678901234567, "torque": -0.123456789}}
try:
    record(read, ["current", "torque"], Path({str(out)!r}), rate_hz=1000.0, duration=5.0, flush_interval=0.05)
except Exception as err:
    print(type(err).__name__, err.rows, err.result.status)
    print(err)
"""
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    kind, rows, status = proc.stdout.splitlines()[0].split()
    assert kind == "OutputError" and status == "failed", proc.stdout + proc.stderr
    message = proc.stdout.splitlines()[1]
    assert "limited.csv: cannot write the log (File too large)" in message and "whole rows only" in message
    data = out.read_bytes()
    assert 4900 < len(data) <= 5000 and data.endswith(b"\n")
    lines = data.decode().splitlines()
    assert all(line.count(",") == 2 for line in lines) and len(lines) - 1 == int(rows)
    meta = json.loads(sidecar_path(out).read_text())
    assert meta["status"] == "failed" and meta["samples"] == int(rows) and "File too large" in meta["message"]


# --- against a real peer: the simulated rig's pymodbus server in its own process, stopped with SIGSTOP -----------


@pytest.fixture(scope="module")
def rig_process(tmp_path_factory):
    """``hound-id dyno simulate-rig`` on a free port: (process, rig file). A process of its own, so SIGSTOP hangs it."""
    rig_file = tmp_path_factory.mktemp("rig") / "sim-rig.yaml"
    proc = subprocess.Popen(
        [sys.executable, "-m", "hound_id", "dyno", "simulate-rig", "--port", "0", "--no-serial"]
        + ["--rig-out", str(rig_file), "--duration", "300"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        preexec_fn=restore_sigint,
    )
    try:
        deadline = time.monotonic() + 30
        while not rig_file.exists() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.05)
        assert rig_file.exists(), "the simulated rig did not start"
        yield proc, rig_file
    finally:
        proc.send_signal(signal.SIGCONT)
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()


class Hang:
    """Stops a process with SIGSTOP for ``seconds`` (a hung peer) once :attr:`trigger` is set, then resumes it."""

    def __init__(self, proc, seconds):
        self.trigger, self._cancelled = threading.Event(), False
        self._thread = threading.Thread(target=self._run, args=(proc, seconds))
        self._thread.start()

    def _run(self, proc, seconds):
        if self.trigger.wait(30) and not self._cancelled:
            proc.send_signal(signal.SIGSTOP)
            time.sleep(seconds)
            proc.send_signal(signal.SIGCONT)

    def join(self):
        """Wait for the hang to end (cancel it if it never started)."""
        self._cancelled = not self.trigger.is_set()
        self.trigger.set()
        self._thread.join()


def record_rig(rig_file, out, *, timeout=None, after_samples=None, **kwargs):
    """Record the rig file's devices in this process; ``after_samples``: (n, event) set after n good reads."""
    from hound_id.dyno.acquire.rig_file import rig_from_mapping
    from hound_id.dyno.acquire.transport import RigReader

    mapping = yaml.safe_load(rig_file.read_text())
    if timeout is not None:
        for device in mapping["devices"].values():
            device["timeout"] = timeout
    rig = rig_from_mapping(mapping, source=str(rig_file))
    with RigReader(rig) as reader:
        read = reader.read_sample
        if after_samples is not None:
            n, event = after_samples
            good = iter(range(n))

            def read():
                sample = reader.read_sample()
                if next(good, None) is None:
                    event.set()
                return sample

        return record(read, list(rig.columns), out, **kwargs)


@pytest.mark.parametrize(
    ("timeout", "why"),
    [(None, "No response"), (3.0, "blocked")],
    ids=["reads-time-out", "read-blocks-then-answers"],
)
def test_a_hung_peer_is_one_gap_from_the_last_sample_to_the_next(rig_process, tmp_path, timeout, why):
    proc, rig_file = rig_process
    out = tmp_path / "hung.csv"
    stopper = Hang(proc, 1.0)
    try:
        result = record_rig(
            rig_file, out, timeout=timeout, after_samples=(40, stopper.trigger), rate_hz=200.0, duration=2.5
        )
    finally:
        stopper.join()
    assert result.status == "complete"
    assert result.samples + result.missed + result.failed == 500  # every tick accounted once
    frame = pd.read_csv(out)
    assert len(frame) == result.samples
    hole = frame["time"].diff()
    k = int(hole.idxmax())
    (gap,) = [g for g in result.gaps if g.end - g.start > 0.5]
    assert why in gap.reason
    # booked from the last good sample to the next one: the hole in the file, all of it
    assert gap.start == pytest.approx(frame["time"][k - 1], abs=1e-5)
    assert gap.end == pytest.approx(frame["time"][k], abs=1e-5)
    assert gap.end - gap.start >= 0.95
    assert abs(gap.ticks - 200 * (gap.end - gap.start)) <= 3
    assert result.missed < 0.1 * gap.ticks  # not booked as the loop running late


def test_sigkill_during_a_hung_peer_leaves_a_sidecar_with_the_open_gap(rig_process, tmp_path):
    proc, rig_file = rig_process
    out = tmp_path / "killed.csv"
    rec = subprocess.Popen(
        [sys.executable, "-m", "hound_id", "dyno", "record", "--rig", str(rig_file), "--out", str(out)]
        + ["--rate", "200"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        preexec_fn=restore_sigint,
    )
    side = sidecar_path(out)
    try:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and rec.poll() is None:
            if side.exists() and json.loads(side.read_text() or "{}").get("samples", 0) > 50:
                break
            time.sleep(0.05)
        proc.send_signal(signal.SIGSTOP)
        time.sleep(1.2)
        rec.send_signal(signal.SIGKILL)
        rec.wait(timeout=10)
    finally:
        proc.send_signal(signal.SIGCONT)
        if rec.poll() is None:
            rec.kill()
    meta = json.loads(side.read_text())
    assert meta["status"] == "recording"
    gap = meta["gaps"][-1]
    assert gap["end"] is None and "No response" in gap["reason"]
    frame = pd.read_csv(out)
    assert gap["start"] == pytest.approx(frame["time"].iloc[-1], abs=1e-5)  # the last good sample, on disk
    assert meta["duration"] - gap["start"] >= 0.6  # rewritten during the hang, not only after a good read
    # every tick due since the last sample is in the gap, also those of the read still waiting for its timeout
    assert gap["ticks"] == meta["failed_ticks"] >= 200 * (meta["duration"] - gap["start"]) - 2
    assert meta["samples"] == len(frame)


def assert_one_line(proc, *fragments):
    assert proc.returncode == 2, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


def test_a_full_disk_stops_the_recorder_with_whole_rows_a_failed_sidecar_and_one_line(rig_process, tmp_path):
    import resource

    _, rig_file = rig_process
    out = tmp_path / "full.csv"

    def limit():  # a file size limit: write() stops at it (short write, then EFBIG), as on a disk that fills
        resource.setrlimit(resource.RLIMIT_FSIZE, (40_000, 40_000))

    proc = subprocess.run(
        [sys.executable, "-m", "hound_id", "dyno", "record", "--rig", str(rig_file), "--out", str(out)]
        + ["--rate", "500", "--duration", "20", "--flush", "0.1"],
        capture_output=True,
        text=True,
        timeout=60,
        preexec_fn=limit,
        env=dict(os.environ, PYTHONDONTWRITEBYTECODE="1"),
    )
    assert_one_line(proc, "full.csv: cannot write the log (File too large)", "whole rows only", "free space")
    data = out.read_bytes()
    assert data.endswith(b"\n") and len(data) <= 40_000
    lines = data.decode().splitlines()
    assert {line.count(",") for line in lines} == {6}  # header and every row whole
    meta = json.loads(sidecar_path(out).read_text())
    assert meta["status"] == "failed" and meta["samples"] == len(lines) - 1 > 100
    assert "File too large" in meta["message"]


def test_a_second_recorder_on_the_same_file_is_refused_at_once(rig_process, tmp_path):
    _, rig_file = rig_process
    out = tmp_path / "shared.csv"
    args = [sys.executable, "-m", "hound_id", "dyno", "record", "--rig", str(rig_file), "--out", str(out)]
    first = subprocess.Popen(
        [*args, "--rate", "200", "--duration", "4", "--json"],
        stdout=subprocess.PIPE,
        text=True,
        preexec_fn=restore_sigint,
    )
    try:
        side = sidecar_path(out)
        deadline = time.monotonic() + 30
        while not side.exists() and time.monotonic() < deadline and first.poll() is None:
            time.sleep(0.05)
        started = time.monotonic()
        second = subprocess.run([*args, "--rate", "200", "--duration", "3"], capture_output=True, text=True)
        assert time.monotonic() - started < 3.0  # refused at once, not after recording
        assert_one_line(second, f"{out}: another recorder (PID {first.pid}) is writing this file")
        stdout, _ = first.communicate(timeout=30)
    finally:
        if first.poll() is None:
            first.kill()
    assert first.returncode == 0
    meta = json.loads(stdout)
    frame = pd.read_csv(out)
    assert meta["status"] == "complete" and meta["pid"] == first.pid and len(frame) == meta["samples"] > 400
    assert frame["time"].is_monotonic_increasing and not frame.isna().any().any()


def test_an_error_in_a_progress_callback_stops_the_run_and_is_raised(tmp_path):
    def broken(result):
        raise RuntimeError("progress bar broke")

    out = tmp_path / "cb.csv"
    started = time.monotonic()
    with pytest.raises(RuntimeError, match="progress bar broke"):
        record(sine_sampler(), ["current", "torque"], out, rate_hz=100.0, duration=10.0, on_progress=broken)
    assert time.monotonic() - started < 2.0
    meta = json.loads(sidecar_path(out).read_text())
    assert meta["status"] == "failed" and meta["samples"] == len(pd.read_csv(out))


# --- a log already at --out ---------------------------------------------------------------------------------------


def old_log(tmp_path):
    """A recorded log and its sidecar, as a previous run left them: (path, its bytes, the sidecar's bytes)."""
    out = tmp_path / "run.csv"
    out.write_text("time,current\n" + "".join(f"{k / 100:.2f},{k}.0\n" for k in range(5000)))
    sidecar_path(out).write_text(json.dumps({"status": "complete", "samples": 5000}))
    return out, out.read_bytes(), sidecar_path(out).read_bytes()


def hidden_files(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def test_a_log_already_there_is_refused_without_overwrite_and_left_as_it_was(tmp_path):
    out, data, meta = old_log(tmp_path)
    with pytest.raises(OutputError, match=r"run.csv: already holds 6[0-9,]+ bytes .*pass --overwrite"):
        record(sine_sampler(), ["current"], out, rate_hz=50.0, duration=0.2)
    assert out.read_bytes() == data and sidecar_path(out).read_bytes() == meta
    empty = tmp_path / "empty.csv"
    empty.touch()  # an empty file is not a log: recorded into without --overwrite
    assert record(sine_sampler(), ["current"], empty, rate_hz=50.0, duration=0.2).samples > 0


@pytest.mark.parametrize("how", ["no-answer", "ctrl-c"])
def test_overwrite_keeps_the_old_log_until_the_first_sample_is_in(tmp_path, how):
    """A rig that answers nothing (or Ctrl-C before the first sample) replaces nothing: the old log, its sidecar
    and the folder are as they were."""
    out, data, meta = old_log(tmp_path)

    def dead():
        if how == "ctrl-c":
            raise KeyboardInterrupt
        raise ReadError("Modbus 127.0.0.1:1 unit 1: connection refused")

    result = record(dead, ["current"], out, rate_hz=50.0, duration=0.3, overwrite=True, policy=RetryPolicy(retries=0))
    assert result.kept_existing and result.samples == 0
    assert result.status == ("failed" if how == "no-answer" else "interrupted")
    assert f"{out} was left as it was" in result.message
    assert out.read_bytes() == data and sidecar_path(out).read_bytes() == meta
    assert hidden_files(tmp_path) == []


def test_overwrite_replaces_the_old_log_and_its_sidecar_with_the_first_rows(tmp_path):
    out, data, _ = old_log(tmp_path)
    seen = []

    def sampler():  # what the folder holds while the first reads come in: the old log, untouched
        seen.append(out.read_bytes() == data)
        return {"current": 1.0}

    result = record(sampler, ["current"], out, rate_hz=50.0, duration=0.4, overwrite=True)
    assert seen[0] and not result.kept_existing and result.status == "complete"
    frame = pd.read_csv(out)
    assert list(frame.columns) == ["time", "current"] and len(frame) == result.samples > 5
    assert json.loads(sidecar_path(out).read_text())["samples"] == result.samples
    assert hidden_files(tmp_path) == []


def test_the_recorder_refuses_to_write_its_log_over_the_rig_file(tmp_path):
    """``dyno record --rig r.csv --out r.csv``: the rig file is an input; refused before anything is read."""
    rig = tmp_path / "r.csv"
    rig.write_text("devices: {}\n")
    proc = subprocess.run(
        [sys.executable, "-m", "hound_id", "dyno", "record", "--rig", str(rig), "--out", str(rig), "--overwrite"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert_one_line(proc, "r.csv: is also an input of this command")
    assert rig.read_text() == "devices: {}\n"


def test_the_command_line_keeps_an_old_log_when_the_rig_answers_nothing(rig_process, tmp_path):
    """A rig file whose devices are not there: exit 2 in one line, and the old log is what it was."""
    _, rig_file = rig_process
    mapping = yaml.safe_load(rig_file.read_text())
    for device in mapping["devices"].values():
        if "port" in device:
            device["port"] = 1  # nothing listens there
    dead_rig = tmp_path / "dead-rig.yaml"
    dead_rig.write_text(yaml.safe_dump(mapping))
    out, data, meta = old_log(tmp_path)
    args = [sys.executable, "-m", "hound_id", "dyno", "record", "--rig", str(dead_rig), "--out", str(out)]
    refused = subprocess.run([*args, "--duration", "1"], capture_output=True, text=True, timeout=60)
    assert_one_line(refused, "run.csv: already holds", "--overwrite")
    kept = subprocess.run([*args, "--duration", "1", "--overwrite"], capture_output=True, text=True, timeout=60)
    assert kept.returncode == 2 and "Traceback" not in kept.stderr, kept.stderr
    errors = [line for line in kept.stderr.splitlines() if line.startswith("hound-id: error")]
    assert len(errors) == 1 and "no sample was read" in errors[0] and "was left as it was" in errors[0]
    assert out.read_bytes() == data and sidecar_path(out).read_bytes() == meta
    assert hidden_files(tmp_path) == []


@pytest.mark.parametrize("how", ["no-answer", "ctrl-c"])
def test_a_new_log_that_never_got_a_sample_leaves_nothing_behind(tmp_path, how):
    """No header-only log and no sidecar of a run that read nothing: the folder is as it was."""

    def dead():
        if how == "ctrl-c":
            raise KeyboardInterrupt
        raise ReadError("Modbus 127.0.0.1:1 unit 1: connection refused")

    out = tmp_path / "new.csv"
    result = record(dead, ["current"], out, rate_hz=50.0, duration=0.3, policy=RetryPolicy(retries=0))
    assert result.samples == 0 and result.kept_existing and result.message.endswith("nothing was written")
    assert list(tmp_path.iterdir()) == []
