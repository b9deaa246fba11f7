"""What ``hound-id fit-current`` found, typed: :class:`FitReport` and its parts, each a frozen dataclass that pickles
(the fleet's workers send it to the client) and renders the versioned JSON (``hound-id/fit/3``) with ``to_json``.

Every module that reads a fit (the verb, the fitted-motor file, the spec-sheet checks, the fleet, the command line)
reads these fields; the JSON is only ever written from them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, is_dataclass, replace
from typing import Any

from hound_id.dyno.current.curve import Compensation, PeakTorque
from hound_id.dyno.current.noise import NoiseFloor
from hound_id.dyno.current.stats import Estimate
from hound_id.dyno.current.wander import Wander
from hound_id.dyno.identify.engine import Suggestion
from hound_id.dyno.logs.columns import CleaningNote
from hound_id.mor.current_curve import CurrentCurve

SCHEMA = "hound-id/fit/3"


@dataclass(frozen=True)
class BlockRow:
    """One time block of the cross-validation."""

    rows: tuple[int, int]
    """Its first and last row."""
    fold: int
    """The fold that holds it out."""
    rmse_held_out: float
    """Held-out RMSE over the block [N m]."""
    noise_floor: float | None
    """The block's own noise floor [N m] (None when the diagnosis has none per block)."""
    disagrees: bool
    """Whether the block disagrees with the rest of the log."""
    time: tuple[float, float] | None = None
    """Its first and last sample time [s] (None for a steady-state table)."""

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "rows": list(self.rows),
            "fold": self.fold,
            "rmse_held_out": self.rmse_held_out,
            "noise_floor": self.noise_floor,
            "disagrees": self.disagrees,
        }
        if self.time is not None:
            out["time"] = list(self.time)
        return out


@dataclass(frozen=True)
class Rows:
    """How many rows the fit used, and how they were cut."""

    read: int | None
    """Rows read from the file (None when the log was built in code)."""
    fitted: int
    """Rows fitted (after cleaning and windowing)."""
    blocks: int
    """Time blocks."""
    folds: int
    """Cross-validation folds."""

    def to_json(self) -> dict[str, Any]:
        return {"read": self.read, "fitted": self.fitted, "blocks": self.blocks, "folds": self.folds}


@dataclass(frozen=True)
class Rung:
    """One rung of the add-an-effect ladder (``--auto``)."""

    model: tuple[str, ...]
    """The model on this rung."""
    added: str | None
    """The effect this rung added (None on the first)."""
    rmse_train: float
    """RMSE of the fit to every row [N m]."""
    rmse_test: float
    """Cross-validated RMSE [N m]."""
    at_noise_floor: bool
    """Whether this rung's error is at the noise floor."""
    aic: float
    """Akaike information criterion."""
    bic: float
    """Bayesian information criterion."""

    def to_json(self) -> dict[str, Any]:
        return {
            "model": list(self.model),
            "added": self.added,
            "rmse_train": self.rmse_train,
            "rmse_test": self.rmse_test,
            "at_noise_floor": self.at_noise_floor,
            "aic": self.aic,
            "bic": self.bic,
        }


@dataclass(frozen=True)
class LeftOut:
    """A stretch of the whole log the headline fit leaves out."""

    rows: tuple[int, int]
    """Its first and last row of the whole log."""
    kind: str
    """What it is (:mod:`hound_id.dyno.current.stretch`)."""
    reading: str
    """What its channels show, in one clause."""
    time: tuple[float, float] | None = None
    """Its first and last sample time [s] (None for an untimed log)."""

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"rows": list(self.rows), "kind": self.kind, "reading": self.reading}
        if self.time is not None:
            out["time"] = list(self.time)
        return out


@dataclass(frozen=True)
class WholeLog:
    """The fit to the whole log, when the headline is fitted to part of it."""

    model: tuple[str, ...]
    """Its model."""
    parameters: Mapping[str, Estimate]
    """Its parameters."""
    rmse_test: float
    """Its cross-validated RMSE [N m]."""
    noise_floor: float
    """The whole log's noise floor [N m]."""
    at_noise_floor: bool
    """Whether its error is at the floor."""
    flags: tuple[str, ...]
    """What disagrees in the whole log."""
    summary: str
    """Its verdict in one sentence."""

    def to_json(self) -> dict[str, Any]:
        return {
            "model": list(self.model),
            "parameters": {name: est.to_dict() for name, est in self.parameters.items()},
            "rmse_test": self.rmse_test,
            "noise_floor": self.noise_floor,
            "at_noise_floor": self.at_noise_floor,
            "flags": list(self.flags),
            "summary": self.summary,
        }


@dataclass(frozen=True)
class Headline:
    """Why the headline fit leaves part of the log out, and the whole log's own fit."""

    option: str | None
    """The option that repeats the headline's choice (``--window ...``), None when none does."""
    sentence: str
    """What was left out and why, for the user."""
    whole_log: WholeLog
    """The whole log's fit."""
    left_out: tuple[LeftOut, ...]
    """The stretches left out."""


