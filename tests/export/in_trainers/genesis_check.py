"""Run inside a Genesis virtual environment (tests/export/test_trainers.py): load an exported URDF in Genesis (which
enforces URDF effort limits on the applied force), set the armature sidecar, apply hound_id.runtime's saturated
torques at random joint speeds, and print how far Genesis's realised control force is from them (JSON on stdout).
Arguments: the export folder, the URDF's file name, the largest motor speed drawn [rad/s]."""

import json
import sys
from pathlib import Path

import genesis as gs
import numpy as np
import yaml

import hound_id.runtime

folder, urdf, speed = Path(sys.argv[1]), sys.argv[2], float(sys.argv[3])
gs.init(backend=gs.cpu, logging_level="error")
ENVS = 64
scene = gs.Scene(show_viewer=False, sim_options=gs.options.SimOptions(dt=1e-3))
robot = scene.add_entity(gs.morphs.URDF(file=str(folder / urdf), fixed=True))
scene.build(n_envs=ENVS)
sat = hound_id.runtime.load(folder / "hound_like_bundle.json")
dofs = [robot.get_joint(j).dofs_idx_local[0] for j in sat.joints]
armature = yaml.safe_load((folder / "hound_like_armature.yaml").read_text())["armature"]
robot.set_dofs_armature(np.array([armature[j] for j in sat.joints]), dofs)
rng = np.random.default_rng(1)
worst = 0.0
for _ in range(20):
    omega = rng.uniform(-1, 1, (ENVS, len(sat.motors))) * speed
    qd = omega @ sat.clip.A.T
    want = sat.saturate(rng.uniform(-1, 1, (ENVS, len(sat.joints))) * 150.0, qd)
    robot.set_dofs_velocity(qd, dofs)
    robot.control_dofs_force(want, dofs)
    scene.step()
    worst = max(worst, float(np.max(np.abs(robot.get_dofs_control_force(dofs).cpu().numpy() - want))))
print(
    json.dumps(
        {
            "genesis": gs.__version__,
            "max_difference": worst,
            "armature": [float(a) for a in robot.get_dofs_armature(dofs).cpu().numpy()],
            "expected_armature": [float(armature[j]) for j in sat.joints],
        }
    )
)
