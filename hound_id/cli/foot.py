"""``hound-id foot``: the leg's foot as it is, and ``--optimise`` for the lightest spherical cap."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Optional

import typer
from rich.table import Table

from hound_id.cli._render import console, print_json
from hound_id.foot.run import ContactOptions, FootOptions, RequirementOptions

_LENGTH_HELP = "with a unit, e.g. '10 mm' (a plain number is metres)"
_C, _R, _F = ContactOptions(), RequirementOptions(), FootOptions()


def foot(
    optimise: bool = typer.Option(False, "--optimise", "--optimize", help="Design the lightest spherical-cap foot."),
    leg: Optional[Path] = typer.Option(None, "--leg", help="Leg URDF (default: the sample Hound-like leg)."),
    angles: Optional[str] = typer.Option(None, "--angles", help="ATTACK,DETACH calf pitch in degrees, e.g. -30,25."),
    gait: Optional[Path] = typer.Option(None, "--gait", help="Gait log CSV/Parquet (default: the sample run)."),
    legs: Optional[str] = typer.Option(None, "--legs", help="Legs of the gait log to use, e.g. RR,RL (default all)."),
    margin: float = typer.Option(_C.margin, "--margin", help="Margin added to both ends of the contact arc [deg]."),
    material: str = typer.Option(_R.material, "--material", help="Foot material name or YAML file."),
    ground: str = typer.Option(_R.ground, "--ground", help="Ground: concrete, steel or a material YAML file."),
    grf: str = typer.Option(_R.grf, "--grf", help="Peak ground reaction force on one foot, e.g. '1.5 kN'."),
    safety: float = typer.Option(_R.safety, "--safety", help="Safety factor on the Hertz yield pressure."),
    roll: float = typer.Option(_R.roll, "--roll", help="Roll angle the cap must also cover [deg]."),
    boss_radius: Optional[str] = typer.Option(
        None, "--boss-radius", help=f"Fix the mounting boss radius (default: optimised), {_LENGTH_HELP}."
    ),
    bolt: str = typer.Option(
        _R.bolt, "--bolt", help="Bolt tapped into the boss, M2 to M12 (ISO coarse), or none for a solid boss."
    ),
    boss_wall: Optional[str] = typer.Option(
        None, "--boss-wall", help=f"Wall around the bolt's major diameter (default 0.5 d), {_LENGTH_HELP}."
    ),
    thread_engagement: Optional[str] = typer.Option(
        None, "--thread-engagement", help=f"Thread engagement the boss must give (default 2 d), {_LENGTH_HELP}."
    ),
    friction: float = typer.Option(
        _R.friction, "--friction", help="Tangential / normal ground force at the peak, for the stress checks."
    ),
    min_boss_length: str = typer.Option(
        _R.min_boss_length, "--min-boss-length", help=f"Shortest boss, {_LENGTH_HELP}."
    ),
    max_radius: Optional[str] = typer.Option(None, "--max-radius", help=f"Largest sphere radius, {_LENGTH_HELP}."),
    radius: Optional[str] = typer.Option(None, "--radius", help=f"Fix the sphere radius, {_LENGTH_HELP}."),
    mass_weight: float = typer.Option(
        _R.mass_weight, "--mass-weight", help="Weight of foot mass x leg length^2 in the cost."
    ),
    nominal_angle: float = typer.Option(
        _R.nominal_angle, "--nominal-angle", help="Calf pitch where leg length is kept [deg]."
    ),
    length_tolerance: str = typer.Option(
        _R.length_tolerance,
        "--length-tolerance",
        help=f"Largest leg-length change over the contact arc, {_LENGTH_HELP}.",
    ),
    knee_angle: float = typer.Option(_F.knee_angle, "--knee-angle", help="Knee angle of the nominal pose [deg]."),
    foot_link: str = typer.Option(_F.foot_link, "--foot-link", help="Name of the foot link in the URDF."),
    robot: Optional[Path] = typer.Option(None, "--robot", help="Robot YAML, for the knee rotor's reflected inertia."),
    robot_knee: str = typer.Option(_F.robot_knee, "--robot-knee", help="The knee joint's name in --robot."),
    mesh_resolution: float = typer.Option(
        _F.mesh_resolution, "--mesh-resolution", help="Angular step of the STL mesh, 0.5 to 10 [deg]."
    ),
    collision_tolerance: str = typer.Option(
        _F.collision_tolerance,
        "--collision-tolerance",
        help=f"Largest dip of the collision spheres below the cap, {_LENGTH_HELP}.",
    ),
    out: Optional[Path] = typer.Option(None, "--out", help="Folder for foot.stl, the patched URDF and foot.json."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="PNG: sagittal section, contact arc, ratios."),
    json_out: bool = typer.Option(False, "--json", help="Print JSON (schema hound-id/foot/2 or foot-leg/1)."),
) -> None:
    """The leg's mass properties and contact angles; with --optimise, the lightest spherical-cap foot."""
    options = FootOptions(
        optimise=optimise,
        leg=leg,
        contact=ContactOptions(angles=angles, gait=gait, legs=legs, margin=margin),
        requirements=RequirementOptions(
            material=material,
            ground=ground,
            grf=grf,
            safety=safety,
            roll=roll,
            boss_radius=boss_radius,
            bolt=bolt,
            boss_wall=boss_wall,
            thread_engagement=thread_engagement,
            friction=friction,
            min_boss_length=min_boss_length,
            max_radius=max_radius,
            radius=radius,
            mass_weight=mass_weight,
            nominal_angle=nominal_angle,
            length_tolerance=length_tolerance,
        ),
        knee_angle=knee_angle,
        foot_link=foot_link,
        robot=robot,
        robot_knee=robot_knee,
        mesh_resolution=mesh_resolution,
        collision_tolerance=collision_tolerance,
        out=out,
        plot=plot,
    )
    _run_and_render(options, json_out)


