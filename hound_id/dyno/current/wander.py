"""The time scale of a residual's excess over the noise floor: a slow wander, or noise faster than a quarter second.

When no candidate effect is significant and the cross-validated residual stays above the floor, the excess is one of
two things, and the residual's time structure tells them apart:

* **slow**: the residual wanders over seconds. Moments with the same current and speed far apart in time say what
  follows it: when they predict it, a shape of the curve the model's terms cannot bend to; when they do not, something
  the log lacks: the rotor's angle (cogging, the gear mesh at a stall, where the rotor turns only as the coupling
  winds up), a transducer's creep or zero drift, heat. On a sweep that never comes back to its inputs the two cannot
  be told apart; the sentence says so.
* **fast**: the excess lives within a fraction of a second: noise the floor reads low (a filtered transducer),
  ringing, a channel updated late.

The split is a centred moving average of :data:`WINDOW` seconds over the held-out residual: white noise of standard
deviation s leaves s^2/k of variance in the average of k samples (noise correlated over m samples, s^2 m/k, with m
summed from the autocorrelation of what the average leaves), and the rest of the slow part's variance is the wander's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: The window separating a slow wander from noise [s]: longer than any transducer lag or resonance the library fits
#: (their searches end at 1 Hz, a 0.16 s time constant) and short against a sweep's seconds. Calibrated on
#: test_wander::test_a_slow_wander_is_measured_and_named and
#: test_wander::test_correlated_fast_noise_is_not_called_a_wander.
WINDOW = 0.25
#: The window holds at least this many samples (a 20 Hz log: 5 samples, 0.25 s). Calibrated on
#: test_wander::test_a_slow_wander_is_measured_and_named.
MIN_SAMPLES = 5
#: The residual must hold this many whole windows of kept rows for its time structure to be read. Calibrated on
#: test_wander::test_a_short_log_has_no_time_scale.
MIN_WINDOWS = 20
#: The excess is called slow when this share of its variance is in the moving average, else fast. Calibrated on
#: test_wander::test_a_slow_wander_is_measured_and_named and
#: test_wander::test_correlated_fast_noise_is_not_called_a_wander.
SLOW_SHARE = 0.5
#: At the noise floor, the floor is called mostly a wander when the slow part's RMS is at least this many times the
#: noise faster than the window (a floor read from moments far apart holds the wander). Calibrated on
#: test_polled_rig::test_a_transducer_zero_that_wanders_is_named_slow_with_its_size and
#: test_polled_rig::test_no_wander_is_read_where_the_log_reaches_its_floor.
FLOOR_WANDER = 1.0
#: The noise's autocorrelation is summed over the lags up to the first below this (a correlation of 0.05 adds less
#: than a tenth of a sample to its correlation length). Calibrated on
#: test_wander::test_correlated_fast_noise_is_not_called_a_wander and
#: test_wander::test_a_transducer_filter_is_not_a_long_memory.
NEGLIGIBLE_RHO = 0.05
#: Moments at least this far apart in time (and twice the wander's sign-change interval), with the same current and
#: speed, say whether the inputs predict the slow part: closer ones share a wander in time [s]. Calibrated on
#: test_wander::test_a_wander_that_follows_the_current_is_not_blamed_on_a_channel_the_log_lacks.
APART = 2.0
#: The slow part follows the inputs when moments with the same inputs at other times predict this share of it; the
#: test needs that share of the rows covered by such moments. Calibrated on
#: test_wander::test_a_wander_that_follows_the_current_is_not_blamed_on_a_channel_the_log_lacks.
FOLLOWS = 0.5
COVERED = 0.3
#: Two moments have the same inputs when each input differs by at most this share of its range (as the neighbour
#: floor's cap). Calibrated on
#: test_wander::test_a_wander_that_follows_the_current_is_not_blamed_on_a_channel_the_log_lacks.
INPUT_TOLERANCE = 0.02
#: At most SEARCHED rows are searched for moments with the same inputs, among at most TREE_ROWS (both evenly spread),
#: and the noise's correlation length is read on the first CORRELATION_ROWS rows: a 10^6-row log costs what a
#: 20,000-row one does. Calibrated on benchmarks/noise_floor.py.
SEARCHED = 5_000
TREE_ROWS = 20_000
CORRELATION_ROWS = 1 << 17
#: The window spans at least this many of the noise's correlation lengths (m samples, read from the fast part), widened
#: up to MAX_WIDENINGS times: a transducer filtered to a few hertz has noise that a 0.25 s average keeps. Calibrated on
#: test_wander::test_correlated_fast_noise_is_not_called_a_wander and
#: test_wander::test_a_transducer_filter_is_not_a_long_memory.
WINDOW_CORRELATIONS = 8.0
MAX_WIDENINGS = 3
#: The slow part is called an offset when its mean is at least this share of its RMS (0.8: nearly two thirds of its
#: variance is one level). Calibrated on test_wander::test_an_offset_the_model_lacks_is_called_an_offset.
OFFSET_SHARE = 0.8
#: The excess is divided only where the residual's variance exceeds the floor's by this share of it (a residual within
#: 5 % of the floor has no excess to speak of). Calibrated on
#: test_wander::test_correlated_fast_noise_is_not_called_a_wander.
MIN_EXCESS = 0.1
#: A sign change of the slow part counts once it passes this many of the average's own noise sigmas beyond zero (the
#: noise left in an average of white noise would cross zero every few samples). Calibrated on
#: test_wander::test_a_slow_wander_is_measured_and_named.
CROSSING_SIGMAS = 2.0


@dataclass(frozen=True)
class Wander:
    """How the excess of a residual over the noise floor divides between slow and fast."""

    window: float
    """The moving average's length [s]."""
    samples: int
    """Samples in it."""
    share: float
    """Share of the excess variance (the residual's minus the floor's) in the moving average, 0-1 (0 when the
    residual is within the floor)."""
    slow: float
    """RMS of the slow part, the fast noise's own share of the average removed [N m]."""
    fast: float
    """Standard deviation of the noise faster than the window, read from the part the average leaves [N m]."""
    fast_ratio: float
    """:attr:`fast` against the floor."""
    crossing: float | None
    """Mean time between the slow part's sign changes [s] (None when it never changes sign)."""
    rows: int
    """Rows whose whole window was kept (outside flagged stretches and gaps)."""
    mean: float = 0.0
    """Mean of the slow part over those rows [N m] (an offset the model lacks, when it is most of :attr:`slow`)."""
    excess: bool = False
    """The residual's variance exceeds the floor's by MIN_EXCESS of it or more (:attr:`share` divides that excess)."""
    follows: float | None = None
    """Share of the residual's variance beyond its noise (the smaller of the floor and the fast part) that moments with
    the same current (and speed) at least :data:`APART` seconds away predict, 0-1, the larger of the current alone and
    with the speed; None when too few moments come back to the same inputs."""

    @property
    def is_slow(self) -> bool:
        """Most of the excess is slow."""
        return self.share >= SLOW_SHARE

    @property
    def floor_is_wander(self) -> bool:
        """The slow part is as large as the fast noise or larger: a floor that holds it is not the sensor's noise."""
        return self.slow >= FLOOR_WANDER * self.fast

    def _every(self) -> str:
        if self.crossing is None:
            return ", changing sign at most once"
        return f", changing sign every {self.crossing:.2g} s on average"

    @property
    def follows_inputs(self) -> bool:
        """Moments with the same inputs at other times predict most of it: a shape in the inputs, not a wander."""
        return self.follows is not None and self.follows >= FOLLOWS

    def _cause(self) -> str:
        """What the slow part follows, as far as the log can say."""
        if self.is_offset:
            return ""
        if self.follows_inputs:
            return (
                f"; moments with the same current and speed at other times predict {self.follows:.0%} of it, so it "
                "follows the inputs: a shape of the curve in the current or the speed that the model's terms cannot "
                "bend to (a ripple or a kink: look at the residual against the current), not something the log lacks"
            )
        if self.follows is not None:
            return (
                f"; moments with the same current and speed at other times predict {self.follows:.0%} of it, so no "
                f"logged channel follows it: {_LACKS}"
            )
        return (
            "; the log does not come back to the same current and speed far enough apart in time, so it cannot tell a "
            f"curve bumpier than the model's terms from something the log lacks ({_SOURCES}): repeat the sweep, or log "
            "the angle and a temperature"
        )

    @property
    def is_offset(self) -> bool:
        """The slow part is mostly one level: an offset the model lacks, not a wander."""
        return abs(self.mean) >= OFFSET_SHARE * self.slow

    def _how(self) -> str:
        """How the slow part moves (off zero throughout, or about it), and what it may be."""
        if self.is_offset:
            return (
                f"sits {self.mean:+.3g} N m off zero throughout: an offset the model does not carry (a transducer's "
                "zero, or an offset term refused as unphysical)"
            )
        return f"wanders by {self.slow:.3g} N m RMS{self._every()}"

    def floor_sentence(self) -> str:
        """What a floor that holds the wander is made of."""
        return (
            f"half or more of that floor's variance is slow: the residual {self._how()}, beside {self.fast:.3g} N m "
            f"of noise faster than {self.window:.2g} s{self._cause()}"
        )

    def sentence(self) -> str:
        """What the excess is, in the words of the rig."""
        if self.is_slow:
            return (
                f"{self.share:.0%} of the excess over the floor is slow: the residual {self._how()}, while its part "
                f"faster than {self.window:.2g} s is {self.fast_ratio:.2g}x the floor{self._cause()}"
            )
        head = (
            f"{1.0 - self.share:.0%} of the excess over the floor is faster than {self.window:.2g} s (that part is "
            f"{self.fast_ratio:.2g}x the floor)"
        )
        if self.follows_inputs:
            return (
                f"{head}, and moments with the same current and speed at other times predict {self.follows:.0%} of "
                "the excess: a shape of the curve in the current or the speed that the model's terms cannot bend to, "
                "swept quickly (look at the residual against the current)"
            )
        return (
            f"{head}: noise the floor reads low (a transducer that filters its noise), ringing, or a channel updated "
            "late"
        )

    @property
    def kind(self) -> str:
        """slow, offset or fast (the excess), or none (within the floor, and the floor not mostly slow)."""
        if self.excess:
            return ("offset" if self.is_offset else "slow") if self.is_slow else "fast"
        return ("offset" if self.is_offset else "slow") if self.floor_is_wander else "none"

    def to_dict(self, said: str | None = None) -> dict[str, Any]:
        """JSON-ready; ``said`` is the sentence the summary carries (None when it carries none)."""
        return {
            "window": self.window,
            "samples": self.samples,
            "share_slow": self.share,
            "slow_rms": self.slow,
            "fast_sd": self.fast,
            "fast_ratio": self.fast_ratio,
            "sign_change_every": self.crossing,
            "rows": self.rows,
            "mean": self.mean,
            "kind": self.kind,
            "floor_is_wander": self.floor_is_wander,
            "follows_inputs": self.follows,
            "sentence": said,
            "units": {"window": "s", "slow_rms": "N m", "fast_sd": "N m", "sign_change_every": "s", "mean": "N m"},
        }


