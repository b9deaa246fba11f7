"""Benchmark: the dyno-log simulator (hound_id.dyno.simulate.current.simulate) on a million rows.

It used to be a test asserting a wall time (under 5 s); speed lives here instead. The simulator is run with every
effect it knows (EFFECTS) at a sample rate that makes the default test plan a million rows, after a warm-up at a
hundredth of that rate. The baseline, run in the same process, is the memory floor of one such log: drawing the
same number of Gaussian noise samples for each of its columns and stacking them into a table (numpy alone). The
ratio is the simulator's median time over the baseline's. Prints a table and the figures as JSON (``--json``: JSON
only).

Run: .venv/bin/python benchmarks/simulate.py [--rows 1000000] [--repeat 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # this checkout's hound_id
sys.path.insert(0, str(Path(__file__).resolve().parent))  # benchmarks/timing.py

from timing import timed  # noqa: E402

from hound_id.dyno.simulate.current import EFFECTS, TestPlan, simulate  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rows", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--json", action="store_true", help="print the figures as JSON only")
    args = parser.parse_args()
    rate = args.rows / TestPlan().duration
    simulate(EFFECTS, rate_hz=rate / 100)  # warm up (imports, caches)
    rows = len(simulate(EFFECTS, rate_hz=rate).frame)
    columns = len(simulate(EFFECTS, rate_hz=rate / 100).frame.columns)
    rng = np.random.default_rng(0)
    t_sim = timed(lambda: simulate(EFFECTS, rate_hz=rate), args.repeat)
    t_floor = timed(lambda: np.column_stack([rng.standard_normal(rows) for _ in range(columns)]), args.repeat)
    result = {
        "schema": "hound-id/bench-simulate/1",
        "date": time.strftime("%Y-%m-%d"),
        "machine": f"{platform.machine()}, {platform.processor() or 'cpu'}, python {platform.python_version()}",
        "rows": rows,
        "columns": columns,
        "effects": list(EFFECTS),
        "simulate_s": t_sim,
        "floor_s": t_floor,
        "ratio": t_sim / t_floor,
        "rows_per_s": rows / t_sim,
    }
    if not args.json:
        print(f"simulate(EFFECTS) {rows:,} rows x {columns} columns: {t_sim:.3f} s ({rows / t_sim:,.0f} rows/s)")
        print(f"floor (numpy noise, same table):      {t_floor:.3f} s")
        print(f"ratio simulate / floor: {t_sim / t_floor:.1f}")
    print(json.dumps(result, indent=None if not args.json else 2))


if __name__ == "__main__":
    main()
