"""Run inside an mjlab virtual environment (tests/export/test_doc_snippets.py), in the folder holding the export
``out/``: the manual's mjlab snippet (the file given as the argument, docs/export.md's block as printed), executed
after a prelude that gives it what it leaves to the user's task: ``env_cfg``, a minimal real task (mjlab's
ManagerBasedRlEnvCfg: 64 environments on a plane, no observations, actions or rewards), ``tau_cmd``, a controller's
joint torques far past the operating regions (+-150 N m), and the generated module on the import path. Then it writes
the snippet's tendon targets to the simulation, computes the actuator forces (as a physics step does first), steps,
and reports on one line of stdout, after ``snippet result:``, the voltage-input dcmotors' realised motor torques against
hound_id.runtime's clip of ``tau_cmd`` at the speeds the snippet read."""

import json
import sys
from pathlib import Path

import mujoco
import torch
from mjlab.envs import ManagerBasedRlEnvCfg
from mjlab.scene import SceneCfg
from mjlab.terrains import TerrainEntityCfg

ENVS = 64
text = Path(sys.argv[1]).read_text()
sys.path.insert(0, "out")  # where the generated hound_like_mjlab.py is
joints = json.loads(Path("out/hound_like_bundle.json").read_text())["joints"]
env_cfg = ManagerBasedRlEnvCfg(
    decimation=4, scene=SceneCfg(num_envs=ENVS, terrain=TerrainEntityCfg(terrain_type="plane")), episode_length_s=20.0
)
gen = torch.Generator().manual_seed(5)
tau_cmd = (torch.rand(ENVS, len(joints), generator=gen) * 2 - 1) * 150.0
namespace = {"__name__": "__main__", "env_cfg": env_cfg, "tau_cmd": tau_cmd}
exec(compile(text, "docs/export.md (the mjlab snippet)", "exec"), namespace)

env, robot, sat, tendons, motors = (namespace[k] for k in ("env", "robot", "sat", "tendons", "motors"))
qd = namespace["qd"]
env.scene.write_data_to_sim()
env.sim.forward()  # the actuator forces of the next step, from ctrl and the speeds the snippet read
act = [mujoco.mj_name2id(env.sim.mj_model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"robot/{t}") for t in tendons]
assert min(act) >= 0, dict(zip(tendons, act, strict=True))
realised = env.sim.data.actuator_force[:, act].double()
out = sat.saturate(tau_cmd.double(), qd.double())
want = sat.motor_torque(out)[:, motors]
volts = env.sim.data.ctrl[:, act].double()
env.sim.step()
print(
    "snippet result:",
    json.dumps(
        {
            "mujoco": mujoco.__version__,
            "robot_joints": list(robot.joint_names),
            "tendons": tendons,
            "actuators": int(env.sim.mj_model.nu),
            "max_difference": float(torch.max(torch.abs(realised - want))),
            "max_volts": float(torch.max(torch.abs(volts))),
            "clipped": float(torch.mean((torch.abs(out - tau_cmd.double()) > 1e-6).any(dim=1).double())),
            "finite": bool(torch.all(torch.isfinite(env.sim.data.qpos))),
        }
    ),
)