_SOURCES = "the rotor's angle through cogging or the gear mesh, a transducer's creep or zero drift, heat"
_LACKS = f"the torque follows something the log lacks ({_SOURCES}): log the angle and a temperature to tell them apart"


def wander(
    time: Array,
    residual: Array,
    floor: float,
    keep: NDArray[np.bool_] | None = None,
    inputs: Sequence[Array] = (),
) -> Wander | None:
    """Split ``residual``'s excess over ``floor`` (white noise's standard deviation) into slow and fast; rows outside
    ``keep`` (flagged stretches) are left out with every window that touches them; ``inputs`` (the current, the speed)
    say whether moments with the same inputs far apart in time predict the excess. None when the log is too short
    or untimed."""
    r = np.asarray(residual, dtype=float)
    t = np.asarray(time, dtype=float)
    kept = np.ones(r.size, dtype=bool) if keep is None else np.asarray(keep, dtype=bool)
    if r.size < 2 or not floor > 0:
        return None
    steps = np.diff(t)
    dt = float(np.median(steps))
    if not (math.isfinite(dt) and dt > 0):
        return None
    gap = np.concatenate([[False], steps > 3.0 * dt])
    k = max(int(round(WINDOW / dt)), MIN_SAMPLES)
    k += 1 - k % 2  # odd: centred
    split = _split(r, kept, gap, k)
    widenings = 0
    # noise correlated over m samples needs a window of several m: widen it (a few times at most) until it has one
    while split is not None and k < WINDOW_CORRELATIONS * split[4] and widenings < MAX_WIDENINGS:
        k = int(math.ceil(WINDOW_CORRELATIONS * split[4]))
        k += 1 - k % 2
        split = _split(r, kept, gap, k)
        widenings += 1
    if split is None:
        return None
    full, slow_part, fast, slow_var, _ = split
    excess = float(np.mean(r[full] ** 2)) - floor**2
    share = min(max(slow_var / excess, 0.0), 1.0) if excess > MIN_EXCESS * floor**2 else 0.0
    crossing = _crossing(t[full], slow_part, CROSSING_SIGMAS * fast / math.sqrt(k))
    apart = max(APART, 2.0 * crossing) if crossing is not None else APART
    # the current alone, then with the speed: a ripple in the current is predicted by the moments with the same
    # current, which the same speed as well may leave too few of on a sweep that comes back at other speeds
    noise = min(floor, fast) ** 2
    shares = [
        min(max(got[0] / max(got[1] - noise, 1e-300), 0.0), 1.0)
        for got in (_predicted(t, r, full, inputs[:n], apart) for n in range(1, len(inputs) + 1))
        if got is not None
    ]
    follows = max(shares) if shares else None
    return Wander(
        window=k * dt,
        samples=k,
        share=share,
        slow=math.sqrt(slow_var),
        fast=fast,
        fast_ratio=fast / floor,
        crossing=crossing,
        rows=int(full.sum()),
        mean=float(np.mean(slow_part)),
        excess=excess > MIN_EXCESS * floor**2,
        follows=follows,
    )


