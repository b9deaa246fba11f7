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
from dataclasses import dataclass, field, replace
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
    from hound_id.dyno.current.fit_report import FitReport
    from hound_id.dyno.current.stretch import Stretch
    from hound_id.dyno.logs import DynoLog

#: Cleaning notes that are information, not warnings (shown as ``note:`` outside ``--json``).
NOTE_KINDS = ("unit", "format", "window")
#: Cleaning notes that show the current reply cut off at the end of its range (the peak-torque advice names the reply);
#: a wrap-around does when its boundary rows were removed (folded back, not restored from the torque).
REPLY_CUT = ("clamp", "reply_clamp")


def _cuts_reply(note: Any) -> bool:
    return bool(note.kind in REPLY_CUT or (note.kind == "wrap" and note.rows > 0))


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
    auto_sign: bool = False
    """Negate the torque when the log's own slope says its sensor is mounted reversed (a note says which)."""
    window: str | None = None
    """``START:STOP`` seconds (data rows of a steady-state table); ends optional."""
    robust: bool = False
    """Huber-robust least squares."""
    whole_log: bool = False
    """Keep the whole log as the headline even when part of it disagrees (by default the headline is the longest
    stretch that agrees and exercises the current)."""
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
class Fitted:
    """One log (or stretch) fitted: the starting model, the ladder and where it ended."""

    signals: Signals
    """The model's input channels."""
    start: FitResult
    """Fit of the starting model."""
    ladder: tuple[Step, ...] | None
    """The ``auto`` ladder (None without ``auto``)."""
    fit: FitResult
    """The final fit."""
    diagnosis: Diagnosis
    """Its diagnosis."""


#: Stretches tried as the headline before the whole log is kept (each is a whole fit, with its ladder); times the
#: headline is narrowed again when its own blocks disagree; the largest share of a log the headline may leave out.
HEADLINE_TRIES = 4
HEADLINE_LEVELS = 2
MAX_LEFT_OUT = 0.5
#: Flagged stretches whose channels look ordinary are left out of the headline only if the rows kept still reach
#: SPAN_KEPT of the log's largest current of each sign and hold HIGH_KEPT of its rows above half that current: the
#: stretches that hold a log's high currents are its evidence of the curve's top, and a headline without them would
#: extrapolate there (on a real log, leaving out 672 of the 997 rows above 3 A made a significant saturation and a
#: peak torque of 4.5 N m at 6.7 A out of a log whose whole saw none). Calibrated on
#: test_fit_current::test_a_stretch_that_holds_the_highest_currents_stays_in_the_headline and
#: test_fit_current::test_a_stretch_that_holds_most_of_the_high_currents_stays_in_the_headline.
SPAN_KEPT = 0.9
HIGH_KEPT = 0.5


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
    report: FitReport
    """What the fit found, typed; its ``warnings`` are :attr:`warnings` (JSON: :meth:`report_json`)."""
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
    whole: Fitted | None = None
    """The fit to the whole log when the headline is a stretch of it (None when the headline is the whole log)."""
    left_out: tuple[Stretch, ...] = ()
    """The stretches of the whole log the headline leaves out, each read from its channels (rows of the whole log)."""

    def report_json(self) -> dict[str, Any]:
        """The ``hound-id/fit/3`` report with its ``warnings`` (what ``--json`` prints before ``plot`` and ``out``)."""
        return self.report.to_json()

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


