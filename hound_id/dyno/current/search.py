"""The searched (nonlinear) parameters of a model: the design matrix over a log (:class:`Design`), the hyper-parameter
grids and their refinement, the delay between the channels (Gauss-Newton on the shifted signals) and the
transducer's filter."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from hound_id.dyno.current import transducer
from hound_id.dyno.current.effects import Effect, Signals, get, inputs, shift_of
from hound_id.dyno.current.stats import Array, Blocks, Stats, robust_cov, solve, solve_normal
from hound_id.errors import FitError

#: Fewest rows a fit takes (ten operating points; fewer cannot hold out ten folds). Calibrated on
#: test_logs::test_a_table_of_26_operating_points_and_a_burst_written_16_times_are_read.
MIN_FIT_ROWS = 10
#: Filters of the torque channel (:mod:`.transducer`): effects that add no column but pass the others through.
FILTERS = transducer.FILTERS


#: Rows used to evaluate hyper-parameter candidates (a strided subset of the log): a 100 s log at 1 kHz is searched
#: whole; a million-row log every tenth row, which keeps its fit within the benchmark's time target while 100,000 rows
#: still place a hyper-parameter far inside its standard error. Calibrated on benchmarks/fit_current.py and
#: test_fit::test_nonlinear_parameters_are_found.
SEARCH_ROWS = 100_000
#: Gauss-Newton iterations for the delay: the step converges quadratically from the grid's start, so twelve leave a
#: margin over the few it takes on the simulated and polled logs. Calibrated on
#: test_fit::test_nonlinear_parameters_are_found and test_fit::test_delay_has_a_standard_error.
DELAY_ITERATIONS = 12
#: Half-width of the delay window [s]: a transducer filter or a bus adds milliseconds, not more (the polled rig's late
#: current is 4 ms; 80 ms is refused). Calibrated on test_polled_rig::test_a_delay_outside_its_window_is_refused and
#: test_polled_rig::test_the_delay_is_signed_and_both_signs_are_named.
DELAY_WINDOW = 0.03


#: Largest delay window [s]: a slower log (two samples further apart) cannot show a rig's lag; a time column in ms read
#: as seconds (1 s steps) lies far beyond. Calibrated on
#: test_polled_rig::test_time_in_ms_without_a_unit_is_a_warning_and_no_delay_is_fitted.
DELAY_MAX = 0.25


def apart(name: str) -> bool:
    """Whether an effect adds no column and fit_model handles it apart from the linear search: a shift of the inputs
    (:attr:`~hound_id.dyno.current.effect.Effect.shift`) or a filter of the torque channel (:data:`FILTERS`)."""
    return get(name).shift or name in FILTERS


class Design:
    """A log with its blocks: builds regressor columns and the search rows."""

    def __init__(self, signals: Signals, torque: Array) -> None:
        self.signals = signals
        self.torque = np.asarray(torque, float)
        n = self.torque.shape[0]
        if n < MIN_FIT_ROWS:
            raise FitError(f"only {n} rows; a fit needs at least {MIN_FIT_ROWS}")
        self.blocks = Blocks.of(n, signals.timed)
        stride = max(1, n // SEARCH_ROWS)
        self.search = np.arange(0, n, stride)

    def columns(self, model: Sequence[str], hypers: Mapping[str, float], signals: Signals | None = None) -> Array:
        """Regressor matrix (n, p) of the model's linear parameters."""
        s = self.signals if signals is None else signals
        blocks = [get(name).columns(s, hypers) for name in model]
        n = s.current.shape[0]
        return np.hstack(blocks) if blocks else np.empty((n, 0))

    def with_ones(self, X: Array) -> Array:
        return np.hstack([np.ones((X.shape[0], 1)), X])

    def model_columns(self, model: Sequence[str], hypers: Mapping[str, float], signals: Signals) -> Array:
        """Columns of the model's linear parameters on every row of (delay-shifted) ``signals``, passed through the
        model's filters of the torque channel (:mod:`.transducer`)."""
        X = self.columns([m for m in model if not apart(m)], hypers, signals)
        for name in model:
            if name in FILTERS:
                X = transducer.apply(name, hypers, signals.time, X)
        return X


def parameters_of(model: Sequence[str]) -> list[tuple[Effect, Any]]:
    """(effect, parameter) of every linear parameter of a model, in column order."""
    return [(e, p) for e in (get(m) for m in model) for p in e.parameters]


