"""Export formats: the registry (:data:`FORMATS`), the bundle and the Isaac Lab actuator fields; the URDF, MuJoCo,
mjlab and Newton formats live in their own modules.

Every format is a function taking an :class:`~hound_id.export.target.Export` (the robot with its fits, its
bundle and its URDF) and the folder its files will be written to (relative mesh paths are computed from it); it
writes nothing and returns its files' text by name with what the user should know
(:class:`~hound_id.export.target.Written`); :func:`hound_id.export.run.write_outputs` writes every format's files
at once. They are registered in :data:`FORMATS` (sorted by name); ``hound-id export --format NAME`` runs one. A
new format is one module importing :mod:`hound_id.export.target` (as :mod:`hound_id.export.mujoco` does) plus one
line in :data:`FORMATS`.

Joint-side numbers of an uncoupled joint with gear ratio G (motor turns per joint turn):
torque G tau_m, speed omega_m / G, rotor inertia J G^2, Coulomb friction G f_c, viscous G^2 b.
For coupled joints the URDF gets the diagonal of A^-T diag(b) A^-1 for damping and the
worst case sum_m |(A^-T)_jm| f_c,m for friction; the exact coupled model is in the bundle, the
runtime and the MuJoCo tendons.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from hound_id.export.bundle import BundleMotor
from hound_id.export.mjlab import mjlab_files
from hound_id.export.mujoco import mujoco_files
from hound_id.export.newton import newton_files
from hound_id.export.target import Export, Written, bundle_json, group_inertia
from hound_id.export.urdf import urdf_files, urdf_open_files

ISAACLAB_SCHEMA = "hound-id/isaaclab/2"


def bundle_files(ex: Export, out: Path) -> Written:
    """``<robot>_bundle.yaml`` and the same content as ``<robot>_bundle.json``."""
    import yaml

    content = ex.bundle.to_dict()
    files = dict([(f"{ex.stem}_bundle.yaml", yaml.safe_dump(content, sort_keys=False)), bundle_json(ex)])
    return Written(files, ("load it in a trainer with hound_id.runtime.load",))


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
            entry: dict[str, Any] = {
                "coupled": coupled,
                "armature": float(reflected[i, i]) if reflected is not None else 0.0,
                "friction": float(coulomb[i]),
                "viscous_friction": float(viscous[i]),
                "inner_box": dict(b.joint_boxes[joint]["inner"]),
            }
            if coupled:
                entry |= _coupled_fields(joint, tx, A, index, reflected)
            else:
                gear = float(1.0 / abs(A[k, k]))  # motor turns per joint turn
                entry |= _uncoupled_fields(ex, b.motors[i], gear, float(coulomb[i]), float(viscous[i]))
            joints[joint] = entry
    return {
        "schema": ISAACLAB_SCHEMA,
        "robot": b.robot,
        "units": "SI, joint side: N m, rad/s, kg m^2, N m s/rad",
        "actuator": "isaaclab.actuators.DCMotorCfg (per uncoupled joint: DCMotorCfg(..., **joints[name]['dcmotor']) in "
        "Isaac Lab 3.0, **joints[name]['dcmotor_isaaclab2'] in 2.x)",
        "joints": joints,
        "notes": [*_ISAACLAB_NOTES, *ex.friction_not_held("isaaclab")],
    }


#: The notes of the Isaac Lab fields file, before what the format does not hold of each friction term.
_ISAACLAB_NOTES = (
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
)


def _coupled_fields(
    joint: str, tx: Mapping[str, Any], A: np.ndarray, index: Mapping[str, int], reflected: np.ndarray | None
) -> dict[str, Any]:
    """The fields of a coupled joint beyond its armature and friction: why it points to the runtime."""
    fields: dict[str, Any] = {
        "use": "hound_id.runtime",
        "reason": (
            f"{joint} shares motors {', '.join(tx['motors'])} with {', '.join(tx['joints'])} through "
            "A = " + str(A.tolist()) + "; Isaac Lab's per-joint DCMotor clips each joint alone and cannot "
            "express the coupled motor-space limits. Apply hound_id.runtime.load(bundle, joint_names)"
            ".saturate(tau, qd) to the group (see docs/export.md); armature is the diagonal of the reflected "
            "inertia (the off-diagonal terms are in reflected_inertia_group), friction the worst case "
            "sum |A^-T| f_c"
        ),
    }
    if reflected is not None:
        idx = [index[j] for j in tx["joints"]]
        fields["reflected_inertia_group"] = group_inertia(reflected[np.ix_(idx, idx)], list(tx["joints"]))
    return fields


def _uncoupled_fields(ex: Export, m: BundleMotor, gear: float, coulomb: float, viscous: float) -> dict[str, Any]:
    """The fields of an uncoupled joint beyond its armature and friction: its gear ratio, its ``DCMotorCfg``
    keyword arguments (Isaac Lab 3.0 and 2.x) and how far DCMotor's straight lines are from hound-id's clip.

    ``gear`` is motor turns per joint turn; ``coulomb`` [N m] and ``viscous`` [N m s/rad] are joint side.
    """
    dcmotor = {  # Isaac Lab 3.0's names (ActuatorBaseCfg)
        "saturation_effort": m.stall_torque * gear,
        "actuator_effort_limit": m.torque_limit * gear,
        "actuator_velocity_limit": m.no_load_speed / gear,
        "armature": (m.rotor_inertia or 0.0) * gear**2,
        # static friction: Coulomb + the Stribeck excess at rest; kinetic: Coulomb; viscous: G^2 b
        "friction": coulomb + float(m.friction.get("stribeck", 0.0)) * gear,
        "dynamic_friction": coulomb,
        "viscous_friction": viscous,
    }
    fields: dict[str, Any] = {
        "gear_ratio": gear,
        "dcmotor": dcmotor,
        "dcmotor_isaaclab2": {  # Isaac Lab 2.x's names (deprecated in 3.0)
            **{k: v for k, v in dcmotor.items() if not k.startswith("actuator_")},
            "effort_limit": m.torque_limit * gear,
            "velocity_limit": m.no_load_speed / gear,
        },
    }
    if m.envelope:  # DCMotor holds straight lines; the measured edge is a polyline
        fields["use"] = "hound_id.runtime"
        fields["reason"] = (
            f"motor {m.name} has a measured envelope (mor --compare --out); DCMotor's straight lines "
            f"allow up to {_over_promise(m) * gear:.4g} N m more than it at the joint. The dcmotor "
            "fields hold the spec sheet; apply hound_id.runtime.load(bundle, joint_names).saturate(tau, "
            "qd) for the measured edge"
        )
        return fields
    return fields | _straight_error_fields(ex, m, gear)


def _straight_error_fields(ex: Export, m: BundleMotor, gear: float) -> dict[str, Any]:
    """``dcmotor_error`` of a motor without a measured envelope (joint side, ``gear`` motor turns per joint turn),
    and a pointer to the runtime when DCMotor's straight line passes hound-id's edges."""
    gap = ex.straight_gap(m.name)
    past, reach = ex.past_overspeed(m.name)
    fields: dict[str, Any] = {
        "dcmotor_error": {
            "over": gap[0] * gear,
            "under": gap[1] * gear,
            "past_overspeed": past * gear,
            "past_overspeed_to": reach / gear,
            "units": "N m, joint side: the most DCMotor's clip passes (over) or falls short of (under) "
            "hound-id's within +-overspeed; past_overspeed: how much more braking hound-id's clip forces "
            "than DCMotor's torque limit, from the overspeed to past_overspeed_to [rad/s, joint side]",
        }
    }
    if gap[0] > DCMOTOR_EXACT * m.torque_limit:
        fields["use"] = "hound_id.runtime"
        spec = ex.robot.motor_specs[m.name]
        bends = (
            ["its current-torque curve bends its voltage edges"] if spec.current_curve.form != "linear" else []
        ) + (["its rated speed cuts them (braking only above max_speed)"] if spec.max_speed else [])
        fields["reason"] = (
            f"motor {m.name}: {' and '.join(bends)} (torque limit {m.torque_limit * gear:.4g} N m "
            f"at the joint): DCMotor's straight line passes hound-id's edges by up to "
            f"{gap[0] * gear:.4g} N m at the joint within the overspeed, and past overspeed DCMotor "
            "returns the torque limit where the back-EMF forces more braking. The dcmotor fields are "
            "the closest straight model; use HoundIdActuator (hound_id.export.isaaclab_actuator) or "
            "hound_id.runtime.load(bundle, joint_names).saturate(tau, qd) for the exact clip"
        )
    return fields


#: A DCMotor whose clip passes hound-id's by less than this share of the torque limit reproduces it (rounding).
DCMOTOR_EXACT = 1e-9


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


def isaaclab_files(ex: Export, out: Path) -> Written:
    """``<robot>_isaaclab.yaml``: :func:`isaaclab_fields`."""
    import yaml

    data = isaaclab_fields(ex)
    files = {f"{ex.stem}_isaaclab.yaml": yaml.safe_dump(data, sort_keys=False)}
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
    return Written(files, (*notes, *ex.friction_not_held("isaaclab")))


#: Every format, by name (sorted).
FORMATS: dict[str, Callable[[Export, Path], Written]] = {
    "bundle": bundle_files,
    "isaaclab": isaaclab_files,
    "mjlab": mjlab_files,  # imports mujoco when it runs
    "mujoco": mujoco_files,  # imports mujoco when it runs
    "newton": newton_files,
    "urdf": urdf_files,
    "urdf-open": urdf_open_files,
}
