"""Diagnosis: which physical effect is the model missing, and is the residual down to noise?

For the current fit, every registered effect not yet in the model (whose channels the
log has) is added in turn; its nonlinear parameter is searched on the log. Each
candidate is first checked: the log must be able to tell its parameters from the
model's (:func:`hound_id.dyno.current.identifiable.identifiability`), and it must fit with physically
possible values (a candidate that explains the residual only with, say, Coulomb
friction below zero is reported as such and never added). It is then scored by
blocked cross-validation (every fold of time blocks held out once) and tested with a
Wald test on cluster-robust standard errors (the time blocks are the clusters, so
correlated residuals do not fake significance). The p-value is Bonferroni-corrected
for the values its search tried and for the number of candidates.

A candidate is **significant** when the corrected p-value is below ``alpha`` and it is
**material**: it lowers the cross-validated mean-square error by at least
:data:`MATERIAL` of the noise variance (an effect whose RMS is a fifth of the noise
or more), so a model at the noise floor is not grown for a 0.03 % gain.

The noise floor (:mod:`hound_id.dyno.current.noise`) is the larger of the residual's
sample-to-sample noise (second differences: right for white noise, low for a filtered
transducer) and its scatter where every input holds still (right whatever the noise's
colour), when the log holds still long enough; never below the torque channel's rounding.

The verdict compares blocks too: a block whose held-out error is several times the
others' and its own noise (a motor switched off, a current running away, a change of
regime) is flagged with its rows and times, and a log with such blocks is never "at
the noise floor". So is a fold whose fit is much worse on its training rows than on
the rows it holds out.

The trials are in :mod:`hound_id.dyno.current.trials`, what the diagnosis says of the log itself (flags,
outliers, the agreeing part) in :mod:`hound_id.dyno.current.flags`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hound_id.dyno.current.effects import Signals, get, inputs
from hound_id.dyno.current.fit import FitResult, fit_model
from hound_id.dyno.current.flags import (
    BLOCK_FACTOR,
    KT_UNDETERMINED,
    OUTLIER_SIGMAS,
    Agreeing,
    agreeing_kt,
    disagreeing_blocks,
    outlier_rows,
    rmse_outside,
    share_of,
    stretch_flags,
    typical_rows,
)
from hound_id.dyno.current.noise import NoiseFloor, estimate, white_floor
from hound_id.dyno.current.search import FILTERS, Design, bounds_of
from hound_id.dyno.current.slope import agreeing_half
from hound_id.dyno.current.stats import Array, Stats, cross_validate
from hound_id.dyno.current.stretch import Stretch, read, runs
from hound_id.dyno.current.trials import (
    MATERIAL,
    ORDER_TRIALS,
    candidates_for,
    dynamics_trace,
    effect_trial,
    filter_trial,
    shift_trial,
    trials,
)
from hound_id.dyno.current.wander import Wander, wander
from hound_id.dyno.identify.engine import (
    ALPHA,
    MAX_STEPS,
    Step,
    Suggestion,
    best,
    climb,
    corrected,
    f_pvalue,
    rank,
    significant,
)
from hound_id.errors import FitError

__all__ = [
    "ALPHA",
    "BLOCK_FACTOR",
    "FLOOR_FACTOR",
    "KT_UNDETERMINED",
    "MATERIAL",
    "ORDER_TRIALS",
    "OUTLIER_SIGMAS",
    "Diagnosis",
    "Step",
    "Suggestion",
    "auto",
    "candidates_for",
    "diagnose",
    "noise_floor",
]

#: A held-out RMSE within this factor of the noise floor counts as at the floor (the floor estimate itself scatters by
#: about 10 % on a block of a few thousand rows). Calibrated on
#: test_diagnose::test_each_hidden_effect_is_named_first_and_adding_it_reaches_the_noise and
#: test_diagnose::test_noise_only_data_has_nothing_significant.
FLOOR_FACTOR = 1.2


#: The floor is never below this share of the torque's RMS (the rounding of the fit's own arithmetic, far below any
#: sensor). Calibrated on test_logs::test_a_table_of_26_operating_points_and_a_burst_written_16_times_are_read.
NUMERICAL_FLOOR = 1e-6


@dataclass(frozen=True)
class Diagnosis:
    """What the residual of a fit says."""

    model: tuple[str, ...]
    """The diagnosed model."""
    rmse_test: float
    """Its cross-validated RMSE [N m]."""
    noise_floor: float
    """Estimated measurement noise (standard deviation) [N m]."""
    at_noise_floor: bool
    """Held-out RMSE within FLOOR_FACTOR of the floor, no significant effect, and no disagreeing block."""
    suggestions: tuple[Suggestion, ...]
    """Candidates, significant first, then the most residual explained."""
    skipped: tuple[str, ...] = ()
    """Effects not tried, with the reason (missing channel, not identifiable on this log)."""
    outliers: str | None = None
    """A sentence when a few far-off rows carry most of the residual."""
    flags: tuple[str, ...] = ()
    """Blocks of the log that disagree with the rest, and train/held-out mismatches."""
    block_floor: Array = field(default_factory=lambda: np.empty(0))
    """Noise floor of each time block [N m]."""
    disagreeing: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    """Blocks whose error under the model fitted to the agreeing half of the blocks is BLOCK_FACTOR times both
    the typical agreeing block's and their own noise."""
    block_agreeing: Array = field(default_factory=lambda: np.empty(0))
    """Each block's RMSE under the model fitted to the agreeing half of the blocks [N m]."""
    noise: NoiseFloor | None = None
    """How :attr:`noise_floor` was found (its method and both estimates)."""
    kt_agreeing: float | None = None
    """Kt of the fit to the agreeing half of the blocks [N m/A] (None without a ``linear`` term)."""
    stretches: tuple[Stretch, ...] = ()
    """Each run of disagreeing blocks, read from its channels (rows of the diagnosed log), in log order."""
    rmse_outside: float | None = None
    """The cross-validated RMSE of the model fitted and scored without the disagreeing blocks [N m] (None when none
    disagrees): how far the model is from the floor where the flagged stretches do not count."""
    wander: Wander | None = None
    """How the held-out residual's excess over the floor, outside the flagged stretches, divides between a slow
    wander and fast noise, and what the inputs predict of it (None on an untimed or a short log, and while a
    significant effect is to be added or a few rows carry the residual)."""

    @property
    def best(self) -> Suggestion | None:
        """The significant suggestion that explains most, if any."""
        return best(self.suggestions)

    @property
    def floor_label(self) -> str:
        """The floor with how it was found, e.g. '0.36 N m, its scatter where the inputs hold still'."""
        how = {
            "still": "the torque's scatter where the inputs hold still",
            "neighbours": "the torque's scatter between far-apart moments with the same inputs",
            "quantisation": "the torque channel's rounding",
        }.get(self.noise.method if self.noise is not None else "", "sample-to-sample")
        return f"{self.noise_floor:.3g} N m, {how}"

    def _outside(self) -> str:
        """How far the model is from the floor outside the flagged stretches, when some are flagged."""
        if self.rmse_outside is None or not self.noise_floor > 0:
            return ""
        return (
            f"; outside the flagged stretches the cross-validated residual is {self.rmse_outside:.3g} N m, "
            f"{self.rmse_outside / self.noise_floor:.2g}x the floor"
        )

    @property
    def wander_said(self) -> str | None:
        """What the summary says the excess outside the flagged stretches is (or, at the floor, that half of the floor
        is slow); None when it says nothing of it: a significant effect or a few outlying rows come first."""
        if self.wander is None or self.best is not None or self.outliers:
            return None
        left = self.rmse_outside if self.rmse_outside is not None else self.rmse_test
        if left > FLOOR_FACTOR * self.noise_floor and self.wander.excess:
            return self.wander.sentence()
        return self.wander.floor_sentence() if self.wander.floor_is_wander else None

    def _wander(self) -> str:
        said = self.wander_said
        return "" if said is None else f"; {said}"

    def summary(self) -> str:
        """One sentence on where the model stands."""
        ratio = self.rmse_test / self.noise_floor if self.noise_floor > 0 else math.inf
        if self.at_noise_floor:
            return (
                f"the cross-validated residual ({self.rmse_test:.3g} N m) is at the noise floor "
                f"({self.floor_label}); no missing effect is significant{self._wander()}"
            )
        if self.best is not None:
            head = (
                f"cross-validated residual {self.rmse_test:.3g} N m is {ratio:.2g}x the noise floor "
                f"({self.floor_label}); add '{self.best.effect}': {self.best.reason}"
            )
            return f"{head}; also: {self.flags[0]}{self._outside()}" if self.flags else head
        if self.outliers:
            return f"no candidate effect is significant, but {self.outliers}"
        if self.flags:
            return f"part of the log does not follow any model tried: {self.flags[0]}{self._outside()}{self._wander()}"
        if ratio <= FLOOR_FACTOR:
            return (
                f"no candidate effect is significant and material; {self.rmse_test:.3g} N m is at the noise floor"
                f"{self._wander()}"
            )
        head = (
            f"no candidate effect is significant, but the cross-validated residual is {ratio:.2g}x the noise floor "
            f"({self.floor_label}){self._wander()}"
        )
        if self.skipped:
            return f"{head}; not tried: {'; '.join(self.skipped)}"
        return f"{head}: something outside the library is missing"


