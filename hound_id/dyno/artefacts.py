"""What real rigs do to the current channel: wrap-around, clamped replies and driver current limits.

Seen on public actuator logs (``physics-notes.md``, "What real logs look like"):

* **Wrap-around.** A polled drive encodes the current in a fixed range, say +-12.95 A. A value
  past the range comes back from the other end (a jump of one whole period P = 25.9 A), and a
  host that "unwraps" such jumps by guesswork adds or removes whole periods at random. The
  torque does not jump with it: a real current jump of P would move the torque by Kt P. So
  jumps of one common size P that the torque does not share are wraps. Each row gets back the
  whole periods that put it nearest torque / Kt (the torque has no wrap), which restores a
  current that went past the range or sat at its edge, when the torque follows the current. When
  the host added periods to a current within the range, the channel is folded back into +-P/2
  and the rows that then sit at the boundary are removed: there the sign cannot be known. The
  one of the two that follows the torque better is kept.
* **A clamped reply.** The reported current sits at its extreme (the reply's encoding range
  or a saturated ADC) while the torque keeps moving: the true current there is unknown, so
  those rows are removed.
* **A reply held at the top of its range.** The command asks for more than the level, the
  torque does not go past what the level makes, and the reply piles up on exactly one value
  at the channel's extreme, nothing beyond it: the reply's encoding range (a protocol clamp)
  ends there. A current loop holding a driver limit scatters its readings about the limit, on
  both sides. The torque says the current is at the level, so the rows are kept as data; the
  advice names the reply's range rather than the driver.
* **A reply that flips sign at the end of its range.** Where a reply's range is known to end
  at +-L (clamped or held there), a row whose current sits within a per cent of the boundary
  with the opposite sign of a torque beyond half of what L makes has crossed the boundary and
  come back from the other end (a value just past the range, read one loop as it passed):
  its sign is wrong and its size unknown, so those rows are removed too.
* **A driver current limit.** The current sits at one level while the command keeps rising,
  and the torque stays with the current: the motor really is at the limit. Those rows are
  kept (they are data) and the limit is reported, so the peak-torque advice names the driver
  rather than "test at higher current".

Without a command channel a flat current with a flat torque is a hold, which is data, and
nothing is said.

And one that reaches every channel:

* **A stale channel.** One channel updates at a lower rate than the log (a second ADC, a slower
  bus, a reply refreshed every few loops): it holds each value for a few samples, the holds of
  nearly one length (the update instants stagger against the log's), while the other channels
  change at every sample. Its values are placed at their update instants and joined by straight
  lines; what lag remains is the delay effect's to measure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: Without a ramp up to a plateau, the torque must spread over this share of what the level makes for a clamp: a fifth,
#: far beyond what friction (which changes with the speed) spreads it by at a held current. Calibrated on
#: test_polled_rig::test_a_held_current_cannot_identify_kt and
#: test_logs::test_a_current_reading_stuck_at_full_scale_is_clipping_but_a_flat_commanded_step_is_not.
NO_RAMP_SHARE = 0.2
#: Wrap-around (a polled reply's fixed range): a jump must exceed this many noise standard deviations of the channel to
#: be a wrap candidate (a period is tens of amps against a noise of tens of mA); jumps whose sizes agree within this
#: fraction share one period (jumps of one period differ only by the noise at their ends); at least this many jumps of
#: one size make a wrap-around (one jump of the right size can be a step); a jump is a wrap when the torque moves less
#: than this share of Kt times the jump (a real jump of one period moves it by all of Kt P). Calibrated on
#: test_polled_rig::test_a_current_wrapped_past_its_range_is_restored_from_the_torque and
#: test_polled_rig::test_a_current_sitting_at_the_edge_of_its_range_flips_sign_and_is_named_a_wrap.
WRAP_SIGMAS = 40.0
WRAP_TOLERANCE = 0.015
WRAP_MIN_JUMPS = 2
WRAP_SILENT = 0.2
#: After undoing the wraps, the jumps start within this share of P/2 from the boundary +-P/2 (a wrap happens at the edge
#: of the range; noise moves it by a few per cent) ... Calibrated on
#: test_polled_rig::test_a_current_sitting_at_the_edge_of_its_range_flips_sign_and_is_named_a_wrap and
#: test_polled_rig::test_a_current_wrapped_past_its_range_is_restored_from_the_torque.
WRAP_EDGE = 0.1
#: ... and, with fewer than WRAP_MANY jumps, this share of the samples lies well inside the range (|x| < P/4): a channel
#: that only sits at the boundary and jumps twice (a spike of just the right size) is no wrap; ten jumps of one size are
#: no coincidence. Calibrated on
#: test_polled_rig::test_a_current_sitting_at_the_edge_of_its_range_flips_sign_and_is_named_a_wrap and
#: test_logs::test_a_spike_anywhere_is_removed_and_nothing_else.
WRAP_INNER = 0.05
WRAP_MANY = 10
#: Restoring the periods from the torque is kept when its squared correlation with the torque (all rows) is within this
#: of folding's (rows off the boundary) and this much above the channel's as read: two hundredths of R^2 is beyond the
#: noise of either estimate on a log of thousands of rows. Calibrated on
#: test_polled_rig::test_a_current_wrapped_past_its_range_is_restored_from_the_torque and
#: test_polled_rig::test_a_current_sitting_at_the_edge_of_its_range_flips_sign_and_is_named_a_wrap.
WRAP_BETTER = 0.02
#: Restoring from the torque adds at most this many whole periods to a row: a reply past its range comes back from the
#: other end once; a torque that asks for more (a current of 216 A from a +-18 A reply) is itself broken there.
#: Calibrated on test_polled_rig::test_a_wrap_is_not_restored_from_a_torque_that_flips and
#: test_polled_rig::test_a_current_wrapped_past_its_range_is_restored_from_the_torque.
WRAP_MAX_PERIODS = 1
#: Plateaus (a clamped reply, a driver current limit): the shortest run at a plateau that counts [samples] (five: no
#: glitch lasts that long); a plateau is within this many noise sigmas of its level (4 sigma keeps 99.99 % of the noise
#: about it) and at least PLATEAU_FLOOR of the level (a noise-free reply). Calibrated on
#: test_polled_rig::test_a_clamped_reply_is_named_and_its_rows_removed and
#: test_polled_rig::test_a_driver_current_limit_is_named_kept_and_changes_the_advice.
PLATEAU_MIN_RUN = 5
PLATEAU_SIGMAS = 4.0
PLATEAU_FLOOR = 0.002
#: A plateau level is a large magnitude: at least this share of the channel's largest |value| (a clamp or a limit is at
#: the channel's extreme, not an intermediate hold) ... Calibrated on
#: test_polled_rig::test_a_clamped_reply_is_named_and_its_rows_removed and
#: test_polled_rig::test_a_driver_current_limit_is_named_kept_and_changes_the_advice.
PLATEAU_LEVEL = 0.5
#: ... and this many times the channel's noise and its quantum (a current that never leaves zero has no plateau).
#: Calibrated on test_logs::test_an_idle_stretch_at_exactly_zero_is_not_clipping and
#: test_polled_rig::test_a_clamped_reply_is_named_and_its_rows_removed.
PLATEAU_RESOLUTION = 20.0
#: The torque "goes past" a plateau when it exceeds what the level makes by this many of its noise sigmas (well beyond
#: the 90th percentile of the noise) ... Calibrated on
#: test_polled_rig::test_a_clamped_reply_is_named_and_its_rows_removed and
#: test_polled_rig::test_a_held_current_cannot_identify_kt.
MOVING_SIGMAS = 10.0
#: ... and this share of the torque the plateau's current makes (Kt times the level): 3 %, so that a torque riding a
#: little above the ramp's line (saturation) is no clamp. Calibrated on
#: test_logs::test_a_current_reading_stuck_at_full_scale_is_clipping_but_a_flat_commanded_step_is_not,
#: test_polled_rig::test_a_clamped_reply_is_named_and_its_rows_removed and
#: test_polled_rig::test_a_held_current_that_the_command_asks_for_is_not_a_clamp.
MOVING_SHARE = 0.03
#: A current stuck exactly at one value is a saturated ADC only where its noise exceeds this many quanta (with noise of
#: a few quanta, a coarse reply repeats values exactly wherever it is flat). Calibrated on
#: test_logs::test_a_current_reading_stuck_at_full_scale_is_clipping_but_a_flat_commanded_step_is_not.
STUCK_QUANTA = 3.0
#: The command asks for more than a plateau when the current it asks for (from the command-current relation of the rows
#: off the plateau) exceeds the level by this share, in the median over the plateau's rows: 5 %, a margin over the
#: scatter of that relation. Calibrated on
#: test_logs::test_a_current_reading_stuck_at_full_scale_is_clipping_but_a_flat_commanded_step_is_not,
#: test_polled_rig::test_a_driver_current_limit_is_named_kept_and_changes_the_advice and
#: test_polled_rig::test_a_held_current_that_the_command_asks_for_is_not_a_clamp.
COMMAND_EXCESS = 0.05
#: That relation must explain this share of the current's variance off the plateau (a weaker relation cannot say what
#: the command asks for). Calibrated on
#: test_polled_rig::test_a_driver_current_limit_is_named_kept_and_changes_the_advice and
#: test_polled_rig::test_a_held_current_that_the_command_asks_for_is_not_a_clamp.
COMMAND_R2 = 0.9
#: A plateau is a reply held at the top of its range when this share of its rows sit on exactly one value (a pile at
#: the ceiling) ...: a current loop at a driver limit scatters its readings about the limit over several quanta.
#: Calibrated on
#: test_polled_rig::test_a_reply_held_at_the_top_of_its_range_is_a_protocol_clamp_not_the_driver and
#: test_polled_rig::test_a_driver_current_limit_is_named_kept_and_changes_the_advice.
CEILING_SHARE = 0.3
#: ... and at most this share of them lie beyond that value (a reply read as it crossed the end and restored from the
#: torque; a driver limit's scatter puts half of them beyond its most common value). Calibrated on
#: test_polled_rig::test_a_reply_held_at_the_top_of_its_range_is_a_protocol_clamp_not_the_driver.
BEYOND_CEILING = 0.05
#: A reply clamp's rows are data when their median torque exceeds what the level makes by at most this share of it:
#: the drive then gives the level, not more (a current 2.5 % past a clamp shows as 2.5 % more torque). Past it, the
#: current there is unknown and the rows are removed. Calibrated on
#: test_polled_rig::test_a_reply_held_at_the_top_of_its_range_is_a_protocol_clamp_not_the_driver.
CEILING_EXCESS = 0.01
#: A row sits at the boundary of a reply's range when its |current| is within this share of the range's end (or
#: PLATEAU_SIGMAS noise sigmas): a value read as it crosses the boundary lands just inside the other end. Calibrated on
#: test_polled_rig::test_a_reply_held_at_the_top_of_its_range_is_a_protocol_clamp_not_the_driver.
BOUNDARY_SHARE = 0.01


@dataclass(frozen=True)
class Wrap:
    """A wrap-around of the current channel."""

    period: float
    """Size of the jumps, one whole encoding range [A]."""
    jumps: int
    """Jumps undone."""
    first: int
    """Index (in the arrays given) of the first sample after the first jump."""
    unwrapped: bool = False
    """True when the true current left the encoding range and the jumps were undone by continuity (the
    current then spans more than +-P/2); False when the channel was folded back into +-P/2 (a host that
    added periods to a current within the range)."""


#: A channel is stale when at least this share of its samples repeat the one before exactly (a live channel with noise
#: repeats few; the holds of a channel updated every k samples repeat (k - 1) / k of them) ... Calibrated on
#: test_polled_rig::test_a_stale_channel_is_found_named_and_aligned and
#: test_polled_rig::test_a_clean_polled_log_recovers_the_truth_and_names_the_late_current.
STALE_SHARE = 0.45
#: ... its holds (the runs of one value) have nearly one length: this share of them lie within one sample of the
#: median hold (the instants stagger by a sample against the log's) ... Calibrated on
#: test_polled_rig::test_a_stale_channel_is_found_named_and_aligned and
#: test_logs::test_an_idle_stretch_at_exactly_zero_is_not_clipping.
STALE_REGULAR = 0.8
#: ... and another channel of the log repeats at most this share of its samples (a log written slower than its
#: channels change repeats none; a logger that holds every channel is a duplicate-row log, not a stale channel).
#: Calibrated on test_polled_rig::test_a_stale_channel_is_found_named_and_aligned.
LIVE_SHARE = 0.2
#: ... and its typical hold is at most this many samples (a second ADC or a slower bus runs a few to tens of times
#: slower than the log; a value held for hundreds of samples is a commanded staircase, which is data). Calibrated on
#: test_logs::test_a_current_reading_stuck_at_full_scale_is_clipping_but_a_flat_commanded_step_is_not.
STALE_MAX_HOLD = 20


def repeated_share(x: Array) -> float:
    """Share of samples that repeat the one before exactly."""
    d = np.diff(np.asarray(x, float))
    return float(np.mean(d == 0)) if d.size else 0.0


def _holds(x: Array) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """The first sample of each run of one value, and the runs' lengths."""
    starts = np.flatnonzero(np.concatenate(([True], np.diff(x) != 0)))
    return starts, np.diff(np.concatenate((starts, [x.size])))


