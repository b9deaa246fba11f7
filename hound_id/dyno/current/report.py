"""Versioned outputs of ``hound-id fit-current``: the JSON report and the fitted-motor YAML."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hound_id.dyno.current.curve import Compensation, PeakTorque
from hound_id.dyno.current.diagnose import Diagnosis, Step, Suggestion
from hound_id.dyno.current.fit import FitResult
from hound_id.mor.current_curve import CurrentCurve

SCHEMA = "hound-id/fit/3"
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
) -> tuple[PeakTorque, Compensation, dict[str, Any]]:
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
    report["current_limit"] = current_limit
    return peak, comp, report


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


def spec_checks(report: dict[str, Any], spec: Any) -> list[str]:
    """Warnings where a fit disagrees with the motor's spec sheet (a :class:`~hound_id.mor.spec.MotorSpec`)."""
    out = []
    kt = report["parameters"]["kt"]["value"]
    ratio = kt / spec.kt
    if not 1 / SPEC_FACTOR <= ratio <= SPEC_FACTOR:
        out.append(
            f"fitted Kt = {kt:.4g} N m/A is {ratio:.3g}x the sheet's {spec.kt:.4g} N m/A (more than a factor "
            f"{SPEC_FACTOR:g} off): check the current and torque units and which side of a gearbox each is measured"
        )
    peak = report["peak_torque"]
    if peak["torque"] is not None:
        ratio = peak["torque"] / spec.peak_torque
        if not 1 / SPEC_FACTOR <= ratio <= SPEC_FACTOR:
            out.append(
                f"fitted peak torque {peak['torque']:.4g} N m is {ratio:.3g}x the sheet's {spec.peak_torque:.4g} N m "
                f"(more than a factor {SPEC_FACTOR:g} off)"
                + (" and is extrapolated beyond the measured current" if peak["extrapolated"] else "")
            )
    i_max = peak["max_measured_current"]
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
) -> dict[str, Any]:
    """JSON-ready report, schema ``hound-id/fit/3`` (SI units).

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
        entry: dict[str, Any] = {
            "rows": [a, b - 1],
            "fold": int(fit.blocks.fold[c]),
            "rmse_held_out": float(fit.block_rmse[c]),
            "noise_floor": float(diagnosis.block_floor[c]) if diagnosis.block_floor.size else None,
            "disagrees": bool(diagnosis.disagreeing[c]) if diagnosis.disagreeing.size else False,
        }
        if time is not None:
            entry["time"] = [float(time[a]), float(time[b - 1])]
        blocks.append(entry)
    return {
        "schema": SCHEMA,
        "source": source,
        "model": list(fit.model),
        "parameters": {name: est.to_dict() for name, est in fit.parameters.items()},
        "rmse": {
            "train": fit.rmse_train,
            "test": fit.rmse_test,
            "outside_flagged": diagnosis.rmse_outside,
            "blocks": blocks,
        },
        "aic": fit.aic,
        "bic": fit.bic,
        "robust": fit.robust,
        "rows": {"read": rows_read, "fitted": fit.n_train, "blocks": fit.blocks.count, "folds": fit.blocks.folds},
        "unphysical": dict(fit.unphysical),
        "flags": list(diagnosis.flags),
        "peak_torque": peak.to_dict(),
        "current_curve": None if curve is None else curve.to_dict(),
        "compensation": None if curve is None else curve.compensation(),
        "compensation_polynomial": None if comp is None else comp.to_dict(),
        "suggestions": [suggestion_dict(s) for s in diagnosis.suggestions],
        "skipped": list(diagnosis.skipped),
        "outliers": diagnosis.outliers,
        "noise_floor": diagnosis.noise_floor,
        "noise": None if diagnosis.noise is None else diagnosis.noise.to_dict(),
        "wander": None if diagnosis.wander is None else diagnosis.wander.to_dict(diagnosis.wander_said),
        "at_noise_floor": diagnosis.at_noise_floor,
        "summary": diagnosis.summary(),
        "ladder": None if ladder is None else [step_dict(s) for s in ladder],
        "cleaning": [{"kind": n.kind, "rows": n.rows, "message": n.message} for n in cleaning],
        "units": {"torque": "N m", "current": "A", "rmse": "N m", "noise_floor": "N m"},
    }


def suggestion_dict(s: Suggestion) -> dict[str, Any]:
    """A suggestion of the report (``p_value`` is the corrected one, ``rmse_test`` the cross-validated RMSE)."""
    return {
        "effect": s.effect,
        "explained": s.explained,
        "significant": s.significant,
        "physical": s.physical,
        "p_value": None if math.isnan(s.p_adjusted) else s.p_adjusted,
        "rmse_test": None if math.isnan(s.rmse) else s.rmse,
        "reason": s.reason,
    }


def step_dict(step: Step[tuple[str, ...], FitResult]) -> dict[str, Any]:
    """A rung of the report's ``ladder``."""
    return {
        "model": list(step.model),
        "added": step.added,
        "rmse_train": step.fit.rmse_train,
        "rmse_test": step.fit.rmse_test,
        "at_noise_floor": step.diagnosis.at_noise_floor,
        "aic": step.fit.aic,
        "bic": step.fit.bic,
    }


def fitted_motor(report: dict[str, Any], out: Path, spec: Path | None, name: str | None = None) -> dict[str, Any]:
    """A motor spec (schema hound-id/motor/1) whose fitted Kt and peak torque override ``spec``'s.

    With a spec sheet the file points at it (``base:``, relative to the output file),
    so ``hound-id mor --spec`` reads the sheet and applies the fit on top.
    """
    motor: dict[str, Any] = {"schema": "hound-id/motor/1"}
    if spec is not None:
        motor["base"] = os.path.relpath(spec.resolve(), out.resolve().parent)
    if name is not None:
        motor["name"] = name
    motor["kt"] = report["parameters"]["kt"]["value"]
    if report["peak_torque"]["torque"] is not None:
        motor["peak_torque"] = report["peak_torque"]["torque"]
        if report["peak_torque"]["extrapolated"]:
            motor["extrapolated"] = ["peak_torque"]
    motor["source"] = f"hound-id fit-current on {report['source']} (model {'+'.join(report['model'])})"
    motor["fit"] = {
        k: report[k]
        for k in (
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
    }
    return motor
