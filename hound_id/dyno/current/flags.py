"""What a diagnosis says about the log itself (:mod:`hound_id.dyno.current.diagnose`): the agreeing part of a log whose
blocks disagree, the flags naming the stretches that break, and the outlier rows."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hound_id.dyno.current.effects import Signals
from hound_id.dyno.current.fit import FitResult
from hound_id.dyno.current.noise import NoiseFloor
from hound_id.dyno.current.search import Design, parameters_of
from hound_id.dyno.current.stats import Array, Stats, cross_validate
from hound_id.dyno.current.stretch import Stretch

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


def rmse_outside(stats: Stats, cols: list[int], lower: Array, upper: Array, disagreeing: np.ndarray) -> float | None:
    """The cross-validated RMSE of the model fitted and scored without the disagreeing blocks [N m] (each fold held
    out once, as for the whole log); None when no block or every block disagrees."""
    if not disagreeing.any() or disagreeing.all():
        return None
    cv = cross_validate(stats, stats, cols, lower, upper, use=~disagreeing)
    return cv.rmse(np.diff(stats.blocks.edges))


def agreeing_kt(fit: FitResult, agreeing: Agreeing) -> float | None:
    """Kt of the fit to the agreeing half of the blocks [N m/A], None without a ``linear`` term."""
    names = [par.name for _, par in parameters_of(fit.model)]
    return float(agreeing.beta[names.index("kt")]) if "kt" in names else None


def share_of(part: float, whole: float) -> str:
    """part / whole as a percentage, or 'all' when whole is zero (a noiseless log)."""
    return f"{part / whole:.1%}" if whole > 0 else "all"


def _span(signals: Signals, start: int, stop: int) -> str:
    if signals.timed:
        return f"t = {signals.time[start]:.4g}-{signals.time[stop - 1]:.4g} s"
    # a steady-state table's time is its 0-based data row
    return f"data rows {int(signals.time[start]) + 1}-{int(signals.time[stop - 1]) + 1}"


@dataclass(frozen=True)
class Agreeing:
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


def typical_rows(design: Design, agreeing: Agreeing) -> NDArray[np.bool_]:
    """Rows of the blocks within BLOCK_FACTOR of the typical block's RMSE under the agreeing half's fit (what the
    noise floor may pair: a broken stretch paired with the rest would read as noise and hide itself)."""
    rows = np.ones(design.torque.size, dtype=bool)
    for block, s in enumerate(design.blocks.slices()):
        rows[s] = agreeing.rmse[block] <= BLOCK_FACTOR * agreeing.typical
    return rows


def disagreeing_blocks(agreeing: Agreeing, floor: float, block_floor: Array) -> np.ndarray:
    r = agreeing.rmse
    own = np.where(np.isfinite(block_floor), np.maximum(block_floor, floor), floor)
    return (r > BLOCK_FACTOR * agreeing.typical) & (r > BLOCK_FACTOR * own)  # type: ignore[no-any-return]


def stretch_flags(
    fit: FitResult,
    agreeing: Agreeing,
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


def outlier_rows(fit: FitResult, floor: float, signals: Signals) -> str | None:
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
