"""Torque-speed envelope models: the operating region's boundary with physical effects added.

The spec-sheet region (:mod:`hound_id.mor.region`) bounds the torque at motor speed omega by the
torque limit and by the voltage the bus can apply, V_bus >= R i + omega/Kv with i = tau/Kt.
Real envelopes differ for physical reasons; each is an :class:`EnvelopeEffect` with one
parameter, and effects compose: the boundary at a speed is the edge of the set of torques
that satisfy every condition at once,

    |V_req(tau, omega)| <= V_avail(tau, omega),   |i(tau)| <= I_lim,   |tau| <= tau_lim,

    V_req   = R(T) i(tau) + omega/Kv          (in quadrature with p omega L i for ``inductance``)
    V_avail = V_bus - R_x P / V_avail,  P = V_q i  (the inverter's input power; R_x = R_pack when
              motoring, P > 0, and R_regen when regenerating, P < 0, which raises the bus): the
              bus voltage itself, (V_bus + sqrt(V_bus^2 - 4 R_x P)) / 2

* ``bus_sag`` (R_pack [ohm]): the pack's internal resistance drops the bus under motoring load;
* ``regen_rise`` (R_regen [ohm]): regenerated current raises the bus when braking;
* ``thermal_resistance`` (alpha [1/K], copper 0.0039): R(T) = R (1 + alpha (T - 25 degC)), with
  the winding temperature from the log;
* ``inductance`` (L [H]): the q-axis current needs p omega L i of voltage in quadrature;
* ``current_limit`` (I_lim [A]): the driver clamps the current below the spec's limit;
* ``kt_saturation`` (s [-]): i(tau) follows the fitted current-torque curve of ``fit-current
  --out`` (its exact inverse, :class:`hound_id.mor.current_curve.CurrentCurve`), s scaling its
  departure from tau/Kt.

The model starts from the linear-Kt region (:func:`hound_id.mor.region.linear_region`): the torque cap
is the peak torque and the current limit is applied through i(tau), so with no effect the cap is
min(peak torque, Kt i_max), the spec sheet's linear figure (``MotorSpec.linear_torque_limit``); a
measured current-torque curve enters only as ``kt_saturation``, which the log must show.

:func:`envelope` evaluates the boundary by a root search on the torque (the feasible set at one
speed is an interval around the zero-voltage torque), vectorised over speeds, started from the
closed-form edge of a linear current-torque line.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hound_id.arrays import frozen
from hound_id.errors import SpecError
from hound_id.mor.current_curve import CurrentCurve
from hound_id.mor.envelope_effects import EFFECTS, EnvelopeEffect  # noqa: F401 - EnvelopeEffect re-exported
from hound_id.mor.spec import MotorSpec

#: Temperature at which a spec sheet's resistance holds [degC] (datasheets quote 20-25 degC).
T_SPEC = 25.0
#: Temperature coefficient of copper resistivity [1/K].
COPPER_ALPHA = 0.0039
#: Bisection steps: 44 halvings of the torque interval (under 1e-12 of it), far below any sensor's resolution.
BISECTION_STEPS = 44
#: The edge's root search stops when its bracket is this share of the torque limit (or after so many steps).
EDGE_TOLERANCE = 1e-12
EDGE_ITERATIONS = 100
#: A voltage this share below the bus voltage is below it whatever the rounding (the edge's start, :func:`edge`).
NO_LOAD_MARGIN = 1e-9

Array = NDArray[np.float64]


@dataclass(frozen=True)
class EnvelopeInputs:
    """What the boundary depends on besides the speed: the spec and, per point, the log's state."""

    spec: MotorSpec
    temperature: Array | None = None
    """Winding temperature per point [degC], if logged."""
    curve: CurrentCurve | None = None
    """The fitted current-torque curve (``fit-current --out``), if given."""


def _checked(params: Mapping[str, float], inputs: EnvelopeInputs) -> dict[str, float]:
    values = {}
    for name, value in params.items():
        if name not in EFFECTS:
            raise SpecError(f"envelope: unknown effect {name!r}; known: {', '.join(EFFECTS)}")
        effect = EFFECTS[name]
        lo, hi = effect.bounds
        if not lo <= value <= hi:
            raise SpecError(
                f"envelope: {name} {effect.parameter} = {value:g} {effect.unit} is outside [{lo:g}, {hi:g}]"
            )
        for need in effect.requires:
            missing = (
                (need == "temperature" and inputs.temperature is None)
                or (need == "pole_pairs" and not inputs.spec.pole_pairs)
                or (need == "current_curve" and inputs.curve is None)
            )
            if missing:
                raise SpecError(f"envelope: {name} needs {need}, which this comparison does not have")
        values[name] = float(value)
    return values


