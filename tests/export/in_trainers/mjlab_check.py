"""Run inside an mjlab virtual environment (tests/export/test_trainers.py): load hound-id's mjlab export as a task
would, drive it at random states across the operating regions, and print the realised torques next to
hound_id.runtime's (JSON on stdout). Arguments: the export folder, the uncoupled mode (dcmotor or voltage), the largest
motor speed drawn [rad/s]."""

import json
import sys
from pathlib import Path

import mujoco
import numpy as np
import torch
from mjlab.scene import Scene, SceneCfg
from mjlab.sim import Simulation, SimulationCfg

import hound_id.runtime

folder, uncoupled, speed = Path(sys.argv[1]), sys.argv[2], float(sys.argv[3])
sys.path.insert(0, str(folder))
import hound_like_mjlab as gen  # noqa: E402  (the generated module)

ENVS, STATES = 64, 8
scene = Scene(SceneCfg(num_envs=ENVS, entities={"robot": gen.entity_cfg(uncoupled=uncoupled)}), device="cpu")
sim = Simulation(num_envs=ENVS, cfg=SimulationCfg(), spec=scene.spec, device="cpu")
scene.initialize(mj_model=sim.mj_model, model=sim.model, data=sim.data)
robot = scene["robot"]
sat = hound_id.runtime.load(gen.BUNDLE, joint_names=gen.JOINTS)
joint_ids = torch.tensor(robot.find_joints(gen.JOINTS, preserve_order=True)[0])
tendons, motors = gen.voltage_motors(uncoupled)
tendon_ids = torch.tensor(robot.find_tendons(tendons, preserve_order=True)[0])
dc_joints = [j for j in gen.JOINTS if uncoupled == "dcmotor" and gen.MOTORS[gen.JOINTS.index(j)] not in gen.COUPLED]
dc_index = [gen.JOINTS.index(j) for j in dc_joints]
act = {n: mujoco.mj_name2id(sim.mj_model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"robot/{n}") for n in tendons + dc_joints}
assert min(act.values()) >= 0, act

gen_ = torch.Generator().manual_seed(5)
A = torch.tensor(sat.clip.A, dtype=torch.float32)
realised, expected, straight, clipped = [], [], [], []
limit = torch.tensor([sat.clip.torque_limit[k] for k in motors], dtype=torch.float64) if len(tendons) else None
for _ in range(STATES):
    omega = (torch.rand(ENVS, len(gen.MOTORS), generator=gen_) * 2 - 1) * speed  # motor speeds across the regions
    qd = omega @ A.T
    tau = (torch.rand(ENVS, len(gen.JOINTS), generator=gen_) * 2 - 1) * 150.0
    q = robot.data.joint_pos[:, joint_ids]
    robot.write_joint_state_to_sim(q, qd, joint_ids=joint_ids)
    volts = sat.voltage(tau.double(), qd.double())
    if len(tendons):
        robot.set_tendon_effort_target(volts[:, motors].float(), tendon_ids=tendon_ids)
    if dc_joints:
        robot.set_joint_effort_target(tau[:, dc_index], joint_ids=joint_ids[dc_index])
    scene.write_data_to_sim()
    sim.forward()
    force = sim.data.actuator_force
    out = sat.saturate(tau.double(), qd.double())
    clipped.append(torch.any(torch.abs(out - tau.double()) > 1e-9, dim=1))
    want = torch.cat([sat.motor_torque(out)[:, motors], out[:, dc_index]], dim=1)
    got = torch.stack([force[:, act[n]] for n in tendons + dc_joints], dim=1)
    realised.append(got.double())
    expected.append(want)
    # the dcmotor's own law at the runtime's voltage: Kt (v - omega/Kv) / R, clamped to the torque limit
    w = sat.motor_velocity(qd.double())[:, motors]
    k = [torch.tensor(np.array(a)[motors]) for a in (sat.kt, sat.kv, sat.resistance)]
    law = torch.clamp(k[0] * (volts[:, motors] - w / k[1]) / k[2], -limit, limit) if limit is not None else None
    straight.append(law)
# then a rollout: hold the last voltages and gains, step, and check the state stays finite
for _ in range(200):
    scene.write_data_to_sim()
    sim.step()
    scene.update(dt=sim.cfg.mujoco.timestep)
r, e = torch.cat(realised), torch.cat(expected)
print(
    json.dumps(
        {
            "mujoco": mujoco.__version__,
            "names": tendons + dc_joints,
            "voltage_columns": len(tendons),
            "max_difference_voltage": float(torch.max(torch.abs(r - e)[:, : len(tendons)])) if tendons else 0.0,
            "max_difference_law": float(torch.max(torch.abs(r[:, : len(tendons)] - torch.cat(straight))))
            if tendons
            else 0.0,
            "max_difference_dcmotor": float(torch.max(torch.abs(r - e)[:, len(tendons) :])) if dc_joints else 0.0,
            "scale": float(torch.max(torch.abs(e))),
            "clipped": float(torch.mean(torch.cat(clipped).double())),
            "finite": bool(torch.all(torch.isfinite(sim.data.qpos))),
        }
    )
)
