"""``hound-id foot``: the leg's foot as it is, and ``--optimise`` for the lightest spherical cap."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Optional

import typer
from rich.table import Table

from hound_id.cli._render import console, print_json, save_figure
from hound_id.errors import SpecError
from hound_id.io import check_folder, check_output

_LENGTH_HELP = "with a unit, e.g. '10 mm' (a plain number is metres)"


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


def _angles(angles: str | None, gait: Path | None, legs: str | None, margin: float, leg: Path | None) -> Any:
    from hound_id.foot.angles import gait_angles, given_angles
    from hound_id.samples import samples_dir

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


def foot(
    optimise: bool = typer.Option(False, "--optimise", "--optimize", help="Design the lightest spherical-cap foot."),
    leg: Optional[Path] = typer.Option(None, "--leg", help="Leg URDF (default: the sample Hound-like leg)."),
    angles: Optional[str] = typer.Option(None, "--angles", help="ATTACK,DETACH calf pitch in degrees, e.g. -30,25."),
    gait: Optional[Path] = typer.Option(None, "--gait", help="Gait log CSV/Parquet (default: the sample run)."),
    legs: Optional[str] = typer.Option(None, "--legs", help="Legs of the gait log to use, e.g. RR,RL (default all)."),
    margin: float = typer.Option(5.0, "--margin", help="Margin added to both ends of the contact arc [deg]."),
    material: str = typer.Option("aluminium_7075_t6", "--material", help="Foot material name or YAML file."),
    ground: str = typer.Option("concrete", "--ground", help="Ground: concrete, steel or a material YAML file."),
    grf: str = typer.Option("1500 N", "--grf", help="Peak ground reaction force on one foot, e.g. '1.5 kN'."),
    safety: float = typer.Option(1.5, "--safety", help="Safety factor on the Hertz yield pressure."),
    roll: float = typer.Option(10.0, "--roll", help="Roll angle the cap must also cover [deg]."),
    boss_radius: str = typer.Option("10 mm", "--boss-radius", help=f"Mounting boss radius, {_LENGTH_HELP}."),
    min_boss_length: str = typer.Option("10 mm", "--min-boss-length", help=f"Shortest boss, {_LENGTH_HELP}."),
    max_radius: Optional[str] = typer.Option(None, "--max-radius", help=f"Largest sphere radius, {_LENGTH_HELP}."),
    radius: Optional[str] = typer.Option(None, "--radius", help=f"Fix the sphere radius, {_LENGTH_HELP}."),
    mass_weight: float = typer.Option(0.0, "--mass-weight", help="Weight of foot mass x leg length^2 in the cost."),
    nominal_angle: float = typer.Option(0.0, "--nominal-angle", help="Calf pitch where leg length is kept [deg]."),
    length_tolerance: str = typer.Option(
        "5 mm", "--length-tolerance", help=f"Largest leg-length change over the contact arc, {_LENGTH_HELP}."
    ),
    knee_angle: float = typer.Option(-70.0, "--knee-angle", help="Knee angle of the nominal pose [deg]."),
    foot_link: str = typer.Option("foot", "--foot-link", help="Name of the foot link in the URDF."),
    robot: Optional[Path] = typer.Option(None, "--robot", help="Robot YAML, for the knee rotor's reflected inertia."),
    robot_knee: str = typer.Option("RR_KFE", "--robot-knee", help="The knee joint's name in --robot."),
    mesh_resolution: float = typer.Option(
        2.0, "--mesh-resolution", help="Angular step of the STL mesh, 0.5 to 10 [deg]."
    ),
    out: Optional[Path] = typer.Option(None, "--out", help="Folder for foot.stl, the patched URDF and foot.json."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="PNG: sagittal section, contact arc, ratios."),
    json_out: bool = typer.Option(False, "--json", help="Print JSON (schema hound-id/foot/1 or foot-leg/1)."),
) -> None:
    """The leg's mass properties and contact angles; with --optimise, the lightest spherical-cap foot."""
    from hound_id.foot.angles import ContactAngles
    from hound_id.samples import samples_dir

    if plot is not None and out is not None and plot.parent.resolve() == out.resolve():
        if plot.suffix.lower() != ".png":  # the folder is made by --out
            raise SpecError(f"{plot}: plot files end in .png; found '{plot.suffix or '(no suffix)'}'")
    else:
        check_output(plot, (".png",), "plot")
    if not optimise and (out is not None or plot is not None):
        raise SpecError("foot: --out and --plot need --optimise (they write the new foot)")
    check_folder(out)
    leg_path = leg if leg is not None else samples_dir() / "legs" / "hound_leg.urdf"
    if not (math.isfinite(knee_angle) and abs(knee_angle) <= 180):
        raise SpecError(f"--knee-angle: found {knee_angle} deg, expected a finite angle within +-180 deg")
    contact: ContactAngles = _angles(angles, gait, legs, margin, leg)
    reflected = None
    if robot is not None:
        from hound_id.mor.robot import load_robot

        reflected = load_robot(robot).reflected_inertia(robot_knee)
    req = _requirements(contact, material, ground, grf, safety, roll, boss_radius, min_boss_length, max_radius,
                        radius, mass_weight, nominal_angle, length_tolerance)  # fmt: skip
    if not optimise:
        from hound_id.foot.design import leg_summary

        summary = leg_summary(leg_path, contact, req, foot_link=foot_link, knee_angle=math.radians(knee_angle),
                              reflected_knee_inertia=reflected)  # fmt: skip
        if json_out:
            print_json(summary)
        else:
            _render_summary(summary)
        return
    from hound_id.foot.design import design_foot, foot_json, write_foot

    with console.status("optimising the foot (casadi/IPOPT), building the mesh, checking with Pinocchio"):
        report = design_foot(leg_path, contact, req, foot_link=foot_link, knee_angle=math.radians(knee_angle),
                             reflected_knee_inertia=reflected, mesh_resolution_deg=mesh_resolution)  # fmt: skip
    files = write_foot(report, out) if out is not None else {}
    if plot is not None:
        from hound_id.foot.plot import plot_foot

        save_figure(plot_foot(report), plot)
        files["plot"] = str(plot)
    data = foot_json(report, files)
    if json_out:
        print_json(data)
    else:
        _render_design(data)


