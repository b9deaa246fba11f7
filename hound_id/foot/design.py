"""A foot redesign from leg to parts: optimise, build the mesh, patch the URDF, check with Pinocchio.

:func:`design_foot` runs the whole job and returns a :class:`FootReport`; :func:`foot_json`
gives its ``hound-id/foot/1`` JSON and :func:`write_foot` writes the STL, the patched URDF and
the JSON into a folder. Ratios are new / original for everything below the knee (calf + foot).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hound_id import io
from hound_id.errors import SpecError
from hound_id.foot.angles import ContactAngles
from hound_id.foot.geometry import MassProperties, foot_mesh, mesh_properties
from hound_id.foot.leg import LegProperties, leg_properties
from hound_id.foot.optimise import FootDesign, FootRequirements, optimise_foot
from hound_id.foot.urdf import FootMount, patched_urdf, read_foot

SCHEMA = "hound-id/foot/1"
#: The paper's redesign (KAIST Hound, "Lightweight foot design"): calf mass and pitch inertia, new / original.
PAPER = {"mass_ratio": 0.380, "inertia_ratio": 0.374}
STL_NAME = "foot.stl"


@dataclass(frozen=True)
class MeshCheck:
    """The manifold3d/trimesh solid against the closed-form properties."""

    watertight: bool
    faces: int
    mass_error: float
    """Relative mass error, mesh / closed form - 1 [-]."""
    com_error: float
    """Distance between the two centres of mass [m]."""
    inertia_error: float
    """Largest inertia-tensor difference over the largest closed-form entry [-]."""

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@dataclass(frozen=True)
class FootReport:
    """Everything ``hound-id foot --optimise`` found."""

    mount: FootMount
    angles: ContactAngles
    requirements: FootRequirements
    design: FootDesign
    original: LegProperties
    """Pinocchio on the original URDF."""
    new: LegProperties
    """Pinocchio on the patched URDF."""
    reflected_knee_inertia: float | None
    """Knee rotor inertia seen at the knee [kg m^2], when a robot file gave it."""
    mesh: Any
    """The foot as a trimesh.Trimesh (foot frame, metres)."""
    mesh_check: MeshCheck
    urdf_text: str
    """The patched URDF (mesh referenced as ``foot.stl`` beside it; other meshes by absolute path)."""

    @property
    def mass_ratio(self) -> float:
        return self.new.calf_foot_mass / self.original.calf_foot_mass

    @property
    def inertia_ratio(self) -> float:
        return self.new.knee_pitch_inertia / self.original.knee_pitch_inertia

    @property
    def pinocchio_error(self) -> float:
        """Pinocchio's new knee inertia against the closed-form prediction, relative [-]."""
        old_foot = self.mount.foot.about_axis_y((0.0, 0.0, self.mount.mount_length))
        predicted = self.original.knee_pitch_inertia - old_foot + self.design.knee_inertia
        return self.new.knee_pitch_inertia / predicted - 1.0


def _mesh_check(mesh: Any, props: MassProperties, density: float) -> MeshCheck:
    measured = mesh_properties(mesh, density)
    scale = float(np.max(np.abs(props.inertia)))
    return MeshCheck(
        watertight=bool(mesh.is_watertight),
        faces=len(mesh.faces),
        mass_error=measured.mass / props.mass - 1.0,
        com_error=float(np.linalg.norm(measured.com - props.com)),
        inertia_error=float(np.max(np.abs(measured.inertia - props.inertia))) / scale,
    )


def _pinocchio_model(urdf_text: str, where: str) -> Any:
    import pinocchio as pin

    try:
        return pin.buildModelFromXML(urdf_text)
    except (RuntimeError, ValueError) as err:  # a bug in the patch, not the user's input
        raise SpecError(f"{where}: Pinocchio cannot load the patched URDF ({err})") from err


def design_foot(
    leg: str | Path,
    angles: ContactAngles,
    requirements: FootRequirements,
    *,
    foot_link: str = "foot",
    knee_angle: float = -1.2,
    reflected_knee_inertia: float | None = None,
    mesh_resolution_deg: float = 2.0,
) -> FootReport:
    """Optimise the foot of a leg URDF for the contact angles and check the result.

    Args:
        leg: The leg URDF (see :mod:`hound_id.foot.urdf` for the layout it needs).
        angles: Contact angles with the margin (``requirements.low/high`` must match them).
        requirements: The constraints' parameters.
        foot_link: Name of the foot link.
        knee_angle: Knee angle of the nominal pose for the hip inertia [rad].
        reflected_knee_inertia: Knee rotor inertia seen at the knee [kg m^2], if known.
        mesh_resolution_deg: Angular step of the mesh [deg].
    """
    from hound_id.foot.leg import load_leg

    if not 0.5 <= mesh_resolution_deg <= 10:  # 0.5 deg is already ~300k faces and 0.002 % in mass
        raise SpecError(f"--mesh-resolution: found {mesh_resolution_deg:g} deg, expected 0.5 to 10 deg")
    mount = read_foot(leg, foot_link)
    design = optimise_foot(mount, requirements)
    original = leg_properties(
        load_leg(leg), hip_joint=mount.hip_joint, knee_joint=mount.knee_joint, knee_angle=knee_angle
    )
    g = design.geometry
    text = _patched(mount, design, requirements, None)
    new = leg_properties(
        _pinocchio_model(text, str(leg)), hip_joint=mount.hip_joint, knee_joint=mount.knee_joint, knee_angle=knee_angle
    )
    mesh = foot_mesh(g, mesh_resolution_deg)
    return FootReport(
        mount=mount,
        angles=angles,
        requirements=requirements,
        design=design,
        original=original,
        new=new,
        reflected_knee_inertia=reflected_knee_inertia,
        mesh=mesh,
        mesh_check=_mesh_check(mesh, design.properties, requirements.material.density),
        urdf_text=text,
    )