def _predicted(
    time: Array, r: Array, full: NDArray[np.bool_], inputs: Sequence[Array], apart: float
) -> tuple[float, float] | None:
    """Variance of ``r`` that moments with the same inputs at least ``apart`` seconds away predict (the mean of up to
    eight such moments, each input within INPUT_TOLERANCE of its range), and r's mean square, over the rows that have
    three or more; None without inputs or when fewer than COVERED of the searched rows have them."""
    from hound_id.dyno.current.neighbours import far_partners

    if not inputs:
        return None
    rows = np.flatnonzero(full)
    rows = rows[np.unique(np.linspace(0, rows.size - 1, min(rows.size, TREE_ROWS)).astype(int))]
    X = np.column_stack([np.asarray(x, dtype=float)[rows] for x in inputs])
    span = np.ptp(X, axis=0)
    if not np.all(span > 0):
        X, span = X[:, span > 0], span[span > 0]
    if X.shape[1] == 0:
        return None
    Z = X / (INPUT_TOLERANCE * span)  # the same inputs: within 1 in every column
    searched = np.unique(np.linspace(0, rows.size - 1, min(rows.size, SEARCHED)).astype(int))
    t, y = time[rows], r[rows]
    # among the 64 nearest in the inputs, the first eight far enough in time
    picked, far = far_partners(Z, Z[searched], t, t[searched], apart, 64, 8)
    count = far.sum(axis=1)
    covered = count >= 3
    if covered.mean() < COVERED:
        return None
    guess = (np.where(far, y[picked], 0.0).sum(axis=1) / np.maximum(count, 1))[covered]
    own = y[searched][covered]
    return float(np.mean(own**2) - np.mean((own - guess) ** 2)), float(np.mean(own**2))


