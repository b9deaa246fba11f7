"""The ``foot`` verb: a leg and its contact arc in; the leg as it is, or the lightest spherical-cap foot, out.

The options are grouped as the command's are: where the contact angles come from
(:class:`ContactOptions`), what the foot must withstand (:class:`RequirementOptions`) and the
rest (:class:`FootOptions`). Their texts and degrees are what a user types; :func:`run_foot`
checks and converts them once (to SI), computes the leg summary or the design, and writes
nothing; :func:`write_outputs` writes the foot files and the plot. The command line and
``hound-id demo`` call these and only render.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hound_id import io
from hound_id.errors import SpecError

if TYPE_CHECKING:
    from hound_id.foot.angles import ContactAngles
    from hound_id.foot.design import FootReport
    from hound_id.foot.optimise import FootRequirements


@dataclass(frozen=True)
class ContactOptions:
    """Where the contact arc comes from: given angles, or a gait log (the sample run by default)."""

    angles: str | None = None
    """``ATTACK,DETACH`` calf pitch [deg], e.g. ``-30,25`` (instead of a gait log)."""
    gait: Path | None = None
    """Gait log CSV/Parquet (None: the sample running log)."""
    legs: str | None = None
    """Legs of the gait log to use, comma-separated (None: all)."""
    margin: float = 5.0
    """Margin added to both ends of the contact arc [deg]."""


@dataclass(frozen=True)
class RequirementOptions:
    """What the foot must withstand and fit, as typed (lengths and forces with units, angles in degrees)."""

    material: str = "aluminium_7075_t6"
    """Foot material: a name or a YAML file."""
    ground: str = "concrete"
    """Ground material: a name or a YAML file."""
    grf: str = "1500 N"
    """Peak ground reaction force on one foot, with a unit."""
    safety: float = 1.5
    """Safety factor on the Hertz yield pressure [-]."""
    roll: float = 10.0
    """Roll angle the cap must also cover [deg]."""
    boss_radius: str | None = None
    """Fix the mounting boss radius, with a unit (None: optimised)."""
    bolt: str = "M4"
    """Bolt tapped into the boss: ``M2`` to ``M12`` (ISO coarse) or ``none`` for a solid boss."""
    boss_wall: str | None = None
    """Wall around the bolt's major diameter, with a unit (None: 0.5 d)."""
    thread_engagement: str | None = None
    """Thread engagement the boss must give, with a unit (None: 2 d)."""
    friction: float = 0.6
    """Tangential over normal ground force at the peak, for the strength checks [-]."""
    min_boss_length: str = "10 mm"
    """Shortest boss, with a unit."""
    max_radius: str | None = None
    """Largest sphere radius, with a unit (None: no limit)."""
    radius: str | None = None
    """Fix the sphere radius, with a unit (None: optimised)."""
    mass_weight: float = 0.0
    """Weight of foot mass x leg length^2 in the cost [-]."""
    nominal_angle: float = 0.0
    """Calf pitch where the leg length is kept [deg]."""
    length_tolerance: str = "5 mm"
    """Largest leg-length change over the contact arc, with a unit."""


@dataclass(frozen=True)
class FootOptions:
    """What ``hound-id foot`` is asked."""

    optimise: bool = False
    """Design the lightest spherical-cap foot (False: summarise the leg as it is)."""
    leg: Path | None = None
    """Leg URDF (None: the sample Hound-like leg)."""
    contact: ContactOptions = field(default_factory=ContactOptions)
    """Where the contact arc comes from."""
    requirements: RequirementOptions = field(default_factory=RequirementOptions)
    """What the foot must withstand."""
    knee_angle: float = -70.0
    """Knee angle of the nominal pose [deg]."""
    foot_link: str = "foot"
    """Name of the foot link in the URDF."""
    robot: Path | None = None
    """Robot YAML, for the knee rotor's reflected inertia."""
    robot_knee: str = "RR_KFE"
    """The knee joint's name in ``robot``."""
    mesh_resolution: float = 2.0
    """Angular step of the STL mesh [deg], 0.5 to 10."""
    collision_tolerance: str = "0.1 mm"
    """Largest dip of the collision spheres below the cap between neighbours, with a unit."""
    out: Path | None = None
    """Folder for foot.stl, the patched URDF and foot.json (needs ``optimise``)."""
    plot: Path | None = None
    """PNG of the design (needs ``optimise``)."""


