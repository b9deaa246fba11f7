"""Synthetic dynamometer logs with known truth, for testing the current-torque identification.

A load motor holds the motor under test at a sequence of speed plateaus while the
motor under test sweeps its current (triangular ramps and short steps beyond the
application's maximum current). The transducer torque is, with ``sgn(w) = tanh(w / eps)``
and ``eps = SIGN_EPS = 0.01 rad/s``::

    measured(t) = H[tau](t - delay) + offset + noise,     noise ~ N(0, noise_std^2), white
    tau = kt i
          - k_sat i |i|                                          saturation
          - k_sat3 i^3                                           saturation_cubic
          - k_knee sign(i) h(|i|),                               saturation_knee
                h(x) = x - i_k - i_k ln(x / i_k) for x > i_k else 0,   i_k = knee_current
          + kt_temp_coeff i (T - 20)                             thermal (T in degC)
          - coulomb sgn(w)                                       coulomb
          - viscous w                                            viscous
          - stribeck sgn(w) exp(-(w / stribeck_speed)^2)         stribeck
          - gear_friction |i| sgn(w)                             gear_friction
          + sum_{h=1,2} cogging_sin_h sin(h N theta) + cogging_cos_h cos(h N theta)
                                                                 cogging, N = cogging_order
          + i (ripple_sin sin(M theta) + ripple_cos cos(M theta))  ripple, M = ripple_order
          - inertia dw/dt                                        inertia (rotor and coupling before the sensor)

``H`` is the transducer's own dynamics, the identity unless simulated: "lag", a first-order
low-pass 1 / (1 + s lag_tau), and "resonance", a second-order one
w0^2 / (s^2 + 2 resonance_zeta w0 s + w0^2), w0 = 2 pi resonance_f0 (lag first when both); they
are integrated by the trapezoidal rule on a grid ten times finer than the log's (at least
10 kHz), from rest at the first torque, and read at the sample times.

``offset`` is the effect "offset" and ``delay`` the effect "delay": the torque channel
lags the current channel, so the torque logged at time t is the physical torque at
t - delay; current, velocity, position and temperature are logged undelayed. The
signals are continuous-time functions of the plan (current piecewise linear, speed
constant with raised-cosine transitions, position its exact integral), so the delayed
torque is evaluated exactly at t - delay; only the winding temperature is interpolated
(linearly) from its grid. Before the log starts the rig is taken to sit at the first
plateau speed at zero current and ambient temperature.

The winding temperature follows C dT/dt = R i^2 - (T - ambient) / R_th from ambient,
discretised exactly for a power that is linear between grid points (grid: the samples,
or 1 kHz when logging slower).

Typical magnitudes (:func:`typical_truth`) follow ``physics-notes.md`` and are assumed,
not measured; they are sized to the motor's peak torque (the torque at ``max_current``
20 % below linear, the project's definition of peak torque).

The test plan and its schedule of set-points are in :mod:`hound_id.dyno.simulate.schedule`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hound_id.dyno.simulate.schedule import SHAPES, TestPlan, check_finite, schedule
from hound_id.errors import DynoDataError

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd


__all__ = [
    "COLUMNS", "EFFECTS", "EFFECT_PARAMETERS", "PARAMETERS", "PARAMETER_UNITS", "SHAPES", "SHAPE_PARAMETERS",
    "SIGN_EPS", "SimMotor", "SimulatedLog", "TestPlan", "physical_torque", "simulate", "smooth_sign", "typical_truth",
]  # fmt: skip

#: Every effect the simulator (and the fit) knows; "linear" (kt i) is always present.
EFFECTS: tuple[str, ...] = (
    "linear",
    "saturation",
    "saturation_cubic",
    "saturation_knee",
    "offset",
    "coulomb",
    "viscous",
    "stribeck",
    "gear_friction",
    "cogging",
    "ripple",
    "thermal",
    "inertia",
    "lag",
    "resonance",
    "delay",
)


#: The parameters each effect switches on; they are 0 when the effect is not simulated.
EFFECT_PARAMETERS: Mapping[str, tuple[str, ...]] = MappingProxyType(
    {
        "linear": ("kt",),
        "saturation": ("k_sat",),
        "saturation_cubic": ("k_sat3",),
        "saturation_knee": ("k_knee",),
        "offset": ("offset",),
        "coulomb": ("coulomb",),
        "viscous": ("viscous",),
        "stribeck": ("stribeck",),
        "gear_friction": ("gear_friction",),
        "cogging": ("cogging_sin_1", "cogging_cos_1", "cogging_sin_2", "cogging_cos_2"),
        "ripple": ("ripple_sin", "ripple_cos"),
        "thermal": ("kt_temp_coeff",),
        "inertia": ("inertia",),
        "lag": ("lag_tau",),
        "resonance": ("resonance_f0", "resonance_zeta"),
        "delay": ("delay",),
    }
)


#: Shape parameters: they keep their nominal value even when their effect is off (it then has no influence).
SHAPE_PARAMETERS: Mapping[str, str] = MappingProxyType(
    {
        "knee_current": "saturation_knee",
        "stribeck_speed": "stribeck",
        "cogging_order": "cogging",
        "ripple_order": "ripple",
    }
)


#: Every key of a truth mapping.
PARAMETERS: tuple[str, ...] = (
    *(p for e in EFFECTS for p in EFFECT_PARAMETERS[e]),
    *SHAPE_PARAMETERS,
    "noise_std",
)


#: Units of every parameter (for reports).
PARAMETER_UNITS: Mapping[str, str] = MappingProxyType(
    {
        "kt": "N m/A",
        "k_sat": "N m/A^2",
        "k_sat3": "N m/A^3",
        "k_knee": "N m/A",
        "knee_current": "A",
        "offset": "N m",
        "coulomb": "N m",
        "viscous": "N m s/rad",
        "stribeck": "N m",
        "stribeck_speed": "rad/s",
        "gear_friction": "N m/A",
        "cogging_sin_1": "N m",
        "cogging_cos_1": "N m",
        "cogging_sin_2": "N m",
        "cogging_cos_2": "N m",
        "cogging_order": "1/rev",
        "ripple_sin": "N m/A",
        "ripple_cos": "N m/A",
        "ripple_order": "1/rev",
        "kt_temp_coeff": "N m/A/K",
        "inertia": "kg m^2",
        "lag_tau": "s",
        "resonance_f0": "Hz",
        "resonance_zeta": "1",
        "delay": "s",
        "noise_std": "N m",
    }
)


#: Speed scale of the smoothed sign, sgn(w) = tanh(w / SIGN_EPS) [rad/s].
SIGN_EPS = 0.01
#: Temperature at which kt is quoted [degC].
KT_REFERENCE_TEMPERATURE = 20.0
#: Fractional drop of the torque below kt i at max_current in :func:`typical_truth` (notes: 10-35 %).
SATURATION_DROP = 0.20
#: Speed at which typical viscous drag is 1 % of peak torque: the top plateau of the default plan [rad/s].
VISCOUS_REFERENCE_SPEED = 40.0
#: The winding temperature is integrated on the sample grid, or on this finer grid when logging slower [Hz].
THERMAL_GRID_HZ = 1000.0


COLUMNS = ("time", "current", "torque", "velocity", "position", "temperature", "bus_voltage")


# typical_truth, relative sizes (physics-notes.md; all assumed)
_NOISE_FRACTION = 0.002  # of peak torque
_OFFSET_FRACTION = 0.003  # of peak torque (notes: 0.1-0.5 % of full scale)
_COULOMB_FRACTION = 0.01  # of peak torque (notes: 0.5-1 %)
_STRIBECK_RATIO = 0.4  # extra static friction / Coulomb (notes: 1.2-1.5 total)
_STRIBECK_SPEED = 3.0  # rad/s
_VISCOUS_FRACTION = 0.01  # of peak torque at VISCOUS_REFERENCE_SPEED
_GEAR_FRICTION = 0.04  # N m per N m (notes: "0.04 N m per N m reported")
_COGGING_FRACTION = (0.008, 0.0024)  # first and second harmonic amplitude, of peak torque (notes: 0.5-1 %)
_COGGING_PHASE = (0.5, -1.2)  # rad
_COGGING_ORDER = 24
_RIPPLE_FRACTION = 0.005  # of kt: amplitude per amp
_RIPPLE_PHASE = 0.9  # rad
_RIPPLE_ORDER = 42
_TEMP_COEFF = -0.0011  # 1/K, NdFeB (notes: -0.09..-0.12 %/K)
_DELAY = 0.005  # s (notes: 1-15 ms)
_LAG_TAU = 0.002  # s: a transducer amplifier's filter of 80 Hz (assumed)
_RESONANCE = (60.0, 0.1)  # Hz and damping ratio: a torque flange's coupling mode (assumed)
#: The transducer's dynamics are integrated on a grid this fine at least, and ten times the log's rate [Hz].
FILTER_GRID_HZ = 10_000.0
_INERTIA_FRACTION = 1.3e-4  # kg m^2 per N m of peak torque: rotor, coupling and transducer flange before the sensor,
# 1e-3 kg m^2 for the default 7.7 N m motor (assumed)
_KNEE_FRACTION = 0.4  # knee current / max_current
_SATURATIONS = ("saturation", "saturation_cubic", "saturation_knee")


@dataclass(frozen=True)
class SimMotor:
    """The motor under test, in SI units; the defaults are a Hound-like 85 mm motor (assumed)."""

    kt: float = 0.138
    """Torque constant at 20 degC [N m/A] (per peak phase amp, as the sample spec)."""
    max_current: float = 70.0
    """The application's maximum current [A] (the Hound drive limit); the plan overdrives beyond it."""
    resistance: float = 0.1
    """Winding resistance that heats the winding, P = R i^2 [ohm]."""
    thermal_resistance: float = 1.5
    """Thermal resistance winding to ambient [K/W]."""
    thermal_capacitance: float = 60.0
    """Thermal capacitance of the winding [J/K]."""
    ambient: float = 25.0
    """Ambient temperature, also the winding temperature at the start of the log [degC]."""

    def __post_init__(self) -> None:
        for name in ("kt", "max_current", "resistance", "thermal_resistance", "thermal_capacitance"):
            object.__setattr__(self, name, check_finite(getattr(self, name), f"SimMotor.{name}", positive=True))
        object.__setattr__(self, "ambient", check_finite(self.ambient, "SimMotor.ambient"))

    @property
    def peak_torque(self) -> float:
        """Peak torque [N m]: the torque at max_current 20 % below linear, (1 - SATURATION_DROP) kt max_current."""
        return (1.0 - SATURATION_DROP) * self.kt * self.max_current

    @property
    def thermal_time_constant(self) -> float:
        """R_th C [s]."""
        return self.thermal_resistance * self.thermal_capacitance

    def scaled(self, factor: float) -> SimMotor:
        """A motor ``factor`` times bigger: the same motor with a ``factor`` times longer stack.

        The torque constant, the winding resistance (copper length) and the thermal capacitance
        (mass) grow by ``factor``, the thermal resistance shrinks by it (cooling surface); current
        limit and ambient stay. Heating per amp and the thermal time constant are therefore
        unchanged, so the same plan gives the same temperature trace, while every torque
        (and every typical magnitude, which is sized to the peak torque) scales by ``factor``.

        Args:
            factor: Size ratio, > 0.

        Raises:
            DynoDataError: ``factor`` is not a positive finite number.
        """
        f = check_finite(factor, "scale factor", positive=True)
        return SimMotor(
            kt=self.kt * f,
            max_current=self.max_current,
            resistance=self.resistance * f,
            thermal_resistance=self.thermal_resistance / f,
            thermal_capacitance=self.thermal_capacitance * f,
            ambient=self.ambient,
        )


