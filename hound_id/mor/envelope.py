"""Torque-speed envelope models: the operating region's boundary with physical effects added.

The spec-sheet region (:mod:`hound_id.mor.region`) bounds the torque at motor speed omega by the
torque limit and by the voltage the bus can apply, V_bus >= R i + omega/Kv with i = tau/Kt.
Real envelopes differ for physical reasons; each is an :class:`EnvelopeEffect` with one
parameter, and effects compose: the boundary at a speed is the edge of the set of torques
that satisfy every condition at once,

    |V_req(tau, omega)| <= V_avail(tau, omega),   |i(tau)| <= I_lim,   |tau| <= tau_lim,

    V_req   = R(T) i(tau) + omega/Kv          (in quadrature with p omega L i for ``inductance``)
    V_avail = V_bus - R_x P / V_bus,  P = V_req i  (the inverter's input power; R_x = R_pack when
              motoring, P > 0, and -R_regen when regenerating, P < 0)

* ``bus_sag`` (R_pack [ohm]): the pack's internal resistance drops the bus under motoring load;
* ``regen_rise`` (R_regen [ohm]): regenerated current raises the bus when braking;
* ``thermal_resistance`` (alpha [1/K], copper 0.0039): R(T) = R (1 + alpha (T - 25 degC)), with
  the winding temperature from the log;
* ``inductance`` (L [H]): the q-axis current needs p omega L i of voltage in quadrature;
* ``current_limit`` (I_lim [A]): the driver clamps the current below the spec's limit;
* ``kt_saturation`` (s [-]): i(tau) follows the fitted current-torque curve of ``fit-current
  --out`` (its compensation polynomial), s scaling its departure from tau/Kt.

:func:`envelope` evaluates the boundary by bisection on the torque (the feasible set at one
speed is an interval around the zero-voltage torque), vectorised over speeds.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hound_id.errors import SpecError
from hound_id.mor.spec import MotorSpec

#: Temperature at which a spec sheet's resistance holds [degC] (datasheets quote 20-25 degC).
T_SPEC = 25.0
#: Temperature coefficient of copper resistivity [1/K].
COPPER_ALPHA = 0.0039
#: Bisection steps: 60 halvings of the torque interval, far below any sensor's resolution.
BISECTION_STEPS = 60

Array = NDArray[np.float64]


@dataclass(frozen=True)
class EnvelopeEffect:
    """One physical reason for the measured envelope to differ from the spec sheet's."""

    name: str
    physics: str
    """One sentence of physics."""
    parameter: str
    unit: str
    bounds: tuple[float, float]
    """Physically sensible range of the parameter."""
    neutral: float
    """Value at which the effect does nothing."""
    requires: tuple[str, ...] = ()
    """Log channels or inputs it needs: ``temperature``, ``pole_pairs``, ``compensation``."""


EFFECTS: dict[str, EnvelopeEffect] = {
    e.name: e
    for e in sorted(
        [
            EnvelopeEffect(
                "bus_sag",
                "the battery's internal resistance drops the bus voltage under motoring load",
                "r_pack",
                "ohm",
                (0.0, 5.0),
                0.0,
            ),
            EnvelopeEffect(
                "regen_rise",
                "regenerated current raises the bus voltage while braking",
                "r_regen",
                "ohm",
                (0.0, 5.0),
                0.0,
            ),
            EnvelopeEffect(
                "thermal_resistance",
                "the winding's copper resistance grows 0.39 %/K as it heats",
                "alpha",
                "1/K",
                (0.0, 0.01),
                0.0,
                ("temperature",),
            ),
            EnvelopeEffect(
                "inductance",
                "the q-axis current needs p omega L i of voltage in quadrature at speed",
                "inductance",
                "H",
                (0.0, 0.01),
                0.0,
                ("pole_pairs",),
            ),
            EnvelopeEffect(
                "current_limit",
                "the driver clamps the current below the spec sheet's limit",
                "i_limit",
                "A",
                (0.0, np.inf),
                np.inf,
            ),
            EnvelopeEffect(
                "kt_saturation",
                "the core saturates: torque per amp falls at high current, so each "
                "newton metre costs more current and voltage",
                "scale",
                "-",
                (0.0, 2.0),
                0.0,
                ("compensation",),
            ),
        ],  # fmt: skip
        key=lambda e: e.name,
    )
}


@dataclass(frozen=True)
class EnvelopeInputs:
    """What the boundary depends on besides the speed: the spec and, per point, the log's state."""

    spec: MotorSpec
    temperature: Array | None = None
    """Winding temperature per point [degC], if logged."""
    compensation: tuple[tuple[int, ...], tuple[float, ...]] | None = None
    """(powers, coefficients) of current [A] = sum c_k tau^k from fit-current, if given."""


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
                or (need == "compensation" and inputs.compensation is None)
            )
            if missing:
                raise SpecError(f"envelope: {name} needs {need}, which this comparison does not have")
        values[name] = float(value)
    return values


def _current(tau: Array, inputs: EnvelopeInputs, scale: float) -> Array:
    linear = tau / inputs.spec.kt
    if scale == 0.0 or inputs.compensation is None:
        return linear
    powers, coefficients = inputs.compensation
    curve = sum(c * tau**p for p, c in zip(powers, coefficients, strict=True))  # odd powers: odd in tau
    return np.asarray(linear + scale * (curve - linear), dtype=float)


