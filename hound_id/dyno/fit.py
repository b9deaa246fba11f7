"""Fitting a sum of effects to a dynamometer log.

Linear parameters are found by least squares on the training rows (optionally
Huber-robust, by iteratively reweighted least squares), nonlinear ones by search:
a candidate grid from the data (orders from the residual's spectrum over rotor
angle, speeds and currents on log/linear grids), then a bounded scalar refinement.
The delay is found by Gauss-Newton on the first-order expansion
torque(t - d) ~ torque(t) - d dtorque/dt, iterated with the shifted signals.

The log is split in time blocks: ten contiguous blocks, two of them (the 3rd and the
8th) held out. The held-out RMSE is the error the diagnosis tries to lower; the
train RMSE, AIC and BIC are reported beside it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen
from hound_id.dyno.effects import Effect, Signals, get, requirements_missing
from hound_id.errors import FitError

Array = NDArray[np.float64]

#: Number of contiguous time blocks the log is cut into, and which of them are held out.
BLOCKS = 10
TEST_BLOCKS = (2, 7)
#: Rows used to evaluate hyper-parameter candidates (a strided subset of the training rows).
SEARCH_ROWS = 100_000
#: Gauss-Newton iterations for the delay.
DELAY_ITERATIONS = 12


@dataclass(frozen=True)
class Estimate:
    """A fitted parameter."""

    value: float
    """Value in SI units."""
    stderr: float
    """Standard error (NaN where none is defined, e.g. an order found by search)."""
    unit: str
    """SI unit."""
    effect: str
    """Effect it belongs to."""

    def to_dict(self) -> dict[str, Any]:
        return {"value": self.value, "stderr": None if math.isnan(self.stderr) else self.stderr, "unit": self.unit}


@dataclass(frozen=True)
class FitResult:
    """A fitted model with its errors; arrays are read-only and in log order."""

    model: tuple[str, ...]
    """Effects in the model, in order."""
    parameters: Mapping[str, Estimate]
    """Every linear and nonlinear parameter by name."""
    rmse_train: float
    """Root-mean-square residual on the training rows [N m]."""
    rmse_test: float
    """Root-mean-square residual on the held-out time blocks [N m]."""
    n_train: int
    """Training rows."""
    n_test: int
    """Held-out rows."""
    aic: float
    """Akaike information criterion on the training rows (Gaussian likelihood)."""
    bic: float
    """Bayesian information criterion on the training rows."""
    prediction: Array
    """Model torque for every row [N m]."""
    residual: Array
    """Measured minus model torque for every row [N m]."""
    test: NDArray[np.bool_]
    """Held-out rows."""
    robust: bool = False
    """Whether Huber weights were used."""
    hypers: Mapping[str, float] = field(default_factory=dict)
    """Nonlinear parameter values (also in ``parameters``)."""

    def value(self, name: str) -> float:
        """A parameter value, 0 if the model lacks it."""
        est = self.parameters.get(name)
        return 0.0 if est is None else est.value

    def values(self) -> dict[str, float]:
        """All parameter values by name."""
        return {k: v.value for k, v in self.parameters.items()}


def time_blocked_split(n: int) -> NDArray[np.bool_]:
    """Held-out mask: blocks :data:`TEST_BLOCKS` of :data:`BLOCKS` contiguous blocks."""
    block = np.minimum((np.arange(n) * BLOCKS) // max(n, 1), BLOCKS - 1)
    return np.isin(block, TEST_BLOCKS)


class Design:
    """Builds regressor columns for a model on a log and solves least-squares problems on it."""

    def __init__(self, signals: Signals, torque: Array, test: NDArray[np.bool_] | None = None) -> None:
        self.signals = signals
        self.torque = np.asarray(torque, float)
        n = self.torque.shape[0]
        if n < 20:
            raise FitError(f"only {n} rows; a fit needs at least 20")
        self.test = time_blocked_split(n) if test is None else test
        self.train = ~self.test
        stride = max(1, int(self.train.sum()) // SEARCH_ROWS)
        self.search = np.flatnonzero(self.train)[::stride]

    def columns(self, model: Sequence[str], hypers: Mapping[str, float], signals: Signals | None = None) -> Array:
        """Regressor matrix (n, p) of the model's linear parameters."""
        s = self.signals if signals is None else signals
        blocks = [get(name).columns(s, hypers) for name in model]
        n = s.current.shape[0]
        return np.hstack(blocks) if blocks else np.empty((n, 0))


