"""``hound-id fleet``: fit many actuators' logs with one model, in parallel, and flag the outliers."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, Optional

import typer
from rich import box
from rich.markup import escape
from rich.table import Table

from hound_id.cli._render import console, err_console, print_json, warn
from hound_id.cli.fit_current import fit_options

if TYPE_CHECKING:
    from hound_id.dyno.fleet.analyse import ActuatorFit, FleetReport
    from hound_id.dyno.fleet.run import FleetResult

#: Beyond this many actuators the table lists only the flagged and failed ones (the CSV has all).
MAX_ROWS = 40


def fleet(
    logs: list[str] = typer.Argument(
        ..., metavar="LOG...", help="Dyno logs (CSV or Parquet), folders of them, or quoted glob patterns."
    ),
    model: str = typer.Option("linear+saturation", "--model", help="Model of every log: effects joined by '+'."),
    add: Optional[list[str]] = typer.Option(None, "--add", help="Add an effect to the model (repeatable)."),
    auto: bool = typer.Option(
        False, "--auto", help="Each log adds its significant effects; the fleet is compared on those most logs need."
    ),
    columns: Optional[str] = typer.Option(None, "--columns", help="Map columns: torque=adc_torque,current=iq,..."),
    units: Optional[str] = typer.Option(None, "--units", help="Units of columns: velocity=rpm,position=deg,..."),
    flip_torque: bool = typer.Option(False, "--flip-torque", help="Negate torque (sensors mounted reversed)."),
    auto_sign: bool = typer.Option(
        False,
        "--auto-sign",
        help="Each log's torque sign from its own slope (sensors mounted either way); stated per log.",
    ),
    window: Optional[str] = typer.Option(None, "--window", help="Fit only START:STOP seconds of every log."),
    robust: bool = typer.Option(False, "--robust", help="Huber-robust least squares."),
    whole_log: bool = typer.Option(
        False, "--whole-log", help="Each log's headline is the whole log, even where part of it disagrees."
    ),
    workers: Optional[int] = typer.Option(
        None,
        "--workers",
        help="Worker processes of the local Dask cluster (default: one per usable core; at most one per core and log).",
    ),
    scheduler: Optional[str] = typer.Option(
        None, "--scheduler", metavar="ADDRESS", help="An existing Dask scheduler (tcp://host:8786) instead."
    ),
    z: float = typer.Option(3.5, "--z", help="Outlier limit: modified z-score (robust spreads with the log's error)."),
    tolerance: Optional[str] = typer.Option(
        None, "--tolerance", help="Least relative difference flagged, per quantity: kt=0.05,coulomb=1,..."
    ),
    csv: Optional[Path] = typer.Option(None, "--csv", help="Write the fleet table (one row per actuator) as CSV."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="PNG: every quantity per actuator, outliers named."),
    reports: Optional[Path] = typer.Option(
        None, "--reports", help="Folder: each log's fit report (what fit-current --json prints)."
    ),
    json_out: bool = typer.Option(False, "--json", help="Print JSON (schema hound-id/fleet/2)."),
) -> None:
    """Fit many actuators' logs at once and flag the outliers with their physical reading.

    Every log is fitted with the same model on Dask (local cores, or --scheduler) and compared with the fleet's
    median. Exit 1 when a log failed."""
    from hound_id.dyno.fleet.run import FleetOptions, write_outputs

    fit = fit_options(
        model, add, auto, columns, units, flip_torque, window, robust, whole_log=whole_log, auto_sign=auto_sign
    )
    options = FleetOptions(scheduler, workers, z, tolerance, csv, plot, reports)
    result = _run_with_progress(logs, fit, options, json_out)
    write_outputs(result)
    report = result.report
    if json_out:
        print_json(result.to_dict())
    elif report.fitted:
        _print(result)
        for note in result.run.notes:
            warn(note)
    if not report.fitted:
        err_console.print(
            f"hound-id: error: none of the {len(report.actuators)} logs could be fitted (each one's reason is above)",
            highlight=False,
            markup=False,
            soft_wrap=True,
        )
        raise typer.Exit(2)
    if report.failed:
        raise typer.Exit(1)


def _run_with_progress(logs: list[str], fit: Any, options: Any, json_out: bool) -> Any:
    """The fleet verb under a progress bar of its passes (a line per log as it is fitted; on a pipe, a line per
    pass instead of the bar)."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TaskID, TextColumn, TimeRemainingColumn

    from hound_id.dyno.fleet.run import fleet as run

    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeRemainingColumn(),
        console=err_console,
        transient=True,
        disable=not err_console.is_terminal,
    ) as progress:
        task: list[TaskID] = []
        again: list[bool] = []

        def on_pass(description: str, count: int) -> None:
            if task:
                progress.remove_task(task.pop())
                again.append(True)  # the second pass: the fleet's model
            task.append(progress.add_task(description, total=count))
            if not err_console.is_terminal and not json_out:
                err_console.print(f"{description}: {count} logs", highlight=False, markup=False)

        def on_result(fit_: ActuatorFit, done: int, total: int) -> None:
            progress.update(task[-1], completed=done)
            line = _log_line(fit_)
            progress.console.print(
                line + (" [fleet model]" if again else ""), highlight=False, markup=False, soft_wrap=True
            )

        return run(logs, fit, options, on_result=on_result, on_pass=on_pass)