def bounds_of(model: Sequence[str]) -> tuple[Array, Array]:
    params = parameters_of(model)
    return np.array([p.lower for _, p in params], float), np.array([p.upper for _, p in params], float)


def search_hyper(
    effect: Effect, base: Array, y: Array, signals: Signals, residual: Array, hypers: Mapping[str, float]
) -> tuple[dict[str, float], int]:
    """Best value of an effect's nonlinear parameter on the search rows.

    Args:
        effect: The effect whose hyper is searched.
        base: Columns of the rest of the model on the search rows.
        y: Torque on the search rows.
        signals: Signals (already delay-shifted) on the search rows.
        residual: Residual of the rest of the model on the search rows.
        hypers: Values of the other nonlinear parameters.

    Returns the chosen {name: value} and the number of candidates tried.
    """
    if not effect.hypers:
        return {}, 1
    if len(effect.hypers) > 1:
        raise FitError(
            f"effect '{effect.name}' has {len(effect.hypers)} nonlinear parameters; at most one is supported"
        )
    hyper = effect.hypers[0]
    candidates = np.unique(hyper.candidates(signals, residual))
    candidates = candidates[np.isfinite(candidates) & (candidates > 0)]
    if candidates.size == 0:
        raise FitError(
            f"effect '{effect.name}': the log gives no candidate for '{hyper.name}' (too little rotation or excitation)"
        )
    G0, g0, yy = base.T @ base, base.T @ y, float(y @ y)

    def cost(value: float) -> float:
        trial = dict(hypers)
        trial[hyper.name] = float(value)
        C = effect.columns(signals, trial)
        BC = base.T @ C
        G = np.block([[G0, BC], [BC.T, C.T @ C]])
        g = np.concatenate([g0, C.T @ y])
        beta, _ = solve_normal(G, g)
        return max(yy - 2.0 * float(beta @ g) + float(beta @ G @ beta), 0.0)

    costs = np.array([cost(v) for v in candidates])
    best = int(np.argmin(costs))
    value = float(candidates[best])
    tried = int(candidates.size)
    if hyper.refine and candidates.size > 2:
        from scipy.optimize import minimize_scalar

        lo = float(candidates[max(best - 1, 0)])
        hi = float(candidates[min(best + 1, candidates.size - 1)])
        if hi > lo:
            res = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 1e-3 * (hi - lo)})
            if res.success and res.fun <= costs[best]:
                value = float(res.x)
            tried += int(res.nfev)
    if hyper.integer:
        value = float(round(value))
    return {hyper.name: value}, tried


def _channels(model: Sequence[str]) -> tuple[str, ...]:
    """Channels the model's effects read (current is always kept)."""
    return tuple(sorted({c for m in model for c in get(m).requires if c != "time"}))


def delay_window(signals: Signals) -> float:
    """Largest |delay| the fit accepts [s]: :data:`DELAY_WINDOW`, or two samples on a slow log.

    Raises:
        FitError: The samples are so far apart (beyond :data:`DELAY_MAX` for two of them) that no lag a rig
            makes can be seen; most often a time column in ms read as seconds.
    """
    dt = float(np.median(np.diff(signals.time))) if signals.time.size > 1 else 0.0
    if 2.0 * dt > DELAY_MAX:
        raise FitError(
            f"the samples are {dt:.3g} s apart ({1 / dt:.3g} Hz): a lag between channels, milliseconds on a rig, "
            "cannot be seen at that rate; if the time column is in ms, pass --units time=ms",
            delay=dt,
        )
    return max(DELAY_WINDOW, 2.0 * dt)


def _delay_step(
    design: Design, model: Sequence[str], hypers: Mapping[str, float], delay: float
) -> tuple[float, float, float]:
    """Gauss-Newton step for the delay on the search rows: (step [s], its robust stderr [s], RSS at ``delay``)."""
    rows = design.search
    shifted = design.signals.shifted(delay, rows, _channels(model))
    X = design.columns(model, hypers, shifted)
    y = design.torque[rows]
    beta, _ = solve(X, y)
    pred = X @ beta
    r0 = y - pred
    # d/dt of the model torque; a positive step means the channel lags more than assumed.
    rate = np.gradient(pred, shifted.time)
    Z = np.column_stack([X, -rate])
    stats = Stats(Z, y, Blocks.of(rows.size))
    G, g, _ = stats.total(range(Z.shape[1]))
    beta2, _ = solve_normal(G, g)
    cov = robust_cov(stats, range(Z.shape[1]), beta2, np.ones(Z.shape[1], dtype=bool))
    return float(beta2[-1]), math.sqrt(max(float(cov[-1, -1]), 0.0)), float(r0 @ r0)


