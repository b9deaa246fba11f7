"""Benchmark: what `hound-id mor --compare` costs, and what its edge solver buys.

In this process:

1. one envelope edge (:func:`hound_id.mor.envelope.edge`: the closed-form guess, then Illinois steps, each speed
   leaving on its own tolerance) against two baselines kept here: the Illinois search it replaced (from the bracket's
   ends, every speed iterated until all had converged, on V_avail - |V_req|), and plain bisection on
   :func:`hound_id.mor.envelope.feasible` (60 halvings, the solver before that), on 20,000 speeds with a sagging bus
   and inductance; the ratios are baseline / current, and the largest differences between the edges are printed;
2. the whole comparison (:func:`hound_id.dyno.envelope.compare.compare` with ``auto``) on a 100,000-row log with a
   hidden 0.15 ohm pack, uniform and time-ordered (``simulate_trajectory``): against one evaluation of both edges
   at every row (the comparison costs this many envelope passes), and with the earlier edge search of 1. put in for
   the current one (everything else as now: the before/after of the root search in one process);
3. ``--scaling``: compare --auto against the rows of the uniform log (10^4, 3x10^4, 10^5, 3x10^5), with the peak
   of the memory numpy and Python allocate during one comparison (tracemalloc);
4. the scoreboard on the independent dyno simulator of ``tests/dyno/envelope/holdrig.py`` (speed
   holds in random order, trapezoidal pulses to 1.2-2.2x the torque limit, a 300 Hz second-order
   transducer, one-loop-late command and current reply, AR(1) noise with mains hum, a winding that
   heats): each effect hidden in turn (and none), with and without ``torque_cmd``, over
   ``--seeds`` seeds alternating 1 and 2 kHz logging. A run passes when the hidden effect is named
   first, within 15 %, the envelope error ends within 3x the noise level, nothing else is added and
   the verdict is "explained"; the matching motor passes when nothing is added.

Times are medians of ``--repeat`` runs (another process may share the CPU). No target was set; the earlier
session measured 24-53 s for 100,000 rows, the cmp18 branch 4.0-7.4 s before its speed-up.

Run: .venv/bin/python benchmarks/compare.py [--repeat 5] [--seeds 3] [--scaling] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import tracemalloc
from dataclasses import replace
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


def earlier_edge(omega, side, params, inputs):
    """The root search edge() used before: Illinois steps from the bracket's ends (the zero-voltage torque and the
    torque and current limits) on V_avail - |V_req|, every speed iterated until all had converged. ``side`` may be
    one per speed (as the comparison asks); a linear current-torque line (no kt_saturation: not needed here)."""
    from hound_id.mor.envelope import EDGE_ITERATIONS, EDGE_TOLERANCE, bus_voltage, feasible

    side = np.broadcast_to(np.asarray(side), np.shape(omega))
    if np.unique(side).size > 1:  # one call per side, as the comparison's offsets made them
        out = np.empty(np.shape(omega))
        for s in (1, -1):
            at = side == s
            temperature = None if inputs.temperature is None else np.broadcast_to(inputs.temperature, out.shape)[at]
            out[at] = earlier_edge(omega[at], s, params, replace(inputs, temperature=temperature))
        return out
    side = int(side.flat[0]) if side.size else 1
    spec, w = inputs.spec, np.asarray(omega, dtype=float)
    cap = spec.linear_torque_limit
    i_limit = min(spec.max_current or np.inf, params.get("current_limit", np.inf))
    start, reach_abs = min(cap, 0.999 * spec.kt * i_limit), min(cap, spec.kt * i_limit)  # a linear line
    tau0 = np.clip(-spec.kt * w / (spec.resistance * spec.kv), -start, start)
    ok0 = feasible(tau0, w, params, inputs)
    for _ in range(40):
        if ok0.all():
            break
        tau0 = np.where(ok0, tau0, 0.8 * tau0)
        ok0 = feasible(tau0, w, params, inputs)
    resistance = spec.resistance * np.ones_like(w)
    if "thermal_resistance" in params and inputs.temperature is not None:
        resistance = resistance * (1.0 + params["thermal_resistance"] * (inputs.temperature - 25.0))
    back_emf, quadrature = w / spec.kv, (spec.pole_pairs or 0) * w * params.get("inductance", 0.0)

    def margin(tau, idx):
        r, e, q = (
            (resistance, back_emf, quadrature) if idx is None else (resistance[idx], back_emf[idx], quadrature[idx])
        )
        i = tau / spec.kt
        v_q = r * i + e
        power = v_q * i
        v_avail = bus_voltage(
            spec.bus_voltage, np.where(power > 0.0, params.get("bus_sag", 0.0), params.get("regen_rise", 0.0)), power
        )
        return v_avail - (np.hypot(v_q, q * i) if params.get("inductance", 0.0) > 0.0 else np.abs(v_q))

    reach = np.full_like(w, side * reach_abs)
    out = reach.copy()
    live = np.flatnonzero(ok0 & (margin(reach, None) < 0.0))
    if live.size:
        a, b = tau0[live], reach[live]
        ga, gb = margin(a, live), margin(b, live)
        stale = np.zeros(live.size, dtype=np.int8)
        for _ in range(EDGE_ITERATIONS):
            if np.all((b - a) * side <= EDGE_TOLERANCE * cap) or np.all(ga <= EDGE_TOLERANCE * spec.bus_voltage):
                break
            c = b - gb * (b - a) / (gb - ga)
            c = np.where(np.isfinite(c) & ((c - a) * (c - b) < 0), c, 0.5 * (a + b))
            gc = margin(c, live)
            inside = gc >= 0.0
            gb = np.where(inside & (stale > 0), 0.5 * gb, gb)
            ga = np.where(~inside & (stale < 0), 0.5 * ga, ga)
            a, ga = np.where(inside, c, a), np.where(inside, gc, ga)
            b, gb = np.where(inside, b, c), np.where(inside, gb, gc)
            stale = np.where(inside, 1, -1).astype(np.int8)
        out[live] = a
    return np.where(ok0, out, np.nan)


def scoreboard(spec, seeds: int) -> list[dict]:
    """The runs on the hold-protocol dyno (module docstring, 3)."""
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


def with_earlier_edge(fn):
    """``fn()`` with :func:`earlier_edge` put in for hound-id's edge (the comparison's before/after of its root
    search)."""
    import hound_id.dyno.envelope.offsets as offsets_module
    import hound_id.mor.envelope as envelope_module

    saved = envelope_module.edge, offsets_module.edge
    envelope_module.edge = offsets_module.edge = earlier_edge
    try:
        return fn()
    finally:
        envelope_module.edge, offsets_module.edge = saved


def peak_memory(fn) -> float:
    """The peak of the memory Python and numpy allocate during ``fn()`` [MB] (tracemalloc)."""
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--seeds", type=int, default=3, help="seeds of the hold-protocol scoreboard (0: skip it)")
    parser.add_argument("--scaling", action="store_true", help="compare --auto against the rows of the uniform log")
    args = parser.parse_args()

    from hound_id.dyno.envelope.compare import compare
    from hound_id.dyno.logs import EnvelopeLog
    from hound_id.dyno.simulate.envelope import simulate_log, simulate_trajectory
    from hound_id.mor.envelope import EnvelopeInputs, edge, envelope
    from hound_id.mor.spec_sheet import load_motor_spec

    spec = load_motor_spec(ROOT / "data" / "samples" / "motors" / "hound_ilm85.yaml")
    inputs = EnvelopeInputs(spec)
    params = {"bus_sag": 0.15, "inductance": 1e-4}
    w = np.random.default_rng(0).uniform(-0.99, 0.99, 20000) * spec.no_load_speed
    current = timed(lambda: edge(w, 1, params, inputs), args.repeat * 4)
    earlier = timed(lambda: earlier_edge(w, 1, params, inputs), args.repeat * 4)
    bisection = timed(lambda: bisection_edge(w, 1, params, inputs), args.repeat * 4)
    now = edge(w, 1, params, inputs)
    diff = float(np.nanmax(np.abs(now - bisection_edge(w, 1, params, inputs))))
    diff_earlier = float(np.nanmax(np.abs(now - earlier_edge(w, 1, params, inputs))))

    truth = {"bus_sag": 0.15}

    def log_of(data):
        return EnvelopeLog(torque=data["torque"], velocity=data["velocity"], bus_voltage=data["bus_voltage"])

    compare(log_of(simulate_log(inputs, truth, n=10_000, seed=1)), inputs, auto=True)  # imports and caches warm
    runs = {}
    for name, data in (
        ("uniform", simulate_log(inputs, truth, n=100_000, seed=1)),
        ("trajectory", simulate_trajectory(inputs, truth, n=100_000, seed=1)),
    ):
        log = log_of(data)
        one_pass = timed(lambda log=log: envelope(log.velocity, {}, inputs), args.repeat)
        result = compare(log, inputs, auto=True)
        total = timed(lambda log=log: compare(log, inputs, auto=True), args.repeat)
        before = timed(lambda log=log: with_earlier_edge(lambda: compare(log, inputs, auto=True)), args.repeat)
        runs[name] = {
            "compare_s": total,
            "compare_earlier_edge_s": before,
            "envelope_pass_s": one_pass,
            "ratio": total / one_pass,
            "r_pack": result.final.model.get("bus_sag"),
        }

    scaling = []
    if args.scaling:
        for rows in (10_000, 30_000, 100_000, 300_000):
            log = log_of(simulate_log(inputs, truth, n=rows, seed=1))
            seconds = timed(lambda log=log: compare(log, inputs, auto=True), args.repeat)
            scaling.append(
                {
                    "rows": rows,
                    "compare_s": seconds,
                    "peak_MB": peak_memory(lambda log=log: compare(log, inputs, auto=True)),
                }
            )

    board = scoreboard(spec, args.seeds) if args.seeds > 0 else []
    report = {
        "hold_protocol": board,
        "hold_protocol_passed": f"{sum(r['passed'] for r in board)}/{len(board)}",
        "edge_20k_illinois_s": current,
        "edge_20k_earlier_illinois_s": earlier,
        "edge_20k_bisection_s": bisection,
        "edge_ratio_bisection_over_illinois": bisection / current,
        "edge_ratio_earlier_over_illinois": earlier / current,
        "edge_max_difference_Nm": diff,
        "edge_max_difference_earlier_Nm": diff_earlier,
        "compare_100k": runs,
        "scaling": scaling,
    }
    if args.json:
        print(json.dumps({"schema": "hound-id/bench-compare/2", **report}, indent=2))
        return
    print(f"edge on 20,000 speeds: {current * 1e3:.1f} ms; the earlier Illinois search {earlier * 1e3:.1f} ms "
          f"(ratio {earlier / current:.1f}, largest difference {diff_earlier:.1e} N m), bisection "
          f"{bisection * 1e3:.1f} ms (ratio {bisection / current:.1f}, largest difference {diff:.1e} N m)")  # fmt: skip
    for name, r in runs.items():
        now, before = r["compare_s"], r["compare_earlier_edge_s"]
        print(f"compare --auto, 100,000 rows ({name}): {now:.2f} s, {before:.2f} s with the earlier edge search "
              f"(ratio {before / now:.1f}); = {r['ratio']:.0f} envelope passes ({r['envelope_pass_s'] * 1e3:.1f} ms "
              f"each); R_pack = {r['r_pack']:.4f} ohm")  # fmt: skip
    if scaling:
        print("\n| rows | compare --auto [s] | per 100,000 rows [s] | peak memory [MB] |\n|---|---|---|---|")
        for r in scaling:
            per = r["compare_s"] * 1e5 / r["rows"]
            print(f"| {r['rows']:,} | {r['compare_s']:.2f} | {per:.2f} | {r['peak_MB']:.0f} |")
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