def fit_warnings(report: FitReport) -> list[str]:
    """Warnings every user must see: parameters held at a physical bound, disagreeing blocks."""
    out = []
    for name, wanted in report.unphysical.items():
        est = report.parameters[name]
        out.append(
            f"{name} is held at its physical bound {est.value:.4g} {est.unit}: the unconstrained fit wants "
            f"{wanted:.4g} {est.unit}, which is not physical; the model lacks what the log shows there, or the "
            f"log cannot separate {name} from another term"
        )
    out += report.flags
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
    from hound_id.dyno.current.effects import Signals
    from hound_id.dyno.current.report import check_kt, fitted_motor, spec_checks

    sheet, model = _checked(data, options)
    log = _loaded(data, options)
    whole = _fit_log(Signals.from_log(log), log.torque, model, options, on_progress)
    fitted: Fitted = whole
    left_out: tuple[Stretch, ...] = ()
    option: str | None = None
    if options.window is None and not options.whole_log and whole.diagnosis.disagreeing.any():
        fitted, log, left_out, option = _headline(log, whole, model, options, on_progress)
    peak, comp, report = _report(data, log, fitted, whole, left_out, option)
    spec, out = options.spec, options.out
    warnings = fit_warnings(report)
    if report.headline is not None:
        warnings.insert(0, report.headline.sentence)
    check_kt(str(data), report.kt, sheet, str(spec))
    if sheet is not None:
        warnings += [f"against {spec}: {w}" for w in spec_checks(report, sheet)]
    motor = None
    if out is not None:
        motor = fitted_motor(report, out, spec, data.stem if sheet is None else None)
        warnings += _motor_warnings(motor, out, report, fitted.diagnosis)
    signals, fit, diagnosis = fitted.signals, fitted.fit, fitted.diagnosis
    figure = _figure(signals, log.torque, fit, fitted.start, diagnosis, options) if options.plot is not None else None
    return FitCurrentResult(
        data=data,
        options=options,
        log=log,
        signals=signals,
        start=fitted.start,
        fit=fit,
        diagnosis=diagnosis,
        ladder=fitted.ladder,
        peak=peak,
        compensation=comp,
        report=replace(report, warnings=tuple(warnings)),
        notes=tuple(n.message for n in log.notes if n.kind in NOTE_KINDS),
        log_warnings=tuple(n.message for n in log.notes if n.kind not in NOTE_KINDS),
        warnings=tuple(warnings),
        motor=motor,
        figure=figure,
        whole=whole if left_out else None,
        left_out=left_out,
    )


def _checked(data: Path, options: FitCurrentOptions) -> tuple[Any, tuple[str, ...]]:
    """Every input checked before the work (the log is a file, the flags agree, the output paths, the window, the
    spec sheet, the effects files, the model): the sheet (None without ``spec``) and the starting model."""
    from hound_id.dyno.current.effects import load_effects_file, parse_model, parse_start_model
    from hound_id.dyno.logs import parse_windows
    from hound_id.mor.spec_sheet import load_motor_spec

    spec, plot, out = options.spec, options.plot, options.out
    if Path(data).is_dir():
        from hound_id.errors import DynoDataError

        raise DynoDataError(
            f"{data}: is a folder; fit-current takes one log (.csv or .parquet): to fit every log in the folder and "
            f"compare them, run 'hound-id fleet {data}'",
            path=str(data),
        )
    if options.flip_torque and options.auto_sign:
        raise FitError(
            "--flip-torque and --auto-sign: found both; pass --flip-torque to negate every log's torque, or "
            "--auto-sign to let each log's own slope decide"
        )
    sources = (data, spec, *options.effects_files)
    io.check_output(plot, (".png",), "plot", inputs=sources)
    parse_windows(options.window)
    io.check_output(out, (".yaml", ".yml"), "fitted-motor", inputs=sources)
    sheet = load_motor_spec(spec) if spec is not None else None  # fail before the work on a bad sheet
    for path in options.effects_files:
        load_effects_file(path)
    names = list(parse_start_model(options.model))
    for extra in options.add:
        for effect_name in parse_model(extra):
            if effect_name in names:
                raise FitError(f"--add {effect_name}: the model already has it")
            names.append(effect_name)
    return sheet, tuple(names)


def _loaded(data: Path, options: FitCurrentOptions) -> DynoLog:
    """The cleaned log, windowed when ``options.window`` asks."""
    from hound_id.dyno.logs import load_log, parse_windows

    log = load_log(
        data,
        columns=_mapping(options.columns, "--columns"),
        units=_mapping(options.units, "--units"),
        flip_torque=options.flip_torque,
        auto_sign=options.auto_sign,
    )
    return log.windows(parse_windows(options.window)) if options.window is not None else log


