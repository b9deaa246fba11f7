"""Benchmark: sustained sampling rate of `dyno record` against a bare pymodbus loop.

The simulated rig serves its registers on 127.0.0.1 from its own process
(``hound-id dyno simulate-rig``), as a real rig is a separate device; sharing this
process's interpreter lock would slow whichever side does more Python work. In this
process, alternately:

1. a bare pymodbus ``ModbusTcpClient`` loop reads the same register blocks as the
   recorder (unit 1 input 0-1, unit 2 input 0-7) as fast as it can for --seconds, and
   counts complete samples (both blocks read);
2. the recorder (``RigReader`` + ``record``), asked for a rate above what the loop can
   reach, records for --seconds; its achieved rate is the rows in the CSV per second.

Both sides decode nothing beyond what they need: the bare loop only reads, the recorder
also decodes, converts to SI and writes CSV. Targets: the recorder's rate at least 90 % of
the bare loop's, and every sample it read is in the file (rows == samples).

With ``--faults`` it measures instead what the recorder books when things go wrong, each run
through the command line (``hound-id dyno record``) against the simulated rig in its own process:

* hung peer: the rig stopped with SIGSTOP for --hang seconds (3) during an 8 s run at 500 Hz:
  the real hole in the CSV against the gap booked (start, end, ticks) and the missed ticks;
* SIGKILL of the recorder 1.5 s into a hung peer: the sidecar's status and open gap;
* disk full: a file size limit (RLIMIT_FSIZE, any user: short write, then EFBIG) and, when this
  process may mount one (root), a real 256 kB tmpfs that fills up (ENOSPC): exit code, stderr
  lines, whole rows in the CSV, the sidecar's status;
* two recorders on one --out: what the second is told, how fast, and whether the first's file
  is intact.

Run: .venv/bin/python benchmarks/record.py [--seconds 3] [--rounds 5] [--json]
     .venv/bin/python benchmarks/record.py --faults [--hang 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path


def bare_rate(host: str, port: int, seconds: float) -> float:
    from pymodbus.client import ModbusTcpClient

    client = ModbusTcpClient(host, port=port, timeout=1.0, retries=0)
    client.connect()
    n = 0
    end = time.monotonic() + seconds
    t0 = time.monotonic()
    while time.monotonic() < end:
        a = client.read_input_registers(0, count=2, device_id=1)
        b = client.read_input_registers(0, count=8, device_id=2)
        if not a.isError() and not b.isError():
            n += 1
    elapsed = time.monotonic() - t0
    client.close()
    return n / elapsed


def recorder_rate(rig_mapping: dict, seconds: float, rate_hz: float, out: Path) -> tuple[float, int, int]:
    import pandas as pd

    from hound_id.dyno.acquire.recorder import record
    from hound_id.dyno.acquire.rig_file import rig_from_mapping
    from hound_id.dyno.acquire.transport import RigReader

    rig = rig_from_mapping(rig_mapping, source="benchmark")
    with RigReader(rig) as reader:
        result = record(reader.read_sample, list(rig.columns), out, rate_hz=rate_hz, duration=seconds)
    rows = len(pd.read_csv(out))
    return rows / result.duration, rows, result.samples


def _cli(*args: str) -> list[str]:
    import sys

    return [sys.executable, "-m", "hound_id", "dyno", *args]


def _start_rig(folder: Path) -> tuple[object, Path]:
    import subprocess

    rig_file = folder / "rig.yaml"
    args = ("--port", "0", "--no-serial", "--rig-out", str(rig_file), "--duration", "600")
    server = subprocess.Popen(_cli("simulate-rig", *args), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 30
    while not rig_file.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    return server, rig_file


def _wait_for_samples(side: Path, n: int) -> None:
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        try:
            if json.loads(side.read_text()).get("samples", 0) >= n:
                return
        except (OSError, ValueError):
            pass
        time.sleep(0.02)


def _whole_rows(out: Path) -> dict:
    data = out.read_bytes()
    lines = data.decode("utf-8", "replace").splitlines()
    fields = {line.count(",") for line in lines}
    return {
        "bytes": len(data),
        "rows": max(len(lines) - 1, 0),
        "ends_with_newline": data.endswith(b"\n"),
        "every_row_whole": len(fields) <= 1,
        "crlf": b"\r" in data,
    }


def hung_peer(server, rig_file: Path, folder: Path, hang: float) -> dict:
    import signal
    import subprocess

    import pandas as pd

    out = folder / "hung.csv"
    rec = subprocess.Popen(
        _cli("record", "--rig", str(rig_file), "--out", str(out), "--rate", "500", "--duration", "8", "--json"),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    _wait_for_samples(out.with_name(out.name + ".meta.json"), 500)
    server.send_signal(signal.SIGSTOP)
    time.sleep(hang)
    server.send_signal(signal.SIGCONT)
    stdout, _ = rec.communicate(timeout=60)
    meta = json.loads(stdout)
    times = pd.read_csv(out)["time"]
    hole = times.diff()
    k = int(hole.idxmax())
    gap = max(meta["gaps"], key=lambda g: g["end"] - g["start"])
    return {
        "hang_s": hang,
        "hole_in_csv_s": float(hole[k]),
        "hole_from_s": float(times[k - 1]),
        "gap_booked_s": gap["end"] - gap["start"],
        "gap_start_s": gap["start"],
        "gap_ticks": gap["ticks"],
        "ticks_due_in_hole": float(hole[k]) * 500,
        "gaps": len(meta["gaps"]),
        "missed_ticks": meta["missed_ticks"],
        "failed_ticks": meta["failed_ticks"],
        "samples": meta["samples"],
        "ticks_accounted": meta["samples"] + meta["missed_ticks"] + meta["failed_ticks"],
        "ticks_due": 8 * 500,
        "status": meta["status"],
    }


def killed_during_hang(server, rig_file: Path, folder: Path) -> dict:
    import signal
    import subprocess

    out = folder / "killed.csv"
    side = out.with_name(out.name + ".meta.json")
    rec = subprocess.Popen(
        _cli("record", "--rig", str(rig_file), "--out", str(out), "--rate", "500"),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    _wait_for_samples(side, 500)
    server.send_signal(signal.SIGSTOP)
    time.sleep(1.5)
    rec.send_signal(signal.SIGKILL)
    rec.wait()
    server.send_signal(signal.SIGCONT)
    meta = json.loads(side.read_text())
    gap = meta["gaps"][-1] if meta["gaps"] else {}
    return {
        "status": meta["status"],
        "gap_open": bool(gap) and gap["end"] is None,
        "gap": gap,
        "sidecar_written_s_into_hang": meta["duration"] - gap.get("start", meta["duration"]),
        "failed_ticks": meta["failed_ticks"],
        "samples_in_sidecar": meta["samples"],
        **{f"csv_{k}": v for k, v in _whole_rows(out).items()},
    }


def disk_full(rig_file: Path, folder: Path, how: str) -> dict:
    import os
    import resource
    import subprocess

    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    preexec = None
    mount = None
    if how == "file size limit":
        out = folder / "limited.csv"

        def preexec() -> None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (65536, 65536))

    else:
        mount = folder / "tmpfs"
        mount.mkdir()
        made = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mount)], capture_output=True)
        if made.returncode != 0:
            return {"skipped": "cannot mount a tmpfs here (needs root)"}
        out = mount / "full.csv"
    try:
        started = time.monotonic()
        proc = subprocess.run(
            _cli("record", "--rig", str(rig_file), "--out", str(out), "--rate", "500", "--duration", "60"),
            capture_output=True,
            text=True,
            env=env,
            preexec_fn=preexec,
            timeout=120,
        )
        meta = json.loads(out.with_name(out.name + ".meta.json").read_text())
        lines = [line for line in proc.stderr.splitlines() if line.strip()]
        return {
            "exit_code": proc.returncode,
            "seconds_until_stopped": time.monotonic() - started,
            "stderr_lines": len(lines),
            "stderr": lines[-1] if lines else "",
            "traceback": "Traceback" in proc.stderr,
            "sidecar_status": meta["status"],
            "sidecar_samples": meta["samples"],
            **{f"csv_{k}": v for k, v in _whole_rows(out).items()},
        }
    finally:
        if mount is not None:
            subprocess.run(["umount", str(mount)], capture_output=True)


def two_recorders(rig_file: Path, folder: Path) -> dict:
    import subprocess

    import pandas as pd

    out = folder / "shared.csv"
    args = ("record", "--rig", str(rig_file), "--out", str(out), "--rate", "500")
    first = subprocess.Popen(_cli(*args, "--duration", "5", "--json"), stdout=subprocess.PIPE, text=True)
    _wait_for_samples(out.with_name(out.name + ".meta.json"), 250)
    started = time.monotonic()
    second = subprocess.run(_cli(*args, "--duration", "5"), capture_output=True, text=True)
    refused_after = time.monotonic() - started
    stdout, _ = first.communicate(timeout=60)
    meta = json.loads(stdout)
    frame = pd.read_csv(out)
    lines = [line for line in second.stderr.splitlines() if line.strip()]
    return {
        "second_exit_code": second.returncode,
        "second_refused_after_s": refused_after,
        "second_stderr_lines": len(lines),
        "second_stderr": lines[-1] if lines else "",
        "first_pid": first.pid,
        "first_status": meta["status"],
        "first_samples": meta["samples"],
        "first_rows": len(frame),
        "first_time_monotonic": bool(frame["time"].is_monotonic_increasing),
        **{f"csv_{k}": v for k, v in _whole_rows(out).items()},
    }


def faults(hang: float, as_json: bool) -> None:
    import signal

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        server, rig_file = _start_rig(folder)
        try:
            figures = {
                "hung_peer": hung_peer(server, rig_file, folder, hang),
                "sigkill_during_hung_peer": killed_during_hang(server, rig_file, folder),
                "disk_full_file_size_limit": disk_full(rig_file, folder, "file size limit"),
                "disk_full_tmpfs": disk_full(rig_file, folder, "tmpfs"),
                "two_recorders": two_recorders(rig_file, folder),
            }
        finally:
            server.send_signal(signal.SIGCONT)  # type: ignore[attr-defined]
            server.send_signal(signal.SIGINT)  # type: ignore[attr-defined]
            server.wait(timeout=10)  # type: ignore[attr-defined]
    if as_json:
        print(json.dumps({"schema": "hound-id/bench-record-faults/1", **figures}, indent=2))
        return
    for name, values in figures.items():
        print(name)
        for key, value in values.items():
            print(f"  {key}: {value:.4g}" if isinstance(value, float) else f"  {key}: {value}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--faults", action="store_true", help="measure the fault cases instead of the rate")
    parser.add_argument("--hang", type=float, default=3.0, help="how long the peer hangs with --faults [s]")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    if args.faults:
        faults(args.hang, args.json)
        return

    import signal
    import subprocess
    import sys

    import yaml

    from hound_id.dyno.acquire.recorder import RATE_LIMITS

    bare, ours, complete = [], [], True
    with tempfile.TemporaryDirectory() as tmp:
        rig_file = Path(tmp) / "rig.yaml"
        server = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "hound_id",
                "dyno",
                "simulate-rig",
                "--port",
                "0",
                "--no-serial",
                "--rig-out",
                str(rig_file),
                "--duration",
                str(2 * args.rounds * args.seconds + 30),
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            deadline = time.monotonic() + 30
            while not rig_file.exists() and time.monotonic() < deadline:
                time.sleep(0.05)
            mapping = yaml.safe_load(rig_file.read_text())
            device = mapping["devices"]["drive"]
            host, port = device["host"], device["port"]
            for k in range(args.rounds):
                b = bare_rate(host, port, args.seconds)
                rate = min(3.0 * b, RATE_LIMITS[1])  # above what the loop can reach, within the accepted range
                r, rows, samples = recorder_rate(mapping, args.seconds, rate, Path(tmp) / f"run{k}.csv")
                bare.append(b)
                ours.append(r)
                complete &= rows == samples
        finally:
            server.send_signal(signal.SIGINT)
            server.wait(timeout=10)
    ratios = [o / b for o, b in zip(ours, bare, strict=True)]
    figures = {
        "bare_rate_hz": statistics.median(bare),
        "recorder_rate_hz": statistics.median(ours),
        "ratio_median": statistics.median(ratios),
        "ratio_min": min(ratios),
        "every_sample_in_file": complete,
        "target_ratio": 0.9,
    }
    if args.json:
        print(json.dumps({"schema": "hound-id/bench-record/1", **figures}, indent=2))
        return
    print(f"dyno record against the loopback simulated rig, {args.rounds} rounds of {args.seconds:g} s")
    print(
        f"  bare pymodbus loop {figures['bare_rate_hz']:.0f} samples/s, recorder {figures['recorder_rate_hz']:.0f} "
        f"rows/s: ratio {figures['ratio_median']:.2f} (lowest {figures['ratio_min']:.2f}; target >= 0.90); "
        f"every sample read is in the file: {complete}"
    )


if __name__ == "__main__":
    main()