def bus_voltage(v0: float, r_x: Array | float, power: Array) -> Array:
    """The bus voltage [V] while the inverter draws ``power`` [W] from a source of open-circuit voltage ``v0``
    through ``r_x`` [ohm]: V = v0 - r_x P / V, so V = (v0 + sqrt(v0^2 - 4 r_x P)) / 2 (the high root; regenerated
    power, P < 0, raises it). Past the most the source can deliver, v0^2 / (4 r_x), no voltage is: -v0 (infeasible).
    """
    disc = v0 * v0 - 4.0 * np.asarray(r_x) * power
    return np.asarray(np.where(disc >= 0.0, 0.5 * (v0 + np.sqrt(np.maximum(disc, 0.0))), -v0), dtype=float)


def motor_current(tau: Array, inputs: EnvelopeInputs, scale: float) -> Array:
    linear = tau / inputs.spec.kt
    if scale == 0.0 or inputs.curve is None:
        return linear
    return np.asarray(linear + scale * (inputs.curve.current(tau) - linear), dtype=float)


@dataclass(frozen=True)
class _Voltage:
    """The voltage condition at each speed, |V_req| <= V_avail (module docstring), with what does not depend on the
    torque worked out once. Per-speed values are arrays, or floats where every speed shares them."""

    inputs: EnvelopeInputs
    resistance: Array | float
    """Winding resistance [ohm]."""
    back_emf: Array
    """omega / Kv [V]."""
    quadrature: Array | None
    """p omega L [ohm]: the quadrature voltage per ampere (None without inductance)."""
    scale: float
    """``kt_saturation``'s share of the current-torque curve's departure from tau / Kt [-]."""
    sag: float
    """R_pack [ohm] (motoring)."""
    rise: float
    """R_regen [ohm] (regenerating)."""

    @classmethod
    def of(cls, omega: Array, p: Mapping[str, float], inputs: EnvelopeInputs) -> _Voltage:
        spec = inputs.spec
        resistance: Array | float = spec.resistance
        if "thermal_resistance" in p and inputs.temperature is not None:
            temperature = np.broadcast_to(inputs.temperature, omega.shape)
            resistance = spec.resistance * (1.0 + p["thermal_resistance"] * (temperature - T_SPEC))
        inductance = p.get("inductance", 0.0)
        quadrature = omega * ((spec.pole_pairs or 0) * inductance) if inductance > 0.0 else None
        sag, rise = p.get("bus_sag", 0.0), p.get("regen_rise", 0.0)
        return cls(inputs, resistance, omega / spec.kv, quadrature, p.get("kt_saturation", 0.0), sag, rise)

    def take(self, idx: NDArray[np.int64] | NDArray[np.bool_]) -> _Voltage:
        """The condition at the speeds ``idx`` (indices or a mask)."""
        r = self.resistance if isinstance(self.resistance, float) else self.resistance[idx]
        q = None if self.quadrature is None else self.quadrature[idx]
        return _Voltage(self.inputs, r, self.back_emf[idx], q, self.scale, self.sag, self.rise)

    def current(self, tau: Array) -> Array:
        """Motor current [A] for each torque [N m]."""
        return motor_current(tau, self.inputs, self.scale)

    def margin(self, tau: Array, i: Array | None = None) -> Array:
        """The voltage condition's margin [V] at each speed's torque ``tau`` [N m] (current ``i`` [A] if known),
        >= 0 where it holds.

        With the bus's discriminant D = v0^2 - 4 R_x P the condition V_avail = (v0 + sqrt(D)) / 2 >= |V_req| is
        D >= max(2 |V_req| - v0, 0)^2 (D >= 0 included: the most power the source can deliver). The margin is
        (D - max(2 |V_req| - v0, 0)^2) / (4 v0), which is V_avail - |V_req| to first order at the edge of a stiff
        bus; unlike that difference it has no square-root cusp where the power limit binds, so the edge's root
        search converges there as fast as elsewhere. A stiff bus (no sag, no rise) has V_avail = v0 exactly.
        """
        # in place where it can: fresh arrays of a few hundred kilobytes cost more than the arithmetic on them
        i = self.current(tau) if i is None else i
        v0 = self.inputs.spec.bus_voltage
        v_q = self.resistance * i
        v_q += self.back_emf
        if self.quadrature is None:
            v_req = np.abs(v_q)
        else:  # |V_req| = hypot(v_q, p omega L i) to rounding, many times faster
            v_req = self.quadrature * i
            v_req *= v_req
            v_req += v_q * v_q
            np.sqrt(v_req, out=v_req)
        if self.sag == self.rise == 0.0:
            return np.asarray(np.subtract(v0, v_req, out=v_req))
        power = v_q
        power *= i  # the quadrature part carries no power; R_x P below
        if self.sag == self.rise:
            power *= self.sag
        elif self.rise == 0.0:
            np.maximum(power, 0.0, out=power)
            power *= self.sag
        elif self.sag == 0.0:
            np.minimum(power, 0.0, out=power)
            power *= self.rise
        else:
            power *= np.where(power > 0.0, self.sag, self.rise)
        short = v_req  # how far |V_req| passes half the open-circuit voltage, doubled, squared
        short *= 2.0
        short -= v0
        np.maximum(short, 0.0, out=short)
        short *= short
        power *= -4.0
        power += v0 * v0
        power -= short
        power *= 1.0 / (4.0 * v0)
        return np.asarray(power)

    def guess(self, side: NDArray[np.int8]) -> Array:
        """Where each speed's edge on ``side`` (+1 upper, -1 lower) lies for a linear current-torque line [N m]: the
        root search's first step, exact to rounding unless ``kt_saturation`` bends the line.

        On the edge the in-phase voltage is side V, and V = v0 - R_x P / V with P = side V i, so R i + e = side v0 -
        R_x i: with the quadrature voltage, ((R + R_x) i + e)^2 + (p omega L i)^2 = v0^2, exact unless both R_x and
        L are in; then Newton steps on D = (2 |V_req| - v0)^2 (:meth:`margin`, up to three) make it so. R_x is
        R_pack where the edge motors (side i > 0), else R_regen. A root on the bus's low branch (|V_req| < v0 / 2) is
        past the most power the pack delivers, which then binds first: D = 0, 4 R_pack (R i + e) i = v0^2.
        """
        v0, r, e = self.inputs.spec.bus_voltage, self.resistance, self.back_emf
        q = 0.0 if self.quadrature is None else self.quadrature

        def line(r_x: float, at: NDArray[np.bool_] | slice = slice(None)) -> Array:
            rr = (r if isinstance(r, float) else r[at]) + r_x
            qq = 0.0 if self.quadrature is None else self.quadrature[at] ** 2
            a = rr * rr + qq
            return np.asarray((side[at] * np.sqrt(np.maximum(a * v0 * v0 - qq * e[at] * e[at], 0.0)) - rr * e[at]) / a)

        i = line(self.sag)
        braking = side * i <= 0.0  # the edge regenerates there: the regen resistance instead
        if self.rise != self.sag and braking.any():
            i[braking] = line(self.rise, braking)
        r_x = np.where(braking, self.rise, self.sag)
        if self.quadrature is not None and (self.sag or self.rise):
            with np.errstate(divide="ignore", invalid="ignore"):  # a degenerate step (NaN) is not taken
                for _ in range(3):
                    v_q = r * i + e
                    v_req = np.sqrt(v_q * v_q + q * q * i * i)
                    short = 2.0 * v_req - v0
                    slope = -4.0 * r_x * (r * i + v_q) - 4.0 * short * (v_q * r + q * q * i) / v_req
                    step = (v0 * v0 - 4.0 * r_x * v_q * i - short * short) / slope
                    i = i - step
                    if not np.any(np.abs(step) > 1e-13 * np.abs(i)):  # converged to rounding (NaN: not taken)
                        break
        if self.sag > 0.0:
            v_q = r * i + e
            low = (side * i > 0.0) & (2.0 * np.sqrt(v_q * v_q + (q * i) ** 2) < v0)
            if low.any():
                r_low, e_low = (r if isinstance(r, float) else r[low]), e[low]
                i[low] = (side[low] * np.sqrt(e_low * e_low + r_low * v0 * v0 / self.sag) - e_low) / (2.0 * r_low)
        return np.asarray(self.inputs.spec.kt * i)