def _report(
    data: Path, log: DynoLog, fitted: Fitted, whole: Fitted, left_out: tuple[Stretch, ...], option: str | None
) -> tuple[PeakTorque, Compensation, FitReport]:
    """The headline fit's peak torque, compensation and report; with stretches left out, the headline's reason and
    the whole log's fit beside it."""
    from hound_id.dyno.current.headline import headline_of, headline_summary
    from hound_id.dyno.current.report import summarize

    signals, ladder = fitted.signals, fitted.ladder
    peak, comp, report = summarize(
        str(data),
        fitted.fit,
        fitted.diagnosis,
        signals.current,
        list(ladder) if ladder is not None else None,
        log.notes,
        log.rows_read,
        current_limit=log.current_limit,
        time=signals.time if signals.timed else None,
        reply_range=log.current_range if any(_cuts_reply(n) for n in log.notes) else None,
    )
    report = replace(report, current_range=log.current_range)
    if left_out:
        parts = (whole.signals, whole.fit, whole.diagnosis, left_out)
        report = replace(report, headline=headline_of(*parts, option), summary=headline_summary(*parts, report.summary))
    return peak, comp, report


def _motor_warnings(motor: Mapping[str, Any], out: Path, report: FitReport, diagnosis: Diagnosis) -> list[str]:
    """What the user must know of the fitted-motor file: an extrapolated peak torque, a fit short of its floor."""
    warnings = []
    if "extrapolated" in motor:
        warnings.append(
            f"{out}: peak torque {motor['peak_torque']:.4g} N m is extrapolated beyond the measured currents "
            f"(|i| <= {report.peak.max_measured_current:.3g} A); written with "
            "'extrapolated: [peak_torque]'"
        )
    if not diagnosis.at_noise_floor:
        warnings.append(
            f"{out}: written from a fit that is not at the noise floor ({diagnosis.summary()}); "
            "its Kt and peak torque may be biased: add the missing effects (--auto) and write it again"
        )
    return warnings


def _fit_log(
    signals: Signals,
    torque: Any,
    model: tuple[str, ...],
    options: FitCurrentOptions,
    on_progress: Callable[[str], None] | None,
) -> Fitted:
    """Fit the starting model, then climb the ladder (``auto``) or diagnose once."""
    from hound_id.dyno.current.diagnose import auto as run_auto
    from hound_id.dyno.current.diagnose import diagnose
    from hound_id.dyno.current.fit import fit_model

    if on_progress is not None:
        on_progress(f"fitting {'+'.join(model)}")
    start = fit_model(signals, torque, model, robust=options.robust)
    if options.auto:

        def on_step(step: Step) -> None:
            if on_progress is not None:
                on_progress(f"diagnosed {'+'.join(step.model)}: held-out RMSE {step.fit.rmse_test:.3g} N m")

        ladder = tuple(run_auto(signals, torque, start, on_step=on_step))
        return Fitted(signals, start, ladder, ladder[-1].fit, ladder[-1].diagnosis)
    if on_progress is not None:
        on_progress("diagnosing")
    return Fitted(signals, start, None, start, diagnose(signals, torque, start))


def _headline(
    log: DynoLog,
    whole: Fitted,
    model: tuple[str, ...],
    options: FitCurrentOptions,
    on_progress: Callable[[str], None] | None,
) -> tuple[Fitted, DynoLog, tuple[Stretch, ...], str | None]:
    """The part of a log whose blocks agree, fitted on its own; the stretches left out, read from their channels
    (:mod:`hound_id.dyno.current.stretch`, in the whole log's rows); the ``--window`` that keeps the part (None when
    it is not a few ranges). The whole log when no part fits.

    Narrowed up to :data:`HEADLINE_LEVELS` times (a part's own blocks may disagree), never leaving out more than
    :data:`MAX_LEFT_OUT` of the log's rows that show torque per amp (a motor switched off or a frozen reply shows
    none, and leaving it out costs nothing).
    """
    import numpy as np

    fitted, part, rows = whole, log, np.arange(log.n)
    left: list[Stretch] = []
    budget = int(MAX_LEFT_OUT * log.n)
    for _ in range(HEADLINE_LEVELS):
        if not fitted.diagnosis.disagreeing.any():
            break
        step = _narrow(part, fitted, rows, model, options, on_progress, budget)
        if step is None:
            break
        fitted, part, rows, found, cost = step
        left += found
        budget -= cost
    if not left:
        return whole, log, (), None
    return fitted, part, tuple(sorted(left, key=lambda s: s.start)), _window_option(whole.signals, rows)


