"""``hound-id demo``: run every part that exists on the shipped samples.

Each step writes its JSON and plots into the output folder and returns one line of
summary. Later capabilities add steps to :data:`STEPS`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hound_id import io
from hound_id.samples import samples_dir

SCHEMA = "hound-id/demo/1"


@dataclass(frozen=True)
class StepResult:
    """Outcome of one demo step."""

    name: str
    """Step name."""
    summary: str
    """One line for the user."""
    files: tuple[str, ...]
    """Files written (relative to the output folder)."""
    figures: dict[str, float]
    """Headline numbers, SI."""


#: Resolution of the demo's plots [dots per inch].
DPI = 110


def step_motor_regions(out: Path) -> StepResult:
    """Operating region of every sample motor: JSON and plot."""
    from hound_id.mor.run import motor_regions

    files, parts, figures = [], [], {}
    for spec_file in sorted((samples_dir() / "motors").glob("*.yaml")):
        run = motor_regions(spec_file)
        spec, region = run.spec, run.region
        io.write_json(out / f"mor_{spec.name}.json", run.report())  # what `mor --spec --json` prints
        io.write_png(run.figure(), out / f"mor_{spec.name}.png", DPI)
        files += [f"mor_{spec.name}.json", f"mor_{spec.name}.png"]
        parts.append(f"{spec.name}: {region.torque_limit:.3g} N m up to {region.corner_speed:.4g} rad/s")
        figures[f"{spec.name}.corner_speed"] = region.corner_speed
    return StepResult("motor regions", "; ".join(parts), tuple(files), figures)


def step_robot_regions(out: Path) -> StepResult:
    """Joint-space regions, URDF boxes and the saturation study of every sample robot."""
    from hound_id.mor.run import robot_regions_of
    from hound_id.mor.saturate_log import box_study
    from hound_id.mor.saturation import saturation_for

    files, parts, figures = [], [], {}
    for robot_file in sorted((samples_dir() / "robots").glob("*.yaml")):
        run = robot_regions_of(robot_file)
        robot, regions = run.robot, run.regions
        sat = saturation_for(robot)
        inner = np.array([[j.inner_box.effort, j.inner_box.velocity] for j in regions.joints])
        outer = np.array([[j.outer_box.effort, j.outer_box.velocity] for j in regions.joints])
        study = box_study(sat, inner, outer, samples=20_000, seed=0)
        data = regions.to_dict()
        data["box_study"] = study.to_dict()
        io.write_json(out / f"mor_robot_{robot.name}.json", data)
        io.write_png(run.figure(), out / f"mor_robot_{robot.name}.png", DPI)
        files += [f"mor_robot_{robot.name}.json", f"mor_robot_{robot.name}.png"]
        parts.append(
            f"{robot.name}: {study.outer_infeasible:.1%} of commands inside the URDF outer box are infeasible "
            f"(mean clip {study.outer_mean_clip:.3g} N m); {study.inner_infeasible:.1%} inside the inner box"
        )
        figures[f"{robot.name}.outer_infeasible"] = study.outer_infeasible
        figures[f"{robot.name}.inner_infeasible"] = study.inner_infeasible
    return StepResult("robot regions and saturation", "; ".join(parts), tuple(files), figures)


def step_saturate_log(out: Path) -> StepResult:
    """Saturate the sample command log as training does; plot it against each motor's region."""
    from hound_id.mor.run import saturate_commands

    run = saturate_commands(
        samples_dir() / "commands" / "hound_like_running.csv", samples_dir() / "robots" / "hound_like.yaml", plot=True
    )
    summary = run.summary.to_dict()
    io.write_json(out / "saturate_hound_like_running.json", summary)
    io.write_png(run.figure(), out / "saturate_hound_like_running.png", DPI)
    worst = max(summary["joints"], key=lambda j: j["max_clip"])
    return StepResult(
        "saturate a command log",
        f"{summary['violating_fraction']:.1%} of {summary['rows']} commands outside the MOR; "
        f"largest clip {worst['max_clip']:.3g} N m at {worst['joint']}",
        ("saturate_hound_like_running.json", "saturate_hound_like_running.png"),
        {"violating_fraction": summary["violating_fraction"]},
    )


#: Knee angle of the demo's nominal pose [rad] (``design_foot``'s default; the command line's is -70 deg).
DEMO_KNEE_ANGLE = -1.2

#: Column mapping of the sample dyno log (a rig's own export names).
DYNO_COLUMNS = {
    "time": "timestamp",
    "current": "iq",
    "torque": "adc_torque",
    "velocity": "speed",
    "position": "angle",
    "temperature": "winding_temp",
    "bus_voltage": "vbus",
}


