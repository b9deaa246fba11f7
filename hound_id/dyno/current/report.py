"""Versioned outputs of ``hound-id fit-current``: the JSON report and the fitted-motor YAML."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from hound_id.dyno.current.curve import Compensation, PeakTorque
from hound_id.dyno.current.diagnose import Diagnosis, Step
from hound_id.dyno.current.fit import FitResult
from hound_id.dyno.current.fit_report import BlockRow, FitReport, Rows, Rung
from hound_id.mor.current_curve import CurrentCurve

#: A fitted Kt or peak torque further than this factor from the spec sheet's is warned about.
SPEC_FACTOR = 1.25


def summarize(
    source: str,
    fit: FitResult,
    diagnosis: Diagnosis,
    current: Any,
    ladder: Sequence[Step] | None = None,
    cleaning: Sequence[Any] = (),
    rows_read: int | None = None,
    current_limit: float | None = None,
    time: Any = None,
    reply_range: float | None = None,
) -> tuple[PeakTorque, Compensation, FitReport]:
    """Peak torque, current compensation (up to the peak, or the measured range) and the report of a fit.

    Args:
        current: The log's current [A]; its largest magnitude bounds the measured range.
        current_limit: The driver's current limit the log shows [A], if any.
        reply_range: Where the current reply's range ends [A], when the log shows it cut off there.
        time: Sample times [s] for the per-block table (None for a steady-state table).
    """
    from hound_id.dyno.current.curve import compensation, fitted_curve, peak_torque

    current_max = float(abs(current).max())
    peak = peak_torque(fit, current_max, current_limit=current_limit, reply_range=reply_range)
    comp = compensation(fit, peak.current if peak.current is not None else current_max)
    curve = fitted_curve(fit, current_max) if fit.value("kt") > 0 else None
    report = fit_report(source, fit, diagnosis, peak, comp, ladder, cleaning, rows_read, time, curve)
    return peak, comp, replace(report, current_limit=current_limit)


#: A fitted Kt further than this factor from the sheet's is refused: the RMS/peak (1.41) and the
#: phase/line (1.73) conventions together make 2.45; beyond that only a unit slip or a wrong
#: column explains it, and no motor is that far off its own sheet.
UNIT_FACTOR = 3.0


def check_kt(source: str, kt: float, spec: Any = None, spec_path: str | None = None) -> None:
    """Refuse a fitted Kt that only a wrong unit or column explains (one line, :class:`DynoDataError`).

    Without a sheet the fitted Kt must lie in the span of real motors
    (:data:`hound_id.mor.spec_sheet.PLAUSIBLE`); with one, within :data:`UNIT_FACTOR` of the sheet's.

    Args:
        source: The log, for the message.
        kt: Fitted torque constant [N m/A].
        spec: The motor's sheet (:class:`~hound_id.mor.spec.MotorSpec`), if given.
        spec_path: Its file, for the message.
    """
    from hound_id.errors import DynoDataError
    from hound_id.mor.spec_sheet import PLAUSIBLE

    fix = (
        "give each column's unit in the header (torque[mN*m], iq[A]) or with --units torque=mN*m,current=A, "
        "check --columns, and fit again"
    )
    lo, hi, _ = PLAUSIBLE["kt"]
    if spec is not None and kt > 0:
        ratio = kt / spec.kt
        if not 1 / UNIT_FACTOR <= ratio <= UNIT_FACTOR:
            raise DynoDataError(
                f"{source}: fitted Kt = {kt:.4g} N m/A is {ratio:.3g}x the sheet's {spec.kt:.4g} N m/A "
                f"({spec_path}); no motor is that far off its sheet{_unit_hint(ratio)}: {fix}",
                kt=kt,
                ratio=ratio,
            )
    if not lo <= kt <= hi:
        slip = "a torque in mN m read as N m or a current in A read as mA" if kt > hi else "the reverse slip"
        raise DynoDataError(
            f"{source}: fitted Kt = {kt:.4g} N m/A is outside {lo:g} to {hi:g} N m/A, the span of real motors "
            f"({slip} does this): {fix}",
            kt=kt,
        )


def _unit_hint(ratio: float) -> str:
    """', a factor 1000: ...' when ``ratio`` is near a milli-unit slip, else ''."""
    for factor in (1e3, 1e-3, 1e6, 1e-6):
        if 0.5 < ratio / factor < 2:
            return f" (about {factor:g}x: a torque in mN m read as N m, or a current in A read as mA, or the reverse)"
    return ""


def spec_checks(report: FitReport, spec: Any) -> list[str]:
    """Warnings where a fit disagrees with the motor's spec sheet (a :class:`~hound_id.mor.spec.MotorSpec`)."""
    out = []
    kt = report.kt
    ratio = kt / spec.kt
    if not 1 / SPEC_FACTOR <= ratio <= SPEC_FACTOR:
        out.append(
            f"fitted Kt = {kt:.4g} N m/A is {ratio:.3g}x the sheet's {spec.kt:.4g} N m/A (more than a factor "
            f"{SPEC_FACTOR:g} off): check the current and torque units and which side of a gearbox each is measured"
        )
    peak = report.peak
    if peak.torque is not None:
        ratio = peak.torque / spec.peak_torque
        if not 1 / SPEC_FACTOR <= ratio <= SPEC_FACTOR:
            out.append(
                f"fitted peak torque {peak.torque:.4g} N m is {ratio:.3g}x the sheet's {spec.peak_torque:.4g} N m "
                f"(more than a factor {SPEC_FACTOR:g} off)"
                + (" and is extrapolated beyond the measured current" if peak.extrapolated else "")
            )
    i_max = peak.max_measured_current
    if spec.max_current is not None and i_max > spec.max_current * 1.001:
        out.append(
            f"the log holds currents up to {i_max:.4g} A, beyond the sheet's max_current {spec.max_current:.4g} A: "
            "check the current's unit or scale, or the sheet"
        )
    return out