def _requirements(
    contact: Any,
    material: str,
    ground: str,
    grf: str,
    safety: float,
    roll: float,
    boss_radius: str,
    min_boss_length: str,
    max_radius: str | None,
    radius: str | None,
    mass_weight: float,
    nominal_angle: float,
    length_tolerance: str,
) -> Any:
    from hound_id.foot.material import GROUNDS, load_material
    from hound_id.foot.optimise import FootRequirements
    from hound_id.units import to_si

    if not all(math.isfinite(v) for v in (safety, roll, mass_weight, nominal_angle)) or mass_weight < 0:
        raise SpecError("foot: --safety, --roll, --mass-weight (>= 0) and --nominal-angle must be finite numbers")
    if not 1.0 <= safety <= 10.0:
        raise SpecError(f"--safety: found {safety:g}, expected a safety factor from 1 to 10 (1.5 is usual)")
    if not 0.0 <= roll < 45.0:
        raise SpecError(f"--roll: found {roll:g} deg, expected 0 to 45 deg")
    if abs(nominal_angle) >= 60:
        raise SpecError(f"--nominal-angle: found {nominal_angle:g} deg, expected a calf pitch within +-60 deg")
    peak_force = to_si(grf, "force", field="--grf")
    if not 0.0 < peak_force <= 1e5:
        raise SpecError(f"--grf: found {grf!r}, expected a positive peak force up to 100 kN (e.g. '1.5 kN')")
    return FootRequirements(
        low=contact.low,
        high=contact.high,
        material=load_material(material),
        ground=load_material(ground, GROUNDS, "--ground"),
        peak_force=peak_force,
        safety=safety,
        roll=math.radians(roll),
        boss_radius=_length(boss_radius, "--boss-radius") or 0.0,
        min_boss_length=_length(min_boss_length, "--min-boss-length") or 0.0,
        nominal_angle=math.radians(nominal_angle),
        max_radius=_length(max_radius, "--max-radius"),
        radius=_length(radius, "--radius"),
        mass_weight=mass_weight,
        length_tolerance=_length(length_tolerance, "--length-tolerance") or 0.0,
    )


