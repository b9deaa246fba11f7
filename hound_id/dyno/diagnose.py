"""Diagnosis: which physical effect is the model missing, and is the residual down to noise?

For the current fit, every registered effect not yet in the model (whose channels the
log has) is added in turn; its nonlinear parameter is searched on the training rows.
Each candidate is scored by the fraction of the **held-out** residual sum of squares it
removes, and tested with a partial F-test on the training rows (nested linear models).
The p-value is Bonferroni-corrected for the values its search tried and for the number
of candidates, so on pure-noise residuals nothing is significant at the stated level.
A candidate is significant when the corrected p-value is below ``alpha`` and it lowers
the held-out error.

The noise floor is estimated from the residual itself: for white measurement noise of
standard deviation sigma, second differences in time have variance 6 sigma^2, while
effects that are smooth at the sample rate nearly cancel; the median absolute
deviation keeps steps and spikes from inflating it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hound_id.dyno.effects import REGISTRY, Signals, get, requirements_missing
from hound_id.dyno.fit import Array, Design, FitResult, Normal, fit_model, mask_slices, search_hyper
from hound_id.errors import FitError

#: Significance level after the multiple-comparison corrections.
ALPHA = 0.01
#: A held-out RMSE within this factor of the noise floor counts as at the floor.
FLOOR_FACTOR = 1.2
#: Residuals beyond this many noise-floor sigmas count as outliers in the summary.
OUTLIER_SIGMAS = 8.0
#: Effective number of values an order search scans (the residual's angular spectrum bins).
ORDER_TRIALS = 511


@dataclass(frozen=True)
class Suggestion:
    """An effect not in the model, scored on the held-out rows."""

    effect: str
    """Effect name."""
    explained: float
    """Fraction of the held-out residual sum of squares the effect removes (negative: it makes it worse)."""
    significant: bool
    """Whether the corrected partial F-test rejects 'no effect' and the held-out error falls."""
    p_value: float
    """Corrected p-value (Bonferroni over search values and candidates)."""
    rmse_test: float
    """Held-out RMSE with the effect added [N m]."""
    reason: str
    """The evidence in one sentence."""
    hypers: Mapping[str, float] = field(default_factory=dict)
    """Nonlinear parameter values with the effect added (e.g. the cogging order found)."""

    def to_dict(self) -> dict[str, Any]:
        return {
            "effect": self.effect,
            "explained": self.explained,
            "significant": self.significant,
            "p_value": self.p_value,
            "rmse_test": self.rmse_test,
            "reason": self.reason,
        }


@dataclass(frozen=True)
class Diagnosis:
    """What the residual of a fit says."""

    model: tuple[str, ...]
    """The diagnosed model."""
    rmse_test: float
    """Its held-out RMSE [N m]."""
    noise_floor: float
    """Estimated measurement noise (standard deviation) [N m]."""
    at_noise_floor: bool
    """Whether the held-out RMSE is within FLOOR_FACTOR of the floor and no effect is significant."""
    suggestions: tuple[Suggestion, ...]
    """Candidates, the most held-out residual explained first."""
    skipped: tuple[str, ...] = ()
    """Effects not tried, with the reason (missing channel)."""
    outliers: str | None = None
    """A sentence when a few far-off rows carry most of the residual."""

    @property
    def best(self) -> Suggestion | None:
        """The significant suggestion that explains most, if any."""
        sig = [s for s in self.suggestions if s.significant]
        return sig[0] if sig else None

    def summary(self) -> str:
        """One sentence on where the model stands."""
        ratio = self.rmse_test / self.noise_floor if self.noise_floor > 0 else math.inf
        if self.at_noise_floor:
            return (
                f"the held-out residual ({self.rmse_test:.3g} N m) is at the noise floor "
                f"({self.noise_floor:.3g} N m); no missing effect is significant"
            )
        if self.best is None:
            head = (
                f"no candidate effect is significant, but the held-out residual is {ratio:.2g}x the noise floor "
                f"({self.noise_floor:.3g} N m)"
            )
            if self.outliers:
                return f"{head}: {self.outliers}"
            if self.skipped:
                return f"{head}; not tried for lack of channels: {'; '.join(self.skipped)}"
            return f"{head}: something outside the library is missing"
        return (
            f"held-out residual {self.rmse_test:.3g} N m is {ratio:.2g}x the noise floor "
            f"({self.noise_floor:.3g} N m); add '{self.best.effect}': {self.best.reason}"
        )


def noise_floor(residual: Array) -> float:
    """Standard deviation of white measurement noise in a residual series [N m] (see module docstring)."""
    r = np.asarray(residual, float)
    if r.size < 10:
        return float("nan")
    d2 = r[2:] - 2.0 * r[1:-1] + r[:-2]
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


def _trials(name: str, fit: FitResult) -> int:
    e = get(name)
    if not e.hypers:
        return 1
    h = e.hypers[0]
    if h.integer:
        return ORDER_TRIALS
    return 30  # grid points plus bounded refinement evaluations (upper bound)


def candidates_for(model: Sequence[str], signals: Signals) -> tuple[list[str], list[str]]:
    """Effects to try (not in the model, channels present) and those skipped with the reason."""
    tried, skipped = [], []
    for name, effect in REGISTRY.items():
        if name in model:
            continue
        missing = requirements_missing(effect, signals)
        if missing:
            skipped.append(f"{name} (no {', '.join(missing)} channel)")
            continue
        tried.append(name)
    return tried, skipped


@dataclass(frozen=True)
class _Trial:
    """A candidate added to the fitted model: what the diagnosis needs of it."""

    values: dict[str, float]
    hypers: dict[str, float]
    rss_train: float
    sse_test: float
    tried: int


def _trial(
    name: str,
    fit: FitResult,
    design: Design,
    shifted: Signals,
    train: Normal,
    test: Normal,
    search: Normal,
    residual_search: Array,
) -> _Trial:
    """Add one effect to the fitted model, reusing the model's normal equations."""
    effect = get(name)
    hypers = dict(fit.hypers)
    tried = 1
    rows = design.search
    if effect.hypers:
        found, tried = search_hyper(design, effect, search, shifted.take(rows), residual_search, hypers)
        hypers.update(found)
    C = effect.columns(shifted, hypers)
    beta, rss = train.extend(C)
    sse = test.sse(beta, C)
    names = [p.name for m in fit.model for p in get(m).parameters] + [p.name for p in effect.parameters]
    values = dict(zip(names, (float(b) for b in beta), strict=True))
    values.update(hypers)
    return _Trial(values, hypers, rss, sse, tried)