def stale_hold(x: Array) -> float | None:
    """The mean number of samples a stale channel holds each value while it changes (module docstring), or None for a
    live channel. Holds far longer than the typical one are the signal standing still, not the update rate."""
    x = np.asarray(x, float)
    if x.size < 20 or repeated_share(x) < STALE_SHARE:
        return None
    holds = _holds(x)[1][:-1]  # the last hold may be cut short by the log's end
    if holds.size < 5:
        return None
    median = float(np.median(holds))
    typical = np.abs(holds - median) <= 1
    if not 2 <= median <= STALE_MAX_HOLD or np.mean(typical) < STALE_REGULAR:
        return None
    return float(np.mean(holds[typical]))


def align_stale(time: Array, x: Array) -> Array:
    """A stale channel placed at its update instants (the first sample of each hold) and joined by straight lines.

    A hold far longer than the typical one is the signal standing still: it stays flat until one typical hold before
    the next update, and only then moves to it."""
    x = np.asarray(x, float)
    t = np.asarray(time, float)
    starts, holds = _holds(x)
    typical = int(round(float(np.median(holds[:-1])))) if holds.size > 1 else 1
    long = np.flatnonzero(holds[:-1] > 2 * typical + 1)
    ends = starts[long] + holds[long] - typical  # still standing there, one typical hold before the next update
    anchors = np.concatenate((starts, ends))
    order = np.argsort(anchors, kind="stable")
    return np.interp(t, t[anchors[order]], x[anchors[order]])