def _log_line(fit: ActuatorFit) -> str:
    if fit.report is None:
        first = (fit.error or "").splitlines()[0] if fit.error else "failed"
        return f"FAILED {fit.name}: {first}"
    r = fit.report
    kt = r.parameters["kt"]
    err = "" if math.isnan(kt.stderr) else f" +- {kt.stderr:.2g}"
    verdict = "at the noise floor" if r.at_noise_floor else "not at the noise floor"
    sign = ", torque negated" if any(c.kind == "flipped_torque" for c in r.cleaning) else ""
    left = f", {len(r.headline.left_out)} stretch(es) left out" if r.headline is not None else ""
    return f"ok     {fit.name}: Kt {kt.value:.5g}{err} N m/A{sign}{left}, {verdict} ({fit.seconds:.2f} s)"


def _deviation(value: float | None, median: float | None) -> str:
    if value is None:
        return "-"
    if not median:
        return f"{value:.3g}"
    return f"{(value - median) / abs(median):+.0%}"


def _actuator_table(report: FleetReport, rows: tuple[ActuatorFit, ...]) -> Table:
    """One row per actuator: each quantity's deviation from the fleet's median, its cogging order and verdict, what
    is flagged in red."""
    stats = report.stats
    table = Table(
        title=f"{len(report.actuators)} actuators against the fleet's median (flagged in red)",
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    table.add_column("actuator", overflow="fold", min_width=8, max_width=28)
    for s in stats:
        table.add_column(s.metric.short, justify="right")
    orders = any(o is not None for o in report.cogging_order.values())
    if orders:
        table.add_column("order", justify="right")
    table.add_column("verdict")
    for a in rows:
        if a.report is None:
            table.add_row(escape(a.name), *(["-"] * (len(stats) + orders)), "[red]failed[/red]")
            continue
        values = report.values[a.name]
        mine = {f.metric for f in report.flags_of(a.name)}
        cells = []
        for s in stats:
            text = _deviation(values[s.metric.key].value, s.median)
            cells.append(f"[bold red]{text}[/bold red]" if s.metric.key in mine else text)
        order = report.cogging_order.get(a.name)
        order_text = "-" if order is None else f"{order:g}"
        if orders:
            cells.append(f"[bold red]{order_text}[/bold red]" if "cogging_order" in mine else order_text)
        verdict = "floor" if a.report.at_noise_floor else "missing"
        table.add_row(escape(a.name), *cells, f"[bold red]{verdict}[/bold red]" if "verdict" in mine else verdict)
    return table


def _fleet_table(report: FleetReport) -> Table:
    """The fleet's median, robust spread and flag rule of each quantity, in SI units."""
    fleet = Table(title=f"the fleet (model {'+'.join(report.model)})", title_justify="left", box=box.SIMPLE_HEAD)
    for col in ("quantity", "median", "robust spread", "unit", "n", "flagged if"):
        fleet.add_column(col, justify="right" if col in ("median", "robust spread", "n") else "left")
    for s in report.stats:
        m = s.metric
        rule = {"both": "off", "high": "above", "low": "below"}[m.side]
        fleet.add_row(
            m.label,
            "-" if s.median is None else f"{s.median:.4g}",
            "-" if s.spread is None else f"{s.spread:.2g}",
            m.unit,
            str(s.n),
            f"{rule} by > {m.tolerance:.0%} and > {s.z:.3g} spreads" if s.judged else "too few",
        )
    if report.fleet_order is not None:
        fleet.add_row("cogging order", f"{report.fleet_order:g}", "", "1/rev", "", "another")
    return fleet


def _print(result: FleetResult) -> None:
    """Per actuator, each quantity's deviation from the fleet's median; then the medians and spreads in SI."""
    from hound_id.dyno.fleet.engine import seconds_per_log

    report, run, options = result.report, result.run, result.options
    flagged = {f.actuator for f in report.flags}
    rows = report.actuators
    if len(rows) > MAX_ROWS:
        rows = tuple(a for a in rows if a.name in flagged or not a.ok)
    console.print(_actuator_table(report, rows))
    console.print(_fleet_table(report))
    console.print(
        "spreads: the robust spread combined with the log's own standard error; the limit grows with the fleet so "
        "that a healthy fleet is flagged with chance below 1 %. verdict: floor = the fit is at its log's noise floor, "
        "missing = the log shows an effect the model lacks",
        highlight=False,
    )
    if len(rows) < len(report.actuators):
        console.print(
            f"{len(report.actuators) - len(rows)} healthy actuators not listed (--csv has every one)", highlight=False
        )
    per_log = seconds_per_log(run)
    console.print(
        f"{len(report.fitted)} fitted, {len(report.failed)} failed on {run.workers} Dask workers "
        f"({'local cluster' if options.scheduler is None else run.scheduler}) in {run.seconds:.1f} s"
        + (f", {per_log:.2f} s per log" if not math.isnan(per_log) else "")
        + (f"; fitted again with the fleet's model: {', '.join(run.refitted)}" if run.refitted else ""),
        highlight=False,
    )
    if run.capped:
        console.print(f"note: {escape(run.capped)}", highlight=False)
    if report.flags:
        console.print(f"[bold]flagged ({len(flagged)} actuator{'s' if len(flagged) != 1 else ''}):[/bold]")
        for f in report.flags:
            console.print(f"  {escape(f.actuator)}: {escape(f.reading)}", highlight=False)
    else:
        console.print("[bold]no actuator is flagged[/bold]")
    for a in report.failed:
        console.print(f"[red]failed[/red] {escape(a.name)}: {escape((a.error or '').splitlines()[0])}", highlight=False)
    for note in report.notes:
        console.print(f"note: {escape(note)}", highlight=False)
    for what, path in (("csv", options.csv), ("plot", options.plot), ("reports", options.reports)):
        if path is not None:
            console.print(f"{what} written to {path}", highlight=False)