def solve_normal(G: Array, g: Array) -> tuple[Array, Array]:
    """Solve the normal equations G beta = g with diagonal scaling; returns (beta, G^-1)."""
    if G.shape[0] == 0:
        return np.empty(0), np.empty((0, 0))
    d = np.sqrt(np.diag(G))
    d[d <= 1e-150 + 1e-12 * max(float(d.max()), 1e-300)] = 1.0  # (near-)empty column: leave it to pinv
    Gs = G / np.outer(d, d)
    try:
        G_inv = np.linalg.inv(Gs)
        if not np.all(np.isfinite(G_inv)) or np.linalg.cond(Gs) > 1e13:
            raise np.linalg.LinAlgError
    except np.linalg.LinAlgError:
        G_inv = np.linalg.pinv(Gs)
    beta = G_inv @ (g / d)
    return beta / d, G_inv / np.outer(d, d)


def solve(X: Array, y: Array, weights: Array | None = None) -> tuple[Array, Array]:
    """Least squares of y on X (optionally weighted): returns (beta, inverse of X^T W X)."""
    if X.shape[1] == 0:
        return np.empty(0), np.empty((0, 0))
    if weights is not None:
        Xw = X * weights[:, None]
        return solve_normal(Xw.T @ X, Xw.T @ y)
    return solve_normal(X.T @ X, X.T @ y)


class Normal:
    """Normal equations of y on X over some rows, so extra columns cost only their cross-products.

    The rows are given as contiguous slices (time blocks), so nothing is copied.
    """

    def __init__(self, X: Array, y: Array, rows: Sequence[slice] | None = None) -> None:
        self.X, self.y = X, y
        self.rows = [slice(None)] if rows is None else list(rows)
        self.G = sum((X[r].T @ X[r] for r in self.rows), np.zeros((X.shape[1], X.shape[1])))
        self.g = sum((X[r].T @ y[r] for r in self.rows), np.zeros(X.shape[1]))
        self.yy = float(sum(y[r] @ y[r] for r in self.rows))

    def extend(self, C: Array) -> tuple[Array, float]:
        """Coefficients on [X, C] and the residual sum of squares over these rows (C: all rows of X)."""
        G, g = self._blocks(C)
        beta, _ = solve_normal(G, g)
        return beta, self._rss(beta, G, g)

    def sse(self, beta: Array, C: Array) -> float:
        """Residual sum of squares over these rows for coefficients fitted elsewhere."""
        G, g = self._blocks(C)
        return self._rss(beta, G, g)

    def _blocks(self, C: Array) -> tuple[Array, Array]:
        if C.shape[1] == 0:
            return self.G, self.g
        p, q = self.X.shape[1], C.shape[1]
        XC, CC, Cy = np.zeros((p, q)), np.zeros((q, q)), np.zeros(q)
        for r in self.rows:
            Cr = C[r]
            XC += self.X[r].T @ Cr
            CC += Cr.T @ Cr
            Cy += Cr.T @ self.y[r]
        return np.block([[self.G, XC], [XC.T, CC]]), np.concatenate([self.g, Cy])

    def _rss(self, beta: Array, G: Array, g: Array) -> float:
        return max(self.yy - 2.0 * float(beta @ g) + float(beta @ G @ beta), 0.0)


def mask_slices(mask: NDArray[np.bool_]) -> list[slice]:
    """The contiguous runs of True in a mask, as slices."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.astype(np.int8), [0]))))
    return [slice(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def rss_with(base: Array, extra: Array, y: Array) -> float:
    """Residual sum of squares of y on [base, extra]."""
    return Normal(base, y).extend(extra)[1]


def _huber_weights(r: Array, k: float = 1.345) -> Array:
    s = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    if s <= 0:
        return np.ones_like(r)
    a = np.abs(r) / (k * s)
    return np.where(a <= 1.0, 1.0, 1.0 / np.maximum(a, 1e-12))


def search_hyper(
    design: Design, effect: Effect, base: Normal, signals: Signals, residual: Array, hypers: Mapping[str, float]
) -> tuple[dict[str, float], int]:
    """Best value of an effect's nonlinear parameter on the search rows.

    Args:
        design: The log.
        effect: The effect whose hyper is searched.
        base: Normal equations of the rest of the model on the search rows.
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

    def cost(value: float) -> float:
        trial = dict(hypers)
        trial[hyper.name] = float(value)
        return base.extend(effect.columns(signals, trial))[1]

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
    return tuple(sorted({c for m in model for c in get(m).requires}))