def fit_report(
    source: str,
    fit: FitResult,
    diagnosis: Diagnosis,
    peak: PeakTorque,
    comp: Compensation | None,
    ladder: Sequence[Step] | None = None,
    cleaning: Sequence[Any] = (),
    rows_read: int | None = None,
    time: Any = None,
    curve: CurrentCurve | None = None,
) -> FitReport:
    """The typed report of a fit (:class:`~hound_id.dyno.current.fit_report.FitReport`); its JSON, schema
    ``hound-id/fit/3`` (SI units), is :meth:`~hound_id.dyno.current.fit_report.FitReport.to_json`.

    Version 3 also carries ``noise`` (added later, so readers of version 3 without it still work): how
    ``noise_floor`` was found (``method``: ``still``, ``neighbours``, ``sample-to-sample`` or ``quantisation``; each
    estimate, the still rows and pieces, the neighbour pairs with their separations, standard errors and the drift,
    the torque channel's rounding, a sentence); and, added later still, ``rmse.outside_flagged`` (the
    cross-validated RMSE of the model fitted and scored without the blocks that disagree, null when none does) and
    each block's ``disagrees``; and ``wander`` (null on a short or untimed log, and while a significant effect is to be
    added or a few rows carry the residual): how the held-out
    residual's excess over the floor, outside the flagged stretches, divides between a slow wander and noise faster
    than ``window`` seconds (``share_slow``, ``slow_rms``, ``fast_sd``, ``fast_ratio``, ``sign_change_every``, ``mean``,
    ``kind``: slow, offset, fast or none, ``floor_is_wander``, ``follows_inputs``: the share moments with the same
    current and speed far apart in time predict, null when the log cannot say; ``sentence``: what the summary says of
    it, null when it says nothing).

    Version 3 (from 2): ``current_curve`` is the fitted current-torque curve, ``compensation`` its exact inverse
    (method and error) and ``compensation_polynomial`` the odd polynomial that ``compensation`` was in version 2.

    Version 2 (from 1): ``rmse.test`` is the blocked cross-validated error (every fold held
    out once), ``rmse.blocks`` gives it per time block, ``flags`` names disagreeing blocks,
    ``unphysical`` the parameters held at a physical bound, parameters carry ``at_bound``,
    suggestions ``physical``, and ``rows`` is {read, fitted, blocks, folds}.
    """
    edges = fit.blocks.edges
    blocks = []
    for c in range(fit.blocks.count):
        a, b = int(edges[c]), int(edges[c + 1])
        blocks.append(
            BlockRow(
                rows=(a, b - 1),
                fold=int(fit.blocks.fold[c]),
                rmse_held_out=float(fit.block_rmse[c]),
                noise_floor=float(diagnosis.block_floor[c]) if diagnosis.block_floor.size else None,
                disagrees=bool(diagnosis.disagreeing[c]) if diagnosis.disagreeing.size else False,
                time=(float(time[a]), float(time[b - 1])) if time is not None else None,
            )
        )
    return FitReport(
        source=source,
        model=tuple(fit.model),
        parameters=dict(fit.parameters),
        rmse_train=fit.rmse_train,
        rmse_test=fit.rmse_test,
        rmse_outside_flagged=diagnosis.rmse_outside,
        blocks=tuple(blocks),
        aic=fit.aic,
        bic=fit.bic,
        robust=fit.robust,
        rows=Rows(rows_read, fit.n_train, fit.blocks.count, fit.blocks.folds),
        unphysical=dict(fit.unphysical),
        flags=tuple(diagnosis.flags),
        peak=peak,
        curve=curve,
        polynomial=comp,
        suggestions=tuple(diagnosis.suggestions),
        skipped=tuple(diagnosis.skipped),
        outliers=diagnosis.outliers,
        noise_floor=diagnosis.noise_floor,
        noise=diagnosis.noise,
        wander=diagnosis.wander,
        wander_said=diagnosis.wander_said,
        at_noise_floor=diagnosis.at_noise_floor,
        summary=diagnosis.summary(),
        ladder=None if ladder is None else tuple(rung(s) for s in ladder),
        cleaning=tuple(cleaning),
    )


