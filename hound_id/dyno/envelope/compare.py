"""``hound-id mor --compare``: the add-an-effect ladder over envelope models.

**What is missing.** Each candidate effect of :mod:`hound_id.mor.envelope` is fitted on top of
the model (bounded scalar search of its parameter, the model's parameters refitted with it) and
ranked by the share of the envelope error's sum of squares it explains. It is significant when
the partial F statistic (SSE0 - SSE1) / (SSE1 / (bins - 1)) beats F(1, bins - 1) at 1 % divided
by the number of candidates (Bonferroni), and when the envelope error falls by at least the
noise level (an effect too small to matter is not suggested). ``--add`` and ``--auto`` grow the
model as in ``fit-current``; :func:`unneeded` names the effects the final model can drop.

"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.dyno.envelope.evidence import bus_evidence, contradicts, current_evidence
from hound_id.dyno.envelope.offsets import (
    MIN_BINS,
    IsolatedBin,
    Offsets,
    OutsideStats,
    at_limit,
    isolated_bins,
    offsets,
    outside_stats,
    past_edges,
)
from hound_id.dyno.envelope.walls import Walls, find_walls, inputs_for
from hound_id.dyno.identify.engine import ALPHA, Step, Suggestion, climb, corrected, f_pvalue, rank, significant
from hound_id.dyno.logs import EnvelopeLog
from hound_id.errors import DynoDataError, SpecError
from hound_id.mor.envelope import EFFECTS, EnvelopeInputs, Polyline, effect_names, polyline
from hound_id.units import DEG_S_PER_RAD_S, MNM_PER_NM, NCM_PER_NM, RPM_PER_RAD_S

Array = NDArray[np.float64]

__all__ = [
    "ALPHA",
    "EXPLAINED",
    "IMPLAUSIBLE",
    "OUTSIDE_OK",
    "REFUTE",
    "Comparison",
    "Step",
    "Suggestion",
    "compare",
    "suggest",
    "unneeded",
]

#: The model explains the envelope when its error is at most this many noise levels (3 sigma) ... Calibrated on
#: test_compare::test_the_hidden_effect_is_named_and_explains_the_envelope and
#: test_mor_compare_cli::test_out_is_refused_when_the_model_does_not_explain_the_log.
EXPLAINED = 3.0

#: ... and (for the spec sheet itself) at most this share of the samples lies past its edges (half a percent: glitches,
#: not a region that is wrong). Calibrated on test_compare::test_a_log_past_the_region_is_measured_and_located.
OUTSIDE_OK = 0.005

#: A candidate is refuted when more than OUTSIDE_OK of the samples pass its edges by this share of the torque limit (5
#: %: far beyond the noise, a compromise between two effects passes by less). Calibrated on
#: test_compare::test_a_candidate_the_log_passes_is_refuted.
REFUTE = 0.05

#: A log's 99th-percentile torque or speed past this multiple of the torque limit or overspeed is a unit mistake: most
#: samples of a log lie inside the region. The unit suggested is the smallest that brings the percentile within
#: UNIT_SLACK of the limit. Calibrated on
#: test_compare::test_an_empty_optional_column_is_left_out_and_implausible_units_are_refused.
IMPLAUSIBLE = 2.0
IMPLAUSIBLE_QUANTILE = 0.99
UNIT_SLACK = 1.2
#: A current-limit search runs from CURRENT_SEARCH[0] to CURRENT_SEARCH[1] x the spec's current limit (a driver clamps
#: below its motor's rating; a hair above it lets the search reach the spec's own value). Calibrated on
#: test_compare::test_the_hidden_effect_is_named_and_explains_the_envelope.
CURRENT_SEARCH = (0.05, 1.0001)
#: Bounded scalar searches stop at this share of their interval (far below any effect's standard error). Calibrated on
#: test_compare::test_the_hidden_effect_is_named_and_explains_the_envelope.
SEARCH_TOLERANCE = 1e-5
#: A candidate is refuted when its share of samples past its edges also exceeds SPILL_GROWTH x the spec sheet's (a log
#: that already spills over the sheet does not refute every effect). Calibrated on
#: test_compare::test_a_candidate_the_log_passes_is_refuted.
SPILL_GROWTH = 2.0
#: A logged channel's evidence is attached to a suggestion that explains more than this share of the envelope error (its
#: own effect, not one that merely helps). Calibrated on test_compare::test_a_wrong_add_does_not_hide_the_right_effect.
EVIDENCE_EXPLAINED = 0.5
#: A refitted parameter is named in the reason when it moved by more than this share of itself (display only).
MOVED = 1e-3
#: Rungs of the automatic ladder past the spec sheet. Calibrated on
#: test_mor_compare_cli::test_a_wrong_add_names_the_right_effect_and_then_says_it_is_not_needed.
MAX_STEPS = 4


def _bounds(name: str, inputs: EnvelopeInputs) -> tuple[float, float]:
    """The search interval of an effect's parameter (a current limit: up to the spec's own)."""
    lo_b, hi_b = EFFECTS[name].bounds
    if not math.isfinite(hi_b):
        top = inputs.spec.max_current or inputs.spec.linear_torque_limit / inputs.spec.kt
        hi_b = top * CURRENT_SEARCH[1]
        lo_b = CURRENT_SEARCH[0] * hi_b
    return lo_b, hi_b


def _at_bound(name: str, value: float, inputs: EnvelopeInputs) -> bool:
    """Whether a fitted parameter sits at a bound of its search (not identified), other than its neutral value."""
    return EFFECTS[name].param.at_bound(value, *_bounds(name, inputs))


def _fit_one(
    log: EnvelopeLog, walls: Walls, model: Mapping[str, float], name: str, inputs: EnvelopeInputs
) -> tuple[float, float, bool]:
    """(fitted parameter, sum of squares, whether it sits at a bound of the search), the others held."""
    from scipy.optimize import minimize_scalar

    lo_b, hi_b = _bounds(name, inputs)
    at = at_limit(log, walls, inputs)  # the samples gathered once for the search's evaluations
    res = minimize_scalar(
        lambda v: at.offsets({**model, name: float(v)}).sse,
        bounds=(lo_b, hi_b),
        method="bounded",
        options={"xatol": (hi_b - lo_b) * SEARCH_TOLERANCE},
    )
    return float(res.x), float(res.fun), _at_bound(name, float(res.x), inputs)


def suggest(log: EnvelopeLog, walls: Walls, model: Mapping[str, float], inputs: EnvelopeInputs) -> list[Suggestion]:
    """Every candidate effect fitted on top of ``model``, best first (module docstring)."""
    base = offsets(log, walls, model, inputs)
    n = base.offset.size
    if n < MIN_BINS:
        raise SpecError(
            f"{log.source}: only {n} speed bins show the motor at its limits (method: {walls.method}); the log does "
            "not push the motor to its envelope, so there is nothing to compare. Log commands past the limits, or "
            "add a torque_cmd column"
        )
    names = [c for c in effect_names(inputs_for(log, inputs, np.arange(log.n))) if c not in model]
    excess0 = np.nan_to_num(past_edges(log, inputs, base.sample_noise, model)[0], nan=0.0)
    spill0 = float(np.mean(excess0 > REFUTE * inputs.spec.linear_torque_limit))
    out = []
    for name in names:
        fitted = _fit_candidate(log, walls, model, name, inputs)
        out.append(_candidate(log, model, name, fitted, base, inputs, spill0, len(names)))
    return rank(_with_evidence(out, log, inputs), verdict_first=False)


def _fit_candidate(
    log: EnvelopeLog, walls: Walls, model: Mapping[str, float], name: str, inputs: EnvelopeInputs
) -> tuple[float, float, bool, dict[str, float]]:
    """(value, envelope sum of squares, at a bound of its search, the model refitted with it) of a candidate."""
    value, sse1, at_bound = _fit_one(log, walls, model, name, inputs)
    refit = dict(model)
    if model:
        # Refit the model's own parameters with the candidate in, from two starts: the candidate on top of the
        # model, and the candidate alone (the model's effects then refitted): an effect added wrongly must not
        # hide the right one.
        alone = _fit_one(log, walls, {}, name, inputs)[0]
        for start in ({**model, name: value}, {**model, name: alone}):
            joint = _refit(log, walls, start, inputs, all_params=True, lead=name)
            sse_joint = offsets(log, walls, joint, inputs).sse
            if sse_joint < sse1:
                value, sse1 = joint.pop(name), sse_joint
                refit = joint
                at_bound = _at_bound(name, value, inputs)
    return value, sse1, at_bound, refit


def _candidate(
    log: EnvelopeLog,
    model: Mapping[str, float],
    name: str,
    fitted: tuple[float, float, bool, dict[str, float]],
    base: Offsets,
    inputs: EnvelopeInputs,
    spill0: float,
    candidates: int,
) -> Suggestion:
    """A fitted candidate scored against the model: its F-test, material, identified, refuted past its edges."""
    value, sse1, at_bound, refit = fitted
    n = base.offset.size
    dof = max(n - 1, 1)
    f_stat = max(base.sse - sse1, 0.0) / max(sse1 / dof, 1e-30)
    p = f_pvalue(f_stat, 1, dof)
    effect = EFFECTS[name]
    # the whole log must fit inside: an effect whose edges the log passes by far is refuted by it (a fit that
    # compromises between two effects passes its samples by a little)
    excess = past_edges(log, inputs, base.sample_noise, {**refit, name: value})[0]
    spill = float(np.mean(np.nan_to_num(excess, nan=0.0) > REFUTE * inputs.spec.linear_torque_limit))
    refuted = spill > max(OUTSIDE_OK, SPILL_GROWTH * spill0)
    moved = ", ".join(
        f"{k} refitted {model[k]:.4g} -> {v:.4g} {EFFECTS[k].unit}"
        for k, v in refit.items()
        if abs(v - model[k]) > MOVED * max(abs(model[k]), 1e-12)
    )
    return Suggestion(
        effect=name,
        value=value,
        unit=effect.unit,
        explained=max(0.0, (base.sse - sse1) / base.sse) if base.sse > 0 else 0.0,
        rmse=math.sqrt(sse1 / n),
        statistic=float(f_stat),
        p_value=p,
        p_adjusted=corrected(p, 1, candidates),
        # statistically and practically: the F-test, and an error that falls by at least the noise level
        significant=significant(
            corrected(p, 1, candidates),
            material=base.rmse - math.sqrt(sse1 / n) >= base.noise,
            identified=not at_bound,
            refuted=refuted,
        ),
        reason=(
            f"{effect.physics}; {effect.parameter} = {value:.4g} {effect.unit} takes the envelope error from "
            f"{base.rmse:.3g} to {math.sqrt(sse1 / n):.3g} N m over {n} bins at the limit"
            + (f" ({moved})" if moved else "")
            + (
                f" (refuted: {spill:.1%} of the samples lie more than {REFUTE:.0%} of the torque limit past "
                "its edges; the log makes torque it forbids)"
                if refuted
                else ""
            )
            + (" (at the bound of its search: not identified)" if at_bound else "")
        ),
        refit=refit,
    )


def _with_evidence(out: list[Suggestion], log: EnvelopeLog, inputs: EnvelopeInputs) -> list[Suggestion]:
    """The suggestions with what the logged bus voltage and current settle (a sag contradicted, support)."""
    # Logged channels settle what the envelope alone cannot: a sagging bus, inductance and a saturating core all
    # shorten the motoring edge at speed; the bus voltage and the current say which it is.
    for named, evidence in (("bus_sag", bus_evidence(log, inputs)), ("kt_saturation", current_evidence(log, inputs))):
        if evidence is None:
            continue
        for k, sug in enumerate(out):
            if named == "bus_sag" and sug.effect == named and contradicts(sug.value, evidence):
                # the logged bus is the direct measurement: a sag it does not show is another effect's shortfall
                out[k] = replace(
                    sug,
                    significant=False,
                    reason=sug.reason + f"; contradicted: {evidence.text}, not {sug.value:.3g} ohm",
                )
            elif sug.effect == named and sug.explained > EVIDENCE_EXPLAINED:
                out[k] = replace(sug, reason=sug.reason + f"; {evidence.text}", supported=evidence.significant)
    return out


@dataclass(frozen=True)
class Comparison:
    """Everything ``hound-id mor --compare`` found."""

    log: EnvelopeLog
    inputs: EnvelopeInputs
    walls: Walls
    """The samples at the limit, found against the final model's edges."""
    ladder: tuple[Step[dict[str, float], Offsets], ...]
    outside: OutsideStats
    """Where the log leaves the spec sheet's region."""
    baseline: Offsets | None = None
    """The spec sheet's offsets on the final walls (the fair 'before' of the final model)."""
    unneeded: tuple[Unneeded, ...] = ()
    """Effects of the final model the log does not need once the others are in (:func:`unneeded`)."""
    isolated: tuple[IsolatedBin, ...] = ()
    """Single bins left out as chance walls (:func:`isolated_bins`): speed, edge, offset, se."""
    outside_final: float = 0.0
    """Share of the samples past the final model's edges (as :func:`outside_stats` counts them)."""

    @property
    def final(self) -> Step[dict[str, float], Offsets]:
        return self.ladder[-1]

    @cached_property
    def polyline(self) -> Polyline:
        """The final model's edges as polylines (:func:`~hound_id.mor.envelope.polyline`), computed once for the JSON
        and the spec file."""
        return polyline(self.final.model, self.inputs)