def _delay_rss(design: Design, model: Sequence[str], hypers: Mapping[str, float], delay: float) -> float:
    rows = design.search
    shifted = design.signals.shifted(delay, rows, _channels(model))
    X = design.columns(model, hypers, shifted)
    y = design.torque[rows]
    beta, _ = solve(X, y)
    r = y - X @ beta
    return float(r @ r)


def estimate_delay(
    design: Design, model: Sequence[str], hypers: Mapping[str, float], start: float = 0.0
) -> tuple[float, float]:
    """Delay of the torque channel behind the current channel [s] and its (robust) standard error: the shift of the
    inputs (:attr:`~hound_id.dyno.current.effect.Effect.shift`) that fits ``model``'s columns best (the shift itself
    adds none).

    Gauss-Newton on the time shift gives the direction; a line search on the residual
    sum of squares (steps x1, x2, x4, ... and halving) takes it as far as it pays. The
    search stays within +-1.5 x :func:`delay_window`, so a value at that edge shows
    the log asks for more than the window.
    """
    delay, stderr = start, float("nan")
    dt = float(np.median(np.diff(design.signals.time)))
    reach = 1.5 * delay_window(design.signals)
    for _ in range(DELAY_ITERATIONS):
        step, stderr, rss0 = _delay_step(design, model, hypers, delay)
        if abs(step) < 1e-3 * dt:
            break
        best, best_rss = delay, rss0
        factor = 1.0
        while factor <= 64:
            target = float(np.clip(delay + factor * step, -reach, reach))
            trial = _delay_rss(design, model, hypers, target)
            if trial >= best_rss:
                break
            best, best_rss = target, trial
            if abs(target) >= reach:
                break
            factor *= 2
        if best == delay:  # the full step overshoots: halve it until it helps
            factor = 0.5
            while factor > 1e-3:
                target = float(np.clip(delay + factor * step, -reach, reach))
                trial = _delay_rss(design, model, hypers, target)
                if trial < best_rss:
                    best, best_rss = target, trial
                    break
                factor /= 2
        if best == delay:
            break
        delay = best
    return delay, stderr


def filter_held(name: str, hypers: Mapping[str, float], signals: Signals) -> set[str]:
    """The filter's hypers held at the end of the range the log can show (a value there is a bound, not a finding):
    within 1e-3 of a bound of the search point."""
    return {c.hyper for c in transducer.at_edge(name, hypers, signals.time, math.expm1(1e-3))}


def _filter_rss(design: Design, X: Array, name: str, hypers: Mapping[str, float]) -> float:
    """Residual sum of squares of the torque on the filtered columns (and an offset), unbounded least squares."""
    Z = design.with_ones(transducer.apply(name, hypers, design.signals.time, X))
    beta, _ = solve(Z, design.torque)
    r = design.torque - Z @ beta
    return float(r @ r)


