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
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.dyno.current import transducer
from hound_id.dyno.current.effects import REGISTRY, Signals, get, requirements_missing
from hound_id.dyno.current.fit import FitResult, fit_model
from hound_id.dyno.current.identifiable import identifiability
from hound_id.dyno.current.noise import NoiseFloor, estimate, white_floor
from hound_id.dyno.current.search import FILTERS, SPECIAL, Design, bounds_of, parameters_of, search_hyper
from hound_id.dyno.current.slope import agreeing_half
from hound_id.dyno.current.stats import Array, Stats, cross_validate, robust_cov, solve_bounded, solve_normal
from hound_id.dyno.current.stretch import Stretch, read, runs
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
from hound_id.errors import DynoDataError, FitError

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
#: A candidate must lower the cross-validated mean-square error by this fraction of the noise variance (an effect whose
#: RMS is a fifth of the noise or more). Calibrated on test_diagnose::test_a_real_effect_is_suggested_only_when_material
#: and test_diagnose::test_combinations_of_hidden_effects_are_found_exactly_with_nothing_extra.
MATERIAL = 0.05
#: A block disagrees when its held-out RMSE exceeds this many times both the median block's and its own noise (3x: a
#: motor switched off, not the scatter of block RMSEs). Calibrated on
#: test_polled_rig::test_a_log_that_breaks_midway_is_flagged_with_its_times and
#: test_polled_rig::test_a_flagged_training_fold_is_not_hidden_by_a_good_held_out_error.
BLOCK_FACTOR = 3.0
#: Kt whose standard error exceeds this fraction of its value is not determined by the log (a 3-sigma interval would
#: include zero). Calibrated on test_diagnose::test_kt_is_undetermined_past_a_third_of_its_value and
#: test_polled_rig::test_a_torque_sensor_the_motor_does_not_load_gives_no_kt.
KT_UNDETERMINED = 1.0 / 3.0
#: Residuals beyond this many noise-floor sigmas count as outliers in the summary, when they are at most OUTLIER_SHARE
#: of the rows and carry OUTLIER_WEIGHT of the residual's sum of squares or more. Calibrated on
#: test_diagnose::test_a_long_glitch_is_named_as_outliers_not_a_missing_effect.
OUTLIER_SIGMAS = 8.0
OUTLIER_SHARE = 0.01
OUTLIER_WEIGHT = 0.5
#: The floor is never below this share of the torque's RMS (the rounding of the fit's own arithmetic, far below any
#: sensor). Calibrated on test_logs::test_a_table_of_26_operating_points_and_a_burst_written_16_times_are_read.
NUMERICAL_FLOOR = 1e-6
#: An effect is tried only while the log has this many rows per parameter of the grown model (its hypers and the
#: offset the identifiability check allows for included): a table of 26 operating points carries five. Calibrated on
#: test_logs::test_a_table_of_26_operating_points_and_a_burst_written_16_times_are_read.
ROWS_PER_PARAMETER = 5
#: Effective number of values an order search scans (the residual's angular spectrum bins), and of a continuous search
#: (grid points plus bounded refinement evaluations, an upper bound): the Bonferroni factors of a searched effect.
#: Calibrated on test_diagnose::test_noise_only_data_has_nothing_significant.
ORDER_TRIALS = 511
SEARCH_TRIALS = 30
#: Half-width of the differences that screen the residual for the torque channel's dynamics [samples]: two, so the
#: current's sample-to-sample noise does not swamp the model torque's derivatives. Calibrated on
#: test_diagnose::test_each_hidden_effect_is_named_first_and_adding_it_reaches_the_noise and
#: test_polled_rig::test_a_transducer_resonance_is_found_named_and_valued.
DYNAMICS_ROWS = 2
#: A filter whose frequency or damping lies within this share of the searched range's ends is at its edge: a
#: resonance at 43 Hz in a 100 Hz log (the range ends at 45 Hz) is the sampling's limit, not a coupling the log
#: resolves. Calibrated on test_polled_rig::test_a_transducer_the_log_cannot_resolve_gives_no_filter and
#: test_polled_rig::test_a_transducer_resonance_is_found_named_and_valued.
FILTER_EDGE = 0.1
#: A filter is added only when each of its values has a standard error of at most this share of it (2 sigma from
#: zero): a filter that helps but whose time constant the log cannot pin down gives no number. Calibrated on
#: test_polled_rig::test_a_first_order_transducer_lag_is_found_and_valued and
#: test_polled_rig::test_a_transducer_the_log_cannot_resolve_gives_no_filter.
FILTER_DETERMINED = 0.5


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