def _delay_trial(signals: Signals, torque: Array, fit: FitResult) -> _Trial:
    trial = fit_model(
        signals, torque, (*fit.model, "delay"), robust=fit.robust, test=np.asarray(fit.test), hypers=fit.hypers
    )
    return _Trial(
        trial.values(), dict(trial.hypers), trial.rmse_train**2 * trial.n_train, trial.rmse_test**2 * trial.n_test, 1
    )


def diagnose(
    signals: Signals, torque: Array, fit: FitResult, *, candidates: Sequence[str] | None = None, alpha: float = ALPHA
) -> Diagnosis:
    """Rank the effects missing from ``fit`` by held-out residual explained, with significance."""
    from scipy.special import fdtrc  # F distribution survival function (scipy.stats is slow to import)

    names, skipped = candidates_for(fit.model, signals)
    if candidates is not None:
        names = [c for c in candidates if c in names]
    test_ss = fit.rmse_test**2 * fit.n_test
    train_rss = fit.rmse_train**2 * fit.n_train
    p_base = sum(len(get(m).parameters) for m in fit.model)

    design = Design(signals, torque, np.asarray(fit.test))
    shifted = signals.shifted(fit.hypers.get("delay", 0.0))
    X = design.columns([m for m in fit.model if m != "delay"], fit.hypers, shifted)
    train = Normal(X, torque, mask_slices(design.train))
    test = Normal(X, torque, mask_slices(design.test))
    search = Normal(X[design.search], torque[design.search])
    residual_search = np.asarray(fit.residual)[design.search]

    suggestions = []
    for name in names:
        try:
            if name == "delay":
                trial = _delay_trial(signals, torque, fit)
            else:
                trial = _trial(name, fit, design, shifted, train, test, search, residual_search)
        except FitError as err:
            skipped.append(f"{name} ({err})")
            continue
        explained = (test_ss - trial.sse_test) / test_ss if test_ss > 0 else 0.0
        q = max(len(get(name).parameters), 1)
        dof = max(fit.n_train - p_base - q, 1)
        if trial.rss_train <= 0:
            p = 0.0
        else:
            F = max((train_rss - trial.rss_train) / q, 0.0) / (trial.rss_train / dof)
            p = float(fdtrc(q, dof, F))
        p_adj = min(1.0, p * _trials(name, fit) * max(len(names), 1))
        significant = bool(p_adj < alpha and explained > 0)
        effect = get(name)
        if significant and effect.evidence is not None:
            reason = effect.evidence(trial.values, signals)
            reason += f" (explains {explained:.1%} of the held-out residual, p = {p_adj:.2g})"
        elif significant:
            reason = f"explains {explained:.1%} of the held-out residual (p = {p_adj:.2g})"
        elif p_adj < alpha:
            reason = (
                f"fits the training rows better (p = {p_adj:.2g}) but raises the held-out error by "
                f"{-explained:.2%}: not kept"
            )
        else:
            reason = f"explains {explained:.2%} of the held-out residual; not significant (p = {p_adj:.2g})"
        rmse = math.sqrt(trial.sse_test / max(fit.n_test, 1))
        suggestions.append(Suggestion(name, float(explained), significant, p_adj, rmse, reason, trial.hypers))
    suggestions.sort(key=lambda s: (-s.significant, -s.explained))
    floor = noise_floor(fit.residual)
    at_floor = bool(fit.rmse_test <= FLOOR_FACTOR * floor and not any(s.significant for s in suggestions))
    return Diagnosis(
        fit.model, fit.rmse_test, floor, at_floor, tuple(suggestions), tuple(skipped), _outliers(fit, floor, signals)
    )