def compare(
    log: EnvelopeLog, inputs: EnvelopeInputs, add: Sequence[str] = (), auto: bool = False, max_steps: int = MAX_STEPS
) -> Comparison:
    """Compare a log with the spec's region; add the named effects, or with ``auto`` the best significant one
    until none is left (at most ``max_steps``)."""
    for name in add:
        if name not in EFFECTS:
            raise SpecError(f"--add: unknown effect {name!r}; effects are {', '.join(EFFECTS)}")
    _plausible(log, inputs)
    walls = find_walls(log, inputs)

    def rung(model: dict[str, float], added: str | None, refound: bool = False) -> Step[dict[str, float], Offsets]:
        found = offsets(log, walls, model, inputs)
        return Step(dict(model), added, found, tuple(suggest(log, walls, model, inputs)), refound=refound)

    def grow(step: Step[dict[str, float], Offsets], chosen: Suggestion) -> Step[dict[str, float], Offsets]:
        nonlocal walls
        model = {**step.model, **chosen.refit, chosen.effect: chosen.value}
        # with the effect in, edges the spec sheet missed line up: look for walls again and refit on them
        again = find_walls(log, inputs, model, commanded=walls.commanded)
        refound = _bins(again) >= _bins(walls)
        if refound:
            walls = again
            model = _refit(log, walls, model, inputs, all_params=True)
        return rung(model, chosen.effect, refound)

    def untestable(name: str) -> SpecError:
        return SpecError(
            f"--add {name}: not testable on this log (it needs {', '.join(EFFECTS[name].requires) or 'nothing'}"
            " that is missing, or is already in the model)"
        )

    ladder = climb(rung({}, None), grow, add=add, auto=auto, max_steps=max_steps, untestable=untestable)
    base, model = ladder[0].offsets, ladder[-1].model
    walls, isolated = isolated_bins(walls, offsets(log, walls, model, inputs), inputs.spec.back_emf_damping)
    if isolated:  # the last rung on the walls that are left
        last = ladder[-1]
        ladder[-1] = replace(last, result=offsets(log, walls, model, inputs))
    baseline = offsets(log, walls, {}, inputs)
    return Comparison(
        log,
        inputs,
        walls,
        tuple(ladder),
        outside_stats(log, inputs, base.sample_noise),
        baseline=baseline,
        unneeded=tuple(unneeded(log, walls, model, inputs)),
        isolated=tuple(isolated),
        outside_final=float(past_edges(log, inputs, base.sample_noise, model)[2].mean()),
    )