def noise_floor(residual: Array) -> float:
    """Standard deviation of white measurement noise in a residual series [N m] (second differences; reads low for
    correlated noise: :func:`hound_id.dyno.current.noise.estimate` is the floor the verdicts use)."""
    return white_floor(residual)


@dataclass(frozen=True)
class _Baseline:
    """The diagnosed fit on its log: columns, statistics, cross-validated error, agreeing half, noise floor."""

    design: Design
    shifted: Signals
    """The signals the fit's columns are built from (shifted by its delay)."""
    Z: Array
    """The model's columns with a column of ones first."""
    stats: Stats
    cols: list[int]
    lower: Array
    upper: Array
    base_sse: float
    """The model's cross-validated sum of squares [N^2 m^2]."""
    residual_search: Array
    agreeing: Agreeing
    noise: NoiseFloor
    floor: float
    """The noise floor the verdicts use [N m]."""


def diagnose(
    signals: Signals, torque: Array, fit: FitResult, *, candidates: Sequence[str] | None = None, alpha: float = ALPHA
) -> Diagnosis:
    """Rank the effects missing from ``fit`` by cross-validated residual explained, with significance."""
    names, skipped = candidates_for(fit.model, signals)
    if candidates is not None:
        names = [c for c in candidates if c in names]
    base = _baseline(signals, torque, fit)
    suggestions = []
    dynamics = dynamics_trace(signals, fit, base.floor) if any(n in FILTERS for n in names) and signals.timed else None
    for name in names:
        tried = _try(name, signals, torque, fit, base, dynamics, len(names), alpha)
        if isinstance(tried, str):
            skipped.append(f"{name} ({tried})")
            continue
        suggestions.append(tried)
    return _diagnosis(signals, fit, base, rank(suggestions), skipped)


