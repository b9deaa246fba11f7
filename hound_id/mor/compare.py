"""``hound-id mor --compare``: a measured torque-speed log against the operating region, and what is missing.

**Samples at the limit.** A log shows the envelope only where the motor was pushed to it. With a
commanded-torque channel (``torque_cmd``) a sample is at its upper limit when the command
exceeds the measured torque by more than :data:`CMD_GAP` of the torque limit (and at its lower
limit the other way round). Without one, hound-id looks for a *wall* in each speed bin: the
margins r = tau - edge(omega) of samples driven into a limit pile up, so the top of the
margin distribution is narrow, (q98 - q90) < :data:`WALL` x (q98 - q50) and below
:data:`WALL_WIDTH` of the torque limit. Where the true edge drifts against the model's across a
bin (steep past the no-load speed), the linear drift of the top fifth of the margins is taken
out first. Walls in fewer than three neighbouring bins are taken for chance: a limit spans a range of speeds. The
samples of a wall (margins above q90 - 2 (q98 - q90)) form the bin's cluster.

**Edge offsets.** For a model (the spec sheet plus effects with parameters), a bin's edge
offset is the mean margin of its cluster against that model [N m], with its standard error.
The *envelope error* is the RMS of the offsets over all wall bins, upper and lower; the *noise
level* is the RMS of their standard errors. A bin whose offset is below -3 SE falls short of
the model; above +3 SE the log spills over it.

**What is missing.** Each candidate effect of :mod:`hound_id.mor.envelope` is fitted on top of
the model (bounded scalar search of its parameter) and ranked by the share of the envelope
error's sum of squares it explains. It is significant when the partial F statistic
(SSE0 - SSE1) / (SSE1 / (bins - 1)) beats F(1, bins - 1) at 1 % divided by the number of
candidates (Bonferroni), and when the envelope error falls by at least the noise level (an effect
too small to matter is not suggested). ``--add`` and ``--auto`` grow the model as in ``fit-current``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.errors import DynoDataError, SpecError
from hound_id.mor.envelope import EFFECTS, EnvelopeInputs, effect_names, envelope
from hound_id.mor.spec import MotorSpec

Array = NDArray[np.float64]
SCHEMA = "hound-id/mor-compare/1"

#: Channels of a comparison log; the first two are required.
CHANNELS = ("torque", "velocity", "torque_cmd", "current", "temperature", "bus_voltage")
#: A command above the measured torque by this share of the torque limit marks a sample at its limit.
CMD_GAP = 0.02
#: A bin has a wall when (q98 - q90) < WALL (q98 - q50) of its margins.
WALL = 0.1
#: ... and its top (q98 - q90) narrower than this share of the torque limit: piled up within the noise.
WALL_WIDTH = 0.03
#: Speed bins across the logged range, and the fewest samples a bin (and a wall) needs.
BINS = 32
MIN_SAMPLES = 40
MIN_WALL = 8
#: Family-wise false-alarm rate of the significance tests.
ALPHA = 0.01
#: The model explains the envelope when its error is at most this many noise levels ...
EXPLAINED = 3.0
#: ... and (for the spec sheet itself) at most this share of the samples lies past its edges.
OUTSIDE_OK = 0.005
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
    data = {"torque": torque, "velocity": velocity, **rest}
    good = np.ones(torque.size, dtype=bool)
    for values in data.values():
        if values is not None:
            good &= np.isfinite(values)
    if good.sum() < 10 * MIN_SAMPLES:
        raise DynoDataError(
            f"{source}: {int(good.sum())} usable rows; an envelope comparison needs at least {10 * MIN_SAMPLES}"
        )
    picked = {k: (v[good] if v is not None else None) for k, v in data.items()}
    return EnvelopeLog(source=source, side=side, dropped=int((~good).sum()), **picked)  # type: ignore[arg-type]


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


def _wall(members: NDArray[np.int64], m: Array, width: float) -> NDArray[np.int64]:
    """The members whose margins form a wall at the top of the bin (module docstring), or none. The top
    must also be narrower than ``width`` [N m] in absolute terms: piled up within the sensor noise."""
    q50, q90, q98 = np.quantile(m, [0.5, 0.9, 0.98])
    if (q98 - q90) < WALL * (q98 - q50) and (q98 - q90) < width:
        return members[m >= q90 - 2 * (q98 - q90)]
    return np.array([], dtype=np.int64)


def find_walls(
    log: EnvelopeLog, inputs: EnvelopeInputs, model: Mapping[str, float] | None = None, bins: int = BINS
) -> Walls:
    """The samples at the limit in each speed bin, against ``model``'s edges (module docstring)."""
    w = log.velocity
    edges = np.linspace(float(w.min()), float(w.max()), bins + 1)
    index = np.clip(np.searchsorted(edges, w, side="right") - 1, 0, bins - 1)
    lo, hi = envelope(w, dict(model or {}), _inputs_for(log, inputs, np.arange(log.n)))
    upper, lower = [], []
    gap = CMD_GAP * inputs.spec.torque_limit
    width = WALL_WIDTH * inputs.spec.torque_limit
    for b in range(bins):
        members = np.flatnonzero(index == b)
        found = []
        for margin_of, cmd_side in ((lambda i: log.torque[i] - hi[i], 1.0), (lambda i: lo[i] - log.torque[i], -1.0)):
            if members.size < MIN_SAMPLES:
                found.append(np.array([], dtype=np.int64))
                continue
            if log.torque_cmd is not None:
                at = members[cmd_side * (log.torque_cmd[members] - log.torque[members]) > gap]
            else:
                m = margin_of(members)
                finite = np.isfinite(m)
                if finite.sum() < MIN_SAMPLES:
                    found.append(np.array([], dtype=np.int64))
                    continue
                cand, m = members[finite], m[finite]
                at = _wall(cand, m, width)
                if at.size == 0:
                    # The true edge may drift against the model's across the bin (steep past the no-load speed):
                    # take out the linear drift of the top fifth of the margins and look again.
                    top = m >= np.quantile(m, 0.8)
                    if top.sum() >= 5 and np.ptp(w[cand[top]]) > 0:
                        slope = np.polyfit(w[cand[top]], m[top], 1)[0]
                        at = _wall(cand, m - slope * (w[cand] - np.mean(w[cand])), width)
            found.append(at if at.size >= MIN_WALL else np.array([], dtype=np.int64))
        upper.append(found[0])
        lower.append(found[1])
    centres = 0.5 * (edges[:-1] + edges[1:])
    if log.torque_cmd is None:  # a limit spans a range of speeds: isolated walls are chance
        upper, lower = _contiguous(upper), _contiguous(lower)
    return Walls(centres, tuple(upper), tuple(lower), "command" if log.torque_cmd is not None else "wall")


