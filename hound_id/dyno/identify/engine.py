"""What makes an identification trustworthy, once for both model families.

The current-torque models (:mod:`hound_id.dyno.current.diagnose`) and the torque-speed envelope models
(:mod:`hound_id.dyno.envelope.compare`) grow a model the same way: every candidate effect not in it is
fitted on top, tested, and ranked; the best significant one is added (or the one the user names), and
the model is diagnosed again, until nothing significant is left. Each family brings its own fit and its
own test statistic; this module holds the rest:

* :class:`Suggestion`: a candidate effect tried on top of a model, with its verdict;
* :func:`corrected` and :func:`significant`: the one significance rule (Bonferroni over the values a
  search tried and over the candidates; physically possible, identified, not refuted by the log, and
  material: large enough to matter against the noise);
* :func:`f_pvalue`: the p-value of an F statistic;
* :func:`rank`: the order of the suggestions; :func:`best`: the one to add;
* :class:`Step` and :func:`climb`: the add-an-effect ladder.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

from hound_id.errors import HoundIdError

#: Family-wise false-alarm rate of the significance tests (after the multiple-comparison corrections): one ladder in a
#: hundred adds an effect that noise alone made look significant, while the hidden effects of the simulated logs (each
#: sized well above the default noise) stay significant. Calibrated on
#: test_engine::test_a_p_value_just_below_alpha_after_correction_is_significant_and_just_above_is_not,
#: test_diagnose::test_noise_only_data_has_nothing_significant and
#: test_diagnose::test_combinations_of_hidden_effects_are_found_exactly_with_nothing_extra.
ALPHA = 0.01
#: Rungs the automatic ladder may add past its start (each rung is a refit): a guard against a runaway ladder that never
#: cuts a real one, which stops at the noise floor first. The current family can add at most 9 effects to its default
#: model (13 effects less linear, saturation and saturation's two other forms); the sample dyno log hides 5. Calibrated
#: on test_fit_cli::test_sample_auto_finds_every_hidden_effect and
#: test_engine::test_max_steps_bounds_the_automatic_rungs.
MAX_STEPS = 10

M = TypeVar("M")
R = TypeVar("R")


@dataclass(frozen=True)
class Suggestion:
    """A candidate effect fitted on top of a model, scored and tested (either family)."""

    effect: str
    """Effect name."""
    explained: float
    """Share of the model's error sum of squares the effect removes [-] (current family: the cross-validated
    residual's, negative when it makes it worse; envelope family: the envelope error's, at least 0)."""
    significant: bool
    """The verdict of :func:`significant`: add it."""
    p_value: float
    """The test's own p-value, before the multiple-comparison correction [-] (NaN when not tested)."""
    p_adjusted: float
    """The corrected p-value, :func:`corrected` [-] (NaN when not tested)."""
    rmse: float
    """The model's error with the effect added [N m]: the cross-validated RMSE (current family) or the envelope
    error, the RMS of the edge offsets (envelope family); NaN when not fitted."""
    reason: str
    """The evidence in one sentence."""
    statistic: float = math.nan
    """The test statistic, F-distributed under 'no effect' [-]: the Wald statistic on cluster-robust standard
    errors over the parameter count (current family) or the partial F statistic (envelope family)."""
    physical: bool = True
    """False when the effect fits only with a value outside its physical bounds."""
    supported: bool = False
    """A logged channel confirms it (the bus voltage for ``bus_sag``); a significant supported suggestion ranks
    first."""
    value: float = math.nan
    """The effect's fitted scalar parameter [:attr:`unit`] (envelope family)."""
    unit: str = ""
    """The unit of :attr:`value`."""
    hypers: Mapping[str, float] = field(default_factory=dict)
    """Nonlinear parameter values with the effect added, e.g. the cogging order found (current family)."""
    refit: Mapping[str, float] = field(default_factory=dict)
    """The model's own parameters refitted together with this effect (envelope family; a wrong earlier effect
    falls back here)."""

    @property
    def rmse_test(self) -> float:
        """:attr:`rmse` under the current family's name (cross-validated) [N m]."""
        return self.rmse

    @property
    def f_statistic(self) -> float:
        """:attr:`statistic` under the envelope family's name [-]."""
        return self.statistic


def corrected(p_value: float, trials: int = 1, candidates: int = 1) -> float:
    """The Bonferroni-corrected p-value: min(1, p x trials x candidates).

    Args:
        p_value: The test's own p-value [-].
        trials: How many values the candidate's parameter search tried (its best is tested) [-].
        candidates: How many candidates were tried on the same model (at least 1 counts) [-].
    """
    return min(1.0, p_value * trials * max(candidates, 1))