@dataclass(frozen=True)
class SimulatedLog:
    """A synthetic dyno log and the truth it was made from."""

    frame: pd.DataFrame
    """Columns ``COLUMNS``: time [s] (from 0, uniform at rate_hz), current [A] (as logged, with current
    noise), torque [N m] (transducer: delayed, offset, noisy), velocity [rad/s], position [rad] (unwrapped,
    0 at the first sample), temperature [degC] (winding), bus_voltage [V]."""
    truth: Mapping[str, float]
    """Every parameter of ``PARAMETERS`` -> its true value (read-only; units in ``PARAMETER_UNITS``)."""
    effects: tuple[str, ...]
    """Simulated effects, in the order of ``EFFECTS``; always includes "linear"."""
    seed: int
    """Seed of the noise generator."""
    motor: SimMotor = field(default_factory=SimMotor)
    """The motor under test."""
    plan: TestPlan = field(default_factory=TestPlan)
    """The test plan that was run."""
    rate_hz: float = 1000.0
    """Logging rate [Hz]."""


def _normalise_effects(effects: Sequence[str] | str) -> tuple[str, ...]:
    """Validated effect names in ``EFFECTS`` order, with "linear" added."""
    names = (effects,) if isinstance(effects, str) else tuple(effects)
    for name in names:
        if name not in EFFECTS:
            raise DynoDataError(
                f"unknown effect {name!r}; expected one of: {', '.join(EFFECTS)}", effect=name, expected=EFFECTS
            )
    chosen = {"linear", *names}
    return tuple(e for e in EFFECTS if e in chosen)