def _outliers(fit: FitResult, floor: float, signals: Signals) -> str | None:
    """A sentence when a few rows far outside the noise carry most of the residual, else None."""
    r = np.asarray(fit.residual)
    far = np.abs(r) > OUTLIER_SIGMAS * floor
    total = float(r @ r)
    if not far.any() or total <= 0 or far.mean() > 0.01:
        return None
    share = float(r[far] @ r[far]) / total
    if share < 0.5:
        return None
    k = int(np.argmax(np.abs(r)))
    return (
        f"{int(far.sum())} rows ({far.mean():.2%}) lie more than {OUTLIER_SIGMAS:g}x the noise floor from the "
        f"model and carry {share:.0%} of the residual (largest {r[k]:+.3g} N m at t = {signals.time[k]:.4g} s): "
        "inspect them (glitches longer than 2 samples are kept as data)"
    )


@dataclass(frozen=True)
class Step:
    """One rung of the ``--auto`` ladder."""

    model: tuple[str, ...]
    """Model at this step."""
    added: str | None
    """Effect added to reach it (None for the start)."""
    fit: FitResult
    """Its fit."""
    diagnosis: Diagnosis
    """Its diagnosis."""

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": list(self.model),
            "added": self.added,
            "rmse_train": self.fit.rmse_train,
            "rmse_test": self.fit.rmse_test,
            "aic": self.fit.aic,
            "bic": self.fit.bic,
        }


def auto(
    signals: Signals, torque: Array, start: FitResult, *, max_steps: int = 10, alpha: float = ALPHA, on_step: Any = None
) -> list[Step]:
    """Add the most explaining significant effect until none is left; the ladder of fits."""
    fit = start
    ladder = []
    added: str | None = None
    for _ in range(max_steps + 1):
        diagnosis = diagnose(signals, torque, fit, alpha=alpha)
        ladder.append(Step(fit.model, added, fit, diagnosis))
        if on_step is not None:
            on_step(ladder[-1])
        best = diagnosis.best
        if best is None:
            break
        added = best.effect
        fit = fit_model(signals, torque, (*fit.model, best.effect), robust=fit.robust, test=np.asarray(fit.test))
    return ladder