@dataclass(frozen=True, eq=False)
class FootRun:
    """What :func:`run_foot` found: the leg's summary, or the optimised foot's report."""

    options: FootOptions
    """The options it ran with."""
    leg: Path
    """The leg URDF used."""
    angles: ContactAngles
    """The contact arc, margin included."""
    requirements: FootRequirements
    """The requirements, SI."""
    reflected_knee_inertia: float | None
    """Knee rotor inertia seen at the knee [kg m^2], with ``robot``."""
    summary: dict[str, Any] | None = None
    """The leg as it is (``hound-id/foot-leg/1``), without ``optimise``."""
    report: FootReport | None = None
    """The optimised foot, with ``optimise``."""


def _length(text: str | None, option: str) -> float | None:
    from hound_id.units import to_si

    if text is None:
        return None
    value = to_si(text, "length", field=option)
    if not 0 < value < 1.0:
        raise SpecError(
            f"{option}: found {text!r} = {value:g} m, expected more than 0 and less than 1 m; write the unit, "
            "e.g. '10 mm'"
        )
    return value


def contact_angles(contact: ContactOptions, leg: Path | None) -> ContactAngles:
    """The contact arc from given angles or a gait log (the sample run unless ``leg`` is the user's own).

    Args:
        contact: Where the angles come from.
        leg: The user's leg URDF, if any (the sample log belongs to the sample leg only).
    """
    from hound_id.foot.angles import gait_angles, given_angles
    from hound_id.samples import samples_dir

    angles, gait, legs, margin = contact.angles, contact.gait, contact.legs, contact.margin
    if angles is not None and gait is not None:
        raise SpecError("foot: give --angles ATTACK,DETACH or --gait LOG, not both")
    if leg is not None and angles is None and gait is None:
        raise SpecError(
            f"foot: --leg {leg} needs --angles ATTACK,DETACH or --gait LOG (the sample running log belongs to the "
            "sample leg)"
        )
    if legs is not None and angles is not None:
        raise SpecError("foot: --legs picks legs of a gait log; it has no meaning with --angles")
    if angles is not None:
        parts = [p.strip() for p in angles.split(",")]
        try:
            attack, detach = (float(p) for p in parts)
        except ValueError:
            raise SpecError(
                f"--angles: found {angles!r}, expected two numbers in degrees, ATTACK,DETACH, e.g. -30,25"
            ) from None
        return given_angles(attack, detach, margin)
    path = gait if gait is not None else samples_dir() / "gait" / "hound_running.csv"
    leg_list = [s.strip() for s in legs.split(",") if s.strip()] if legs is not None else None
    if leg_list is not None and len(set(leg_list)) != len(leg_list):
        twice = sorted({name for name in leg_list if leg_list.count(name) > 1})
        raise SpecError(f"--legs: found {legs!r}, which names {', '.join(twice)} twice; name each leg once")
    return gait_angles(path, leg_list, margin)


def requirements_of(contact: ContactAngles, r: RequirementOptions) -> FootRequirements:
    """The requirements, SI, checked: each option out of its range is named in one line."""
    from hound_id.foot.material import GROUNDS, load_material
    from hound_id.foot.optimise import FootRequirements
    from hound_id.foot.strength import fastener
    from hound_id.units import to_si

    safety, roll, mass_weight, nominal_angle = r.safety, r.roll, r.mass_weight, r.nominal_angle
    if not (math.isfinite(r.friction) and 0.0 <= r.friction <= 2.0):
        raise SpecError(f"--friction: found {r.friction:g}, expected a friction coefficient from 0 to 2 (0.6 default)")
    if not all(math.isfinite(v) for v in (safety, roll, mass_weight, nominal_angle)) or mass_weight < 0:
        raise SpecError("foot: --safety, --roll, --mass-weight (>= 0) and --nominal-angle must be finite numbers")
    if not 1.0 <= safety <= 10.0:
        raise SpecError(f"--safety: found {safety:g}, expected a safety factor from 1 to 10 (1.5 is usual)")
    if not 0.0 <= roll < 45.0:
        raise SpecError(f"--roll: found {roll:g} deg, expected 0 to 45 deg")
    if abs(nominal_angle) >= 60:
        raise SpecError(f"--nominal-angle: found {nominal_angle:g} deg, expected a calf pitch within +-60 deg")
    peak_force = to_si(r.grf, "force", field="--grf")
    if not 0.0 < peak_force <= 1e5:
        raise SpecError(f"--grf: found {r.grf!r}, expected a positive peak force up to 100 kN (e.g. '1.5 kN')")
    return FootRequirements(
        low=contact.low,
        high=contact.high,
        material=load_material(r.material),
        ground=load_material(r.ground, GROUNDS, "--ground"),
        peak_force=peak_force,
        safety=safety,
        roll=math.radians(roll),
        boss_radius=_length(r.boss_radius, "--boss-radius"),
        fastener=fastener(
            r.bolt, _length(r.boss_wall, "--boss-wall"), _length(r.thread_engagement, "--thread-engagement")
        ),
        friction=r.friction,
        min_boss_length=_length(r.min_boss_length, "--min-boss-length") or 0.0,
        nominal_angle=math.radians(nominal_angle),
        max_radius=_length(r.max_radius, "--max-radius"),
        radius=_length(r.radius, "--radius"),
        mass_weight=mass_weight,
        length_tolerance=_length(r.length_tolerance, "--length-tolerance") or 0.0,
        margin=contact.margin,
    )