def _knee_h(x: float, knee: float) -> float:
    return x - knee - knee * math.log(x / knee) if x > knee else 0.0


def typical_truth(effects: Sequence[str], motor: SimMotor = SimMotor()) -> dict[str, float]:
    """Realistic true parameters for ``effects``, sized to ``motor`` (magnitudes assumed, from the physics notes).

    With P the motor's peak torque (:attr:`SimMotor.peak_torque`): noise_std 0.2 % P; offset 0.3 % P;
    coulomb 1 % P; stribeck 0.4 coulomb with stribeck_speed 3 rad/s; viscous 1 % P at 40 rad/s;
    gear_friction 0.04 kt; cogging order 24 with harmonics of 0.8 % and 0.24 % P; ripple order 42 with
    amplitude 0.5 % kt per amp; kt_temp_coeff -0.0011 kt per K (NdFeB); inertia 1.3e-4 kg m^2 per N m of P;
    lag 2 ms; resonance at 60 Hz with damping 0.1; delay 5 ms. The chosen saturation forms together make the torque
    at max_current 20 % below kt max_current, shared equally (the knee sits at 0.4 max_current). Parameters of effects
    not chosen are 0; shape parameters (knee_current, stribeck_speed, cogging_order, ripple_order) keep their nominal
    value.

    Args:
        effects: Effect names from ``EFFECTS``.
        motor: The motor under test (default :class:`SimMotor`).

    Returns:
        Every name of ``PARAMETERS`` -> value (SI; orders as integral floats).

    Raises:
        DynoDataError: An unknown effect name.
    """
    chosen = _normalise_effects(effects)
    kt, imax, peak = motor.kt, motor.max_current, motor.peak_torque
    knee = _KNEE_FRACTION * imax
    n_sat = sum(e in chosen for e in _SATURATIONS)
    drop = SATURATION_DROP * kt * imax / max(n_sat, 1)  # torque each saturation form removes at max_current
    cog1, cog2 = (f * peak for f in _COGGING_FRACTION)
    ripple = _RIPPLE_FRACTION * kt
    values = {
        "kt": kt,
        "k_sat": drop / imax**2,
        "k_sat3": drop / imax**3,
        "k_knee": drop / _knee_h(imax, knee),
        "offset": _OFFSET_FRACTION * peak,
        "coulomb": _COULOMB_FRACTION * peak,
        "viscous": _VISCOUS_FRACTION * peak / VISCOUS_REFERENCE_SPEED,
        "stribeck": _STRIBECK_RATIO * _COULOMB_FRACTION * peak,
        "gear_friction": _GEAR_FRICTION * kt,
        "cogging_sin_1": cog1 * math.cos(_COGGING_PHASE[0]),
        "cogging_cos_1": cog1 * math.sin(_COGGING_PHASE[0]),
        "cogging_sin_2": cog2 * math.cos(_COGGING_PHASE[1]),
        "cogging_cos_2": cog2 * math.sin(_COGGING_PHASE[1]),
        "ripple_sin": ripple * math.cos(_RIPPLE_PHASE),
        "ripple_cos": ripple * math.sin(_RIPPLE_PHASE),
        "kt_temp_coeff": _TEMP_COEFF * kt,
        "inertia": _INERTIA_FRACTION * peak,
        "lag_tau": _LAG_TAU,
        "resonance_f0": _RESONANCE[0],
        "resonance_zeta": _RESONANCE[1],
        "delay": _DELAY,
    }
    truth = {p: (values[p] if e in chosen else 0.0) for e in EFFECTS for p in EFFECT_PARAMETERS[e]}
    truth.update(
        knee_current=knee,
        stribeck_speed=_STRIBECK_SPEED,
        cogging_order=float(_COGGING_ORDER),
        ripple_order=float(_RIPPLE_ORDER),
        noise_std=_NOISE_FRACTION * peak,
    )
    return {p: float(truth[p]) for p in PARAMETERS}


