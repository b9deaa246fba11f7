"""Fitting a sum of effects to a dynamometer log.

Linear parameters are found by least squares within their physical bounds (Kt > 0,
friction >= 0, saturation bending the curve down; :class:`~hound_id.dyno.current.effects.Parameter`),
optionally Huber-robust, nonlinear ones by search: a candidate grid from the data
(orders from the residual's spectrum over rotor angle, speeds and currents on
log/linear grids), then a bounded scalar refinement. The delay is found by
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
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen
from hound_id.dyno.artefacts import noise_sigma, quantum
from hound_id.dyno.current import transducer
from hound_id.dyno.current.effects import Effect, Signals, get, requirements_missing
from hound_id.errors import DynoDataError, FitError

Array = NDArray[np.float64]

#: Largest number of contiguous time blocks (clusters of the robust standard errors): 50 blocks of a 60 s log are 1.2 s
#: each, long enough to span a plateau of the test plan (so that slow drifts stay within a cluster) and short enough to
#: date where a log breaks to about a second; the smallest number of rows in a block keeps each block's statistics
#: meaningful on short logs; folds of blocks, each held out once: ten, the usual cross-validation compromise between
#: held-out rows per fold and refits. Calibrated on test_fit::test_blocks_cover_every_row_once_and_folds_are_contiguous
#: and test_polled_rig::test_a_log_that_breaks_midway_is_flagged_with_its_times.
MAX_BLOCKS = 50
MIN_BLOCK_ROWS = 25
FOLDS = 10
#: Fewest rows a fit takes (ten operating points; fewer cannot hold out ten folds). Calibrated on
#: test_logs::test_a_table_of_26_operating_points_and_a_burst_written_16_times_are_read.
MIN_FIT_ROWS = 10
#: Filters of the torque channel (:mod:`.transducer`): effects that add no column but pass the others through.
FILTERS = transducer.FILTERS
#: Effects that add no column: fit_model handles them apart from the linear search.
SPECIAL = ("delay", *FILTERS)
#: Blocks of a log shorter than ten ordinary blocks (a table of tens of operating points, a burst): ten, as many as
#: folds. Calibrated on test_logs::test_a_table_of_26_operating_points_and_a_burst_written_16_times_are_read and
#: test_logs::test_clean_small_tables_keep_every_row.
SMALL_BLOCKS = 10
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
#: Variance inflation beyond which the log cannot tell a parameter from the others (R^2 > 0.9999). The library's effects
#: on a well-designed test stay below 1.5e3 (saturation family beside each other); one quadrant (Kt against gear
#: friction) or a held current (Kt against the offset) go far beyond. Calibrated on
#: test_polled_rig::test_one_quadrant_cannot_tell_kt_from_gear_friction,
#: test_polled_rig::test_a_held_current_cannot_identify_kt, test_fit_cli::test_logs_that_identify_nothing_are_refused
#: and test_diagnose::test_combinations_of_hidden_effects_are_found_exactly_with_nothing_extra.
VIF_MAX = 1.0e4
#: Largest delay window [s]: a slower log (two samples further apart) cannot show a rig's lag; a time column in ms read
#: as seconds (1 s steps) lies far beyond. Calibrated on
#: test_polled_rig::test_time_in_ms_without_a_unit_is_a_warning_and_no_delay_is_fitted.
DELAY_MAX = 0.25
#: A parameter held at its bound is reported as wanting an unphysical value when the unconstrained fit puts it this many
#: standard errors beyond the bound (closer, the bound is simply where the truth may be: 3 sigma is one false report in
#: 740 bounded parameters). Calibrated on
#: test_polled_rig::test_a_clean_polled_log_recovers_the_truth_and_names_the_late_current and
#: test_diagnose::test_combinations_of_hidden_effects_are_found_exactly_with_nothing_extra.
UNPHYSICAL_SIGMAS = 3.0
#: Name of the torque offset the identifiability check always allows for.
OFFSET = "a torque offset"


@dataclass(frozen=True)
class Estimate:
    """A fitted parameter."""

    value: float
    """Value in SI units."""
    stderr: float
    """Standard error, cluster-robust over time blocks (NaN where none is defined, e.g. an order found by search)."""
    unit: str
    """SI unit."""
    effect: str
    """Effect it belongs to."""
    at_bound: bool = False
    """Whether the value sits on a physical bound the unconstrained fit would cross."""

    def to_dict(self) -> dict[str, Any]:
        return {
            "value": self.value,
            "stderr": None if math.isnan(self.stderr) else self.stderr,
            "unit": self.unit,
            "at_bound": self.at_bound,
        }


@dataclass(frozen=True)
class Blocks:
    """How the rows are cut for cross-validation and robust errors."""

    edges: NDArray[np.intp]
    """Row index where each block starts, and the row count at the end (length blocks + 1)."""
    fold: NDArray[np.intp]
    """Fold of each block."""

    @classmethod
    def of(cls, n: int, timed: bool = True) -> Blocks:
        """Contiguous blocks of a log of ``n`` rows (in time, or in row order for a steady-state table): a log shorter
        than SMALL_BLOCKS ordinary blocks is cut into up to SMALL_BLOCKS blocks of two rows or more (a block of one row
        would be judged on one residual); longer ones into blocks of MIN_BLOCK_ROWS or more, at most MAX_BLOCKS."""
        if n < SMALL_BLOCKS * MIN_BLOCK_ROWS:
            count = max(2, min(SMALL_BLOCKS, n // 2))
        else:
            count = max(2, min(MAX_BLOCKS, n // MIN_BLOCK_ROWS))
        edges = (np.arange(count + 1) * n) // count
        folds = min(FOLDS, count)
        fold = (np.arange(count) * folds) // count
        return cls(frozen(edges, dtype=np.intp), frozen(fold, dtype=np.intp))

    @property
    def count(self) -> int:
        return int(self.edges.size - 1)

    @property
    def folds(self) -> int:
        return int(self.fold.max()) + 1

    def slices(self) -> list[slice]:
        return [slice(int(a), int(b)) for a, b in zip(self.edges[:-1], self.edges[1:], strict=True)]

    def rows_of_fold(self, k: int) -> slice:
        idx = np.flatnonzero(self.fold == k)
        return slice(int(self.edges[idx[0]]), int(self.edges[idx[-1] + 1]))


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


# ---------------------------------------------------------------------------------------------
# Per-block sums and what comes from them


class Stats:
    """Per-block Gram matrices of a design Z (n, p) and torque y.

    Column 0 is always a column of ones (a virtual torque offset for the identifiability
    check; the model's own columns follow).
    """

    def __init__(self, Z: Array, y: Array, blocks: Blocks, weights: Array | None = None) -> None:
        self.blocks = blocks
        count, p = blocks.count, Z.shape[1]
        self.G = np.empty((count, p, p))
        self.g = np.empty((count, p))
        self.yy = np.empty(count)
        for c, s in enumerate(blocks.slices()):
            Zc, yc = Z[s], y[s]
            if weights is not None:
                Zw = Zc * weights[s, None]
                self.G[c], self.g[c], self.yy[c] = Zw.T @ Zc, Zw.T @ yc, float((weights[s] * yc) @ yc)
            else:
                self.G[c], self.g[c], self.yy[c] = Zc.T @ Zc, Zc.T @ yc, float(yc @ yc)

    @classmethod
    def extended(cls, base: Stats, Z: Array, C: Array, y: Array) -> Stats:
        """Stats of [Z, C] from those of Z: only the new cross-products are computed."""
        out = cls.__new__(cls)
        out.blocks = base.blocks
        count, p, q = base.blocks.count, Z.shape[1], C.shape[1]
        out.G = np.empty((count, p + q, p + q))
        out.g = np.empty((count, p + q))
        out.yy = base.yy
        out.G[:, :p, :p] = base.G
        out.g[:, :p] = base.g
        for c, s in enumerate(base.blocks.slices()):
            Cc = C[s]
            ZC = Z[s].T @ Cc
            out.G[c, :p, p:] = ZC
            out.G[c, p:, :p] = ZC.T
            out.G[c, p:, p:] = Cc.T @ Cc
            out.g[c, p:] = Cc.T @ y[s]
        return out

    def total(self, cols: Sequence[int], use: NDArray[np.bool_] | None = None) -> tuple[Array, Array, float]:
        """Summed (G, g, y^T y) over the blocks in ``use`` (all by default), restricted to ``cols``."""
        ix = np.asarray(cols, dtype=np.intp)
        sel = slice(None) if use is None else use
        G = self.G[sel].sum(axis=0)[np.ix_(ix, ix)]
        g = self.g[sel].sum(axis=0)[ix]
        return G, g, float(self.yy[sel].sum())

    def sse(self, cols: Sequence[int], beta: Array) -> Array:
        """Residual sum of squares of every block for coefficients ``beta`` on ``cols``."""
        ix = np.asarray(cols, dtype=np.intp)
        G = self.G[:, ix][:, :, ix]
        g = self.g[:, ix]
        out = self.yy - 2.0 * (g @ beta) + np.einsum("i,cij,j->c", beta, G, beta)
        return np.maximum(out, 0.0)  # type: ignore[no-any-return]

    def scores(self, cols: Sequence[int], beta: Array) -> Array:
        """Per-block score X_c^T r_c (blocks, len(cols))."""
        ix = np.asarray(cols, dtype=np.intp)
        return self.g[:, ix] - np.einsum("cij,j->ci", self.G[:, ix][:, :, ix], beta)  # type: ignore[no-any-return]


@dataclass(frozen=True)
class CrossValidation:
    """Blocked cross-validation from per-block sums."""

    block_sse: Array
    """Held-out residual sum of squares of every block [N m^2]."""
    fold_rmse_train: Array
    """RMSE of each fold's fit on its training rows [N m]."""
    fold_rmse_test: Array
    """RMSE of each fold's fit on its held-out rows [N m]."""
    betas: list[Array]
    """Each fold's coefficients."""

    @property
    def sse(self) -> float:
        """The held-out residual sum of squares over the blocks scored [N m^2]."""
        return float(np.nansum(self.block_sse))

    def rmse(self, rows: Array) -> float | None:
        """The held-out RMSE over the blocks scored, given every block's row count [N m]; None when none was."""
        scored = np.isfinite(self.block_sse)
        n = float(rows[scored].sum())
        return math.sqrt(self.sse / n) if n else None


def cross_validate(
    fit_stats: Stats,
    stats: Stats,
    cols: Sequence[int],
    lower: Array,
    upper: Array,
    use: NDArray[np.bool_] | None = None,
) -> CrossValidation:
    """Hold out each fold once, fit the others (``fit_stats``, possibly weighted) within bounds, score on ``stats``.

    ``use`` keeps only some blocks, for training and scoring alike; the others get a NaN ``block_sse``, and a fold
    with no kept block on either side is skipped (NaN fold RMSEs, no coefficients).
    """
    blocks = stats.blocks
    rows = np.diff(blocks.edges)
    kept = np.ones(blocks.count, dtype=bool) if use is None else np.asarray(use, dtype=bool)
    n = int(rows[kept].sum())
    block_sse = np.full(blocks.count, np.nan)
    train, test = np.full(blocks.folds, np.nan), np.full(blocks.folds, np.nan)
    betas: list[Array] = []
    for k in range(blocks.folds):
        inside = (blocks.fold == k) & kept
        outside = (blocks.fold != k) & kept
        if not inside.any() or not outside.any():
            continue
        Gk, gk, _ = fit_stats.total(cols, outside)
        beta_k, _ = solve_bounded(Gk, gk, lower, upper)
        sse = stats.sse(cols, beta_k)
        block_sse[inside] = sse[inside]
        n_in = int(rows[inside].sum())
        test[k] = math.sqrt(float(sse[inside].sum()) / max(n_in, 1))
        train[k] = math.sqrt(float(sse[outside].sum()) / max(n - n_in, 1))
        betas.append(beta_k)
    return CrossValidation(block_sse, train, test, betas)


def solve_normal(G: Array, g: Array) -> tuple[Array, Array]:
    """Solve the normal equations G beta = g with diagonal scaling; returns (beta, G^-1)."""
    if G.shape[0] == 0:
        return np.empty(0), np.empty((0, 0))
    d = np.sqrt(np.maximum(np.diag(G), 0.0))
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


def solve_bounded(G: Array, g: Array, lower: Array, upper: Array) -> tuple[Array, NDArray[np.bool_]]:
    """Least squares from normal equations within bounds; returns (beta, which bounds are active).

    The unconstrained solution is kept when it is inside the bounds; otherwise the problem
    min |R beta - R^-T g|^2 (R the Cholesky factor of the scaled Gram matrix, the same
    objective up to a constant) is solved by bounded-variable least squares.
    """
    beta, _ = solve_normal(G, g)
    p = beta.size
    if p == 0 or (np.all(beta >= lower) and np.all(beta <= upper)):
        return beta, np.zeros(p, dtype=bool)
    from scipy.linalg import cho_factor, solve_triangular
    from scipy.optimize import lsq_linear

    d = np.sqrt(np.maximum(np.diag(G), 0.0))
    d[d <= 1e-150 + 1e-12 * max(float(d.max()), 1e-300)] = 1.0
    Gs = G / np.outer(d, d)
    jitter = 1e-12 * max(float(np.trace(Gs)) / p, 1e-300)
    R, _ = cho_factor(Gs + jitter * np.eye(p), lower=False)
    R = np.triu(R)
    b = solve_triangular(R, g / d, trans="T", lower=False)
    res = lsq_linear(R, b, bounds=(lower * d, upper * d), method="bvls")
    active = np.asarray(res.active_mask) != 0
    x = np.clip(res.x / d, lower, upper)
    x[active] = np.where(np.asarray(res.active_mask)[active] < 0, lower[active], upper[active])
    return x, active


def robust_cov(
    stats: Stats, cols: Sequence[int], beta: Array, free: NDArray[np.bool_], use: NDArray[np.bool_] | None = None
) -> Array:
    """Cluster-robust covariance of the free coefficients (blocks as clusters, small-sample corrected), over
    the blocks in ``use`` (all by default).

    Zero rows and columns for coefficients held at a bound.
    """
    p = len(cols)
    cov = np.zeros((p, p))
    idx = np.flatnonzero(free)
    if idx.size == 0:
        return cov
    G, _, _ = stats.total(cols, use)
    _, G_inv = solve_normal(G[np.ix_(idx, idx)], np.zeros(idx.size))
    S = stats.scores(cols, beta)[slice(None) if use is None else use][:, idx]
    count = S.shape[0]
    meat = S.T @ S * (count / max(count - 1, 1))
    cov[np.ix_(idx, idx)] = G_inv @ meat @ G_inv
    return cov


def vif(G: Array) -> tuple[Array, Array]:
    """Variance inflation of each column of a Gram matrix, and the normalised inverse (for partners).

    Uncentred (the columns are compared as they enter the model); a zero column gets inf.
    """
    d = np.sqrt(np.maximum(np.diag(G), 0.0))
    dead = d <= 1e-300
    d[dead] = 1.0
    Gs = G / np.outer(d, d)
    w, V = np.linalg.eigh(Gs)
    w = np.maximum(w, max(float(w[-1]), 1e-300) * 1e-16)
    inv = (V / w) @ V.T
    out = np.diag(inv).copy()
    out[dead] = np.inf
    return out, inv


@dataclass(frozen=True)
class Unidentified:
    """A parameter the log cannot tell from another."""

    parameter: str
    """The parameter."""
    partner: str
    """What it cannot be told from (a parameter, or :data:`OFFSET`)."""
    vif: float
    """Its worst variance inflation (whole log, or one fold left out)."""
    why: str
    """The reason in the log's terms, and what to record instead."""

    def sentence(self) -> str:
        return f"this log cannot tell {self.parameter} from {self.partner}: {self.why}"


def _why(a: str, b: str, signals: Signals, vif_value: float) -> str:
    """The physical reason two parameters cannot be told apart on this log, and what to record."""
    pair = {a, b}
    i = signals.current
    friction = {"coulomb", "stribeck", "viscous"}
    curve = {"kt", "k_sat", "k_sat3", "k_knee", "offset", OFFSET}
    mean, std = float(np.mean(i)), float(np.std(i))
    if pair <= curve and std < 0.1 * max(abs(mean), 1e-300):
        return (
            f"the current hardly varies ({mean:.3g} +- {std:.2g} A), so torque per amp cannot be told from a constant "
            "torque; vary the current: record a current sweep over both signs"
        )
    if "gear_friction" in pair and signals.velocity is not None:
        quadrant = np.sign(i * signals.velocity)
        moving = quadrant[quadrant != 0]
        share = float(np.mean(moving > 0)) if moving.size else 1.0
        if share > 0.95 or share < 0.05:
            kind = "motoring" if share > 0.5 else "braking"
            return (
                f"current and speed keep one sign relative to each other ({max(share, 1 - share):.0%} of the rows "
                f"{kind}), so friction that grows with load looks like a change of Kt; record both motoring and "
                "braking (all four quadrants)"
            )
    if pair & friction and (OFFSET in pair or "offset" in pair) and signals.velocity is not None:
        w = signals.velocity
        share = float(np.mean(w > 0))
        return (
            f"the speed keeps one sign ({max(share, 1 - share):.0%} of the rows), so friction that opposes motion "
            "looks like a sensor offset; record both directions of rotation"
        )
    return (
        f"their regressors are nearly collinear on this log (variance inflation {vif_value:.2g}, above "
        f"{VIF_MAX:.0g}); vary the current and the speed more widely"
    )


def identifiability(stats: Stats, cols: Sequence[int], names: Sequence[str], signals: Signals) -> list[Unidentified]:
    """Parameters among ``cols`` this log cannot estimate, with the reason.

    A parameter is identified when its variance inflation stays below :data:`VIF_MAX`
    on the whole log and with any one fold left out (a handful of rows must not be all
    that separates two parameters). A torque offset (column 0) is always allowed for,
    unless the model has its own.
    """
    i = signals.current
    if "kt" in names and float(np.std(i)) < 0.1 * abs(float(np.mean(i))):
        # one held current: Kt against any constant, whatever else the model has
        return [Unidentified("kt", OFFSET, math.inf, _why("kt", OFFSET, signals, math.inf))]
    with_offset = "offset" not in names
    check = [0, *cols] if with_offset else list(cols)
    labels = [OFFSET, *names] if with_offset else list(names)
    uses = [np.ones(stats.blocks.count, dtype=bool)] + [
        stats.blocks.fold != k for k in range(stats.blocks.folds) if stats.blocks.folds > 2
    ]
    worst = np.zeros(len(check))
    worst_inv: Array | None = None
    for use in uses:
        G, _, _ = stats.total(check, use)
        v, inv = vif(G)
        if worst_inv is None or float(np.max(v)) > float(np.max(worst)):
            worst_inv = inv
        worst = np.maximum(worst, v)
    out: list[Unidentified] = []
    seen: set[frozenset[str]] = set()
    assert worst_inv is not None
    # Kt first: when it is lost, that is the news, whatever else goes with it.
    order = sorted(range(len(labels)), key=lambda j: (labels[j] != "kt", -worst[j]))
    for j in order:
        if worst[j] <= VIF_MAX or labels[j] == OFFSET:
            continue
        corr = np.abs(worst_inv[j]) / np.sqrt(np.abs(np.diag(worst_inv)) * abs(worst_inv[j, j]) + 1e-300)
        corr[j] = -1.0
        k = int(np.argmax(corr))
        key = frozenset((labels[j], labels[k]))
        if key in seen:
            continue
        seen.add(key)
        out.append(Unidentified(labels[j], labels[k], float(worst[j]), _why(labels[j], labels[k], signals, worst[j])))
    return out


# ---------------------------------------------------------------------------------------------
# Building and searching


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
        X = self.columns([m for m in model if m not in SPECIAL], hypers, signals)
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


def solve(X: Array, y: Array, weights: Array | None = None) -> tuple[Array, Array]:
    """Least squares of y on X (optionally weighted): returns (beta, inverse of X^T W X)."""
    if X.shape[1] == 0:
        return np.empty(0), np.empty((0, 0))
    if weights is not None:
        Xw = X * weights[:, None]
        return solve_normal(Xw.T @ X, Xw.T @ y)
    return solve_normal(X.T @ X, X.T @ y)


def _huber_weights(r: Array, k: float = 1.345) -> Array:
    s = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    if s <= 0:
        return np.ones_like(r)
    a = np.abs(r) / (k * s)
    return np.where(a <= 1.0, 1.0, 1.0 / np.maximum(a, 1e-12))


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
    X = design.columns([m for m in model if m != "delay"], hypers, shifted)
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
    X = design.columns([m for m in model if m != "delay"], hypers, shifted)
    y = design.torque[rows]
    beta, _ = solve(X, y)
    r = y - X @ beta
    return float(r @ r)


def estimate_delay(
    design: Design, model: Sequence[str], hypers: Mapping[str, float], start: float = 0.0
) -> tuple[float, float]:
    """Delay of the torque channel behind the current channel [s] and its (robust) standard error.

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


def _filter_held(name: str, hypers: Mapping[str, float], signals: Signals) -> set[str]:
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
    """The residual of a model whose filter (and, with ``free_delay``, whose delay) are trial values: the point is
    the filter's hypers in log space, then the delay [s]."""

    def __init__(
        self, design: Design, model: Sequence[str], hypers: Mapping[str, float], name: str, free_delay: bool
    ) -> None:
        self.design, self.model, self.hypers, self.name, self.free_delay = design, model, hypers, name, free_delay
        signals = design.signals
        lo, hi = transducer.search_bounds(name, signals.time)
        if free_delay:
            reach = 1.5 * delay_window(signals)
            lo, hi = np.append(lo, -reach), np.append(hi, reach)
        self.lo, self.hi = lo, hi
        self._fixed_X = (
            None if free_delay else design.model_columns(model, hypers, signals.shifted(hypers.get("delay", 0.0)))
        )

    def values(self, point: Array) -> dict[str, float]:
        p = np.clip(point, self.lo, self.hi)
        out = transducer.from_point(self.name, p[: p.size - int(self.free_delay)])
        if self.free_delay:
            out["delay"] = float(p[-1])
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
    model's columns on every row (a filter needs the rows in sequence), and with ``free_delay`` the delay with them:
    the candidates of its hypers on a grid (their product for a resonance) at the current delay, then a Nelder-Mead
    refinement in log space (and the delay) within the range the log can show."""
    from scipy.optimize import minimize

    search = _FilterSearch(design, model, hypers, name, free_delay)
    effect = get(name)
    grids = [np.log(np.unique(h.candidates(design.signals, design.torque))) for h in effect.hypers]
    if free_delay:
        grids.append(np.array([float(hypers.get("delay", 0.0))]))
    points = np.array(np.meshgrid(*grids, indexing="ij")).reshape(len(grids), -1).T
    costs = [search.rss(p) for p in points]
    start = points[int(np.argmin(costs))]
    res = minimize(search.rss, start, method="Nelder-Mead", options={"xatol": 1e-3, "fatol": 1e-12, "maxiter": 150})
    best = res.x if res.fun <= min(costs) else start
    return search.values(best)


def filter_stderr(
    design: Design, model: Sequence[str], hypers: Mapping[str, float], name: str, *, with_delay: bool = False
) -> dict[str, float]:
    """Cluster-robust standard errors of a filter's hypers (and of the delay found with it): the prediction's
    sensitivity to each (central differences, in log space for the filter), the linear parameters beside them, with
    the time blocks as clusters."""
    others = [m for m in model if m != name and m != "delay"]
    search = _FilterSearch(design, others, hypers, name, with_delay)
    point = transducer.to_point(name, hypers)
    if with_delay:
        point = np.append(point, hypers.get("delay", 0.0))
    delay = hypers.get("delay", 0.0)
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
        scale = 1.0 if key == "delay" else values[key]  # d value = value d log value
        out[key] = scale * math.sqrt(var) if var >= 0 else float("nan")
    return out


def _check_model(model: Sequence[str], signals: Signals) -> list[Effect]:
    effects = [get(name) for name in model]
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
        e.name for e in effects if e.name not in SPECIAL and (not e.hypers or all(h.name in fixed for h in e.hypers))
    ]
    searched = [e for e in effects if e.name not in SPECIAL and e.name not in linear_names]
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
        beta, _ = solve(base, torque[rows])
        value, _ = search_hyper(e, base, torque[rows], sub, torque[rows] - base @ beta, current)
        current.update(value)
        base_names.append(e.name)
    if has_delay and "delay" not in fixed and searched:
        delay, delay_stderr = estimate_delay(design, [m for m in model if m != "delay"], current, start=delay)
        current["delay"] = delay
        shifted = signals.shifted(delay)
    stderr = {"delay": delay_stderr}
    plain = [m for m in model if m not in SPECIAL]
    filters = [m for m in model if m in FILTERS]
    # a filter and a free delay both shift the reading in time: they are found together
    joint = has_delay and "delay" not in fixed and bool(filters)
    for name in filters:
        if joint or not all(h.name in fixed for h in get(name).hypers):
            others = [m for m in filters if m != name and all(h.name in current for h in get(m).hypers)]
            current.update(estimate_filter(design, [*plain, *others], current, name, free_delay=joint))
    delay = current.get("delay", 0.0)
    shifted = signals.shifted(delay)
    window = delay_window(signals) if has_delay else math.inf
    if abs(delay) > window:
        raise FitError(
            f"the delay fits only at {1e3 * delay:+.3g} ms, outside the +-{1e3 * window:.3g} ms a "
            "transducer filter or a bus can explain; check the time column's unit (--units time=ms) or leave "
            "'delay' out",
            delay=delay,
        )
    X = design.model_columns(model, current, shifted)
    held: set[str] = set()
    for name in filters:
        stderr.update(filter_stderr(design, model, current, name, with_delay=joint))
        held |= _filter_held(name, current, signals)
    return _finish(design, model, effects, X, current, stderr, robust, held)


def reversed_sensor_error(kt: float) -> DynoDataError:
    return DynoDataError(
        f"the fitted torque constant is negative (Kt = {kt:.4g} N m/A): torque falls as current rises; the torque "
        "sensor (or the current's sign) looks reversed: rerun with --flip-torque, or without it if you gave it",
        kt=kt,
    )


#: The sign of Kt (a reversed sensor, or a torque that does not follow the current): the plain torque-per-amp slope must
#: lie this many (cluster-robust) standard errors from zero to be read (3 sigma: a drifting, unloaded sensor reads as no
#: slope); the block sign test must reach this significance (one false sign in a thousand logs); the blocks' median
#: slope and the agreeing half's slope count only over at least this many blocks (in which the current moves, for the
#: median; too few blocks give no median to trust); a block's current moves when its standard deviation reaches this
#: many noise sigmas (well clear of the reply's noise and quanta); the agreeing half of the blocks must explain at least
#: half the torque's variance (the half is picked for fitting well, which flatters its standard error). Calibrated on
#: test_polled_rig::test_a_torque_sensor_the_motor_does_not_load_gives_no_kt and
#: test_polled_rig::test_negative_kt_is_never_accepted.
SLOPE_SIGMAS = 3.0
SIGN_ALPHA = 0.001
MIN_SIGN_BLOCKS = 8
MOVING_NOISE = 5.0
HALF_EXPLAINED = 0.5


def agreeing_half(
    stats: Stats, cols: Sequence[int], lower: Array, upper: Array, start: Array | None = None
) -> tuple[NDArray[np.bool_], Array, Array]:
    """Block-level least trimmed squares: fit the half of the blocks that fit best, re-pick that half, repeat.

    Starts from the half with the smallest ``start`` (e.g. held-out RMSE; by default the RMSE under a fit to
    all blocks). Returns (the agreeing half, its coefficients, every block's RMSE under them).
    """
    rows = np.maximum(np.diff(stats.blocks.edges), 1)
    half = max(stats.blocks.count // 2, 1)
    if start is None:
        G, g, _ = stats.total(cols)
        beta, _ = solve_bounded(G, g, lower, upper)
        start = np.sqrt(stats.sse(cols, beta) / rows)
    good = np.zeros(stats.blocks.count, dtype=bool)
    good[np.argsort(start, kind="stable")[:half]] = True
    rmse = np.asarray(start, float)
    beta = np.zeros(len(cols))
    for _ in range(8):
        G, g, _ = stats.total(cols, good)
        beta, _ = solve_bounded(G, g, lower, upper)
        rmse = np.sqrt(stats.sse(cols, beta) / rows)
        picked = np.zeros_like(good)
        picked[np.argsort(rmse, kind="stable")[:half]] = True
        if np.array_equal(picked, good):
            break
        good = picked
    return good, beta, rmse


def _check_slope(stats: Stats, col: int, current: Array) -> None:
    """Refuse a log whose torque does not follow the current, or falls with it (a reversed sensor).

    Judged on the plain slope of torque on current (with an offset), which shape terms that trade off
    against Kt (saturation, load-dependent friction) cannot flip, two ways: over the whole log (within
    SLOPE_SIGMAS cluster-robust standard errors of zero or not), and block by block over the blocks in which
    the current moves (a sign test, and the median of the blocks' slopes against its standard error), and
    over the agreeing half of the blocks (:func:`agreeing_half`), which a broken stretch of the log cannot
    sway. Any of them showing a sign is enough; if they disagree in sign, the log is read as rising (the
    fit's own checks flag what is broken).
    """
    from scipy.special import bdtr  # binomial cdf

    G, g, _ = stats.total([0, col])
    beta, _ = solve_normal(G, g)
    se = math.sqrt(max(float(robust_cov(stats, [0, col], beta, np.ones(2, dtype=bool))[1, 1]), 0.0))
    slope = float(beta[1])
    n = stats.G[:, 0, 0]
    mean = stats.G[:, 0, col] / np.maximum(n, 1)
    var = stats.G[:, col, col] / np.maximum(n, 1) - mean**2
    # a block counts where its current moves by more than a few noise sigmas (or steps of the reply)
    floor = max(noise_sigma(current), quantum(current))
    moving = var > (MOVING_NOISE * floor) ** 2 if floor > 0 else var > 0
    cov = stats.g[moving, col] / n[moving] - mean[moving] * stats.g[moving, 0] / n[moving]
    up, m = int(np.count_nonzero(cov > 0)), int(np.count_nonzero(moving))
    p_down = float(bdtr(up, m, 0.5)) if m else 1.0  # this few rising blocks by chance
    p_up = float(bdtr(m - up, m, 0.5)) if m else 1.0
    # the blocks' own slopes: their median, with the standard error of a median (1.2533 x that of a mean)
    block = cov / np.maximum(var[moving], 1e-300)
    typical = float(np.median(block)) if m else 0.0
    scatter = 1.2533 * 1.4826 * float(np.median(np.abs(block - typical))) / math.sqrt(max(m, 1)) if m else math.inf
    blocks_say = m >= MIN_SIGN_BLOCKS and abs(typical) > SLOPE_SIGMAS * scatter
    clear = abs(slope) > SLOPE_SIGMAS * se
    # the same slope over the agreeing half of the blocks, which a broken tail or a spike cannot drag
    free = np.full(2, -np.inf), np.full(2, np.inf)
    good, trimmed, _ = agreeing_half(stats, [0, col], *free)
    G_half, _, _ = stats.total([0, col], good)
    half_cov = robust_cov(stats, [0, col], trimmed, np.ones(2, dtype=bool), good)
    half_se = math.sqrt(max(float(half_cov[1, 1]), 0.0))
    # the half is picked for fitting well, which flatters its standard error: it must also explain the torque
    yy = float(stats.yy[good].sum())
    g0 = float(stats.g[good, 0].sum())
    total = yy - g0**2 / max(float(G_half[0, 0]), 1.0)
    explained = 1.0 - float(stats.sse([0, col], trimmed)[good].sum()) / total if total > 0 else 0.0
    half_says = (
        good.sum() >= MIN_SIGN_BLOCKS
        and abs(float(trimmed[1])) > SLOPE_SIGMAS * half_se
        and explained >= HALF_EXPLAINED
    )
    down = (clear and slope < 0) or p_down < SIGN_ALPHA or (blocks_say and typical < 0)
    down = down or (half_says and trimmed[1] < 0)
    rise = (clear and slope > 0) or p_up < SIGN_ALPHA or (blocks_say and typical > 0)
    rise = rise or (half_says and trimmed[1] > 0)
    if down and not rise:
        raise reversed_sensor_error(slope if slope < 0 else typical)
    if not rise:
        raise FitError(
            f"the torque does not follow the current: torque per amp is {slope:.3g} +- {se:.2g} N m/A, no different "
            "from zero, "
            + (
                f"and it rises with the current in {up} of the {m} blocks where the current moves"
                if m
                else "and in no block does the current move beyond its noise"
            )
            + "; this log cannot measure Kt: the torque sensor is not loaded by the motor (or not connected), or the "
            "current column is not this motor's",
            kt=slope,
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
        _check_slope(stats, 1 + names.index("kt"), design.signals.current)
    beta, active = solve_bounded(G, g, lower, upper)
    solve_stats = stats
    weights = None
    if robust:
        for _ in range(8):
            weights = _huber_weights(y - X @ beta)
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
    fold_train, fold_test = cv.fold_rmse_train, cv.fold_rmse_test
    rmse_cv = math.sqrt(float(block_sse.sum()) / n)
    # robust standard errors, never below the classical ones
    free = ~active
    cov = robust_cov(solve_stats, cols, beta, free)
    dof = max(n - int(free.sum()), 1)
    sigma2 = (float((weights * resid**2).sum()) if weights is not None else rss) / dof
    classic = np.zeros(p)
    if free.any():
        Gf, _, _ = solve_stats.total([c for c, f in zip(cols, free, strict=True) if f])
        _, Ginv = solve_normal(Gf, np.zeros(Gf.shape[0]))
        classic[free] = np.diag(Ginv) * sigma2
    stderr = np.sqrt(np.maximum(np.maximum(np.diag(cov), classic), 0.0))
    # how far past its bound the unconstrained fit puts each held parameter, in its own standard errors
    beyond = np.zeros(p)
    if active.any():
        free_all = np.ones(p, dtype=bool)
        free_cov = robust_cov(stats, cols, free_beta, free_all)
        _, Ginv_all = solve_normal(G, np.zeros(p))
        free_err = np.sqrt(np.maximum(np.maximum(np.diag(free_cov), np.diag(Ginv_all) * rss / dof), 1e-300))
        bound = np.where(free_beta < lower, lower, upper)
        beyond = np.abs(free_beta - bound) / free_err
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
        fold_rmse_train=frozen(fold_train),
        fold_rmse_test=frozen(fold_test),
        robust=robust,
        hypers={h.name: float(hypers.get(h.name, 0.0)) for e in effects for h in e.hypers},
        unphysical=unphysical,
    )


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
