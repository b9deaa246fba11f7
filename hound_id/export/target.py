"""What every export format is written from and returns: :class:`Export`, :class:`Written`, and the
helpers more than one format uses (:func:`put_feet`).

A format is one module with a function ``x_files(ex: Export, out: Path) -> Written`` (its files' text by name;
``out`` is where they will be written, for relative paths) that imports this module, plus one line in
:data:`hound_id.export.formats.FORMATS`. Formats built on another's model import it
(mjlab builds on :mod:`hound_id.export.mujoco`'s MJCF, Newton on :mod:`hound_id.export.urdf`'s open URDF); the
registry imports every format, so no format imports the registry.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hound_id import io
from hound_id.errors import SpecError
from hound_id.export.bundle import Bundle
from hound_id.mor.region import OperatingRegion
from hound_id.mor.robot import Robot

#: Exports state what a straight-line actuator cannot hold up to this many no-load speeds (a leg overspeeds when
#: the foot strikes or the gait reverses a joint; trainers reach it).
TRAINER_REACH = 2.0
#: Motor speeds between overspeed and that reach at which the forced braking is searched.
PAST_POINTS = 2001


@dataclass(frozen=True)
class Export:
    """What every format is written from."""

    robot: Robot
    """The robot, with fitted motor specs in place."""
    bundle: Bundle
    """Its ``hound-id/bundle/5`` bundle."""
    mujoco_actuator: str = "dcmotor"
    """``dcmotor`` (voltage input), ``dcmotor-ff`` (torque input, MuJoCo >= 4.0) or ``motor`` (plain torque, saturate
    with the runtime)."""
    _regions: dict[int, OperatingRegion] = field(default_factory=dict, init=False, compare=False, repr=False)
    _gaps: dict[int, tuple[float, float]] = field(default_factory=dict, init=False, compare=False, repr=False)

    @property
    def A(self) -> np.ndarray:
        """The global velocity map qd_joint = A thetad_motor."""
        return np.asarray(self.bundle.saturation["A"], dtype=float)

    def joint_friction(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint-side (Coulomb [N m], viscous [N m s/rad]) per joint (see :mod:`hound_id.export.formats`)."""
        A_inv = np.linalg.inv(self.A)
        fc = np.array([m.friction["coulomb"] for m in self.bundle.motors])
        b = np.array([m.friction["viscous"] for m in self.bundle.motors])
        coulomb = np.abs(A_inv.T) @ fc
        viscous = np.diag(A_inv.T @ np.diag(b) @ A_inv)
        return coulomb, viscous

    def straight_gap(self, motor: str) -> tuple[float, float]:
        """(over, under) [N m, motor side]: how far a straight-line DC-motor clip (Isaac Lab's DCMotor, MuJoCo's
        dcmotor) passes or falls short of the motor's region within +-overspeed
        (:func:`hound_id.mor.region_report.straight_gap`; 0 for a linear curve)."""
        from hound_id.mor.region_report import straight_gap

        spec = self.robot.motor_specs[motor]
        if id(spec) not in self._gaps:  # motors sharing a spec share its gap
            self._gaps[id(spec)] = straight_gap(self.region(motor))
        return self._gaps[id(spec)]

    def region(self, motor: str) -> OperatingRegion:
        """The motor's spec-sheet region, built once per spec (a drive model's takes ~0.1 s)."""
        from hound_id.mor.region import operating_region

        spec = self.robot.motor_specs[motor]
        if id(spec) not in self._regions:
            self._regions[id(spec)] = operating_region(spec)
        return self._regions[id(spec)]

    def past_overspeed(self, motor: str) -> tuple[float, float]:
        """(most braking past the torque limit [N m, motor side], up to speed [rad/s]): how much harder than a
        straight-line actuator's torque limit the runtime brakes past the motor's overspeed, up to
        :data:`TRAINER_REACH` x its no-load speed (the back-EMF's forced braking under the DC law, the diode
        bridge's with a winding reactance)."""
        from hound_id.mor.region import torque_interval

        region = self.region(motor)
        top = TRAINER_REACH * region.no_load_speed
        if top <= region.overspeed:
            return 0.0, top
        w = np.linspace(region.overspeed, top, PAST_POINTS)
        braking = np.abs(torque_interval(w, region)[1])
        return max(float(np.max(braking)) - region.torque_limit, 0.0), top

    def friction_not_held(self, fmt: str) -> tuple[str, ...]:
        """One line per fitted friction term (:data:`hound_id.mor.friction.TERMS`) that format ``fmt`` has no home
        for, with the largest torque it loses (motor side: at the current of the torque limit, up to the no-load
        speed) and the motors that have it."""
        from hound_id.mor.friction import TERMS

        lines = []
        for term in TERMS.values():
            if fmt in term.homes:
                continue
            lost, share = {}, 0.0
            for m in self.bundle.motors:
                p = {name: float(m.friction.get(name) or default) for name, _, default in term.parameters}
                current = m.limit_current or m.max_current or m.torque_limit / m.kt
                size = term.largest(p, current, m.no_load_speed)
                if size > 0:
                    lost[m.name], share = size, max(share, size / m.torque_limit)
            if lost:
                which = "every motor" if len(lost) == len(self.bundle.motors) else f"motors {', '.join(lost)}"
                lines.append(
                    f"{term.label} ({term.name}): up to {max(lost.values()):.4g} N m at the motor ({share:.1%} of "
                    f"its torque limit; {which}) has no home in this format: {term.physics}; hound_id.runtime's "
                    "friction_torque(qd, tau) applies it"
                )
        return tuple(lines)

    @property
    def stem(self) -> str:
        """The robot's name as the stem of every file a format writes (checked: a Robot built in code too)."""
        return io.file_stem(self.robot.name, "robot field 'name'")

    def unlisted_joints(self) -> list[str]:
        """The URDF's movable joints (revolute, continuous, prismatic) that the robot file does not list: a simulator
        loads them with the URDF's own limits and no armature or actuator from hound-id."""
        from hound_id.foot.urdf import parse_urdf

        listed = set(self.bundle.joints)
        movable = ("revolute", "continuous", "prismatic")
        return [
            str(j.get("name"))
            for j in parse_urdf(self.urdf()).iter("joint")
            if j.get("type") in movable and j.get("name") not in listed
        ]

    def urdf(self) -> Path:
        """The robot's URDF, or SpecError saying how to give one."""
        if self.robot.urdf is None:
            raise SpecError(
                f"robot {self.robot.name}: this format needs the robot's URDF; add 'urdf: my_robot.urdf' to the "
                "robot file (relative to it), or pass --urdf"
            )
        return Path(self.robot.urdf)


