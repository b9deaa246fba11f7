"""Export formats: the bundle, Isaac Lab actuator fields, a URDF with limits, a MuJoCo model.

Every writer takes an :class:`~hound_id.export.target.Export` (the robot with its fits, its bundle
and its URDF) and a folder, writes its files atomically and returns what it wrote with a short
report (:class:`~hound_id.export.target.Written`). They are registered in :data:`FORMATS` (sorted by
name); ``hound-id export --format NAME`` runs one. A new format is one module importing
:mod:`hound_id.export.target` (as :mod:`hound_id.export.mujoco` does) plus one line in :data:`FORMATS`.

Joint-side numbers of an uncoupled joint with gear ratio G (motor turns per joint turn):
torque G tau_m, speed omega_m / G, rotor inertia J G^2, Coulomb friction G f_c, viscous G^2 b.
For coupled joints the URDF gets the diagonal of A^-T diag(b) A^-1 for damping and the
worst case sum_m |(A^-T)_jm| f_c,m for friction; the exact coupled model is in the bundle, the
runtime and the MuJoCo tendons.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from hound_id import io
from hound_id.errors import SpecError
from hound_id.export.bundle import BundleMotor
from hound_id.export.mjlab import write_mjlab
from hound_id.export.mujoco import write_mujoco
from hound_id.export.newton import write_newton
from hound_id.export.target import Export, Written, put_feet

ISAACLAB_SCHEMA = "hound-id/isaaclab/2"
ARMATURE_SCHEMA = "hound-id/armature/1"


def _stem(ex: Export) -> str:
    return io.file_stem(ex.robot.name, "robot field 'name'")  # a Robot built in code is checked here too


def write_bundle(ex: Export, out: Path) -> Written:
    """``<robot>_bundle.yaml`` and the same content as ``<robot>_bundle.json``."""
    import yaml

    y, j = out / f"{_stem(ex)}_bundle.yaml", out / f"{_stem(ex)}_bundle.json"
    content = ex.bundle.to_dict()
    io.write_text(y, yaml.safe_dump(content, sort_keys=False))
    io.write_json(j, content)
    return Written((str(y), str(j)), ("load it in a trainer with hound_id.runtime.load",))


def isaaclab_fields(ex: Export) -> dict[str, Any]:
    """Isaac Lab ``DCMotorCfg`` fields per uncoupled joint; coupled joints point to the runtime.

    Each joint has ``armature`` and ``friction`` (joint side); an uncoupled joint also has
    ``dcmotor``: the keyword arguments of ``DCMotorCfg`` that hold its region.
    """
    b = ex.bundle
    coulomb, viscous = ex.joint_friction()
    reflected = np.asarray(b.reflected_inertia) if b.reflected_inertia is not None else None
    joints: dict[str, Any] = {}
    index = {j: i for i, j in enumerate(b.joints)}
    for tx in b.transmissions:
        A = np.asarray(tx["A"], dtype=float)
        coupled = bool(np.any(A[~np.eye(len(A), dtype=bool)] != 0))
        for k, joint in enumerate(tx["joints"]):
            i = index[joint]
            m = b.motors[i]
            entry: dict[str, Any] = {
                "coupled": coupled,
                "armature": float(reflected[i, i]) if reflected is not None else 0.0,
                "friction": float(coulomb[i]),
                "viscous_friction": float(viscous[i]),
                "inner_box": dict(b.joint_boxes[joint]["inner"]),
            }
            if coupled:
                entry["use"] = "hound_id.runtime"
                entry["reason"] = (
                    f"{joint} shares motors {', '.join(tx['motors'])} with {', '.join(tx['joints'])} through "
                    "A = " + str(A.tolist()) + "; Isaac Lab's per-joint DCMotor clips each joint alone and cannot "
                    "express the coupled motor-space limits. Apply hound_id.runtime.load(bundle, joint_names)"
                    ".saturate(tau, qd) to the group (see the README); armature is the diagonal of the reflected "
                    "inertia (the off-diagonal terms are in reflected_inertia_group), friction the worst case "
                    "sum |A^-T| f_c"
                )
                if reflected is not None:
                    idx = [index[j] for j in tx["joints"]]
                    entry["reflected_inertia_group"] = _group_inertia(reflected[np.ix_(idx, idx)], list(tx["joints"]))
            else:
                gear = float(1.0 / abs(A[k, k]))  # motor turns per joint turn
                entry["gear_ratio"] = gear
                entry["dcmotor"] = {  # Isaac Lab 3.0's names (ActuatorBaseCfg)
                    "saturation_effort": m.stall_torque * gear,
                    "actuator_effort_limit": m.torque_limit * gear,
                    "actuator_velocity_limit": m.no_load_speed / gear,
                    "armature": (m.rotor_inertia or 0.0) * gear**2,
                    # static friction: Coulomb + the Stribeck excess at rest; kinetic: Coulomb; viscous: G^2 b
                    "friction": float(coulomb[i]) + float(m.friction.get("stribeck", 0.0)) * gear,
                    "dynamic_friction": float(coulomb[i]),
                    "viscous_friction": float(viscous[i]),
                }
                entry["dcmotor_isaaclab2"] = {  # Isaac Lab 2.x's names (deprecated in 3.0)
                    **{k: v for k, v in entry["dcmotor"].items() if not k.startswith("actuator_")},
                    "effort_limit": m.torque_limit * gear,
                    "velocity_limit": m.no_load_speed / gear,
                }
                if m.envelope:  # DCMotor holds straight lines; the measured edge is a polyline
                    entry["use"] = "hound_id.runtime"
                    entry["reason"] = (
                        f"motor {m.name} has a measured envelope (mor --compare --out); DCMotor's straight lines "
                        f"allow up to {_over_promise(m) * gear:.4g} N m more than it at the joint. The dcmotor "
                        "fields hold the spec sheet; apply hound_id.runtime.load(bundle, joint_names).saturate(tau, "
                        "qd) for the measured edge"
                    )
                else:
                    gap = ex.straight_gap(m.name)
                    entry["dcmotor_error"] = {
                        "over": gap[0] * gear,
                        "under": gap[1] * gear,
                        "units": "N m, joint side: the most DCMotor's clip passes (over) or falls short of (under) "
                        "hound-id's within +-overspeed",
                    }
                    if gap[0] > DCMOTOR_EXACT * m.torque_limit:
                        entry["use"] = "hound_id.runtime"
                        entry["reason"] = (
                            f"motor {m.name}'s current-torque curve bends its voltage edges (and its torque limit "
                            f"is the curve's, {m.torque_limit * gear:.4g} N m at the joint): DCMotor's straight "
                            f"line passes them by up to {gap[0] * gear:.4g} N m at the joint between the corner "
                            "and the overspeed, and past overspeed DCMotor returns the torque limit where the "
                            "back-EMF forces more braking. The dcmotor fields are the closest straight model; apply "
                            "hound_id.runtime.load(bundle, joint_names).saturate(tau, qd) for the exact clip"
                        )
            joints[joint] = entry
    return {
        "schema": ISAACLAB_SCHEMA,
        "robot": b.robot,
        "units": "SI, joint side: N m, rad/s, kg m^2, N m s/rad",
        "actuator": "isaaclab.actuators.DCMotorCfg (per uncoupled joint: DCMotorCfg(..., **joints[name]['dcmotor']) in "
        "Isaac Lab 3.0, **joints[name]['dcmotor_isaaclab2'] in 2.x)",
        "joints": joints,
        "notes": [
            "dcmotor holds Isaac Lab 3.0's field names (actuator_effort_limit, actuator_velocity_limit, friction = "
            "static, dynamic_friction = kinetic, viscous_friction), as its ActuatorBaseCfg defines them; "
            "dcmotor_isaaclab2 the names of 2.x (effort_limit, velocity_limit; deprecated in 3.0). "
            "saturation_effort = stall torque Kt V/R x G, (actuator_)velocity_limit "
            "= no-load speed / G, (actuator_)effort_limit = the torque limit x G (the current-torque curve's torque at "
            "the driver's limit, or the peak torque). "
            "DCMotor's torque-speed line is straight: for a motor whose curve saturates, hound-id's voltage edges "
            "bend inwards and dcmotor_error says by how much DCMotor passes them; for a linear curve (kt_curve: "
            "linear, or a fit without saturation) DCMotor's clip equals hound-id's within +-overspeed in releases "
            "that first clamp the joint speed to the speed at the effort limit (vel_at_effort_lim, as mjlab's "
            "DcMotorActuator does). Past overspeed DCMotor returns the torque limit; hound-id the braking torque the "
            "back-EMF forces (larger)",
            "friction (static: Coulomb plus the fitted Stribeck excess at rest) and dynamic_friction (kinetic: "
            "Coulomb) are in N m, joint side, as Isaac Sim >= 5.0 takes them (Isaac Sim 4.5 took unitless "
            "coefficients); viscous_friction is the fitted viscous term in N m s/rad. Isaac Lab's actuator 'damping' "
            "is a PD gain: do not put viscous friction there",
        ],
    }


#: A DCMotor whose clip passes hound-id's by less than this share of the torque limit reproduces it (rounding).
DCMOTOR_EXACT = 1e-9


def _group_inertia(M: np.ndarray, joints: list[str]) -> dict[str, Any]:
    """A coupled group's reflected rotor inertia, what Isaac Lab's per-joint armature keeps (the diagonal) and what
    it drops: the off-diagonal terms, and the most the rotors' kinetic energy then errs, max |q'(D - M)q| / q'Mq
    (the extreme generalised eigenvalues of D - M against M)."""
    from scipy.linalg import eigh

    D = np.diag(np.diag(M))
    lam = eigh(D - M, M, eigvals_only=True)
    off = M[~np.eye(len(M), dtype=bool)]
    scale = np.sqrt(np.outer(np.diag(M), np.diag(M)))[~np.eye(len(M), dtype=bool)]
    return {
        "joints": joints,
        "matrix": M.tolist(),
        "dropped_off_diagonal": float(np.max(np.abs(off))) if off.size else 0.0,
        "dropped_relative": float(np.max(np.abs(off) / scale)) if off.size else 0.0,
        "kinetic_energy_error": float(np.max(np.abs(lam))),
        "units": "kg m^2, joint side; dropped_relative = |M_ij| / sqrt(M_ii M_jj); kinetic_energy_error: the largest "
        "relative error of the rotors' kinetic energy with the diagonal armature only (any joint velocities)",
        "note": "Isaac Lab's armature is per joint: the off-diagonal terms cannot be set there; the MuJoCo export "
        "(tendon armature) and hound_id.runtime keep them",
    }


def _over_promise(motor: BundleMotor) -> float:
    """The most the spec sheet's straight edges pass a motor's measured polyline edges [N m, motor side]."""
    env: Mapping[str, Any] = motor.envelope or {}
    points = np.asarray(env["speeds"], dtype=float)
    stall, tl = motor.stall_torque, motor.torque_limit
    damping = stall / motor.no_load_speed
    corner = (stall - tl) / damping  # where the straight motoring line leaves the torque limit: the largest gap
    w = np.unique(np.concatenate([points, np.linspace(points[0], points[-1], 4001), [corner, -corner]]))
    w = w[(w >= points[0]) & (w <= points[-1])]
    worst = 0.0
    for key, sign in (("upper", 1.0), ("lower", -1.0)):
        edge = np.interp(w, points, np.array([np.nan if v is None else v for v in env[key]], dtype=float))
        straight = np.clip(sign * stall - damping * w, -tl, tl)
        worst = max(worst, float(np.nanmax(sign * (straight - edge))))
    return worst


def write_isaaclab(ex: Export, out: Path) -> Written:
    """``<robot>_isaaclab.yaml``: :func:`isaaclab_fields`."""
    import yaml

    data = isaaclab_fields(ex)
    path = out / f"{_stem(ex)}_isaaclab.yaml"
    io.write_text(path, yaml.safe_dump(data, sort_keys=False))
    coupled = [j for j, v in data["joints"].items() if v["coupled"]]
    straight = [j for j, v in data["joints"].items() if not v["coupled"] and v.get("use")]
    notes: tuple[str, ...] = (f"{len(coupled)} coupled joints point to hound_id.runtime",) if coupled else ()
    if straight:
        worst = max(data["joints"][j].get("dcmotor_error", {}).get("over", 0.0) for j in straight)
        notes += (
            f"{len(straight)} uncoupled joints ({', '.join(straight)}) have motors whose edges are not straight "
            "(a saturating current-torque curve or a measured envelope): their dcmotor fields are the closest "
            "straight model"
            + (f" (passing hound-id's clip by up to {worst:.3g} N m)" if worst > 0 else "")
            + "; they point to hound_id.runtime",
        )
    groups = [v["reflected_inertia_group"] for v in data["joints"].values() if "reflected_inertia_group" in v]
    if groups:
        g = max(groups, key=lambda x: x["kinetic_energy_error"])
        notes += (
            f"coupled armature: Isaac Lab takes the diagonal only; the dropped off-diagonal reflected inertia is up "
            f"to {g['dropped_off_diagonal']:.4g} kg m^2 ({g['dropped_relative']:.1%} of sqrt(M_ii M_jj)), the rotors' "
            f"kinetic energy then errs by up to {g['kinetic_energy_error']:.1%} (reflected_inertia_group)",
        )
    return Written((str(path),), notes)


def _fmt(v: float) -> str:
    return f"{v:.9g}"


#: The open URDF's limits hold every state whose motor speeds are within this multiple of each motor's overspeed.
OPEN_REACH = 2.0
#: Motor speeds at which a motor's largest torque is searched (across +-OPEN_REACH x overspeed).
OPEN_POINTS = 4001


def open_limits(ex: Export) -> tuple[np.ndarray, np.ndarray]:
    """(effort [N m], velocity [rad/s]) per joint that never bind on what the runtime returns for motor speeds up to
    :data:`OPEN_REACH` x overspeed: effort_j = sum_m |(A^-T)_jm| T_m with T_m the largest |torque| of motor m's
    interval there (the curve's top, or the back-EMF braking of a linear motor at that speed), velocity_j =
    sum_m |A_jm| OPEN_REACH overspeed_m."""
    from hound_id.mor.region import operating_region, torque_interval

    tops, speeds = [], []
    for m in ex.bundle.motors:
        region = operating_region(ex.robot.motor_specs[m.name])
        w = np.linspace(-OPEN_REACH, OPEN_REACH, OPEN_POINTS) * region.overspeed
        lo, hi = torque_interval(w, region)
        tops.append(float(max(np.max(np.abs(lo)), np.max(np.abs(hi)))))
        speeds.append(OPEN_REACH * region.overspeed)
    A_inv = np.linalg.inv(ex.A)
    return np.abs(A_inv.T) @ np.array(tops), np.abs(ex.A) @ np.array(speeds)


def limited_urdf(ex: Export, out_dir: Path | None, limits: str = "inner", friction: bool = True) -> str:
    """The robot's URDF with inner-box limits (``limits="open"``: :func:`open_limits`, which never fight the
    runtime's clip), fitted friction (``friction=False``: none, for a simulator whose motor tendons carry it) and the
    optimised foot (XML text)."""
    from hound_id.foot.urdf import parse_urdf, rebase_meshes

    path = ex.urdf()
    root = parse_urdf(path)
    rebase_meshes(root, path, out_dir)
    joints = {j.get("name"): j for j in root.iter("joint")}
    missing = [j for j in ex.bundle.joints if j not in joints]
    if missing:
        raise SpecError(f"{path}: joints {', '.join(missing)} of robot {ex.robot.name} are not in the URDF")
    coulomb, viscous = ex.joint_friction()
    effort, velocity = open_limits(ex) if limits == "open" else (None, None)
    for i, name in enumerate(ex.bundle.joints):
        joint = joints[name]
        box = ex.bundle.joint_boxes[name]["inner"]
        limit = joint.find("limit")
        if limit is None:
            limit = ET.SubElement(joint, "limit", lower="-3.14159265", upper="3.14159265")
        if effort is not None and velocity is not None:
            limit.set("effort", _fmt(float(effort[i])))
            limit.set("velocity", _fmt(float(velocity[i])))
        else:
            limit.set("effort", _fmt(box["effort"]))
            limit.set("velocity", _fmt(box["velocity"]))
        dynamics = joint.find("dynamics")
        if not friction:
            if dynamics is not None:
                joint.remove(dynamics)
            continue
        if dynamics is None:
            dynamics = ET.SubElement(joint, "dynamics")
        dynamics.set("damping", _fmt(float(viscous[i])))
        dynamics.set("friction", _fmt(float(coulomb[i])))
    foot = ex.bundle.foot
    if foot:
        put_feet(root, foot, path)
    if limits == "open":
        root.insert(0, ET.Comment(OPEN_REASON.format(schema=ex.bundle.schema, reach=OPEN_REACH)))
    else:
        root.insert(0, ET.Comment(f" limits from hound-id ({ex.bundle.schema}): inner boxes of the operating regions "))
    ET.indent(root, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def write_urdf(ex: Export, out: Path) -> Written:
    """``<robot>_limits.urdf``: :func:`limited_urdf`."""
    path = out / f"{_stem(ex)}_limits.urdf"
    io.write_text(path, limited_urdf(ex, out))
    notes = ["effort/velocity limits are the inner boxes (always feasible); coupled joints get the group's box"]
    return Written((str(path),), tuple(notes))


#: Why the open URDF's limits are what they are (its first comment).
OPEN_REASON = (
    " hound-id ({schema}), for simulators that enforce URDF effort limits (Genesis and the like): the limits are "
    "open, the largest torque and speed the runtime's clip returns for motor speeds up to {reach:g} x overspeed, so "
    "they never fight hound_id.runtime's saturation (apply it every step: it holds the operating regions, which "
    "these limits do not). Armature is not a URDF field: see the armature sidecar "
)


def write_urdf_open(ex: Export, out: Path) -> Written:
    """``<robot>_open_limits.urdf`` (:func:`limited_urdf` with open limits) and ``<robot>_armature.yaml``: per joint
    the reflected rotor inertia, with each coupled group's full matrix and what a per-joint armature drops."""
    import yaml

    urdf = out / f"{_stem(ex)}_open_limits.urdf"
    io.write_text(urdf, limited_urdf(ex, out, limits="open"))
    reflected = ex.bundle.reflected_inertia
    sidecar: dict[str, Any] = {
        "schema": ARMATURE_SCHEMA,
        "robot": ex.bundle.robot,
        "units": "kg m^2, joint side",
        "reason": "URDF has no armature field; set each joint's armature in your simulator from 'armature' (the "
        "diagonal of A^-T diag(J) A^-1); coupled groups list the off-diagonal terms a per-joint armature drops",
        "armature": None,
        "groups": [],
    }
    if reflected is not None:
        M = np.asarray(reflected, dtype=float)
        sidecar["armature"] = {j: float(M[i, i]) for i, j in enumerate(ex.bundle.joints)}
        index = {j: i for i, j in enumerate(ex.bundle.joints)}
        for tx in ex.bundle.transmissions:
            if len(tx["joints"]) > 1:
                idx = [index[j] for j in tx["joints"]]
                sidecar["groups"].append(_group_inertia(M[np.ix_(idx, idx)], list(tx["joints"])))
    else:
        sidecar["reason"] += "; a motor's rotor inertia is unknown, so none is given"
    side = out / f"{_stem(ex)}_armature.yaml"
    io.write_text(side, yaml.safe_dump(sidecar, sort_keys=False))
    notes = (
        f"effort/velocity limits are open (what the runtime returns up to {OPEN_REACH:g} x overspeed): apply "
        "hound_id.runtime's saturation each step",
        "armature (reflected rotor inertia) in the sidecar; URDF has no field for it",
    )
    return Written((str(urdf), str(side)), notes)


#: Every format, by name (sorted).
FORMATS: dict[str, Callable[[Export, Path], Written]] = {
    "bundle": write_bundle,
    "isaaclab": write_isaaclab,
    "mjlab": write_mjlab,  # imports mujoco when it runs
    "mujoco": write_mujoco,  # imports mujoco when it runs
    "newton": write_newton,
    "urdf": write_urdf,
    "urdf-open": write_urdf_open,
}