def feasible(tau: Array, omega: Array, params: Mapping[str, float], inputs: EnvelopeInputs) -> NDArray[np.bool_]:
    """Whether each (tau, omega) [N m, rad/s] satisfies every condition (module docstring)."""
    p = _checked(params, inputs)
    tau, omega = np.broadcast_arrays(np.asarray(tau, dtype=float), np.asarray(omega, dtype=float))
    volts = _Voltage.of(omega, p, inputs)
    i = volts.current(tau)
    return _feasible(tau, i, volts.margin(tau, i), omega, _current_limit(p, inputs), inputs.spec)


def _feasible(tau: Array, i: Array, margin: Array, omega: Array, i_limit: float, spec: MotorSpec) -> NDArray[np.bool_]:
    """Whether each torque ``tau`` [N m], with its current ``i`` [A] and voltage margin [V], at ``omega`` [rad/s]
    satisfies every condition."""
    ok = (margin >= 0.0) & (np.abs(i) <= i_limit) & (np.abs(tau) <= spec.linear_torque_limit)
    if spec.max_speed is not None:  # past the rated speed only braking passes, as in the region
        ok &= ~((np.abs(omega) > spec.max_speed) & (tau * omega > 0))
    return np.asarray(ok)


def _current_limit(p: Mapping[str, float], inputs: EnvelopeInputs) -> float:
    """The driver's current limit [A]: the spec's, or the ``current_limit`` effect's below it."""
    return float(min(inputs.spec.max_current or np.inf, p.get("current_limit", np.inf)))


