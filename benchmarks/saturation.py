"""Benchmark: coupled motor-space saturation vs the per-joint DC-motor clip.

4096 environments x 12 joints of the sample Hound-like robot (4 legs of HAA on its
own gearbox + hollow-shaft HFE/KFE). The baseline is the per-joint DC-motor clip of
Isaac Lab / mjlab (:func:`hound_id.mor.saturation.dc_motor_clip`) with each joint's
joint-side stall torque, no-load speed and torque limit, computed in the same run on
the same inputs. Prints the time ratio (target: at most 1.5) for numpy and torch
(CPU, float32 as trainers use).

Run: .venv/bin/python benchmarks/saturation.py [--envs 4096] [--repeats 200]
"""

from __future__ import annotations

import argparse
import json
import timeit
from pathlib import Path

import numpy as np

from hound_id.mor.region import operating_region
from hound_id.mor.robot import load_robot
from hound_id.mor.saturation import dc_motor_clip, saturation_for

ROBOT = Path(__file__).resolve().parent.parent / "data" / "samples" / "robots" / "hound_like.yaml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", type=int, default=4096)
    parser.add_argument("--repeats", type=int, default=200)
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parser.parse_args()

    robot = load_robot(ROBOT)
    sat = saturation_for(robot)
    # per-joint parameters a simulator's DC-motor model would hold (diagonal gear ratio)
    gear = 1.0 / np.abs(np.diag(robot.velocity_map()))
    regions = [operating_region(robot.motor_specs[m]) for m in robot.motors]
    sat_effort = np.array([r.stall_torque for r in regions]) * gear
    vel_limit = np.array([r.no_load_speed for r in regions]) / gear
    eff_limit = np.array([r.torque_limit for r in regions]) * gear

    rng = np.random.default_rng(0)
    tau = (rng.uniform(-1.3, 1.3, (args.envs, sat.n)) * eff_limit).astype(np.float32)
    qd = (rng.uniform(-1.2, 1.2, (args.envs, sat.n)) * vel_limit).astype(np.float32)
    consts32 = [a.astype(np.float32) for a in (sat_effort, vel_limit, eff_limit)]

    def timed(base, ours) -> tuple[float, float]:  # type: ignore[no-untyped-def]
        """Best time per call of each, measured in alternating rounds so drift hits both alike."""
        base(), ours()  # warm-up (caches, allocations)
        best = [float("inf"), float("inf")]
        for _ in range(max(3, args.repeats // 10)):
            for i, fn in enumerate((base, ours)):
                best[i] = min(best[i], timeit.timeit(fn, number=10) / 10)
        return best[0], best[1]

    results = {}
    results["numpy"] = timed(lambda: dc_motor_clip(tau, qd, *consts32), lambda: sat(tau, qd))

    try:
        import torch
    except ImportError:  # pragma: no cover - torch is part of the test set-up
        torch = None
    if torch is not None:
        torch.set_num_threads(1)
        tt, tq = torch.from_numpy(tau), torch.from_numpy(qd)
        tc = [torch.from_numpy(c) for c in consts32]
        results["torch-cpu"] = timed(lambda: dc_motor_clip(tt, tq, *tc), lambda: sat(tt, tq))

    figures = {k: {"per_joint_clip_us": b * 1e6, "coupled_mor_clip_us": o * 1e6, "ratio": o / b}
               for k, (b, o) in results.items()}
    if args.json:
        print(json.dumps({"schema": "hound-id/bench-saturation/1", "envs": args.envs, "joints": sat.n,
                          "results": figures}, indent=2))
        return
    print(f"saturation of {args.envs} envs x {sat.n} joints (target ratio <= 1.5)")
    for k, f in figures.items():
        print(f"  {k:10s} per-joint DC clip {f['per_joint_clip_us']:8.1f} us   coupled MOR clip "
              f"{f['coupled_mor_clip_us']:8.1f} us   ratio {f['ratio']:.2f}")


if __name__ == "__main__":
    main()
