"""The ``fit-current`` verb: a dyno log in, a fitted and diagnosed current-torque model out.

:func:`fit_current` does everything the command decides: load and window the log, fit the
starting model (plus ``--add``), run the ``--auto`` ladder or diagnose once, the peak torque
and compensation, the versioned report, the spec-sheet checks, the fitted-motor mapping for
``--out`` and the fits the plot compares. It prints nothing and writes nothing;
:func:`write_outputs` writes the plot and the fitted motor, both or neither. The command line
and ``hound-id demo`` call these two and only render.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hound_id import io
from hound_id.errors import FitError, HoundIdError

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from hound_id.dyno.current.curve import Compensation, PeakTorque
    from hound_id.dyno.current.diagnose import Diagnosis, Step
    from hound_id.dyno.current.effects import Signals
    from hound_id.dyno.current.fit import FitResult
    from hound_id.dyno.logs import DynoLog

#: Cleaning notes that are information, not warnings (shown as ``note:`` outside ``--json``).
NOTE_KINDS = ("unit", "format", "window")


@dataclass(frozen=True)
class FitCurrentOptions:
    """What ``hound-id fit-current`` is asked, as given on the command line (texts are parsed by the verb)."""

    model: str = "linear+saturation"
    """Starting model: effect names joined by '+'."""
    add: tuple[str, ...] = ()
    """Effects added to the model (each may itself be 'a+b')."""
    auto: bool = False
    """Add the top significant effect until none is left."""
    columns: str | Mapping[str, str] | None = None
    """Column map, ``torque=adc_torque,current=iq`` (or already a mapping canonical -> file column)."""
    units: str | Mapping[str, str] | None = None
    """Units of columns, ``velocity=rpm,position=deg`` (or a mapping)."""
    flip_torque: bool = False
    """Negate torque (sensor mounted reversed)."""
    window: str | None = None
    """``START:STOP`` seconds (data rows of a steady-state table); ends optional."""
    robust: bool = False
    """Huber-robust least squares."""
    effects_files: tuple[Path, ...] = ()
    """Python files registering the user's own effects (executed)."""
    spec: Path | None = None
    """Motor spec sheet the fitted Kt and peak torque are checked against and override in ``out``."""
    plot: Path | None = None
    """PNG the fit is drawn into (None: the fits the plot compares are not computed)."""
    out: Path | None = None
    """Fitted-motor YAML (None: no fitted-motor mapping)."""


@dataclass(frozen=True)
class FitFigure:
    """What the plot draws, fitted once by the verb."""

    pairs: tuple[tuple[str, FitResult], ...]
    """(label, fit) pairs whose residuals the panels compare."""
    cogging_order: float | None
    """Periods per revolution the position panel folds on (None: no fold)."""


@dataclass(frozen=True, eq=False)
class FitCurrentResult:
    """Everything ``fit-current`` found; arrays are the log's read-only arrays."""

    data: Path
    """The dyno log."""
    options: FitCurrentOptions
    """The options it ran with."""
    log: DynoLog
    """The cleaned (and windowed) log."""
    signals: Signals
    """The model's input channels."""
    start: FitResult
    """Fit of the starting model (with ``add``)."""
    fit: FitResult
    """The final fit (the last rung with ``auto``)."""
    diagnosis: Diagnosis
    """Its diagnosis."""
    ladder: tuple[Step, ...] | None
    """The ``auto`` ladder, None without ``auto``."""
    peak: PeakTorque
    """Peak torque of the final fit."""
    compensation: Compensation
    """Current compensation of the final fit."""
    report: dict[str, Any]
    """The versioned report (schema ``hound-id/fit/2``), without the warnings (see :meth:`report_json`)."""
    notes: tuple[str, ...]
    """Cleaning notes that are information (units, format, window)."""
    log_warnings: tuple[str, ...]
    """Cleaning notes the user must see."""
    warnings: tuple[str, ...]
    """Warnings about the fit, the spec sheet and ``out``, in the order they are shown."""
    motor: dict[str, Any] | None = None
    """The fitted-motor mapping for ``options.out`` (None without it)."""
    figure: FitFigure | None = field(default=None)
    """What ``options.plot`` draws (None without it)."""

    def report_json(self) -> dict[str, Any]:
        """The report with its ``warnings`` (what ``--json`` prints before ``plot`` and ``out``)."""
        return {**self.report, "warnings": list(self.warnings)}

    def draw(self) -> Figure:
        """The plot: the fit, its 20 % point and the residual panels of :attr:`figure`."""
        from hound_id.dyno.current.plot import plot_fit

        if self.figure is None:
            raise HoundIdError("fit-current: the plot was not asked for (give options.plot)")
        return plot_fit(
            self.signals,
            self.log.torque,
            self.fit,
            self.peak,
            list(self.figure.pairs),
            cogging_order=self.figure.cogging_order,
            diagnosis=self.diagnosis,
        )