@dataclass(frozen=True)
class FitReport:
    """Everything a fit found that leaves the verb: the ``hound-id/fit/3`` report (:meth:`to_json`), typed.

    Small and picklable (no log arrays): the fleet's workers return it."""

    source: str
    """The log it was fitted to."""
    model: tuple[str, ...]
    """Effects in the final model, in order."""
    parameters: Mapping[str, Estimate]
    """Every parameter, with its standard error and unit."""
    rmse_train: float
    """RMSE of the fit to every row [N m]."""
    rmse_test: float
    """Blocked cross-validated RMSE, every fold held out once [N m]."""
    rmse_outside_flagged: float | None
    """Cross-validated RMSE fitted and scored without the disagreeing blocks [N m] (None when none disagrees)."""
    blocks: tuple[BlockRow, ...]
    """Each time block's held-out error."""
    aic: float
    """Akaike information criterion."""
    bic: float
    """Bayesian information criterion."""
    robust: bool
    """Whether Huber weights were used."""
    rows: Rows
    """Rows read, fitted, blocks and folds."""
    unphysical: Mapping[str, float]
    """Parameters held at a physical bound, with the value the unconstrained fit wants."""
    flags: tuple[str, ...]
    """Disagreeing blocks and train/held-out mismatches, one sentence each."""
    peak: PeakTorque
    """Where the fitted curve bends 20 % from linear."""
    curve: CurrentCurve | None
    """The fitted current-torque curve (None when Kt is not positive)."""
    polynomial: Compensation | None
    """The odd polynomial compensation (``compensation_polynomial``)."""
    suggestions: tuple[Suggestion, ...]
    """Candidate effects, significant first."""
    skipped: tuple[str, ...]
    """Effects not tried, with the reason."""
    outliers: str | None
    """A sentence when a few far-off rows carry most of the residual."""
    noise_floor: float
    """The noise floor the verdicts use [N m]."""
    noise: NoiseFloor | None
    """How the floor was found."""
    wander: Wander | None
    """How the held-out residual's excess over the floor divides between slow and fast."""
    wander_said: str | None
    """What the summary says of the wander (None: nothing)."""
    at_noise_floor: bool
    """Whether the cross-validated error is at the floor."""
    summary: str
    """The verdict in one sentence."""
    ladder: tuple[Rung, ...] | None
    """The ``--auto`` ladder (None without it)."""
    cleaning: tuple[CleaningNote, ...]
    """What loading the log changed."""
    current_limit: float | None = None
    """The driver's current limit the log shows [A]."""
    current_range: float | None = None
    """Where the current reply's range ends [A], when the log shows it."""
    headline: Headline | None = None
    """Why the headline leaves part of the log out (None when it fits the whole log)."""
    warnings: tuple[str, ...] = ()
    """What every user must see, in the order shown."""

    def value(self, name: str) -> float:
        """A parameter's value in SI units (``KeyError`` when the model lacks it)."""
        return self.parameters[name].value

    @property
    def kt(self) -> float:
        """The fitted torque constant [N m/A]."""
        return self.value("kt")

    def relabel(self, old: str, new: str) -> FitReport:
        """The same report with ``old`` replaced by ``new`` in every text it holds (the fleet's workers fit a copy of
        each log: its messages must name the log as the user gave it)."""
        out = _relabelled(self, old, new)
        assert isinstance(out, FitReport)
        return out

    def to_json(self) -> dict[str, Any]:
        """The ``hound-id/fit/3`` report (SI units; see :func:`hound_id.dyno.current.report.fit_report` for what
        each version added)."""
        out: dict[str, Any] = {
            "schema": SCHEMA,
            "source": self.source,
            "model": list(self.model),
            "parameters": {name: est.to_dict() for name, est in self.parameters.items()},
            "rmse": {
                "train": self.rmse_train,
                "test": self.rmse_test,
                "outside_flagged": self.rmse_outside_flagged,
                "blocks": [b.to_json() for b in self.blocks],
            },
            "aic": self.aic,
            "bic": self.bic,
            "robust": self.robust,
            "rows": self.rows.to_json(),
            "unphysical": dict(self.unphysical),
            "flags": list(self.flags),
            "peak_torque": self.peak.to_dict(),
            "current_curve": None if self.curve is None else self.curve.to_dict(),
            "compensation": None if self.curve is None else self.curve.compensation(),
            "compensation_polynomial": None if self.polynomial is None else self.polynomial.to_dict(),
            "suggestions": [suggestion_dict(s) for s in self.suggestions],
            "skipped": list(self.skipped),
            "outliers": self.outliers,
            "noise_floor": self.noise_floor,
            "noise": None if self.noise is None else self.noise.to_dict(),
            "wander": None if self.wander is None else self.wander.to_dict(self.wander_said),
            "at_noise_floor": self.at_noise_floor,
            "summary": self.summary,
            "ladder": None if self.ladder is None else [r.to_json() for r in self.ladder],
            "cleaning": [{"kind": n.kind, "rows": n.rows, "message": n.message} for n in self.cleaning],
            "units": {"torque": "N m", "current": "A", "rmse": "N m", "noise_floor": "N m"},
            "current_limit": self.current_limit,
            "current_range": self.current_range,
        }
        if self.headline is not None:
            out["headline"] = {"option": self.headline.option, "sentence": self.headline.sentence}
            out["whole_log"] = self.headline.whole_log.to_json()
            out["left_out"] = [s.to_json() for s in self.headline.left_out]
        out["warnings"] = list(self.warnings)
        return out


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


def _relabelled(value: Any, old: str, new: str) -> Any:
    """``value`` with ``old`` replaced by ``new`` in every string inside it: dataclasses (their init fields), tuples,
    lists and mappings are rebuilt, anything else (numbers, arrays) is kept."""
    if isinstance(value, str):
        return value.replace(old, new)
    if is_dataclass(value) and not isinstance(value, type):
        changed = {f.name: _relabelled(getattr(value, f.name), old, new) for f in fields(value) if f.init}
        return replace(value, **changed)
    if isinstance(value, tuple | list):
        return type(value)(_relabelled(v, old, new) for v in value)
    if isinstance(value, Mapping):
        return {_relabelled(k, old, new): _relabelled(v, old, new) for k, v in value.items()}
    return value