@dataclass(frozen=True)
class Plateau:
    """Rows where the current sits at one extreme level."""

    kind: str
    """``clamp`` (the reported value is cut off while the torque moves on; rows unusable), ``reply_clamp`` (the reply
    held at the top of its range while the command asks for more and the torque stays with the level; rows kept) or
    ``driver_limit`` (real; rows kept)."""
    level: float
    """The level [A], signed."""
    rows: NDArray[np.intp]
    """Indices at the level."""
    torque_span: tuple[float, float]
    """Torque range over those rows (5th and 95th percentile) [N m]."""
    command_span: tuple[float, float] | None
    """Command range over those rows, if a command channel exists."""
    longest: int
    """Longest run [samples]."""
    asked: float | None = None
    """For a driver limit or a reply clamp, the current the command asked for there (median) [A]."""
    excess: float | None = None
    """For a reply clamp, the median torque there beyond what the level makes (a line through the ramp up to it), as a
    share of that torque; None without a ramp to compare with."""
    at_range_end: bool = False
    """For a reply clamp, whether its level is the end of the range a wrap-around showed."""

    @property
    def usable(self) -> bool:
        """Whether the rows are data: a driver limit, or a reply clamp whose torque stays with its level."""
        if self.kind == "reply_clamp":
            return self.excess is not None and self.excess <= CEILING_EXCESS
        return self.kind == "driver_limit"