class _FilterSearch:
    """The residual of a model whose filter (and, with ``free_delay``, whose shift of the inputs) are trial values: the
    point is the filter's hypers in log space, then the delay [s]."""

    def __init__(
        self, design: Design, model: Sequence[str], hypers: Mapping[str, float], name: str, free_delay: bool
    ) -> None:
        self.design, self.model, self.hypers, self.name, self.free_delay = design, model, hypers, name, free_delay
        shift = shift_of(model)
        if free_delay and shift is None:
            raise FitError(f"the filter '{name}' is searched with a delay, and the model has no shift of the inputs")
        self.shift = None if shift is None else shift.hypers[0].name
        signals = design.signals
        lo, hi = transducer.search_bounds(name, signals.time)
        if free_delay:
            reach = 1.5 * delay_window(signals)
            lo, hi = np.append(lo, -reach), np.append(hi, reach)
        self.lo, self.hi = lo, hi
        self._fixed_X = None if free_delay else design.model_columns(model, hypers, inputs(signals, model, hypers))

    def delay(self) -> float:
        """The shift's value in the hypers [s] (0 without a shift)."""
        return 0.0 if self.shift is None else self.hypers.get(self.shift, 0.0)

    def values(self, point: Array) -> dict[str, float]:
        p = np.clip(point, self.lo, self.hi)
        out = transducer.from_point(self.name, p[: p.size - int(self.free_delay)])
        if self.shift is not None and self.free_delay:
            out[self.shift] = float(p[-1])
        return out

    def columns(self, point: Array) -> Array:
        """The model's columns before this filter, at the point's delay."""
        if self._fixed_X is not None:
            return self._fixed_X
        delay = float(np.clip(point, self.lo, self.hi)[-1])
        return self.design.model_columns(self.model, self.hypers, self.design.signals.shifted(delay))

    def rss(self, point: Array) -> float:
        return _filter_rss(self.design, self.columns(point), self.name, {**self.hypers, **self.values(point)})


def estimate_filter(
    design: Design, model: Sequence[str], hypers: Mapping[str, float], name: str, *, free_delay: bool = False
) -> dict[str, float]:
    """The filter's hypers (``lag_tau``, or ``resonance_f0`` and ``resonance_zeta``) that fit the torque best with the
    model's columns on every row (a filter needs the rows in sequence), and with ``free_delay`` the model's shift of
    the inputs with them:
    the candidates of its hypers on a grid (their product for a resonance) at the current delay, then a Nelder-Mead
    refinement in log space (and the delay) within the range the log can show."""
    from scipy.optimize import minimize

    search = _FilterSearch(design, model, hypers, name, free_delay)
    effect = get(name)
    grids = [np.log(np.unique(h.candidates(design.signals, design.torque))) for h in effect.hypers]
    if free_delay:
        grids.append(np.array([float(search.delay())]))
    points = np.array(np.meshgrid(*grids, indexing="ij")).reshape(len(grids), -1).T
    costs = [search.rss(p) for p in points]
    start = points[int(np.argmin(costs))]
    res = minimize(search.rss, start, method="Nelder-Mead", options={"xatol": 1e-3, "fatol": 1e-12, "maxiter": 150})
    best = res.x if res.fun <= min(costs) else start
    return search.values(best)


def filter_stderr(
    design: Design, model: Sequence[str], hypers: Mapping[str, float], name: str, *, with_delay: bool = False
) -> dict[str, float]:
    """Cluster-robust standard errors of a filter's hypers (and of the model's shift of the inputs found with it): the
    prediction's sensitivity to each (central differences, in log space for the filter), the linear parameters beside
    them, with the time blocks as clusters."""
    others = [m for m in model if m != name]
    search = _FilterSearch(design, others, hypers, name, with_delay)
    delay = search.delay()
    point = transducer.to_point(name, hypers)
    if with_delay:
        point = np.append(point, delay)
    X = transducer.apply(name, hypers, design.signals.time, search.columns(point))
    Z = design.with_ones(X)
    beta, _ = solve(Z, design.torque)
    resid = design.torque - Z @ beta
    J = []
    for j in range(point.size):
        step = np.zeros_like(point)
        step[j] = 1e-3 if j < point.size - int(with_delay) else 1e-2 * max(abs(delay), 1e-4)
        pred = []
        for sign in (1.0, -1.0):
            trial = point + sign * step
            cols = transducer.apply(
                name, {**hypers, **search.values(trial)}, design.signals.time, search.columns(trial)
            )
            pred.append(design.with_ones(cols) @ beta)
        J.append((pred[0] - pred[1]) / (2 * step[j]))
    full = np.column_stack([Z, *J])
    A = full.T @ full
    meat = np.zeros_like(A)
    for rows in design.blocks.slices():
        score = full[rows].T @ resid[rows]
        meat += np.outer(score, score)
    _, A_inv = solve_normal(A, np.zeros(A.shape[0]))
    cov = A_inv @ meat @ A_inv
    values = search.values(point)
    out = {}
    for j, key in enumerate(values):
        var = float(cov[Z.shape[1] + j, Z.shape[1] + j])
        scale = 1.0 if key == search.shift else values[key]  # d value = value d log value
        out[key] = scale * math.sqrt(var) if var >= 0 else float("nan")
    return out
