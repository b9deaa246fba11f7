"""``hound-id mor --compare``: a measured torque-speed log against the operating region, and what is missing.

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

**Edge offsets.** For a model (the spec sheet plus effects with parameters), a bin's edge
offset is the mean margin of its cluster against that model [N m], with its standard error
(widened by sqrt((1 + rho)/(1 - rho)) for the lag-1 autocorrelation rho of consecutive samples).
The *envelope error* is the RMS of the offsets over all wall bins, upper and lower; the *noise
level* is the RMS of their standard errors. A bin whose offset is below -3 SE falls short of
the model; above +3 SE the log spills over it. :func:`verdict` says whether the model explains
the log, and flags bins off it and an inflated noise level.

**What is missing.** Each candidate effect of :mod:`hound_id.mor.envelope` is fitted on top of
the model (bounded scalar search of its parameter, the model's parameters refitted with it) and
ranked by the share of the envelope error's sum of squares it explains. It is significant when
the partial F statistic (SSE0 - SSE1) / (SSE1 / (bins - 1)) beats F(1, bins - 1) at 1 % divided
by the number of candidates (Bonferroni), and when the envelope error falls by at least the
noise level (an effect too small to matter is not suggested). ``--add`` and ``--auto`` grow the
model as in ``fit-current``; :func:`unneeded` names the effects the final model can drop.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence, Set
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

from hound_id.errors import DynoDataError, SpecError
from hound_id.mor.envelope import EFFECTS, EnvelopeInputs, edge, effect_names, envelope
from hound_id.mor.spec import MotorSpec

Array = NDArray[np.float64]
SCHEMA = "hound-id/mor-compare/2"

#: Channels of a comparison log; the first two are required.
CHANNELS = ("torque", "velocity", "torque_cmd", "current", "temperature", "bus_voltage")
#: With a command channel: the lag searched [rows], a floor (robust noise levels) under the shortfall a sample at the
#: limit must pass, the rows it must last, and the robust spreads about a cluster's median beyond which a sample is
#: left out of it.
LAG_MAX = 100
CMD_SIGMAS = 5.0
PERSIST = 3
TRIM = 5.0
#: A bin has a wall when (q98 - q90) < WALL (q98 - q50) of its margins.
WALL = 0.1
#: ... and its top (q98 - q90) narrower than this share of the torque limit: piled up within the noise.
WALL_WIDTH = 0.03
#: ... and approached: the bin's margins span at least this share of the torque limit below it (a motor resting while
#: the speed ramps piles up too, at one torque).
APPROACH = 0.2
#: Or a pile: at least PILE of the bin's margins within WALL_WIDTH of its top (q98), and at most WALL_CONTRAST as many
#: in the band of that width below; such a wall is its margins within BAND robust spreads of their median.
PILE = 0.2
WALL_CONTRAST = 0.2
BAND = 4.0
#: Speed bins across the logged range, and the fewest samples a bin (and a wall) needs.
BINS = 32
MAX_BINS = 96
#: A wall's level may depart from the line through its neighbours by this share of the torque limit ...
STEP = 0.05
#: ... looking this many bins either side for them.
NEIGHBOURS = 3
#: ... or this share of all bins, whichever is more.
NEIGHBOUR_SPAN = 0.1
#: A one-pass wall whose margins' slope in speed is this many standard errors from a plateau's tracks the edge.
TRACK_SIGMAS = 5.0
#: A single bin this many sample noises off the final model, between bins that fit it, is a chance wall.
ISOLATED = 5.0
#: Passes of a wall whose levels differ at this significance are not one wall, unless they differ by less than
#: this share of the torque limit.
LEVEL_ALPHA = 1e-4
LEVEL_FLOOR = 0.005
#: A wall's samples spread at most this many times the typical noise at a limit (a pass of a moving command spreads
#: more).
FLAT = 3.0
#: Passes (at one level) that make a wall on their own, without walls in the bins beside it.
REPEATED = 2
#: Rows of a log apart beyond which two samples of a wall belong to different passes through its speed bin.
PASS_GAP = 25
#: Speeds [share of the spec's corner / no-load speed] past which a motoring / braking edge may fall steeply.
STEEP_MOTORING = 0.6
STEEP_BRAKING = 0.9
MIN_SAMPLES = 40
MIN_WALL = 8
#: Family-wise false-alarm rate of the significance tests.
ALPHA = 0.01
#: The model explains the envelope when its error is at most this many noise levels ...
EXPLAINED = 3.0
#: ... and (for the spec sheet itself) at most this share of the samples lies past its edges.
OUTSIDE_OK = 0.005
#: A candidate is refuted when more than OUTSIDE_OK of the samples pass its edges by this share of the torque limit.
REFUTE = 0.05
#: A fitted pack resistance this many standard errors (and a third of itself) above the one the logged bus voltage
#: shows is contradicted by it.
EVIDENCE_SIGMAS = 5.0
#: A bin off the final model by more than OFF_SIGMAS standard errors and OFF_FLOOR of the torque limit is not explained;
#: a noise level above INFLATED x that of the bins whose samples spread less than WIDE x the typical is flagged.
OFF_SIGMAS = 5.0
OFF_FLOOR = 0.01
INFLATED = 1.5
WIDE = 3.0
#: A log's 99th-percentile torque or speed past this multiple of the torque limit or overspeed is a unit mistake.
IMPLAUSIBLE = 2.0
#: Accuracy of the polyline boundary, as a share of the torque limit.
POLYLINE_TOLERANCE = 0.002


@dataclass(frozen=True)
class EnvelopeLog:
    """A torque-speed log on the motor side, SI."""

    torque: Array
    velocity: Array
    torque_cmd: Array | None = None
    current: Array | None = None
    temperature: Array | None = None
    """Winding temperature [degC]."""
    bus_voltage: Array | None = None
    source: str = "log"
    side: str = "motor"
    """``motor``, or how joint-side data was mapped (joint, transmission)."""
    dropped: int = 0
    """Rows dropped for a non-finite value in any channel used."""
    ignored: tuple[str, ...] = ()
    """Optional channels left out because they hold no finite value."""

    @property
    def n(self) -> int:
        return int(self.torque.size)


def load_envelope_log(
    path: str | Path,
    columns: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    robot: Any = None,
    joint: str | None = None,
) -> EnvelopeLog:
    """Read a CSV/Parquet torque-speed log (motor side, or joint side mapped through ``robot``'s
    transmission of ``joint``). Columns are named after :data:`CHANNELS` (``[unit]`` suffixes
    converted), or mapped with ``columns``; ``units`` overrides the suffixes.

    For a coupled joint the log needs ``<joint>_torque`` and ``<joint>_velocity`` for every joint
    of its transmission group; the result is the motor paired with ``joint``.
    """
    from hound_id.dyno.log import _convert, _numeric, _split_header
    from hound_id.tables import read_table

    source = str(path)
    frame = read_table(path)
    names = [str(c) for c in frame.columns]
    frame = frame.set_axis(names, axis=1)
    by_base = {_split_header(n)[0]: n for n in names}
    columns, units = dict(columns or {}), dict(units or {})
    for key in columns:
        if key not in CHANNELS and not key.endswith(("_torque", "_velocity")):
            raise DynoDataError(f"--columns: unknown channel '{key}'; channels are {', '.join(CHANNELS)}")

    def channel(name: str, required: bool) -> Array | None:
        column = columns.get(name) or by_base.get(name)
        if column is not None and column not in frame.columns:
            column = by_base.get(column)  # a mapped name without its [unit] suffix
            if column is None:
                raise DynoDataError(f"{source}: --columns {name}={columns[name]}: no such column; columns are {names}")
        if column is None:
            if required:
                raise DynoDataError(
                    f"{source}: column '{name}' missing; a comparison log needs torque and velocity (optionally "
                    f"torque_cmd, current, temperature, bus_voltage); the file has {names}; map with --columns"
                )
            return None
        values, _, bad = _numeric(frame, column, name, source)
        if bad is not None:
            count, cell, row = bad
            raise DynoDataError(f"{source}: column '{column}' row {row} is {cell!r}, expected a number")
        unit = units.get(name) or _split_header(column)[1]
        kind = "torque" if name.endswith("torque") or name == "torque_cmd" else name
        kind = "velocity" if name.endswith("_velocity") else kind
        if unit:
            values, _ = _convert(values, unit, "header or --units", kind, column, source)
        return np.asarray(values, dtype=float)

    if robot is None or joint is None:
        if (robot is None) != (joint is None):
            raise SpecError("--compare: --robot and --joint go together (joint-side logs)")
        torque, velocity = channel("torque", True), channel("velocity", True)
        side = "motor"
        assert torque is not None and velocity is not None
    else:
        tx = robot.transmission_of(joint)
        if not tx.coupled:
            tau_j, qd_j = channel("torque", True), channel("velocity", True)
            assert tau_j is not None and qd_j is not None
            torque, velocity = tau_j * float(tx.A[0, 0]), qd_j / float(tx.A[0, 0])
        else:
            taus = [channel(f"{j}_torque", True) for j in tx.joints]
            qds = [channel(f"{j}_velocity", True) for j in tx.joints]
            k = tx.joints.index(joint)
            tau_m = np.column_stack([np.asarray(t) for t in taus]) @ tx.A  # tau_m = A^T tau_j, row form
            omega_m = np.column_stack([np.asarray(q) for q in qds]) @ tx.A_inv.T
            torque, velocity = tau_m[:, k], omega_m[:, k]
        side = f"joint {joint} through the {tx.kind} transmission of {', '.join(tx.joints)}"
    rest = {name: channel(name, False) for name in CHANNELS[2:]}
    if robot is not None and joint is not None and rest["torque_cmd"] is not None:
        tx = robot.transmission_of(joint)
        if tx.coupled:  # a joint-side command cannot be mapped without the other joints' commands
            rest["torque_cmd"] = None
        else:
            rest["torque_cmd"] = rest["torque_cmd"] * float(tx.A[0, 0])
    ignored = tuple(k for k, v in rest.items() if v is not None and not np.isfinite(v).any())
    rest = {k: (None if k in ignored else v) for k, v in rest.items()}  # an empty optional channel is no channel
    data = {"torque": torque, "velocity": velocity, **rest}
    good = np.ones(torque.size, dtype=bool)
    for values in data.values():
        if values is not None:
            good &= np.isfinite(values)
    if good.sum() < 10 * MIN_SAMPLES:
        gaps = {k: int((~np.isfinite(v)).sum()) for k, v in data.items() if v is not None}
        worst = max(gaps, key=lambda k: gaps[k])
        raise DynoDataError(
            f"{source}: {int(good.sum())} usable rows; an envelope comparison needs at least {10 * MIN_SAMPLES} "
            f"(rows with NaN or inf are dropped; most in {worst}: {gaps[worst]})"
        )
    picked = {k: (v[good] if v is not None else None) for k, v in data.items()}
    return EnvelopeLog(source=source, side=side, dropped=int((~good).sum()), ignored=ignored, **picked)  # type: ignore[arg-type]


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
    lo_s, hi_s = envelope(log.velocity, {}, _inputs_for(log, inputs, np.arange(n)))
    lo_s, hi_s = np.nan_to_num(lo_s, nan=0.0), np.nan_to_num(hi_s, nan=0.0)

    def inside(c: Array) -> NDArray[np.bool_]:
        return np.asarray((c < 0.5 * hi_s) & (c > 0.5 * lo_s))

    def misfit(lag: float) -> float:
        c = _lagged(cmd, lag)
        keep = inside(c)
        return float(np.mean(np.abs(tau[keep] - c[keep]))) if keep.sum() >= MIN_SAMPLES else math.inf

    ordered = time_ordered(tau)
    lag = 0.0
    if ordered:  # a table of operating points (rows in no time order) has no lag to find
        scores = [misfit(float(d)) for d in range(min(LAG_MAX, n // 10) + 1)]
        best = int(np.argmin(scores))
        fine = np.arange(max(best - 1, 0), best + 1.0001, 0.1)
        lag = float(fine[int(np.argmin([misfit(float(d)) for d in fine]))])
    c = _lagged(cmd, lag)
    keep = inside(c)
    if keep.sum() < MIN_SAMPLES:
        raise DynoDataError(
            f"{log.source}: torque_cmd is inside the region in only {int(keep.sum())} rows; the command cannot be "
            "compared with the torque: is it the command of this motor, in N m (map with --columns, --units)?"
        )
    gain, bias = np.polyfit(c[keep], tau[keep], 1)
    if not 0.5 <= gain <= 2.0:
        raise DynoDataError(
            f"{log.source}: the measured torque follows torque_cmd with a gain of {gain:.3g} inside the region, "
            "expected about 1: is torque_cmd in another unit (a current, N*cm)? Fix its unit with --units "
            "torque_cmd=..., or leave the column out"
        )
    expected = gain * c + bias
    short = expected - tau  # positive: the torque falls short of the command (upper limit)
    noise = _robust(short[keep])[1]
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

    def runs(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
        edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
        out = np.zeros(n, dtype=bool)
        for start, stop in zip(edges[::2], edges[1::2], strict=True):
            if stop - start < persist:
                continue
            if not ordered:
                out[start:stop] = True
                continue
            settled = float(np.median(tau[start + (stop - start) // 2 : stop]))
            off = np.abs(tau[start:stop] - settled) > 3 * noise
            first = int(np.argmin(off)) if not off.all() else stop - start
            first = min(first, (stop - start) // 2)
            out[start + first : stop] = True
        return out

    return CommandLimits(
        upper=runs(short > thr_up),
        lower=runs(-short > thr_lo),
        lag=lag,
        gain=float(gain),
        bias=float(bias),
        threshold=(thr_up, thr_lo),
        noise=noise,
        persist=persist,
    )


def time_ordered(x: Array) -> bool:
    """Whether consecutive rows are samples of one signal in time (steps between rows much smaller than its spread),
    not a table of operating points or a shuffled log."""
    if x.size < 3:
        return False
    q25, q75 = np.quantile(x, [0.25, 0.75])
    return bool(np.median(np.abs(np.diff(x))) < 0.1 * (q75 - q25))


def _trimmed(members: NDArray[np.int64], margin_of: Any, width: float) -> NDArray[np.int64]:
    """A cluster of samples at the limit without its outliers: margins more than :data:`TRIM` robust spreads from the
    cluster's median (a sample flagged by a passing disturbance) are left out. ``width`` [N m] floors the spread."""
    if members.size < 3:
        return members
    m = margin_of(members)
    centre, spread = _robust(m)
    return members[np.abs(m - centre) <= TRIM * max(spread, 1e-3 * width)]