def noise_sigma(x: Array) -> float:
    """Noise standard deviation from first differences: 1.4826 MAD / sqrt(2) (steps barely move it)."""
    d = np.diff(np.asarray(x, float))
    if d.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2.0))


def quantum(x: Array) -> float:
    """The channel's resolution: the smallest step it takes (1st percentile of the non-zero |steps|) [its unit]."""
    steps = np.abs(np.diff(np.asarray(x, float)))
    steps = steps[steps > 0]
    return float(np.percentile(steps, 1)) if steps.size else 0.0


def asked_at_boundary(current: Array, command: Array | None, boundary: NDArray[np.bool_], half: float) -> float | None:
    """The current the command asks for where the current sits at a wrap boundary (median) [A], if it can be told."""
    if command is None or not boundary.any():
        return None
    return _asked_current(np.abs(current), np.abs(command), np.flatnonzero(boundary), half)


def torque_per_amp(current: Array, torque: Array) -> float:
    """torque / current where the current is large (median), a robust signed "Kt" before any fit [N m/A].

    Negative for a torque sensor mounted the other way round.
    """
    a = np.abs(current)
    top = float(np.percentile(a, 95)) if a.size else 0.0
    big = a > 0.3 * top
    if top <= 0 or not big.any():
        return 0.0
    return float(np.median(torque[big] / current[big]))


