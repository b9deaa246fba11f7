"""The torque's sign against the current: a reversed sensor, and the agreeing half of a log whose slope is in doubt."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from hound_id.dyno.artefacts import noise_sigma, quantum
from hound_id.dyno.current.stats import Array, Stats, robust_cov, solve_bounded, solve_normal
from hound_id.errors import DynoDataError, FitError


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


def check_slope(stats: Stats, col: int, current: Array) -> None:
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