def _run_and_render(options: FootOptions, json_out: bool) -> None:
    """Run the verb (with a status line while it optimises), write its files and render its result."""
    from hound_id.foot.run import foot_data, run_foot, write_outputs

    if options.optimise:
        with console.status("optimising the foot (casadi/IPOPT), building the mesh, checking with Pinocchio"):
            run = run_foot(options)
    else:
        run = run_foot(options)
    data = foot_data(run, write_outputs(run))
    if json_out:
        print_json(data)
    elif run.report is None:
        _render_summary(data)
    else:
        _render_design(data)


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
    table = Table(title="Optimised foot: new / original, calf + foot of this leg (Pinocchio)", title_justify="left")
    table.add_column("")
    table.add_column("this design", justify="right")
    table.add_column("paper (KAIST Hound, its own leg; axis not stated)", justify="right")
    table.add_row("mass ratio", f"{d['mass_ratio']:.3f}", f"{d['paper']['mass_ratio']:.3f}")
    table.add_row("pitch inertia ratio, about the knee axis", f"{d['inertia_ratio']:.3f}",
                  f"{d['paper']['inertia_ratio']:.3f}")  # fmt: skip
    table.add_row("pitch inertia ratio, about its own centre of mass", f"{d['com_inertia_ratio']:.3f}",
                  f"{d['paper']['inertia_ratio']:.3f}")  # fmt: skip
    table.add_row("hip inertia ratio", f"{d['hip_inertia_ratio']:.3f}", "")
    if d["inertia_ratio_with_rotor"] is not None:
        table.add_row("knee inertia ratio with the rotor", f"{d['inertia_ratio_with_rotor']:.3f}", "")
    console.print(table)
    fastener = d["requirements"]["fastener"]
    console.print(
        f"cap: R = {g['radius'] * 1e3:.2f} mm, wall {g['thickness'] * 1e3:.2f} mm, width {g['width'] * 1e3:.2f} mm, "
        f"{d['coverage_deg'][0]:.1f} to {d['coverage_deg'][1]:.1f} deg, centre {g['centre_z'] * 1e3:+.2f} mm above "
        f"the mount; boss r = {g['boss_radius'] * 1e3:.2f} mm"
        + (f", bored {2 * g['bore_radius'] * 1e3:.2f} mm for {fastener['name']}" if fastener else " (solid)")
        + f"; foot {d['foot']['closed_form']['mass'] * 1e3:.1f} g of "
        f"{d['requirements']['material']['name']} (was {d['original_foot']['mass'] * 1e3:.0f} g)",
        highlight=False,
    )
    console.print(f"paper: {d['ratios']['paper_note']}", highlight=False)
    ct = Table(title="Constraints", title_justify="left")
    for col in ("constraint", "value", "limit", "margin", "ok"):
        ct.add_column(col, justify="left" if col == "constraint" else "right")
    for name, c in d["constraints"].items():
        fmt = _CONSTRAINT_FORMAT[c["unit"]]
        margin = fmt(abs(c["margin"])) if c["kind"] == "==" else fmt(c["margin"])
        ct.add_row(name, fmt(c["value"]), f"{c['kind']} {fmt(c['limit'])}", margin,
                   "yes" if c["satisfied"] else "[red]NO[/red]")  # fmt: skip
    console.print(ct)
    st = d["strength"]
    title = (f"Stress at the peak ground force {st['peak_force']:g} N, friction {st['friction']:g} "
             f"(allowed {st['allowed_stress'] / 1e6:.0f} MPa = {st['allowed_meaning']})")  # fmt: skip
    stable = Table(title=title, title_justify="left")
    for col in ("check", "stress", "margin", "allowed / stress", "model (formula in the JSON)"):
        stable.add_column(col, justify="left" if col == "check" or col.startswith("model") else "right")
    for name, c in st["checks"].items():
        stable.add_row(name, f"{c['stress'] / 1e6:.1f} MPa", f"{c['margin'] / 1e6:.1f} MPa", f"{c['margin_ratio']:.2f}",
                       c["model"])  # fmt: skip
    console.print(stable)
    v = st["checks"]["shell_bending"]["validity"]
    console.print(
        f"shell_bending validity: t/R = {v['t_over_R']:.3f} "
        f"({'thin' if v['thin_shell'] else 'not thin, over 0.1: outside the formula'}), "
        f"stance contacts {v['stance_edge_distance_over_l']:.2f} l from the cap's edges (l = "
        f"{v['characteristic_length'] * 1e3:.2f} mm; the interior formula needs >= 1 l)",
        highlight=False,
    )
    console.print("binding: " + "; ".join(f"{k} ({why})" for k, why in d["binding"].items()), highlight=False)
    col = d["collision"]
    console.print(
        f"collision: {col['count']} spheres r = {col['sphere_radius'] * 1e3:.2f} mm on the cap's arc; dip below the "
        f"cap <= {col['sagittal_deviation'] * 1e3:.3f} mm over its angles, {col['roll_deviation'] * 1e3:.2f} mm at the "
        f"roll angle, {col['edge_deviation'] * 1e3:.2f} mm at its lateral edge; "
        f"{math.degrees(col['overreach_angle']):.0f} deg past its ends the spheres reach "
        f"{col['overreach'] * 1e3:.2f} mm beyond the rim (a full sphere {col['full_sphere_overreach'] * 1e3:.2f} mm)",
        highlight=False,
    )
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