def find_wraps(current: Array, torque: Array) -> tuple[Array, Wrap | None]:
    """Undo wrap-around of the current channel (module docstring); returns the current and what was found.

    1. Large jumps of the current (over WRAP_SIGMAS noise sigmas) whose sizes agree within WRAP_TOLERANCE
       give the period P (at least WRAP_MIN_JUMPS of them).
    2. The torque per amp is measured where the current lies within +-P/2 (rows no wrap has moved), and a
       jump is a wrap where the torque does not follow it (it moves less than WRAP_SILENT of Kt P, one
       sample either side: a reply read one loop late).
    3. When the channel as read fills its range end to end (a reply that wraps), the whole number of
       periods that puts each row nearest torque / Kt restores a current that went past the range, or sat
       at its edge, on every row: that is kept when it follows the torque on all rows as well as folding
       does on the rows off the boundary, and no row needs more than WRAP_MAX_PERIODS periods (a torque
       that asks for more is broken there and cannot choose). Otherwise the encoded
       current lies within +-P/2, whatever the host added: the channel is folded into +-P/2 (whole periods
       taken out).
    4. It is a wrap-around only if the wraps left the range at its boundary, the folded channel spends time
       well inside the range and follows the torque at least as well as before; otherwise the channel is
       returned as it was.
    """
    x = np.asarray(current, float)
    y = np.asarray(torque, float)
    if x.size < 3:
        return x, None
    d = np.diff(x)
    big = np.flatnonzero(np.abs(d) > max(WRAP_SIGMAS * noise_sigma(x), 0.02 * float(np.max(np.abs(x))), 1e-12))
    if big.size < WRAP_MIN_JUMPS:
        return x, None
    sizes = np.abs(d[big])
    agree = np.abs(sizes[:, None] - sizes[None, :]) <= WRAP_TOLERANCE * sizes[:, None]
    best = int(np.argmax(agree.sum(axis=1)))
    if agree[best].sum() < WRAP_MIN_JUMPS:
        return x, None
    period = float(np.median(sizes[agree[best]]))
    half = period / 2.0
    inside = np.abs(x) <= half * (1.0 + WRAP_EDGE)
    k = abs(torque_per_amp(x[inside], y[inside]))
    candidates = big[agree[best]]
    dy = np.abs(np.diff(y))
    near = np.maximum.reduce([dy[np.clip(candidates + s, 0, dy.size - 1)] for s in (-1, 0, 1)])
    jumps = candidates[near < WRAP_SILENT * k * period] if k > 0 else candidates
    if jumps.size < WRAP_MIN_JUMPS:
        return x, None
    # The jumps mix the wrap with the current's change between samples; a reply that wraps fills its range
    # from end to end, so its extent (plus one quantum) measures the period better when it agrees.
    extent = float(np.ptp(x)) + quantum(x)
    fills = abs(extent - period) <= WRAP_TOLERANCE * period  # the reply as read fills its range end to end
    if fills:
        period, half = extent, extent / 2.0
    folded = x - period * np.round(x / period)
    edge = np.abs(np.abs(folded[jumps]) - half) <= WRAP_EDGE * half
    inner = np.abs(folded) < half / 2.0
    clear = np.abs(folded) < half * (1.0 - WRAP_EDGE)  # rows off the boundary, where the sign is known
    if edge.mean() < 0.9:
        return x, None
    # A current that really went past the range: on each row take the whole number of periods that puts the
    # current nearest torque / Kt (the torque does not wrap; Kt from rows well inside the range, which no wrap
    # reaches; the choice is discrete, so a rough Kt and a torque off by friction do not matter).
    k_inner = torque_per_amp(folded[inner], y[inner]) if inner.sum() >= 10 else 0.0
    if k_inner != 0.0 and fills:
        added = np.round((y / k_inner - x) / period)
        continuous = x + period * added
        # the torque's choice keeps every row: take it when it follows the torque on all rows as well as folding
        # does on the rows off the boundary (a torque that hardly follows the current cannot choose)
        folding = _follows(folded[clear], y[clear])
        # a value past the range wraps once: a torque that asks for more periods is not this current's torque there
        # (a torque channel that flips or runs away), so it cannot choose
        believable = float(np.max(np.abs(added))) <= WRAP_MAX_PERIODS
        if believable and _follows(continuous, y) >= max(folding - WRAP_BETTER, _follows(x, y) + WRAP_BETTER):
            return continuous, Wrap(period, int(jumps.size), int(jumps[0]) + 1, unwrapped=True)
    if _follows(folded[clear], y[clear]) < _follows(x[clear], y[clear]):
        return x, None
    if jumps.size < WRAP_MANY and inner.mean() < WRAP_INNER:  # a few jumps of a channel that never leaves the edge
        return x, None
    return folded, Wrap(period, int(jumps.size), int(jumps[0]) + 1)