def run_foot(options: FootOptions = FootOptions()) -> FootRun:
    """Summarise a leg, or (``options.optimise``) design its lightest spherical-cap foot; writes nothing.

    Every input is checked before the work, in the order the command line names them: the
    outputs, the knee angle, the contact arc, the robot, the requirements.

    Raises:
        HoundIdError: A bad input, or a foot no design can satisfy.
    """
    from hound_id.samples import samples_dir

    plot, out = options.plot, options.out
    if plot is not None and out is not None and plot.parent.resolve() == out.resolve():
        if plot.suffix.lower() != ".png":  # the folder is made by --out
            raise SpecError(f"{plot}: plot files end in .png; found '{plot.suffix or '(no suffix)'}'")
    else:
        io.check_output(plot, (".png",), "plot")
    if not options.optimise and (out is not None or plot is not None):
        raise SpecError("foot: --out and --plot need --optimise (they write the new foot)")
    io.check_folder(out)
    leg_path = options.leg if options.leg is not None else samples_dir() / "legs" / "hound_leg.urdf"
    knee_angle = options.knee_angle
    if not (math.isfinite(knee_angle) and abs(knee_angle) <= 180):
        raise SpecError(f"--knee-angle: found {knee_angle} deg, expected a finite angle within +-180 deg")
    contact = contact_angles(options.contact, options.leg)
    reflected = None
    if options.robot is not None:
        from hound_id.mor.robot import load_robot

        reflected = load_robot(options.robot).reflected_inertia(options.robot_knee)
    req = requirements_of(contact, options.requirements)
    if not options.optimise:
        from hound_id.foot.design import leg_summary

        summary = leg_summary(leg_path, contact, req, foot_link=options.foot_link,
                              knee_angle=math.radians(knee_angle), reflected_knee_inertia=reflected)  # fmt: skip
        return FootRun(options, leg_path, contact, req, reflected, summary=summary)
    from hound_id.foot.design import design_foot

    tolerance = _length(options.collision_tolerance, "--collision-tolerance") or 0.0
    report = design_foot(leg_path, contact, req, foot_link=options.foot_link, knee_angle=math.radians(knee_angle),
                         reflected_knee_inertia=reflected, mesh_resolution_deg=options.mesh_resolution,
                         collision_tolerance=tolerance)  # fmt: skip
    return FootRun(options, leg_path, contact, req, reflected, report=report)


def write_outputs(run: FootRun, dpi: int = 120) -> dict[str, str]:
    """Write the foot files into ``options.out`` (all or nothing), then the plot; the written paths by kind.

    Args:
        run: What :func:`run_foot` returned.
        dpi: Resolution of the PNG [dots per inch].
    """
    if run.report is None:
        return {}
    from hound_id.foot.design import write_foot

    plot, out = run.options.plot, run.options.out
    files = write_foot(run.report, out) if out is not None else {}
    if plot is not None:
        from hound_id.foot.plot import plot_foot

        fig = plot_foot(run.report)
        io.check_output(plot, (".png",), "plot")
        io.write_png(fig, plot, dpi)
        files["plot"] = str(plot)
    return files


def foot_data(run: FootRun, files: dict[str, str] | None = None) -> dict[str, Any]:
    """The JSON of a run: ``hound-id/foot-leg/1`` for the leg, ``hound-id/foot/2`` with the written ``files``."""
    if run.report is None:
        assert run.summary is not None
        return run.summary
    from hound_id.foot.design import foot_json

    return foot_json(run.report, files)


__all__ = [
    "ContactOptions",
    "FootOptions",
    "FootRun",
    "RequirementOptions",
    "contact_angles",
    "foot_data",
    "requirements_of",
    "run_foot",
    "write_outputs",
]
