"""Run inside a Newton virtual environment (tests/export/test_trainers.py): build hound-id's Newton export as the
README snippet does (add_urdf, then the generated add_actuators and joint_dofs), drive SolverMuJoCo at random states
across the operating regions and then through a PD-controlled rollout with hound_id.runtime's voltages, and print
the realised motor torques' differences from the runtime (JSON on stdout). Arguments: the export folder, the largest
motor speed drawn [rad/s], MuJoCo-Warp (warp) or MuJoCo's CPU engine (cpu), and optionally the motor speed the rollout
starts from [rad/s] (alternating signs per motor; default 0, from rest), to make the rollout reach it."""

import json
import sys
from pathlib import Path

import mujoco
import newton
import numpy as np

import hound_id.runtime

folder, speed, engine = Path(sys.argv[1]), float(sys.argv[2]), sys.argv[3]
spin = float(sys.argv[4]) if len(sys.argv) > 4 else 0.0
sys.path.insert(0, str(folder))
import hound_like_newton as gen  # noqa: E402  (the generated module)

builder = newton.ModelBuilder()
newton.solvers.SolverMuJoCo.register_custom_attributes(builder)
builder.add_urdf(str(gen.URDF), floating=True)
rows = gen.add_actuators(builder)
dofs = gen.joint_dofs(builder)
model = builder.finalize(device="cpu")
solver = newton.solvers.SolverMuJoCo(model, use_mujoco_cpu=engine == "cpu")
mjm = solver.mj_model
tendons = [mujoco.mj_id2name(mjm, mujoco.mjtObj.mjOBJ_TENDON, i) for i in range(mjm.ntendon)]
on_tendons = [a for a in range(mjm.nu) if mjm.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_TENDON]
ours = {tendons[mjm.actuator_trnid[a, 0]]: a for a in on_tendons}
actuators = [ours[m + "_tendon"] for m in gen.MOTORS]
sat = hound_id.runtime.load(gen.BUNDLE)
state0, state1, control = model.state(), model.state(), model.control()
DT = 1e-4


def step(tau: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Send the runtime's voltages, step, and return (realised, runtime, dcmotor law) motor torques."""
    global state0, state1
    volts = sat.voltage(tau, qd)
    control.mujoco.ctrl.assign(volts.astype(np.float32))
    solver.step(state0, state1, control, None, DT)
    state0, state1 = state1, state0
    if engine == "cpu":
        force = np.array(solver.mj_data.actuator_force)[actuators]
    else:
        force = solver.mjw_data.actuator_force.numpy()[0][actuators]
    omega = sat.motor_velocity(qd)
    law = np.clip(sat.kt * (volts - omega / sat.kv) / sat.resistance, -sat.clip.torque_limit, sat.clip.torque_limit)
    return force, sat.motor_torque(sat.saturate(tau, qd)), law


rng = np.random.default_rng(7)
worst = worst_law = worst_roll = 0.0
clipped, n = 0, 100
for _ in range(n):
    qd = sat.clip.A @ (rng.uniform(-1, 1, len(gen.MOTORS)) * speed)
    tau = rng.uniform(-1, 1, len(gen.JOINTS)) * 150.0
    jqd = np.zeros(model.joint_dof_count, dtype=np.float32)
    jqd[dofs] = qd
    state0.joint_qd.assign(jqd)
    qd = state0.joint_qd.numpy()[dofs].astype(float)  # the float32 speeds the simulator holds
    force, want, law = step(tau, qd)
    clipped += bool(np.any(np.abs(sat.saturate(tau, qd) - tau) > 1e-9))
    worst = max(worst, float(np.max(np.abs(force - want))))
    worst_law = max(worst_law, float(np.max(np.abs(force - law))))
# a PD-controlled rollout from rest, or from the motors spinning at +-spin (falling freely), every step compared
signs = np.array([(-1.0) ** k for k in range(len(gen.MOTORS))])
jqd = np.zeros(model.joint_dof_count, dtype=np.float32)
jqd[dofs] = sat.clip.A @ (spin * signs)
state0.joint_qd.assign(jqd)
top_speed = worst_within = 0.0  # worst_within: over the steps whose motor speeds stay within the drawn speed
start_q = [int(builder.joint_q_start[gen._joint_index(builder, j)]) for j in gen.JOINTS]
q0 = state0.joint_q.numpy()[start_q].astype(float)
for k in range(500):
    q, qd = state0.joint_q.numpy()[start_q].astype(float), state0.joint_qd.numpy()[dofs].astype(float)
    fastest = float(np.max(np.abs(sat.motor_velocity(qd))))
    top_speed = max(top_speed, fastest)
    target = q0 + 0.6 * np.sin(2 * np.pi * 3 * k * DT)
    force, want, _ = step(400.0 * (target - q) - 8.0 * qd, qd)
    worst_roll = max(worst_roll, float(np.max(np.abs(force - want))))
    worst_within = max(worst_within, float(np.max(np.abs(force - want)))) if fastest <= speed else worst_within
print(
    json.dumps(
        {
            "newton": newton.__version__,
            "mujoco": mujoco.__version__,
            "actuators": len(rows),
            "max_difference": worst,
            "max_difference_law": worst_law,
            "max_difference_rollout": worst_roll,
            "rollout_top_motor_speed": top_speed,
            "max_difference_rollout_within_speed": worst_within,
            "clipped": clipped / n,
            "finite": bool(np.all(np.isfinite(state0.joint_q.numpy()))),
        }
    )
)