def _render_summary(s: dict[str, Any]) -> None:
    table = Table(title=f"Leg {s['leg']} (Pinocchio) and the contact it needs", title_justify="left")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    leg, a = s["leg_properties"], s["angles"]
    rows = [
        ("calf + foot mass", f"{leg['calf_foot_mass']:.4g} kg"),
        ("knee pitch inertia (calf + foot)", f"{leg['knee_pitch_inertia']:.4g} kg m^2"),
        (f"hip pitch inertia (knee {math.degrees(leg['knee_angle']):.0f} deg)",
         f"{leg['hip_pitch_inertia']:.4g} kg m^2"),
        ("original foot", f"{s['original_foot']['mass']:.4g} kg, {s['original_foot']['shape']} "
         f"r = {s['original_foot']['contact_radius'] * 1e3:.1f} mm"),
        ("contact angle at touchdown",
         f"{math.degrees(a['attack']):.1f} +- {math.degrees(a['attack_spread']):.1f} deg"),
        ("contact angle at liftoff", f"{math.degrees(a['detach']):.1f} +- {math.degrees(a['detach_spread']):.1f} deg"),
        ("arc to cover (with margin)", f"{math.degrees(a['low']):.1f} to {math.degrees(a['high']):.1f} deg"),
        ("angles from", f"{a['source']} ({a['strides']} stances)" if a["strides"] else "--angles"),
        ("Hertz minimum radius", f"{s['hertz_min_radius'] * 1e3:.1f} mm"),
    ]  # fmt: skip
    if s["reflected_knee_inertia"] is not None:
        rows.append(("knee rotor inertia at the knee", f"{s['reflected_knee_inertia']:.4g} kg m^2"))
    for r in rows:
        table.add_row(*r)
    console.print(table)
    console.print("Run with --optimise to design the lightest spherical-cap foot.", highlight=False)


def _render_design(d: dict[str, Any]) -> None:
    g = d["geometry"]
    table = Table(title="Optimised foot: new / original, calf + foot (Pinocchio)", title_justify="left")
    table.add_column("")
    table.add_column("this design", justify="right")
    table.add_column("paper (KAIST Hound)", justify="right")
    table.add_row("mass ratio", f"{d['mass_ratio']:.3f}", f"{d['paper']['mass_ratio']:.3f}")
    table.add_row("pitch inertia ratio (knee)", f"{d['inertia_ratio']:.3f}", f"{d['paper']['inertia_ratio']:.3f}")
    table.add_row("hip inertia ratio", f"{d['hip_inertia_ratio']:.3f}", "")
    if d["inertia_ratio_with_rotor"] is not None:
        table.add_row("knee inertia ratio with the rotor", f"{d['inertia_ratio_with_rotor']:.3f}", "")
    console.print(table)
    console.print(
        f"cap: R = {g['radius'] * 1e3:.2f} mm, wall {g['thickness'] * 1e3:.2f} mm, width {g['width'] * 1e3:.2f} mm, "
        f"{d['coverage_deg'][0]:.1f} to {d['coverage_deg'][1]:.1f} deg, centre {g['centre_z'] * 1e3:+.2f} mm above "
        f"the mount; foot {d['foot']['closed_form']['mass'] * 1e3:.1f} g of "
        f"{d['requirements']['material']['name']} (was {d['original_foot']['mass'] * 1e3:.0f} g)",
        highlight=False,
    )
    ct = Table(title="Constraints", title_justify="left")
    for col in ("constraint", "value", "limit", "margin", "ok"):
        ct.add_column(col, justify="left" if col == "constraint" else "right")
    for name, c in d["constraints"].items():
        fmt = _CONSTRAINT_FORMAT[c["unit"]]
        margin = fmt(abs(c["margin"])) if c["kind"] == "==" else fmt(c["margin"])
        ct.add_row(name, fmt(c["value"]), f"{c['kind']} {fmt(c['limit'])}", margin,
                   "yes" if c["satisfied"] else "[red]NO[/red]")  # fmt: skip
    console.print(ct)
    mc, pc = d["mesh_check"], d["pinocchio_check"]
    console.print(
        f"mesh: watertight {mc['watertight']}, {mc['faces']} faces, mass {mc['mass_error'] * 100:+.3f} %, "
        f"inertia {mc['inertia_error'] * 100:.3f} % from the closed form; Pinocchio knee inertia "
        f"{pc['knee_inertia_relative_error']:+.1e} from the closed form",
        highlight=False,
    )
    for kind, path in d["files"].items():
        console.print(f"wrote {kind}: {path}", highlight=False)


_CONSTRAINT_FORMAT = {
    "rad": lambda v: f"{math.degrees(v):.2f} deg",
    "m": lambda v: f"{v * 1e3:.3f} mm",
    "Pa": lambda v: f"{v / 1e6:.1f} MPa",
}