def _split(
    r: Array, kept: NDArray[np.bool_], gap: NDArray[np.bool_], k: int
) -> tuple[NDArray[np.bool_], Array, float, float, float] | None:
    """The rows whose whole window of k samples is kept, the slow part there, the fast noise's standard deviation, the
    wander's variance and the samples m one draw of the noise stays correlated over; None when too few rows."""
    if r.size < MIN_WINDOWS * k:  # (np.convolve's "same" is as long as the window when the window is longer)
        return None
    summed = _centred_sum(np.where(kept, r, 0.0), k)
    count = _centred_sum(kept.astype(float), k)
    # a window across a gap in time (a dropped stretch of the log) averages moments that are not neighbours
    across = _centred_sum(gap.astype(float), k) > 0.5
    full = kept & (count >= k - 0.5) & ~across
    if int(full.sum()) < MIN_WINDOWS * k:
        return None
    slow_part = summed[full] / k
    fast_part = r[full] - slow_part
    # noise of variance s^2 leaves about s^2 (1 - m/k) outside the average and s^2 m/k in it, where m = (1 + rho) /
    # (1 - rho) is the number of samples one draw of AR(1) noise stays correlated over (1 for white noise): read rho
    # from the fast part's neighbouring samples, so a filtered transducer's noise is not called a wander
    m = _correlation_length(fast_part, full, k)
    share_out = max(1.0 - m / k, 0.5)
    fast = math.sqrt(float(np.mean(fast_part**2)) / share_out)
    slow_var = max(float(np.mean(slow_part**2)) - fast**2 * (1.0 - share_out), 0.0)
    return full, slow_part, fast, slow_var, m


