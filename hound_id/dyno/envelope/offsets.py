"""Edge offsets: how far the samples at the limit sit from a model's edges, and where a log leaves the region.

**Edge offsets.** For a model (the spec sheet plus effects with parameters), a bin's edge
offset is the mean margin of its cluster against that model [N m], with its standard error
(widened by sqrt((1 + rho)/(1 - rho)) for the lag-1 autocorrelation rho of consecutive samples).
The *envelope error* is the RMS of the offsets over all wall bins, upper and lower; the *noise
level* is the RMS of their standard errors. A bin whose offset is below -3 SE falls short of
the model; above +3 SE the log spills over it. :func:`verdict` says whether the model explains
the log, and flags bins off it and an inflated noise level.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen
from hound_id.dyno.envelope.walls import Walls, inputs_for
from hound_id.dyno.logs import EnvelopeLog
from hound_id.mor.envelope import EnvelopeInputs, edge, envelope

Array = NDArray[np.float64]

#: A comparison needs this many speed bins at the limit (an F-test on fewer has no degrees of freedom left), and so does
#: looking for isolated bins among them. Calibrated on
#: test_compare::test_a_log_that_never_reaches_its_limits_is_refused.
MIN_BINS = 3
#: A single bin this many sample noises off the final model, between bins that fit it, is a chance wall. Calibrated on
#: test_compare::test_a_jump_at_the_end_of_an_edge_is_isolated_but_a_departure_is_not.
ISOLATED = 5.0
#: ... when its neighbours lie within FITS_SIGMAS standard errors of the model (3 SE: 99.7 % of Gaussian noise); an end
#: bin also jumps from its neighbour by more than twice the back-EMF slope times their speed gap plus JUMP_SIGMAS
#: standard errors. Calibrated on test_compare::test_a_jump_at_the_end_of_an_edge_is_isolated_but_a_departure_is_not.
FITS_SIGMAS = 3.0
JUMP_SIGMAS = 5.0
#: A sample is past an edge when it passes it by more than PAST_SIGMAS torque noises of one sample at the limit and
#: PAST_FLOOR of the torque limit. Calibrated on test_compare::test_a_log_past_the_region_is_measured_and_located.
PAST_SIGMAS = 4.0
PAST_FLOOR = 0.005


@dataclass(frozen=True)
class Offsets:
    """Edge offsets of the wall bins against one model [N m]."""

    speeds: Array
    """Speed of each wall bin (its samples' mean) [rad/s]."""
    side: NDArray[np.int8]
    """+1 upper edge, -1 lower edge."""
    offset: Array
    """Mean margin of the bin's wall samples against the model (positive: past the model) [N m]."""
    se: Array
    """Standard error of the offset [N m]."""
    spread: Array
    """Standard deviation of the bin's wall margins: the torque noise at the limit [N m]."""

    @property
    def sample_noise(self) -> float:
        """Typical torque noise of one sample at the limit [N m] (median over the bins)."""
        return float(np.median(self.spread)) if self.spread.size else 0.0

    @property
    def rmse(self) -> float:
        return float(np.sqrt(np.mean(self.offset**2)))

    @property
    def noise(self) -> float:
        return float(np.sqrt(np.mean(self.se**2)))

    @property
    def sse(self) -> float:
        return float(np.sum(self.offset**2))


@dataclass(frozen=True)
class AtLimit:
    """The samples of a log's walls, gathered once for the many models a fit evaluates on them (:func:`at_limit`):
    the upper walls' samples by bin, then the lower ones'."""

    walls: Walls
    spec_limit: float
    """The torque limit [N m] (a bin without a finite edge is this far off)."""
    velocity: Array
    """Motor speed of each sample [rad/s]."""
    torque: Array
    """Torque of each sample [N m]."""
    sample_side: NDArray[np.int8]
    """+1 for a sample at the upper limit, -1 at the lower one."""
    inputs: EnvelopeInputs
    """The samples' inputs (their temperatures)."""
    starts: NDArray[np.int64]
    """Where each wall's samples start (they are consecutive)."""
    sizes: NDArray[np.int64]
    """Samples per wall."""
    side: NDArray[np.int8]
    """+1 for an upper wall, -1 for a lower one."""
    speeds: Array
    """Mean speed of each wall's samples [rad/s]."""

    def offsets(self, model: Mapping[str, float]) -> Offsets:
        """Edge offsets of every wall bin against ``model`` (effect -> parameter)."""
        if not self.sizes.size:
            return Offsets(np.array([]), np.array([], dtype=np.int8), np.array([]), np.array([]), np.array([]))
        # each sample against its own edge: positive margins lie past the model's
        m = self.torque - edge(self.velocity, self.sample_side, model, self.inputs)
        m *= self.sample_side
        sizes, starts = self.sizes, self.starts
        finite = np.isfinite(m)
        if finite.all():  # the usual case: no bin without an edge
            bad = np.zeros(sizes.size, dtype=bool)
        else:
            bad = np.logical_or.reduceat(~finite, starts)
            m = np.where(finite, m, 0.0)
        # each wall's samples are consecutive: sums by wall are sums over those runs
        mean = np.add.reduceat(m, starts) / sizes
        about = np.repeat(mean, sizes)
        np.subtract(m, about, out=about)
        about *= about
        spread = np.sqrt(np.maximum(np.add.reduceat(about, starts) / sizes, 0.0))
        off = np.where(bad, -self.spec_limit, mean)
        # consecutive samples of a trajectory log share their noise: n (1 - rho) / (1 + rho) independent ones (AR(1))
        se = spread / np.sqrt(sizes) * math.sqrt((1 + self.walls.rho) / (1 - self.walls.rho))
        return Offsets(self.speeds.copy(), self.side.copy(), off, se, spread)


def at_limit(log: EnvelopeLog, walls: Walls, inputs: EnvelopeInputs) -> AtLimit:
    """The samples of ``walls`` (found on ``log``), gathered for :meth:`AtLimit.offsets`."""
    groups = [(s, i) for s, side in ((1, walls.upper), (-1, walls.lower)) for i in side if i.size]
    sizes = np.array([i.size for _, i in groups], dtype=np.int64)
    rows = np.concatenate([i for _, i in groups]) if groups else np.array([], dtype=np.int64)
    velocity = log.velocity[rows]
    return AtLimit(
        walls=walls,
        spec_limit=inputs.spec.linear_torque_limit,
        velocity=frozen(velocity),
        torque=frozen(log.torque[rows]),
        sample_side=frozen(np.repeat([s for s, _ in groups], sizes), dtype=np.int8),
        inputs=inputs_for(log, inputs, rows),
        starts=frozen(np.cumsum(sizes) - sizes, dtype=np.int64),
        sizes=frozen(sizes, dtype=np.int64),
        side=frozen([s for s, _ in groups], dtype=np.int8),
        speeds=frozen(np.add.reduceat(velocity, np.cumsum(sizes) - sizes) / sizes if groups else []),
    )


def offsets(log: EnvelopeLog, walls: Walls, model: Mapping[str, float], inputs: EnvelopeInputs) -> Offsets:
    """Edge offsets of every wall bin against ``model`` (effect -> parameter)."""
    return at_limit(log, walls, inputs).offsets(model)


def past_edges(
    log: EnvelopeLog, inputs: EnvelopeInputs, noise: float, model: Mapping[str, float] | None = None
) -> tuple[Array, float, NDArray[np.bool_]]:
    """(how far each sample passes the edges of ``model`` (default the spec sheet) [N m], the threshold, the
    samples past it)."""
    lo, hi = envelope(log.velocity, dict(model or {}), inputs_for(log, inputs, np.arange(log.n)))
    thr = max(PAST_SIGMAS * noise, PAST_FLOOR * inputs.spec.linear_torque_limit)
    excess = np.maximum(log.torque - hi, lo - log.torque)
    return excess, thr, np.asarray(np.isfinite(excess) & (excess > thr))


def outside_mask(log: EnvelopeLog, inputs: EnvelopeInputs, noise: float) -> NDArray[np.bool_]:
    """Samples past the spec sheet's region by more than the threshold of :func:`outside_stats`."""
    return past_edges(log, inputs, noise)[2]


@dataclass(frozen=True)
class OutsideStats:
    """Where a log leaves a region (:func:`outside_stats`)."""

    fraction: float
    """Share of the samples past the edges [0-1]."""
    samples: int
    """How many samples."""
    threshold: float
    """How far past an edge a sample must be to count [N m]."""
    max_excess: float
    """The furthest past [N m] (0 when none)."""
    p95_excess: float
    """95th percentile of how far past [N m] (0 when none)."""
    by_quadrant: Mapping[str, int]
    """Samples past the edges per quadrant (I, II, III, IV)."""
    speed_range: tuple[float, float] | None
    """Smallest and largest |motor speed| of those samples [rad/s] (None when none)."""

    def to_dict(self) -> dict[str, Any]:
        """The ``outside`` block of the ``hound-id/mor-compare/2`` JSON."""
        return {
            "fraction": self.fraction,
            "samples": self.samples,
            "threshold": self.threshold,
            "max_excess": self.max_excess,
            "p95_excess": self.p95_excess,
            "by_quadrant": dict(self.by_quadrant),
            "speed_range": list(self.speed_range) if self.speed_range is not None else None,
        }


@dataclass(frozen=True)
class IsolatedBin:
    """A single bin left out as a chance wall (:func:`isolated_bins`)."""

    speed: float
    """Its speed [rad/s]."""
    edge: str
    """``upper`` or ``lower``."""
    offset: float
    """Its offset against the final model [N m]."""
    se: float
    """The offset's standard error [N m]."""

    def to_dict(self) -> dict[str, Any]:
        return {"speed": self.speed, "edge": self.edge, "offset": self.offset, "se": self.se}


def outside_stats(log: EnvelopeLog, inputs: EnvelopeInputs, noise: float) -> OutsideStats:
    """Where the log leaves the spec sheet's region: share of samples, how far, which quadrant and speeds.

    A sample is outside when it passes an edge by more than :data:`PAST_SIGMAS` x the torque noise of one sample
    at the limit (and :data:`PAST_FLOOR` of the torque limit). Quadrants: I motoring forward (tau > 0, omega > 0),
    II braking (tau > 0, omega < 0), III motoring backward, IV braking (tau < 0, omega > 0).
    """
    excess, thr, out = past_edges(log, inputs, noise)
    t, w = log.torque[out], log.velocity[out]
    quadrant = np.where(t >= 0, np.where(w >= 0, "I", "II"), np.where(w < 0, "III", "IV"))
    return OutsideStats(
        fraction=float(out.mean()),
        samples=int(out.sum()),
        threshold=thr,
        max_excess=float(excess[out].max()) if out.any() else 0.0,
        p95_excess=float(np.quantile(excess[out], 0.95)) if out.any() else 0.0,
        by_quadrant=MappingProxyType({q: int(np.sum(quadrant == q)) for q in ("I", "II", "III", "IV")}),
        speed_range=(float(np.abs(w).min()), float(np.abs(w).max())) if out.any() else None,
    )


@dataclass(frozen=True)
class Coverage:
    """Motor speeds [rad/s] the bins at the limit span, per edge (None: no bin on that edge)."""

    upper: tuple[float, float] | None
    lower: tuple[float, float] | None

    def to_dict(self) -> dict[str, list[float] | None]:
        return {"upper": list(self.upper) if self.upper else None, "lower": list(self.lower) if self.lower else None}


def coverage(off: Offsets) -> Coverage:
    """Motor speeds [rad/s] the bins at the limit span, per edge: where the data say anything."""
    spans = []
    for side in (1, -1):
        w = off.speeds[off.side == side]
        spans.append((float(w.min()), float(w.max())) if w.size else None)
    return Coverage(*spans)


def isolated_bins(walls: Walls, off: Offsets, slope: float) -> tuple[Walls, list[IsolatedBin]]:
    """Without a command channel, leave out single bins far off the final model whose neighbours agree with it:
    passes that happened to line up into a wall (a real departure spans a range of speeds). A bin is isolated when
    its offset exceeds :data:`ISOLATED` x the torque noise of one sample at the limit and the nearest bin on each
    side of the same edge lies within 3 standard errors of the model. The last bin of an edge (effects show at the
    ends of the speed range) is isolated only if it also jumps from its neighbour by more than an edge can change
    between their speeds, twice the back-EMF slope ``slope`` [N m s/rad] (plus 5 standard errors)."""
    if walls.method != "wall" or off.offset.size < MIN_BINS:
        return walls, []
    noise = off.sample_noise
    sides = {1: list(walls.upper), -1: list(walls.lower)}
    bins = {s: [b for b, i in enumerate(sides[s]) if i.size] for s in sides}  # offsets run over these, by edge
    position = {s: 0 for s in sides}
    found, drop = [], []
    for k in range(off.offset.size):  # offsets run over upper bins, then lower ones, each by speed
        s = int(off.side[k])
        b = bins[s][position[s]]
        position[s] += 1
        if abs(off.offset[k]) <= ISOLATED * noise:
            continue
        near = [j for j in range(off.offset.size) if off.side[j] == s and j != k]
        left, right = [j for j in near if j < k], [j for j in near if j > k]
        if left and right:
            isolated = all(abs(off.offset[j]) <= FITS_SIGMAS * off.se[j] for j in (left[-1], right[0]))
        elif left or right:  # an end bin: only a jump no edge can make between neighbouring speeds
            j = left[-1] if left else right[0]
            jump = abs(off.offset[k] - off.offset[j])
            bound = 2 * slope * abs(off.speeds[k] - off.speeds[j]) + JUMP_SIGMAS * math.hypot(off.se[k], off.se[j])
            isolated = abs(off.offset[j]) <= FITS_SIGMAS * off.se[j] and jump > bound
        else:
            isolated = False
        if isolated:
            drop.append((s, b))
            edge_name = "upper" if s == 1 else "lower"
            found.append(IsolatedBin(float(off.speeds[k]), edge_name, float(off.offset[k]), float(off.se[k])))
    empty = np.array([], dtype=np.int64)
    for s, b in drop:
        sides[s][b] = empty
    return replace(walls, upper=tuple(sides[1]), lower=tuple(sides[-1])), found