def _baseline(signals: Signals, torque: Array, fit: FitResult) -> _Baseline:
    """The fit's columns, statistics and cross-validated error on the log, its agreeing half and the noise floor."""
    design = Design(signals, torque)
    shifted = inputs(signals, fit.model, fit.hypers)
    X = design.model_columns(fit.model, fit.hypers, shifted)
    Z = design.with_ones(X)
    stats = Stats(Z, design.torque, design.blocks)
    cols = list(range(1, Z.shape[1]))
    lower, upper = bounds_of(fit.model)
    base_sse = cross_validate(stats, stats, cols, lower, upper).sse
    residual_search = np.asarray(fit.residual)[design.search]
    agreeing = Agreeing(*agreeing_half(stats, cols, lower, upper, np.asarray(fit.block_rmse)))
    noise = estimate(signals, design.torque, np.asarray(fit.residual), rows=typical_rows(design, agreeing))
    # never below the arithmetic's own noise: a noiseless log's residual is rounding, not a missing effect
    floor = max(noise.value, NUMERICAL_FLOOR * float(np.sqrt(np.mean(design.torque**2))))
    return _Baseline(design, shifted, Z, stats, cols, lower, upper, base_sse, residual_search, agreeing, noise, floor)


def _try(
    name: str,
    signals: Signals,
    torque: Array,
    fit: FitResult,
    base: _Baseline,
    dynamics: str | None,
    candidates: int,
    alpha: float,
) -> Suggestion | str:
    """One candidate's trial scored as a suggestion (of ``candidates`` tried), or why it could not be tried."""
    try:
        if get(name).shift:
            trial = shift_trial(name, signals, torque, fit)
        elif name in FILTERS:
            trial = dynamics if dynamics is not None else filter_trial(name, signals, torque, fit)
        else:
            trial = effect_trial(name, fit, base.design, base.shifted, base.Z, base.stats, base.residual_search)
    except FitError as err:
        trial = str(err)
    if isinstance(trial, str):
        return trial
    n = base.design.torque.size
    base_sse, floor = base.base_sse, base.floor
    explained = (base_sse - trial.cv_sse) / base_sse if base_sse > 0 else 0.0
    gain = (base_sse - trial.cv_sse) / n  # fall of the cross-validated mean-square error [N^2 m^2]
    material = bool(math.isfinite(floor) and gain >= MATERIAL * floor**2 and gain > 0)
    dfd = max(base.design.blocks.count - 1, 1)
    p = f_pvalue(trial.wald, trial.q, dfd) if trial.p_value is None else trial.p_value
    p_adj = corrected(p, trials(name), candidates)
    rmse = math.sqrt(trial.cv_sse / n)
    effect = get(name)
    # unphysical only if the effect is there: the fit without bounds passes the same test
    p_free = (
        p_adj
        if trial.p_value is not None
        else corrected(f_pvalue(trial.wald_free, trial.q, dfd), trials(name), candidates)
    )
    unphysical = trial.unphysical if p_free < alpha else None
    verdict = significant(p_adj, material=material, physical=trial.unphysical is None, alpha=alpha)
    if unphysical is not None:
        reason = unphysical
    elif verdict:
        reason = effect.evidence(trial.values, signals) if effect.evidence is not None else "it fits"
        reason += f" (explains {explained:.1%} of the cross-validated residual, p = {p_adj:.2g})"
    else:
        reason = _not_kept(explained, gain, p_adj, floor, alpha)
    return Suggestion(
        effect=name,
        explained=float(explained),
        significant=verdict,
        p_value=p,
        p_adjusted=p_adj,
        rmse=rmse,
        reason=reason,
        statistic=trial.wald,
        physical=unphysical is None,
        hypers=trial.hypers,
    )