def _trials(name: str) -> int:
    e = get(name)
    if not e.hypers or name in FILTERS:  # a filter's test is on held-out blocks, not on the best value searched
        return 1
    h = e.hypers[0]
    if h.integer:
        return ORDER_TRIALS
    return SEARCH_TRIALS


def candidates_for(model: Sequence[str], signals: Signals) -> tuple[list[str], list[str]]:
    """Effects to try (not in the model, channels present, rows enough for their parameters) and those skipped with
    the reason."""
    tried, skipped = [], []
    rows = int(signals.current.size)
    count = 1 + sum(len(get(m).parameters) + len(get(m).hypers) for m in model)  # and the offset always allowed for
    for name, effect in REGISTRY.items():
        if name in model:
            continue
        missing = requirements_missing(effect, signals)
        if missing == ["time"]:
            skipped.append(f"{name} (a steady-state table has no sample times)")
            continue
        if missing:
            skipped.append(f"{name} (no {', '.join(missing)} channel)")
            continue
        needed = ROWS_PER_PARAMETER * (count + len(effect.parameters) + len(effect.hypers))
        if rows < needed:
            skipped.append(
                f"{name} ({rows} rows cannot carry its parameters beside the model's: it needs {needed}, "
                f"{ROWS_PER_PARAMETER} per parameter)"
            )
            continue
        tried.append(name)
    return tried, skipped


@dataclass(frozen=True)
class _Trial:
    """A candidate added to the fitted model: what the diagnosis needs of it."""

    values: dict[str, float]
    hypers: dict[str, float]
    cv_sse: float
    wald: float
    """Wald statistic divided by the candidate's parameter count (F-distributed)."""
    q: int
    tried: int
    unphysical: str | None = None
    wald_free: float = 0.0
    """Wald statistic of the candidate fitted without bounds (to tell 'unphysical' from 'nothing there')."""
    p_value: float | None = None
    """The candidate's p-value when its test is not a Wald test (a filter's block-paired test), else None."""


def _wald(stats: Stats, cols: list[int], beta: Array, active: np.ndarray, which: list[int]) -> float:
    cov = robust_cov(stats, cols, beta, ~active)
    idx = [k for k in which if not active[k]]
    if not idx:
        return 0.0
    V = cov[np.ix_(idx, idx)]
    b = beta[idx]
    _, V_inv = solve_normal(V, np.zeros(len(idx)))
    return float(b @ V_inv @ b) / len(idx)


def _trial(
    name: str, fit: FitResult, design: Design, shifted: Signals, Z: Array, stats: Stats, residual_search: Array
) -> _Trial | str:
    """Add one effect to the fitted model, reusing the model's per-block sums; a string says why not."""
    effect = get(name)
    model = [m for m in fit.model if m not in SPECIAL]
    hypers = dict(fit.hypers)
    tried = 1
    rows = design.search
    if effect.hypers:
        base = Z[rows, 1:]
        found, tried = search_hyper(effect, base, design.torque[rows], shifted.take(rows), residual_search, hypers)
        hypers.update(found)
    C = effect.columns(shifted, hypers)
    for f in fit.model:
        if f in FILTERS:  # the candidate's torque reaches the reading through the same transducer
            C = transducer.apply(f, hypers, shifted.time, C)
    ext = Stats.extended(stats, Z, C, design.torque)
    p, q = Z.shape[1] - 1, C.shape[1]
    cols = list(range(1, p + q + 1))
    names = [par.name for _, par in parameters_of([*model, name])]
    problems = [
        u for u in identifiability(ext, cols, names, design.signals) if {u.parameter, u.partner} & set(names[p:])
    ]
    if problems:
        return problems[0].sentence()
    lower, upper = bounds_of([*model, name])
    G, g, _ = ext.total(cols)
    free, _ = solve_normal(G, g)
    bad = [
        (par, float(v))
        for (_, par), v in zip(parameters_of([*model, name]), free, strict=True)
        if par.outside(float(v)) is not None and (par.name in names[p:] or par.name == "kt")
    ]
    beta, active = solve_bounded(G, g, lower, upper)
    values = dict(zip(names, (float(b) for b in beta), strict=True))
    values.update(hypers)
    unphysical = None
    if bad:
        par, v = bad[0]
        unphysical = (
            f"fits only with {par.outside(v)} ({par.name} = {v:.3g} {par.unit}; {par.bound_reason}): not physical, "
            "not added"
        )
    cv = cross_validate(ext, ext, cols, lower, upper)
    which = list(range(p, p + q))
    wald = _wald(ext, cols, beta, active, which)
    wald_free = _wald(ext, cols, free, np.zeros(p + q, dtype=bool), which) if bad else wald
    return _Trial(values, hypers, cv.sse, wald, q, tried, unphysical, wald_free)