def step_fit_current(out: Path) -> StepResult:
    """Fit the sample dyno log with --auto: the ladder of effects, the plot, the fitted motor."""
    from hound_id.dyno.current.run import FitCurrentOptions, fit_current, write_outputs

    options = FitCurrentOptions(
        auto=True,
        columns=DYNO_COLUMNS,
        spec=samples_dir() / "motors" / "hound_ilm85.yaml",
        plot=out / "fit_ilm85_dyno.png",
        out=out / "hound_ilm85_fitted.yaml",
    )
    result = fit_current(samples_dir() / "dyno" / "ilm85_dyno.csv", options)
    io.write_json(out / "fit_ilm85_dyno.json", result.report_json())  # what `fit-current --json` prints
    write_outputs(result, dpi=DPI)
    fit, diagnosis, peak = result.fit, result.diagnosis, result.peak
    rungs = " -> ".join(f"{s.added or '+'.join(s.model)} {s.fit.rmse_test:.3g}" for s in result.ladder or ())
    kt = fit.parameters["kt"]
    return StepResult(
        "fit a dyno log",
        f"held-out RMSE [N m]: {rungs}; noise floor {diagnosis.noise_floor:.3g} N m; "
        f"Kt {kt.value:.4g} +- {kt.stderr:.1g} N m/A; {peak.note}",
        ("fit_ilm85_dyno.json", "fit_ilm85_dyno.png", "hound_ilm85_fitted.yaml"),
        {
            "rmse_test": fit.rmse_test,
            "noise_floor": diagnosis.noise_floor,
            "kt": kt.value,
            "peak_torque": float(peak.torque or 0.0),
        },
    )


def step_fleet(out: Path) -> StepResult:
    """Fit the sample fleet of twelve actuators on a local Dask cluster and flag the faulty ones."""
    import json

    from hound_id.dyno.current.run import FitCurrentOptions
    from hound_id.dyno.fleet.run import FleetOptions, fleet, write_outputs

    folder = samples_dir() / "fleet"
    options = FleetOptions(csv=out / "fleet.csv", plot=out / "fleet.png")
    result = fleet([folder], FitCurrentOptions(auto=True), options)
    io.write_json(out / "fleet.json", result.to_dict())  # what `fleet --json` prints
    write_outputs(result, dpi=DPI)
    report = result.report
    planted = json.loads((folder / "fleet_truth.json").read_text())["faults"]
    flagged = sorted({f.actuator for f in report.flags})
    found = sum(name in flagged for name in planted)
    readings = "; ".join(f"{f.actuator}: {f.reading.split(':')[0]}" for f in report.flags)
    return StepResult(
        "compare a fleet",
        f"{len(report.fitted)} of {len(report.actuators)} actuators fitted with {'+'.join(report.model)}; "
        f"flagged {', '.join(flagged) or 'none'} ({readings}); {found} of {len(planted)} planted faults found, "
        f"{len(set(flagged) - set(planted))} healthy actuators flagged",
        ("fleet.json", "fleet.csv", "fleet.png"),
        {
            "flagged": float(len(flagged)),
            "planted_found": float(found),
            "healthy_flagged": float(len(set(flagged) - set(planted))),
            "seconds_per_log": float(result.to_dict()["engine"]["seconds_per_log"] or 0.0),
        },
    )


def step_foot(out: Path) -> StepResult:
    """Optimise the sample leg's foot for the sample running log: STL, URDF, JSON, plot."""
    from hound_id.foot.design import PAPER
    from hound_id.foot.run import FootOptions, run_foot, write_outputs

    options = FootOptions(
        optimise=True,
        knee_angle=math.degrees(DEMO_KNEE_ANGLE),
        robot=samples_dir() / "robots" / "hound_like.yaml",
        out=out / "foot",
        plot=out / "foot" / "foot.png",
    )
    run = run_foot(options)
    write_outputs(run, dpi=DPI)
    report = run.report
    assert report is not None  # optimise=True
    g = report.design.geometry
    return StepResult(
        "optimise the foot",
        f"mass ratio {report.mass_ratio:.3f} (paper {PAPER['mass_ratio']:.3f}), knee pitch inertia ratio "
        f"{report.inertia_ratio:.3f} (paper {PAPER['inertia_ratio']:.3f}); cap R {g.radius * 1e3:.1f} mm, wall "
        f"{g.thickness * 1e3:.2f} mm, {math.degrees(g.low):.1f} to {math.degrees(g.high):.1f} deg; "
        f"{sum(c.satisfied for c in report.design.constraints)}/{len(report.design.constraints)} constraints hold; "
        f"STL watertight: {report.mesh_check.watertight}",
        ("foot/foot.json", "foot/foot.stl", "foot/hound_leg_light_foot.urdf", "foot/foot.png"),
        {
            "mass_ratio": report.mass_ratio,
            "inertia_ratio": report.inertia_ratio,
            "radius": g.radius,
            "foot_mass": report.design.properties.mass,
        },
    )