def envelope(omega: ArrayLike, params: Mapping[str, float], inputs: EnvelopeInputs) -> tuple[Array, Array]:
    """Lowest and highest feasible torque [N m] at each motor speed [rad/s] (NaN where none is).

    The search starts at the zero-voltage torque, tau0 = -Kt omega / (R Kv) clamped to the torque
    and current limits, and looks outwards for the edge of :func:`feasible` (:func:`edge`). Past the
    rated speed only braking torque is feasible, as in :func:`hound_id.mor.region.torque_interval`.
    """
    return edge(omega, -1, params, inputs), edge(omega, 1, params, inputs)


def edge(omega: ArrayLike, side: ArrayLike, params: Mapping[str, float], inputs: EnvelopeInputs) -> Array:
    """One edge of :func:`envelope`: the highest (``side`` = +1) or lowest (-1) feasible torque [N m] at each
    motor speed [rad/s] (``side`` may be given per speed), NaN where none is. Half the work of both when only one
    is needed.

    Between the zero-voltage torque and the torque and current limits only the voltage condition can bind, and
    its margin (:meth:`_Voltage.margin`) is continuous in the torque: its root is found by the Illinois method
    (regula falsi that halves a stale end), whose first steps bracket the edge in closed form for a linear
    current-torque line (:meth:`_Voltage.guess`; they end the search when it is on the root). Each speed leaves
    the search once its own bracket is :data:`EDGE_TOLERANCE` of the torque limit or its feasible end's margin
    that share of the bus voltage. (Earlier versions started from the bracket's ends, ran every speed until all had
    converged and searched V_avail - |V_req|, which jumps where the pack's power limit binds; their edges agree
    with these within that tolerance.)
    """
    spec = inputs.spec
    p = _checked(params, inputs)
    w = np.asarray(omega, dtype=float)
    s = np.broadcast_to(np.asarray(side, dtype=np.int8), w.shape)
    cap = spec.linear_torque_limit
    i_limit = _current_limit(p, inputs)
    start = min(cap, 0.999 * spec.kt * i_limit)  # inside the current limit too (linear curve)
    volts = _Voltage.of(w, p, inputs)
    tau0 = w * (-spec.kt / (spec.resistance * spec.kv))
    np.clip(tau0, -start, start, out=tau0)
    # the start is within the torque limit and brakes (so passes past the rated speed), and with a linear current-
    # torque line within the current limit too: only the voltage, and a curve's current, can fail it
    curved = volts.scale != 0.0 and inputs.curve is not None

    def starts(t: Array, there: _Voltage) -> tuple[Array, NDArray[np.bool_]]:
        i = there.current(t)
        g = there.margin(t, i)
        return g, (g >= 0.0) & (np.abs(i) <= i_limit) if curved else g >= 0.0

    if curved or not isinstance(volts.resistance, float):
        ok0 = np.zeros(w.size, dtype=bool)
    else:
        # With a linear line and the spec's resistance the start needs |v_q| <= |e| and draws no power (it brakes: P
        # <= 0, so V_avail >= v0): it is feasible where |V_req| <= hypot(e, p omega L i) lies below v0.
        bound = volts.back_emf * volts.back_emf
        if volts.quadrature is not None:
            bound += (volts.quadrature * (tau0 / spec.kt)) ** 2
        ok0 = bound < ((1.0 - NO_LOAD_MARGIN) * spec.bus_voltage) ** 2
    bad = np.array([], dtype=np.int64) if ok0.all() else np.flatnonzero(~ok0)
    g0 = np.full(w.size, np.nan)  # the search's feasible end starts here (its margin: where it is needed)
    if bad.size:
        there, t = volts.take(bad), tau0[bad]
        for k in range(41):  # inductance or a curved current-torque line may need a smaller start: towards zero
            if k:
                t = t * 0.8
            g, good = starts(t, there)
            tau0[bad[good]], g0[bad[good]], ok0[bad[good]] = t[good], g[good], True
            if good.all():
                break
            bad, t, there = bad[~good], t[~good], there.take(~good)
    out: Array = np.asarray(s * _current_reach(p, inputs), dtype=float)  # torque and current limits on this side
    if spec.max_speed is not None:  # past the rated speed this edge passes no motoring torque
        out[(np.abs(w) > spec.max_speed) & (s * w > 0)] = 0.0
    g_reach = volts.margin(out)
    live = np.flatnonzero(ok0 & ~(g_reach >= 0.0))  # the voltage line binds before the limits (NaN: it binds)
    if live.size:
        there, s_live = volts.take(live), s[live]
        g_live = g0[live]
        unknown = np.isnan(g_live)  # a start feasible by construction
        if unknown.any():
            g_live[unknown] = there.take(unknown).margin(tau0[live[unknown]])
        out[live] = _illinois(there, tau0[live], out[live], g_live, g_reach[live], s_live, cap, there.guess(s_live))
    if not ok0.all():
        out[~ok0] = np.nan
    return out