def rung(step: Step[tuple[str, ...], FitResult]) -> Rung:
    """A rung of the report's ``ladder``."""
    return Rung(
        model=tuple(step.model),
        added=step.added,
        rmse_train=step.fit.rmse_train,
        rmse_test=step.fit.rmse_test,
        at_noise_floor=step.diagnosis.at_noise_floor,
        aic=step.fit.aic,
        bic=step.fit.bic,
    )


def fitted_motor(report: FitReport, out: Path, spec: Path | None, name: str | None = None) -> dict[str, Any]:
    """A motor spec (schema hound-id/motor/1) whose fitted Kt and peak torque override ``spec``'s.

    With a spec sheet the file points at it (``base:``, relative to the output file),
    so ``hound-id mor --spec`` reads the sheet and applies the fit on top.
    """
    motor: dict[str, Any] = {"schema": "hound-id/motor/1"}
    if spec is not None:
        motor["base"] = os.path.relpath(spec.resolve(), out.resolve().parent)
    if name is not None:
        motor["name"] = name
    motor["kt"] = report.kt
    if report.peak.torque is not None:
        motor["peak_torque"] = report.peak.torque
        if report.peak.extrapolated:
            motor["extrapolated"] = ["peak_torque"]
    motor["source"] = f"hound-id fit-current on {report.source} (model {'+'.join(report.model)})"
    rendered = report.to_json()
    motor["fit"] = {k: rendered[k] for k in FITTED_MOTOR_KEYS}
    return motor


#: The parts of the report a fitted-motor file carries under ``fit``.
FITTED_MOTOR_KEYS = (
    "schema",
    "source",
    "model",
    "parameters",
    "rmse",
    "peak_torque",
    "current_curve",
    "compensation",
    "compensation_polynomial",
    "noise_floor",
    "at_noise_floor",
    "flags",
    "summary",
)