def _merge_truth(base: dict[str, float], overrides: Mapping[str, float], effects: tuple[str, ...]) -> dict[str, float]:
    """``base`` updated with validated ``overrides``."""
    truth = dict(base)
    for key, value in overrides.items():
        if key not in truth:
            raise DynoDataError(
                f"truth: unknown parameter {key!r}; expected one of: {', '.join(PARAMETERS)}", parameter=key
            )
        truth[key] = check_finite(value, f"truth[{key!r}]")
    owner = {p: e for e, ps in EFFECT_PARAMETERS.items() for p in ps}
    for key in overrides:
        effect = owner.get(key)
        if effect is not None and effect not in effects and truth[key] != 0.0:
            raise DynoDataError(
                f"truth[{key!r}] = {truth[key]:g} but effect {effect!r} is not simulated; add it to effects",
                parameter=key,
                effect=effect,
            )
    for key in ("kt", "knee_current", "stribeck_speed"):
        check_finite(truth[key], f"truth[{key!r}]", positive=True)
    for key in ("delay", "noise_std", "lag_tau", "resonance_f0", "resonance_zeta"):
        check_finite(truth[key], f"truth[{key!r}]", nonnegative=True)
    if truth["resonance_f0"] > 0 and truth["resonance_zeta"] <= 0:
        raise DynoDataError(
            f"truth['resonance_zeta']: found {truth['resonance_zeta']:g}, expected a positive damping ratio",
            parameter="resonance_zeta",
        )
    for key in ("cogging_order", "ripple_order"):
        if truth[key] < 1 or truth[key] != round(truth[key]):
            raise DynoDataError(f"truth[{key!r}]: found {truth[key]:g}, expected a positive integer", parameter=key)
    return truth