def _robust(x: Array) -> tuple[float, float]:
    """(median, 1.4826 MAD): the centre and the standard deviation of Gaussian noise, unmoved by a few outliers."""
    centre = float(np.median(x))
    return centre, 1.4826 * float(np.median(np.abs(x - centre)))


def _wall(members: NDArray[np.int64], m: Array, width: float) -> NDArray[np.int64]:
    """The members whose margins form a wall at the top of the bin (module docstring), or none. The top
    must also be narrower than ``width`` [N m] in absolute terms: piled up within the sensor noise."""
    q10, q50, q90, q98 = np.quantile(m, [0.1, 0.5, 0.9, 0.98])
    if (q98 - q10) <= APPROACH * width / WALL_WIDTH:
        return np.array([], dtype=np.int64)
    if (q98 - q90) < WALL * (q98 - q50) and (q98 - q90) < width:
        return members[m >= q90 - 2 * (q98 - q90)]
    top = m >= q98 - width
    below = (m >= q98 - 2 * width) & ~top
    if top.mean() >= PILE and below.sum() <= WALL_CONTRAST * top.sum():
        # a wall that holds much of the bin (a speed hold, pushed for long): centred on its median, as wide as its
        # noise either side
        band = top
        for _ in range(2):
            centre, spread = _robust(m[band])
            band = np.abs(m - centre) <= BAND * max(spread, 1e-3 * width)
        return members[band]
    return np.array([], dtype=np.int64)


