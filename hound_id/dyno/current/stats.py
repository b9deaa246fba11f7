"""The per-block statistics every fit of :mod:`hound_id.dyno.current.fit` works on: the log's contiguous blocks, each
block's Gram matrix X^T X, X^T y and y^T y, and what comes from them without another pass over the rows (the
bounded least-squares solution, blocked cross-validation, cluster-robust covariances)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen

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


#: Blocks of a log shorter than ten ordinary blocks (a table of tens of operating points, a burst): ten, as many as
#: folds. Calibrated on test_logs::test_a_table_of_26_operating_points_and_a_burst_written_16_times_are_read and
#: test_logs::test_clean_small_tables_keep_every_row.
SMALL_BLOCKS = 10


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


def solve(X: Array, y: Array, weights: Array | None = None) -> tuple[Array, Array]:
    """Least squares of y on X (optionally weighted): returns (beta, inverse of X^T W X)."""
    if X.shape[1] == 0:
        return np.empty(0), np.empty((0, 0))
    if weights is not None:
        Xw = X * weights[:, None]
        return solve_normal(Xw.T @ X, Xw.T @ y)
    return solve_normal(X.T @ X, X.T @ y)


def huber_weights(r: Array, k: float = 1.345) -> Array:
    s = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    if s <= 0:
        return np.ones_like(r)
    a = np.abs(r) / (k * s)
    return np.where(a <= 1.0, 1.0, 1.0 / np.maximum(a, 1e-12))