def _illinois(
    volts: _Voltage, a: Array, b: Array, ga: Array, gb: Array, side: NDArray[np.int8], cap: float, guess: Array
) -> Array:
    """The root of ``volts``' margin between the feasible ``a`` and the infeasible ``b`` [N m] (margins ``ga`` and
    ``gb`` [V]) at each speed: its feasible end once its bracket is :data:`EDGE_TOLERANCE` x ``cap`` [N m] or its
    margin that share of the bus voltage (:func:`edge`). The first steps are a quarter of that bracket either side of
    the ``guess`` [N m], where they lie between a and b: a guess on the root closes the bracket there."""
    tol_tau, tol_v = EDGE_TOLERANCE * cap, EDGE_TOLERANCE * volts.inputs.spec.bus_voltage
    for probe in (guess - 0.25 * tol_tau * side, guess + 0.25 * tol_tau * side):  # the nearer one first
        g = volts.margin(probe)
        inner = (probe - a) * (probe - b) < 0.0  # NaN: not inside
        moves_a, moves_b = inner & (g >= 0.0), inner & ~(g >= 0.0)
        a, ga = np.where(moves_a, probe, a), np.where(moves_a, g, ga)
        b, gb = np.where(moves_b, probe, b), np.where(moves_b, g, gb)
    out = a.copy()
    live = np.arange(a.size)  # positions in out of the speeds still searched
    moved_a = np.zeros(a.size, dtype=bool)  # the last step moved a (b): a step of the same end again is stale
    moved_b = np.zeros(a.size, dtype=bool)
    for _ in range(EDGE_ITERATIONS):
        # a (the feasible end, returned) is on the root when its bracket is tiny or its margin nil
        done = ((b - a) * side <= tol_tau) | (ga <= tol_v)
        if done.any():  # those leave: the rest iterate on smaller arrays
            out[live[done]] = a[done]
            more = ~done
            if not more.any():
                return out
            live, a, b, ga, gb, side = live[more], a[more], b[more], ga[more], gb[more], side[more]
            moved_a, moved_b, volts = moved_a[more], moved_b[more], volts.take(more)
        c = b - gb * (b - a) / (gb - ga)
        c = np.where((c - a) * (c - b) < 0.0, c, 0.5 * (a + b))  # a NaN or infinite step: bisect
        gc = volts.margin(c)
        inside = gc >= 0.0  # NaN: outside
        gb = np.where(inside & moved_a, 0.5 * gb, gb)  # a moved twice: halve b's margin (Illinois)
        ga = np.where(moved_b & ~inside, 0.5 * ga, ga)
        a, ga = np.where(inside, c, a), np.where(inside, gc, ga)
        b, gb = np.where(inside, b, c), np.where(inside, gb, gc)
        moved_a, moved_b = inside, ~inside
    out[live] = a
    return out


