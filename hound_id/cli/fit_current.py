"""``hound-id fit-current`` and ``hound-id effects``: current-torque identification from dyno logs."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Optional

import typer
from rich.markup import escape
from rich.table import Table

from hound_id.cli._render import console, err_console, print_json, warn

if TYPE_CHECKING:
    from hound_id.dyno.current.fit_report import FitReport
    from hound_id.dyno.current.run import FitCurrentOptions


def fit_current(
    data: Path = typer.Argument(
        ..., metavar="DATA", help="Dyno log, CSV or Parquet (time, current, torque [, velocity, ...])."
    ),
    model: str = typer.Option("linear+saturation", "--model", help="Starting model: effects joined by '+'."),
    add: Optional[list[str]] = typer.Option(None, "--add", help="Add an effect to the model (repeatable)."),
    auto: bool = typer.Option(False, "--auto", help="Add the top significant effect until none is left."),
    columns: Optional[str] = typer.Option(None, "--columns", help="Map columns: torque=adc_torque,current=iq,..."),
    units: Optional[str] = typer.Option(None, "--units", help="Units of columns: velocity=rpm,position=deg,..."),
    flip_torque: bool = typer.Option(False, "--flip-torque", help="Negate torque (sensor mounted reversed)."),
    auto_sign: bool = typer.Option(
        False, "--auto-sign", help="Negate the torque when it falls as current rises (a note says which was done)."
    ),
    window: Optional[str] = typer.Option(
        None,
        "--window",
        help="Fit only START:STOP seconds (data rows of a steady-state table); ends optional; several ranges "
        "separated by commas.",
    ),
    robust: bool = typer.Option(False, "--robust", help="Huber-robust least squares (outliers left in the log)."),
    whole_log: bool = typer.Option(
        False,
        "--whole-log",
        help="Keep the whole log as the headline even where part of it disagrees (by default the disagreeing "
        "stretches are left out and the whole log's fit is reported beside).",
    ),
    effects_file: Optional[list[Path]] = typer.Option(
        None,
        "--effects-file",
        help="Python file registering your own effects (repeatable). It is executed: use only files you trust.",
    ),
    spec: Optional[Path] = typer.Option(None, "--spec", help="Motor spec the fitted Kt and peak torque override."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="PNG: fit, 20 % point, residuals before and after."),
    out: Optional[Path] = typer.Option(
        None, "--out", help="Write a fitted-motor YAML (with --spec, one that 'hound-id mor --spec' reads)."
    ),
    json_out: bool = typer.Option(False, "--json", help="Print JSON (schema hound-id/fit/3)."),
) -> None:
    """Fit a current-torque model to a dyno log, diagnose what is missing, and report Kt and peak torque."""

    from hound_id.dyno.current.run import write_outputs

    options = fit_options(
        model,
        add,
        auto,
        columns,
        units,
        flip_torque,
        window,
        robust,
        whole_log=whole_log,
        auto_sign=auto_sign,
        effects_files=tuple(effects_file or ()),
        spec=spec,
        plot=plot,
        out=out,
    )
    result = _run_with_spinner(data, options)
    write_outputs(result)
    # Notes and warnings are printed once the command has succeeded: an error is then the only line.
    if not json_out:
        for message in result.notes:
            err_console.print(f"note: {message}", highlight=False, markup=False, soft_wrap=True)
    for w in [*result.log_warnings, *result.warnings]:
        warn(w)
    if json_out:
        print_json(result.report_json() | {"plot": str(plot) if plot else None, "out": str(out) if out else None})
        return
    _print(result.report, result.fit, result.diagnosis, result.ladder, plot, out)


def _run_with_spinner(data: Path, options: FitCurrentOptions) -> Any:
    """The fit-current verb under a spinner that names each step (fitting, each rung of the ladder)."""
    from rich.progress import Progress, SpinnerColumn, TaskID, TextColumn, TimeElapsedColumn

    from hound_id.dyno.current.run import fit_current as run

    with Progress(
        SpinnerColumn(),
        TextColumn("{task.description}"),
        TimeElapsedColumn(),
        console=err_console,
        transient=True,
        disable=not err_console.is_terminal,
    ) as progress:
        task: list[TaskID] = []

        def on_progress(description: str) -> None:
            if task:
                progress.update(task[0], description=description)
            else:
                task.append(progress.add_task(description))

        return run(data, options, on_progress=on_progress)


def fit_options(
    model: str,
    add: list[str] | None,
    auto: bool,
    columns: str | None,
    units: str | None,
    flip_torque: bool,
    window: str | None,
    robust: bool,
    **extra: Any,
) -> FitCurrentOptions:
    """The fit's options as ``fit-current`` and ``fleet`` take them on the command line."""
    from hound_id.dyno.current.run import FitCurrentOptions

    return FitCurrentOptions(
        model=model,
        add=tuple(add or ()),
        auto=auto,
        columns=columns,
        units=units,
        flip_torque=flip_torque,
        window=window,
        robust=robust,
        **extra,
    )