def _follows(x: Array, y: Array) -> float:
    """Squared correlation of two channels (0 when one is constant)."""
    if x.size < 3:
        return 0.0
    sx, sy = float(np.std(x)), float(np.std(y))
    if sx == 0 or sy == 0:
        return 0.0
    return float(np.corrcoef(x, y)[0, 1] ** 2)


def at_boundary(current: Array, wrap: Wrap) -> NDArray[np.bool_]:
    """Rows whose current sits at the wrap boundary +-P/2, where its sign cannot be known."""
    x = np.asarray(current, float)
    tol = max(PLATEAU_SIGMAS * noise_sigma(x), 0.005 * wrap.period)
    return np.abs(x) >= wrap.period / 2.0 - tol  # type: ignore[no-any-return]


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.astype(np.int8), [0]))))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def find_plateaus(
    current: Array, torque: Array, command: Array | None = None, range_end: float | None = None
) -> list[Plateau]:
    """Clamped replies and driver current limits at either extreme of the current (module docstring).

    ``range_end``: where the reply's encoding range ends [A], when a wrap-around showed it; a plateau there is the
    reply's range, not the driver's limit."""
    x = np.asarray(current, float)
    y = np.asarray(torque, float)
    if x.size < PLATEAU_MIN_RUN:
        return []
    sigma_x, sigma_y = noise_sigma(x), noise_sigma(y)
    peak = float(np.max(np.abs(x)))
    k_scale = abs(torque_per_amp(x, y))
    resolution = PLATEAU_RESOLUTION * max(sigma_x, quantum(x))
    found = []
    for level in (float(x.max()), float(x.min())):
        if peak <= 0 or abs(level) < max(PLATEAU_LEVEL * peak, resolution):
            continue
        tol = max(PLATEAU_SIGMAS * sigma_x, PLATEAU_FLOOR * abs(level))
        at = np.abs(x - level) <= tol
        runs = [(a, b) for a, b in _runs(at) if b - a >= PLATEAU_MIN_RUN]
        if not runs:
            continue
        rows = np.concatenate([np.arange(a, b) for a, b in runs])
        if rows.size < max(PLATEAU_MIN_RUN, 0.001 * x.size):
            continue
        lo, hi = (float(v) for v in np.percentile(y[rows], [5, 95]))
        cmd_span = None
        if command is not None:
            c = np.asarray(command, float)
            cmd_span = (float(np.min(c[rows])), float(np.max(c[rows])))
        longest = max(b - a for a, b in runs)
        asked = None if command is None else _asked_current(x, np.asarray(command, float), rows, level)
        if asked is not None and abs(asked) <= (1.0 + COMMAND_EXCESS) * abs(level):
            continue  # the command asks for this current: a hold, which is data
        if _torque_goes_past(x, y, rows, level, sigma_y, k_scale):
            found.append(Plateau("clamp", level, rows, (lo, hi), cmd_span, longest))
            continue
        at_range_end = range_end is not None and abs(abs(level) - range_end) <= max(tol, BOUNDARY_SHARE * range_end)
        # a pile at the top tells a reply's range without a command, on a channel that is noisy elsewhere
        ceiling = _ceiling(x[rows], level) if (asked is not None or sigma_x >= max(quantum(x), 1e-300)) else None
        if at_range_end or ceiling is not None:
            top = level if ceiling is None else ceiling
            excess = _excess(x, y, rows, top)
            found.append(Plateau("reply_clamp", top, rows, (lo, hi), cmd_span, longest, asked, excess, at_range_end))
            continue
        if asked is not None:  # asking for more than the level (a hold it asks for was left above)
            found.append(Plateau("driver_limit", level, rows, (lo, hi), cmd_span, longest, asked))
            continue
        stuck = x == level
        exact = max((b - a for a, b in _runs(stuck)), default=0)
        if exact >= PLATEAU_MIN_RUN and sigma_x > STUCK_QUANTA * quantum(x):
            # finely resolved and noisy elsewhere, yet exactly one value for whole runs: a saturated ADC
            found.append(Plateau("clamp", level, np.flatnonzero(stuck), (lo, hi), cmd_span, exact))
    return found