def _contiguous(walls: list[NDArray[np.int64]], run: int = 3) -> list[NDArray[np.int64]]:
    """Keep the walls that belong to a run of at least ``run`` neighbouring bins with walls."""
    has = np.array([w.size > 0 for w in walls])
    keep = np.zeros_like(has)
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
    idx = np.concatenate([i for _, i in groups])
    lo, hi = envelope(log.velocity[idx], model, _inputs_for(log, inputs, idx))
    margins = {1: log.torque[idx] - hi, -1: lo - log.torque[idx]}  # positive past the model's edge
    speeds, side, off, se, spread, start = [], [], [], [], [], 0
    for s, i in groups:
        m = margins[s][start : start + i.size]
        start += i.size
        speeds.append(float(np.mean(log.velocity[i])))
        side.append(s)
        off.append(float(np.mean(m)) if np.all(np.isfinite(m)) else -inputs.spec.torque_limit)
        se.append(float(np.std(m) / math.sqrt(i.size)))
        spread.append(float(np.std(m)))
    return Offsets(np.array(speeds), np.array(side, dtype=np.int8), np.array(off), np.array(se), np.array(spread))


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

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def _fit_one(
    log: EnvelopeLog, walls: Walls, model: Mapping[str, float], name: str, inputs: EnvelopeInputs
) -> tuple[float, float, bool]:
    """(fitted parameter, sum of squares, whether it sits at a bound of the search)."""
    from scipy.optimize import minimize_scalar

    effect = EFFECTS[name]
    lo_b, hi_b = effect.bounds
    if not math.isfinite(hi_b):  # a current limit: search up to the spec's own
        hi_b = (inputs.spec.max_current or inputs.spec.torque_limit / inputs.spec.kt) * 1.0001
        lo_b = 0.05 * hi_b
    res = minimize_scalar(
        lambda v: offsets(log, walls, {**model, name: float(v)}, inputs).sse,
        bounds=(lo_b, hi_b),
        method="bounded",
        options={"xatol": (hi_b - lo_b) * 1e-5},
    )
    at_bound = min(abs(float(res.x) - lo_b), abs(hi_b - float(res.x))) < 1e-3 * (hi_b - lo_b)
    return float(res.x), float(res.fun), bool(at_bound and float(res.x) != effect.neutral)


