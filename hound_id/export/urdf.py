"""URDF exports: the robot's URDF with inner-box limits (``urdf``) or open limits that never fight the runtime's clip
(``urdf-open``, and the Newton export's URDF), fitted friction and the optimised foot."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from hound_id.errors import SpecError
from hound_id.export.target import Export, Written, group_inertia, put_feet

ARMATURE_SCHEMA = "hound-id/armature/1"


def _fmt(v: float) -> str:
    return f"{v:.9g}"


def _fmt_up(v: float) -> str:
    """``v`` > 0 in 9 significant digits, rounded up (an open limit written below its value would bind)."""
    step = 10.0 ** (math.floor(math.log10(v)) - 8)
    up = math.ceil(v / step) * step
    return _fmt(up if up >= v else up + step)


#: The open URDF's limits hold every state whose motor speeds are within this multiple of each motor's overspeed.
OPEN_REACH = 2.0
#: Motor speeds at which a motor's largest torque is searched (across +-OPEN_REACH x overspeed).
OPEN_POINTS = 4001


def open_limits(ex: Export) -> tuple[np.ndarray, np.ndarray]:
    """(effort [N m], velocity [rad/s]) per joint that never bind on what the runtime returns for motor speeds up to
    :data:`OPEN_REACH` x overspeed: effort_j = sum_m |(A^-T)_jm| T_m with T_m the largest |torque| of motor m's
    interval there (the curve's top, or the back-EMF braking of a linear motor at that speed), velocity_j =
    sum_m |A_jm| OPEN_REACH overspeed_m."""
    from hound_id.mor.region import torque_interval

    tops, speeds = [], []
    for m in ex.bundle.motors:
        region = ex.region(m.name)
        w = np.linspace(-OPEN_REACH, OPEN_REACH, OPEN_POINTS) * region.overspeed
        lo, hi = torque_interval(w, region)
        mag = np.maximum(np.abs(lo), np.abs(hi))
        k = int(np.argmax(mag))  # a smooth peak (the diode bridge's braking) lies between grid points: refine there
        near = np.linspace(w[max(k - 1, 0)], w[min(k + 1, w.size - 1)], OPEN_POINTS)
        lo_n, hi_n = torque_interval(near, region)
        tops.append(float(max(mag[k], np.max(np.abs(lo_n)), np.max(np.abs(hi_n)))))
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
            limit.set("effort", _fmt_up(float(effort[i])))
            limit.set("velocity", _fmt_up(float(velocity[i])))
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


def urdf_files(ex: Export, out: Path) -> Written:
    """``<robot>_limits.urdf``: :func:`limited_urdf`."""
    files = {f"{ex.stem}_limits.urdf": limited_urdf(ex, out)}
    notes = [
        "effort/velocity limits are the inner boxes, feasible at every point at the battery's lowest bus voltage where "
        "the specs state a range (else the nominal) and at 20 degC (a warm winding: apply hound_id.runtime with its "
        "temperature); coupled joints get the group's box",
        *ex.friction_not_held("urdf"),
    ]
    return Written(files, tuple(notes))


#: Why the open URDF's limits are what they are (its first comment).
OPEN_REASON = (
    " hound-id ({schema}), for simulators that enforce URDF effort limits (Genesis and the like): the limits are "
    "open, the largest torque and speed the runtime's clip returns for motor speeds up to {reach:g} x overspeed, so "
    "they never fight hound_id.runtime's saturation (apply it every step: it holds the operating regions, which "
    "these limits do not). Armature is not a URDF field: see the armature sidecar "
)


def urdf_open_files(ex: Export, out: Path) -> Written:
    """``<robot>_open_limits.urdf`` (:func:`limited_urdf` with open limits) and ``<robot>_armature.yaml``: per joint
    the reflected rotor inertia, with each coupled group's full matrix and what a per-joint armature drops."""
    import yaml

    urdf = limited_urdf(ex, out, limits="open")
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
                sidecar["groups"].append(group_inertia(M[np.ix_(idx, idx)], list(tx["joints"])))
    else:
        sidecar["reason"] += "; a motor's rotor inertia is unknown, so none is given"
    files = {f"{ex.stem}_open_limits.urdf": urdf, f"{ex.stem}_armature.yaml": yaml.safe_dump(sidecar, sort_keys=False)}
    notes = (
        f"effort/velocity limits are open (what the runtime returns up to {OPEN_REACH:g} x overspeed): apply "
        "hound_id.runtime's saturation each step",
        "armature (reflected rotor inertia) in the sidecar; URDF has no field for it",
        *ex.friction_not_held("urdf-open"),
    )
    return Written(files, notes)