@dataclass(frozen=True)
class Unneeded:
    """An effect of the final model the log does not need once the others are in (:func:`unneeded`)."""

    effect: str
    value: float
    """Its fitted parameter [the effect's unit]."""
    rmse_without: float
    """The envelope error without it, the others refitted [N m]."""
    p_value: float
    """The drop's partial F-test p-value (uncorrected)."""
    reason: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "effect": self.effect,
            "value": self.value,
            "rmse_without": self.rmse_without,
            "p_value": self.p_value,
            "reason": self.reason,
        }


def unneeded(log: EnvelopeLog, walls: Walls, model: Mapping[str, float], inputs: EnvelopeInputs) -> list[Unneeded]:
    """The model's effects the log does not need once the others are in: each dropped in turn, the rest refitted;
    needed only if the drop is significant (partial F-test at :data:`ALPHA` / effects) and raises the envelope
    error by at least the noise level, as for adding one (the one rule,
    :func:`~hound_id.dyno.identify.engine.significant`). Empty for models of fewer than two effects."""
    if len(model) < 2:
        return []
    full = offsets(log, walls, model, inputs)
    n, dof = full.offset.size, max(full.offset.size - len(model), 1)
    out = []
    for name in model:
        rest = _refit(log, walls, {k: v for k, v in model.items() if k != name}, inputs, all_params=True)
        without = offsets(log, walls, rest, inputs)
        f_stat = max(without.sse - full.sse, 0.0) / max(full.sse / dof, 1e-30)
        p = f_pvalue(f_stat, 1, dof)
        if significant(corrected(p, 1, len(model)), material=without.rmse - full.rmse >= full.noise):
            continue
        others = ", ".join(f"{k} = {v:.4g} {EFFECTS[k].unit}" for k, v in rest.items())
        reason = (
            f"without it (and {others} refitted) the envelope error is {without.rmse:.3g} N m against "
            f"{full.rmse:.3g} N m with it over {n} bins (p = {p:.2g}): the log does not need it"
        )
        out.append(Unneeded(name, model[name], without.rmse, p, reason))
    return out


