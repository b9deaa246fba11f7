"""Fitting a sum of effects to a dynamometer log.

Linear parameters are found by least squares within their physical bounds (Kt > 0,
friction >= 0, saturation bending the curve down; :class:`~hound_id.dyno.current.effects.Parameter`),
optionally Huber-robust, nonlinear ones by search: a candidate grid from the data
(orders from the residual's spectrum over rotor angle, speeds and currents on
log/linear grids), then a bounded scalar refinement. The delay, a shift of every
input channel in time (:attr:`~hound_id.dyno.current.effect.Effect.shift`), is found by
Gauss-Newton on the first-order expansion torque(t - d) ~ torque(t) - d dtorque/dt,
iterated with the shifted signals, within +-:data:`DELAY_WINDOW` (or two samples).

Everything after the columns are built works on per-block sums: the log is cut in
contiguous time blocks (rows in order for a steady-state table) and each block keeps
its Gram matrix X^T X, X^T y and y^T y. From these come, without another pass over
the rows:

* the fit itself (bounded least squares on the Cholesky factor of the Gram matrix,
  ``scipy.optimize.lsq_linear``),
* blocked cross-validation: the blocks are grouped in :data:`FOLDS` contiguous folds,
  each fold is held out once and predicted by the fit to the others; the held-out
  RMSE is the pooled error of those predictions, and every block has its own,
* cluster-robust standard errors (the blocks are the clusters), so residuals that are
  correlated in time (drift, coloured noise, a lag) do not make them too small,
* identifiability: the variance inflation of each parameter, with a torque offset
  always allowed for, on the whole log and with each fold left out.


The per-block statistics are in :mod:`hound_id.dyno.current.stats`, identifiability in
:mod:`hound_id.dyno.current.identifiable`, the searched parameters (delay, filter, hypers) in
:mod:`hound_id.dyno.current.search` and the torque's sign in :mod:`hound_id.dyno.current.slope`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen
from hound_id.dyno.current.effects import Effect, Signals, get, inputs, requirements_missing, shift_of
from hound_id.dyno.current.identifiable import identifiability
from hound_id.dyno.current.search import (
    FILTERS,
    Design,
    apart,
    bounds_of,
    delay_window,
    estimate_delay,
    estimate_filter,
    filter_held,
    filter_stderr,
    parameters_of,
    search_hyper,
)
from hound_id.dyno.current.slope import check_slope
from hound_id.dyno.current.stats import (
    Array,
    Blocks,
    Estimate,
    Stats,
    cross_validate,
    huber_weights,
    robust_cov,
    solve,
    solve_bounded,
    solve_normal,
)
from hound_id.errors import FitError

#: A parameter held at its bound is reported as wanting an unphysical value when the unconstrained fit puts it this many
#: standard errors beyond the bound (closer, the bound is simply where the truth may be: 3 sigma is one false report in
#: 740 bounded parameters). Calibrated on
#: test_polled_rig::test_a_clean_polled_log_recovers_the_truth_and_names_the_late_current and
#: test_diagnose::test_combinations_of_hidden_effects_are_found_exactly_with_nothing_extra.
UNPHYSICAL_SIGMAS = 3.0


@dataclass(frozen=True)
class FitResult:
    """A fitted model with its errors; arrays are read-only and in log order."""

    model: tuple[str, ...]
    """Effects in the model, in order."""
    parameters: Mapping[str, Estimate]
    """Every linear and nonlinear parameter by name."""
    rmse_train: float
    """Root-mean-square residual of the fit to every row [N m]."""
    rmse_test: float
    """Cross-validated RMSE: every fold predicted by the fit to the others [N m]."""
    n_train: int
    """Rows fitted (every row)."""
    n_test: int
    """Rows held out once each (every row)."""
    aic: float
    """Akaike information criterion (Gaussian likelihood, every row)."""
    bic: float
    """Bayesian information criterion."""
    prediction: Array
    """Model torque for every row [N m]."""
    residual: Array
    """Measured minus model torque for every row [N m]."""
    held_out: Array
    """Measured minus the torque predicted by the fit without the row's fold [N m]."""
    blocks: Blocks
    """The time blocks and folds."""
    block_rmse: Array
    """Held-out RMSE of each block [N m]."""
    fold_rmse_train: Array
    """RMSE of each fold's fit on its own training rows [N m]."""
    fold_rmse_test: Array
    """RMSE of each fold's fit on the fold it holds out [N m]."""
    robust: bool = False
    """Whether Huber weights were used."""
    hypers: Mapping[str, float] = field(default_factory=dict)
    """Nonlinear parameter values (also in ``parameters``)."""
    unphysical: Mapping[str, float] = field(default_factory=dict)
    """Parameters held at a bound where the unconstrained fit wants a value beyond it by more than
    :data:`UNPHYSICAL_SIGMAS` standard errors (a finding: the model lacks something), with that value."""

    @property
    def test(self) -> NDArray[np.bool_]:
        """Held-out rows: every row (each in its own fold)."""
        return np.ones(self.residual.shape[0], dtype=bool)

    def value(self, name: str) -> float:
        """A parameter value, 0 if the model lacks it."""
        est = self.parameters.get(name)
        return 0.0 if est is None else est.value

    def values(self) -> dict[str, float]:
        """All parameter values by name."""
        return {k: v.value for k, v in self.parameters.items()}