def _not_kept(explained: float, gain: float, p_adj: float, floor: float, alpha: float) -> str:
    """Why a physically possible candidate is not significant: immaterial, worse held out, or not significant."""
    if p_adj < alpha and gain > 0:
        return (
            f"real (p = {p_adj:.2g}) but immaterial: it lowers the cross-validated mean-square error by "
            f"{share_of(gain, floor**2)} of the noise variance, less than {MATERIAL:.0%}"
        )
    if p_adj < alpha:
        return (
            f"fits the log better (p = {p_adj:.2g}) but raises the cross-validated error by {-explained:.2%}: not kept"
        )
    return f"explains {explained:.2%} of the cross-validated residual; not significant (p = {p_adj:.2g})"


def _diagnosis(
    signals: Signals, fit: FitResult, base: _Baseline, suggestions: list[Suggestion], skipped: list[str]
) -> Diagnosis:
    """The diagnosis of ranked suggestions: disagreeing stretches, flags, outliers, the verdict, the wander."""
    design, agreeing, noise, floor = base.design, base.agreeing, base.noise, base.floor
    block_floor = np.array([noise_floor(np.asarray(fit.residual)[s]) for s in design.blocks.slices()])
    disagreeing = disagreeing_blocks(agreeing, floor, block_floor)
    kt = agreeing_kt(fit, agreeing)
    residual = np.asarray(fit.residual)
    edges = design.blocks.edges
    stretches = tuple(
        read(signals, design.torque, residual, int(edges[a]), int(edges[b]), kt) for a, b in runs(disagreeing)
    )
    flags = tuple(stretch_flags(fit, agreeing, noise, floor, disagreeing, signals, stretches))
    at_floor = bool(fit.rmse_test <= FLOOR_FACTOR * floor and not any(s.significant for s in suggestions) and not flags)
    held_out = np.asarray(fit.held_out)
    keep = np.repeat(~disagreeing, np.diff(edges))
    outliers = outlier_rows(fit, floor, signals)
    # read only where the summary may say it: no significant effect is to be added first, no few rows carry the residual
    time_scale = (
        wander(signals.time, held_out, floor, keep, [x for x in (signals.current, signals.velocity) if x is not None])
        if signals.timed
        and held_out.size == signals.time.size == keep.size
        and best(suggestions) is None
        and outliers is None
        else None
    )
    return Diagnosis(
        fit.model,
        fit.rmse_test,
        floor,
        at_floor,
        tuple(suggestions),
        tuple(skipped),
        outliers,
        flags,
        block_floor,
        disagreeing,
        agreeing.rmse,
        noise,
        kt,
        stretches,
        rmse_outside(base.stats, base.cols, base.lower, base.upper, disagreeing),
        time_scale,
    )


def auto(
    signals: Signals,
    torque: Array,
    start: FitResult,
    *,
    max_steps: int = MAX_STEPS,
    alpha: float = ALPHA,
    on_step: Any = None,
) -> list[Step[tuple[str, ...], FitResult]]:
    """Add the most explaining significant (physical, material) effect until none is left; the ladder of fits
    (:func:`hound_id.dyno.identify.engine.climb`; each rung's ``fit`` and ``diagnosis``).

    The ladder stops at the noise floor: there no candidate is material by construction of the rule.
    """

    def rung(fit: FitResult, added: str | None) -> Step[tuple[str, ...], FitResult]:
        diagnosis = diagnose(signals, torque, fit, alpha=alpha)
        return Step(fit.model, added, fit, diagnosis.suggestions, diagnosis)

    def grow(step: Step[tuple[str, ...], FitResult], chosen: Suggestion) -> Step[tuple[str, ...], FitResult]:
        fit = fit_model(signals, torque, (*step.fit.model, chosen.effect), robust=step.fit.robust)
        return rung(fit, chosen.effect)

    return climb(
        rung(start, None),
        grow,
        auto=True,
        max_steps=max_steps,
        on_step=on_step,
        at_floor=lambda step: bool(step.diagnosis.at_noise_floor),
    )
