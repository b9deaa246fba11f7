"""Run inside an Isaac Lab virtual environment (tests/export/test_doc_snippets.py), in the folder holding the export
``out/``: the manual's Isaac Lab snippet (the file given as the first argument, docs/export.md's block as printed),
executed after a prelude that gives it ``robot_cfg``; then the actuator group it configures is built and driven as
Isaac Lab's ``Articulation`` builds and drives it, and one line of stdout, after ``snippet result:``, reports the
actuator's joints, gains, armature and friction and its applied torques against hound_id.runtime's clip of its PD
torque. The second argument is the largest motor speed drawn [rad/s].

Isaac Sim is not on this machine's package index, and Isaac Lab 2.3.2's assets, scene and simulation import it
(``omni.*``), so three things a full install does are not run here:

* ``robot_cfg`` is not an ``isaaclab.assets.ArticulationCfg``: that module imports ``Articulation``, which imports
  ``omni.physics``. It is an Isaac Lab ``configclass`` holding ArticulationCfg's ``actuators`` field, declared as
  ArticulationCfg declares it (its declaration is read from Isaac Lab's source and reported, for the test to compare);
* ``Articulation._process_actuators_cfg`` is not called (it needs the PhysX view). Its calls are made here: the joints
  found by ``resolve_matching_names`` (``Articulation.find_joints``) among the joints in PhysX's breadth-first order,
  and ``cfg.class_type(cfg=..., joint_names=..., joint_ids=..., num_envs=..., device=..., stiffness=..., ...)`` with
  the values a USD without drives, armature or friction gives; the armature and friction the actuator resolves are
  reported, not written into PhysX;
* no PhysX step: ``actuator.compute`` gets the joint targets and state as ``Articulation._apply_actuator_model`` passes
  them (float32 buffers), drawn at random instead of read from a simulation.
"""

import ast
import json
import sys
from dataclasses import MISSING
from pathlib import Path

import isaaclab
import torch
from isaaclab.utils import configclass
from isaaclab.utils.string import resolve_matching_names
from isaaclab.utils.types import ArticulationActions
from isaaclab_without_sim import actuator_base_cfg

import hound_id.runtime

ENVS = 4096
#: The hound_like joints in the order PhysX lists an articulation's joints (breadth-first), as Isaac Lab names them.
PHYSX_JOINTS = [f"{leg}_{joint}" for joint in ("HAA", "HFE", "KFE") for leg in ("FL", "FR", "RL", "RR")]
text, speed = Path(sys.argv[1]).read_text(), float(sys.argv[2])


@configclass
class ArticulationActuatorsCfg:
    """ArticulationCfg's ``actuators`` field (the class itself imports Isaac Sim)."""

    actuators: dict[str, actuator_base_cfg.ActuatorBaseCfg] = MISSING


source = Path(isaaclab.__path__[0]) / "assets" / "articulation" / "articulation_cfg.py"
declared = next(
    ast.unparse(node)
    for cls in ast.parse(source.read_text()).body
    if isinstance(cls, ast.ClassDef) and cls.name == "ArticulationCfg"
    for node in cls.body
    if isinstance(node, ast.AnnAssign) and ast.unparse(node.target) == "actuators"
)
namespace = {"__name__": "__main__", "robot_cfg": ArticulationActuatorsCfg()}
exec(compile(text, "docs/export.md (the isaaclab snippet)", "exec"), namespace)
robot_cfg, fields = namespace["robot_cfg"], namespace["joints"]
missing = robot_cfg.validate() or []

# Articulation._process_actuators_cfg, for each group (a USD without drives, armature or friction; open limits)
zeros = torch.zeros(ENVS, len(PHYSX_JOINTS))
actuators = {}
for name, cfg in robot_cfg.actuators.items():
    joint_ids, joint_names = resolve_matching_names(cfg.joint_names_expr, PHYSX_JOINTS)
    ids = slice(None) if len(joint_names) == len(PHYSX_JOINTS) else torch.tensor(joint_ids)
    actuators[name] = cfg.class_type(
        cfg=cfg,
        joint_names=joint_names,
        joint_ids=ids,
        num_envs=ENVS,
        device="cpu",
        stiffness=zeros[:, ids],
        damping=zeros[:, ids],
        armature=zeros[:, ids],
        friction=zeros[:, ids],
        dynamic_friction=zeros[:, ids],
        viscous_friction=zeros[:, ids],
        effort_limit=torch.full_like(zeros[:, ids], 1e9),
        velocity_limit=torch.full_like(zeros[:, ids], 1e9),
    )
(act,) = actuators.values()
names = list(act.joint_names)

# Articulation._apply_actuator_model: targets and state in Isaac Lab's float32 buffers, motor speeds up to ``speed``
sat = hound_id.runtime.load("out/hound_like_bundle.json", joint_names=names)
gen = torch.Generator().manual_seed(13)
omega = (torch.rand(ENVS, len(names), generator=gen, dtype=torch.float64) * 2 - 1) * speed
qd = (omega @ torch.tensor(sat.clip.A).T).float()
q, q_star = ((torch.rand(ENVS, len(names), generator=gen) * 2 - 1) for _ in range(2))
tau_ff = (torch.rand(ENVS, len(names), generator=gen) * 2 - 1) * 150.0
out = act.compute(
    ArticulationActions(joint_positions=q_star, joint_velocities=torch.zeros_like(q), joint_efforts=tau_ff), q, qd
)
kp, kd = act.stiffness.double(), act.damping.double()
pd = kp * (q_star.double() - q.double()) - kd * qd.double() + tau_ff.double()  # the PD law, in float64
want = sat.saturate(act.computed_effort, qd)  # the runtime's clip of the actuator's own PD torque


def per_joint(values: torch.Tensor) -> dict[str, float]:
    return {n: float(v) for n, v in zip(names, values[0], strict=True)}


print(
    "snippet result:",
    json.dumps(
        {
            "isaaclab": isaaclab.__version__,
            "declared": declared,
            "missing": missing,
            "groups": list(actuators),
            "class": type(act).__name__,
            "joint_names": names,
            "stiffness": per_joint(act.stiffness),
            "damping": per_joint(act.damping),
            "armature": per_joint(act.armature),
            "friction": per_joint(act.friction),
            "viscous_friction": per_joint(act.viscous_friction),
            "exported": {k: {n: fields[n][k] for n in names} for k in ("armature", "friction", "viscous_friction")},
            "dtype": str(out.joint_efforts.dtype),
            "pd_difference": float(torch.max(torch.abs(act.computed_effort.double() - pd))),
            "max_difference": float(torch.max(torch.abs(out.joint_efforts - want))),
            "clipped": float(torch.mean((torch.abs(want.double() - pd) > 1e-3).any(dim=1).double())),
            "finite": bool(torch.all(torch.isfinite(out.joint_efforts))),
        }
    ),
)