def _check_model(model: Sequence[str], signals: Signals) -> list[Effect]:
    effects = [get(name) for name in model]
    shift_of(model)  # at most one shift of the inputs
    for e in effects:
        missing = requirements_missing(e, signals)
        if missing == ["time"]:
            raise FitError(
                f"effect '{e.name}' needs sample times, and this log is a steady-state table (no time column); "
                f"leave '{e.name}' out, or map a time column with --columns time=<column>",
                effect=e.name,
            )
        if missing:
            raise FitError(
                f"effect '{e.name}' needs the {', '.join(missing)} channel, which the log lacks; "
                f"map it with --columns {missing[0]}=<column> or leave '{e.name}' out",
                effect=e.name,
            )
    return effects


def fit_model(
    signals: Signals,
    torque: Array,
    model: Sequence[str],
    *,
    robust: bool = False,
    hypers: Mapping[str, float] | None = None,
) -> FitResult:
    """Fit a model (sequence of effect names) to a log, within the parameters' physical bounds.

    Args:
        signals: Input channels.
        torque: Measured torque [N m].
        model: Effect names; ``linear`` is normally first.
        robust: Use Huber weights (iteratively reweighted least squares).
        hypers: Nonlinear parameter values to use instead of searching.

    Raises:
        FitError: Unknown effect, a channel it needs is missing, too few rows, or the log
            cannot identify a parameter of the model (the message says which and why).
        DynoDataError: The fitted torque constant is negative (a reversed torque sensor).
    """
    effects = _check_model(model, signals)
    design = Design(signals, torque)
    fixed = dict(hypers or {})
    delay_stderr = float("nan")
    linear_names = [
        e.name for e in effects if not apart(e.name) and (not e.hypers or all(h.name in fixed for h in e.hypers))
    ]
    searched = [e for e in effects if not apart(e.name) and e.name not in linear_names]
    shift_effect = shift_of(model)
    # the shift of the inputs (the delay) by its hyper's name; None when the inputs are read as logged
    shift = None if shift_effect is None else shift_effect.hypers[0].name
    free = shift is not None and shift not in fixed
    delay = 0.0 if shift is None else fixed.get(shift, 0.0)
    current = dict(fixed)
    if free:
        delay, delay_stderr = estimate_delay(design, linear_names, current)
    if shift is not None:
        current[shift] = delay
    shifted = signals.shifted(delay)
    base_names = list(linear_names)
    rows = design.search
    sub = shifted.take(rows)
    for e in searched:
        base = design.columns(base_names, current, sub)
        beta, _ = solve(base, torque[rows])
        value, _ = search_hyper(e, base, torque[rows], sub, torque[rows] - base @ beta, current)
        current.update(value)
        base_names.append(e.name)
    if shift is not None and free and searched:
        delay, delay_stderr = estimate_delay(design, model, current, start=delay)
        current[shift] = delay
    stderr = {} if shift is None else {shift: delay_stderr}
    inner = [m for m in model if m not in FILTERS]  # the columns and the shift, before the filters
    filters = [m for m in model if m in FILTERS]
    # a filter and a free delay both shift the reading in time: they are found together
    joint = free and bool(filters)
    for name in filters:
        if joint or not all(h.name in fixed for h in get(name).hypers):
            others = [m for m in filters if m != name and all(h.name in current for h in get(m).hypers)]
            current.update(estimate_filter(design, [*inner, *others], current, name, free_delay=joint))
    _check_window(signals, model, current)
    X = design.model_columns(model, current, inputs(signals, model, current))
    held: set[str] = set()
    for name in filters:
        stderr.update(filter_stderr(design, model, current, name, with_delay=joint))
        held |= filter_held(name, current, signals)
    return _finish(design, model, effects, X, current, stderr, robust, held)