def _sensor_dynamics(
    tau: NDArray[np.float64], rate: float, params: Mapping[str, float], dynamics: Sequence[str]
) -> NDArray[np.float64]:
    """The torque as the transducer reads it: each of ``dynamics`` ("lag", then "resonance") integrated by the
    trapezoidal rule (Tustin; no added delay, and at a grid ten times the log's the error is far below any noise), from
    rest at the first value."""
    from scipy.signal import cont2discrete, lfilter, lfilter_zi, ss2tf

    out = np.asarray(tau, dtype=np.float64)
    for name in dynamics:
        if name == "lag":
            tc = params["lag_tau"]
            system = (np.array([[-1.0 / tc]]), np.array([[1.0 / tc]]), np.array([[1.0]]), np.array([[0.0]]))
        else:
            w0, zeta = 2 * math.pi * params["resonance_f0"], params["resonance_zeta"]
            A = np.array([[0.0, 1.0], [-(w0**2), -2.0 * zeta * w0]])
            system = (A, np.array([[0.0], [w0**2]]), np.array([[1.0, 0.0]]), np.array([[0.0]]))
        Ad, Bd, Cd, Dd, _ = cont2discrete(system, 1.0 / rate, method="bilinear")
        b, a = ss2tf(Ad, Bd, Cd, Dd)
        b, a = np.asarray(b, float).ravel() / a[0], np.asarray(a, float) / a[0]
        out = lfilter(b, a, out, zi=lfilter_zi(b, a) * out[0])[0]
    return out


