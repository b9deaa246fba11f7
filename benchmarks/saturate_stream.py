"""Benchmark: ``hound-id saturate`` on long logs, streamed (before streaming: 45 s and 2.4 GB for 1,000,000 CSV rows).

Writes logs of the sample Hound-like robot (12 joints: time + 24 columns, the sample gait with noise)
into a temporary folder: 1,000,000 rows of CSV and of Parquet by default (``--rows``, ``--parquet-rows``,
e.g. 5,000,000). Each case runs in a fresh process, one at a time, and reports its wall time, rows per
second and peak resident memory (``ru_maxrss`` of that process, from ``os.wait4``):

* ``hound-id saturate LOG --robot ROBOT --out OUT --json``, the command as a user runs it, for
  CSV to CSV, CSV with no ``--out`` and Parquet to Parquet;
* the I/O floor: the same file copied by pyarrow alone (only read, for the case with no ``--out``),
  streamed batch by batch with the reader and writer options hound-id uses: no validation, no
  saturation, no summary, and the input's 25 columns only (hound-id writes 12 more);
* the imports alone (``hound-id --version`` memory is not enough: the command loads numpy, scipy,
  pint and pyarrow), to show what part of the peak memory the log's length could own.

The ratio is hound-id's time over the floor's on the same file, in the same run. Prints a table and
the figures as JSON (``--json``: JSON only).

Run: .venv/bin/python benchmarks/saturate_stream.py [--rows 1000000] [--parquet-rows 5000000] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # this checkout's hound_id, here and in the processes it starts
ROBOT = ROOT / "data" / "samples" / "robots" / "hound_like.yaml"
#: Rows generated per write, so that making a 5,000,000-row log needs little memory itself.
GENERATE_ROWS = 250_000

FLOOR = """
import sys
import pyarrow.csv as pcsv, pyarrow.parquet as pq
src, dst, batch_rows, block_bytes = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
if src.endswith(".csv"):  # the options hound_id.tables uses
    batches = pcsv.open_csv(src, read_options=pcsv.ReadOptions(block_size=block_bytes, use_threads=False))
    schema = batches.schema
else:
    source = pq.ParquetFile(src, pre_buffer=False, buffer_size=1 << 20)
    batches = source.iter_batches(batch_size=batch_rows, use_threads=False)
    schema = source.schema_arrow
if dst == "-":  # read only
    for batch in batches:
        pass
elif dst.endswith(".csv"):
    with pcsv.CSVWriter(dst, schema) as writer:
        for batch in batches:
            writer.write_batch(batch)
else:
    with pq.ParquetWriter(dst, schema, use_dictionary=False) as writer:
        for batch in batches:
            writer.write_batch(batch)
"""

IMPORTS = """
import numpy, scipy.spatial, pint, pyarrow.csv, pyarrow.parquet, pyarrow.compute  # what saturate loads
import hound_id.cli, hound_id.mor.saturation, hound_id.tables
from hound_id.mor.robot import load_robot
from hound_id.mor.saturation import saturation_for
saturation_for(load_robot(sys.argv[1]))
"""


def write_log(path: Path, rows: int, seed: int = 0) -> None:
    """The sample gait (4 Hz trot, knees to 95 N m at 60 rad/s) with noise, ``rows`` rows at 1 kHz."""
    import pyarrow as pa
    import pyarrow.csv as pcsv
    import pyarrow.parquet as pq

    legs = {"FL": 0.0, "FR": 0.5, "RL": 0.5, "RR": 0.0}
    joints = {"HAA": (30.0, 0.3, 10.0, 1.2), "HFE": (70.0, 3.4, 45.0, 0.2), "KFE": (95.0, 1.35, 60.0, 1.0)}
    rng = np.random.default_rng(seed)
    writer = None
    for start in range(0, rows, GENERATE_ROWS):
        t = np.arange(start, min(rows, start + GENERATE_ROWS)) / 1000.0
        cols = {"time": t}
        for leg, phase in legs.items():
            for joint, (a_tau, p_tau, a_qd, p_qd) in joints.items():
                angle = 2 * np.pi * (4.0 * t + phase)
                cols[f"tau_{leg}_{joint}"] = np.round(a_tau * np.sin(angle + p_tau) + rng.normal(0, 1, t.size), 4)
                cols[f"qd_{leg}_{joint}"] = np.round(a_qd * np.sin(angle + p_qd) + rng.normal(0, 1, t.size), 4)
        table = pa.table(cols)
        if writer is None:
            writer = (
                pq.ParquetWriter(path, table.schema)
                if path.suffix == ".parquet"
                else pcsv.CSVWriter(path, table.schema, write_options=pcsv.WriteOptions(quoting_style="none"))
            )
        writer.write_table(table)
    assert writer is not None
    writer.close()


def measure(args: list[str]) -> dict[str, float]:
    """Run a command in a fresh process; its wall time [s] and peak resident memory [MB]."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    start = time.perf_counter()
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    _, status, usage = os.wait4(proc.pid, 0)
    seconds = time.perf_counter() - start
    out, err = proc.communicate()
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(args)} failed: {err.decode()[-2000:]}")
    return {"seconds": seconds, "peak_rss_mb": usage.ru_maxrss / 1024, "stdout": out.decode()}  # type: ignore[dict-item]


