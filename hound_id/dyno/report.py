"""Versioned outputs of ``hound-id fit-current``: the JSON report and the fitted-motor YAML."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hound_id.dyno.curve import Compensation, PeakTorque
from hound_id.dyno.diagnose import Diagnosis, Step
from hound_id.dyno.fit import FitResult

SCHEMA = "hound-id/fit/1"


def summarize(
    source: str,
    fit: FitResult,
    diagnosis: Diagnosis,
    current: Any,
    ladder: Sequence[Step] | None = None,
    cleaning: Sequence[Any] = (),
    rows_read: int | None = None,
) -> tuple[PeakTorque, Compensation, dict[str, Any]]:
    """Peak torque, current compensation (up to the peak, or the measured range) and the report of a fit.

    Args:
        current: The log's current [A]; its largest magnitude bounds the measured range.
    """
    from hound_id.dyno.curve import compensation, peak_torque

    current_max = float(abs(current).max())
    peak = peak_torque(fit, current_max)
    comp = compensation(fit, peak.current if peak.current is not None else current_max)
    return peak, comp, fit_report(source, fit, diagnosis, peak, comp, ladder, cleaning, rows_read)


def fit_report(
    source: str,
    fit: FitResult,
    diagnosis: Diagnosis,
    peak: PeakTorque,
    comp: Compensation | None,
    ladder: Sequence[Step] | None = None,
    cleaning: Sequence[Any] = (),
    rows_read: int | None = None,
) -> dict[str, Any]:
    """JSON-ready report, schema ``hound-id/fit/1`` (SI units)."""
    return {
        "schema": SCHEMA,
        "source": source,
        "model": list(fit.model),
        "parameters": {name: est.to_dict() for name, est in fit.parameters.items()},
        "rmse": {"train": fit.rmse_train, "test": fit.rmse_test},
        "aic": fit.aic,
        "bic": fit.bic,
        "robust": fit.robust,
        "rows": {"read": rows_read, "train": fit.n_train, "test": fit.n_test},
        "peak_torque": peak.to_dict(),
        "compensation": None if comp is None else comp.to_dict(),
        "suggestions": [s.to_dict() for s in diagnosis.suggestions],
        "skipped": list(diagnosis.skipped),
        "outliers": diagnosis.outliers,
        "noise_floor": diagnosis.noise_floor,
        "at_noise_floor": diagnosis.at_noise_floor,
        "summary": diagnosis.summary(),
        "ladder": None if ladder is None else [s.to_dict() for s in ladder],
        "cleaning": [{"kind": n.kind, "rows": n.rows, "message": n.message} for n in cleaning],
        "units": {"torque": "N m", "current": "A", "rmse": "N m", "noise_floor": "N m"},
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
            "compensation",
            "noise_floor",
            "at_noise_floor",
            "summary",
        )
    }
    return motor