def _ramp_line(current: Array, torque: Array, level: float) -> tuple[float, float, NDArray[np.bool_]] | None:
    """A straight line torque = a current + b through the rows on the level's side between 30 % and 95 % of it (the
    ramp up to a plateau), with those rows; None when they are fewer than ten or span less than 30 % of the level."""
    sign = 1.0 if level > 0 else -1.0
    ramp = (sign * current > 0.3 * abs(level)) & (sign * current < 0.95 * abs(level))
    if np.count_nonzero(ramp) < 10 or np.ptp(current[ramp]) <= 0.3 * abs(level):
        return None
    a, b = np.polyfit(current[ramp], torque[ramp], 1)
    return float(a), float(b), ramp


def _excess(current: Array, torque: Array, rows: NDArray[np.intp], level: float) -> float | None:
    """Median torque on a plateau beyond the ramp's line (:func:`_ramp_line`) at the level, as a share of the line's
    torque there; None without such a ramp."""
    line = _ramp_line(current, torque, level)
    if line is None:
        return None
    made = line[0] * level + line[1]
    if made == 0:
        return None
    return float((np.median(torque[rows]) - made) / made)


def _ceiling(values: Array, level: float) -> float | None:
    """The value a plateau's readings pile up on, when they pile at its top (CEILING_SHARE of them on it, at most
    BEYOND_CEILING beyond it in the level's direction): a reply's range ending there. None for a scatter about a
    level."""
    held, counts = np.unique(values, return_counts=True)
    top = float(held[int(np.argmax(counts))])
    sign = 1.0 if level > 0 else -1.0
    beyond = np.count_nonzero(sign * (values - top) > 0)
    if counts.max() >= CEILING_SHARE * values.size and beyond <= BEYOND_CEILING * values.size:
        return top
    return None


