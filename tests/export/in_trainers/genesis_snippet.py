"""Run inside a Genesis virtual environment (tests/export/test_doc_snippets.py), in the folder holding the export
``out/``: the manual's Genesis snippet (the file given as the argument, docs/export.md's block as printed), executed
after a prelude that gives it the one object it leaves to the user, ``tau_cmd``: a controller's joint torques, far
past the operating regions (+-150 N m, one row per environment the snippet builds). Then it reports on one line of
stdout, after ``snippet result:``, what the snippet did in Genesis: the URDF it loaded, the armature it set against the
sidecar's, and the control force of the step it ran against hound_id.runtime's clip of ``tau_cmd``."""

import json
import re
import sys
from pathlib import Path

import torch

text = Path(sys.argv[1]).read_text()
joints = json.loads(Path("out/hound_like_bundle.json").read_text())["joints"]
envs = int(re.search(r"n_envs=(\d+)", text).group(1))
gen = torch.Generator().manual_seed(3)
namespace = {"__name__": "__main__", "tau_cmd": (torch.rand(envs, len(joints), generator=gen) * 2 - 1) * 150.0}
exec(compile(text, "docs/export.md (the genesis snippet)", "exec"), namespace)

gs, robot, sat, dofs = (namespace[k] for k in ("gs", "robot", "sat", "dofs"))
tau_cmd, qd = namespace["tau_cmd"], namespace["qd"]
want = sat.saturate(tau_cmd, qd)  # the clip at the speeds the snippet read, before its step
applied = robot.get_dofs_control_force(dofs)
print(
    "snippet result:",
    json.dumps(
        {
            "genesis": gs.__version__,
            "urdf": Path(robot.morph.file).name,
            "dofs": int(robot.n_dofs),
            "joints": list(sat.joints),
            "armature": [float(a) for a in robot.get_dofs_armature(dofs).cpu().numpy()],
            "expected_armature": [float(namespace["armature"][j]) for j in sat.joints],
            "shape": list(applied.shape),
            "max_difference": float(torch.max(torch.abs(applied.cpu().double() - want.cpu().double()))),
            "clipped": float(torch.mean((torch.abs(want - tau_cmd) > 1e-6).any(dim=1).double())),
            "finite": bool(torch.all(torch.isfinite(robot.get_dofs_position().cpu()))),
        }
    ),
)