def _centred_sum(x: Array, k: int) -> Array:
    """Sum of x over the centred window of k (odd) samples at every row, cut at the ends (np.convolve's "same" in
    O(n) from a running sum)."""
    half = k // 2
    c = np.concatenate([[0.0], np.cumsum(x)])
    index = np.arange(x.size)
    lo = np.clip(index - half, 0, x.size)
    hi = np.clip(index + half + 1, 0, x.size)
    return c[hi] - c[lo]  # type: ignore[no-any-return]


def _correlation_length(x: Array, full: NDArray[np.bool_], k: int) -> float:
    """Samples one draw of the noise in ``x`` stays correlated over: 1 + 2 sum of its autocorrelations over the lags
    up to the first that falls below NEGLIGIBLE_RHO (1 for white noise, (1 + rho) / (1 - rho) for AR(1) noise; a
    second-order transducer filter correlates its neighbours strongly but only over a few lags, which a one-lag reading
    would take for a long memory). Lags are read within runs of rows adjacent in the log, up to a quarter window."""
    rows = np.flatnonzero(full)
    span = rows < rows[0] + CORRELATION_ROWS if rows.size else rows.astype(bool)
    rows, x = rows[span], x[span]  # the noise's memory is read on the first stretch of the log
    if rows.size < 2:
        return 1.0
    # back on the log's own grid, zero where a row is not kept, and every lag's sums at once (FFT): a pair counts only
    # when both its rows are kept
    on_grid = np.zeros(int(rows[-1] - rows[0]) + 1)
    mask = np.zeros_like(on_grid)
    on_grid[rows - rows[0]] = x
    mask[rows - rows[0]] = 1.0
    lags = max(k // 4, 1)
    size = 1 << int(np.ceil(np.log2(2 * on_grid.size)))
    fx, fm, fxx = np.fft.rfft(on_grid, size), np.fft.rfft(mask, size), np.fft.rfft(on_grid**2, size)
    products = np.fft.irfft(fx * np.conj(fx), size)[: lags + 1]
    # each lag's own variances, over the rows that pair at it: sum of x^2 at the first and at the second of a pair
    first = np.fft.irfft(fxx * np.conj(fm), size)[: lags + 1]
    second = np.fft.irfft(fm * np.conj(fxx), size)[: lags + 1]
    m = 1.0
    for lag in range(1, lags + 1):
        denominator = math.sqrt(max(float(first[lag]) * float(second[lag]), 0.0))
        if not denominator > 0:
            break
        rho = float(products[lag]) / denominator
        if rho < NEGLIGIBLE_RHO:
            break
        m += 2.0 * rho
    return m


def _crossing(time: Array, slow: Array, band: float) -> float | None:
    """Mean time between sign changes of ``slow`` that pass ``band`` beyond zero [s]."""
    side = np.where(slow > band, 1, np.where(slow < -band, -1, 0))
    signs = side[side != 0]
    if signs.size < 2:
        return None
    changes = int(np.count_nonzero(np.diff(signs)))
    if changes == 0:
        return None
    return float(time[-1] - time[0]) / changes