def smooth_sign(velocity: ArrayLike) -> NDArray[np.float64]:
    """sgn(w) = tanh(w / SIGN_EPS), the smoothed sign of every friction term [-]."""
    return np.tanh(np.asarray(velocity, dtype=np.float64) / SIGN_EPS)


def physical_torque(
    current: ArrayLike,
    velocity: ArrayLike,
    position: ArrayLike,
    temperature: ArrayLike,
    truth: Mapping[str, float],
    acceleration: ArrayLike = 0.0,
) -> NDArray[np.float64]:
    """The shaft torque tau of the module formula, without offset, delay and noise [N m].

    Args:
        current: Current [A].
        velocity: Rotor speed [rad/s].
        position: Rotor angle [rad].
        temperature: Winding temperature [degC].
        truth: Parameters by name (``PARAMETERS``); a missing effect parameter counts as 0.
        acceleration: Rotor acceleration [rad/s^2] (for ``inertia``).

    Returns:
        tau, broadcast over the inputs.
    """

    def get(name: str) -> float:
        return float(truth.get(name, 0.0))

    i, w, theta, temp = np.broadcast_arrays(
        *(np.asarray(a, dtype=np.float64) for a in (current, velocity, position, temperature))
    )
    tau = get("kt") * i  # a new array, updated in place below
    abs_i = np.abs(i)
    if get("k_sat"):
        tau -= get("k_sat") * i * abs_i
    if get("k_sat3"):
        tau -= get("k_sat3") * i * i * i
    if get("k_knee"):
        knee = get("knee_current")
        x = np.maximum(abs_i, knee)  # h is 0 up to the knee
        tau -= get("k_knee") * np.sign(i) * (x - knee - knee * np.log(x / knee))
    if get("kt_temp_coeff"):
        tau += get("kt_temp_coeff") * i * (temp - KT_REFERENCE_TEMPERATURE)
    if get("coulomb") or get("stribeck") or get("gear_friction"):
        sgn = smooth_sign(w)
        friction = np.full(tau.shape, get("coulomb"))
        if get("stribeck"):
            friction += get("stribeck") * np.exp(-np.square(w / get("stribeck_speed")))
        if get("gear_friction"):
            friction += get("gear_friction") * abs_i
        tau -= friction * sgn
    if get("viscous"):
        tau -= get("viscous") * w
    if any(get(p) for p in EFFECT_PARAMETERS["cogging"]):
        angle = get("cogging_order") * theta
        s1, c1 = np.sin(angle), np.cos(angle)
        tau += get("cogging_sin_1") * s1 + get("cogging_cos_1") * c1
        # second harmonic by the double-angle identities (equal to sin/cos(2 angle) to rounding)
        tau += get("cogging_sin_2") * 2.0 * s1 * c1 + get("cogging_cos_2") * (c1 - s1) * (c1 + s1)
    if get("ripple_sin") or get("ripple_cos"):
        angle = get("ripple_order") * theta
        tau += i * (get("ripple_sin") * np.sin(angle) + get("ripple_cos") * np.cos(angle))
    if get("inertia"):
        tau -= get("inertia") * np.asarray(acceleration, dtype=np.float64)
    return tau


