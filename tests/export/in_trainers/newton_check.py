"""Run inside a Newton virtual environment (tests/export/test_trainers.py): build hound-id's Newton export as a user
would (add_urdf, then the generated add_actuators), drive SolverMuJoCo at random states across the operating regions
with hound_id.runtime's voltages, and print the realised motor torques' differences from the runtime (JSON on
stdout). Arguments: the export folder, the largest motor speed drawn [rad/s], whether to use MuJoCo-Warp (warp) or
MuJoCo's CPU engine (cpu)."""

import json
import sys
from pathlib import Path

import mujoco
import newton
import numpy as np

import hound_id.runtime

folder, speed, engine = Path(sys.argv[1]), float(sys.argv[2]), sys.argv[3]
sys.path.insert(0, str(folder))
import hound_like_newton as gen  # noqa: E402  (the generated module)

builder = newton.ModelBuilder()
newton.solvers.SolverMuJoCo.register_custom_attributes(builder)
builder.add_urdf(str(gen.URDF), floating=True)
rows = gen.add_actuators(builder)
model = builder.finalize(device="cpu")
solver = newton.solvers.SolverMuJoCo(model, use_mujoco_cpu=engine == "cpu")
mjm = solver.mj_model
tendons = [mujoco.mj_id2name(mjm, mujoco.mjtObj.mjOBJ_TENDON, i) for i in range(mjm.ntendon)]
on_tendons = [a for a in range(mjm.nu) if mjm.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_TENDON]
ours = {tendons[mjm.actuator_trnid[a, 0]]: a for a in on_tendons}
actuators = [ours[m + "_tendon"] for m in gen.MOTORS]
sat = hound_id.runtime.load(gen.BUNDLE, joint_names=gen.JOINTS)
labels = {label.rsplit("/", 1)[-1]: i for i, label in enumerate(builder.joint_label)}
dofs = [int(model.joint_qd_start.numpy()[labels[j]]) for j in gen.JOINTS]
state0, state1, control = model.state(), model.state(), model.control()
rng = np.random.default_rng(7)
worst = worst_law = 0.0
clipped = 0
n = 100
for _ in range(n):
    omega = rng.uniform(-1, 1, len(gen.MOTORS)) * speed
    qd = sat.clip.A @ omega
    tau = rng.uniform(-1, 1, len(gen.JOINTS)) * 150.0
    volts = sat.voltage(tau, qd)
    jqd = np.zeros(model.joint_dof_count, dtype=np.float32)
    jqd[dofs] = qd
    state0.joint_qd.assign(jqd)
    control.mujoco.ctrl.assign(volts.astype(np.float32))
    solver.step(state0, state1, control, None, 1e-4)
    if engine == "cpu":
        force = np.array(solver.mj_data.actuator_force)[actuators]
    else:
        force = solver.mjw_data.actuator_force.numpy()[0][actuators]
    out = sat.saturate(tau, qd)
    clipped += bool(np.any(np.abs(out - tau) > 1e-9))
    worst = max(worst, float(np.max(np.abs(force - sat.motor_torque(out)))))
    law = np.clip(sat.kt * (volts - omega / sat.kv) / sat.resistance, -sat.clip.torque_limit, sat.clip.torque_limit)
    worst_law = max(worst_law, float(np.max(np.abs(force - law))))
for _ in range(200):  # a short rollout from rest with the last voltages: the state stays finite
    solver.step(state0, state1, control, None, 1e-4)
    state0, state1 = state1, state0
print(
    json.dumps(
        {
            "newton": newton.__version__,
            "mujoco": mujoco.__version__,
            "actuators": len(rows),
            "max_difference": worst,
            "max_difference_law": worst_law,
            "clipped": clipped / n,
            "finite": bool(np.all(np.isfinite(state0.joint_q.numpy()))),
        }
    )
)