def _bound_text(p: dict) -> str:  # type: ignore[type-arg]
    """' >= 0', ' <= 0' or '' for a parameter's physical bound."""
    lower, upper = p.get("lower"), p.get("upper")
    if lower is not None and upper is not None:
        return f" in [{lower:g}, {upper:g}]"
    if lower is not None:
        return f" >= {lower:g}"
    if upper is not None:
        return f" <= {upper:g}"
    return ""


def _table(report: FitReport) -> bool:
    """Whether the log is a steady-state table (no time column)."""
    return any(c.kind == "steady_state" for c in report.cleaning)


def _print(report: FitReport, fit, diagnosis, ladder, plot, out) -> None:  # type: ignore[no-untyped-def]
    rows = report.rows
    console.print(
        f"[bold]{report.source}[/bold]: model {'+'.join(fit.model)}, {rows.fitted} rows in "
        f"{rows.blocks} {'blocks of rows' if _table(report) else 'time blocks'}; cross-validated over "
        f"{rows.folds} folds (each held out once)",
        highlight=False,
    )
    table = Table(title="parameters", title_justify="left")
    for col in ("parameter", "value", "std. error", "unit", "effect"):
        table.add_column(col, justify="right" if col in ("value", "std. error") else "left")
    for name, est in fit.parameters.items():
        err = "" if est.stderr != est.stderr else f"{est.stderr:.2g}"
        if est.at_bound:
            err = "at bound"
        table.add_row(name, f"{est.value:.5g}", err, est.unit, est.effect)
    console.print(table)
    console.print(
        f"RMSE fit {fit.rmse_train:.4g} N m, cross-validated {fit.rmse_test:.4g} N m; "
        f"noise floor {diagnosis.noise_floor:.3g} N m; AIC {fit.aic:.6g}, BIC {fit.bic:.6g}",
        highlight=False,
    )
    if diagnosis.noise is not None:
        console.print(diagnosis.noise.sentence(), highlight=False, markup=False)
    console.print(report.peak.note, highlight=False)
    if report.curve is not None:
        exact = report.curve.compensation()
        console.print(
            f"current compensation: the exact inverse of the fitted curve, {exact['method']}"
            + (f" (table error {exact['max_error']:.2g} A)" if exact["max_error"] else ""),
            highlight=False,
        )
    if (comp := report.polynomial) is not None:
        terms = " + ".join(f"{c:.4g} tau^{p}" for p, c in zip(comp.powers, comp.coefficients, strict=True))
        console.print(
            f"  or, for a driver that takes an odd polynomial: i(tau) = {terms} [A] (off the exact inverse by up "
            f"to {comp.max_error:.2g} A over |tau| <= {comp.torque_range:.3g} N m, its slope at zero torque "
            f"by {comp.slope_error:+.1%})",
            highlight=False,
        )
    if ladder is not None:
        lt = Table(title="--auto ladder", title_justify="left")
        for col in ("step", "added", "cross-validated RMSE [N m]", "fit RMSE [N m]", "BIC"):
            lt.add_column(col, justify="left" if col in ("step", "added") else "right")
        for k, step in enumerate(ladder):
            lt.add_row(
                str(k),
                step.added or "(start)",
                f"{step.fit.rmse_test:.4g}",
                f"{step.fit.rmse_train:.4g}",
                f"{step.fit.bic:.6g}",
            )
        console.print(lt)
    st = Table(title="missing effects, best first (cross-validated residual explained)", title_justify="left")
    for col in ("effect", "explained", "significant", "evidence"):
        st.add_column(col, justify="right" if col == "explained" else "left", overflow="fold")
    for s in diagnosis.suggestions:
        st.add_row(s.effect, f"{s.explained:.2%}", "yes" if s.significant else "no", escape(s.reason))
    console.print(st)
    if diagnosis.skipped:
        console.print(f"not tried: {'; '.join(diagnosis.skipped)}", highlight=False)
    # the report's summary: the diagnosis's, and that it holds for the rest of the log when the headline left out
    # stretches that follow another law
    console.print(f"[bold]{escape(report.summary)}[/bold]", highlight=False)
    for path, what in ((plot, "plot"), (out, "fitted motor")):
        if path is not None:
            console.print(f"{what} written to {path}", highlight=False)


def effects(json_out: bool = typer.Option(False, "--json", help="Print JSON (schema hound-id/effects/1).")) -> None:
    """List the effects library: names, physics, parameters and units."""
    from hound_id.dyno.current.effects import describe

    items = describe()
    if json_out:
        print_json({"schema": "hound-id/effects/1", "effects": items})
        return
    table = Table(title="effects (use with --model / --add)", title_justify="left")
    for col in ("effect", "parameters", "needs", "physics"):
        table.add_column(col, overflow="fold")
    for e in items:
        params = ", ".join(f"{p['name']} [{p['unit']}]{_bound_text(p)}" for p in (*e["parameters"], *e["hypers"]))
        table.add_row(*(escape(x) for x in (e["effect"], params, ", ".join(e["requires"]) or "-", e["physics"])))
    console.print(table)