def _first_order_filter(drive: NDArray[np.float64], decay: float) -> NDArray[np.float64]:
    """y[n] = decay y[n-1] + drive[n] with y[-1] = 0, in numpy only (scipy.signal would take a second to import).

    Blocks of length L are solved in closed form, y_j = decay^j cumsum(drive_k decay^-k), with L
    small enough that decay^-L stays below 1e150; block ends are chained by the same filter with
    decay^L, recursively. ``drive`` must be >= 0 (no cancellation in the sums).
    """
    n = drive.size
    rate = -math.log(decay) if decay > 0 else math.inf
    max_len = n if rate == 0 else int(min(n, 345.0 / rate))
    if n == 0 or max_len <= 1:
        return drive.copy()  # decay < 1e-150: no memory
    blocks = -(-n // max_len)
    padded = np.zeros(blocks * max_len)
    padded[:n] = drive
    d = padded.reshape(blocks, max_len)
    j = np.arange(max_len, dtype=np.float64)
    local = np.cumsum(d * decay ** (-j), axis=1) * decay**j
    if blocks > 1:
        ends = _first_order_filter(local[:, -1].copy(), decay**max_len)
        local += np.concatenate(([0.0], ends[:-1]))[:, None] * decay ** (j + 1)
    return local.ravel()[:n]


def _winding_temperature(
    times: NDArray[np.float64], current: NDArray[np.float64], motor: SimMotor
) -> NDArray[np.float64]:
    """Solve C dT/dt = R i^2 - (T - ambient)/R_th from ambient on a uniform grid, exactly for power linear in time."""
    if times.size < 2:
        return np.full(times.shape, motor.ambient)
    dt = float(times[1] - times[0])
    x = dt / motor.thermal_time_constant
    decay = math.exp(-x)
    gamma = 1.0 + math.expm1(-x) / x  # weight of the end-of-step power
    power = motor.resistance * current**2
    drive = motor.thermal_resistance * (power[:-1] * (-math.expm1(-x) - gamma) + power[1:] * gamma)
    rise = np.empty(times.size)
    rise[0] = 0.0
    rise[1:] = _first_order_filter(drive, decay)
    return motor.ambient + rise


def simulate(
    effects: Sequence[str] = ("linear", "saturation"),
    *,
    motor: SimMotor = SimMotor(),
    plan: TestPlan | None = None,
    truth: Mapping[str, float] | None = None,
    seed: int = 0,
    rate_hz: float = 1000.0,
    noise_std: float | None = None,
    current_noise_std: float = 0.0,
) -> SimulatedLog:
    """Simulate a dynamometer log of ``motor`` running ``plan`` with the chosen effects.

    Args:
        effects: Effect names from ``EFFECTS`` ("linear" is always added; a single string is one name).
        motor: The motor under test (default :class:`SimMotor`, Hound-like).
        plan: The rig's schedule (default :class:`TestPlan`, 60 s).
        truth: Overrides of :func:`typical_truth` entries. Effect parameters of effects not simulated
            must stay 0.
        seed: Seed of the noise (numpy ``default_rng``); the signals themselves do not depend on it.
        rate_hz: Logging rate [Hz].
        noise_std: Standard deviation of the white torque noise [N m]; None takes ``truth["noise_std"]``
            if given, else the typical 0.2 % of peak torque.
        current_noise_std: Standard deviation of white noise on the logged current channel [A]; the
            torque is made by the true current.

    Returns:
        The log and its truth.

    Raises:
        DynoDataError: Unknown effect or parameter, or a non-physical argument.
    """
    import pandas as pd

    plan = plan if plan is not None else TestPlan()
    chosen = _normalise_effects(effects)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise DynoDataError(f"seed: found {seed!r}, expected an integer >= 0", value=seed)
    rate = check_finite(rate_hz, "rate_hz", positive=True)
    params = _merge_truth(typical_truth(chosen, motor), truth or {}, chosen)
    if noise_std is not None:
        params["noise_std"] = check_finite(noise_std, "noise_std", nonnegative=True)
    sigma_i = check_finite(current_noise_std, "current_noise_std", nonnegative=True)

    sched = schedule(plan, motor.max_current)
    n = int(math.floor(sched.duration * rate + 1e-9)) + 1
    if n < 2:
        raise DynoDataError(f"rate_hz: {rate:g} Hz gives {n} sample over {sched.duration:g} s, expected at least 2")
    time = np.arange(n, dtype=np.float64) / rate
    current = sched.current(time)
    velocity, position = sched.speed_and_position(time)
    grid, grid_temp, temperature = _temperatures(sched, time, current, rate, motor)
    state = (current, velocity, position, temperature)
    tau = _true_torque(sched, time, state, (grid, grid_temp), params, chosen, rate, motor)

    torque, logged_current = _logged(tau, current, params, sigma_i, int(seed))
    bus = plan.bus_voltage - plan.bus_sag * np.abs(current)

    frame = pd.DataFrame(
        {
            "time": time,
            "current": logged_current,
            "torque": torque,
            "velocity": velocity,
            "position": position,
            "temperature": temperature,
            "bus_voltage": bus,
        },
        columns=list(COLUMNS),
    )
    return SimulatedLog(
        frame=frame,
        truth=MappingProxyType(params),
        effects=chosen,
        seed=int(seed),
        motor=motor,
        plan=plan,
        rate_hz=rate,
    )


def _logged(
    tau: NDArray[np.float64], current: NDArray[np.float64], params: Mapping[str, float], sigma_i: float, seed: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(logged torque, logged current): the offset and the seeded white noise of each channel added."""
    n = tau.size
    rng = np.random.default_rng(seed)
    torque = tau + params["offset"]
    if params["noise_std"] > 0:
        torque += params["noise_std"] * rng.standard_normal(n)
    logged_current = current + sigma_i * rng.standard_normal(n) if sigma_i > 0 else current
    return torque, logged_current


def _temperatures(
    sched: Any, time: NDArray[np.float64], current: NDArray[np.float64], rate: float, motor: SimMotor
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(grid [s], winding temperature there [degC], at the sample times [degC]) from ambient."""
    if rate >= THERMAL_GRID_HZ:
        grid, grid_temp = time, _winding_temperature(time, current, motor)
        temperature = grid_temp
    else:
        grid = np.arange(int(math.floor(sched.duration * THERMAL_GRID_HZ)) + 2, dtype=np.float64) / THERMAL_GRID_HZ
        grid_temp = _winding_temperature(grid, sched.current(grid), motor)
        temperature = np.interp(time, grid, grid_temp)
    return grid, grid_temp, temperature


def _true_torque(
    sched: Any,
    time: NDArray[np.float64],
    state: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]],
    thermal: tuple[NDArray[np.float64], NDArray[np.float64]],
    params: dict[str, float],
    chosen: tuple[str, ...],
    rate: float,
    motor: SimMotor,
) -> NDArray[np.float64]:
    """The torque the sensor reads before offset and noise [N m]: delayed, through its dynamics if simulated."""
    current, velocity, position, temperature = state
    grid, grid_temp = thermal
    delay = params["delay"]
    dynamics = [e for e in ("lag", "resonance") if e in chosen]
    if dynamics:  # the transducer's dynamics on a fine grid, read at the sample times
        fine_rate = max(FILTER_GRID_HZ, 10.0 * rate)
        fine = np.arange(int(math.floor(sched.duration * fine_rate + 1e-9)) + 1, dtype=np.float64) / fine_rate
        lagged = fine - delay
        w_lag, theta_lag = sched.speed_and_position(lagged)
        temp_lag = np.interp(lagged, grid, grid_temp, left=motor.ambient)
        tau_fine = physical_torque(
            sched.current(lagged), w_lag, theta_lag, temp_lag, params, sched.acceleration(lagged)
        )
        return np.interp(time, fine, _sensor_dynamics(tau_fine, fine_rate, params, dynamics))
    if delay > 0:
        lagged = time - delay
        w_lag, theta_lag = sched.speed_and_position(lagged)
        temp_lag = np.interp(lagged, grid, grid_temp, left=motor.ambient)
        return physical_torque(sched.current(lagged), w_lag, theta_lag, temp_lag, params, sched.acceleration(lagged))
    return physical_torque(current, velocity, position, temperature, params, sched.acceleration(time))
