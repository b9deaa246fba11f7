"""``hound-id fit-current`` and ``hound-id effects``: current-torque identification from dyno logs."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from rich.markup import escape
from rich.table import Table

from hound_id import io
from hound_id.cli._render import console, err_console, print_json, save_figure, warn
from hound_id.errors import FitError, HoundIdError
from hound_id.io import check_output


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
    window: Optional[str] = typer.Option(
        None, "--window", help="Fit only START:STOP seconds (data rows of a steady-state table); ends optional."
    ),
    robust: bool = typer.Option(False, "--robust", help="Huber-robust least squares (outliers left in the log)."),
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
    json_out: bool = typer.Option(False, "--json", help="Print JSON (schema hound-id/fit/2)."),
) -> None:
    """Fit a current-torque model to a dyno log, diagnose what is missing, and report Kt and peak torque."""
    from hound_id.dyno.current.effects import Signals, load_effects_file, parse_model
    from hound_id.dyno.logs import load_log, parse_mapping, parse_window

    sources = (data, spec, *(effects_file or []))
    check_output(plot, (".png",), "plot", inputs=sources)
    start_stop = parse_window(window)
    check_output(out, (".yaml", ".yml"), "fitted-motor", inputs=sources)
    from hound_id.mor.spec import load_motor_spec

    sheet = load_motor_spec(spec) if spec is not None else None  # fail before the work on a bad sheet
    for path in effects_file or []:
        load_effects_file(path)
    names = list(parse_model(model))
    for extra in add or []:
        for effect_name in parse_model(extra):
            if effect_name in names:
                raise FitError(f"--add {effect_name}: the model already has it")
            names.append(effect_name)
    log = load_log(
        data,
        columns=parse_mapping(columns, "--columns"),
        units=parse_mapping(units, "--units"),
        flip_torque=flip_torque,
    )
    if window is not None:
        log = log.window(*start_stop)
    # Notes and warnings are printed once the command has succeeded: an error is then the only line.
    notes = [n.message for n in log.notes if n.kind in ("unit", "format", "window")] if not json_out else []
    log_warnings = [n.message for n in log.notes if n.kind not in ("unit", "format", "window")]
    signals = Signals.from_log(log)
    torque = log.torque
    result = _run(signals, torque, tuple(names), auto=auto, robust=robust)
    fit, diagnosis, ladder, start = result
    from hound_id.dyno.current.report import fitted_motor, summarize

    peak, _, report = summarize(
        str(data),
        fit,
        diagnosis,
        signals.current,
        ladder,
        log.notes,
        log.rows_read,
        current_limit=log.current_limit,
        time=signals.time if signals.timed else None,
    )
    warnings = _fit_warnings(report)
    from hound_id.dyno.current.report import check_kt, spec_checks

    check_kt(str(data), report["parameters"]["kt"]["value"], sheet, str(spec))
    if sheet is not None:
        warnings += [f"against {spec}: {w}" for w in spec_checks(report, sheet)]
    if out is not None:
        import yaml

        motor = fitted_motor(report, out, spec, data.stem if sheet is None else None)
        motor_text = yaml.safe_dump(motor, sort_keys=False)  # written after the plot: both or neither
        if "extrapolated" in motor:
            warnings.append(
                f"{out}: peak torque {motor['peak_torque']:.4g} N m is extrapolated beyond the measured currents "
                f"(|i| <= {report['peak_torque']['max_measured_current']:.3g} A); written with "
                "'extrapolated: [peak_torque]'"
            )
        if not diagnosis.at_noise_floor:
            warnings.append(
                f"{out}: written from a fit that is not at the noise floor ({diagnosis.summary()}); "
                "its Kt and peak torque may be biased: add the missing effects (--auto) and write it again"
            )
    report["warnings"] = warnings
    if plot is not None:
        from hound_id.dyno.current.fit import fit_model
        from hound_id.dyno.current.plot import plot_fit

        order = fit.hypers.get("cogging_order") or next(
            (s.hypers.get("cogging_order") for s in diagnosis.suggestions if s.effect == "cogging" and s.significant),
            None,
        )
        base = tuple(parse_model(model))
        if auto or tuple(fit.model) != base:  # compare against the model the user started from
            before = start if auto else _fit_or_none(signals, torque, base, robust)
        else:
            before = None
        if before is not None:
            pairs = [("before: " + "+".join(before.model), before), ("after: " + "+".join(fit.model), fit)]
        elif diagnosis.best is not None:  # show what the top suggestion would do
            best = diagnosis.best.effect
            suggested = fit_model(signals, torque, (*fit.model, best), robust=robust)
            pairs = [("model: " + "+".join(fit.model), fit), (f"with suggested {best}", suggested)]
        else:
            pairs = [("model: " + "+".join(fit.model), fit)]
        save_figure(plot_fit(signals, torque, fit, peak, pairs, cogging_order=order, diagnosis=diagnosis), plot)
    if out is not None:
        try:
            io.write_text(out, motor_text)
        except HoundIdError:
            if plot is not None:
                plot.unlink(missing_ok=True)
            raise
    for message in notes:
        err_console.print(f"note: {message}", highlight=False, markup=False, soft_wrap=True)
    for w in [*log_warnings, *warnings]:
        warn(w)
    if json_out:
        report.update(plot=str(plot) if plot else None, out=str(out) if out else None)
        print_json(report)
        return
    _print(report, fit, diagnosis, ladder, plot, out)


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


def _fit_warnings(report: dict) -> list[str]:  # type: ignore[type-arg]
    """Warnings every user must see: parameters held at a physical bound, disagreeing blocks."""
    out = []
    for name, wanted in report["unphysical"].items():
        est = report["parameters"][name]
        out.append(
            f"{name} is held at its physical bound {est['value']:.4g} {est['unit']}: the unconstrained fit wants "
            f"{wanted:.4g} {est['unit']}, which is not physical; the model lacks what the log shows there, or the "
            f"log cannot separate {name} from another term"
        )
    out += report["flags"]
    return out


def _fit_or_none(signals, torque, model, robust):  # type: ignore[no-untyped-def]
    from hound_id.dyno.current.fit import fit_model

    try:
        return fit_model(signals, torque, model, robust=robust)
    except FitError:
        return None


def _run(signals, torque, names, *, auto: bool, robust: bool):  # type: ignore[no-untyped-def]
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    from hound_id.dyno.current.diagnose import auto as run_auto
    from hound_id.dyno.current.diagnose import diagnose
    from hound_id.dyno.current.fit import fit_model

    with Progress(
        SpinnerColumn(),
        TextColumn("{task.description}"),
        TimeElapsedColumn(),
        console=err_console,
        transient=True,
        disable=not err_console.is_terminal,
    ) as progress:
        task = progress.add_task(f"fitting {'+'.join(names)}")
        start = fit_model(signals, torque, names, robust=robust)
        if auto:

            def on_step(step) -> None:  # type: ignore[no-untyped-def]
                progress.update(
                    task, description=f"diagnosed {'+'.join(step.model)}: held-out RMSE {step.fit.rmse_test:.3g} N m"
                )

            ladder = run_auto(signals, torque, start, on_step=on_step)
            return ladder[-1].fit, ladder[-1].diagnosis, ladder, start
        progress.update(task, description="diagnosing")
        return start, diagnose(signals, torque, start), None, start


def _print(report, fit, diagnosis, ladder, plot, out) -> None:  # type: ignore[no-untyped-def]
    rows = report["rows"]
    console.print(
        f"[bold]{report['source']}[/bold]: model {'+'.join(fit.model)}, {rows['fitted']} rows in "
        f"{rows['blocks']} time blocks; cross-validated over {rows['folds']} folds (each held out once)",
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
    pk = report["peak_torque"]
    console.print(pk["note"], highlight=False)
    comp = report["compensation"]
    if comp:
        terms = " + ".join(f"{c:.4g} tau^{p}" for p, c in zip(comp["powers"], comp["coefficients"], strict=True))
        console.print(
            f"current compensation i(tau) = {terms} [A] (max error {comp['max_error']:.2g} A "
            f"over |tau| <= {comp['torque_range']:.3g} N m)",
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
    console.print(f"[bold]{diagnosis.summary()}[/bold]", highlight=False)
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
