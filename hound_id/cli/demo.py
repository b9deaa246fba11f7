"""``hound-id demo``: every capability on the shipped samples."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from hound_id.cli._render import console, err_console, print_json


def demo(
    out: Path = typer.Option(Path("hound-id-demo"), "--out", help="Folder for the plots and JSON."),
    json_out: bool = typer.Option(False, "--json", help="Print the summary as JSON (schema hound-id/demo/1)."),
) -> None:
    """Run every part of hound-id on data/samples and write plots and JSON into a folder."""
    from hound_id.demo import STEPS, run_demo, summary_dict

    columns = (
        TextColumn("{task.description}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(),
    )
    with Progress(*columns, console=err_console, transient=True, disable=not err_console.is_terminal) as progress:
        task = progress.add_task("demo", total=len(STEPS))
        done = 0

        def on_step(name: str) -> None:
            nonlocal done
            progress.update(task, description=name, completed=done)
            done += 1

        results = run_demo(out, on_step=on_step)
        progress.update(task, completed=done)
    if json_out:
        print_json(summary_dict(out, results))
        return
    console.print(f"[bold]hound-id demo[/bold]: outputs in {out}/", highlight=False)
    for r in results:
        console.print(f"  [bold]{r.name}[/bold]: {r.summary}", highlight=False)
        console.print(f"    files: {', '.join(r.files)}", highlight=False)
