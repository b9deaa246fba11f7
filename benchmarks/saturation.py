"""Benchmark: coupled motor-space saturation vs the per-joint DC-motor clip.

4096 environments x 12 joints of the sample Hound-like robot (4 legs of HAA on its
own gearbox + hollow-shaft HFE/KFE). The baseline is the per-joint DC-motor clip of
Isaac Lab / mjlab (:func:`hound_id.mor.saturation.dc_motor_clip`) with each joint's
joint-side stall torque, no-load speed and torque limit, computed in the same run on
the same inputs. Prints the time ratio (target: at most 1.5) for numpy and torch
(CPU, float32 as trainers use).

Each measurement runs the baseline and the coupled clip alternately in one process.
Single processes on this 2-core VM swing by up to +-40 % with memory layout and
neighbours, so the script runs --processes fresh processes and reports the median
ratio and the range.

Besides the ratio to the per-joint clip it prints the ratio to the memory floor: one pass that
reads both inputs and writes one output (``add(tau, qd, out=buf)``), the least traffic any clip
needs. ``--envs 256,4096,65536`` (or ``--scaling``: 256 to 65,536) runs several batch sizes. With
a CUDA device, torch is timed there too (synchronised around each call).

``--dc-law`` drops the sample motor's inductance (the paper's DC law, the clip before the drive's dq model);
``--bus-voltage`` gives each environment its own bus voltage, drawn in the battery's range (66-84 V), to both
clips as full (envs, joints) arrays set at reset, as a trainer randomising the charge keeps them: the per-joint
clip's stall torque and no-load speed scaled by V / V_nom, the coupled clip's ``bus_voltage``.
``--temperature`` gives each winding its own temperature (25-115 degC, a full (envs, joints) array, as a trainer
carrying the runtime's temperature state holds it) to the coupled clip (``temperature``: R, Kt and the back-EMF at
that temperature, the derated current limit; the general path, no fused loop); the per-joint baseline keeps its
20 degC limits, so the ratio includes all of the temperature's arithmetic.

Run: .venv/bin/python benchmarks/saturation.py [--envs 4096] [--processes 5] [--json] [--dc-law] [--bus-voltage]
         [--temperature]
     .venv/bin/python benchmarks/saturation.py --scaling --json    # 256 ... 65,536 environments
     .venv/bin/python benchmarks/saturation.py --feasibility   # worst excess past the region, per dtype
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import timeit
from pathlib import Path

import numpy as np

from hound_id.mor import fused
from hound_id.mor.region import operating_region
from hound_id.mor.robot import load_robot
from hound_id.mor.saturation import dc_motor_clip, saturation_for

ROBOT = Path(__file__).resolve().parent.parent / "data" / "samples" / "robots" / "hound_like.yaml"


def pin_allocator() -> bool:
    """Fix glibc's malloc thresholds for the whole process (both sides alike).

    By default glibc serves each ~200 kB temporary with mmap and returns it to the
    OS on free, so every call page-faults its arrays in; whether it does depends on
    the allocation history, which made single runs swing by +-40 %. A trainer's
    long-lived process reaches the steady state this pins.
    """
    import ctypes
    import ctypes.util

    name = ctypes.util.find_library("c")
    if name is None:
        return False
    libc = ctypes.CDLL(name)
    m_trim_threshold, m_mmap_threshold = -1, -3
    return bool(libc.mallopt(m_mmap_threshold, 64 << 20)) and bool(libc.mallopt(m_trim_threshold, 256 << 20))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", default="4096", help="environments, or a comma-separated list of them")
    parser.add_argument("--scaling", action="store_true", help="--envs 256,1024,4096,16384,65536")
    parser.add_argument("--repeats", type=int, default=1000)
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    parser.add_argument("--raw-malloc", action="store_true", help="leave glibc's malloc thresholds alone")
    parser.add_argument("--processes", type=int, default=5, help="fresh processes to take the median over")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--dc-law", action="store_true", help="the sample motor without its inductance (DC law)")
    parser.add_argument("--bus-voltage", action="store_true", help="a bus voltage per environment (66-84 V)")
    parser.add_argument("--temperature", action="store_true", help="a winding temperature per motor (25-115 degC)")
    parser.add_argument(
        "--feasibility",
        action="store_true",
        help="instead: the worst motor-torque excess over a sweep of command sizes",
    )
    args = parser.parse_args()
    if args.feasibility:
        return feasibility(args)
    if not args.worker:
        return report(args)
    pinned = False if args.raw_malloc else pin_allocator()
    envs = int(args.envs)

    robot = load_robot(ROBOT)
    if args.dc_law:
        from dataclasses import replace

        specs = {m: replace(s, inductance=None, inductance_convention=None) for m, s in robot.motor_specs.items()}
        robot = replace(robot, motor_specs=specs)
    sat = saturation_for(robot)
    # per-joint parameters a simulator's DC-motor model would hold (diagonal gear ratio)
    gear = 1.0 / np.abs(np.diag(robot.velocity_map()))
    regions = [operating_region(robot.motor_specs[m]) for m in robot.motors]
    sat_effort = np.array([r.stall_torque for r in regions]) * gear
    vel_limit = np.array([r.no_load_speed for r in regions]) / gear
    eff_limit = np.array([r.torque_limit for r in regions]) * gear

    rng = np.random.default_rng(0)
    tau = (rng.uniform(-1.3, 1.3, (envs, sat.n)) * eff_limit).astype(np.float32)
    qd = (rng.uniform(-1.2, 1.2, (envs, sat.n)) * vel_limit).astype(np.float32)
    # The baseline holds its limits as full (envs, joints) arrays, as Isaac Lab does, with the
    # corner speed precomputed at start-up.
    vel_at_limit = vel_limit * (1.0 + eff_limit / sat_effort)
    consts32 = [
        np.ascontiguousarray(np.broadcast_to(a, tau.shape), dtype=np.float32)
        for a in (sat_effort, vel_limit, eff_limit, vel_at_limit)
    ]
    volts = None
    if args.bus_voltage:  # set at reset: the per-joint clip's stall torque and no-load speed follow V / V_nom
        v_nom = np.array([robot.motor_specs[m].bus_voltage for m in robot.motors])
        volts = np.repeat(rng.uniform(66.0, 84.0, (envs, 1)), sat.n, axis=1).astype(np.float32)
        scale = (volts / v_nom).astype(np.float32)
        consts32[0] = np.ascontiguousarray(consts32[0] * scale)
        consts32[1] = np.ascontiguousarray(consts32[1] * scale)
        consts32[3] = np.ascontiguousarray(consts32[1] * (1.0 + consts32[2] / consts32[0]))

    temps = None
    if args.temperature:
        temps = rng.uniform(25.0, 115.0, tau.shape).astype(np.float32)

    # fewer rounds for big batches: each call is longer, and the total stays about the same
    rounds = max(3, int(args.repeats * 4096 / max(envs, 4096)) // 10)

    def timed(*fns, sync=None) -> list[float]:  # type: ignore[no-untyped-def]
        """Best time per call of each, measured in alternating rounds so drift hits all alike."""
        for fn in fns:  # warm-up (caches, allocations)
            fn()
        best = [float("inf")] * len(fns)

        def call(fn):  # type: ignore[no-untyped-def]
            def run() -> None:
                fn()
                if sync is not None:
                    sync()

            return run

        for _ in range(rounds):
            for i, fn in enumerate(fns):
                best[i] = min(best[i], timeit.timeit(call(fn), number=10) / 10)
        return best

    results = {}
    buf = np.empty_like(tau)
    fused_on = fused.available()
    results["numpy"] = timed(
        lambda: dc_motor_clip(tau, qd, *consts32),
        lambda: sat(tau, qd, volts, temps),
        lambda: np.add(tau, qd, out=buf),
    )
    if fused_on and temps is None:  # the same clip with numpy's steps (one pass each), as without numba
        os.environ[fused.ENV] = "0"
        results["numpy-steps"] = timed(
            lambda: dc_motor_clip(tau, qd, *consts32), lambda: sat(tau, qd, volts), lambda: np.add(tau, qd, out=buf)
        )
        os.environ[fused.ENV] = "1"

    import importlib.util

    if importlib.util.find_spec("torch") is not None:  # torch is part of the test set-up
        import torch

        torch.set_num_threads(1)
        devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
        for device in devices:
            tt, tq = torch.from_numpy(tau).to(device), torch.from_numpy(qd).to(device)
            tv = None if volts is None else torch.from_numpy(volts).to(device)
            tT = None if temps is None else torch.from_numpy(temps).to(device)
            tc = [torch.from_numpy(c).to(device) for c in consts32]
            tb = torch.empty_like(tt)
            results[f"torch-{device}"] = timed(
                lambda: dc_motor_clip(tt, tq, *tc),  # noqa: B023 (timed here, in this iteration)
                lambda: sat(tt, tq, tv, tT),  # noqa: B023
                lambda: torch.add(tt, tq, out=tb),  # noqa: B023
                sync=torch.cuda.synchronize if device == "cuda" else None,
            )

    figures = {
        k: {
            "per_joint_clip_us": b * 1e6,
            "coupled_mor_clip_us": o * 1e6,
            "memory_floor_us": f * 1e6,
            "ratio": o / b,
            "ratio_to_floor": o / f,
            "per_joint_ratio_to_floor": b / f,
        }
        for k, (b, o, f) in results.items()
    }
    print(json.dumps({"allocator_pinned": pinned, "joints": sat.n, "fused": fused_on, "results": figures}))


def feasibility(args: argparse.Namespace) -> None:
    """Worst excess of the saturated motor torques past their intervals, relative to the torque limit.

    Commands of 1e-3 to 1e30 N m (log-uniform, random signs), within +-400 N m, within the largest
    command the short path takes (uniform) and, in each dtype, the largest finite value in every
    joint; speeds uniform within +-120 rad/s (past every motor's overspeed). The
    saturated torques are mapped to motor space and compared with the intervals in float64.
    With ``--temperature`` every winding has its own temperature, uniform in -20 to 140 degC (past the winding
    limit: no current), and the intervals are those at it.
    """
    robot = load_robot(ROBOT)
    sat = saturation_for(robot)
    rng = np.random.default_rng(0)
    rows = 200_000
    magnitude = 10.0 ** rng.uniform(-3, 30, (rows, sat.n)) * rng.choice([-1.0, 1.0], (rows, sat.n))
    qd = rng.uniform(-120.0, 120.0, (rows, sat.n))
    temps = rng.uniform(-20.0, 140.0, (rows, sat.n)) if args.temperature else None
    lo, hi = sat.torque_bounds(qd)
    results = {}
    import torch

    for dtype in (np.float32, np.float64):
        big = float(np.finfo(dtype).max)
        extreme = np.vstack([np.eye(sat.n) * big, -np.eye(sat.n) * big, np.full((1, sat.n), big)])
        ordinary = rng.uniform(-1.0, 1.0, (rows, sat.n)) * 400.0  # the short path
        bound = sat._constants(np.zeros((1, sat.n))).ordinary  # the largest command the short path takes
        edge = rng.uniform(-1.0, 1.0, (rows, sat.n)) * bound
        cases = (("huge", magnitude), ("ordinary", ordinary), (f"to {bound:.0f} N m", edge), ("dtype max", extreme))
        for name, tau in cases:
            q = qd[: len(tau)].astype(dtype)
            temp = None if temps is None else temps[: len(tau)].astype(dtype)
            lo_, hi_ = sat.torque_bounds(q.astype(np.float64), None, None if temp is None else temp.astype(np.float64))
            for backend in ("numpy", "torch"):
                t = tau.astype(dtype)
                if backend == "numpy":
                    out = sat(t, q, None, temp)
                else:
                    tt = None if temp is None else torch.from_numpy(temp)
                    out = sat(torch.from_numpy(t), torch.from_numpy(q), None, tt).numpy()
                tau_m = out.astype(np.float64) @ sat.A
                excess = np.maximum(np.maximum(tau_m - hi_, lo_ - tau_m), 0.0) / sat.torque_limit
                key = f"{np.dtype(dtype).name} {backend} {name}"
                results[key] = {"worst_excess_over_limit": float(excess.max()), "finite": bool(np.isfinite(out).all())}
    del lo, hi
    if args.json:
        print(
            json.dumps(
                {
                    "schema": "hound-id/bench-saturation-feasibility/1",
                    "rows": rows,
                    "temperature": bool(args.temperature),
                    "results": results,
                }
            )
        )
        return
    print("worst motor torque past its interval, over the torque limit (float64 check of the saturated torques):")
    for key, r in results.items():
        print(f"  {key:28s} {r['worst_excess_over_limit']:.2e}  finite: {r['finite']}")


#: ``--scaling``: the batch sizes, 256 to 65,536 environments.
SCALING = (256, 1024, 4096, 16384, 65536)
#: The target for the ratio to the per-joint clip.
TARGET_RATIO = 1.0


def report(args: argparse.Namespace) -> None:
    """Run the workers for each batch size and print the median ratios per backend (JSON with --json)."""
    sizes = SCALING if args.scaling else tuple(int(e) for e in str(args.envs).split(","))
    table = []
    for envs in sizes:
        cmd = [sys.executable, __file__, "--worker", "--envs", str(envs), "--repeats", str(args.repeats)]
        if args.raw_malloc:
            cmd.append("--raw-malloc")
        cmd += ["--dc-law"] * args.dc_law + ["--bus-voltage"] * args.bus_voltage + ["--temperature"] * args.temperature
        runs = [
            json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
            for _ in range(args.processes)
        ]
        summary = {}
        for backend in runs[0]["results"]:
            rows = [r["results"][backend] for r in runs]
            ratios = [r["ratio"] for r in rows]
            summary[backend] = {
                "ratio_median": statistics.median(ratios),
                "ratio_min": min(ratios),
                "ratio_max": max(ratios),
                "ratio_to_floor_median": statistics.median(r["ratio_to_floor"] for r in rows),
                "per_joint_ratio_to_floor_median": statistics.median(r["per_joint_ratio_to_floor"] for r in rows),
                "per_joint_clip_us_median": statistics.median(r["per_joint_clip_us"] for r in rows),
                "coupled_mor_clip_us_median": statistics.median(r["coupled_mor_clip_us"] for r in rows),
                "memory_floor_us_median": statistics.median(r["memory_floor_us"] for r in rows),
            }
        flags = {k: runs[0][k] for k in ("allocator_pinned", "fused")}
        table.append({"envs": envs, "results": summary, **flags})
    if args.json:
        print(
            json.dumps(
                {
                    "schema": "hound-id/bench-saturation/3",
                    "joints": 12,
                    "processes": args.processes,
                    "target_ratio": TARGET_RATIO,
                    "sizes": table,
                },
                indent=2,
            )
        )
        return
    print(
        f"saturation of envs x 12 joints, median of {args.processes} processes (target ratio <= {TARGET_RATIO}); "
        f"malloc thresholds {'pinned' if table[0]['allocator_pinned'] else 'default'}; floor = one add(tau, qd); "
        + ("numpy and torch-cpu fused (numba), numpy-steps without" if table[0]["fused"] else "numba absent: no fusion")
    )
    for row in table:
        for backend, f in row["results"].items():
            print(
                f"  {row['envs']:6d} {backend:11s} per-joint {f['per_joint_clip_us_median']:8.1f} us  coupled "
                f"{f['coupled_mor_clip_us_median']:8.1f} us  floor {f['memory_floor_us_median']:7.1f} us  ratio "
                f"{f['ratio_median']:.2f} ({f['ratio_min']:.2f}-{f['ratio_max']:.2f})  to floor: coupled "
                f"{f['ratio_to_floor_median']:.1f}, per-joint {f['per_joint_ratio_to_floor_median']:.1f}"
            )


if __name__ == "__main__":
    main()
