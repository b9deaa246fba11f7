"""Run inside a Newton virtual environment (tests/export/test_doc_snippets.py), in the folder holding the export
``out/``: the manual's Newton snippet (the file given as the argument, docs/export.md's block as printed), executed
after a prelude that gives it what it leaves to the user: ``tau_cmd``, a controller's joint torques far past the
operating regions (+-150 N m), and the generated module on the import path. The snippet steps SolverMuJoCo once; this
reports on one line of stdout, after ``snippet result:``, the realised motor torques of that step's voltage-input
dcmotors against hound_id.runtime's clip of ``tau_cmd`` at the speeds the snippet read."""

import json
import sys
from pathlib import Path

import mujoco
import newton
import numpy as np

text = Path(sys.argv[1]).read_text()
sys.path.insert(0, "out")  # where the generated hound_like_newton.py is
joints = json.loads(Path("out/hound_like_bundle.json").read_text())["joints"]
tau_cmd = np.random.default_rng(7).uniform(-150.0, 150.0, len(joints))
namespace = {"__name__": "__main__", "tau_cmd": tau_cmd}
exec(compile(text, "docs/export.md (the newton snippet)", "exec"), namespace)

solver, sat, state, qd = (namespace[k] for k in ("solver", "sat", "state", "qd"))
mjm = solver.mj_model
tendons = [mujoco.mj_id2name(mjm, mujoco.mjtObj.mjOBJ_TENDON, i) for i in range(mjm.ntendon)]
TENDON = mujoco.mjtTrn.mjTRN_TENDON
on_tendons = {tendons[mjm.actuator_trnid[a, 0]]: a for a in range(mjm.nu) if mjm.actuator_trntype[a] == TENDON}
actuators = [on_tendons[m + "_tendon"] for m in sat.motors]
realised = solver.mjw_data.actuator_force.numpy()[0][actuators]
out = sat.saturate(tau_cmd, qd)
print(
    "snippet result:",
    json.dumps(
        {
            "newton": newton.__version__,
            "tendon_actuators": len(on_tendons),
            "max_difference": float(np.max(np.abs(realised - sat.motor_torque(out)))),
            "clipped": bool(np.any(np.abs(out - tau_cmd) > 1e-6)),
            "finite": bool(np.all(np.isfinite(state.joint_q.numpy()))),
        }
    ),
)