def step_compare(out: Path) -> StepResult:
    """Compare the sample sagging-supply log with the ILM85's region and name what is missing."""
    from hound_id.dyno.envelope.run import CompareOptions, compare_envelope, write_outputs
    from hound_id.mor.region import measured_region, operating_region
    from hound_id.mor.spec_sheet import load_motor_spec

    options = CompareOptions(
        columns={"velocity": "speed", "current": "iq", "temperature": "winding_temp", "bus_voltage": "vbus"},
        auto=True,
        plot=out / "compare_ilm85_sag.png",
        out=out / "hound_ilm85_envelope.yaml",
    )
    result = compare_envelope(
        samples_dir() / "motors" / "hound_ilm85.yaml", samples_dir() / "envelope" / "ilm85_sag_log.csv", options
    )
    data = result.data
    io.write_json(out / "compare_ilm85_sag.json", data)
    write_outputs(result, dpi=DPI)
    added = ", ".join(f"{k} = {v:.4g}" for k, v in data["model"].items()) or "nothing"
    measured = load_motor_spec(out / "hound_ilm85_envelope.yaml")  # the region the envelope leaves
    corner, sheet_corner = measured_region(measured).corner_speed, operating_region(measured).corner_speed
    return StepResult(
        "compare a log with the region",
        f"{data['outside_fraction']:.1%} of the samples outside the region; added {added}; envelope error "
        f"{data['envelope_rmse']['model']:.3g} -> {data['envelope_rmse']['with_added']:.3g} N m "
        f"(noise level {data['noise_level']:.2g} N m); measured corner speed {corner:.4g} rad/s "
        f"(spec sheet {sheet_corner:.4g})",
        ("compare_ilm85_sag.json", "compare_ilm85_sag.png", "hound_ilm85_envelope.yaml"),
        {
            "envelope_rmse_model": data["envelope_rmse"]["model"],
            "envelope_rmse_with_added": data["envelope_rmse"]["with_added"],
            "noise_level": data["noise_level"],
            "corner_speed_measured": corner,
            "corner_speed_spec_sheet": sheet_corner,
        },
    )


def step_export(out: Path) -> StepResult:
    """Export every format of the sample robot with the fitted motor and the new foot; run the MuJoCo model."""
    from hound_id.export.mujoco import rollout_check
    from hound_id.export.run import ExportOptions, run_export, write_outputs

    fit, foot = out / "hound_ilm85_fitted.yaml", out / "foot" / "foot.json"
    options = ExportOptions("all", (fit,) if fit.is_file() else (), foot if foot.is_file() else None)
    result = run_export(samples_dir() / "robots" / "hound_like.yaml", out / "export", options)
    write_outputs(result)
    stats = rollout_check(out / "export" / "hound_like.xml", out / "export" / "hound_like_bundle.yaml", seconds=1.0)
    stats["straight_line_gap"] = _straight_line_gap(fit if fit.is_file() else None)
    # formats share files (Isaac Lab, Genesis and Newton read the bundle JSON): each file once
    files = tuple(dict.fromkeys(str(Path(f).relative_to(out)) for name in result.formats for f in result.files(name)))
    io.write_json(out / "export" / "export.json", result.to_json() | {"mujoco_check": stats})
    return StepResult(
        "export to trainers",
        f"{', '.join(result.formats)} for {result.robot} "
        f"(fitted: {', '.join(result.fitted_motors) or 'none'}, "
        f"foot: {'optimised' if result.foot else 'original'}); MuJoCo ran {stats['steps']} steps with "
        f"{stats['clipped_fraction']:.0%} of the commands past the region: realised motor torques within "
        f"{stats['max_difference']:.2g} N m of hound_id.runtime, {stats['max_outside']:.2g} N m outside the region "
        f"(dcmotor's straight voltage lines against the curved edges: up to {stats['straight_line_gap']:.2g} N m; "
        "--mujoco-actuator motor with the runtime is exact)",
        (*files, "export/export.json"),
        {k: float(v) for k, v in stats.items()},
    )


def _straight_line_gap(fit: Path | None) -> float:
    """The most a straight-line dcmotor passes the exported motor's curved region [N m, motor side]."""
    from hound_id.mor.region import operating_region
    from hound_id.mor.region_report import straight_gap
    from hound_id.mor.spec_sheet import load_motor_spec

    spec = load_motor_spec(fit if fit is not None else samples_dir() / "motors" / "hound_ilm85.yaml")
    return straight_gap(operating_region(spec))[0]


STEPS: tuple[Callable[[Path], StepResult], ...] = (
    step_motor_regions,
    step_robot_regions,
    step_saturate_log,
    step_fit_current,
    step_fleet,
    step_compare,
    step_foot,
    step_export,
)


def run_demo(out: Path, on_step: Callable[[str], None] | None = None) -> list[StepResult]:
    """Run every demo step into ``out`` (created if missing) and write ``summary.json``."""
    io.make_folder(out)
    results = []
    for step in STEPS:
        if on_step is not None:
            on_step((step.__doc__ or step.__name__).splitlines()[0])
        results.append(step(out))
    io.write_json(out / "summary.json", summary_dict(out, results))
    return results


def summary_dict(out: Path, results: list[StepResult]) -> dict[str, object]:
    """JSON-ready summary, schema ``hound-id/demo/1``."""
    return {
        "schema": SCHEMA,
        "out": str(out),
        "steps": [
            {"name": r.name, "summary": r.summary, "files": list(r.files), "figures": r.figures} for r in results
        ],
    }