def significant(
    p_adjusted: float,
    *,
    material: bool,
    physical: bool = True,
    identified: bool = True,
    refuted: bool = False,
    alpha: float = ALPHA,
) -> bool:
    """The one rule: an effect is significant when its corrected p-value is below ``alpha`` and it is physically
    possible, identified (not at a bound of its search), not refuted by the log, and material (it lowers the
    error by at least the family's measure of the noise: statistically and practically significant)."""
    return bool(physical and identified and not refuted and p_adjusted < alpha and material)


def f_pvalue(statistic: float, dfn: float, dfd: float) -> float:
    """P(F(dfn, dfd) > statistic): the p-value of an F statistic."""
    from scipy.special import fdtrc  # F distribution survival function (scipy.stats is slow to import)

    return float(fdtrc(dfn, dfd, statistic))


def rank(suggestions: Sequence[Suggestion], *, verdict_first: bool = True) -> list[Suggestion]:
    """The suggestions best first (a stable sort).

    A significant suggestion a logged channel supports comes first; then, with ``verdict_first`` (the current
    family), significant before not and physical before not; then the most explained. The envelope family
    ranks by the share explained alone (``verdict_first=False``): its table shows what each effect would
    explain whatever the verdict, and its ladder adds the first significant one (:func:`best`) either way.
    """

    def key(s: Suggestion) -> tuple[int, int, int, float]:
        verdict = (-int(s.significant), -int(s.physical)) if verdict_first else (0, 0)
        return (-int(s.supported and s.significant), *verdict, -s.explained)

    return sorted(suggestions, key=key)


def best(suggestions: Sequence[Suggestion]) -> Suggestion | None:
    """The first significant suggestion of a ranked list, if any."""
    return next((s for s in suggestions if s.significant), None)


@dataclass(frozen=True)
class Step(Generic[M, R]):
    """One rung of the add-an-effect ladder: a model, what the family found for it, and the candidates on top."""

    model: M
    """The model at this rung: the effect names (current family, a tuple) or effect -> fitted parameter
    (envelope family, a dict)."""
    added: str | None
    """Effect added to reach it (None for the start)."""
    result: R
    """The family's fit of the model: the :class:`~hound_id.dyno.current.fit.FitResult` (current family), or the
    edge :class:`~hound_id.dyno.envelope.offsets.Offsets` against it (envelope family)."""
    suggestions: tuple[Suggestion, ...]
    """The candidates tried on top of it, ranked (:func:`rank`)."""
    diagnosis: Any = None
    """The current family's whole :class:`~hound_id.dyno.current.diagnose.Diagnosis` of the fit (None for the
    envelope family)."""
    refound: bool = False
    """Envelope family: whether the walls were found again against this model (and every parameter refitted)."""

    @property
    def fit(self) -> R:
        """:attr:`result` under the current family's name."""
        return self.result

    @property
    def offsets(self) -> R:
        """:attr:`result` under the envelope family's name."""
        return self.result


def _untestable(name: str) -> Exception:
    return HoundIdError(f"{name}: not a candidate on this model")


def climb(
    first: Step[M, R],
    grow: Callable[[Step[M, R], Suggestion], Step[M, R]],
    *,
    add: Sequence[str] = (),
    auto: bool = False,
    max_steps: int = MAX_STEPS,
    on_step: Callable[[Step[M, R]], None] | None = None,
    at_floor: Callable[[Step[M, R]], bool] | None = None,
    untestable: Callable[[str], Exception] = _untestable,
) -> list[Step[M, R]]:
    """The add-an-effect ladder, from the family's diagnosis of the starting model.

    First the effects named in ``add`` are added in their order (each must be a suggestion of the rung before,
    else ``untestable(name)`` is raised); then, with ``auto``, the best significant suggestion (:func:`best`)
    while there is one, the last rung is not at the family's floor (``at_floor``) and the ladder has at most
    ``max_steps`` rungs past the first (``add`` is not counted against it while it lasts).

    Args:
        first: The family's diagnosis of the starting model (its rung 0).
        grow: The family's step: add a suggestion (its fitted values) to a rung's model, refit and diagnose.
        on_step: Called with every rung as it is made, the first included (progress display).
    """
    ladder = [first]
    if on_step is not None:
        on_step(first)
    queue = list(add)
    while queue or auto:
        last = ladder[-1]
        if queue:
            name = queue.pop(0)
            chosen = next((s for s in last.suggestions if s.effect == name), None)
            if chosen is None:
                raise untestable(name)
        else:
            if len(ladder) > max_steps or (at_floor is not None and at_floor(last)):
                break
            chosen = best(last.suggestions)
            if chosen is None:
                break
        ladder.append(grow(last, chosen))
        if on_step is not None:
            on_step(ladder[-1])
    return ladder