def _delay_step(
    design: Design, model: Sequence[str], hypers: Mapping[str, float], delay: float
) -> tuple[float, float, float]:
    """Gauss-Newton step for the delay on the search rows: (step [s], its stderr [s], RSS at ``delay``)."""
    rows = design.search
    shifted = design.signals.shifted(delay, rows, _channels(model))
    X = design.columns([m for m in model if m != "delay"], hypers, shifted)
    y = design.torque[rows]
    beta, _ = solve(X, y)
    pred = X @ beta
    r0 = y - pred
    # d/dt of the model torque; a positive step means the channel lags more than assumed.
    rate = np.gradient(pred, shifted.time)
    Z = np.column_stack([X, -rate])
    beta2, cov = solve(Z, y)
    r = y - Z @ beta2
    dof = max(rows.size - Z.shape[1], 1)
    sigma2 = float(r @ r) / dof
    return float(beta2[-1]), math.sqrt(max(sigma2 * cov[-1, -1], 0.0)), float(r0 @ r0)


def _delay_rss(design: Design, model: Sequence[str], hypers: Mapping[str, float], delay: float) -> float:
    rows = design.search
    shifted = design.signals.shifted(delay, rows, _channels(model))
    X = design.columns([m for m in model if m != "delay"], hypers, shifted)
    return rss_with(X, np.empty((rows.size, 0)), design.torque[rows])


def estimate_delay(
    design: Design, model: Sequence[str], hypers: Mapping[str, float], start: float = 0.0
) -> tuple[float, float]:
    """Delay of the torque channel [s] and its standard error.

    Gauss-Newton on the time shift gives the direction; a line search on the residual
    sum of squares (steps x1, x2, x4, ... and halving) takes it as far as it pays. Near
    the answer the linearisation is good and the steps converge quickly; far from it
    (fast current edges, a delay of several samples) the line search keeps it moving.
    """
    delay, stderr = start, float("nan")
    dt = float(np.median(np.diff(design.signals.time)))
    for _ in range(DELAY_ITERATIONS):
        step, stderr, rss0 = _delay_step(design, model, hypers, delay)
        if abs(step) < 1e-3 * dt:
            break
        best, best_rss = delay, rss0
        factor = 1.0
        while factor <= 64:
            trial = _delay_rss(design, model, hypers, delay + factor * step)
            if trial >= best_rss:
                break
            best, best_rss = delay + factor * step, trial
            factor *= 2
        if best == delay:  # the full step overshoots: halve it until it helps
            factor = 0.5
            while factor > 1e-3:
                trial = _delay_rss(design, model, hypers, delay + factor * step)
                if trial < best_rss:
                    best, best_rss = delay + factor * step, trial
                    break
                factor /= 2
        if best == delay:
            break
        delay = best
    return delay, stderr


def fit_model(
    signals: Signals,
    torque: Array,
    model: Sequence[str],
    *,
    robust: bool = False,
    test: NDArray[np.bool_] | None = None,
    hypers: Mapping[str, float] | None = None,
) -> FitResult:
    """Fit a model (sequence of effect names) to a log.

    Args:
        signals: Input channels.
        torque: Measured torque [N m].
        model: Effect names; ``linear`` is normally first.
        robust: Use Huber weights (iteratively reweighted least squares).
        test: Held-out mask (default: time blocks, :func:`time_blocked_split`).
        hypers: Nonlinear parameter values to use instead of searching.

    Raises:
        FitError: Unknown effect, a channel it needs is missing, or too few rows.
    """
    effects = [get(name) for name in model]
    for e in effects:
        missing = requirements_missing(e, signals)
        if missing:
            raise FitError(
                f"effect '{e.name}' needs the {', '.join(missing)} channel, which the log lacks; "
                f"map it with --columns {missing[0]}=<column> or leave '{e.name}' out",
                effect=e.name,
            )
    design = Design(signals, torque, test)
    fixed = dict(hypers or {})
    delay_stderr = float("nan")
    linear_names = [
        e.name for e in effects if e.name != "delay" and (not e.hypers or all(h.name in fixed for h in e.hypers))
    ]
    searched = [e for e in effects if e.name != "delay" and e.name not in linear_names]
    has_delay = "delay" in model
    delay = fixed.get("delay", 0.0)
    current = dict(fixed)
    if has_delay and "delay" not in fixed:
        delay, delay_stderr = estimate_delay(design, linear_names, current)
    current["delay"] = delay
    shifted = signals.shifted(delay)
    base_names = list(linear_names)
    rows = design.search
    sub = shifted.take(rows)
    for e in searched:
        base = design.columns(base_names, current, sub)
        normal = Normal(base, torque[rows])
        beta, _ = solve_normal(normal.G, normal.g)
        value, _ = search_hyper(design, e, normal, sub, torque[rows] - base @ beta, current)
        current.update(value)
        base_names.append(e.name)
    if has_delay and "delay" not in fixed and searched:
        delay, delay_stderr = estimate_delay(design, [m for m in model if m != "delay"], current, start=delay)
        current["delay"] = delay
        shifted = signals.shifted(delay)
    X = design.columns([m for m in model if m != "delay"], current, shifted)
    return _finish(design, model, effects, X, current, has_delay, delay_stderr, robust)