def foot_json(report: FootReport, files: dict[str, str] | None = None) -> dict[str, Any]:
    """The ``hound-id/foot/1`` JSON of a report (SI units; angles also in degrees where named _deg)."""
    d, g, req = report.design, report.design.geometry, report.requirements
    refl = report.reflected_knee_inertia
    with_rotor = None
    if refl is not None:
        with_rotor = (report.new.knee_pitch_inertia + refl) / (report.original.knee_pitch_inertia + refl)
    return {
        "schema": SCHEMA,
        "mass_ratio": report.mass_ratio,
        "inertia_ratio": report.inertia_ratio,
        "radius": g.radius,
        "coverage_deg": [math.degrees(g.low), math.degrees(g.high)],
        "constraints": {c.name: c.to_dict() for c in d.constraints},
        "paper": PAPER,
        "units": "SI: m, kg, kg m^2, rad, Pa, N",
        "leg": report.mount.path,
        "geometry": {k: getattr(g, k) for k in g.__dataclass_fields__},
        "foot": {"closed_form": d.properties.to_dict(), "knee_inertia": d.knee_inertia},
        "original_foot": report.mount.foot.to_dict() | {"contact_radius": report.mount.contact_radius},
        "leg_original": _leg_dict(report.original),
        "leg_new": _leg_dict(report.new),
        "hip_inertia_ratio": report.new.hip_pitch_inertia / report.original.hip_pitch_inertia,
        "reflected_knee_inertia": refl,
        "inertia_ratio_with_rotor": with_rotor,
        "angles": report.angles.to_dict(),
        "requirements": {
            "low": req.low,
            "high": req.high,
            "peak_force": req.peak_force,
            "safety": req.safety,
            "roll": req.roll,
            "boss_radius": req.boss_radius,
            "min_boss_length": req.min_boss_length,
            "nominal_angle": req.nominal_angle,
            "max_radius": req.max_radius,
            "radius": req.radius,
            "mass_weight": req.mass_weight,
            "length_tolerance": req.length_tolerance,
            "material": req.material.to_dict(),
            "ground": req.ground.to_dict(),
        },
        "hertz_min_radius": d.hertz_min_radius,
        "mesh_check": report.mesh_check.to_dict(),
        "pinocchio_check": {"knee_inertia_relative_error": report.pinocchio_error},
        "solver": d.solver,
        "files": files or {},
    }


def _patched(mount: FootMount, design: FootDesign, req: FootRequirements, out_dir: Path | None) -> str:
    g = design.geometry
    return patched_urdf(
        mount,
        design.properties,
        mesh_filename=STL_NAME,
        sphere_radius=g.radius,
        sphere_centre_z=g.centre_z,
        comment=(
            f"foot by hound-id ({SCHEMA}): spherical cap R={g.radius * 1e3:.2f} mm, t={g.thickness * 1e3:.2f} mm, "
            f"W={g.width * 1e3:.2f} mm, {math.degrees(g.low):.1f} to {math.degrees(g.high):.1f} deg, "
            f"{req.material.name}"
        ),
        out_dir=out_dir,
    )


def _leg_dict(props: LegProperties) -> dict[str, Any]:
    out = props.to_dict()
    del out["reflected_knee_inertia"]  # given once, at the top level
    return out


def write_foot(report: FootReport, out: Path) -> dict[str, str]:
    """Write ``foot.stl``, ``<leg>_light_foot.urdf`` and ``foot.json`` into ``out`` (created if missing).

    Each file is written atomically. Returns the written paths by kind.
    """
    names = {"stl": STL_NAME, "urdf": f"{Path(report.mount.path).stem}_light_foot.urdf", "json": "foot.json"}
    files = {kind: os.fspath(out / name) for kind, name in names.items()}
    with io.staged_folder(out) as stage:  # the three files appear together or not at all
        io.write_with(stage / names["stl"], lambda handle: report.mesh.export(handle, file_type="stl"))
        urdf = _patched(report.mount, report.design, report.requirements, out)  # mesh paths from out
        io.write_text(stage / names["urdf"], urdf)
        io.write_json(stage / names["json"], foot_json(report, files))
    return files


def leg_summary(
    leg: str | Path,
    angles: ContactAngles,
    requirements: FootRequirements,
    *,
    foot_link: str = "foot",
    knee_angle: float = -1.2,
    reflected_knee_inertia: float | None = None,
) -> dict[str, Any]:
    """The leg as it is (``hound-id/foot-leg/1``): Pinocchio mass properties, the original foot,
    the contact arc it must cover and the Hertz minimum radius for the requirements."""
    from hound_id.foot.leg import load_leg
    from hound_id.foot.optimise import hertz_min_radius

    mount = read_foot(leg, foot_link)
    props = leg_properties(load_leg(leg), hip_joint=mount.hip_joint, knee_joint=mount.knee_joint, knee_angle=knee_angle)
    return {
        "schema": "hound-id/foot-leg/1",
        "units": "SI: m, kg, kg m^2, rad",
        "leg": mount.path,
        "leg_properties": _leg_dict(props),
        "original_foot": mount.foot.to_dict()
        | {"contact_radius": mount.contact_radius, "shape": mount.contact_shape, "width": mount.contact_width},
        "knee_joint": mount.knee_joint,
        "hip_joint": mount.hip_joint,
        "mount_length": mount.mount_length,
        "angles": angles.to_dict(),
        "hertz_min_radius": hertz_min_radius(requirements),
        "reflected_knee_inertia": reflected_knee_inertia,
    }