def suggest(log: EnvelopeLog, walls: Walls, model: Mapping[str, float], inputs: EnvelopeInputs) -> list[Suggestion]:
    """Every candidate effect fitted on top of ``model``, best first (module docstring)."""
    from scipy.stats import f as f_dist

    base = offsets(log, walls, model, inputs)
    n = base.offset.size
    if n < 3:
        raise SpecError(
            f"{log.source}: only {n} speed bins show the motor at its limits (method: {walls.method}); the log does "
            "not push the motor to its envelope, so there is nothing to compare. Log commands past the limits, or "
            "add a torque_cmd column"
        )
    names = [c for c in effect_names(_inputs_for(log, inputs, np.arange(log.n))) if c not in model]
    out = []
    for name in names:
        value, sse1, at_bound = _fit_one(log, walls, model, name, inputs)
        dof = max(n - 1, 1)
        f_stat = max(base.sse - sse1, 0.0) / max(sse1 / dof, 1e-30)
        p = float(f_dist.sf(f_stat, 1, dof))
        effect = EFFECTS[name]
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
                and base.rmse - math.sqrt(sse1 / n) >= base.noise,
                reason=(
                    f"{effect.physics}; {effect.parameter} = {value:.4g} {effect.unit} takes the envelope error from "
                    f"{base.rmse:.3g} to {math.sqrt(sse1 / n):.3g} N m over {n} bins at the limit"
                    + (" (at the bound of its search: not identified)" if at_bound else "")
                ),
            )
        )
    # Logged channels settle what the envelope alone cannot: a sagging bus, inductance and a saturating core all
    # shorten the motoring edge at speed; the bus voltage and the current say which it is.
    for named, evidence in (("bus_sag", bus_evidence(log, inputs)), ("kt_saturation", current_evidence(log, inputs))):
        if evidence is None:
            continue
        for k, sug in enumerate(out):
            if sug.effect == named and sug.explained > 0.5:
                out[k] = replace(sug, reason=sug.reason + f"; {evidence['text']}", supported=evidence["significant"])
    out.sort(key=lambda s: (-int(s.supported and s.significant), -s.explained))
    return out


def current_evidence(log: EnvelopeLog, inputs: EnvelopeInputs) -> dict[str, Any] | None:
    """Whether the logged current grows faster than tau / Kt at high torque (a saturating core): the slope of
    Kt i - tau against tau^3, with its standard error; None without a current channel."""
    if log.current is None:
        return None
    x = log.torque**3
    y = inputs.spec.kt * log.current - log.torque
    A = np.column_stack([x, log.torque, np.ones_like(x)])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    resid = y - A @ coef
    cov = np.linalg.pinv(A.T @ A) * float(np.sum(resid**2)) / max(x.size - 3, 1)
    slope, se = float(coef[0]), math.sqrt(max(float(cov[0, 0]), 0.0))
    significant = slope > 5 * se
    return {
        "slope": slope,
        "se": se,
        "significant": significant,
        "text": f"the logged current exceeds tau/Kt by {slope:.3g} +- {se:.2g} A/Kt per (N m)^3"
        + ("" if significant else " (not significant)"),
    }