def _mapping(value: str | Mapping[str, str] | None, option: str) -> dict[str, str]:
    from hound_id.dyno.logs import parse_mapping

    if value is None or isinstance(value, str):
        return parse_mapping(value, option)
    return dict(value)


def fit_warnings(report: Mapping[str, Any]) -> list[str]:
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


def fit_current(
    data: Path, options: FitCurrentOptions = FitCurrentOptions(), on_progress: Callable[[str], None] | None = None
) -> FitCurrentResult:
    """Fit a current-torque model to a dyno log, diagnose what is missing, report Kt and peak torque.

    Every input is checked before the work: the output paths, the window, the spec sheet, the
    effects files and the model; the fitted Kt is refused when only a wrong unit or column
    explains it.

    Args:
        data: Dyno log, CSV or Parquet.
        options: What to fit and check (:class:`FitCurrentOptions`).
        on_progress: Called with a one-line description as the work goes (fitting, each rung).

    Raises:
        HoundIdError: A bad input (log, option, spec, output path), or a fit the log cannot support.
    """
    from hound_id.dyno.current.diagnose import auto as run_auto
    from hound_id.dyno.current.diagnose import diagnose
    from hound_id.dyno.current.effects import Signals, load_effects_file, parse_model
    from hound_id.dyno.current.fit import fit_model
    from hound_id.dyno.current.report import check_kt, fitted_motor, spec_checks, summarize
    from hound_id.dyno.logs import load_log, parse_window
    from hound_id.mor.spec import load_motor_spec

    spec, plot, out = options.spec, options.plot, options.out
    if Path(data).is_dir():
        from hound_id.errors import DynoDataError

        raise DynoDataError(
            f"{data}: is a folder; fit-current takes one log (.csv or .parquet): to fit every log in the folder and "
            f"compare them, run 'hound-id fleet {data}'",
            path=str(data),
        )
    sources = (data, spec, *options.effects_files)
    io.check_output(plot, (".png",), "plot", inputs=sources)
    start_stop = parse_window(options.window)
    io.check_output(out, (".yaml", ".yml"), "fitted-motor", inputs=sources)
    sheet = load_motor_spec(spec) if spec is not None else None  # fail before the work on a bad sheet
    for path in options.effects_files:
        load_effects_file(path)
    names = list(parse_model(options.model))
    for extra in options.add:
        for effect_name in parse_model(extra):
            if effect_name in names:
                raise FitError(f"--add {effect_name}: the model already has it")
            names.append(effect_name)
    log = load_log(
        data,
        columns=_mapping(options.columns, "--columns"),
        units=_mapping(options.units, "--units"),
        flip_torque=options.flip_torque,
    )
    if options.window is not None:
        log = log.window(*start_stop)
    notes = tuple(n.message for n in log.notes if n.kind in NOTE_KINDS)
    log_warnings = tuple(n.message for n in log.notes if n.kind not in NOTE_KINDS)
    signals = Signals.from_log(log)
    torque = log.torque
    model = tuple(names)
    if on_progress is not None:
        on_progress(f"fitting {'+'.join(model)}")
    start = fit_model(signals, torque, model, robust=options.robust)
    ladder: tuple[Step, ...] | None = None
    if options.auto:

        def on_step(step: Step) -> None:
            if on_progress is not None:
                on_progress(f"diagnosed {'+'.join(step.model)}: held-out RMSE {step.fit.rmse_test:.3g} N m")

        ladder = tuple(run_auto(signals, torque, start, on_step=on_step))
        fit, diagnosis = ladder[-1].fit, ladder[-1].diagnosis
    else:
        if on_progress is not None:
            on_progress("diagnosing")
        fit, diagnosis = start, diagnose(signals, torque, start)
    peak, comp, report = summarize(
        str(data),
        fit,
        diagnosis,
        signals.current,
        list(ladder) if ladder is not None else None,
        log.notes,
        log.rows_read,
        current_limit=log.current_limit,
        time=signals.time if signals.timed else None,
    )
    warnings = fit_warnings(report)
    check_kt(str(data), report["parameters"]["kt"]["value"], sheet, str(spec))
    if sheet is not None:
        warnings += [f"against {spec}: {w}" for w in spec_checks(report, sheet)]
    motor = None
    if out is not None:
        motor = fitted_motor(report, out, spec, data.stem if sheet is None else None)
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
    figure = _figure(signals, torque, fit, start, diagnosis, options) if plot is not None else None
    return FitCurrentResult(
        data=data,
        options=options,
        log=log,
        signals=signals,
        start=start,
        fit=fit,
        diagnosis=diagnosis,
        ladder=ladder,
        peak=peak,
        compensation=comp,
        report=report,
        notes=notes,
        log_warnings=log_warnings,
        warnings=tuple(warnings),
        motor=motor,
        figure=figure,
    )