def _plausible(log: EnvelopeLog, inputs: EnvelopeInputs) -> None:
    """Refuse a log whose torque or speed the motor cannot have made: most samples of a log lie inside the region,
    so a 99th percentile past :data:`IMPLAUSIBLE` x the torque limit or the overspeed is a unit mistake."""
    from hound_id.mor.region import linear_region

    spec = inputs.spec
    overspeed = linear_region(spec).overspeed
    for name, values, limit, unit, units in (
        ("torque", log.torque, spec.linear_torque_limit, "N m", (("N*cm", NCM_PER_NM), ("mN*m", MNM_PER_NM))),
        ("velocity", log.velocity, overspeed, "rad/s", (("rpm", RPM_PER_RAD_S), ("deg/s", DEG_S_PER_RAD_S))),
    ):
        p99 = float(np.quantile(np.abs(values), IMPLAUSIBLE_QUANTILE))
        if p99 > IMPLAUSIBLE * limit:
            fits = [u for u, factor in units if p99 / factor <= UNIT_SLACK * limit]  # the smallest unit that fits
            hint = f"--units {name}={fits[0]}" if fits else "--units " + " or ".join(f"{name}={u}" for u, _ in units)
            raise DynoDataError(
                f"{log.source}: {name} reaches {p99:.4g} {unit} (99th percentile), over {IMPLAUSIBLE:g}x what "
                f"{spec.name} can ({limit:.4g} {unit}); check its unit: a [unit] in the header or {hint}"
            )


def _bins(walls: Walls) -> int:
    return sum(w.size > 0 for w in walls.upper) + sum(w.size > 0 for w in walls.lower)


def _refit(
    log: EnvelopeLog,
    walls: Walls,
    model: Mapping[str, float],
    inputs: EnvelopeInputs,
    all_params: bool = False,
    lead: str | None = None,
) -> dict[str, float]:
    """One coordinate-descent sweep over the model's parameters, each refitted with the others fixed (``lead``,
    if given, is held first and refitted last)."""
    fitted = dict(model)
    if len(fitted) > 1 or all_params:
        order = [k for k in fitted if k != lead] + ([lead] if lead in fitted else [])
        for name in order:
            others = {k: v for k, v in fitted.items() if k != name}
            fitted[name] = _fit_one(log, walls, others, name, inputs)[0]
    return fitted
