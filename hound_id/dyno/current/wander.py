"""The time scale of a residual's excess over the noise floor: a slow wander, or noise faster than a quarter second.

When no candidate effect is significant and the cross-validated residual stays above the floor, the excess is one of
two things, and the residual's time structure tells them apart:

* **slow**: the residual wanders over seconds. Neither the current nor the speed follows it (no candidate did), so
  the torque follows something the log lacks: the rotor's angle (cogging, the gear mesh at a stall, where the rotor
  turns only as the coupling winds up), a transducer's creep or zero drift, heat. On a sweep that never revisits
  its inputs such a wander cannot be told from a curve the model's terms cannot bend to; the sentence says so.
* **fast**: the excess lives within a fraction of a second: noise the floor reads low (a filtered transducer),
  ringing, a channel updated late.

The split is a centred moving average of :data:`WINDOW` seconds over the held-out residual: white noise of standard
deviation s leaves s^2/k of variance in the average of k samples (noise correlated over m samples, s^2 m/k, with m
read from the fast part's neighbouring samples), and the rest of the slow part's variance is the wander's.
"""

from __future__ import annotations

import math
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
#: Largest neighbour correlation read from the fast part (0.95: noise correlated over 39 samples, past which the
#: window no longer separates noise from a wander). Calibrated on
#: test_wander::test_correlated_fast_noise_is_not_called_a_wander.
MAX_RHO = 0.95
#: The window spans at least this many of the noise's correlation lengths (m samples, read from the fast part), widened
#: up to MAX_WIDENINGS times: a transducer filtered to a few hertz has noise that a 0.25 s average keeps. Calibrated on
#: test_wander::test_correlated_fast_noise_is_not_called_a_wander.
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

    @property
    def is_slow(self) -> bool:
        """Most of the excess is slow."""
        return self.share >= SLOW_SHARE

    @property
    def floor_is_wander(self) -> bool:
        """The slow part is as large as the fast noise or larger: a floor that holds it is not the sensor's noise."""
        return self.slow >= FLOOR_WANDER * self.fast

    def _every(self) -> str:
        return f", changing sign every {self.crossing:.2g} s on average" if self.crossing is not None else " one way"

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

    def _lacks(self) -> str:
        return "" if self.is_offset else f"; {_LACKS}"

    def floor_sentence(self) -> str:
        """What a floor that holds the wander is made of."""
        return (
            f"half or more of that floor's variance is slow: the residual {self._how()}, beside {self.fast:.3g} N m "
            f"of noise faster than {self.window:.2g} s{self._lacks()}"
        )

    def sentence(self) -> str:
        """What the excess is, in the words of the rig."""
        if self.is_slow:
            return (
                f"{self.share:.0%} of the excess over the floor is slow: the residual {self._how()}, while its part "
                f"faster than {self.window:.2g} s is {self.fast_ratio:.2g}x the floor{self._lacks()}"
            )
        return (
            f"{1.0 - self.share:.0%} of the excess over the floor is faster than {self.window:.2g} s (that part is "
            f"{self.fast_ratio:.2g}x the floor): noise the floor reads low (a transducer that filters its noise), "
            "ringing, or a channel updated late"
        )

    def to_dict(self) -> dict[str, Any]:
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
            "kind": ("offset" if self.is_offset else "slow") if self.is_slow else "fast",
            "floor_is_wander": self.floor_is_wander,
            "sentence": self.sentence() if self.share > 0 else self.floor_sentence(),
            "units": {"window": "s", "slow_rms": "N m", "fast_sd": "N m", "sign_change_every": "s", "mean": "N m"},
        }


_LACKS = (
    "no logged channel follows the wander, so the torque follows something the log lacks (the rotor's angle through "
    "cogging or the gear mesh, a transducer's creep or zero drift, heat) or a curve bumpier than the model's terms: "
    "log the angle and a temperature, or repeat the sweep, to tell them apart"
)


def wander(time: Array, residual: Array, floor: float, keep: NDArray[np.bool_] | None = None) -> Wander | None:
    """Split ``residual``'s excess over ``floor`` (white noise's standard deviation) into slow and fast; rows outside
    ``keep`` (flagged stretches) are left out with every window that touches them. None when the log is too short
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
    return Wander(
        window=k * dt,
        samples=k,
        share=share,
        slow=math.sqrt(slow_var),
        fast=fast,
        fast_ratio=fast / floor,
        crossing=_crossing(t[full], slow_part, CROSSING_SIGMAS * fast / math.sqrt(k)),
        rows=int(full.sum()),
        mean=float(np.mean(slow_part)),
    )


def _split(
    r: Array, kept: NDArray[np.bool_], gap: NDArray[np.bool_], k: int
) -> tuple[NDArray[np.bool_], Array, float, float, float] | None:
    """The rows whose whole window of k samples is kept, the slow part there, the fast noise's standard deviation, the
    wander's variance and the samples m one draw of the noise stays correlated over; None when too few rows."""
    if r.size < MIN_WINDOWS * k:  # (np.convolve's "same" is as long as the window when the window is longer)
        return None
    kernel = np.ones(k)
    summed = np.convolve(np.where(kept, r, 0.0), kernel, mode="same")
    count = np.convolve(kept.astype(float), kernel, mode="same")
    # a window across a gap in time (a dropped stretch of the log) averages moments that are not neighbours
    across = np.convolve(gap.astype(float), kernel, mode="same") > 0
    full = kept & (count >= k - 0.5) & ~across
    if int(full.sum()) < MIN_WINDOWS * k:
        return None
    slow_part = summed[full] / k
    fast_part = r[full] - slow_part
    # noise of variance s^2 leaves about s^2 (1 - m/k) outside the average and s^2 m/k in it, where m = (1 + rho) /
    # (1 - rho) is the number of samples one draw of AR(1) noise stays correlated over (1 for white noise): read rho
    # from the fast part's neighbouring samples, so a filtered transducer's noise is not called a wander
    rho = _lag_one(fast_part, full)
    m = (1.0 + rho) / (1.0 - rho)
    share_out = max(1.0 - m / k, 0.5)
    fast = math.sqrt(float(np.mean(fast_part**2)) / share_out)
    slow_var = max(float(np.mean(slow_part**2)) - fast**2 * (1.0 - share_out), 0.0)
    return full, slow_part, fast, slow_var, m


def _lag_one(x: Array, full: NDArray[np.bool_]) -> float:
    """Correlation of neighbouring samples of ``x`` (the rows of ``full``, pairs adjacent in the log only), in
    [0, MAX_RHO]."""
    rows = np.flatnonzero(full)
    pair = np.diff(rows) == 1
    a, b = x[:-1][pair], x[1:][pair]
    denominator = float(a @ a)
    if a.size < 2 or not denominator > 0:
        return 0.0
    return min(max(float(a @ b) / denominator, 0.0), MAX_RHO)


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
