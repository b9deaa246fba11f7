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

Run: .venv/bin/python benchmarks/record.py [--seconds 3] [--rounds 5] [--json]
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

    from hound_id.dyno.acquire import record
    from hound_id.dyno.rig import rig_from_mapping
    from hound_id.dyno.transport import RigReader

    rig = rig_from_mapping(rig_mapping, source="benchmark")
    with RigReader(rig) as reader:
        result = record(reader.read_sample, list(rig.columns), out, rate_hz=rate_hz, duration=seconds)
    rows = len(pd.read_csv(out))
    return rows / result.duration, rows, result.samples


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()

    import signal
    import subprocess
    import sys

    import yaml

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
                r, rows, samples = recorder_rate(mapping, args.seconds, 3.0 * b, Path(tmp) / f"run{k}.csv")
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