def bus_evidence(log: EnvelopeLog, inputs: EnvelopeInputs) -> dict[str, Any] | None:
    """The pack resistance the logged bus voltage shows: V_nominal - V_bus against the bus current P / V_nominal
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
    x = power[motoring] / spec.bus_voltage
    y = spec.bus_voltage - log.bus_voltage[motoring]
    A = np.column_stack([x, np.ones_like(x)])
    coef, res, *_ = np.linalg.lstsq(A, y, rcond=None)
    dof = max(x.size - 2, 1)
    sigma2 = float(res[0]) / dof if res.size else float(np.var(y - A @ coef))
    se = math.sqrt(sigma2 / max(float(np.sum((x - x.mean()) ** 2)), 1e-30))
    r_pack = float(coef[0])
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

    @property
    def final(self) -> Step:
        return self.ladder[-1]


def _excess(log: EnvelopeLog, inputs: EnvelopeInputs, noise: float) -> tuple[Array, float, NDArray[np.bool_]]:
    """(how far each sample passes the spec sheet's edges [N m], the threshold, the samples past it)."""
    lo, hi = envelope(log.velocity, {}, _inputs_for(log, inputs, np.arange(log.n)))
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
        value = next(s.value for s in ladder[-1].suggestions if s.effect == name)
        model = {**model, name: value}
        model = _refit(log, walls, model, inputs)
        # with the effect in, edges the spec sheet missed line up: look for walls again and refit on them
        again = find_walls(log, inputs, model)
        if _bins(again) > _bins(walls):
            walls = again
            model = _refit(log, walls, model, inputs, all_params=True)
        step_offsets = offsets(log, walls, model, inputs)
        ladder.append(Step(dict(model), name, step_offsets, tuple(suggest(log, walls, model, inputs))))
    baseline = offsets(log, walls, {}, inputs)
    return Comparison(
        log, inputs, walls, tuple(ladder), outside_stats(log, inputs, base.sample_noise), baseline=baseline
    )


def _bins(walls: Walls) -> int:
    return sum(w.size > 0 for w in walls.upper) + sum(w.size > 0 for w in walls.lower)


def _refit(
    log: EnvelopeLog, walls: Walls, model: Mapping[str, float], inputs: EnvelopeInputs, all_params: bool = False
) -> dict[str, float]:
    """One coordinate-descent sweep over the model's parameters, each refitted with the others fixed."""
    fitted = dict(model)
    if len(fitted) > 1 or all_params:
        for name in list(fitted):
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
    return {
        "added": step.added,
        "model": step.model,
        "envelope_rmse": step.offsets.rmse,
        "noise_level": step.offsets.noise,
        "why": why,
    }


def comparison_json(c: Comparison) -> dict[str, Any]:
    """The ``hound-id/mor-compare/1`` JSON."""
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
        "bins_at_limit": int(last.offsets.offset.size),
        "outside_fraction": c.outside["fraction"],
        "outside": c.outside,
        "envelope_rmse": {"model": before.rmse, "with_added": last.offsets.rmse},
        # explained: the error at the noise level, and (against the spec sheet) no share of samples past its edges
        "explained": bool(
            last.offsets.rmse <= EXPLAINED * max(last.offsets.noise, 1e-12)
            and (bool(last.model) or c.outside["fraction"] <= OUTSIDE_OK)
        ),
        "coverage": coverage(last.offsets),
        "noise_level": last.offsets.noise,
        "sample_noise": first.offsets.sample_noise,
        "model": last.model,
        "added": [s.added for s in c.ladder[1:]],
        "suggestions": [s.to_dict() for s in last.suggestions],
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