def case(name: str, log: Path, rows: int, out: Path | None) -> dict[str, object]:
    command = [sys.executable, "-m", "hound_id", "saturate", str(log), "--robot", str(ROBOT), "--json"]
    if out is not None:
        command += ["--out", str(out)]
    ours = measure(command)
    summary = json.loads(str(ours.pop("stdout")))
    assert summary["rows"] == rows, summary["rows"]
    from hound_id.table_stream import BATCH_ROWS, CSV_BLOCK_BYTES

    floor_out = log.with_name(f"floor_{log.stem}{log.suffix}") if out is not None else None
    floor = measure(
        [sys.executable, "-c", FLOOR, str(log), str(floor_out or "-"), str(BATCH_ROWS), str(CSV_BLOCK_BYTES)]
    )
    floor.pop("stdout")
    for path in (out, floor_out):
        if path is not None:
            path.unlink(missing_ok=True)
    return {
        "case": name,
        "rows": rows,
        "file_mb": round(log.stat().st_size / 1e6, 1),
        "seconds": round(float(ours["seconds"]), 2),
        "rows_per_second": round(rows / float(ours["seconds"])),
        "peak_rss_mb": round(float(ours["peak_rss_mb"])),
        "floor_seconds": round(float(floor["seconds"]), 2),
        "floor_peak_rss_mb": round(float(floor["peak_rss_mb"])),
        "ratio_to_floor": round(float(ours["seconds"]) / float(floor["seconds"]), 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=1_000_000, help="CSV rows")
    parser.add_argument("--parquet-rows", type=int, default=1_000_000, help="Parquet rows (0: skip)")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON only")
    args = parser.parse_args()
    results = []
    with tempfile.TemporaryDirectory(prefix="hound-id-bench-") as folder:
        tmp = Path(folder)
        imports = measure([sys.executable, "-c", "import sys\n" + IMPORTS, str(ROBOT)])
        csv_log = tmp / "log.csv"
        write_log(csv_log, args.rows)
        results.append(case("csv -> csv", csv_log, args.rows, tmp / "out.csv"))
        results.append(case("csv, no --out", csv_log, args.rows, None))
        csv_log.unlink()
        if args.parquet_rows:
            pq_log = tmp / "log.parquet"
            write_log(pq_log, args.parquet_rows)
            results.append(case("parquet -> parquet", pq_log, args.parquet_rows, tmp / "out.parquet"))
    figures = {
        "schema": "hound-id/bench-saturate-stream/1",
        "joints": 12,
        "imports_peak_rss_mb": round(float(imports["peak_rss_mb"])),
        "results": results,
    }
    if args.json:
        print(json.dumps(figures, indent=2))
        return
    print(
        f"hound-id saturate on long logs of the sample robot (12 joints); each case a fresh process; "
        f"the imports alone peak at {figures['imports_peak_rss_mb']} MB"
    )
    for r in results:
        print(
            f"  {r['case']:20s} {r['rows']:>9,} rows ({r['file_mb']} MB): {r['seconds']:6.2f} s, "
            f"{r['rows_per_second']:>9,} rows/s, peak {r['peak_rss_mb']} MB; pyarrow copy (I/O floor) "
            f"{r['floor_seconds']:.2f} s, peak {r['floor_peak_rss_mb']} MB; ratio {r['ratio_to_floor']:.2f}"
        )
    print(json.dumps(figures, indent=2))


if __name__ == "__main__":
    main()
