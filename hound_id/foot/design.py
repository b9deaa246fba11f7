"""A foot redesign from leg to parts: optimise, build the mesh, patch the URDF, check with Pinocchio.

:func:`design_foot` runs the whole job and returns a :class:`FootReport`; :func:`foot_json`
gives its ``hound-id/foot/2`` JSON and :func:`write_foot` writes the STL, the patched URDF and
the JSON into a folder. Ratios are new / original for everything below the knee (calf + foot) of
the *same* leg URDF, about two axes: the knee axis, and the pitch axis through the calf + foot's
own centre of mass. The paper's ratios (:data:`PAPER`) are the KAIST Hound's own redesign against
its own cylindrical foot: another leg, and the paper does not state the axis of its inertia.
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
from hound_id.foot.collision import CollisionSpheres, collision_spheres
from hound_id.foot.geometry import MassProperties, foot_mesh, mesh_properties
from hound_id.foot.leg import LegProperties, leg_properties
from hound_id.foot.optimise import FootDesign, FootRequirements, optimise_foot
from hound_id.foot.urdf import FootMount, patched_urdf, read_foot

SCHEMA = "hound-id/foot/2"
#: The paper's redesign (KAIST Hound, "Lightweight foot design"): calf mass and pitch inertia, new / original.
PAPER: dict[str, Any] = {
    "mass_ratio": 0.380,
    "inertia_ratio": 0.374,
    "axis": "not stated in the paper (the calf's pitch inertia; knee axis or the calf's own centre of mass)",
    "baseline": "the KAIST Hound's calf with its original cylindrical foot (another leg than the one designed here)",
}
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
    collision: CollisionSpheres
    """The collision spheres along the cap's arc."""

    @property
    def mass_ratio(self) -> float:
        """Calf + foot mass, new / original [-]."""
        return self.new.calf_foot_mass / self.original.calf_foot_mass

    @property
    def inertia_ratio(self) -> float:
        """Calf + foot pitch inertia about the knee axis, new / original [-]."""
        return self.new.knee_pitch_inertia / self.original.knee_pitch_inertia

    @property
    def com_inertia_ratio(self) -> float:
        """Calf + foot pitch inertia about its own centre of mass, new / original [-]."""
        return self.new.com_pitch_inertia / self.original.com_pitch_inertia

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
    collision_tolerance: float = 1e-4,
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
        collision_tolerance: Largest sagittal dip of the collision spheres below the cap [m].
    """
    from hound_id.foot.leg import load_leg

    if not 0.5 <= mesh_resolution_deg <= 10:  # 0.5 deg is already ~300k faces and 0.002 % in mass
        raise SpecError(f"--mesh-resolution: found {mesh_resolution_deg:g} deg, expected 0.5 to 10 deg")
    mount = read_foot(leg, foot_link)
    if not (math.isfinite(collision_tolerance) and 0 < collision_tolerance <= 0.005):
        raise SpecError(
            f"--collision-tolerance: found {collision_tolerance * 1e3:g} mm, expected more than 0 and at most 5 mm"
        )
    design = optimise_foot(mount, requirements)
    collision = collision_spheres(design.geometry, collision_tolerance, requirements.roll)
    original = leg_properties(
        load_leg(leg), hip_joint=mount.hip_joint, knee_joint=mount.knee_joint, knee_angle=knee_angle
    )
    g = design.geometry
    text = _patched(mount, design, requirements, collision, None)
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
        collision=collision,
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
        "com_inertia_ratio": report.com_inertia_ratio,
        "ratios": ratios(report),
        "radius": g.radius,
        "coverage_deg": [math.degrees(g.low), math.degrees(g.high)],
        "constraints": {c.name: c.to_dict() for c in d.constraints},
        "binding": binding(d),
        "strength": strength_summary(report),
        "collision": report.collision.to_dict(),
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
            "fastener": req.fastener.to_dict() if req.fastener is not None else None,
            "friction": req.friction,
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


#: Why each constraint binds when it does (an active constraint is where the lightest foot stops).
WHY_BINDING = {
    "coverage_touchdown": "the cap ends where the stance needs it on the touchdown side: more cap is more mass",
    "coverage_liftoff": "the cap ends where the stance needs it on the liftoff side: more cap is more mass",
    "hertz_pressure": "the smallest sphere the contact pressure allows: a smaller sphere is lighter",
    "hertz_depth": "the thinnest wall below the Hertz shear depth rule",
    "wall_thickness": "the thinnest wall the process makes",
    "leg_length": "an equality: the knee-to-ground height at nominal contact is kept",
    "leg_length_stance": "the knee-to-ground height over the arc is at its tolerance",
    "lateral_coverage": "the narrowest cap that covers the roll angle",
    "boss_seat_front": "the cap is as short as the boss seat allows (touchdown side)",
    "boss_seat_back": "the cap is as short as the boss seat allows (liftoff side)",
    "boss_width": "the cap is as narrow as the boss and its rim allow",
    "boss_length": "the shortest boss allowed",
    "boss_wall": "the thinnest boss the bolt's wall allows",
    "thread_engagement": "the shortest boss the thread engagement allows",
    "boss_stress": "the thinnest boss that carries the contact force's moment at the mount: a thinner one is lighter",
    "shell_bending": "the thinnest wall that carries the load locally without yield",
    "shell_root_touchdown": "the lightest cap section that carries a touchdown-end contact to the boss without yield",
    "shell_root_liftoff": "the lightest cap section that carries a liftoff-end contact to the boss without yield",
    "shell_edge_touchdown": "the cap ends one characteristic length past the stance's touchdown contacts",
    "shell_edge_liftoff": "the cap ends one characteristic length past the stance's liftoff contacts",
    "max_radius": "the sphere is as large as the packaging allows",
}


def binding(design: FootDesign) -> dict[str, str]:
    """The active constraints at the optimum (margin within the tolerance of the limit) and why they bind."""
    from hound_id.foot.optimise import TOLERANCE

    out = {}
    for c in design.constraints:
        scale = max(abs(c.limit), abs(c.value), 1e-9)
        if c.satisfied and abs(c.margin) <= 10 * TOLERANCE * scale:
            out[c.name] = WHY_BINDING.get(c.name, "at its limit")
    return out


def ratios(report: FootReport) -> dict[str, Any]:
    """The new / original ratios of the calf + foot, each with its axis and baseline."""
    base = f"the same leg ({Path(report.mount.path).name}) with its original foot, Pinocchio"
    return {
        "mass": {"value": report.mass_ratio, "axis": None, "baseline": base, "paper": PAPER["mass_ratio"]},
        "knee_axis_inertia": {
            "value": report.inertia_ratio,
            "axis": "pitch (y), about the knee axis",
            "baseline": base,
            "paper": PAPER["inertia_ratio"],
        },
        "com_pitch_inertia": {
            "value": report.com_inertia_ratio,
            "axis": "pitch (y), about the calf + foot's own centre of mass",
            "baseline": base,
            "paper": PAPER["inertia_ratio"],
        },
        "paper_note": "the paper's 0.380 / 0.374 are its own leg against its own cylindrical foot and it does not "
        "state the axis of the inertia: compare orders of magnitude, not digits",
    }


def strength_summary(report: FootReport) -> dict[str, Any]:
    """The stress checks at the peak ground force: stress, allowed, margin, formula and validity."""
    from hound_id.foot.material import contact_radius, effective_modulus
    from hound_id.foot.strength import characteristic_length

    g, req, angles = report.design.geometry, report.requirements, report.angles
    by_name = {c.name: c for c in report.design.constraints}
    l_char = characteristic_length(g.radius, g.thickness, req.material.poisson)
    # the stance's own extreme contacts (the arc without its margin) to the cap's free edges
    to_edge = min(g.radius * (angles.low + angles.margin - g.low), g.radius * (g.high - (angles.high - angles.margin)))
    formulas = {
        "shell_bending": "Reissner shallow spherical shell under a load on a small circle = Westergaard's interior "
        "formula for a plate on an elastic foundation (Timoshenko & Woinowsky-Krieger sec. 57): sigma = 3 (1 + nu) F "
        "/ (2 pi t^2) (ln(l / b) + ln 2 + 1/2 - gamma), l = (R^2 t^2 / (12 (1 - nu^2)))^(1/4), b Westergaard's "
        "equivalent radius of the Hertz contact circle",
        "shell_root_touchdown": "the cap as a curved cantilever from the boss seat: statics-exact resultant on the "
        "cut through the centre at the seat angle, Winkler-Bach curved-beam stress N/A + M (r_n - s)/(A e s) "
        "(Roark 7th ed. sec. 9.1) on the band section",
        "boss_stress": "hollow circular section at the mount plane: N/A + M r_b / I (beam flexure)",
    }
    formulas["shell_root_liftoff"] = formulas["shell_root_touchdown"]
    short = {"shell_bending": "Reissner/Westergaard shell under the load", "boss_stress": "beam flexure at the mount",
             "shell_root_touchdown": "Winkler-Bach curved beam at the boss seat"}  # fmt: skip
    short["shell_root_liftoff"] = short["shell_root_touchdown"]
    checks = {}
    for name, formula in formulas.items():
        c = by_name[name]
        checks[name] = {"stress": c.value, "allowed": c.limit, "margin": c.margin, "margin_ratio": c.limit / c.value,
                        "model": short[name], "formula": formula}  # fmt: skip
    checks["shell_bending"]["validity"] = {
        "t_over_R": g.thickness / g.radius,
        "thin_shell": g.thickness / g.radius <= 0.1,
        "characteristic_length": l_char,
        "load_radius": contact_radius(req.peak_force, g.radius, effective_modulus(req.material, req.ground)),
        "stance_edge_distance_over_l": to_edge / l_char,
        "note": "valid for t/R <= 0.1 and a load about l or more from the free edges (the shell_edge constraints "
        "keep the stance's contacts there) and from the boss; with a thicker wall the Hertz checks govern",
    }
    return {
        "peak_force": req.peak_force,
        "friction": req.friction,
        "allowed_stress": req.allowed_stress,
        "allowed_meaning": f"yield {req.material.yield_strength / 1e6:.0f} MPa / safety {req.safety:g}",
        "load_case": "the peak ground force along the ground normal at every contact angle of the arc (margin "
        "included), with a tangential force friction x peak on top (the gait log has no forces)",
        "checks": checks,
        "not_checked": "the bolted joint (preload, bolt stress, joint opening), shear lag beside the boss, fatigue; "
        "use FEA for the final part",
    }


def _patched(
    mount: FootMount, design: FootDesign, req: FootRequirements, collision: CollisionSpheres, out_dir: Path | None
) -> str:
    g = design.geometry
    return patched_urdf(
        mount,
        design.properties,
        mesh_filename=STL_NAME,
        spheres=collision.spheres,
        comment=(
            f"foot by hound-id ({SCHEMA}): spherical cap R={g.radius * 1e3:.2f} mm, t={g.thickness * 1e3:.2f} mm, "
            f"W={g.width * 1e3:.2f} mm, {math.degrees(g.low):.1f} to {math.degrees(g.high):.1f} deg, "
            f"boss r={g.boss_radius * 1e3:.2f} mm bored {g.bore_radius * 1e3:.2f} mm, {req.material.name}; collision: "
            f"{len(collision.spheres)} spheres on the cap's arc"
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
        urdf = _patched(report.mount, report.design, report.requirements, report.collision, out)  # paths from out
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