def flipped_at_boundary(current: Array, torque: Array, end: float) -> NDArray[np.bool_]:
    """Rows whose current sits at the boundary +-``end`` of the reply's range with the sign opposite to the torque's
    (the torque beyond half of what ``end`` makes): the reply crossed the boundary and came back from the other end."""
    x, y = np.asarray(current, float), np.asarray(torque, float)
    k = torque_per_amp(x, y)
    if k == 0 or end <= 0:
        return np.zeros(x.shape, dtype=bool)
    tol = max(PLATEAU_SIGMAS * noise_sigma(x), BOUNDARY_SHARE * end)
    return (np.abs(x) >= end - tol) & (np.sign(x) != np.sign(y / k)) & (np.abs(y) > 0.5 * abs(k) * end)  # type: ignore[no-any-return]


def _torque_goes_past(
    current: Array, torque: Array, rows: NDArray[np.intp], level: float, sigma_y: float, k_scale: float
) -> bool:
    """Whether the torque on a plateau goes past what the plateau's current makes.

    The torque the level makes comes from a straight line torque = a current + b through the rows on the
    same side between 30 % and 95 % of the level (spanning 30 % of it at least); the plateau's torque (its
    90th percentile in the level's direction) must exceed it by MOVING_SIGMAS noise sigmas, MOVING_SHARE
    of it, and twice the torque's scatter about the line on those rows (friction, which changes with the
    speed, scatters it there as much as on the plateau). Without such rows, the torque's spread over the
    plateau must exceed the same margin and NO_RAMP_SHARE of the torque the level makes.
    """
    sign = 1.0 if level > 0 else -1.0
    margin = max(MOVING_SIGMAS * sigma_y, MOVING_SHARE * k_scale * abs(level))
    line = _ramp_line(current, torque, level)
    if line is not None:
        a, b, ramp = line
        # friction and other speed effects scatter the torque about the line on the ramp as on the plateau
        scatter = float(np.percentile(np.abs(torque[ramp] - (a * current[ramp] + b)), 95))
        margin = max(margin, 2.0 * scatter)
        beyond = sign * (1.0 if a >= 0 else -1.0)  # the torque's way of growing current (a sensor may be reversed)
        return bool(np.percentile(beyond * torque[rows], 90) - beyond * (a * level + b) > margin)
    # no ramp to compare with: only a spread far beyond friction's (a fifth of what the level makes) is a clamp
    return bool(np.ptp(np.percentile(torque[rows], [5, 95])) > max(margin, NO_RAMP_SHARE * k_scale * abs(level)))


def _asked_current(current: Array, command: Array, rows: NDArray[np.intp], level: float) -> float | None:
    """The current the command asks for on a plateau's rows (median) [A], from the relation off the plateau.

    The command may be a torque (either side of a gearbox) or a current: a straight line current = a command + b,
    fitted where the current is clearly below the plateau, converts it. None when the line explains too little.
    """
    off = np.abs(current) < 0.9 * abs(level)
    off[rows] = False
    if np.count_nonzero(off) < 10 or np.ptp(command[off]) <= 0:
        return None
    A = np.column_stack([command[off], np.ones(np.count_nonzero(off))])
    coef, *_ = np.linalg.lstsq(A, current[off], rcond=None)
    fitted = A @ coef
    spread = float(np.var(current[off]))
    if spread <= 0 or 1.0 - float(np.var(current[off] - fitted)) / spread < COMMAND_R2:
        return None
    return float(np.median(coef[0] * command[rows] + coef[1]))


__all__ = [
    "Plateau",
    "align_stale",
    "repeated_share",
    "stale_hold",
    "Wrap",
    "at_boundary",
    "find_plateaus",
    "find_wraps",
    "flipped_at_boundary",
    "noise_sigma",
    "torque_per_amp",
]