def _figure(
    signals: Signals, torque: Any, fit: FitResult, start: FitResult, diagnosis: Diagnosis, options: FitCurrentOptions
) -> FitFigure:
    """The fits the plot compares: before/after when the model changed, else the top suggestion's effect."""
    from hound_id.dyno.current.effects import parse_model
    from hound_id.dyno.current.fit import fit_model

    order = fit.hypers.get("cogging_order") or next(
        (s.hypers.get("cogging_order") for s in diagnosis.suggestions if s.effect == "cogging" and s.significant),
        None,
    )
    base = tuple(parse_model(options.model))
    before: FitResult | None = None
    if options.auto or tuple(fit.model) != base:  # compare against the model the user started from
        before = start if options.auto else _fit_or_none(signals, torque, base, options.robust)
    if before is not None:
        pairs = [("before: " + "+".join(before.model), before), ("after: " + "+".join(fit.model), fit)]
    elif diagnosis.best is not None:  # show what the top suggestion would do
        best = diagnosis.best.effect
        suggested = fit_model(signals, torque, (*fit.model, best), robust=options.robust)
        pairs = [("model: " + "+".join(fit.model), fit), (f"with suggested {best}", suggested)]
    else:
        pairs = [("model: " + "+".join(fit.model), fit)]
    return FitFigure(tuple(pairs), order)


def _fit_or_none(signals: Signals, torque: Any, model: tuple[str, ...], robust: bool) -> FitResult | None:
    from hound_id.dyno.current.fit import fit_model

    try:
        return fit_model(signals, torque, model, robust=robust)
    except FitError:
        return None


def write_outputs(result: FitCurrentResult, dpi: int = 120) -> None:
    """Write ``options.plot`` and then ``options.out``, each atomically; the plot is removed if ``out`` fails.

    Args:
        result: What :func:`fit_current` returned.
        dpi: Resolution of the PNG [dots per inch].
    """
    plot, out = result.options.plot, result.options.out
    motor_text = None
    if out is not None and result.motor is not None:
        import yaml

        motor_text = yaml.safe_dump(result.motor, sort_keys=False)  # written after the plot: both or neither
    if plot is not None:
        fig = result.draw()
        io.check_output(plot, (".png",), "plot")
        io.write_png(fig, plot, dpi)
    if out is not None and motor_text is not None:
        try:
            io.write_text(out, motor_text)
        except HoundIdError:
            if plot is not None:
                plot.unlink(missing_ok=True)
            raise


__all__ = ["FitCurrentOptions", "FitCurrentResult", "FitFigure", "fit_current", "fit_warnings", "write_outputs"]