def _delay_trial(signals: Signals, torque: Array, fit: FitResult) -> _Trial | str:
    try:
        trial = fit_model(signals, torque, (*fit.model, "delay"), robust=fit.robust, hypers=fit.hypers)
    except (FitError, DynoDataError) as err:
        return str(err)
    est = trial.parameters["delay"]
    if not est.stderr > 0:
        return "the delay has no defined standard error on this log"
    z2 = (est.value / est.stderr) ** 2
    return _Trial(trial.values(), dict(trial.hypers), trial.rmse_test**2 * trial.n_test, z2, 1, 1)


def _dynamics_trace(signals: Signals, fit: FitResult, floor: float) -> str | None:
    """Why no filter of the torque channel is worth a trial, or None when the residual shows a trace of one.

    A filter H near unit gain changes the reading by about -a p' - b p'' (p the model's torque, its derivatives
    smoothed over a few samples: a lag's a = tau, a resonance's a = 2 zeta / w0 and b = 1 / w0^2 less a's square).
    When the residual's projection on those two columns lowers its mean square by less than half of
    :data:`MATERIAL` of the noise variance, no filter near the log's can be material, and the costly trials (a
    search on every row) are skipped with that reason."""
    t = signals.time
    p = np.asarray(fit.prediction, float)
    r = np.asarray(fit.residual, float)
    if p.size < 2 * DYNAMICS_ROWS + 3:
        return None
    k = DYNAMICS_ROWS
    rate = np.zeros_like(p)
    rate[k:-k] = (p[2 * k :] - p[: -2 * k]) / np.maximum(t[2 * k :] - t[: -2 * k], 1e-300)
    curve = np.zeros_like(p)
    curve[k:-k] = (rate[2 * k :] - rate[: -2 * k]) / np.maximum(t[2 * k :] - t[: -2 * k], 1e-300)
    D = np.column_stack([rate, curve])
    beta, _ = solve_normal(D.T @ D, D.T @ r)
    gain = float(beta @ (D.T @ r)) / p.size
    if math.isfinite(gain) and gain >= 0.5 * MATERIAL * floor**2:
        return None
    return (
        f"the residual shows no trace of the torque channel's own dynamics: its part along the model torque's first "
        f"and second derivatives is {_share(max(gain, 0.0), floor**2)} of the noise variance"
    )


def _filter_at_edge(name: str, hypers: Mapping[str, float], signals: Signals) -> str | None:
    """A sentence when a filter fits only at the edge of the range the log can show (within FILTER_EDGE of a bound):
    then it is not the transducer's dynamics but something else the filter's shape happens to smooth."""
    edge = transducer.at_edge(name, hypers, signals.time, FILTER_EDGE)
    if not edge:
        return None
    c = edge[0]
    unit = f" {c.unit}" if c.unit else ""
    return (
        f"fits only at the edge of what this log can show ({c.label} {c.value:.3g}{unit}, the range being "
        f"{c.low:.3g} to {c.high:.3g}{unit}): not a transducer's dynamics the log can resolve"
    )


