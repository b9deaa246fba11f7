"""Benchmark: why the foot optimiser uses closed-form mass properties, and what the whole job costs.

In this process, on the sample leg and its running log:

1. one design evaluation the closed-form way (:func:`hound_id.foot.geometry.mass_properties`)
   against the baseline an optimiser without closed forms would use: build the solid with
   manifold3d at the default 2 deg mesh and measure it with trimesh
   (:func:`foot_mesh` + :func:`mesh_properties`); the ratio is mesh / closed form;
2. the casadi/IPOPT optimisation (:func:`optimise_foot`, warm process) against one mesh
   evaluation: the whole optimisation costs this many mesh evaluations;
3. the accuracy that buys: closed form against a fine (0.5 deg) mesh.

No target is set; the figures show the closed form is what makes an
interactive (sub-second) optimisation possible.

Run: .venv/bin/python benchmarks/foot.py [--repeat 20] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))  # benchmarks/timing.py


from timing import timed  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=20)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()

    from hound_id.foot.angles import gait_angles
    from hound_id.foot.geometry import foot_mesh, mass_properties, mesh_properties
    from hound_id.foot.material import GROUNDS, MATERIALS
    from hound_id.foot.optimise import FootRequirements, optimise_foot
    from hound_id.foot.urdf import read_foot

    samples = ROOT / "data" / "samples"
    angles = gait_angles(samples / "gait" / "hound_running.csv")
    req = FootRequirements(low=angles.low, high=angles.high, material=MATERIALS["aluminium_7075_t6"],
                           ground=GROUNDS["concrete"], peak_force=1500.0, margin=angles.margin)  # fmt: skip
    mount = read_foot(samples / "legs" / "hound_leg.urdf")
    design = optimise_foot(mount, req)  # warm-up: imports, casadi code generation
    g, rho = design.geometry, req.material.density

    closed = timed(lambda: mass_properties(g, rho), args.repeat * 50)
    mesh = timed(lambda: mesh_properties(foot_mesh(g, 2.0), rho), args.repeat)
    optimise = timed(lambda: optimise_foot(mount, req), args.repeat)
    fine = mesh_properties(foot_mesh(g, 0.5), rho)
    exact = mass_properties(g, rho)
    result = {
        "closed_form_s": closed,
        "mesh_s": mesh,
        "ratio_mesh_over_closed_form": mesh / closed,
        "optimise_s": optimise,
        "optimise_in_mesh_evaluations": optimise / mesh,
        "ipopt_iterations": design.solver["iterations"],
        "closed_form_vs_fine_mesh_mass": fine.mass / exact.mass - 1,
        "closed_form_vs_fine_mesh_iyy": fine.inertia[1, 1] / exact.inertia[1, 1] - 1,
    }
    if args.json:
        print(json.dumps(result, indent=2))
        return
    print(f"one evaluation: closed form {closed * 1e6:.1f} us, mesh (manifold3d + trimesh, 2 deg) {mesh * 1e3:.1f} ms")
    print(f"ratio mesh / closed form: {mesh / closed:.0f}")
    print(f"whole casadi/IPOPT optimisation: {optimise * 1e3:.1f} ms ({design.solver['iterations']} iterations) "
          f"= {optimise / mesh:.2f} mesh evaluations")  # fmt: skip
    print(f"closed form vs a 0.5 deg mesh: mass {result['closed_form_vs_fine_mesh_mass']:+.2e}, "
          f"Iyy {result['closed_form_vs_fine_mesh_iyy']:+.2e}")  # fmt: skip


if __name__ == "__main__":
    main()