def _check_window(signals: Signals, model: Sequence[str], hypers: Mapping[str, float]) -> None:
    """Refuse a model whose shift of the inputs (its delay, in ``hypers``) is beyond what a transducer filter or a bus
    makes."""
    shift = shift_of(model)
    if shift is None:
        return
    delay = hypers[shift.hypers[0].name]
    window = delay_window(signals)
    if abs(delay) > window:
        raise FitError(
            f"the delay fits only at {1e3 * delay:+.3g} ms, outside the +-{1e3 * window:.3g} ms a "
            "transducer filter or a bus can explain; check the time column's unit (--units time=ms) or leave "
            f"'{shift.name}' out",
            delay=delay,
        )


def _finish(
    design: Design,
    model: Sequence[str],
    effects: list[Effect],
    X: Array,
    hypers: Mapping[str, float],
    hyper_stderr: Mapping[str, float],
    robust: bool,
    hyper_held: set[str] | None = None,
) -> FitResult:
    """The linear parameters of ``model`` fitted within their bounds on the design's columns ``X`` (the hyper-parameters
    held at ``hypers``), with their standard errors, the cross-validated errors and the held-out residual."""
    y = design.torque
    n = y.size
    p = X.shape[1]
    names = [par.name for _, par in parameters_of(model)]
    Z = design.with_ones(X)
    stats = Stats(Z, y, design.blocks)
    cols = list(range(1, p + 1))
    _refuse_unidentified(stats, cols, model, design.signals)
    lower, upper = bounds_of(model)
    G, g, _ = stats.total(cols)
    free_beta, _ = solve_normal(G, g)
    if "kt" in names:
        check_slope(stats, 1 + names.index("kt"), design.signals.current)
    beta, active = solve_bounded(G, g, lower, upper)
    solve_stats = stats
    weights = None
    if robust:
        for _ in range(8):
            weights = huber_weights(y - X @ beta)
            solve_stats = Stats(Z, y, design.blocks, weights)
            Gw, gw, _ = solve_stats.total(cols)
            beta, active = solve_bounded(Gw, gw, lower, upper)
    pred = X @ beta
    resid = y - pred
    rss = float(resid @ resid)
    blocks = design.blocks
    cv = cross_validate(solve_stats, stats, cols, lower, upper)
    block_sse = cv.block_sse
    held_out = np.empty(n)
    for k, beta_k in enumerate(cv.betas):
        s = blocks.rows_of_fold(k)
        held_out[s] = y[s] - X[s] @ beta_k
    rmse_cv = math.sqrt(float(block_sse.sum()) / n)
    stderr, dof = _stderr(solve_stats, cols, beta, active, weights, resid, rss)
    beyond = _beyond(stats, cols, G, free_beta, active, (lower, upper), rss, dof)
    params, unphysical = _estimates(effects, beta, stderr, active, beyond, free_beta, hypers, hyper_stderr, hyper_held)
    k_all = p + sum(len(e.hypers) for e in effects)
    loglik_term = n * math.log(max(rss / max(n, 1), 1e-300))
    return FitResult(
        model=tuple(model),
        parameters=params,
        rmse_train=math.sqrt(rss / max(n, 1)),
        rmse_test=rmse_cv,
        n_train=n,
        n_test=n,
        aic=loglik_term + 2 * k_all,
        bic=loglik_term + k_all * math.log(max(n, 1)),
        prediction=frozen(pred),
        residual=frozen(resid),
        held_out=frozen(held_out),
        blocks=blocks,
        block_rmse=frozen(np.sqrt(block_sse / np.maximum(np.diff(blocks.edges), 1))),
        fold_rmse_train=frozen(cv.fold_rmse_train),
        fold_rmse_test=frozen(cv.fold_rmse_test),
        robust=robust,
        hypers={h.name: float(hypers.get(h.name, 0.0)) for e in effects for h in e.hypers},
        unphysical=unphysical,
    )


