"""Run inside an Isaac Lab virtual environment (tests/export/test_trainers.py): Isaac Lab 2.3.2's own actuator classes
(DCMotor, IdealPDActuator) with hound-id's fields, and hound_id's HoundIdActuator, fed random commands at random
joint speeds; prints the applied torques' differences from hound_id.runtime (JSON on stdout). Arguments: the export
folder, the largest motor speed drawn [rad/s]. Isaac Lab's actuator modules are imported without Isaac Sim by
isaaclab_without_sim (nothing of Isaac Lab is replaced)."""

import json
import logging
import sys
import warnings
from pathlib import Path

import isaaclab
import torch
import yaml
from isaaclab.utils.types import ArticulationActions
from isaaclab_without_sim import actuator_pd, actuator_pd_cfg

import hound_id.runtime
from hound_id.export.isaaclab_actuator import HoundIdActuatorCfg

folder, speed = Path(sys.argv[1]), float(sys.argv[2])
# every warning Isaac Lab raises or logs while the configs and actuators are built (deprecations among them)
warnings.simplefilter("always")
caught: list[str] = []
warnings.showwarning = lambda message, category, *args, **kwargs: caught.append(f"{category.__name__}: {message}")


class _Collect(logging.Handler):
    def emit(self, record: logging.LogRecord) -> None:
        if record.levelno >= logging.WARNING:
            caught.append(f"log {record.levelname}: {record.getMessage()}")


logging.getLogger().addHandler(_Collect())
bundle = folder / "hound_like_bundle.json"
fields = yaml.safe_load((folder / "hound_like_isaaclab.yaml").read_text())["joints"]
sat = hound_id.runtime.load(bundle)
ENVS = 4096
gen = torch.Generator().manual_seed(11)
omega = (torch.rand(ENVS, len(sat.motors), generator=gen, dtype=torch.float64) * 2 - 1) * speed
qd = omega @ torch.tensor(sat.clip.A).T
tau = (torch.rand(ENVS, len(sat.joints), generator=gen, dtype=torch.float64) * 2 - 1) * 150.0
want = sat.saturate(tau, qd)
zeros = torch.zeros_like(tau)

# Isaac Lab's DCMotor on each uncoupled joint, with the exported 2.x fields
dc_worst, dc_gap, dc_joints = 0.0, 0.0, []
for j, name in enumerate(sat.joints):
    f = fields[name]
    if f["coupled"]:
        continue
    cfg = actuator_pd_cfg.DCMotorCfg(joint_names_expr=[name], stiffness=0.0, damping=0.0, **f["dcmotor_isaaclab2"])
    act = actuator_pd.DCMotor(cfg, joint_names=[name], joint_ids=[j], num_envs=ENVS, device="cpu")
    out = act.compute(
        ArticulationActions(joint_positions=zeros[:, [j]], joint_velocities=qd[:, [j]], joint_efforts=tau[:, [j]]),
        zeros[:, [j]],
        qd[:, [j]],
    )
    dc_worst = max(dc_worst, float(torch.max(torch.abs(out.joint_efforts[:, 0] - want[:, j]))))
    error = f.get("dcmotor_error", {})
    dc_gap = max(dc_gap, float(error.get("over", 0.0)))
    d = f["dcmotor_isaaclab2"]  # the straight line's overspeed, joint side, to motor side (motor j turns with joint j)
    overspeed = d["velocity_limit"] * (1.0 + d["effort_limit"] / d["saturation_effort"]) / abs(float(sat.clip.A[j][j]))
    if speed > overspeed:  # states past the overspeed are drawn
        dc_gap = max(dc_gap, float(error.get("past_overspeed", 0.0)))
    dc_joints.append(name)

# HoundIdActuator on every joint, in a breadth-first order (not the bundle's), with PD gains
order = sorted(sat.joints, key=lambda n: (n.split("_")[1], n))  # all HAA, then HFE, then KFE
idx = [sat.joints.index(n) for n in order]
cfg = HoundIdActuatorCfg(joint_names_expr=order, bundle=str(bundle), stiffness=40.0, damping=1.5)
act = cfg.class_type(cfg, joint_names=order, joint_ids=list(range(len(order))), num_envs=ENVS, device="cpu")
q = torch.rand(ENVS, len(order), generator=gen, dtype=torch.float64) * 2 - 1
q_star = torch.rand(ENVS, len(order), generator=gen, dtype=torch.float64) * 2 - 1
out = act.compute(
    ArticulationActions(joint_positions=q_star, joint_velocities=torch.zeros_like(q), joint_efforts=tau[:, idx]),
    q,
    qd[:, idx],
)
pd = 40.0 * (q_star - q) + 1.5 * (0.0 - qd[:, idx]) + tau[:, idx]
reference = hound_id.runtime.load(bundle, joint_names=order).saturate(pd, qd[:, idx])
# the same in float32, as Isaac Lab's buffers are, against the runtime in float64 on the same float32 inputs
act32 = cfg.class_type(cfg, joint_names=order, joint_ids=list(range(len(order))), num_envs=ENVS, device="cpu")
f32 = [x.float() for x in (q_star, q, tau[:, idx], qd[:, idx])]
out32 = act32.compute(
    ArticulationActions(joint_positions=f32[0], joint_velocities=torch.zeros_like(f32[1]), joint_efforts=f32[2]),
    f32[1],
    f32[3],
)
pd32 = 40.0 * (f32[0].double() - f32[1].double()) - 1.5 * f32[3].double() + f32[2].double()
ref32 = hound_id.runtime.load(bundle, joint_names=order).saturate(pd32, f32[3].double())
print(
    json.dumps(
        {
            "isaaclab": isaaclab.__version__,
            "dcmotor_joints": dc_joints,
            "dcmotor_max_difference": dc_worst,
            "dcmotor_stated_gap": dc_gap,
            "hound_max_difference": float(torch.max(torch.abs(out.joint_efforts - reference))),
            "hound_clipped": float(torch.mean((torch.abs(reference - pd) > 1e-9).any(dim=1).double())),
            "hound_dtype": str(out.joint_efforts.dtype),
            "hound_float32_dtype": str(out32.joint_efforts.dtype),
            "hound_max_difference_float32": float(torch.max(torch.abs(out32.joint_efforts.double() - ref32))),
            "warnings": caught,
        }
    )
)