def _narrow(
    log: DynoLog,
    fitted: Fitted,
    rows: Any,
    model: tuple[str, ...],
    options: FitCurrentOptions,
    on_progress: Callable[[str], None] | None,
    budget: int,
) -> tuple[Fitted, DynoLog, Any, list[Stretch], int] | None:
    """One narrowing of :func:`_headline`: leave out the disagreeing stretches whose channels show a fault of the log
    (:data:`~hound_id.dyno.current.stretch.FAULTS`); or, when the agreeing blocks show no torque per amp (a motor off
    most of the log), keep the longest stretch that exercises the current; else leave out every flagged stretch
    (:func:`_leave_out_flagged`). ``rows`` are the
    whole log's rows of ``log``; the result's stretches are in the whole log's rows too, and the last value is how
    many rows that show torque per amp it left out (at most ``budget``)."""
    import dataclasses

    import numpy as np

    from hound_id.dyno.current.effects import Signals
    from hound_id.dyno.current.headline import span
    from hound_id.dyno.current.stretch import FAULTS, UNINFORMATIVE, candidates, read, runs
    from hound_id.dyno.logs import MIN_ROWS

    signals = fitted.signals
    edges = fitted.fit.blocks.edges
    bad = np.asarray(fitted.diagnosis.disagreeing, bool)

    def whole_rows(s: Stretch) -> Stretch:
        return dataclasses.replace(s, start=int(rows[s.start]), stop=int(rows[s.stop - 1]) + 1)

    def attempt(keep: Any, message: str, stretches: list[Stretch]) -> tuple[Any, ...] | None:
        blank = np.zeros(keep.size, dtype=bool)  # rows that show no torque per amp
        for s in stretches:
            if s.kind in UNINFORMATIVE:
                blank[s.start : s.stop] = True
        cost = int((~keep & ~blank).sum())
        if cost > budget or int(keep.sum()) < MIN_ROWS:
            return None
        try:
            part = log.without(np.flatnonzero(~keep), message)
            fitted = _fit_log(Signals.from_log(part), part.torque, model, options, on_progress)
        except HoundIdError:
            return None
        return fitted, part, rows[keep], [whole_rows(s) for s in stretches], cost

    kt = fitted.diagnosis.kt_agreeing
    faults = [s for s in fitted.diagnosis.stretches if s.kind in FAULTS]
    if faults:  # the log is broken there (read from its channels): leave those stretches out
        keep = np.ones(signals.current.size, dtype=bool)
        for s in faults:
            keep[s.start : s.stop] = False
        if on_progress is not None:
            on_progress("fitting the log without its broken stretches")
        what = ", ".join(f"{span(signals, s.start, s.stop)} ({s.kind})" for s in faults)
        done = attempt(keep, f"left out {int((~keep).sum())} rows of {what}", faults)
        if done is not None:
            return done  # type: ignore[return-value]
    if not _motor_off(log, fitted):
        return _leave_out_flagged(fitted, attempt, on_progress)
    # the motor is off from some point to the end (or until late): the agreeing part shows no torque per amp; keep the
    # longest stretch that does
    for a, b in candidates(signals, edges, bad, MIN_ROWS)[:HEADLINE_TRIES]:
        if on_progress is not None:
            on_progress(f"fitting the stretch {span(signals, a, b)} on its own")
        keep = np.zeros(signals.current.size, dtype=bool)
        keep[a:b] = True
        outside = np.ones(bad.size, dtype=bool)
        outside[(edges[:-1] >= a) & (edges[1:] <= b)] = False
        left = [
            read(signals, log.torque, fitted.fit.residual, int(edges[x]), int(edges[y]), kt) for x, y in runs(outside)
        ]
        message = f"kept {span(signals, a, b)}, the longest stretch that exercises the current"
        done = attempt(keep, message, left)
        if done is not None:
            return done  # type: ignore[return-value]
    return None


