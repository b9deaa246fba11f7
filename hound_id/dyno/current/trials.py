"""The trials of a diagnosis (:mod:`hound_id.dyno.current.diagnose`): which effects a log can test, and each candidate
effect, the shift of the inputs (the delay) and the transducer's filter tried against the fitted model with a
cluster-robust Wald test."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from hound_id.dyno.current import transducer
from hound_id.dyno.current.effects import REGISTRY, Signals, get, requirements_missing
from hound_id.dyno.current.fit import FitResult, fit_model
from hound_id.dyno.current.flags import share_of
from hound_id.dyno.current.identifiable import identifiability
from hound_id.dyno.current.search import FILTERS, Design, apart, bounds_of, parameters_of, search_hyper
from hound_id.dyno.current.stats import Array, Stats, cross_validate, robust_cov, solve_bounded, solve_normal
from hound_id.errors import DynoDataError, FitError

#: A candidate must lower the cross-validated mean-square error by this fraction of the noise variance (an effect whose
#: RMS is a fifth of the noise or more). Calibrated on test_diagnose::test_a_real_effect_is_suggested_only_when_material
#: and test_diagnose::test_combinations_of_hidden_effects_are_found_exactly_with_nothing_extra.
MATERIAL = 0.05


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


def trials(name: str) -> int:
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


def effect_trial(
    name: str, fit: FitResult, design: Design, shifted: Signals, Z: Array, stats: Stats, residual_search: Array
) -> _Trial | str:
    """Add one effect to the fitted model, reusing the model's per-block sums; a string says why not."""
    effect = get(name)
    model = [m for m in fit.model if not apart(m)]
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


def shift_trial(name: str, signals: Signals, torque: Array, fit: FitResult) -> _Trial | str:
    """The model refitted with a shift of its inputs (:attr:`~hound_id.dyno.current.effect.Effect.shift`, the
    delay), the other hypers held; the shift's z-statistic squared is its Wald statistic."""
    try:
        trial = fit_model(signals, torque, (*fit.model, name), robust=fit.robust, hypers=fit.hypers)
    except (FitError, DynoDataError) as err:
        return str(err)
    shift = get(name).hypers[0].name
    est = trial.parameters[shift]
    if not est.stderr > 0:
        return f"the {shift} has no defined standard error on this log"
    z2 = (est.value / est.stderr) ** 2
    return _Trial(trial.values(), dict(trial.hypers), trial.rmse_test**2 * trial.n_test, z2, 1, 1)


def dynamics_trace(signals: Signals, fit: FitResult, floor: float) -> str | None:
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
        f"and second derivatives is {share_of(max(gain, 0.0), floor**2)} of the noise variance"
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


def filter_trial(name: str, signals: Signals, torque: Array, fit: FitResult) -> _Trial | str:
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