def bin_count(n: int) -> int:
    """Speed bins for a log of ``n`` samples: :data:`BINS`, more for long logs (about 250 samples a bin, at most
    :data:`MAX_BINS`), so an edge that falls steeply with speed stays nearly straight across one bin."""
    return int(np.clip(n // 250, BINS, MAX_BINS))


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
    lo, hi = envelope(w, dict(model or {}), _inputs_for(log, inputs, np.arange(log.n)))
    upper, lower = [], []
    drifting: set[tuple[int, int]] = set()  # (side, bin) of walls found with their drift taken out
    if commanded is None and log.torque_cmd is not None:
        commanded = command_limits(log, inputs)
    width = WALL_WIDTH * inputs.spec.torque_limit
    for b in range(bins):
        members = np.flatnonzero(index == b)
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
                    top = m >= np.quantile(m, 0.8)
                    if top.sum() >= 5 and np.ptp(w[cand[top]]) > 0:
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
        tol = STEP * inputs.spec.torque_limit
        floor = LEVEL_FLOOR * inputs.spec.torque_limit
        empty = np.array([], dtype=np.int64)
        margins = {1: log.torque - hi, -1: lo - log.torque}
        noise = _noise_scale(log, upper + lower)
        for side, walls_ in ((1, upper), (-1, lower)):
            margin = margins[side]
            for b, i in enumerate(walls_):
                if not i.size:
                    continue
                m = margin[i]
                # one pass of a moving command spreads more than the noise; passes of a limit sit on one curve in
                # speed (drifting against a model that is wrong there), passes of commands at several levels
                line = m - np.polyval(np.polyfit(w[i], m, 2), w[i]) if np.ptp(w[i]) > 0 else m
                i = _agreeing_passes(i, line, rho, floor)
                drifts = (side, b) in drifting  # its passes were checked to drift alike (_passes_agree)
                if i.size < MIN_WALL or (not drifts and _one_pass(i) and float(np.std(margin[i])) > FLAT * noise):
                    i = empty
                walls_[b] = i
            kept, vouched = _continuous(walls_, margin, w, tol, (hi if side > 0 else lo, side))
            walls_[:] = _contiguous(kept, vouched)
        rho = _autocorrelation(log, upper + lower)
    method = "command" if log.torque_cmd is not None else "wall"
    return Walls(centres, tuple(upper), tuple(lower), method, rho, commanded)


def _passes(idx: NDArray[np.int64], run: int = 5) -> list[NDArray[np.int64]]:
    """The passes of a wall (rows ``idx``, ascending, at most :data:`PASS_GAP` apart) of ``run`` samples or more,
    as positions into ``idx``."""
    breaks = np.flatnonzero(np.diff(idx) > PASS_GAP) + 1
    return [p for p in np.split(np.arange(idx.size), breaks) if p.size >= run]


def _detrended_passes(log: EnvelopeLog, idx: NDArray[np.int64]) -> list[tuple[NDArray[np.int64], Array]]:
    """Each pass of a wall (rows ``idx``) with the torque about its own straight line in time: the noise."""
    out = []
    for p in _passes(idx):
        rows, tau = idx[p].astype(float), log.torque[idx[p]]
        out.append((idx[p], tau - np.polyval(np.polyfit(rows, tau, 1), rows)))
    return out


def _autocorrelation(
    log: EnvelopeLog, groups: Sequence[NDArray[np.int64]], fewest: int = 10, pooled: bool = True
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
        d = tau - np.polyval(np.polyfit(w, tau, 1), w) if np.ptp(w) > 0 else tau - tau.mean()
        next_ = np.flatnonzero(np.diff(idx) == 1)
        den = float(np.sum(d[next_] ** 2 + d[next_ + 1] ** 2)) / 2
        if next_.size >= fewest and den > 0:
            nums.append(float(np.sum(d[next_] * d[next_ + 1])))
            dens.append(den)
    if not nums:
        return 0.0
    rho = sum(nums) / sum(dens) if pooled else float(np.median(np.array(nums) / np.array(dens)))
    return float(np.clip(rho, 0.0, 0.95))


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
            fit = np.polyval(np.polyfit(w, tau, 1), w) if np.ptp(w) > 0 else np.mean(tau)
            spreads.append(float(np.std(tau - fit)))
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


def _passes_agree(idx: NDArray[np.int64], m: Array, w: Array, run: int = 5) -> bool:
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
    return bool(np.all(np.abs(slopes - ref) <= np.maximum(4 * se, 0.2 * abs(ref))))


def _steep(speed: float, side: float, inputs: EnvelopeInputs) -> bool:
    """Whether an edge (``side`` +1 upper, -1 lower) may fall steeply at motor ``speed`` [rad/s]: the motoring edge
    past :data:`STEEP_MOTORING` of the spec's corner speed (a sagging or hot motor turns its corner sooner), the
    braking edge past :data:`STEEP_BRAKING` of the no-load speed. Elsewhere every effect keeps the edge flat, and a
    drift across a bin is passes of the command lining up, not a wall."""
    spec = inputs.spec
    motoring = side * speed > 0
    corner = max(spec.kv * (spec.bus_voltage - spec.resistance * spec.torque_limit / spec.kt), 0.0)
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
    rho = float(np.clip(np.sum(resid[1:] * resid[:-1]) / max(float(np.sum(resid**2)), 1e-30), 0.0, 0.95))
    se = float(np.std(resid)) / (float(np.std(x)) * math.sqrt(idx.size)) * math.sqrt((1 + rho) / (1 - rho))
    plateau = -side * slope_edge  # the margins' slope if the torque stayed put (margin = side (tau - edge))
    return bool(abs(coef[0]) < 0.5 * abs(plateau) and abs(coef[0] - plateau) > TRACK_SIGMAS * se)


def _one_pass(idx: NDArray[np.int64], share: float = 0.75) -> bool:
    """Whether ``share`` of the samples (row indices, ascending) form one pass (rows at most :data:`PASS_GAP` apart)."""
    return bool(max(p.size for p in _passes(idx, run=1)) >= share * idx.size)


def _contiguous(
    walls: list[NDArray[np.int64]], vouched: Set[int] = frozenset(), run: int = 3
) -> list[NDArray[np.int64]]:
    """Keep the walls that belong to a run of at least ``run`` neighbouring bins with walls, that are seen in
    :data:`REPEATED` passes or more (a speed hold with several pulses: repeated evidence at one speed; their levels
    were checked to agree), or that are ``vouched`` for by the walls of such passes around them."""
    has = np.array([w.size > 0 for w in walls])
    keep = np.array([w.size > 0 and (b in vouched or len(_passes(w)) >= REPEATED) for b, w in enumerate(walls)])
    start = 0
    for b in range(len(has) + 1):
        if b == len(has) or not has[b]:
            if b - start >= run:
                keep[start:b] = True
            start = b + 1
    empty = np.array([], dtype=np.int64)
    return [w if keep[b] else empty for b, w in enumerate(walls)]


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


def _inputs_for(log: EnvelopeLog, inputs: EnvelopeInputs, idx: NDArray[np.int64]) -> EnvelopeInputs:
    temperature = log.temperature[idx] if log.temperature is not None else None
    return EnvelopeInputs(inputs.spec, temperature=temperature, compensation=inputs.compensation)


def offsets(log: EnvelopeLog, walls: Walls, model: Mapping[str, float], inputs: EnvelopeInputs) -> Offsets:
    """Edge offsets of every wall bin against ``model`` (effect -> parameter)."""
    groups = [(s, i) for s, side in ((1, walls.upper), (-1, walls.lower)) for i in side if i.size]
    if not groups:
        return Offsets(np.array([]), np.array([], dtype=np.int8), np.array([]), np.array([]), np.array([]))
    margin = []
    for s in (1, -1):  # each edge only where it is needed: positive margins lie past the model's edge
        idx = np.concatenate([i for side, i in groups if side == s] or [np.array([], dtype=np.int64)])
        if idx.size:
            limit = edge(log.velocity[idx], s, model, _inputs_for(log, inputs, idx))
            margin.append(s * (log.torque[idx] - limit))
    m = np.concatenate(margin)
    ordered = [g for s in (1, -1) for g in groups if g[0] == s]
    sizes = np.array([i.size for _, i in ordered])
    gid = np.repeat(np.arange(sizes.size), sizes)
    bad = np.bincount(gid, weights=~np.isfinite(m), minlength=sizes.size) > 0
    m = np.where(np.isfinite(m), m, 0.0)
    mean = np.bincount(gid, weights=m) / sizes
    spread = np.sqrt(np.maximum(np.bincount(gid, weights=(m - mean[gid]) ** 2) / sizes, 0.0))
    speeds = np.bincount(gid, weights=log.velocity[np.concatenate([i for _, i in ordered])]) / sizes
    side = np.array([s for s, _ in ordered], dtype=np.int8)
    off = np.where(bad, -inputs.spec.torque_limit, mean)
    # consecutive samples of a trajectory log share their noise: n (1 - rho) / (1 + rho) independent ones (AR(1))
    se = spread / np.sqrt(sizes) * math.sqrt((1 + walls.rho) / (1 - walls.rho))
    return Offsets(speeds, side, off, se, spread)


@dataclass(frozen=True)
class Suggestion:
    """A candidate effect tried on top of the model."""

    effect: str
    value: float
    """Fitted parameter [the effect's unit]."""
    unit: str
    explained: float
    """Share of the envelope error's sum of squares it removes [0-1]."""
    rmse: float
    """Envelope error with it [N m]."""
    f_statistic: float
    p_value: float
    significant: bool
    reason: str
    supported: bool = False
    """A logged channel confirms it (the bus voltage for ``bus_sag``); such a suggestion ranks first."""
    refit: Mapping[str, float] = field(default_factory=dict)
    """The model's own parameters refitted together with this effect (a wrong earlier effect falls back here)."""

    def to_dict(self) -> dict[str, Any]:
        out = {k: getattr(self, k) for k in self.__dataclass_fields__}
        out["refit"] = dict(self.refit)
        return out


def _bounds(name: str, inputs: EnvelopeInputs) -> tuple[float, float]:
    """The search interval of an effect's parameter (a current limit: up to the spec's own)."""
    lo_b, hi_b = EFFECTS[name].bounds
    if not math.isfinite(hi_b):
        hi_b = (inputs.spec.max_current or inputs.spec.torque_limit / inputs.spec.kt) * 1.0001
        lo_b = 0.05 * hi_b
    return lo_b, hi_b


def _at_bound(name: str, value: float, inputs: EnvelopeInputs) -> bool:
    """Whether a fitted parameter sits at a bound of its search (not identified), other than its neutral value."""
    lo_b, hi_b = _bounds(name, inputs)
    near = min(abs(value - lo_b), abs(hi_b - value)) < 1e-3 * (hi_b - lo_b)
    return bool(near and value != EFFECTS[name].neutral)


def _fit_one(
    log: EnvelopeLog, walls: Walls, model: Mapping[str, float], name: str, inputs: EnvelopeInputs
) -> tuple[float, float, bool]:
    """(fitted parameter, sum of squares, whether it sits at a bound of the search), the others held."""
    from scipy.optimize import minimize_scalar

    lo_b, hi_b = _bounds(name, inputs)
    res = minimize_scalar(
        lambda v: offsets(log, walls, {**model, name: float(v)}, inputs).sse,
        bounds=(lo_b, hi_b),
        method="bounded",
        options={"xatol": (hi_b - lo_b) * 1e-5},
    )
    return float(res.x), float(res.fun), _at_bound(name, float(res.x), inputs)


def suggest(log: EnvelopeLog, walls: Walls, model: Mapping[str, float], inputs: EnvelopeInputs) -> list[Suggestion]:
    """Every candidate effect fitted on top of ``model``, best first (module docstring)."""
    from scipy.special import fdtrc  # F distribution survival function (scipy.stats is slow to import)

    base = offsets(log, walls, model, inputs)
    n = base.offset.size
    if n < 3:
        raise SpecError(
            f"{log.source}: only {n} speed bins show the motor at its limits (method: {walls.method}); the log does "
            "not push the motor to its envelope, so there is nothing to compare. Log commands past the limits, or "
            "add a torque_cmd column"
        )
    names = [c for c in effect_names(_inputs_for(log, inputs, np.arange(log.n))) if c not in model]
    excess0 = np.nan_to_num(_excess(log, inputs, base.sample_noise, model)[0], nan=0.0)
    spill0 = float(np.mean(excess0 > REFUTE * inputs.spec.torque_limit))
    out = []
    for name in names:
        value, sse1, at_bound = _fit_one(log, walls, model, name, inputs)
        refit = dict(model)
        if model:
            # Refit the model's own parameters with the candidate in, from two starts: the candidate on top of the
            # model, and the candidate alone (the model's effects then refitted): an effect added wrongly must not
            # hide the right one.
            alone = _fit_one(log, walls, {}, name, inputs)[0]
            for start in ({**model, name: value}, {**model, name: alone}):
                joint = _refit(log, walls, start, inputs, all_params=True, lead=name)
                sse_joint = offsets(log, walls, joint, inputs).sse
                if sse_joint < sse1:
                    value, sse1 = joint.pop(name), sse_joint
                    refit = joint
                    at_bound = _at_bound(name, value, inputs)
        dof = max(n - 1, 1)
        f_stat = max(base.sse - sse1, 0.0) / max(sse1 / dof, 1e-30)
        p = float(fdtrc(1, dof, f_stat))
        effect = EFFECTS[name]
        # the whole log must fit inside: an effect whose edges the log passes by far is refuted by it (a fit that
        # compromises between two effects passes its samples by a little)
        excess = _excess(log, inputs, base.sample_noise, {**refit, name: value})[0]
        spill = float(np.mean(np.nan_to_num(excess, nan=0.0) > REFUTE * inputs.spec.torque_limit))
        refuted = spill > max(OUTSIDE_OK, 2 * spill0)
        moved = ", ".join(
            f"{k} refitted {model[k]:.4g} -> {v:.4g} {EFFECTS[k].unit}"
            for k, v in refit.items()
            if abs(v - model[k]) > 1e-3 * max(abs(model[k]), 1e-12)
        )
        out.append(
            Suggestion(
                effect=name,
                value=value,
                unit=effect.unit,
                explained=max(0.0, (base.sse - sse1) / base.sse) if base.sse > 0 else 0.0,
                rmse=math.sqrt(sse1 / n),
                f_statistic=float(f_stat),
                p_value=p,
                # statistically and practically: the F-test, and an error that falls by at least the noise level
                significant=bool(p < ALPHA / max(len(names), 1))
                and not at_bound
                and not refuted
                and base.rmse - math.sqrt(sse1 / n) >= base.noise,
                reason=(
                    f"{effect.physics}; {effect.parameter} = {value:.4g} {effect.unit} takes the envelope error from "
                    f"{base.rmse:.3g} to {math.sqrt(sse1 / n):.3g} N m over {n} bins at the limit"
                    + (f" ({moved})" if moved else "")
                    + (
                        f" (refuted: {spill:.1%} of the samples lie more than {REFUTE:.0%} of the torque limit past "
                        "its edges; the log makes torque it forbids)"
                        if refuted
                        else ""
                    )
                    + (" (at the bound of its search: not identified)" if at_bound else "")
                ),
                refit=refit,
            )
        )
    # Logged channels settle what the envelope alone cannot: a sagging bus, inductance and a saturating core all
    # shorten the motoring edge at speed; the bus voltage and the current say which it is.
    for named, evidence in (("bus_sag", bus_evidence(log, inputs)), ("kt_saturation", current_evidence(log, inputs))):
        if evidence is None:
            continue
        for k, sug in enumerate(out):
            if named == "bus_sag" and sug.effect == named and _contradicts(sug.value, evidence):
                # the logged bus is the direct measurement: a sag it does not show is another effect's shortfall
                out[k] = replace(
                    sug,
                    significant=False,
                    reason=sug.reason + f"; contradicted: {evidence['text']}, not {sug.value:.3g} ohm",
                )
            elif sug.effect == named and sug.explained > 0.5:
                out[k] = replace(sug, reason=sug.reason + f"; {evidence['text']}", supported=evidence["significant"])
    out.sort(key=lambda s: (-int(s.supported and s.significant), -s.explained))
    return out


def _contradicts(value: float, evidence: Mapping[str, Any]) -> bool:
    """Whether a fitted pack resistance is ruled out by the logged bus voltage's own: more than
    :data:`EVIDENCE_SIGMAS` standard errors and a third of the fitted value above it."""
    return bool(value - evidence["r_pack"] > max(EVIDENCE_SIGMAS * evidence["se"], value / 3))


def current_evidence(log: EnvelopeLog, inputs: EnvelopeInputs) -> dict[str, Any] | None:
    """Whether the logged current grows faster than tau / Kt at high torque (a saturating core): the slope of
    Kt i - tau against tau^3, with its standard error; None without a current channel."""
    if log.current is None:
        return None
    x = log.torque**3
    slope, se = _leading(np.column_stack([x, log.torque, np.ones_like(x)]), inputs.spec.kt * log.current - log.torque)
    significant = slope > 5 * se
    return {
        "slope": slope,
        "se": se,
        "significant": significant,
        "text": f"the logged current exceeds tau/Kt by {slope:.3g} +- {se:.2g} A/Kt per (N m)^3"
        + ("" if significant else " (not significant)"),
    }


def _leading(A: Array, y: Array) -> tuple[float, float]:
    """Least squares y ~ A c: the first coefficient and its standard error."""
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    resid = y - A @ coef
    cov = np.linalg.pinv(A.T @ A) * float(np.sum(resid**2)) / max(y.size - A.shape[1], 1)
    return float(coef[0]), math.sqrt(max(float(cov[0, 0]), 0.0))


def bus_evidence(log: EnvelopeLog, inputs: EnvelopeInputs) -> dict[str, Any] | None:
    """The pack resistance the logged bus voltage shows: V_nominal - V_bus against the bus current P / V_bus
    of motoring samples (P = (R i + omega/Kv) i, i from the current channel or tau / Kt); None without the channel.
    """
    if log.bus_voltage is None:
        return None
    spec = inputs.spec
    i = log.current if log.current is not None else log.torque / spec.kt
    power = (spec.resistance * i + log.velocity / spec.kv) * i
    motoring = power > 0.05 * float(np.max(np.abs(power)))
    if motoring.sum() < 20:
        return None
    x = power[motoring] / np.maximum(log.bus_voltage[motoring], 1e-3 * spec.bus_voltage)  # the bus current
    r_pack, se = _leading(np.column_stack([x, np.ones_like(x)]), spec.bus_voltage - log.bus_voltage[motoring])
    significant = r_pack > 5 * se and r_pack > 1e-3
    return {
        "r_pack": r_pack,
        "se": se,
        "significant": significant,
        "text": f"the logged bus voltage falls {r_pack:.3g} +- {se:.2g} ohm x bus current while motoring"
        + ("" if significant else " (not significant)"),
    }


@dataclass(frozen=True)
class Step:
    """One rung of the ladder: the model, its offsets and the suggestions on top of it."""

    model: dict[str, float]
    added: str | None
    offsets: Offsets
    suggestions: tuple[Suggestion, ...]
    refound: bool = False
    """Whether the walls were found again against this model (and every parameter refitted on them)."""


@dataclass(frozen=True)
class Comparison:
    """Everything ``hound-id mor --compare`` found."""

    log: EnvelopeLog
    inputs: EnvelopeInputs
    walls: Walls
    """The samples at the limit, found against the final model's edges."""
    ladder: tuple[Step, ...]
    outside: dict[str, Any] = field(default_factory=dict)
    baseline: Offsets | None = None
    """The spec sheet's offsets on the final walls (the fair 'before' of the final model)."""
    unneeded: tuple[dict[str, Any], ...] = ()
    """Effects of the final model the log does not need once the others are in (:func:`unneeded`)."""
    isolated: tuple[dict[str, Any], ...] = ()
    """Single bins left out as chance walls (:func:`_isolated`): speed, edge, offset, se."""
    outside_final: float = 0.0
    """Share of the samples past the final model's edges (as :func:`outside_stats` counts them)."""

    @property
    def final(self) -> Step:
        return self.ladder[-1]


def _excess(
    log: EnvelopeLog, inputs: EnvelopeInputs, noise: float, model: Mapping[str, float] | None = None
) -> tuple[Array, float, NDArray[np.bool_]]:
    """(how far each sample passes the edges of ``model`` (default the spec sheet) [N m], the threshold, the
    samples past it)."""
    lo, hi = envelope(log.velocity, dict(model or {}), _inputs_for(log, inputs, np.arange(log.n)))
    thr = max(4 * noise, 0.005 * inputs.spec.torque_limit)
    excess = np.maximum(log.torque - hi, lo - log.torque)
    return excess, thr, np.asarray(np.isfinite(excess) & (excess > thr))


def outside_mask(log: EnvelopeLog, inputs: EnvelopeInputs, noise: float) -> NDArray[np.bool_]:
    """Samples past the spec sheet's region by more than the threshold of :func:`outside_stats`."""
    return _excess(log, inputs, noise)[2]


def outside_stats(log: EnvelopeLog, inputs: EnvelopeInputs, noise: float) -> dict[str, Any]:
    """Where the log leaves the spec sheet's region: share of samples, how far, which quadrant and speeds.

    A sample is outside when it passes an edge by more than 4 x the torque noise of one sample at
    the limit (and 0.5 % of the torque limit). Quadrants: I motoring forward (tau > 0, omega > 0), II braking (tau > 0,
    omega < 0), III motoring backward, IV braking (tau < 0, omega > 0).
    """
    excess, thr, out = _excess(log, inputs, noise)
    t, w = log.torque[out], log.velocity[out]
    quadrant = np.where(t >= 0, np.where(w >= 0, "I", "II"), np.where(w < 0, "III", "IV"))
    return {
        "fraction": float(out.mean()),
        "samples": int(out.sum()),
        "threshold": thr,
        "max_excess": float(excess[out].max()) if out.any() else 0.0,
        "p95_excess": float(np.quantile(excess[out], 0.95)) if out.any() else 0.0,
        "by_quadrant": {q: int(np.sum(quadrant == q)) for q in ("I", "II", "III", "IV")},
        "speed_range": [float(np.abs(w).min()), float(np.abs(w).max())] if out.any() else None,
    }


def compare(
    log: EnvelopeLog, inputs: EnvelopeInputs, add: Sequence[str] = (), auto: bool = False, max_steps: int = 4
) -> Comparison:
    """Compare a log with the spec's region; add the named effects, or with ``auto`` the best significant one
    until none is left (at most ``max_steps``)."""
    for name in add:
        if name not in EFFECTS:
            raise SpecError(f"--add: unknown effect {name!r}; effects are {', '.join(EFFECTS)}")
    _plausible(log, inputs)
    walls = find_walls(log, inputs)
    model: dict[str, float] = {}
    base = offsets(log, walls, model, inputs)
    ladder = [Step(dict(model), None, base, tuple(suggest(log, walls, model, inputs)))]
    queue = list(add)
    while queue or auto:
        if queue:
            name = queue.pop(0)
            if name not in {s.effect for s in ladder[-1].suggestions}:
                raise SpecError(
                    f"--add {name}: not testable on this log (it needs {', '.join(EFFECTS[name].requires) or 'nothing'}"
                    " that is missing, or is already in the model)"
                )
        else:
            best = [s for s in ladder[-1].suggestions if s.significant]
            if not best or len(ladder) > max_steps:
                break
            name = best[0].effect
        chosen = next(s for s in ladder[-1].suggestions if s.effect == name)
        model = {**model, **chosen.refit, name: chosen.value}
        # with the effect in, edges the spec sheet missed line up: look for walls again and refit on them
        again = find_walls(log, inputs, model, commanded=walls.commanded)
        refound = _bins(again) >= _bins(walls)
        if refound:
            walls = again
            model = _refit(log, walls, model, inputs, all_params=True)
        step_offsets = offsets(log, walls, model, inputs)
        ladder.append(Step(dict(model), name, step_offsets, tuple(suggest(log, walls, model, inputs)), refound))
    walls, isolated = _isolated(walls, offsets(log, walls, model, inputs), inputs.spec.back_emf_damping)
    if isolated:  # the last rung on the walls that are left
        last = ladder[-1]
        ladder[-1] = replace(last, offsets=offsets(log, walls, model, inputs))
    baseline = offsets(log, walls, {}, inputs)
    return Comparison(
        log,
        inputs,
        walls,
        tuple(ladder),
        outside_stats(log, inputs, base.sample_noise),
        baseline=baseline,
        unneeded=tuple(unneeded(log, walls, model, inputs)),
        isolated=tuple(isolated),
        outside_final=float(_excess(log, inputs, base.sample_noise, model)[2].mean()),
    )


def _isolated(walls: Walls, off: Offsets, slope: float) -> tuple[Walls, list[dict[str, Any]]]:
    """Without a command channel, leave out single bins far off the final model whose neighbours agree with it:
    passes that happened to line up into a wall (a real departure spans a range of speeds). A bin is isolated when
    its offset exceeds :data:`ISOLATED` x the torque noise of one sample at the limit and the nearest bin on each
    side of the same edge lies within 3 standard errors of the model. The last bin of an edge (effects show at the
    ends of the speed range) is isolated only if it also jumps from its neighbour by more than an edge can change
    between their speeds, twice the back-EMF slope ``slope`` [N m s/rad] (plus 5 standard errors)."""
    if walls.method != "wall" or off.offset.size < 3:
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
            isolated = all(abs(off.offset[j]) <= 3 * off.se[j] for j in (left[-1], right[0]))
        elif left or right:  # an end bin: only a jump no edge can make between neighbouring speeds
            j = left[-1] if left else right[0]
            jump = abs(off.offset[k] - off.offset[j])
            bound = 2 * slope * abs(off.speeds[k] - off.speeds[j]) + 5 * math.hypot(off.se[k], off.se[j])
            isolated = abs(off.offset[j]) <= 3 * off.se[j] and jump > bound
        else:
            isolated = False
        if isolated:
            drop.append((s, b))
            found.append({"speed": float(off.speeds[k]), "edge": "upper" if s == 1 else "lower",
                          "offset": float(off.offset[k]), "se": float(off.se[k])})  # fmt: skip
    empty = np.array([], dtype=np.int64)
    for s, b in drop:
        sides[s][b] = empty
    return replace(walls, upper=tuple(sides[1]), lower=tuple(sides[-1])), found


def unneeded(
    log: EnvelopeLog, walls: Walls, model: Mapping[str, float], inputs: EnvelopeInputs
) -> list[dict[str, Any]]:
    """The model's effects the log does not need once the others are in: each dropped in turn, the rest refitted;
    needed only if the drop is significant (partial F-test at :data:`ALPHA` / effects) and raises the envelope
    error by at least the noise level, as for adding one. Empty for models of fewer than two effects."""
    from scipy.special import fdtrc  # F distribution survival function (scipy.stats is slow to import)

    if len(model) < 2:
        return []
    full = offsets(log, walls, model, inputs)
    n, dof = full.offset.size, max(full.offset.size - len(model), 1)
    out = []
    for name in model:
        rest = _refit(log, walls, {k: v for k, v in model.items() if k != name}, inputs, all_params=True)
        without = offsets(log, walls, rest, inputs)
        f_stat = max(without.sse - full.sse, 0.0) / max(full.sse / dof, 1e-30)
        p = float(fdtrc(1, dof, f_stat))
        if p < ALPHA / len(model) and without.rmse - full.rmse >= full.noise:
            continue
        others = ", ".join(f"{k} = {v:.4g} {EFFECTS[k].unit}" for k, v in rest.items())
        out.append(
            {
                "effect": name,
                "value": model[name],
                "rmse_without": without.rmse,
                "p_value": p,
                "reason": f"without it (and {others} refitted) the envelope error is {without.rmse:.3g} N m against "
                f"{full.rmse:.3g} N m with it over {n} bins (p = {p:.2g}): the log does not need it",
            }
        )
    return out


def _plausible(log: EnvelopeLog, inputs: EnvelopeInputs) -> None:
    """Refuse a log whose torque or speed the motor cannot have made: most samples of a log lie inside the region,
    so a 99th percentile past :data:`IMPLAUSIBLE` x the torque limit or the overspeed is a unit mistake."""
    from hound_id.mor.region import operating_region

    spec = inputs.spec
    overspeed = operating_region(spec).overspeed
    for name, values, limit, unit, units in (
        ("torque", log.torque, spec.torque_limit, "N m", (("N*cm", 100.0), ("mN*m", 1000.0))),
        ("velocity", log.velocity, overspeed, "rad/s", (("rpm", 30.0 / math.pi), ("deg/s", 180.0 / math.pi))),
    ):
        p99 = float(np.quantile(np.abs(values), 0.99))
        if p99 > IMPLAUSIBLE * limit:
            fits = [u for u, factor in units if p99 / factor <= 1.2 * limit]  # the smallest unit that makes sense
            hint = f"--units {name}={fits[0]}" if fits else "--units " + " or ".join(f"{name}={u}" for u, _ in units)
            raise DynoDataError(
                f"{log.source}: {name} reaches {p99:.4g} {unit} (99th percentile), over {IMPLAUSIBLE:g}x what "
                f"{spec.name} can ({limit:.4g} {unit}); check its unit: a [unit] in the header or {hint}"
            )


def _bins(walls: Walls) -> int:
    return sum(w.size > 0 for w in walls.upper) + sum(w.size > 0 for w in walls.lower)


def _refit(
    log: EnvelopeLog,
    walls: Walls,
    model: Mapping[str, float],
    inputs: EnvelopeInputs,
    all_params: bool = False,
    lead: str | None = None,
) -> dict[str, float]:
    """One coordinate-descent sweep over the model's parameters, each refitted with the others fixed (``lead``,
    if given, is held first and refitted last)."""
    fitted = dict(model)
    if len(fitted) > 1 or all_params:
        order = [k for k in fitted if k != lead] + ([lead] if lead in fitted else [])
        for name in order:
            others = {k: v for k, v in fitted.items() if k != name}
            fitted[name] = _fit_one(log, walls, others, name, inputs)[0]
    return fitted


def polyline(model: Mapping[str, float], inputs: EnvelopeInputs, tolerance: float | None = None) -> dict[str, Any]:
    """The model's edges as polylines over speed, refined until linear interpolation is within ``tolerance``
    [N m] (default :data:`POLYLINE_TOLERANCE` x the torque limit) of the model at a quarter, half and three
    quarters of every segment (``max_error`` is the largest miss found there).

    Temperature-dependent effects are evaluated at the spec's reference temperature.
    """
    spec = inputs.spec
    tol = tolerance if tolerance is not None else POLYLINE_TOLERANCE * spec.torque_limit
    plain = {k: v for k, v in model.items() if "temperature" not in EFFECTS[k].requires}
    ref = EnvelopeInputs(spec, compensation=inputs.compensation)
    top = spec.bus_voltage * spec.kv
    speeds = np.linspace(-top, top, 17)
    for _ in range(14):  # split every segment whose interpolation misses the model at 1/4, 1/2 or 3/4 of it
        lo, hi = envelope(speeds, plain, ref)
        err = np.zeros(speeds.size - 1)
        for f in (0.25, 0.5, 0.75):
            probe = speeds[:-1] + f * np.diff(speeds)
            plo, phi = envelope(probe, plain, ref)
            miss = np.maximum(np.abs(hi[:-1] + f * np.diff(hi) - phi), np.abs(lo[:-1] + f * np.diff(lo) - plo))
            err = np.maximum(err, np.nan_to_num(miss, nan=0.0))
        bad = err > tol
        if not bad.any():
            break
        speeds = np.sort(np.concatenate([speeds, (speeds[:-1] + 0.5 * np.diff(speeds))[bad]]))
    else:  # refined to the limit: the edges of the last speeds
        lo, hi = envelope(speeds, plain, ref)
    return {
        "speeds": speeds.tolist(),
        "upper": hi.tolist(),
        "lower": lo.tolist(),
        "tolerance": tol,
        "max_error": float(np.nanmax(err)) if err.size else 0.0,
        "model": plain,
        "units": "rad/s, N m (motor side)",
    }


def compensation_of(spec: MotorSpec) -> tuple[tuple[int, ...], tuple[float, ...]] | None:
    """The current-compensation polynomial of a fitted spec (``fit-current --out``), if it has one."""
    comp = (spec.fit or {}).get("compensation")
    if not comp:
        return None
    return tuple(int(p) for p in comp["powers"]), tuple(float(c) for c in comp["coefficients"])


def coverage(off: Offsets) -> dict[str, list[float] | None]:
    """Motor speeds [rad/s] the bins at the limit span, per edge: where the data say anything."""
    out: dict[str, list[float] | None] = {}
    for side, name in ((1, "upper"), (-1, "lower")):
        w = off.speeds[off.side == side]
        out[name] = [float(w.min()), float(w.max())] if w.size else None
    return out


def _rung(c: Comparison, k: int) -> dict[str, Any]:
    """One step of the ladder, with the suggestion (from the step before) that added its effect."""
    step = c.ladder[k]
    why = None
    if k > 0:
        why = next((x.to_dict() for x in c.ladder[k - 1].suggestions if x.effect == step.added), None)
    # the spec sheet's rung on the final walls, as the headline "before" (its suggestions' texts are on the first)
    off = c.baseline if k == 0 and c.baseline is not None else step.offsets
    return {
        "added": step.added,
        "model": step.model,
        "envelope_rmse": off.rmse,
        "noise_level": off.noise,
        "bins": int(off.offset.size),
        "walls_found_again": step.refound,
        "why": why,
    }


def verdict(c: Comparison) -> dict[str, Any]:
    """``explained`` and the ``flags`` that say why not: the model explains the log when its envelope error is at
    the noise level (:data:`EXPLAINED` x), no bin sits off it by more than :data:`OFF_SIGMAS` standard errors (the
    bin's, or the typical sample noise's if larger) and :data:`OFF_FLOOR` of the torque limit, and (against the spec
    sheet) no share of the samples lies past its edges. A noise level inflated by bins whose samples spread more
    than :data:`WIDE` x the typical sample noise (over :data:`INFLATED` x the other bins' noise level) would pass
    any model: it is flagged, and the error must also be at the other bins' level."""
    off, spec = c.final.offsets, c.inputs.spec
    flags: list[dict[str, Any]] = []
    typical, off_model, inflated = off.noise, False, False
    if off.offset.size:
        # a bin's own spread is a noisy estimate of the noise (few independent samples): never below the typical one
        se = off.se * np.maximum(1.0, off.sample_noise / np.maximum(off.spread, 1e-30))
        far = (np.abs(off.offset) > OFF_SIGMAS * se) & (np.abs(off.offset) > OFF_FLOOR * spec.torque_limit)
        off_model = bool(far.any())
        if off_model:
            worst = int(np.argmax(np.where(far, np.abs(off.offset) / np.maximum(se, 1e-30), -1.0)))
            where = "; ".join(
                f"{name} edge at {_speeds(off.speeds[far & (off.side == s)])} rad/s"
                for s, name in ((1, "upper"), (-1, "lower"))
                if (far & (off.side == s)).any()
            )
            flags.append({
                "kind": "bins_off_model",
                "bins": int(far.sum()),
                "text": f"{int(far.sum())} bin{'s' if far.sum() > 1 else ''} sit{'' if far.sum() > 1 else 's'} off "
                f"the model by more than {OFF_SIGMAS:g} standard errors and "
                f"{OFF_FLOOR:.1%} of the torque limit ({where}), up to {off.offset[worst]:+.3g} N m "
                f"({abs(off.offset[worst]) / max(se[worst], 1e-30):.0f} SE at {off.speeds[worst]:.4g} rad/s): the "
                "model misses something there",
            })  # fmt: skip
        wide = off.spread > WIDE * off.sample_noise
        if wide.any() and not wide.all():
            typical = float(np.sqrt(np.mean(off.se[~wide] ** 2)))
            inflated = off.noise > INFLATED * typical
            if inflated:
                flags.append({
                    "kind": "noise_inflated",
                    "bins": int(wide.sum()),
                    "text": f"the noise level {off.noise:.3g} N m is {off.noise / max(typical, 1e-30):.1f}x the "
                    f"{typical:.3g} N m of the other bins, from {int(wide.sum())} bin(s) at "
                    f"{_speeds(off.speeds[wide])} rad/s whose samples spread up to "
                    f"{float(np.max(off.spread[wide])):.3g} N m (typical sample noise {off.sample_noise:.3g} N m): "
                    "samples counted at the limit that were not, or an edge that moves within the bin",
                })  # fmt: skip
    rmse = off.rmse
    explained = (
        rmse <= EXPLAINED * max(off.noise, 1e-12)
        and (not inflated or rmse <= EXPLAINED * typical)
        and not off_model
        and (bool(c.final.model) or c.outside["fraction"] <= OUTSIDE_OK)
        and c.outside_final <= OUTSIDE_OK
    )
    return {"explained": bool(explained), "flags": flags}


def _speeds(w: Array) -> str:
    """Speeds [rad/s] for a message: all of up to four ("-483, 12, 496"), else the range ("-483 to 496")."""
    values = sorted(float(x) for x in w)
    return ", ".join(f"{v:.4g}" for v in values) if len(values) <= 4 else f"{values[0]:.4g} to {values[-1]:.4g}"


def comparison_json(c: Comparison) -> dict[str, Any]:
    """The ``hound-id/mor-compare/2`` JSON."""
    first, last = c.ladder[0], c.final
    before = c.baseline if c.baseline is not None else first.offsets
    return {
        "schema": SCHEMA,
        "source": c.log.source,
        "side": c.log.side,
        "motor": c.inputs.spec.name,
        "samples": c.log.n,
        "rows_dropped": c.log.dropped,
        "limit_method": c.walls.method,
        "limit_detection": c.walls.commanded.to_dict() if c.walls.commanded is not None else None,
        "bins_at_limit": int(last.offsets.offset.size),
        "outside_fraction": c.outside["fraction"],
        "outside": c.outside,
        "envelope_rmse": {"model": before.rmse, "with_added": last.offsets.rmse},
        **verdict(c),
        "outside_final": c.outside_final,
        "coverage": coverage(last.offsets),
        "noise_level": last.offsets.noise,
        "sample_noise": first.offsets.sample_noise,
        "model": last.model,
        "added": [s.added for s in c.ladder[1:]],
        "suggestions": [s.to_dict() for s in last.suggestions],
        "unneeded": list(c.unneeded),
        "isolated_bins": list(c.isolated),
        "ladder": [_rung(c, k) for k in range(len(c.ladder))],
        "bins": [
            {
                "speed": float(w),
                "edge": "upper" if side == 1 else "lower",
                "offset_model": float(o0),
                "se": float(se),
                "offset_with_added": float(o1),
            }
            for w, side, o0, se, o1 in zip(
                before.speeds,
                before.side,
                before.offset,
                before.se,
                last.offsets.offset,
                strict=True,
            )
        ],  # fmt: skip
        "polyline": polyline(last.model, c.inputs),
        "units": "SI, motor side: N m, rad/s",
    }


def envelope_spec(spec_path: Path, out_path: Path, c: Comparison) -> dict[str, Any]:
    """A motor spec file (``hound-id/motor/1``) with the measured envelope, for the saturation and the export:
    the spec sheet (by ``base:``, relative to ``out_path``) plus ``envelope`` = the model's effects and its
    polyline edges (:func:`polyline`)."""
    import os

    from hound_id.io import read_yaml

    raw = read_yaml(spec_path, "motor spec")
    line = polyline(c.final.model, c.inputs)
    env = {
        "effects": line["model"],
        "speeds": line["speeds"],
        "lower": [None if not math.isfinite(v) else v for v in line["lower"]],
        "upper": [None if not math.isfinite(v) else v for v in line["upper"]],
        "tolerance": line["tolerance"],
        "coverage": coverage(c.final.offsets),
        "units": "rad/s, N m (motor side); outside the coverage the polyline is the model's extrapolation",
        "source": f"hound-id mor --compare {c.log.source}",
    }
    folder = out_path.resolve().parent
    if isinstance(raw, dict) and "base" in raw:  # a fitted spec: keep its own fields, rebase its base
        data = dict(raw)
        data["base"] = os.path.relpath((spec_path.resolve().parent / raw["base"]).resolve(), folder)
    else:
        data = {"schema": "hound-id/motor/1", "base": os.path.relpath(spec_path.resolve(), folder)}
    data["envelope"] = env
    return data