def _filter_trial(name: str, signals: Signals, torque: Array, fit: FitResult) -> _Trial | str:
    """The model with a filter of the torque channel added, tested block by block: each time block's held-out sum of
    squares falls by some amount, and a one-sided Wilcoxon signed-rank test over the blocks asks whether the falls
    outweigh the rises. A filter has no parameter whose zero means "absent" (its frequency would go to infinity), so
    no Wald test; ranks, because a filter helps most in the few blocks that hold the current's steps."""
    from scipy.stats import wilcoxon

    try:
        trial = fit_model(signals, torque, (*fit.model, name), robust=fit.robust, hypers=fit.hypers)
    except (FitError, DynoDataError) as err:
        return str(err)
    edge = _filter_at_edge(name, trial.hypers, signals)
    if edge is not None:
        return edge
    for h in get(name).hypers:
        est = trial.parameters[h.name]
        if not est.stderr <= FILTER_DETERMINED * est.value:
            return (
                f"its {h.name} = {est.value:.3g} +- {est.stderr:.2g} {h.unit} is not determined by this log (the "
                f"standard error is more than {FILTER_DETERMINED:.0%} of it): no value to report"
            )
    sizes = np.diff(fit.blocks.edges)
    gain = np.asarray(fit.block_rmse) ** 2 * sizes - np.asarray(trial.block_rmse) ** 2 * sizes
    p = 1.0 if not np.any(gain != 0) else float(wilcoxon(gain, alternative="greater").pvalue)
    return _Trial(trial.values(), dict(trial.hypers), trial.rmse_test**2 * trial.n_test, 0.0, 1, 1, p_value=p)


def diagnose(
    signals: Signals, torque: Array, fit: FitResult, *, candidates: Sequence[str] | None = None, alpha: float = ALPHA
) -> Diagnosis:
    """Rank the effects missing from ``fit`` by cross-validated residual explained, with significance."""
    names, skipped = candidates_for(fit.model, signals)
    if candidates is not None:
        names = [c for c in candidates if c in names]
    design = Design(signals, torque)
    n = design.torque.size
    shifted = signals.shifted(fit.hypers.get("delay", 0.0))
    X = design.model_columns(fit.model, fit.hypers, shifted)
    Z = design.with_ones(X)
    stats = Stats(Z, design.torque, design.blocks)
    cols = list(range(1, Z.shape[1]))
    lower, upper = bounds_of(fit.model)
    base_sse = cross_validate(stats, stats, cols, lower, upper).sse
    residual_search = np.asarray(fit.residual)[design.search]
    agreeing = _Agreeing(*agreeing_half(stats, cols, lower, upper, np.asarray(fit.block_rmse)))
    noise = estimate(signals, design.torque, np.asarray(fit.residual), rows=_typical_rows(design, agreeing))
    # never below the arithmetic's own noise: a noiseless log's residual is rounding, not a missing effect
    floor = max(noise.value, NUMERICAL_FLOOR * float(np.sqrt(np.mean(design.torque**2))))
    clusters = design.blocks.count

    suggestions = []
    dynamics = _dynamics_trace(signals, fit, floor) if any(n in FILTERS for n in names) and signals.timed else None
    for name in names:
        try:
            if name == "delay":
                trial = _delay_trial(signals, torque, fit)
            elif name in FILTERS:
                trial = dynamics if dynamics is not None else _filter_trial(name, signals, torque, fit)
            else:
                trial = _trial(name, fit, design, shifted, Z, stats, residual_search)
        except FitError as err:
            trial = str(err)
        if isinstance(trial, str):
            skipped.append(f"{name} ({trial})")
            continue
        explained = (base_sse - trial.cv_sse) / base_sse if base_sse > 0 else 0.0
        gain = (base_sse - trial.cv_sse) / n  # fall of the cross-validated mean-square error [N^2 m^2]
        material = bool(math.isfinite(floor) and gain >= MATERIAL * floor**2 and gain > 0)
        dfd = max(clusters - 1, 1)
        p = f_pvalue(trial.wald, trial.q, dfd) if trial.p_value is None else trial.p_value
        p_adj = corrected(p, _trials(name), len(names))
        rmse = math.sqrt(trial.cv_sse / n)
        effect = get(name)
        # unphysical only if the effect is there: the fit without bounds passes the same test
        p_free = (
            p_adj
            if trial.p_value is not None
            else corrected(f_pvalue(trial.wald_free, trial.q, dfd), _trials(name), len(names))
        )
        unphysical = trial.unphysical if p_free < alpha else None
        verdict = significant(p_adj, material=material, physical=trial.unphysical is None, alpha=alpha)
        if unphysical is not None:
            reason = unphysical
        elif verdict:
            reason = effect.evidence(trial.values, signals) if effect.evidence is not None else "it fits"
            reason += f" (explains {explained:.1%} of the cross-validated residual, p = {p_adj:.2g})"
        elif p_adj < alpha and gain > 0:
            reason = (
                f"real (p = {p_adj:.2g}) but immaterial: it lowers the cross-validated mean-square error by "
                f"{_share(gain, floor**2)} of the noise variance, less than {MATERIAL:.0%}"
            )
        elif p_adj < alpha:
            reason = (
                f"fits the log better (p = {p_adj:.2g}) but raises the cross-validated error by "
                f"{-explained:.2%}: not kept"
            )
        else:
            reason = f"explains {explained:.2%} of the cross-validated residual; not significant (p = {p_adj:.2g})"
        suggestions.append(
            Suggestion(
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
        )
    suggestions = rank(suggestions)
    block_floor = np.array([noise_floor(np.asarray(fit.residual)[s]) for s in design.blocks.slices()])
    disagreeing = _disagreeing(agreeing, floor, block_floor)
    kt = _kt(fit, agreeing)
    residual = np.asarray(fit.residual)
    edges = design.blocks.edges
    stretches = tuple(
        read(signals, design.torque, residual, int(edges[a]), int(edges[b]), kt) for a, b in runs(disagreeing)
    )
    flags = tuple(_flags(fit, agreeing, noise, floor, disagreeing, signals, stretches))
    at_floor = bool(fit.rmse_test <= FLOOR_FACTOR * floor and not any(s.significant for s in suggestions) and not flags)
    held_out = np.asarray(fit.held_out)
    keep = np.repeat(~disagreeing, np.diff(edges))
    outliers = _outliers(fit, floor, signals)
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
        _rmse_outside(stats, cols, lower, upper, disagreeing),
        time_scale,
    )