def _finish(
    design: Design,
    model: Sequence[str],
    effects: list[Effect],
    X: Array,
    hypers: Mapping[str, float],
    has_delay: bool,
    delay_stderr: float,
    robust: bool,
) -> FitResult:
    tr, te = design.train, design.test
    y = design.torque
    _check_identifiable(X[tr], model, effects)
    weights = None
    beta, cov_unit = solve(X[tr], y[tr])
    if robust:
        for _ in range(8):
            weights = _huber_weights(y[tr] - X[tr] @ beta)
            beta, cov_unit = solve(X[tr], y[tr], weights)
    pred = X @ beta
    resid = y - pred
    n_tr, n_te = int(tr.sum()), int(te.sum())
    rss = float(resid[tr] @ resid[tr])
    k = X.shape[1] + sum(len(e.hypers) for e in effects)
    dof = max(n_tr - X.shape[1], 1)
    sigma2 = (float((weights * resid[tr] ** 2).sum()) if weights is not None else rss) / dof
    stderr = np.sqrt(np.maximum(np.diag(cov_unit) * sigma2, 0.0))
    params: dict[str, Estimate] = {}
    col = 0
    for e in effects:
        for p in e.parameters:
            params[p.name] = Estimate(float(beta[col]), float(stderr[col]), p.unit, e.name)
            col += 1
        for h in e.hypers:
            err = delay_stderr if h.name == "delay" else float("nan")
            params[h.name] = Estimate(float(hypers.get(h.name, 0.0)), err, h.unit, e.name)
    loglik_term = n_tr * math.log(max(rss / max(n_tr, 1), 1e-300))
    return FitResult(
        model=tuple(model),
        parameters=params,
        rmse_train=math.sqrt(rss / max(n_tr, 1)),
        rmse_test=math.sqrt(float(resid[te] @ resid[te]) / max(n_te, 1)),
        n_train=n_tr,
        n_test=n_te,
        aic=loglik_term + 2 * k,
        bic=loglik_term + k * math.log(max(n_tr, 1)),
        prediction=frozen(pred),
        residual=frozen(resid),
        test=frozen(te, dtype=bool),
        robust=robust,
        hypers={h.name: float(hypers.get(h.name, 0.0)) for e in effects for h in e.hypers},
    )


def _check_identifiable(X: Array, model: Sequence[str], effects: list[Effect]) -> None:
    """Refuse a fit whose columns the log cannot tell apart (constant current, zero current, ...)."""
    names = [f"{e.name}:{p.name}" for e in effects for p in e.parameters]
    G = X.T @ X
    norms = np.sqrt(np.diag(G))
    for k, value in enumerate(norms):
        if value == 0.0:
            raise FitError(
                f"the log gives '{names[k]}' nothing to fit (its regressor is zero on every training row); "
                "vary the current (both signs) and the speed, or leave that effect out",
                parameter=names[k],
            )
    # Singular values of the column-normalised X are the square roots of the normalised Gram's eigenvalues.
    eigval, eigvec = np.linalg.eigh(G / np.outer(norms, norms))
    smallest, largest = max(float(eigval[0]), 0.0), float(eigval[-1])
    if smallest < 1e-12 * largest:
        involved = [names[k] for k in np.argsort(np.abs(eigvec[:, 0]))[::-1][:2]]
        raise FitError(
            f"the log cannot tell {involved[0]} from {involved[1]} (their regressors are collinear, "
            f"condition {np.sqrt(largest / max(smallest, 1e-300)):.2g}); the test must vary the current over a range "
            "of both signs (and the speed, for friction terms)",
            parameters=involved,
        )
