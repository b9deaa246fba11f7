"""Run inside an mjlab virtual environment (tests/export/test_trainers.py): load hound-id's mjlab export as the README
snippet does, drive it at random states across the operating regions and then through a PD-controlled rollout, and
print the realised torques' differences from hound_id.runtime (JSON on stdout). Arguments: the export folder, the
uncoupled mode (dcmotor or voltage), the largest motor speed drawn [rad/s], and optionally the motor speed the
rollout starts from [rad/s] (alternating signs per motor; default 0, from rest), to make the rollout reach it."""

import json
import sys
from pathlib import Path

import mujoco
import torch
from mjlab.scene import Scene, SceneCfg
from mjlab.sim import Simulation, SimulationCfg

import hound_id.runtime

folder, uncoupled, speed = Path(sys.argv[1]), sys.argv[2], float(sys.argv[3])
spin = float(sys.argv[4]) if len(sys.argv) > 4 else 0.0
sys.path.insert(0, str(folder))
import hound_like_mjlab as gen  # noqa: E402  (the generated module)

ENVS, STATES, STEPS = 64, 8, 300
scene_cfg = SceneCfg(num_envs=ENVS, entities={"robot": gen.entity_cfg(uncoupled=uncoupled)})
scene = Scene(scene_cfg, device="cpu")
sim = Simulation(num_envs=ENVS, cfg=SimulationCfg(), spec=scene.spec, device="cpu")
scene.initialize(mj_model=sim.mj_model, model=sim.model, data=sim.data)
robot = scene["robot"]
# the README snippet: the runtime in the entity's joint order, the voltage-input tendons of the same mode
sat = hound_id.runtime.load(gen.BUNDLE, joint_names=robot.joint_names)
tendons, motors = gen.voltage_motors(uncoupled=uncoupled)
tendon_ids = robot.find_tendons(tendons, preserve_order=True)[0]
names = list(robot.joint_names)
dc_joints = [j for j in names if uncoupled == "dcmotor" and gen.MOTORS[gen.JOINTS.index(j)] not in gen.COUPLED]
dc_index = [names.index(j) for j in dc_joints]
act = {n: mujoco.mj_name2id(sim.mj_model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"robot/{n}") for n in tendons + dc_joints}
assert min(act.values()) >= 0, act
kt, kv, res = (torch.tensor(a, dtype=torch.float64)[motors] for a in (sat.kt, sat.kv, sat.resistance))
limit = torch.tensor(sat.clip.torque_limit, dtype=torch.float64)[motors]


def command(tau: torch.Tensor, qd: torch.Tensor) -> torch.Tensor:
    """Send the command as the README does; the runtime's torques on the same columns as the realised ones."""
    volts = sat.voltage(tau, qd)
    if tendons:
        robot.set_tendon_effort_target(volts[:, motors].float(), tendon_ids=tendon_ids)
    if dc_joints:
        robot.set_joint_effort_target(tau[:, dc_index].float(), joint_ids=dc_index)
    out = sat.saturate(tau, qd)
    law = torch.clamp(kt * (volts[:, motors] - sat.motor_velocity(qd)[:, motors] / kv) / res, -limit, limit)
    return torch.cat([sat.motor_torque(out)[:, motors], out[:, dc_index]], dim=1), law


def realised() -> torch.Tensor:
    force = sim.data.actuator_force
    return torch.stack([force[:, act[n]] for n in tendons + dc_joints], dim=1).double()


gen_ = torch.Generator().manual_seed(5)
A = torch.tensor(sat.clip.A)
worst_v = worst_law = worst_dc = worst_roll = 0.0
clipped = []
nv = len(tendons)
for _ in range(STATES):
    omega = (torch.rand(ENVS, len(sat.motors), generator=gen_, dtype=torch.float64) * 2 - 1) * speed
    qd = omega @ A.T
    tau = (torch.rand(ENVS, len(names), generator=gen_, dtype=torch.float64) * 2 - 1) * 150.0
    robot.write_joint_state_to_sim(robot.data.joint_pos, qd.float())
    qd = robot.data.joint_vel.double()  # the float32 speeds the simulator holds
    want, law = command(tau, qd)
    scene.write_data_to_sim()
    sim.forward()
    got = realised()
    clipped.append(torch.any(torch.abs(sat.saturate(tau, qd) - tau) > 1e-9, dim=1))
    worst_v = max(worst_v, float(torch.max(torch.abs(got - want)[:, :nv]))) if nv else 0.0
    worst_law = max(worst_law, float(torch.max(torch.abs(got[:, :nv] - law)))) if nv else 0.0
    worst_dc = max(worst_dc, float(torch.max(torch.abs(got - want)[:, nv:]))) if dc_joints else 0.0
# a PD-controlled rollout from rest, or from the motors spinning at +-spin (falling freely: no terrain), every step
# compared
signs = torch.tensor([(-1.0) ** k for k in range(len(sat.motors))], dtype=torch.float64)
start = ((spin * signs) @ A.T).repeat(ENVS, 1).float()
robot.write_joint_state_to_sim(robot.data.default_joint_pos, start)
top_speed = worst_within = 0.0  # worst_within: over the steps whose motor speeds stay within the drawn speed
stand = torch.tensor([gen.STAND_JOINTS[j] for j in names], dtype=torch.float64)
assert torch.allclose(robot.data.default_joint_pos[0].double(), stand)  # entity_cfg starts from the stand pose
q0 = robot.data.joint_pos.double().clone()
for step in range(STEPS):
    q, qd = robot.data.joint_pos.double(), robot.data.joint_vel.double()
    fastest = float(torch.max(torch.abs(sat.motor_velocity(qd))))
    top_speed = max(top_speed, fastest)
    target = q0 + 0.6 * torch.sin(torch.tensor(2 * torch.pi * 3 * step * sim.cfg.mujoco.timestep))
    want, _ = command(400.0 * (target - q) - 8.0 * qd, qd)
    scene.write_data_to_sim()
    sim.step()
    difference = float(torch.max(torch.abs(realised() - want)))
    worst_roll = max(worst_roll, difference)
    worst_within = max(worst_within, difference) if fastest <= speed else worst_within
    scene.update(dt=sim.cfg.mujoco.timestep)
print(
    json.dumps(
        {
            "mujoco": mujoco.__version__,
            "names": tendons + dc_joints,
            "voltage_columns": nv,
            "max_difference_voltage": worst_v,
            "max_difference_law": worst_law,
            "max_difference_dcmotor": worst_dc,
            "max_difference_rollout": worst_roll,
            "rollout_top_motor_speed": top_speed,
            "max_difference_rollout_within_speed": worst_within,
            "clipped": float(torch.mean(torch.cat(clipped).double())),
            "finite": bool(torch.all(torch.isfinite(sim.data.qpos))),
        }
    )
)