def _current_reach(p: Mapping[str, float], inputs: EnvelopeInputs) -> float:
    """Largest torque magnitude [N m] within the torque limit and the current limit (the current-torque curve is
    odd and monotonic)."""
    spec = inputs.spec
    i_limit = _current_limit(p, inputs)
    scale = p.get("kt_saturation", 0.0)
    cap = np.array([spec.linear_torque_limit])
    if abs(motor_current(cap, inputs, scale)[0]) <= i_limit:
        return spec.linear_torque_limit
    if scale == 0.0 or inputs.curve is None:  # a linear line: Kt I_lim, a rounding below it if need be
        reach = spec.kt * i_limit
        return reach if reach / spec.kt <= i_limit else float(np.nextafter(reach, 0.0))
    lo, hi = np.array([0.0]), cap
    for _ in range(BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        below = abs(motor_current(mid, inputs, scale)[0]) <= i_limit
        lo, hi = (mid, hi) if below else (lo, mid)
    return float(lo[0])


def effect_names(inputs: EnvelopeInputs) -> list[str]:
    """The effects this comparison can test (those whose requirements it has)."""
    names = []
    for name, effect in EFFECTS.items():
        try:
            _checked({name: effect.neutral}, inputs)
        except SpecError:
            continue
        names.append(name)
    return names


#: Accuracy of the polyline boundary, as a share of the torque limit (0.2 %: far inside any sensor's accuracy).
POLYLINE_TOLERANCE = 0.002
#: The polyline starts from this many evenly spaced speeds across +-the no-load speed (one every 1/8 of it) and
#: halves each segment that misses at most POLYLINE_REFINEMENTS times (down to 1/131072 of the speed range); the miss
#: is probed at POLYLINE_PROBES of each segment.
POLYLINE_POINTS = 17
POLYLINE_REFINEMENTS = 14
POLYLINE_PROBES = (0.25, 0.5, 0.75)


@dataclass(frozen=True)
class Polyline:
    """A model's edges as polylines over motor speed (:func:`polyline`); read-only arrays."""

    speeds: Array
    """Motor speeds [rad/s], ascending."""
    upper: Array
    """Upper edge at each speed [N m] (NaN where no torque is feasible)."""
    lower: Array
    """Lower edge [N m]."""
    tolerance: float
    """The accuracy asked for [N m]."""
    max_error: float
    """The largest miss of linear interpolation found at the probes [N m]."""
    model: Mapping[str, float]
    """The effects evaluated (temperature-dependent ones left out)."""
    units: str = "rad/s, N m (motor side)"

    def to_dict(self) -> dict[str, Any]:
        """The ``polyline`` block of the ``hound-id/mor-compare/2`` JSON."""
        return {
            "speeds": self.speeds.tolist(),
            "upper": self.upper.tolist(),
            "lower": self.lower.tolist(),
            "tolerance": self.tolerance,
            "max_error": self.max_error,
            "model": dict(self.model),
            "units": self.units,
        }


def polyline(model: Mapping[str, float], inputs: EnvelopeInputs, tolerance: float | None = None) -> Polyline:
    """The model's edges as polylines over speed, refined until linear interpolation is within ``tolerance``
    [N m] (default :data:`POLYLINE_TOLERANCE` x the torque limit) of the model at a quarter, half and three
    quarters of every segment (``max_error`` is the largest miss found there).

    Temperature-dependent effects are evaluated at the spec's reference temperature.
    """
    spec = inputs.spec
    tol = tolerance if tolerance is not None else POLYLINE_TOLERANCE * spec.linear_torque_limit
    plain = {k: v for k, v in model.items() if "temperature" not in EFFECTS[k].requires}
    ref = EnvelopeInputs(spec, curve=inputs.curve)
    top = spec.bus_voltage * spec.kv
    speeds = np.linspace(-top, top, POLYLINE_POINTS)
    for _ in range(POLYLINE_REFINEMENTS):  # split every segment whose interpolation misses the model at a probe
        lo, hi = envelope(speeds, plain, ref)
        err = np.zeros(speeds.size - 1)
        for f in POLYLINE_PROBES:
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
    max_error = float(np.nanmax(err)) if err.size else 0.0
    return Polyline(frozen(speeds), frozen(hi), frozen(lo), tol, max_error, MappingProxyType(plain))


def fitted_curve(spec: MotorSpec) -> CurrentCurve | None:
    """The fitted current-torque curve of a fitted spec (``fit-current --out``), if it has one."""
    return spec.fit.curve if spec.fit is not None else None