def _stderr(
    stats: Stats,
    cols: list[int],
    beta: Array,
    active: NDArray[np.bool_],
    weights: Array | None,
    resid: Array,
    rss: float,
) -> tuple[Array, int]:
    """(standard errors, cluster-robust and never below the classical ones; the residual's degrees of freedom)."""
    p = beta.size
    free = ~active
    cov = robust_cov(stats, cols, beta, free)
    dof = max(resid.size - int(free.sum()), 1)
    sigma2 = (float((weights * resid**2).sum()) if weights is not None else rss) / dof
    classic = np.zeros(p)
    if free.any():
        Gf, _, _ = stats.total([c for c, f in zip(cols, free, strict=True) if f])
        _, Ginv = solve_normal(Gf, np.zeros(Gf.shape[0]))
        classic[free] = np.diag(Ginv) * sigma2
    return np.sqrt(np.maximum(np.maximum(np.diag(cov), classic), 0.0)), dof


def _beyond(
    stats: Stats,
    cols: list[int],
    G: Array,
    free_beta: Array,
    active: NDArray[np.bool_],
    bounds: tuple[Array, Array],
    rss: float,
    dof: int,
) -> Array:
    """How far past its bound the unconstrained fit puts each held parameter, in standard errors (0 if free)."""
    p = free_beta.size
    beyond = np.zeros(p)
    if active.any():
        lower, upper = bounds
        free_all = np.ones(p, dtype=bool)
        free_cov = robust_cov(stats, cols, free_beta, free_all)
        _, Ginv_all = solve_normal(G, np.zeros(p))
        free_err = np.sqrt(np.maximum(np.maximum(np.diag(free_cov), np.diag(Ginv_all) * rss / dof), 1e-300))
        bound = np.where(free_beta < lower, lower, upper)
        beyond = np.abs(free_beta - bound) / free_err
    return beyond


def _estimates(
    effects: list[Effect],
    beta: Array,
    stderr: Array,
    active: NDArray[np.bool_],
    beyond: Array,
    free_beta: Array,
    hypers: Mapping[str, float],
    hyper_stderr: Mapping[str, float],
    hyper_held: set[str] | None,
) -> tuple[dict[str, Estimate], dict[str, float]]:
    """(every parameter's estimate by name; the free value of each held past UNPHYSICAL_SIGMAS at its bound)."""
    unphysical: dict[str, float] = {}
    params: dict[str, Estimate] = {}
    col = 0
    for e in effects:
        for par in e.parameters:
            at = bool(active[col])
            if at and beyond[col] > UNPHYSICAL_SIGMAS:
                unphysical[par.name] = float(free_beta[col])
            params[par.name] = Estimate(float(beta[col]), float(stderr[col]), par.unit, e.name, at)
            col += 1
        for h in e.hypers:
            err = float(hyper_stderr.get(h.name, float("nan")))
            held = h.name in (hyper_held or set())
            params[h.name] = Estimate(float(hypers.get(h.name, 0.0)), err, h.unit, e.name, held)
    return params, unphysical


def _refuse_unidentified(stats: Stats, cols: Sequence[int], model: Sequence[str], signals: Signals) -> None:
    """Refuse a fit whose parameters the log cannot tell apart (constant current, one quadrant, ...)."""
    owners = {par.name: e.name for e, par in parameters_of(model)}
    names = list(owners)
    G, _, _ = stats.total(cols)
    for k, name in enumerate(names):
        if G[k, k] == 0.0:
            raise FitError(
                f"the log gives '{name}' nothing to fit (its regressor is zero on every row); "
                "vary the current (both signs) and the speed, or leave that effect out",
                parameter=name,
            )
    problems = identifiability(stats, cols, names, signals)
    if problems:
        first = problems[0]
        # Kt is the point of the fit: suggest dropping the other effect (a torque offset is not an effect)
        drop = [
            owners[x] for x in (first.parameter, first.partner) if x in owners and owners[x] not in ("linear", "offset")
        ]
        remedy = f"leave out '{drop[-1]}' or record what is named" if drop else "record what is named"
        raise FitError(
            f"{first.sentence()}; no value is reported for {first.parameter} ({remedy})",
            parameters=[first.parameter, first.partner],
            vif=first.vif,
        )
