"""Benchmark: what `hound-id mor --compare` costs, and what its edge solver buys.

In this process:

1. one envelope edge (:func:`hound_id.mor.envelope.edge`, the Illinois root search on the
   voltage margin) against the baseline it replaced: plain bisection on
   :func:`hound_id.mor.envelope.feasible` (60 halvings, the earlier solver, kept here), on
   20,000 speeds with a sagging bus and inductance; the ratio is bisection / Illinois, and the
   largest difference between the two edges is printed;
2. the whole comparison (:func:`hound_id.mor.compare.compare` with ``auto``) on a 100,000-row
   log with a hidden 0.15 ohm pack, uniform and time-ordered (``simulate_trajectory``), against
   one evaluation of both edges at every row: the comparison costs this many envelope passes.

Issue 7 names no target; the earlier session measured 24-53 s for 100,000 rows.

Run: .venv/bin/python benchmarks/compare.py [--repeat 5] [--json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def timed(fn, repeat: int) -> float:
    """Median wall time of ``fn()`` over ``repeat`` calls [s]."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def bisection_edge(omega, side, params, inputs, steps=60):
    """The baseline, as the earlier solver did it: from the zero-voltage torque (moved towards zero until
    feasible), bisect outwards on the feasibility test."""
    from hound_id.mor.envelope import feasible

    spec = inputs.spec
    cap = spec.torque_limit
    i_limit = min(spec.max_current or np.inf, float(params.get("current_limit", np.inf)))
    start = min(cap, 0.999 * spec.kt * i_limit)
    tau0 = np.clip(-spec.kt * omega / (spec.resistance * spec.kv), -start, start)
    ok0 = feasible(tau0, omega, params, inputs)
    for _ in range(40):
        if ok0.all():
            break
        tau0 = np.where(ok0, tau0, 0.8 * tau0)
        ok0 = feasible(tau0, omega, params, inputs)
    inside, outside = tau0.copy(), np.full_like(omega, side * cap)
    done = feasible(outside, omega, params, inputs)
    inside = np.where(done, outside, inside)
    for _ in range(steps):
        mid = 0.5 * (inside + outside)
        good = feasible(mid, omega, params, inputs)
        inside = np.where(good & ~done, mid, inside)
        outside = np.where(~good & ~done, mid, outside)
    return np.where(ok0, inside, np.nan)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()

    from hound_id.mor.compare import EnvelopeLog, compare
    from hound_id.mor.envelope import EnvelopeInputs, edge, envelope, simulate_log, simulate_trajectory
    from hound_id.mor.spec import load_motor_spec

    spec = load_motor_spec(ROOT / "data" / "samples" / "motors" / "hound_ilm85.yaml")
    inputs = EnvelopeInputs(spec)
    params = {"bus_sag": 0.15, "inductance": 1e-4}
    w = np.random.default_rng(0).uniform(-0.99, 0.99, 20000) * spec.no_load_speed
    illinois = timed(lambda: edge(w, 1, params, inputs), args.repeat * 4)
    bisection = timed(lambda: bisection_edge(w, 1, params, inputs), args.repeat * 4)
    diff = float(np.nanmax(np.abs(edge(w, 1, params, inputs) - bisection_edge(w, 1, params, inputs))))

    runs = {}
    truth = {"bus_sag": 0.15}
    for name, data in (
        ("uniform", simulate_log(inputs, truth, n=100_000, seed=1)),
        ("trajectory", simulate_trajectory(inputs, truth, n=100_000, seed=1)),
    ):
        log = EnvelopeLog(torque=data["torque"], velocity=data["velocity"], bus_voltage=data["bus_voltage"])
        one_pass = timed(lambda log=log: envelope(log.velocity, {}, inputs), args.repeat)
        start = time.perf_counter()
        result = compare(log, inputs, auto=True)
        total = time.perf_counter() - start
        runs[name] = {
            "compare_s": total,
            "envelope_pass_s": one_pass,
            "ratio": total / one_pass,
            "r_pack": result.final.model.get("bus_sag"),
        }

    report = {
        "edge_20k_illinois_s": illinois,
        "edge_20k_bisection_s": bisection,
        "edge_ratio_bisection_over_illinois": bisection / illinois,
        "edge_max_difference_Nm": diff,
        "compare_100k": runs,
    }
    if args.json:
        print(json.dumps(report, indent=2))
        return
    print(f"edge on 20,000 speeds: Illinois {illinois * 1e3:.1f} ms, bisection {bisection * 1e3:.1f} ms, "
          f"ratio {bisection / illinois:.2f}, largest difference {diff:.1e} N m")  # fmt: skip
    for name, r in runs.items():
        print(f"compare --auto, 100,000 rows ({name}): {r['compare_s']:.1f} s = {r['ratio']:.0f} envelope passes "
              f"({r['envelope_pass_s'] * 1e3:.0f} ms each); R_pack = {r['r_pack']:.4f} ohm")  # fmt: skip


if __name__ == "__main__":
    main()