@dataclass(frozen=True)
class Written:
    """What a format produced: its files' text, not yet written, and what the user should know."""

    files: Mapping[str, str]
    """File name (in the export folder) -> its text."""
    notes: tuple[str, ...] = ()
    """What the format cannot hold, and how a trainer gets it instead."""


def bundle_json(ex: Export) -> tuple[str, str]:
    """(``<robot>_bundle.json``, its text): the bundle as JSON, which the bundle, mjlab and Newton formats all carry
    (the same file when written together)."""
    return f"{ex.stem}_bundle.json", io.json_text(ex.bundle.to_dict())


def put_feet(root: ET.Element, foot: Mapping[str, Any], path: Path) -> None:
    """Put the optimised foot (a bundle's ``foot``) on every link of the URDF tree ``root`` whose name ends in
    'foot'; ``path`` is the URDF, for messages."""
    from hound_id.arrays import frozen
    from hound_id.foot.geometry import MassProperties
    from hound_id.foot.urdf import replace_foot

    props = MassProperties(
        mass=float(foot["mass"]), com=frozen(np.asarray(foot["com"])), inertia=frozen(np.asarray(foot["inertia"]))
    )
    feet = [link for link in root.iter("link") if str(link.get("name", "")).endswith("foot")]
    if not feet:
        raise SpecError(f"{path}: no link whose name ends in 'foot' to put the optimised foot on")
    # hound-id/foot/2 gives spheres along the cap's arc; a bundle made from a /1 foot has the one contact sphere
    spheres = foot.get("collision_spheres") or [
        (0.0, 0.0, float(foot["sphere_centre_z"]), float(foot["sphere_radius"]))
    ]
    for link in feet:
        replace_foot(
            link,
            props,
            None,
            [tuple(float(v) for v in s) for s in spheres],
            f"optimised foot from {foot.get('source', 'hound-id foot')}",
        )


def group_inertia(M: np.ndarray, joints: list[str]) -> dict[str, Any]:
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
