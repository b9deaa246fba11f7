"""Which samples of a torque-speed log sit at the motor's limits, per speed bin.

**Samples at the limit.** A log shows the envelope only where the motor was pushed to it. With a
commanded-torque channel (``torque_cmd``) a sample is at its upper limit when the lagged command
passes the measured torque, for a few rows, by more than anything seen inside the region; the lag,
the gain and bias between command and torque, and the threshold are all measured on the log
(:func:`command_limits`). Without one, hound-id looks for a *wall* in each speed bin
(:func:`bin_count` bins): the margins r = tau - edge(omega) of samples driven into a limit pile up,
so the top of the margin distribution is narrow, (q98 - q90) < :data:`WALL` x (q98 - q50) and
below :data:`WALL_WIDTH` of the torque limit, or holds a large share of the bin (:data:`PILE`, a
speed hold), and the bin's margins reach :data:`APPROACH` of the torque limit below it. Where an
edge can fall steeply (:func:`_steep`) the linear drift of the top fifth of the margins is taken
out first; such a wall needs two passes that drift alike (:func:`_passes_agree`). A wall of one
pass must agree with the model or with walls seen in several passes nearby, or follow the speed
as the edge does (:func:`_continuous`); walls need three neighbouring bins, or two passes that agree
at one speed (:func:`_contiguous`). The samples of a wall form the bin's cluster.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence, Set
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

from hound_id.dyno.logs import MAD_TO_SIGMA, EnvelopeLog
from hound_id.errors import DynoDataError
from hound_id.mor.envelope import EnvelopeInputs, envelope

Array = NDArray[np.float64]

# Every threshold of the wall finder, with why it has its value and the test it was calibrated on. A test named
# here fails when the value moves far enough to matter (tests/test_thresholds.py checks that every one is named).

# --- with a command channel (command_limits) ---

#: Lag searched between the command and the measured torque [rows]: 100 rows is 0.1 s at 1 kHz, ten times a current loop
#: plus a filtered transducer. Calibrated on test_hold_protocol::test_the_lag_is_measured_from_the_log.
LAG_MAX = 100
#: ... and at most a LAG_LOG_DIVISOR-th of the log (a short log cannot show a long lag). Calibrated on
#: test_hold_protocol::test_the_lag_is_measured_from_the_log.
LAG_LOG_DIVISOR = 10
#: The lag is refined to this fraction of a row (linear interpolation between rows). Calibrated on
#: test_hold_protocol::test_the_lag_is_measured_from_the_log.
LAG_STEP = 0.1
#: "Inside the region": commands within this share of the spec sheet's edges, where no plausible effect (a sag of a
#: third, a hot winding) bounds the torque. Calibrated on
#: test_hold_protocol::test_a_sample_far_inside_the_region_is_never_at_the_limit.
INSIDE_SHARE = 0.5
#: Measured torque per commanded torque inside the region must lie in this range; outside it the command is in another
#: unit (a current: Kt is far from 1; N cm: 100). Calibrated on
#: test_hold_protocol::test_a_command_in_another_unit_is_refused.
GAIN_RANGE = (0.5, 2.0)
#: A shortfall must pass this many robust noise levels at least (5 sigma: one false row in 3.5 million). Calibrated on
#: test_hold_protocol::test_a_sample_far_inside_the_region_is_never_at_the_limit.
CMD_SIGMAS = 5.0
#: Rows a shortfall must last (at least; twice the lag when that is longer): a single noisy row is no limit. Calibrated
#: on test_compare::test_a_commanded_torque_channel_finds_the_limit_directly.
PERSIST = 3
#: The first rows of a run at the limit are left out while the filtered torque is more than this many noise levels from
#: the run's later median (still settling). Calibrated on test_hold_protocol::test_the_lag_is_measured_from_the_log.
SETTLE_SIGMAS = 3.0
#: Samples further than this many robust spreads from their cluster's median are left out of it (a passing disturbance).
#: Calibrated on test_compare::test_a_commanded_torque_channel_finds_the_limit_directly.
TRIM = 5.0
#: A robust spread is floored at this share of the wall width (a simulated, noise-free wall has none). Calibrated on
#: test_compare::test_data_that_match_the_model_flag_nothing.
SPREAD_FLOOR = 1e-3
#: Rows are samples in time when the median step between rows is below this share of the signal's interquartile range (a
#: table of operating points or a shuffled log steps across it). Calibrated on
#: test_compare::test_time_ordered_logs_without_a_command.
ORDERED_STEP = 0.1

# --- without one: walls in speed bins (find_walls) ---

#: A bin has a wall when (q98 - q90) < WALL (q98 - q50) of its margins: the top tenth of the margins is packed ten times
#: tighter than the upper half. Calibrated on test_compare::test_the_hidden_effect_is_named_and_explains_the_envelope.
WALL = 0.1
#: Such a wall is the margins above q90 - WALL_BAND (q98 - q90): its top and as much again below. Calibrated on
#: test_compare::test_the_hidden_effect_is_named_and_explains_the_envelope.
WALL_BAND = 2.0
#: ... and its top (q98 - q90) narrower than this share of the torque limit: piled up within the noise (3 % of a 9.7 N m
#: limit is 0.3 N m, ten sensor sigmas). Calibrated on test_compare::test_data_that_match_the_model_flag_nothing.
WALL_WIDTH = 0.03
#: ... and approached: the bin's margins span at least this share of the torque limit below it (a motor resting while
#: the speed ramps piles up too, at one torque). Calibrated on
#: test_compare::test_a_slow_command_is_not_taken_for_a_limit.
APPROACH = 0.2
#: Or a pile: at least PILE of the bin's margins within WALL_WIDTH of its top (q98), and at most WALL_CONTRAST as many
#: in the band of that width below (a speed hold pushes the motor against its limit for long). Calibrated on
#: test_hold_protocol::test_the_hidden_effect_is_named_first.
PILE = 0.2
WALL_CONTRAST = 0.2
#: Such a wall is its margins within BAND robust spreads of their median (4 sigma keeps 99.99 % of Gaussian noise).
#: Calibrated on test_hold_protocol::test_the_hidden_effect_is_named_first.
BAND = 4.0
#: A pile's band is re-centred on its median this many times (the first band is its top only). Calibrated on
#: test_hold_protocol::test_the_hidden_effect_is_named_first.
RECENTRE_PASSES = 2
#: Speed bins across the logged range: BINS, or one per SAMPLES_PER_BIN samples for long logs, at most MAX_BINS, so that
#: an edge falling steeply with speed stays nearly straight across one bin. Calibrated on
#: test_compare::test_time_ordered_logs_without_a_command and benchmarks/compare.py (its scoreboard).
BINS = 32
MAX_BINS = 96
SAMPLES_PER_BIN = 250
#: The fewest samples a bin needs, and a wall. Calibrated on
#: test_compare::test_a_log_that_never_reaches_its_limits_is_refused.
MIN_SAMPLES = 40
MIN_WALL = 8
#: Where an edge may fall steeply, the linear drift of the top DRIFT_QUANTILE of the margins is taken out (if it holds
#: DRIFT_MIN samples or more) before looking for a wall again. Calibrated on
#: test_compare::test_time_ordered_logs_without_a_command.
DRIFT_QUANTILE = 0.8
DRIFT_MIN = 5
#: A wall's level may depart from the line through its neighbours by this share of the torque limit ... Calibrated on
#: test_compare::test_a_slow_command_is_not_taken_for_a_limit.
STEP = 0.05
#: ... looking this many bins either side for them, or this share of all bins, whichever is more. Calibrated on
#: test_compare::test_a_slow_command_is_not_taken_for_a_limit.
NEIGHBOURS = 3
NEIGHBOUR_SPAN = 0.1
#: Walls need this many neighbouring bins with walls (or REPEATED passes): a limit spans a range of speeds. Calibrated
#: on test_compare::test_a_slow_command_is_not_taken_for_a_limit.
NEIGHBOURING_WALLS = 3
#: A one-pass wall whose margins' slope in speed is this many standard errors from a plateau's tracks the edge.
#: Calibrated on test_hold_protocol::test_the_hidden_effect_is_named_first.
TRACK_SIGMAS = 5.0
#: ... and within TRACK_SHARE of a plateau's slope of zero (a limit's margins are flat in speed). Calibrated on
#: test_hold_protocol::test_the_hidden_effect_is_named_first.
TRACK_SHARE = 0.5
#: Passes of a wall whose levels differ at this significance are not one wall, unless they differ by less than
#: LEVEL_FLOOR of the torque limit. Calibrated on
#: test_hold_protocol::test_pulses_that_never_reach_the_limit_name_nothing_with_the_command.
LEVEL_ALPHA = 1e-4
LEVEL_FLOOR = 0.005
#: A wall's samples spread at most this many times the typical noise at a limit (a pass of a moving command spreads
#: more). Calibrated on test_compare::test_a_slow_command_is_not_taken_for_a_limit.
FLAT = 3.0
#: Passes (at one level) that make a wall on their own, without walls in the bins beside it. Calibrated on
#: test_hold_protocol::test_the_hidden_effect_is_named_first.
REPEATED = 2
#: Rows of a log apart beyond which two samples of a wall belong to different passes through its speed bin; a pass
#: counts when it has PASS_RUN samples; a wall is one pass when ONE_PASS_SHARE of its samples are. Calibrated on
#: test_compare::test_a_slow_command_is_not_taken_for_a_limit.
PASS_GAP = 25
PASS_RUN = 5
ONE_PASS_SHARE = 0.75
#: Passes drift alike when their slopes agree within SLOPE_SIGMAS standard errors or SLOPE_SHARE of the mean slope.
#: Calibrated on test_compare::test_time_ordered_logs_without_a_command.
SLOPE_SIGMAS = 4.0
SLOPE_SHARE = 0.2
#: Speeds [share of the spec's corner / no-load speed] past which a motoring / braking edge may fall steeply (a sagging
#: or hot motor turns its corner sooner). Calibrated on test_compare::test_time_ordered_logs_without_a_command.
STEEP_MOTORING = 0.6
STEEP_BRAKING = 0.9
#: The lag-1 autocorrelation of the noise at a limit is clipped to [0, RHO_MAX] (at 0.95 a wall of n samples counts as
#: n/39 independent ones) and needs FEWEST_PAIRS consecutive pairs in a wall. Calibrated on
#: test_compare::test_the_noise_level_allows_for_correlated_sensor_noise.
RHO_MAX = 0.95
FEWEST_PAIRS = 10


@dataclass(frozen=True)
class Walls:
    """Which samples sit at the upper and lower limits, per speed bin."""

    centres: Array
    """Bin centres, motor speed [rad/s]."""
    upper: tuple[NDArray[np.int64], ...]
    """Per bin, the indices of the samples at the upper limit (empty: no wall)."""
    lower: tuple[NDArray[np.int64], ...]
    method: str
    """``command`` or ``wall``."""
    rho: float = 0.0
    """Lag-1 autocorrelation of the torque noise between consecutive samples at the limit (0 for shuffled logs),
    from the walls' residuals about a straight line in speed; it widens the offsets' standard errors."""
    commanded: CommandLimits | None = None
    """How the command channel was read (``command`` method only)."""


@dataclass(frozen=True)
class CommandLimits:
    """The samples a command channel shows at the limit (:func:`command_limits`)."""

    upper: NDArray[np.bool_]
    lower: NDArray[np.bool_]
    lag: float
    """Rows by which the measured torque follows the command (current loop, transducer filter, a late reply)."""
    gain: float
    """Measured torque per commanded torque inside the region (1 for a driver and transducer that agree)."""
    bias: float
    """Measured minus commanded torque at zero command inside the region [N m] (friction, inertia torque)."""
    threshold: tuple[float, float]
    """Shortfall [N m] of the measured torque under (upper) and over (lower) the lagged command past which a sample
    may be at its limit: the largest that lasted ``persist`` rows inside the region, at least :data:`CMD_SIGMAS`
    noise levels."""
    noise: float
    """Robust noise of the torque about the lagged command inside the region (1.4826 MAD) [N m]."""
    persist: int
    """Consecutive rows the shortfall must last."""

    def to_dict(self) -> dict[str, Any]:
        return {
            "lag_rows": self.lag,
            "gain": self.gain,
            "bias": self.bias,
            "threshold": {"upper": self.threshold[0], "lower": self.threshold[1]},
            "noise": self.noise,
            "persist_rows": self.persist,
            "samples": {"upper": int(self.upper.sum()), "lower": int(self.lower.sum())},
            "units": "N m, rows",
        }


def _lagged(x: Array, lag: float) -> Array:
    """``x`` delayed by ``lag`` rows (linear interpolation; the first rows hold x[0])."""
    rows = np.arange(x.size, dtype=float)
    return np.interp(rows - lag, rows, x)


def command_limits(log: EnvelopeLog, inputs: EnvelopeInputs) -> CommandLimits:
    """Which samples a command channel shows at the limit, allowing for the lag, gain and bias between the command
    and the measured torque, and for their noise, all measured on the log itself.

    *Inside the region* are the samples whose command lies within half the spec sheet's edges at their speed
    (where no plausible effect bounds the torque). There the measured torque follows the command: the lag (whole
    rows up to :data:`LAG_MAX` rows, refined to a tenth of a row) minimises the mean absolute difference between
    the torque and the lagged command (no lag when the rows are not in time order, :func:`time_ordered`), then a
    straight line torque = gain x command + bias is fitted. A sample is at its upper limit when the line through its
    lagged command exceeds its torque for :data:`PERSIST` rows or more (and twice the lag; any one row in a table) by
    more than any shortfall that lasted as long inside the region (the rotor's inertia torque while the speed ramps,
    a filter ringing), and by :data:`CMD_SIGMAS` robust noise levels at least; the first rows of each such run, while
    the filtered torque still settles (more than 3 noise levels from the run's later median), are left out. The
    lower limit likewise."""
    assert log.torque_cmd is not None
    tau, cmd = log.torque, log.torque_cmd
    n = tau.size
    lo_s, hi_s = envelope(log.velocity, {}, inputs_for(log, inputs, np.arange(n)))
    lo_s, hi_s = np.nan_to_num(lo_s, nan=0.0), np.nan_to_num(hi_s, nan=0.0)

    def inside(c: Array) -> NDArray[np.bool_]:
        return np.asarray((c < INSIDE_SHARE * hi_s) & (c > INSIDE_SHARE * lo_s))

    def misfit(lag: float) -> float:
        c = _lagged(cmd, lag)
        keep = inside(c)
        return float(np.mean(np.abs(tau[keep] - c[keep]))) if keep.sum() >= MIN_SAMPLES else math.inf

    ordered = time_ordered(tau)
    lag = 0.0
    if ordered:  # a table of operating points (rows in no time order) has no lag to find
        scores = [misfit(float(d)) for d in range(min(LAG_MAX, n // LAG_LOG_DIVISOR) + 1)]
        best = int(np.argmin(scores))
        fine = np.arange(max(best - 1, 0), best + 1.0001, LAG_STEP)
        lag = float(fine[int(np.argmin([misfit(float(d)) for d in fine]))])
    c = _lagged(cmd, lag)
    keep = inside(c)
    if keep.sum() < MIN_SAMPLES:
        raise DynoDataError(
            f"{log.source}: torque_cmd is inside the region in only {int(keep.sum())} rows; the command cannot be "
            "compared with the torque: is it the command of this motor, in N m (map with --columns, --units)?"
        )
    gain, bias = np.polyfit(c[keep], tau[keep], 1)
    if not GAIN_RANGE[0] <= gain <= GAIN_RANGE[1]:
        raise DynoDataError(
            f"{log.source}: the measured torque follows torque_cmd with a gain of {gain:.3g} inside the region, "
            "expected about 1: is torque_cmd in another unit (a current, N*cm)? Fix its unit with --units "
            "torque_cmd=..., or leave the column out"
        )
    expected = gain * c + bias
    short = expected - tau  # positive: the torque falls short of the command (upper limit)
    noise = robust(short[keep])[1]
    floor = CMD_SIGMAS * noise
    persist = max(PERSIST, int(math.ceil(2 * lag)) + 1) if ordered else 1
    # the largest shortfall that lasted `persist` rows inside the region: a limit must beat what the region does
    whole = sliding_window_view(keep, persist).all(axis=1)
    if not whole.any():
        whole = np.ones(n - persist + 1, dtype=bool)
    lasting_up = sliding_window_view(short, persist).min(axis=1)[whole]
    lasting_lo = sliding_window_view(-short, persist).min(axis=1)[whole]
    thr_up = max(float(np.max(lasting_up)), floor)
    thr_lo = max(float(np.max(lasting_lo)), floor)
    return CommandLimits(
        upper=_settled_runs(short > thr_up, tau, persist, ordered, noise),
        lower=_settled_runs(-short > thr_lo, tau, persist, ordered, noise),
        lag=lag,
        gain=float(gain),
        bias=float(bias),
        threshold=(thr_up, thr_lo),
        noise=noise,
        persist=persist,
    )


def _settled_runs(mask: NDArray[np.bool_], tau: Array, persist: int, ordered: bool, noise: float) -> NDArray[np.bool_]:
    """The runs of ``mask`` at least ``persist`` rows long, less their first rows while the torque still settles."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    out = np.zeros(tau.size, dtype=bool)
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        if stop - start < persist:
            continue
        if not ordered:
            out[start:stop] = True
            continue
        settled = float(np.median(tau[start + (stop - start) // 2 : stop]))
        off = np.abs(tau[start:stop] - settled) > SETTLE_SIGMAS * noise
        first = int(np.argmin(off)) if not off.all() else stop - start
        first = min(first, (stop - start) // 2)
        out[start + first : stop] = True
    return out


def time_ordered(x: Array) -> bool:
    """Whether consecutive rows are samples of one signal in time (steps between rows much smaller than its spread),
    not a table of operating points or a shuffled log."""
    if x.size < 3:
        return False
    q25, q75 = np.quantile(x, [0.25, 0.75])
    return bool(np.median(np.abs(np.diff(x))) < ORDERED_STEP * (q75 - q25))


def _trimmed(members: NDArray[np.int64], margin_of: Any, width: float) -> NDArray[np.int64]:
    """A cluster of samples at the limit without its outliers: margins more than :data:`TRIM` robust spreads from the
    cluster's median (a sample flagged by a passing disturbance) are left out. ``width`` [N m] floors the spread."""
    if members.size < 3:
        return members
    m = margin_of(members)
    centre, spread = robust(m)
    return members[np.abs(m - centre) <= TRIM * max(spread, SPREAD_FLOOR * width)]


def robust(x: Array) -> tuple[float, float]:
    """(median, 1.4826 MAD): the centre and the standard deviation of Gaussian noise, unmoved by a few outliers."""
    centre = float(np.median(x))
    return centre, MAD_TO_SIGMA * float(np.median(np.abs(x - centre)))


def _wall(members: NDArray[np.int64], m: Array, width: float) -> NDArray[np.int64]:
    """The members whose margins form a wall at the top of the bin (module docstring), or none. The top
    must also be narrower than ``width`` [N m] in absolute terms: piled up within the sensor noise."""
    q10, q50, q90, q98 = np.quantile(m, [0.1, 0.5, 0.9, 0.98])
    if (q98 - q10) <= APPROACH * width / WALL_WIDTH:
        return np.array([], dtype=np.int64)
    if (q98 - q90) < WALL * (q98 - q50) and (q98 - q90) < width:
        return members[m >= q90 - WALL_BAND * (q98 - q90)]
    top = m >= q98 - width
    below = (m >= q98 - 2 * width) & ~top
    if top.mean() >= PILE and below.sum() <= WALL_CONTRAST * top.sum():
        # a wall that holds much of the bin (a speed hold, pushed for long): centred on its median, as wide as its
        # noise either side
        band = top
        for _ in range(RECENTRE_PASSES):
            centre, spread = robust(m[band])
            band = np.abs(m - centre) <= BAND * max(spread, SPREAD_FLOOR * width)
        return members[band]
    return np.array([], dtype=np.int64)


def bin_count(n: int) -> int:
    """Speed bins for a log of ``n`` samples: :data:`BINS`, more for long logs (about 250 samples a bin, at most
    :data:`MAX_BINS`), so an edge that falls steeply with speed stays nearly straight across one bin."""
    return int(np.clip(n // SAMPLES_PER_BIN, BINS, MAX_BINS))


def find_walls(
    log: EnvelopeLog,
    inputs: EnvelopeInputs,
    model: Mapping[str, float] | None = None,
    bins: int | None = None,
    commanded: CommandLimits | None = None,
) -> Walls:
    """The samples at the limit in each speed bin, against ``model``'s edges (module docstring). ``commanded``: the
    log's :func:`command_limits`, which do not depend on the model (computed here when the log has a command)."""
    w = log.velocity
    bins = bins or bin_count(log.n)
    edges = np.linspace(float(w.min()), float(w.max()), bins + 1)
    index = np.clip(np.searchsorted(edges, w, side="right") - 1, 0, bins - 1)
    lo, hi = envelope(w, dict(model or {}), inputs_for(log, inputs, np.arange(log.n)))
    upper, lower = [], []
    drifting: set[tuple[int, int]] = set()  # (side, bin) of walls found with their drift taken out
    if commanded is None and log.torque_cmd is not None:
        commanded = command_limits(log, inputs)
    width = WALL_WIDTH * inputs.spec.linear_torque_limit
    order = np.argsort(index, kind="stable")  # rows by bin, ascending within each
    bounds = np.searchsorted(index[order], np.arange(bins + 1))
    for b in range(bins):
        members = order[bounds[b] : bounds[b + 1]]
        found = []
        for margin_of, cmd_side in ((lambda i: log.torque[i] - hi[i], 1.0), (lambda i: lo[i] - log.torque[i], -1.0)):
            if members.size < MIN_SAMPLES:
                found.append(np.array([], dtype=np.int64))
                continue
            if commanded is not None:
                flagged = commanded.upper if cmd_side > 0 else commanded.lower
                at = _trimmed(members[flagged[members]], margin_of, width)
            else:
                m = margin_of(members)
                finite = np.isfinite(m)
                if finite.sum() < MIN_SAMPLES:
                    found.append(np.array([], dtype=np.int64))
                    continue
                cand, m = members[finite], m[finite]
                at = _wall(cand, m, width)
                if at.size == 0 and _steep(float(np.mean(w[cand])), cmd_side, inputs):
                    # The true edge may drift against the model's across the bin where edges are steep (the motoring
                    # edge past the corner, the braking one past the no-load speed): take out the linear drift of
                    # the top fifth of the margins and look again.
                    top = m >= np.quantile(m, DRIFT_QUANTILE)
                    if top.sum() >= DRIFT_MIN and np.ptp(w[cand[top]]) > 0:
                        slope = np.polyfit(w[cand[top]], m[top], 1)[0]
                        at = _wall(cand, m - slope * (w[cand] - np.mean(w[cand])), width)
                        if at.size and not _passes_agree(at, margin_of(at), w[at]):
                            at = np.array([], dtype=np.int64)
                        drifting.add((int(cmd_side), b))
            if commanded is None and at.size:
                at = _trimmed(at, margin_of, width)
            found.append(at if at.size >= MIN_WALL else np.array([], dtype=np.int64))
        upper.append(found[0])
        lower.append(found[1])
    centres = 0.5 * (edges[:-1] + edges[1:])
    rho = _autocorrelation(log, upper + lower, pooled=log.torque_cmd is not None)
    if log.torque_cmd is None:  # a limit spans a range of speeds: isolated walls and walls off the edge are chance
        upper, lower = _drop_chance_walls(log, inputs, (upper, lower), (lo, hi), rho, drifting)
        rho = _autocorrelation(log, upper + lower)
    method = "command" if log.torque_cmd is not None else "wall"
    return Walls(centres, tuple(upper), tuple(lower), method, rho, commanded)


def _drop_chance_walls(
    log: EnvelopeLog,
    inputs: EnvelopeInputs,
    walls: tuple[list[NDArray[np.int64]], list[NDArray[np.int64]]],
    edges: tuple[Array, Array],
    rho: float,
    drifting: Set[tuple[int, int]],
) -> tuple[list[NDArray[np.int64]], list[NDArray[np.int64]]]:
    """The (upper, lower) walls of a log without a command, less passes that disagree and walls off a run of them."""
    (upper, lower), (lo, hi), w = (list(walls[0]), list(walls[1])), edges, log.velocity
    tol, floor = (k * inputs.spec.linear_torque_limit for k in (STEP, LEVEL_FLOOR))
    empty = np.array([], dtype=np.int64)
    noise = _noise_scale(log, upper + lower)
    for side, walls_, margin in ((1, upper, log.torque - hi), (-1, lower, lo - log.torque)):
        for b, i in enumerate(walls_):
            if not i.size:
                continue
            m = margin[i]
            # one pass of a moving command spreads more than the noise; passes of a limit sit on one curve in
            # speed (drifting against a model that is wrong there), passes of commands at several levels
            line = _about_parabola(w[i], m) if np.ptp(w[i]) > 0 else m
            i = _agreeing_passes(i, line, rho, floor)
            drifts = (side, b) in drifting  # its passes were checked to drift alike (_passes_agree)
            if i.size < MIN_WALL or (not drifts and _one_pass(i) and float(np.std(margin[i])) > FLAT * noise):
                i = empty
            walls_[b] = i
        kept, vouched = _continuous(walls_, margin, w, tol, (hi if side > 0 else lo, side))
        walls_[:] = _contiguous(kept, vouched)
    return upper, lower


def _pass_bounds(idx: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Where each pass of a wall (rows ``idx``, ascending, at most :data:`PASS_GAP` apart) starts and stops, as
    positions into ``idx``."""
    breaks = np.flatnonzero(np.diff(idx) > PASS_GAP) + 1
    return np.concatenate(([0], breaks)), np.concatenate((breaks, [idx.size]))


def _passes(idx: NDArray[np.int64], run: int = PASS_RUN) -> list[NDArray[np.int64]]:
    """The passes of a wall (rows ``idx``, ascending, at most :data:`PASS_GAP` apart) of ``run`` samples or more,
    as positions into ``idx``."""
    starts, stops = _pass_bounds(idx)
    return [np.arange(a, b) for a, b in zip(starts.tolist(), stops.tolist(), strict=True) if b - a >= run]


def _pass_count(idx: NDArray[np.int64], run: int = PASS_RUN) -> int:
    """How many passes of ``run`` samples or more a wall (rows ``idx``) has (:func:`_passes`)."""
    starts, stops = _pass_bounds(idx)
    return int(np.count_nonzero(stops - starts >= run))


def _about_line(x: Array, y: Array) -> Array:
    """``y`` about its least-squares straight line in ``x`` (``x`` not all equal): np.polyfit's line in closed form,
    without its overhead (a wall finder fits hundreds of them)."""
    dx, dy = x - np.mean(x), y - np.mean(y)
    return np.asarray(dy - (np.dot(dx, dy) / np.dot(dx, dx)) * dx)


def _about_parabola(x: Array, y: Array) -> Array:
    """``y`` about its least-squares parabola in ``x`` (``x`` not all equal): np.polyfit's, from the orthogonal
    polynomials 1, t, t^2 - ... of the centred ``x`` (three values of x or more; fewer fit exactly)."""
    if x.size < 3:
        return np.zeros_like(y)
    t = x - np.mean(x)
    square = t * t
    square -= np.mean(square)
    square -= (np.dot(square, t) / np.dot(t, t)) * t  # orthogonal to 1 and t
    out = y - np.mean(y)
    out -= (np.dot(out, t) / np.dot(t, t)) * t
    norm = np.dot(square, square)
    if norm > 0.0:  # two distinct speeds only: the line fits them exactly
        out -= (np.dot(out, square) / norm) * square
    return np.asarray(out)


def _detrended_passes(log: EnvelopeLog, idx: NDArray[np.int64]) -> list[tuple[NDArray[np.int64], Array]]:
    """Each pass of a wall (rows ``idx``) with the torque about its own straight line in time: the noise."""
    out = []
    for p in _passes(idx):
        rows, tau = idx[p].astype(float), log.torque[idx[p]]
        out.append((idx[p], _about_line(rows, tau)))
    return out


def _autocorrelation(
    log: EnvelopeLog, groups: Sequence[NDArray[np.int64]], fewest: int = FEWEST_PAIRS, pooled: bool = True
) -> float:
    """Lag-1 autocorrelation of the torque noise between consecutive samples within a wall, about the wall's
    straight line in speed, clipped to [0, 0.95]; 0 without walls of ``fewest`` consecutive pairs, as in a shuffled
    log. ``pooled``: over all pairs of all walls (walls already checked); else the median of the walls' own
    estimates, which a few walls that are passes of a slow command do not move (short walls bias it low)."""
    nums, dens = [], []
    for idx in groups:
        if idx.size < 3:
            continue
        w, tau = log.velocity[idx], log.torque[idx]
        d = _about_line(w, tau) if np.ptp(w) > 0 else tau - tau.mean()
        next_ = np.flatnonzero(np.diff(idx) == 1)
        den = float(np.sum(d[next_] ** 2 + d[next_ + 1] ** 2)) / 2
        if next_.size >= fewest and den > 0:
            nums.append(float(np.sum(d[next_] * d[next_ + 1])))
            dens.append(den)
    if not nums:
        return 0.0
    rho = sum(nums) / sum(dens) if pooled else float(np.median(np.array(nums) / np.array(dens)))
    return float(np.clip(rho, 0.0, RHO_MAX))


def _noise_scale(log: EnvelopeLog, groups: Sequence[NDArray[np.int64]]) -> float:
    """Typical torque noise at a limit [N m]: the median over walls of the spread of their samples, each pass about
    its own line in time (a shuffled log: the spread of the wall's torque about a line in speed)."""
    spreads = []
    for idx in groups:
        if idx.size < MIN_WALL:
            continue
        parts = _detrended_passes(log, idx)
        if parts:
            spreads.append(float(np.sqrt(np.mean(np.concatenate([d for _, d in parts]) ** 2))))
        else:
            w, tau = log.velocity[idx], log.torque[idx]
            spreads.append(float(np.std(_about_line(w, tau) if np.ptp(w) > 0 else tau)))
    return float(np.median(spreads)) if spreads else math.inf


def _agreeing_passes(idx: NDArray[np.int64], m: Array, rho: float, floor: float) -> NDArray[np.int64]:
    """The samples of a wall whose passes sit at one level: samples of a limit do, whichever pass brought the motor
    there; passes of a slow command that happen to top out close together do not. While a chi-square test of the
    passes' mean margins ``m`` against their common mean fails at :data:`LEVEL_ALPHA` (each mean's variance the
    within-pass variance / n x (1 + rho) / (1 - rho), AR(1) noise), the pass furthest off is dropped; differences
    under ``floor`` [N m] always agree. Returns the rows kept."""
    from scipy.special import chdtrc  # chi-square survival function

    parts = _passes(idx)
    keep = np.ones(idx.size, dtype=bool)
    while len(parts) >= 2:
        means = np.array([float(np.mean(m[p])) for p in parts])
        sizes = np.array([p.size for p in parts], dtype=float)
        within = np.concatenate([m[p] - np.mean(m[p]) for p in parts])
        var = max(float(np.sum(within**2)) / max(within.size - len(parts), 1), 1e-30) * (1 + rho) / (1 - rho)
        centre = float(np.sum(means * sizes) / np.sum(sizes))
        if np.max(np.abs(means - centre)) <= floor:
            break
        chi2 = float(np.sum((means - centre) ** 2 * sizes / var))
        if chdtrc(len(parts) - 1, chi2) >= LEVEL_ALPHA:
            break
        worst = int(np.argmax(np.abs(means - centre) * np.sqrt(sizes)))
        keep[parts[worst]] = False
        parts.pop(worst)
    return idx[keep]


def _passes_agree(idx: NDArray[np.int64], m: Array, w: Array, run: int = PASS_RUN) -> bool:
    """Whether a wall found with its drift removed is one: in a time-ordered log any single pass through a narrow
    bin is nearly straight, so it lines up with itself whatever the command did. Such a wall needs at least two
    passes of ``run`` samples or more (rows ``idx`` at most :data:`PASS_GAP` apart) whose margins ``m`` drift
    with speed ``w`` alike (slopes within 4 standard errors, or 20 %). Shuffled logs (no passes) pass."""
    fits = []
    for p in _passes(idx, run):
        if np.ptp(w[p]) > 0:
            coef, res, *_ = np.polyfit(w[p], m[p], 1, full=True)
            sigma = math.sqrt(float(res[0]) / max(p.size - 2, 1)) if res.size else 0.0
            fits.append((float(coef[0]), sigma / (float(np.std(w[p])) * math.sqrt(p.size))))
    if not fits:
        return True
    if len(fits) < 2:
        return False
    slopes = np.array([f[0] for f in fits])
    se = np.array([f[1] for f in fits])
    ref = float(np.average(slopes, weights=1 / np.maximum(se, 1e-12) ** 2))
    return bool(np.all(np.abs(slopes - ref) <= np.maximum(SLOPE_SIGMAS * se, SLOPE_SHARE * abs(ref))))


def _steep(speed: float, side: float, inputs: EnvelopeInputs) -> bool:
    """Whether an edge (``side`` +1 upper, -1 lower) may fall steeply at motor ``speed`` [rad/s]: the motoring edge
    past :data:`STEEP_MOTORING` of the spec's corner speed (a sagging or hot motor turns its corner sooner), the
    braking edge past :data:`STEEP_BRAKING` of the no-load speed. Elsewhere every effect keeps the edge flat, and a
    drift across a bin is passes of the command lining up, not a wall."""
    spec = inputs.spec
    motoring = side * speed > 0
    corner = max(spec.kv * (spec.bus_voltage - spec.resistance * spec.linear_torque_limit / spec.kt), 0.0)
    return abs(speed) >= (STEEP_MOTORING * corner if motoring else STEEP_BRAKING * spec.no_load_speed)


def _continuous(
    walls: list[NDArray[np.int64]], margin: Array, w: Array, tol: float, edge: tuple[Array, int] | None = None
) -> tuple[list[NDArray[np.int64]], set[int]]:
    """Drop the walls that are likely a command's peak: a smooth command topping out while the speed passes one bin
    (or dwells at a turning point) piles samples up like a wall, at an arbitrary torque. Such a wall is made of one
    pass (most of its samples at most :data:`PASS_GAP` rows apart). A one-pass wall counts only if its offset (mean
    margin against the model) is within ``tol`` [N m] of the model, or of the straight line through the nearest two
    walls seen in several passes within :data:`NEIGHBOURS` bins or :data:`NEIGHBOUR_SPAN` of the bins (on both
    sides, or two on one side), or if its torque follows the speed as the model's ``edge`` (values, side) does,
    where that is steep (:func:`_tracks_edge`). Returns the walls and the one-pass walls vouched for by such a line
    or by tracking (they need no run of neighbouring walls: in a protocol of speed holds the walls lie bins apart)."""
    walled = [b for b, i in enumerate(walls) if i.size]
    single = {b for b in walled if _one_pass(walls[b])}
    level = {b: float(np.mean(margin[walls[b]])) for b in walled}
    speed = {b: float(np.mean(w[walls[b]])) for b in walled}
    solid = [b for b in walled if b not in single]
    reach = max(NEIGHBOURS, math.ceil(NEIGHBOUR_SPAN * len(walls)))

    def on_line(b: int) -> bool:
        left = [k for k in solid if b - reach <= k < b][-2:]
        right = [k for k in solid if b < k <= b + reach][:2]
        if left and right:
            pair = [left[-1], right[0]]
        else:
            pair = left if len(left) == 2 else right
        if len(pair) < 2:
            return False
        k1, k2 = pair
        line = level[k1] + (level[k2] - level[k1]) * (speed[b] - speed[k1]) / (speed[k2] - speed[k1])
        return abs(level[b] - line) <= tol

    vouched = {b for b in single if on_line(b) or (edge is not None and _tracks_edge(walls[b], margin, *edge, w))}
    empty = np.array([], dtype=np.int64)
    keep = [i if i.size and (b not in single or b in vouched or abs(level[b]) <= tol) else empty for b, i in
            enumerate(walls)]  # fmt: skip
    return keep, vouched


def _tracks_edge(idx: NDArray[np.int64], margin: Array, edge: Array, side: int, w: Array) -> bool:
    """Whether the samples ``idx`` of a one-pass wall follow the speed as a limit does, not as a command's plateau.
    Where an edge is steep, a speed that wanders within the pass (a dyno's speed loop yielding to the torque) moves
    the torque at a limit along the edge, while a commanded plateau stays flat. Against the model's ``edge`` [N m]
    (``side`` +1 upper, -1 lower), the margins of a limit are flat in speed and those of a plateau fall with the
    edge's slope s: the margins' slope must be within half of s of zero, and :data:`TRACK_SIGMAS` standard errors
    (AR(1) noise) away from -s."""
    x, m = w[idx], margin[idx]
    if idx.size < MIN_WALL or np.ptp(x) <= 0:
        return False
    slope_edge = float(np.polyfit(x, edge[idx], 1)[0])
    coef = np.polyfit(x, m, 1)
    resid = m - np.polyval(coef, x)
    rho = float(np.clip(np.sum(resid[1:] * resid[:-1]) / max(float(np.sum(resid**2)), 1e-30), 0.0, RHO_MAX))
    se = float(np.std(resid)) / (float(np.std(x)) * math.sqrt(idx.size)) * math.sqrt((1 + rho) / (1 - rho))
    plateau = -side * slope_edge  # the margins' slope if the torque stayed put (margin = side (tau - edge))
    return bool(abs(coef[0]) < TRACK_SHARE * abs(plateau) and abs(coef[0] - plateau) > TRACK_SIGMAS * se)


def _one_pass(idx: NDArray[np.int64], share: float = ONE_PASS_SHARE) -> bool:
    """Whether ``share`` of the samples (row indices, ascending) form one pass (rows at most :data:`PASS_GAP` apart)."""
    starts, stops = _pass_bounds(idx)
    return bool(np.max(stops - starts) >= share * idx.size)


def _contiguous(
    walls: list[NDArray[np.int64]], vouched: Set[int] = frozenset(), run: int = NEIGHBOURING_WALLS
) -> list[NDArray[np.int64]]:
    """Keep the walls that belong to a run of at least ``run`` neighbouring bins with walls, that are seen in
    :data:`REPEATED` passes or more (a speed hold with several pulses: repeated evidence at one speed; their levels
    were checked to agree), or that are ``vouched`` for by the walls of such passes around them."""
    has = np.array([w.size > 0 for w in walls])
    keep = np.array([w.size > 0 and (b in vouched or _pass_count(w) >= REPEATED) for b, w in enumerate(walls)])
    start = 0
    for b in range(len(has) + 1):
        if b == len(has) or not has[b]:
            if b - start >= run:
                keep[start:b] = True
            start = b + 1
    empty = np.array([], dtype=np.int64)
    return [w if keep[b] else empty for b, w in enumerate(walls)]


def inputs_for(log: EnvelopeLog, inputs: EnvelopeInputs, idx: NDArray[np.int64]) -> EnvelopeInputs:
    temperature = log.temperature[idx] if log.temperature is not None else None
    return EnvelopeInputs(inputs.spec, temperature=temperature, curve=inputs.curve)
