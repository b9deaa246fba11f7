"""Benchmark: what `hound-id mor --compare` costs, and what its edge solver buys.

In this process:

1. one envelope edge (:func:`hound_id.mor.envelope.edge`, the Illinois root search on the
   voltage margin) against the baseline it replaced: plain bisection on
   :func:`hound_id.mor.envelope.feasible` (60 halvings, the earlier solver, kept here), on
   20,000 speeds with a sagging bus and inductance; the ratio is bisection / Illinois, and the
   largest difference between the two edges is printed;
2. the whole comparison (:func:`hound_id.dyno.envelope.compare.compare` with ``auto``) on a 100,000-row
   log with a hidden 0.15 ohm pack, uniform and time-ordered (``simulate_trajectory``), against
   one evaluation of both edges at every row: the comparison costs this many envelope passes.

3. the scoreboard of issue 13 on the independent dyno simulator of ``tests/dyno/envelope/holdrig.py`` (speed
   holds in random order, trapezoidal pulses to 1.2-2.2x the torque limit, a 300 Hz second-order
   transducer, one-loop-late command and current reply, AR(1) noise with mains hum, a winding that
   heats): each effect hidden in turn (and none), with and without ``torque_cmd``, over
   ``--seeds`` seeds alternating 1 and 2 kHz logging. A run passes when the hidden effect is named
   first, within 15 %, the envelope error ends within 3x the noise level, nothing else is added and
   the verdict is "explained"; the matching motor passes when nothing is added.

Issue 7 names no target; the earlier session measured 24-53 s for 100,000 rows.

Run: .venv/bin/python benchmarks/compare.py [--repeat 5] [--seeds 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))  # benchmarks/timing.py
sys.path.insert(0, str(ROOT))  # the independent simulator lives with the tests


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


def scoreboard(spec, seeds: int) -> list[dict]:
    """Issue 13's runs on the hold-protocol dyno (module docstring, 3)."""
    from rich.progress import Progress

    from hound_id.dyno.envelope.compare import compare
    from hound_id.dyno.envelope.report import comparison_json
    from hound_id.dyno.logs import EnvelopeLog
    from hound_id.mor.envelope import EnvelopeInputs
    from tests.dyno.envelope.holdrig import Dyno, Hidden, run

    cases = {
        "none": (Hidden(), None),
        "bus_sag": (Hidden(r_pack=0.15), 0.15),
        "inductance": (Hidden(inductance=1.0e-4), 1.0e-4),
        "thermal_resistance": (Hidden(alpha=0.0039), 0.0039),
        "current_limit": (Hidden(current_limit=50.0), 50.0),
    }
    rows = []
    with Progress(transient=True) as progress:
        task = progress.add_task("hold-protocol scoreboard", total=seeds * len(cases) * 2)
        for seed in range(1, seeds + 1):
            hz = 2000.0 if seed % 2 == 0 else 1000.0
            for name, (hidden, truth) in cases.items():
                d = run(spec, Dyno(hidden=hidden, seed=seed, log_hz=hz))
                for command in (True, False):
                    log = EnvelopeLog(
                        torque=d["torque"], velocity=d["velocity"], torque_cmd=d["torque_cmd"] if command else None,
                        current=d["current"], bus_voltage=d["bus_voltage"], temperature=d["temperature"],
                    )  # fmt: skip
                    start = time.perf_counter()
                    data = comparison_json(compare(log, EnvelopeInputs(spec), auto=True))
                    seconds = time.perf_counter() - start
                    value = data["model"].get(name)
                    error = None if truth is None or value is None else value / truth - 1
                    rmse, noise = data["envelope_rmse"], data["noise_level"]
                    passed = data["added"] == [] if truth is None else data["added"] == [name] and abs(error) <= 0.15
                    passed = passed and data["explained"] and rmse["with_added"] <= 3 * noise
                    rows.append({
                        "seed": seed, "log_hz": hz, "hidden": name, "torque_cmd": command, "added": data["added"],
                        "value": value, "error": error, "rmse_spec": rmse["model"], "rmse_final": rmse["with_added"],
                        "noise_level": noise, "explained": data["explained"], "bins": data["bins_at_limit"],
                        "lag_rows": (data["limit_detection"] or {}).get("lag_rows"), "seconds": seconds,
                        "passed": bool(passed),
                    })  # fmt: skip
                    progress.advance(task)
    return rows


from timing import timed  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--seeds", type=int, default=3, help="seeds of the hold-protocol scoreboard (0: skip it)")
    args = parser.parse_args()

    from hound_id.dyno.envelope.compare import compare
    from hound_id.dyno.logs import EnvelopeLog
    from hound_id.dyno.simulate.envelope import simulate_log, simulate_trajectory
    from hound_id.mor.envelope import EnvelopeInputs, edge, envelope
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

    board = scoreboard(spec, args.seeds) if args.seeds > 0 else []
    report = {
        "hold_protocol": board,
        "hold_protocol_passed": f"{sum(r['passed'] for r in board)}/{len(board)}",
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
    if board:
        print(f"\nhold protocol (tests/dyno/envelope/holdrig.py), {report['hold_protocol_passed']} runs pass")
        print(
            "| seed | kHz | hidden | torque_cmd | added | fitted (error) | error spec -> final [N m] | noise [N m] "
            "| explained | lag [rows] | s |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for r in board:
            fitted = (
                "-"
                if r["value"] is None
                else f"{r['value']:.4g} ({r['error']:+.1%})"
                if r["error"] is not None
                else f"{r['value']:.4g}"
            )
            lag = "-" if r["lag_rows"] is None else f"{r['lag_rows']:.1f}"
            cells = [r["seed"], f"{r['log_hz'] / 1000:g}", r["hidden"], "yes" if r["torque_cmd"] else "no",
                     ", ".join(r["added"]) or "-", fitted, f"{r['rmse_spec']:.3g} -> {r['rmse_final']:.3g}",
                     f"{r['noise_level']:.2g}", "yes" if r["explained"] else "NO", lag,
                     f"{r['seconds']:.1f}"]  # fmt: skip
            print("| " + " | ".join(str(c) for c in cells) + " |")


if __name__ == "__main__":
    main()