def _rmse_outside(stats: Stats, cols: list[int], lower: Array, upper: Array, disagreeing: np.ndarray) -> float | None:
    """The cross-validated RMSE of the model fitted and scored without the disagreeing blocks [N m] (each fold held
    out once, as for the whole log); None when no block or every block disagrees."""
    if not disagreeing.any() or disagreeing.all():
        return None
    cv = cross_validate(stats, stats, cols, lower, upper, use=~disagreeing)
    return cv.rmse(np.diff(stats.blocks.edges))


def _kt(fit: FitResult, agreeing: _Agreeing) -> float | None:
    """Kt of the fit to the agreeing half of the blocks [N m/A], None without a ``linear`` term."""
    names = [par.name for _, par in parameters_of(fit.model)]
    return float(agreeing.beta[names.index("kt")]) if "kt" in names else None


def _share(part: float, whole: float) -> str:
    """part / whole as a percentage, or 'all' when whole is zero (a noiseless log)."""
    return f"{part / whole:.1%}" if whole > 0 else "all"


def _span(signals: Signals, start: int, stop: int) -> str:
    if signals.timed:
        return f"t = {signals.time[start]:.4g}-{signals.time[stop - 1]:.4g} s"
    # a steady-state table's time is its 0-based data row
    return f"data rows {int(signals.time[start]) + 1}-{int(signals.time[stop - 1]) + 1}"


@dataclass(frozen=True)
class _Agreeing:
    """The blocks judged against a fit to the half of them that agrees (:func:`.fit.agreeing_half`).

    A motor switched off for a third of the log pulls a fit to all blocks towards it, so that no block stands
    out against the median; a fit to the agreeing half does not (robust to breakage in up to half the log).
    """

    good: np.ndarray
    """The agreeing half."""
    beta: Array
    """The coefficients of the fit to it (the model's columns)."""
    rmse: Array
    """Every block's RMSE under that fit [N m]."""

    @property
    def typical(self) -> float:
        """The median block's RMSE under that fit (a good block's while fewer than half disagree)."""
        return float(np.median(self.rmse))


def _typical_rows(design: Design, agreeing: _Agreeing) -> NDArray[np.bool_]:
    """Rows of the blocks within BLOCK_FACTOR of the typical block's RMSE under the agreeing half's fit (what the
    noise floor may pair: a broken stretch paired with the rest would read as noise and hide itself)."""
    rows = np.ones(design.torque.size, dtype=bool)
    for block, s in enumerate(design.blocks.slices()):
        rows[s] = agreeing.rmse[block] <= BLOCK_FACTOR * agreeing.typical
    return rows


def _disagreeing(agreeing: _Agreeing, floor: float, block_floor: Array) -> np.ndarray:
    r = agreeing.rmse
    own = np.where(np.isfinite(block_floor), np.maximum(block_floor, floor), floor)
    return (r > BLOCK_FACTOR * agreeing.typical) & (r > BLOCK_FACTOR * own)  # type: ignore[no-any-return]