def _motor_off(log: DynoLog, fitted: Fitted) -> bool:
    """Whether the agreeing blocks are one run at an end of the log whose channels show the motor off (no torque per
    amp): the headline is then the longest stretch that exercises the current."""
    import numpy as np

    from hound_id.dyno.current.stretch import read, runs

    bad = np.asarray(fitted.diagnosis.disagreeing, bool)
    edges = fitted.fit.blocks.edges
    good = runs(~bad)
    if not (len(good) == 1 and (good[0][0] == 0 or good[0][1] == bad.size)):
        return False
    a0, b0 = int(edges[good[0][0]]), int(edges[good[0][1]])
    residual, kt = fitted.fit.residual, fitted.diagnosis.kt_agreeing
    return read(fitted.signals, log.torque, residual, a0, b0, kt).kind == "motor off"


def _leave_out_flagged(
    fitted: Fitted, attempt: Callable[[Any, str, list[Stretch]], Any], on_progress: Callable[[str], None] | None
) -> Any:
    """Leave out every stretch the diagnosis flags, each named by what its channels show (a step transient, another
    regime, a motor off midway): the headline is the part of the log that agrees; the whole log's fit, reported
    beside it, keeps what the stretches say (an effect the library lacks acts there, or the set-up changed). Not
    when the rows kept fall short of :data:`SPAN_KEPT` of the log's largest current of either sign, or of
    :data:`HIGH_KEPT` of its rows above half that current."""
    import numpy as np

    from hound_id.dyno.current.headline import span

    stretches = sorted(fitted.diagnosis.stretches, key=lambda s: s.start)
    if not stretches:
        return None
    signals = fitted.signals
    keep = np.ones(signals.current.size, dtype=bool)
    for s in stretches:
        keep[s.start : s.stop] = False
    if not keep.any():
        return None
    for i in (signals.current, -signals.current):  # each sign of the current
        top = float(np.max(i))
        high = i > 0.5 * top
        if top > 0 and (float(np.max(i[keep])) < SPAN_KEPT * top or float(np.mean(keep[high])) < HIGH_KEPT):
            return None  # the stretches hold the top of the current: they stay in, flagged
    if on_progress is not None:
        on_progress("fitting the log without its flagged stretches")
    what = ", ".join(f"{span(signals, s.start, s.stop)} ({s.kind})" for s in stretches)
    return attempt(keep, f"left out {int((~keep).sum())} rows the model does not follow: {what}", stretches)


def _window_option(signals: Signals, rows: Any) -> str | None:
    """``--window`` ranges that keep exactly ``rows`` of the whole log (at most four ranges), else None."""
    import numpy as np

    from hound_id.dyno.current.headline import window_keys

    breaks = np.flatnonzero(np.diff(rows) > 1)
    starts = np.concatenate(([rows[0]], rows[breaks + 1]))
    stops = np.concatenate((rows[breaks], [rows[-1]]))
    if starts.size > 4:
        return None
    keys = [window_keys(signals, int(a), int(b) + 1) for a, b in zip(starts, stops, strict=True)]
    # the log's own ends stay open, so that a printed bound cannot cut a row
    n = signals.current.size
    text = []
    for (lo, hi), a, b in zip(keys, starts, stops, strict=True):  # 10 digits: a printed bound cuts no row
        text.append(f"{'' if a == 0 else f'{lo:.10g}'}:{'' if b == n - 1 else f'{hi:.10g}'}")
    return "--window " + ",".join(text)


def _figure(
    signals: Signals, torque: Any, fit: FitResult, start: FitResult, diagnosis: Diagnosis, options: FitCurrentOptions
) -> FitFigure:
    """The fits the plot compares: before/after when the model changed, else the top suggestion's effect."""
    from hound_id.dyno.current.effects import parse_start_model
    from hound_id.dyno.current.fit import fit_model

    order = fit.hypers.get("cogging_order") or next(
        (s.hypers.get("cogging_order") for s in diagnosis.suggestions if s.effect == "cogging" and s.significant),
        None,
    )
    base = tuple(parse_start_model(options.model))
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


__all__ = [
    "FitCurrentOptions",
    "FitCurrentResult",
    "FitFigure",
    "Fitted",
    "fit_current",
    "fit_warnings",
    "write_outputs",
]
