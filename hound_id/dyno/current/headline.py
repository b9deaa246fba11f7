"""What the headline fit leaves out of a log, said: the report's headline (the stretches, why, the option that
repeats the choice, the whole log's fit) and the verdict said to hold for the rest of the log only; rows as the user
reads them (a time span, or data rows of a steady-state table)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from hound_id.dyno.current.fit_report import Headline, LeftOut, WholeLog
from hound_id.dyno.current.stretch import FAULTS, UNINFORMATIVE, Stretch

if TYPE_CHECKING:
    from hound_id.dyno.current.diagnose import Diagnosis
    from hound_id.dyno.current.effects import Signals
    from hound_id.dyno.current.fit import FitResult


def window_keys(signals: Signals, a: int, b: int) -> tuple[float, float]:
    """The --window bounds that keep rows a..b-1 (seconds, or 1-based data rows of a steady-state table)."""
    if signals.timed:
        return float(signals.time[a]), float(signals.time[b - 1])
    return float(signals.time[a]) + 1.0, float(signals.time[b - 1]) + 1.0


def span(signals: Signals, a: int, b: int) -> str:
    """Rows a..b-1 as the user reads them: "t = 1.2-3.4 s", or "data rows 5-9" of a steady-state table."""
    lo, hi = window_keys(signals, a, b)
    return f"t = {lo:.4g}-{hi:.4g} s" if signals.timed else f"data rows {lo:.0f}-{hi:.0f}"


def headline_summary(
    signals: Signals, fit: FitResult, diagnosis: Diagnosis, left_out: Sequence[Stretch], summary: str
) -> str:
    """The headline's verdict, said to hold for the rest of the log only when stretches that look ordinary (another
    regime, a step transient: maybe an effect the library lacks) were left out of it."""
    ordinary = [s for s in left_out if s.kind not in FAULTS and s.kind not in UNINFORMATIVE]
    if not ordinary:
        return summary
    spans = "; ".join(f"{span(signals, s.start, s.stop)}: {s.kind}" for s in ordinary)
    error, floor = fit.rmse_test, diagnosis.noise_floor
    ratio = f", {error / floor:.3g}x its floor" if floor > 0 else ""
    return (
        f"the log as a whole does not follow one model: the headline leaves out {spans} (the whole log's "
        f"cross-validated error is {error:.3g} N m{ratio}); on the rest: {summary}"
    )


def headline_of(
    signals: Signals, fit: FitResult, diagnosis: Diagnosis, left_out: Sequence[Stretch], option: str | None
) -> Headline:
    """What the headline leaves out of the whole log (its ``signals``, ``fit`` and ``diagnosis``) and why, the option
    that repeats it, a sentence, and the whole log's fit."""
    kt = fit.parameters.get("kt")
    kt_text = f"Kt = {kt.value:.4g} +- {kt.stderr:.2g} N m/A" if kt is not None else "no Kt"
    parts = "; ".join(f"{span(signals, s.start, s.stop)}: {s.kind} ({s.reading})" for s in left_out)
    repeat = f" ({option})" if option is not None else ""
    sentence = (
        f"part of the log disagrees with the rest, so the headline fit leaves it out{repeat}: {parts}. The whole log "
        f"gives {kt_text} with a cross-validated error of {fit.rmse_test:.3g} N m (pass --whole-log to make "
        "it the headline)"
    )
    whole_log = WholeLog(
        model=tuple(fit.model),
        parameters=dict(fit.parameters),
        rmse_test=fit.rmse_test,
        noise_floor=diagnosis.noise_floor,
        at_noise_floor=diagnosis.at_noise_floor,
        flags=tuple(diagnosis.flags),
        summary=diagnosis.summary(),
    )
    spans = tuple(
        LeftOut(
            rows=(s.start, s.stop - 1),
            kind=s.kind,
            reading=s.reading,
            time=(float(signals.time[s.start]), float(signals.time[s.stop - 1])) if signals.timed else None,
        )
        for s in left_out
    )
    return Headline(option=option, sentence=sentence, whole_log=whole_log, left_out=spans)
