"""Benchmark: a fleet of 200 simulated actuator logs, time per log against Dask workers, and every planted fault.

The fleet (:func:`hound_id.dyno.simulate.fleet.simulate_fleet`): 200 actuators of one type with a production
batch's scatter, one in ten with a planted fault (weak magnet, bearing, gearbox, different motor in turn; 20
faults), 12.5 s logs at 400 Hz written as CSV into ``--logs`` (kept and reused when it holds them already).

In this one process it times:

1. the baseline: every log fitted in turn, in this process, by the same function a Dask worker runs
   (:func:`hound_id.dyno.fleet.engine.fit_log`; the imports are warmed on one log first);
2. ``run_fleet`` on a local Dask cluster of each ``--workers`` count (the cluster's start is timed apart).

It prints seconds per log and the ratio to the baseline (below 1: faster), and for the last run whether every
planted fault is flagged with its reading (``FAULTS``: the metric it must flag and the consequences it may
flag too) and no healthy actuator is flagged.

Run: .venv/bin/python benchmarks/fleet.py [--actuators 200] [--workers 1 2] [--auto] [--logs DIR] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from hound_id.dyno.current.run import FitCurrentOptions
from hound_id.dyno.fleet.analyse import analyse
from hound_id.dyno.fleet.engine import client_for, fit_log, run_fleet
from hound_id.dyno.simulate.fleet import FAULTS, FLEET_COLUMNS, FLEET_MODEL, planted, simulate_fleet

SCHEMA = "hound-id/bench-fleet/1"


def write_fleet(folder: Path, n: int, seed: int) -> dict[str, str]:
    """Write the fleet's logs into ``folder`` (unless there) and return actuator -> planted fault."""
    faults = planted(n)
    names = [f"act_{i:03d}" for i in range(n)]
    truth = folder / "planted.json"
    if truth.is_file() and all((folder / f"{name}.csv").is_file() for name in names):
        return dict(json.loads(truth.read_text()))
    folder.mkdir(parents=True, exist_ok=True)
    for member in simulate_fleet(n, faults=faults, seed=seed, names=names):
        member.log.frame[list(FLEET_COLUMNS)].to_csv(folder / f"{member.name}.csv", index=False, float_format="%.6g")
    out = {names[i]: fault for i, fault in faults.items()}
    truth.write_text(json.dumps(out, indent=2) + "\n")
    return out


def check(report, faults: dict[str, str]) -> dict[str, object]:
    """Which planted faults are flagged with their reading, and which actuators are flagged without one."""
    flagged: dict[str, set[str]] = {}
    for f in report.flags:
        flagged.setdefault(f.actuator, set()).add(f.metric)
    missed = []
    for name, fault in sorted(faults.items()):
        need, may = set(FAULTS[fault].flags), set(FAULTS[fault].may_flag)
        if not need <= flagged.get(name, set()) <= need | may:
            missed.append({"actuator": name, "fault": fault, "flagged": sorted(flagged.get(name, set()))})
    false = sorted(name for name in flagged if name not in faults)
    return {
        "planted": len(faults),
        "found": len(faults) - len(missed),
        "missed": missed,
        "healthy_flagged": false,
        "all_found_nothing_else": not missed and not false,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--actuators", type=int, default=200)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--auto", action="store_true", help="each log climbs its ladder (default: the fleet model)")
    parser.add_argument("--logs", type=Path, default=None, help="folder for the simulated logs (kept, reused)")
    parser.add_argument("--seed", type=int, default=19)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    folder = args.logs or Path(tempfile.mkdtemp(prefix="hound-id-fleet-bench-"))
    t0 = time.perf_counter()
    faults = write_fleet(folder, args.actuators, args.seed)
    simulate_s = time.perf_counter() - t0
    paths = sorted(folder.glob("*.csv"))
    options = FitCurrentOptions(auto=True) if args.auto else FitCurrentOptions(model=FLEET_MODEL)

    fit_log(paths[0].stem, str(paths[0]), paths[0].read_bytes(), options)  # imports and caches warm
    t0 = time.perf_counter()
    baseline = [fit_log(p.stem, str(p), p.read_bytes(), options) for p in paths]
    base_per_log = (time.perf_counter() - t0) / len(paths)

    assert all(f.ok for f in baseline), [f.error for f in baseline if not f.ok]
    runs = []
    for workers in args.workers:
        t0 = time.perf_counter()
        with client_for(None, workers):
            pass
        start_s = time.perf_counter() - t0
        run = run_fleet(paths, options, workers=workers)
        per_log = run.seconds / (len(paths) + len(run.refitted))
        report = analyse(run.actuators, model=run.model)
        runs.append(
            {
                "workers": workers,
                "cluster_start_s": start_s,
                "seconds": run.seconds,
                "seconds_per_log": per_log,
                "ratio_to_baseline": per_log / base_per_log,
                "failed": len(report.failed),
                "refitted": len(run.refitted),
            }
        )
    found = check(report, faults)  # the last run's
    result = {
        "schema": SCHEMA,
        "actuators": len(paths),
        "model": "auto" if args.auto else FLEET_MODEL,
        "simulate_s": simulate_s,
        "baseline_seconds_per_log": base_per_log,
        "runs": runs,
        "faults": found,
        "logs": str(folder),
    }
    if args.json:
        print(json.dumps(result, indent=2))
        return
    print(f"{len(paths)} logs in {folder} (simulated in {simulate_s:.1f} s); model {result['model']}")
    print(f"baseline, one after the other in this process: {base_per_log:.3f} s per log")
    print("workers | cluster start [s] | wall [s] | s per log | ratio to baseline")
    for r in runs:
        print(
            f"{r['workers']:7d} | {r['cluster_start_s']:17.2f} | {r['seconds']:8.1f} | {r['seconds_per_log']:9.3f} | "
            f"{r['ratio_to_baseline']:.2f}"
        )
    print(
        f"planted faults flagged with their reading: {found['found']}/{found['planted']}; healthy actuators flagged: "
        f"{len(found['healthy_flagged'])} {found['healthy_flagged'] or ''}"
    )
    for m in found["missed"]:
        print(f"  missed: {m}")
    sys.exit(0 if found["all_found_nothing_else"] else 1)


if __name__ == "__main__":
    main()