def _flags(
    fit: FitResult,
    agreeing: _Agreeing,
    noise: NoiseFloor,
    floor: float,
    bad: np.ndarray,
    signals: Signals,
    stretches: Sequence[Stretch],
) -> list[str]:
    """Disagreeing blocks (grouped in runs) and folds that fit their training rows much worse than their held-out,
    each side judged against the noise it expects (a fold of quiet rows, where the noise grows with the load, is
    not a fold the model fits better)."""
    r = agreeing.rmse
    edges = fit.blocks.edges
    ref = agreeing.typical
    out: list[str] = []
    runs_seen = 0
    k = 0
    while k < bad.size:
        if not bad[k]:
            k += 1
            continue
        j = k
        while j + 1 < bad.size and bad[j + 1]:
            j += 1
        worst = float(r[k : j + 1].max())
        stretch = stretches[runs_seen]  # one per run of disagreeing blocks, in order
        runs_seen += 1
        out.append(
            f"blocks {k + 1}-{j + 1} of {bad.size} ({_span(signals, int(edges[k]), int(edges[j + 1]))}) disagree with "
            f"the rest: RMSE up to {worst:.3g} N m under the model fitted to the agreeing half of the blocks, against "
            f"{ref:.3g} N m for the median block; {stretch.kind}: {stretch.reading}"
        )
        k = j + 1
    kt = fit.parameters.get("kt")
    if kt is not None and not kt.stderr <= KT_UNDETERMINED * abs(kt.value):
        out.insert(
            0,
            f"Kt = {kt.value:.4g} +- {kt.stderr:.2g} N m/A is not determined by this log (its standard error is more "
            f"than {KT_UNDETERMINED:.0%} of it): the torque hardly follows the current; record a current sweep "
            "against a torque sensor that is loaded",
        )
    train, test = np.asarray(fit.fold_rmse_train), np.asarray(fit.fold_rmse_test)
    fold_of_row = np.repeat(fit.blocks.fold, np.diff(edges))
    current = signals.current if fold_of_row.size == signals.current.size else np.zeros(fold_of_row.size)
    shape = floor / noise.value if noise.value > 0 else 0.0  # the numerical floor of a noiseless log has no shape

    def expect(rows: NDArray[np.bool_]) -> float:
        return noise.expected(current, rows) * shape if shape > 0 else floor

    expect_train = np.array([expect(fold_of_row != k) for k in range(train.size)])
    expect_test = np.array([expect(fold_of_row == k) for k in range(train.size)])
    ratio = (train / np.maximum(expect_train, 1e-300)) / np.maximum(test / np.maximum(expect_test, 1e-300), 1e-300)
    worst_fold = int(np.argmax(ratio))
    if ratio[worst_fold] > BLOCK_FACTOR and train[worst_fold] > BLOCK_FACTOR * expect_train[worst_fold]:
        k = worst_fold
        raw = train[k] / max(float(test[k]), 1e-300)
        shaped = (
            ""
            if noise.load is None
            else f", {ratio[k]:.3g}x against the noise each side expects ({expect_train[k]:.3g} and "
            f"{expect_test[k]:.3g} N m: the noise changes with the load)"
        )
        out.append(
            f"the fit without fold {k + 1} of {train.size} is {raw:.3g}x worse on its own training rows "
            f"({train[k]:.3g} N m) than on the fold it holds out ({test[k]:.3g} N m){shaped}: the rows outside that "
            "fold do not follow the model"
        )
    return out


def _outliers(fit: FitResult, floor: float, signals: Signals) -> str | None:
    """A sentence when a few rows far outside the noise carry most of the residual, else None."""
    r = np.asarray(fit.residual)
    far = np.abs(r) > OUTLIER_SIGMAS * floor
    total = float(r @ r)
    if not far.any() or total <= 0 or far.mean() > OUTLIER_SHARE:
        return None
    share = float(r[far] @ r[far]) / total
    if share < OUTLIER_WEIGHT:
        return None
    k = int(np.argmax(np.abs(r)))
    where = f"t = {signals.time[k]:.4g} s" if signals.timed else f"row {k}"
    return (
        f"{int(far.sum())} rows ({far.mean():.2%}) lie more than {OUTLIER_SIGMAS:g}x the noise floor from the "
        f"model and carry {share:.0%} of the residual (largest {r[k]:+.3g} N m at {where}): "
        "inspect them (glitches longer than 2 samples are kept as data)"
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
