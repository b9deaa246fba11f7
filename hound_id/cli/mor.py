"""``hound-id mor``: operating regions of a motor or of every joint of a robot."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, Optional

import typer
from rich.table import Table

from hound_id.cli._render import console, print_json, save_figure, warn
from hound_id.errors import HoundIdError
from hound_id.io import check_output
from hound_id.units import RPM_PER_RAD_S

if TYPE_CHECKING:
    from hound_id.dyno.envelope.run import CompareOptions, EnvelopeComparison
    from hound_id.mor.run import MotorRegions


def mor(
    spec: Optional[Path] = typer.Option(None, "--spec", help="Motor spec YAML: the motor-side region."),
    robot: Optional[Path] = typer.Option(None, "--robot", help="Robot YAML: joint-space regions and URDF boxes."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="Write a PNG plot of the region(s) to this file."),
    compare: Optional[Path] = typer.Option(
        None, "--compare", metavar="LOG", help="Torque-speed log (CSV/Parquet) to compare with --spec's region."
    ),
    columns: Optional[str] = typer.Option(None, "--columns", help="With --compare: torque=tau_m,velocity=w,..."),
    units: Optional[str] = typer.Option(None, "--units", help="With --compare: velocity=rpm,torque=mN*m,..."),
    joint: Optional[str] = typer.Option(None, "--joint", help="With --compare and --robot: the log's joint."),
    add: Optional[list[str]] = typer.Option(None, "--add", metavar="EFFECT", help="With --compare: add an effect."),
    auto: bool = typer.Option(False, "--auto", help="With --compare: add significant effects until none is left."),
    out: Optional[Path] = typer.Option(
        None, "--out", help="With --compare: write a motor spec YAML with the measured envelope (for saturate/export)."
    ),
    bus_range: Optional[str] = typer.Option(
        None,
        "--bus-range",
        metavar="LOW,HIGH",
        help="With --spec: the battery's lowest and highest bus voltage, e.g. '66 V,84 V' (instead of the spec's "
        "bus_voltage_range).",
    ),
    json_out: bool = typer.Option(
        False, "--json", help="Print JSON (schema hound-id/mor/3, mor-robot/1 or mor-compare/2)."
    ),
) -> None:
    """Motor operating regions (--spec) and joint-space regions and boxes (--robot).

    With --compare LOG, the region against measured data and the effects that explain the difference."""
    if bus_range is not None and (spec is None or compare is not None):
        raise HoundIdError("mor: --bus-range goes with --spec MOTOR.yaml (without --compare)")
    if compare is not None:
        if spec is None:
            raise HoundIdError(
                "mor --compare: give --spec MOTOR.yaml (the motor whose region the log is compared with)"
            )
        from hound_id.dyno.envelope.run import CompareOptions

        options = CompareOptions(columns, units, robot, joint, tuple(add or ()), auto, plot, out)
        _mor_compare(spec, compare, options, json_out)
        return
    if columns or units or joint or add or auto or out:
        raise HoundIdError("mor: --columns, --units, --joint, --add, --auto and --out go with --compare LOG")
    if (spec is None) == (robot is None):
        raise HoundIdError("mor: give exactly one of --spec MOTOR.yaml or --robot ROBOT.yaml")
    if spec is not None:
        _mor_spec(spec, plot, json_out, bus_range)
    else:
        assert robot is not None
        _mor_robot(robot, plot, json_out)


def _mor_compare(spec_path: Path, log_path: Path, options: CompareOptions, json_out: bool) -> None:
    from hound_id.dyno.envelope.run import compare_envelope, write_outputs

    with console.status("comparing the log with the operating region"):
        result = compare_envelope(spec_path, log_path, options)
    write_outputs(result)
    plot, out = options.plot, options.out
    data = {**result.data, "plot": str(plot) if plot else None, "out": str(out) if out else None}
    if json_out:
        print_json(data)
        return
    _print_compare_head(result, data)
    _print_ladder(data)
    _print_compare_coverage(result, data)
    _print_compare_verdict(result, data)
    if plot is not None:
        console.print(f"plot written to {plot}", highlight=False)
    if out is not None:
        console.print(f"motor spec with the measured envelope written to {out}", highlight=False)


def _print_compare_head(result: EnvelopeComparison, data: dict[str, Any]) -> None:
    """The samples outside the region, the bins at the limit and how the limit was detected (``mor --compare``)."""
    spec, log = result.spec, result.log
    outside = data["outside"]
    console.print(
        f"[bold]{spec.name}[/bold] against {log.source} ({log.side}, {log.n} samples): "
        f"{outside['fraction']:.1%} of the samples outside the region (by more than {outside['threshold']:.3g} N m"
        + (
            f"; up to {outside['max_excess']:.3g} N m, quadrants {outside['by_quadrant']})"
            if outside["samples"]
            else ")"
        ),
        highlight=False,
    )
    if result.ignored_warning:
        warn(result.ignored_warning)
    console.print(
        f"{data['bins_at_limit']} speed bins show the motor at its limit ({data['limit_method']}); envelope error "
        f"{data['envelope_rmse']['model']:.3g} N m against the spec sheet, noise level {data['noise_level']:.2g} N m",
        highlight=False,
    )
    detection = data["limit_detection"]
    if detection:
        console.print(
            f"at the limit where the lagged command passes the torque by more than "
            f"{detection['threshold']['upper']:.3g} N m (upper) / {detection['threshold']['lower']:.3g} N m (lower) "
            f"for {detection['persist_rows']} rows: lag {detection['lag_rows']:.1f} rows, "
            f"gain {detection['gain']:.3f}, bias {detection['bias']:+.3g} N m, "
            f"noise {detection['noise']:.2g} N m inside the region",
            highlight=False,
        )


def _print_ladder(data: dict[str, Any]) -> None:
    """The effects added step by step and the table of candidates on top of the model (``mor --compare``)."""
    for step in data["ladder"][1:]:
        params = ", ".join(f"{k} = {v:.4g}" for k, v in step["model"].items())
        console.print(f"+ {step['added']}: envelope error {step['envelope_rmse']:.3g} N m ({params})", highlight=False)
        if step["why"]:
            console.print(f"  why: {step['why']['reason']} (p = {step['why']['p_value']:.1e})", highlight=False)
        if step["walls_found_again"]:
            console.print(
                f"  with it in, the walls were found again ({step['bins']} bins) and every parameter refitted",
                highlight=False,
            )
    table = Table(title="Candidate effects on top of the model", title_justify="left")
    for col in ("effect", "parameter", "explained", "error after", "significant"):
        table.add_column(col, justify="left" if col == "effect" else "right")
    for sug in data["suggestions"]:
        table.add_row(sug["effect"], f"{sug['value']:.4g} {sug['unit']}", f"{sug['explained']:.1%}",
                      f"{sug['rmse']:.3g} N m", "yes" if sug["significant"] else "no")  # fmt: skip
    console.print(table)


def _print_compare_coverage(result: EnvelopeComparison, data: dict[str, Any]) -> None:
    """The motor speeds at which the log shows the limits, and a note when it stops short of speed."""
    cov = data["coverage"]
    console.print(
        "the log shows the limits at motor speeds "
        + "; ".join(f"{k} edge {v[0]:.4g} to {v[1]:.4g} rad/s" for k, v in cov.items() if v)
        + (f"; {data['rows_dropped']} rows with NaN or inf dropped" if data["rows_dropped"] else ""),
        highlight=False,
    )
    if not result.covers_speed:
        forward, backward = result.motoring_speeds
        console.print(
            f"note: the log shows the motoring edges to {forward:.4g} rad/s forward and {backward:.4g} rad/s backward "
            f"(no-load speed {result.spec.no_load_speed:.4g} rad/s): effects that act at speed (bus_sag, inductance, "
            "thermal_resistance) show little or nothing below that, so the verdict holds only there",
            highlight=False,
        )


def _print_compare_verdict(result: EnvelopeComparison, data: dict[str, Any]) -> None:
    """The flags, the effects not needed, and what to add or check next (``mor --compare``)."""
    final = data["envelope_rmse"]["with_added"]
    for text in result.flag_warnings:
        warn(text)
    for item in data["unneeded"]:
        name = item["effect"]
        console.print(f"not needed: {name}: {item['reason']}; leave out --add {name}", highlight=False)
    suggestion = result.suggestion
    if suggestion is not None:
        console.print(f"suggested: --add {suggestion.effect}: {suggestion.reason}", highlight=False)
    elif result.verdict == "explained":
        console.print("no missing effect is significant: the model explains the envelope", highlight=False)
    else:
        console.print(
            f"no candidate effect is significant, but the model does not explain the log: envelope error "
            f"{final:.3g} N m ({final / max(data['noise_level'], 1e-12):.1f}x the noise level), "
            f"{data['outside_fraction']:.1%} of the samples past the region. Check the units"
            + (", log torque_cmd" if data["limit_method"] == "wall" else "")
            + ", log the channels the effects need (temperature, bus_voltage), or suspect an effect hound-id does "
            "not model",
            highlight=False,
        )
    if any(k == "thermal_resistance" for k in data["model"]):
        console.print(
            "note: thermal_resistance enters --out at 25 degC (the polyline has no temperature)", highlight=False
        )


#: A region with more vertices than this (curved edges) has them in --json only.
VERTICES_SHOWN = 12


def _mor_spec(path: Path, plot: Path | None, json_out: bool, bus_range: str | None = None) -> None:
    from hound_id.mor.run import motor_regions

    check_output(plot, (".png",), "plot")
    run = motor_regions(path, bus_range)
    spec = run.spec
    for w in run.warnings:
        warn(w)
    if plot is not None:
        save_figure(run.figure(), plot)
    if json_out:
        data = run.report()
        data["plot"] = str(plot) if plot else None
        print_json(data)
        return
    console.print(_spec_table(run))
    _print_curve(path, run)
    speed = run.at_speed
    if speed is not None:
        _print_at_speed(spec, speed)
    if run.heat is not None:
        _print_heat(spec, run.heat)
    _print_shape(run)
    if plot is not None:
        console.print(f"plot written to {plot}", highlight=False)


def _spec_table(run: MotorRegions) -> Table:
    """The ``mor --spec`` table: constants, limits, speeds, inner box (the sheet's beside a measured envelope)."""
    spec, sheet, region, measured = run.spec, run.sheet, run.region, run.measured
    title = f"Operating region of {spec.name} (motor side" + (", measured envelope)" if measured else ")")
    table = Table(title=title, title_justify="left")
    table.add_column("quantity")
    table.add_column("SI", justify="right")
    table.add_column("also", justify="right")
    if measured:
        table.add_column("spec sheet", justify="right")

    def row(name: str, value: str, also: str, sheet_value: str = "") -> tuple[str, ...]:
        return (name, value, also, sheet_value) if measured else (name, value, also)

    rows = [
        row("torque constant Kt", f"{spec.kt:.4g} N m/A", ""),
        row("speed constant Kv", f"{spec.kv:.4g} rad/s/V", f"{spec.kv * RPM_PER_RAD_S:.4g} rpm/V"),
        row("resistance R (model)", f"{spec.resistance:.4g} ohm", ""),
        row("bus voltage", f"{spec.bus_voltage:.4g} V", ""),
        row(
            "torque limit",
            f"{region.torque_limit:.4g} N m",
            "driver-limited" if run.bindings[0].limit == "current" else "peak torque",
        ),
        row("current at the torque limit", f"{region.limit_x / spec.current_curve.kt:.4g} A", ""),
        row("stall torque Kt V/R (linear)", f"{region.stall_torque:.4g} N m", ""),
    ]
    for name, a, b in (
        ("no-load speed", region.no_load_speed, sheet.no_load_speed),
        ("corner speed", region.corner_speed, sheet.corner_speed),
        ("overspeed", region.overspeed, sheet.overspeed),
    ):
        rows.append(row(name, f"{a:.4g} rad/s", f"{a * RPM_PER_RAD_S:.0f} rpm", f"{b:.4g} rad/s"))
    rows.append(
        row(
            "inner box",
            f"{region.inner_box[0]:.4g} N m, {region.inner_box[1]:.4g} rad/s",
            "",
            f"{sheet.inner_box[0]:.4g} N m, {sheet.inner_box[1]:.4g} rad/s",
        )
    )
    rows.append(row("back-EMF damping Kt/(R Kv)", f"{region.back_emf_damping:.4g} N m s/rad", ""))
    if region.max_speed is not None:
        rows.append(
            row("rated max speed", f"{region.max_speed:.4g} rad/s", f"{region.max_speed * RPM_PER_RAD_S:.0f} rpm")
        )
    for r in rows:
        table.add_row(*r)
    return table


def _print_curve(path: Path, run: MotorRegions) -> None:
    """The dyno fit the spec carries, its current-torque curve and which limit binds at which speed."""
    spec = run.spec
    if spec.fit is not None:
        model = "+".join(spec.fit.model)
        rmse = spec.fit.rmse_test
        console.print(
            f"Kt and peak torque from the dyno fit in {path} (model {model}"
            + (f", held-out RMSE {rmse:.3g} N m)" if isinstance(rmse, float) else ")"),
            highlight=False,
        )
    curve = spec.current_curve
    console.print(
        f"current-torque curve: {curve.source or curve.form}"
        + (f", k = {curve.k_sat:.4g} N m/A^2" if curve.form == "quadratic" else ""),
        highlight=False,
    )
    console.print("which limit binds (motor side, omega >= 0; the region is point-symmetric):", highlight=False)
    for binding in run.bindings:
        w0, w1 = binding.speeds
        console.print(f"  {w0:.4g} to {w1:.4g} rad/s: {binding.limit}: {binding.detail}", highlight=False)


def _print_shape(run: MotorRegions) -> None:
    """What a linear Kt would promise, the convex cut, the vertices and the measured envelope (``mor --spec``)."""
    spec, region, measured = run.spec, run.region, run.measured
    lk = run.linear_kt
    if lk.largest > 0:
        linear, curved = (f"{t:.4g}" for t in lk.torque_limit)
        limit = f"{linear} N m either way" if linear == curved else f"{linear} instead of {curved} N m"
        console.print(
            f"a linear-Kt region (tau = Kt i) would promise up to {lk.largest:.3g} N m ({lk.share:.1%}) more (largest "
            f"at {lk.at_speed:.4g} rad/s): torque limit {limit}, "
            f"corner speed {lk.corner_speed[0]:.4g} instead of {lk.corner_speed[1]:.4g} rad/s",
            highlight=False,
        )
    if region.convexity_loss > 1e-6 * region.torque_limit and not measured:
        console.print(
            f"the region's half-spaces are a convex cut inside its curved edges, short of them by up to "
            f"{region.convexity_loss:.3g} N m (past the no-load speed); the saturation uses the exact edges",
            highlight=False,
        )
    if len(region.vertices) <= VERTICES_SHOWN:
        verts = ", ".join(f"({t:.3g} N m, {w:.4g} rad/s)" for t, w in region.vertices)
        console.print(f"vertices (counter-clockwise): {verts}", highlight=False)
    else:
        console.print(f"{len(region.vertices)} vertices along the curved edges (--json or --plot)", highlight=False)
    if measured and spec.envelope:
        env = spec.envelope
        effects = ", ".join(f"{k} = {v:.4g}" for k, v in env.effects.items()) or "none"
        console.print(
            f"the region is the measured envelope ({effects}; {len(env.speeds)}-point polyline from "
            f"{env.source}), the spec sheet's beyond its speeds; the saturation, the "
            f"bundle, the runtime and mor --robot use it. Its half-spaces are a convex cut inside the polyline, "
            f"short of it by up to {region.convexity_loss:.3g} N m",
            highlight=False,
        )


def _print_heat(spec: Any, h: Any) -> None:
    """The thermal lines of ``mor --spec`` (:class:`hound_id.mor.heat.Heat`)."""
    th = h.thermal
    console.print(
        f"heat: winding to ambient {th.resistance:.4g} K/W, time constant {th.time_constant:.4g} s, ambient "
        f"{th.ambient:.4g} degC, winding limit {th.winding_limit:.4g} degC (the drive derates from "
        f"{th.derate_start:.4g} degC); R {th.alpha_resistance * 100:+.3g} %/K, Kt {th.alpha_kt * 100:+.3g} %/K "
        f"({th.alpha_kt_source or 'spec'})",
        highlight=False,
    )
    runaway = "" if math.isinf(th.runaway_current) else f"; held above {th.runaway_current:.3g} A it runs away"
    amps = "A (peak phase)" if spec.commutation == "foc" else "A"
    if h.derates:
        reach = (
            f"would reach {th.winding_limit:.4g} degC in {h.time_to_limit:.3g} s"
            if math.isfinite(h.time_to_limit)
            else f"would settle below {th.winding_limit:.4g} degC"
        )
        held = (
            f"  at the drive's {h.drive_limit:.4g} {amps} the winding reaches {th.derate_start:.4g} degC in "
            f"{h.time_to_derate:.3g} s (and {reach} without the derating)"
        )
    else:
        held = (
            f"  at the drive's {h.drive_limit:.4g} {amps} the winding settles at {h.continuous_temperature:.4g} degC, "
            f"below the derating ({th.derate_start:.4g} degC): the drive's limit is its continuous current"
        )
    console.print(held + runaway, highlight=False)
    w, c = h.warm, h.continuous
    console.print(
        f"  warm ({th.derate_start:.4g} degC, full current): torque limit {h.warm_torque:.4g} N m, corner speed "
        f"{w.corner_speed:.4g} rad/s, no-load speed {w.no_load_speed:.4g} rad/s (the flux is weaker)",
        highlight=False,
    )
    where = (
        f"at {h.continuous_temperature:.4g} degC under the derating ({h.limit_current:.4g} A at the limit without it)"
        if h.derates
        else f"(the drive's limit; the winding settles at {h.continuous_temperature:.4g} degC)"
    )
    console.print(
        f"  continuous: {h.continuous_current:.4g} {amps} {where}: torque limit {h.continuous_torque:.4g} N m, inner "
        f"box {c.inner_box[0]:.4g} N m to {c.inner_box[1]:.4g} rad/s",
        highlight=False,
    )


def _print_at_speed(spec: Any, speed: Any) -> None:
    """The drive model's and the battery's lines of ``mor --spec`` (:class:`hound_id.mor.region_report.AtSpeed`)."""
    d, dc = speed.drive, speed.dc_law
    drive = spec.drive
    if drive is not None:
        parts = []
        if drive.inductance_phase is not None:
            stated = "" if drive.convention == "phase" else f" ({spec.inductance * 1e6:.4g} uH line to line)"
            parts.append(f"{drive.inductance_phase * 1e6:.4g} uH per phase{stated}, {drive.pole_pairs} pole pairs")
        parts.append("field weakening" if drive.field_weakening else "i_d = 0 (no field weakening)")
        console.print(f"at speed, the drive's dq model: {', '.join(parts)}", highlight=False)
        worst = speed.largest_cost
        console.print(
            f"  corner speed {d.corner_speed:.4g} rad/s (DC law {dc.corner_speed:.4g}, "
            f"{(d.corner_speed / dc.corner_speed - 1):+.1%}); motoring reaches {d.no_load_speed:.4g} rad/s (DC law "
            f"{dc.no_load_speed:.4g}); control is lost past {d.overspeed:.4g} rad/s (DC law {dc.overspeed:.4g}), the "
            "diode bridge's braking from there",
            highlight=False,
        )
        if worst[0] > 0:
            console.print(
                f"  the reactance costs up to {worst[0]:.3g} N m of motoring torque ({worst[0] / worst[2]:.1%}) at "
                f"{worst[1]:.4g} rad/s; per speed in --json (at_speed.motoring_edge)",
                highlight=False,
            )
        if speed.without_weakening is not None:
            p = speed.without_weakening
            console.print(
                f"  without field weakening: motoring to {p.no_load_speed:.4g} rad/s, control to {p.overspeed:.4g}",
                highlight=False,
            )
            emf = d.no_load_speed / spec.kv  # the line-to-line back-EMF amplitude at the motoring reach
            if emf > spec.bus_voltage:
                console.print(
                    f"  at {d.no_load_speed:.4g} rad/s the back-EMF is {emf:.4g} V against the "
                    f"{spec.bus_voltage:.4g} V bus: a drive fault there regenerates uncontrolled into the bus; "
                    "check the drive's and the battery's voltage ratings",
                    highlight=False,
                )
    if speed.battery:
        low, high = speed.battery
        console.print(
            f"battery {low.bus_voltage:.4g}-{high.bus_voltage:.4g} V: corner speed {low.corner_speed:.4g}-"
            f"{high.corner_speed:.4g} rad/s, motoring to {low.no_load_speed:.4g}-{high.no_load_speed:.4g} rad/s; "
            f"inner box at {low.bus_voltage:.4g} V: {low.inner_box[0]:.4g} N m to {low.inner_box[1]:.4g} rad/s "
            "(the box every charge holds)",
            highlight=False,
        )


def _mor_robot(path: Path, plot: Path | None, json_out: bool) -> None:
    from hound_id.mor.run import robot_regions_of

    check_output(plot, (".png",), "plot")

    def show(warnings: tuple[str, ...]) -> None:
        for w in warnings:
            warn(w)

    run = robot_regions_of(path, on_warnings=show)
    robot, regions = run.robot, run.regions
    if plot is not None:
        save_figure(run.figure(), plot)
    if json_out:
        data = regions.to_dict()
        data["plot"] = str(plot) if plot else None
        print_json(data)
        return
    table = Table(title=f"Joint-space limits of {robot.name} (joint side)", title_justify="left")
    for col in ("joint", "transmission", "inner N m", "inner rad/s", "outer N m", "outer rad/s"):
        table.add_column(col, justify="left" if col in ("joint", "transmission") else "right")
    for jr in regions.joints:
        kind = jr.transmission + ("*" if jr.coupled else "")
        table.add_row(
            jr.joint,
            kind,
            f"{jr.inner_box.effort:.4g}",
            f"{jr.inner_box.velocity:.4g}",
            f"{jr.outer_box.effort:.4g}",
            f"{jr.outer_box.velocity:.4g}",
        )
    console.print(table)
    console.print(
        "* coupled. inner box: every command inside is feasible whatever the coupled joints do within theirs; "
        "outer box: bounds of what is reachable at all.",
        highlight=False,
    )
    low = sorted({v for jr in regions.joints for v, m in zip(jr.inner_box_bus_voltage, jr.motors, strict=True)
                  if v != robot.motor_specs[m].bus_voltage})  # fmt: skip
    if low:
        console.print(
            f"inner boxes at the battery's lowest bus voltage ({', '.join(f'{v:.4g} V' for v in low)}) and 20 degC: "
            "every charge holds them; outer boxes and regions at the nominal bus",
            highlight=False,
        )
    measured = sorted({s.name for s in robot.motor_specs.values() if s.envelope})
    if measured:
        console.print(
            f"{', '.join(measured)}: the measured envelope in the spec bounds these limits, not the spec sheet "
            "(coupled groups: a convex cut inside it)",
            highlight=False,
        )
    if plot is not None:
        console.print(f"plot written to {plot}", highlight=False)


def saturate(
    commands: Path = typer.Argument(
        ..., metavar="LOG", help="CSV or Parquet with tau_<joint> [N m] and qd_<joint> [rad/s] columns."
    ),
    robot: Path = typer.Option(..., "--robot", help="Robot YAML whose motors and transmissions apply."),
    out: Optional[Path] = typer.Option(None, "--out", help="Write the table with tau_sat_<joint> columns added."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="PNG: each motor's commands against its region."),
    json_out: bool = typer.Option(False, "--json", help="Print JSON (schema hound-id/saturate/2)."),
) -> None:
    """Saturate a log of joint torque commands exactly as the method does in training.

    The log is streamed: memory stays bounded whatever its length."""
    from hound_id.mor.run import saturate_commands
    from hound_id.tables import SUFFIXES

    check_output(out, SUFFIXES, "table", inputs=(commands, robot))
    check_output(plot, (".png",), "plot", inputs=(commands, robot))
    run = saturate_commands(commands, robot, out=out, plot=plot is not None)
    log = run.summary
    figure = run.figure() if plot is not None else None
    if plot is not None and figure is not None:
        save_figure(figure, plot)
    summary = log.to_dict()
    if json_out:
        summary.update(out=str(out) if out else None, plot=str(plot) if plot else None)
        # allow_nan=False: the summary is finite by construction, and NaN/Infinity are not JSON
        sys.stdout.write(json.dumps(summary, indent=2, allow_nan=False) + "\n")
        return
    console.print(
        f"{summary['rows']} commands, {summary['violating_fraction']:.1%} outside some motor's region", highlight=False
    )
    table = Table(title="clipping per joint (joint side) and motor", title_justify="left")
    for col in ("joint", "max clip [N m]", "mean clip [N m]", "motor", "motor clipped"):
        table.add_column(col, justify="left" if col in ("joint", "motor") else "right")
    for j, m in zip(summary["joints"], summary["motors"], strict=True):
        table.add_row(
            j["joint"], f"{j['max_clip']:.3g}", f"{j['mean_clip']:.3g}", m["motor"], f"{m['clipped_fraction']:.1%}"
        )
    console.print(table)
    if summary["clip_turn"] is not None:
        _print_turn(summary["clip_turn"])
    if log.sample is not None and log.sample_step > 1:
        console.print(
            f"the plot draws one row in {log.sample_step} ({len(log.sample.tau_cmd)} of {summary['rows']}); "
            "the figures above count every row",
            highlight=False,
        )
    for path, what in ((out, "table"), (plot, "plot")):
        if path is not None:
            console.print(f"{what} written to {path}", highlight=False)


def _angles(a: dict[str, float]) -> str:
    return f"{a['median']:.3g}/{a['p95']:.3g}/{a['max']:.3g}" if a["count"] else "-"


def _grew(g: dict[str, Any], joints: list[str]) -> tuple[str, str]:
    """(joints that grew and the share of the clips, the largest growth [N m])."""
    if not g["rows"]:
        return "none", "-"
    return f"{'+'.join(j for j in joints if g['by_joint'][j])} {g['fraction']:.0%}", f"{g['max']:.3g}"


def _print_turn(turn: dict[str, Any]) -> None:
    """The direction change of the coupled clip, per coupled group (``clip_turn`` of the JSON)."""
    groups = turn["groups"]
    if not groups:
        console.print("no coupled joints: the clip only shortens each joint torque, as a per-joint clip does")
        return
    floor = turn["floor"]
    table = Table(title="direction change of the coupled clip (joint side)", title_justify="left")
    for col in ("coupled group", "clipped", "turn \\[deg] med/p95/max", "|tau| grew in", "by [N m]"):
        table.add_column(col, justify="left" if col in ("coupled group", "|tau| grew in") else "right")
    for g in groups:
        table.add_row(g["group"], f"{g['clipped_fraction']:.1%}", _angles(g["angle"]), *_grew(g["grew"], g["joints"]))
    console.print(table)
    patterns = Table(title="the same by which motors clipped", title_justify="left")
    for col in ("group: motors clipped", "rows", "turn \\[deg]", "|tau| grew in", "by [N m]"):
        patterns.add_column(col, justify="left" if col in ("group: motors clipped", "|tau| grew in") else "right")
    for g in groups:
        patterns.add_row(f"{g['group']}:", "", "", "", "")
        for p in g["by_motors"]:
            which = "all" if len(p["motors"]) == len(g["motors"]) else "+".join(p["motors"]) + " alone"
            patterns.add_row(f"  {which}", str(p["rows"]), _angles(p["angle"]), *_grew(p["grew"], g["joints"]))
    console.print(patterns)
    if turn["reference"] is not None:
        ref_table = Table(title="against a per-joint clip of the same commands", title_justify="left")
        for col in ("coupled group", "per-joint turn \\[deg]", "differs mean/max [N m]", "per-joint infeasible"):
            ref_table.add_column(col, justify="left" if col == "coupled group" else "right")
        for g in groups:
            ref = g["per_joint"]
            outside = f"{ref['outside_rows'] / max(ref['rows'], 1):.0%}"
            if ref["outside_rows"]:
                outside += f" (<= {ref['outside_max']:.3g} N m)"
            ref_table.add_row(
                g["group"],
                _angles(ref["angle"]),
                f"{ref['difference_mean']:.3g}/{ref['difference_max']:.3g}",
                outside,
            )
        console.print(ref_table)
    console.print(
        "turn: angle between the commanded and the saturated joint-torque vector of the group, over the rows in "
        f"which a motor of the group clipped (no angle for vectors under {floor:.3g} N m: "
        f"{sum(g['below_floor'] for g in groups)} clips). Each motor is clipped to its own interval and mapped back "
        "(the paper's method), so one motor's clip moves every joint it drives: a joint can grow (counted above "
        f"{floor:.3g} N m), which a per-joint clip never does."
        + (
            " Per-joint clip: each joint alone through its own gear ratio, as Isaac Lab's DCMotor (reference in the "
            "JSON); differs: |coupled - per-joint| over the group, where either clipped; infeasible: of those rows, "
            "where the per-joint torques are outside some motor's region (up to N m, motor side)."
            if turn["reference"] is not None
            else ""
        ),
        highlight=False,
    )


__all__ = ["mor", "saturate"]