def feasible(tau: Array, omega: Array, params: Mapping[str, float], inputs: EnvelopeInputs) -> NDArray[np.bool_]:
    """Whether each (tau, omega) [N m, rad/s] satisfies every condition (module docstring)."""
    spec = inputs.spec
    p = _checked(params, inputs)
    i = _current(tau, inputs, p.get("kt_saturation", 0.0))
    resistance = spec.resistance * np.ones_like(omega)
    if "thermal_resistance" in p and inputs.temperature is not None:
        resistance = resistance * (1.0 + p["thermal_resistance"] * (inputs.temperature - T_SPEC))
    v_q = resistance * i + omega / spec.kv
    v_req = v_q
    if p.get("inductance", 0.0) > 0.0:
        v_req = np.hypot(v_q, (spec.pole_pairs or 0) * omega * p["inductance"] * i)
    power = v_q * i  # the quadrature part carries no power
    r_x = np.where(power > 0.0, p.get("bus_sag", 0.0), p.get("regen_rise", 0.0))
    v_avail = spec.bus_voltage - r_x * power / spec.bus_voltage
    i_limit = min(spec.max_current or np.inf, p.get("current_limit", np.inf))
    ok = (np.abs(v_req) <= v_avail) & (np.abs(i) <= i_limit) & (np.abs(tau) <= spec.torque_limit)
    if spec.max_speed is not None:  # past the rated speed only braking passes, as in the region
        ok &= ~((np.abs(omega) > spec.max_speed) & (tau * omega > 0))
    return np.asarray(ok)


def envelope(omega: ArrayLike, params: Mapping[str, float], inputs: EnvelopeInputs) -> tuple[Array, Array]:
    """Lowest and highest feasible torque [N m] at each motor speed [rad/s] (NaN where none is).

    The search starts at the zero-voltage torque, tau0 = -Kt omega / (R Kv) clamped to the torque
    and current limits, and bisects outwards on :func:`feasible`. Past the rated speed only
    braking torque is feasible, as in :func:`hound_id.mor.region.torque_interval`.
    """
    spec = inputs.spec
    w = np.asarray(omega, dtype=float)
    cap = spec.torque_limit
    i_limit = min(spec.max_current or np.inf, float(params.get("current_limit", np.inf)))
    start = min(cap, 0.999 * spec.kt * i_limit)  # inside the current limit too (linear curve)
    tau0 = np.clip(-spec.kt * w / (spec.resistance * spec.kv), -start, start)
    ok0 = feasible(tau0, w, params, inputs)
    for _ in range(40):  # a curved current-torque line may need a smaller start: move towards zero torque
        if ok0.all():
            break
        tau0 = np.where(ok0, tau0, 0.8 * tau0)
        ok0 = feasible(tau0, w, params, inputs)
    bounds = []
    for edge in (-cap, cap):
        inside, outside = tau0.copy(), np.full_like(w, edge)
        done = feasible(outside, w, params, inputs)
        inside = np.where(done, outside, inside)
        for _ in range(BISECTION_STEPS):
            mid = 0.5 * (inside + outside)
            good = feasible(mid, w, params, inputs)
            inside = np.where(good & ~done, mid, inside)
            outside = np.where(~good & ~done, mid, outside)
        bounds.append(np.where(ok0, inside, np.nan))
    return bounds[0], bounds[1]


def simulate_log(
    inputs: EnvelopeInputs,
    params: Mapping[str, float],
    n: int = 20000,
    noise: float = 0.02,
    speed_fraction: float = 0.9,
    seed: int = 0,
    temperature_range: tuple[float, float] = (30.0, 90.0),
) -> dict[str, Array]:
    """A seeded log of a motor driven past its envelope with hidden effects (for tests and demos).

    Speeds are uniform within ``speed_fraction`` of the no-load speed; commands are uniform over
    1.5 x the torque limit; the realised torque is the command clipped to the true envelope plus
    Gaussian sensor noise [N m]. Columns: velocity [rad/s], torque [N m], current [A],
    temperature [degC] (a slow sweep over ``temperature_range``) and bus_voltage [V].
    """
    rng = np.random.default_rng(seed)
    spec = inputs.spec
    no_load = spec.bus_voltage * spec.kv
    omega = rng.uniform(-speed_fraction, speed_fraction, n) * no_load
    t_lo, t_hi = temperature_range
    temperature = t_lo + (t_hi - t_lo) * 0.5 * (1 - np.cos(np.linspace(0, 2 * np.pi, n)))
    truth = EnvelopeInputs(spec, temperature=temperature, compensation=inputs.compensation)
    lo, hi = envelope(omega, params, truth)
    command = rng.uniform(-1.5, 1.5, n) * spec.torque_limit
    tau = np.clip(command, lo, hi)
    i = _current(tau, truth, params.get("kt_saturation", 0.0))
    power = (spec.resistance * i + omega / spec.kv) * i
    r_x = np.where(power > 0, params.get("bus_sag", 0.0), params.get("regen_rise", 0.0))
    return {
        "velocity": omega,
        "torque": tau + noise * rng.standard_normal(n),
        "current": i,
        "temperature": temperature,
        "bus_voltage": spec.bus_voltage - r_x * power / spec.bus_voltage,
    }


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
