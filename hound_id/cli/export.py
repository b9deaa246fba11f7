"""``hound-id export``: the bundle, MuJoCo, URDF and Isaac Lab formats of a robot."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from hound_id.cli._render import console, print_json


def export(
    robot: Path = typer.Option(..., "--robot", help="Robot YAML (its 'urdf:' names the robot's URDF)."),
    fmt: str = typer.Option(
        "bundle", "--format", help="bundle, isaaclab, mjlab, mujoco, newton, urdf, urdf-open (comma-separated) or all."
    ),
    out: Path = typer.Option(..., "--out", help="Folder for the exported files (created if missing)."),
    fit: Optional[list[Path]] = typer.Option(
        None, "--fit", help="Fitted motor YAML from fit-current --out (repeatable)."
    ),
    foot: Optional[Path] = typer.Option(
        None, "--foot", metavar="foot.json", help="foot.json from hound-id foot --optimise."
    ),
    urdf: Optional[Path] = typer.Option(None, "--urdf", help="The robot's URDF, instead of the robot file's 'urdf:'."),
    mujoco_actuator: str = typer.Option(
        "dcmotor",
        "--mujoco-actuator",
        help="dcmotor (voltage input: MuJoCo 3.x and 4.x; ctrl = runtime.voltage), dcmotor-ff (torque input, "
        "MuJoCo >= 4.0) or motor (saturate with the runtime).",
    ),
    json_out: bool = typer.Option(False, "--json", help="Print JSON (schema hound-id/export/1)."),
) -> None:
    """Export what hound-id identified to the formats trainers read."""
    from hound_id.export.run import ExportOptions, run_export, write_outputs

    result = run_export(robot, out, ExportOptions(fmt, tuple(fit or ()), foot, urdf, mujoco_actuator))
    write_outputs(result)
    if json_out:
        print_json(result.to_json())
        return
    console.print(f"[bold]hound-id export[/bold] {result.robot}: {len(result.joints)} joints", highlight=False)
    if result.fitted_motors:
        console.print(f"fitted motors: {', '.join(result.fitted_motors)}", highlight=False)
    for name, part in result.formats.items():
        console.print(f"[bold]{name}[/bold]: {', '.join(result.files(name))}", highlight=False)
        for note in part.notes:
            console.print(f"  - {note}", highlight=False, soft_wrap=False)
