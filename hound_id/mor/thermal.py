"""The winding's heat: a first-order thermal model, the resistance and Kt following the temperature, and the drive's
current derating.

One thermal node, the winding, with a thermal resistance R_th [K/W] to the ambient and a time constant tau = R_th C
[s] (the drive-side I^2 t model: ODrive's, VESC's and moteus's motor-temperature limits act on one such
temperature). The copper loss is P = c R(T) i^2, with i the model's current (:mod:`hound_id.mor.spec`: the peak
phase current i_q under field-oriented control, the DC current under six-step) and R the model's DC-equivalent
resistance, so c is the ratio of the true loss to R i^2: 3/2 R_ph i^2 = (sqrt(3)/2) R i^2 under field-oriented
control (R = sqrt(3) R_ph), R i^2 under six-step (two phases in series). Temperatures are in degC, as in the dyno
logs (:mod:`hound_id.dyno.logs`): the model uses only differences and T - 20 degC.

    C dT/dt = c R(T) i^2 - (T - T_amb) / R_th,     R(T) = R20 (1 + a_R (T - 20)),     Kt(T) = Kt20 (1 + a_K (T - 20))

The resistance rises with the copper's 0.393 %/K; the magnets' flux, and so Kt and the back-EMF constant 1/Kv, fall
with NdFeB's -0.09 to -0.12 %/K (a fit's measured drift, ``kt_temp_coeff``, where the spec carries one). Because
R(T) is linear in T, the model is linear in T for a held current, so every question has a closed form:

    dT/dt = a T + b,   a = (R_th k - 1) / tau,   b = (R_th p0 + T_amb) / tau,
    k = c R20 a_R i^2,   p0 = c R20 (1 - 20 a_R) i^2

the steady state is -b/a (a < 0), the time to reach a temperature is ln((T1 + b/a) / (T0 + b/a)) / a, and one
control step of length dt with the current held is exact: T' = T + (a T + b) dt phi(a dt), phi(z) = (e^z - 1)/z.
Past the current where R_th k = 1 (a >= 0) the winding runs away: its resistance heats faster than it cools.

**Derating.** The drive lowers its current limit linearly from the full limit at ``derate_start`` to zero at the
winding limit (ODrive's ``temp_limit_lower``/``upper``, VESC's ``l_temp_motor_start``/``end``), so the winding
settles below its limit whatever is commanded. The continuous current is the current the winding holds at its limit
in steady state, sqrt((T_lim - T_amb) / (c R(T_lim) R_th)).

**The region at a temperature.** With R -> s_R R, Kt and 1/Kv -> s_K Kt, s_K/Kv (s = 1 + a (T - 20)), the
inductance unchanged, and the current-torque curve scaled by s_K (the flux scales the torque at every current; the
saturation is taken not to move with temperature), the DC-equivalent voltage equation divided by s_R is the 20 degC
one at speed s_K omega / s_R and bus voltage V / s_R, with the reactance seen 1/s_K larger in the linear-equivalent
torque. So the window at T is s_K times the 20 degC window at that speed and bus, with k_rho / s_K, exactly
(:meth:`hound_id.mor.saturation.Saturation.__call__`'s ``temperature``); :func:`hot_spec` builds the same motor as a
spec, for the region (:mod:`hound_id.mor.region`) and the tests.

Only numpy is needed (torch tensors work too): the runtime steps the temperature with :func:`step`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Temperature [degC] at which a spec's resistance, Kt and Kv hold (datasheets quote 20 or 25 degC; hound-id's fit
#: and simulator use 20).
REFERENCE = 20.0
#: Copper's resistance temperature coefficient at 20 degC [1/K] (annealed copper, IEC 60028: 0.00393).
COPPER = 0.00393
#: Kt's temperature coefficient [1/K] when neither the spec nor a fit gives one: the middle of NdFeB's remanence
#: coefficient, -0.09 to -0.12 %/K (assumed; SmCo is -0.03 to -0.05 %/K).
NDFEB = -0.0011
#: Ambient temperature [degC] when the spec gives none (assumed).
AMBIENT = 25.0
#: Width of the derating band below the winding limit [K] when the spec gives no ``derate_start``: ODrive's
#: thermistor defaults (``temp_limit_lower`` 100 degC, ``temp_limit_upper`` 120 degC); no lower than the ambient.
DERATE_BAND = 20.0
#: True copper loss over the model's R i^2, per commutation (module docstring).
LOSS_FACTOR = {"foc": math.sqrt(3.0) / 2.0, "six_step": 1.0}
#: Below this |a dt| the step uses phi(z) = 1 + z/2 (its error, z^2/6, is below float64's rounding).
_SMALL = 1e-8


@dataclass(frozen=True)
class Thermal:
    """A motor's winding temperature model and its drive's derating (module docstring). Temperatures in degC."""

    resistance: float
    """R_th, winding to ambient [K/W]."""
    time_constant: float
    """tau = R_th C [s]."""
    winding_limit: float
    """Highest winding temperature [degC]; the drive's current limit reaches zero there."""
    derate_start: float
    """Temperature [degC] at which the drive starts lowering its current limit (= ``winding_limit``: none before)."""
    ambient: float
    """Ambient temperature [degC]."""
    alpha_resistance: float
    """a_R, the resistance's temperature coefficient [1/K]."""
    alpha_kt: float
    """a_K, Kt's (and the back-EMF constant's) temperature coefficient [1/K]."""
    copper_loss: float
    """c R20 [ohm]: the copper loss at 20 degC per squared model current, P = c R20 (1 + a_R (T - 20)) i^2."""
    alpha_kt_source: str = ""
    """Where a_K comes from (the spec, a fit, or the NdFeB default)."""
    continuous_given: float | None = None
    """The continuous current the spec stated [A], when R_th was derived from it."""

    def scales(self, temperature: Any) -> tuple[Any, Any]:
        """(s_R, s_K) = (R(T)/R20, Kt(T)/Kt20) at winding temperatures [degC] (arrays or tensors)."""
        dt = temperature - REFERENCE
        return 1.0 + self.alpha_resistance * dt, 1.0 + self.alpha_kt * dt

    def derating(self, temperature: Any) -> Any:
        """The drive's current-limit factor in [0, 1] at winding temperatures [degC]: 1 up to ``derate_start``, then
        linear to 0 at ``winding_limit`` (a step there if the two coincide)."""
        return derating(temperature, self.derate_start, self.winding_limit)

    def power(self, temperature: Any, current: Any) -> Any:
        """Copper loss [W] at winding temperatures [degC] and model currents [A]."""
        return self.copper_loss * (1.0 + self.alpha_resistance * (temperature - REFERENCE)) * current * current

    def step(self, temperature: Any, current: Any, dt: float) -> Any:
        """The winding temperature [degC] after ``dt`` [s] with ``current`` [A] held (exact; :func:`step`)."""
        return step(
            temperature, current, dt, self.resistance, self.time_constant, self.ambient, self.copper_loss,
            self.alpha_resistance,
        )  # fmt: skip

    def rates(self, current: float) -> tuple[float, float]:
        """(a [1/s], b [K/s]) of dT/dt = a T + b with ``current`` [A] held."""
        return rates(
            current, self.resistance, self.time_constant, self.ambient, self.copper_loss, self.alpha_resistance
        )

    def steady(self, current: float) -> float:
        """Steady winding temperature [degC] with ``current`` [A] held; inf past the runaway current."""
        a, b = self.rates(current)
        return -b / a if a < 0 else math.inf

    def time_to(self, target: float, current: float, start: float | None = None) -> float:
        """Time [s] the winding takes from ``start`` (default: the ambient) to ``target`` [degC] with ``current`` [A]
        held, in closed form (module docstring); inf if it never gets there, 0 if it is there."""
        t0 = self.ambient if start is None else start
        if target <= t0:
            return 0.0
        a, b = self.rates(current)
        if a == 0.0:
            return (target - t0) / b if b > 0 else math.inf
        ratio = (target + b / a) / (t0 + b / a)
        return math.log(ratio) / a if ratio > 0 and math.log(ratio) / a > 0 else math.inf

    def continuous_current(self, temperature: float | None = None) -> float:
        """Current [A] the winding holds in steady state at ``temperature`` (default: its limit)."""
        t = self.winding_limit if temperature is None else temperature
        s_r = 1.0 + self.alpha_resistance * (t - REFERENCE)
        return math.sqrt(max(t - self.ambient, 0.0) / (self.copper_loss * s_r * self.resistance))

    @property
    def runaway_current(self) -> float:
        """Current [A] past which the winding heats without bound (R_th c R20 a_R i^2 = 1); inf if a_R <= 0."""
        if self.alpha_resistance <= 0:
            return math.inf
        return 1.0 / math.sqrt(self.resistance * self.copper_loss * self.alpha_resistance)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (SI, temperatures in degC)."""
        return {
            "thermal_resistance": self.resistance,
            "thermal_time_constant": self.time_constant,
            "winding_limit": self.winding_limit,
            "derate_start": self.derate_start,
            "ambient": self.ambient,
            "alpha_resistance": self.alpha_resistance,
            "alpha_kt": self.alpha_kt,
            "alpha_kt_source": self.alpha_kt_source,
            "copper_loss_per_current_squared": self.copper_loss,
            "continuous_current": self.continuous_current(),
            "units": {
                "thermal_resistance": "K/W",
                "thermal_time_constant": "s",
                "winding_limit": "degC",
                "derate_start": "degC",
                "ambient": "degC",
                "alpha_resistance": "1/K",
                "alpha_kt": "1/K",
                "copper_loss_per_current_squared": "W/A^2 (at 20 degC)",
                "continuous_current": "A",
            },
        }


def thermal_from_fields(
    *,
    resistance_20: float,
    commutation: str,
    time_constant: float,
    winding_limit: float,
    thermal_resistance: float | None = None,
    continuous_current: float | None = None,
    ambient: float | None = None,
    derate_start: float | None = None,
    alpha_resistance: float | None = None,
    alpha_kt: float | None = None,
    alpha_kt_source: str = "",
) -> Thermal:
    """A :class:`Thermal` from a spec's fields (SI, degC): R_th given, or derived from the continuous current at the
    winding limit. The caller has checked that exactly one of the two is given and the values are in range."""
    amb = AMBIENT if ambient is None else ambient
    a_r = COPPER if alpha_resistance is None else alpha_resistance
    loss = LOSS_FACTOR[commutation] * resistance_20
    if thermal_resistance is None:
        assert continuous_current is not None
        s_r = 1.0 + a_r * (winding_limit - REFERENCE)
        thermal_resistance = (winding_limit - amb) / (loss * s_r * continuous_current**2)
    return Thermal(
        resistance=thermal_resistance,
        time_constant=time_constant,
        winding_limit=winding_limit,
        derate_start=max(winding_limit - DERATE_BAND, amb) if derate_start is None else derate_start,
        ambient=amb,
        alpha_resistance=a_r,
        alpha_kt=NDFEB if alpha_kt is None else alpha_kt,
        copper_loss=loss,
        alpha_kt_source=alpha_kt_source or ("NdFeB default (assumed)" if alpha_kt is None else "spec"),
        continuous_given=continuous_current,
    )


def _lib(x: Any) -> Any:
    if type(x).__module__.startswith("torch"):
        import torch

        return torch
    return np


def derating(temperature: Any, start: Any, limit: Any) -> Any:
    """The current-limit factor (see :meth:`Thermal.derating`), elementwise, numpy or torch; NaN stays NaN."""
    lib = _lib(temperature)
    band = limit - start
    if lib is np:
        with np.errstate(divide="ignore", invalid="ignore"):
            ramp = np.where(band > 0, (limit - temperature) / np.where(band > 0, band, 1.0), 0.0)
        d = np.where(temperature < start, 1.0, np.clip(ramp, 0.0, 1.0))
        return np.where(np.isnan(temperature), np.nan, d)
    band_t = lib.as_tensor(band, dtype=temperature.dtype, device=temperature.device)
    ramp = lib.where(band_t > 0, (limit - temperature) / lib.where(band_t > 0, band_t, lib.ones_like(band_t)), 0.0)
    d = lib.where(temperature < start, lib.ones_like(temperature), lib.clamp(ramp, 0.0, 1.0))
    return lib.where(lib.isnan(temperature), temperature, d)


def rates(
    current: Any, resistance: Any, time_constant: Any, ambient: Any, copper_loss: Any, alpha_resistance: Any
) -> tuple[Any, Any]:
    """(a [1/s], b [K/s]) of dT/dt = a T + b with ``current`` [A] held (module docstring), elementwise."""
    i2 = current * current
    k = copper_loss * alpha_resistance * i2
    p0 = copper_loss * (1.0 - REFERENCE * alpha_resistance) * i2
    return (resistance * k - 1.0) / time_constant, (resistance * p0 + ambient) / time_constant


def step(
    temperature: Any,
    current: Any,
    dt: float,
    resistance: Any,
    time_constant: Any,
    ambient: Any,
    copper_loss: Any,
    alpha_resistance: Any,
) -> Any:
    """One exact step of the winding temperature [degC] over ``dt`` [s] with each ``current`` [A] held (module
    docstring); the parameters broadcast (per motor), numpy or torch, float32 or float64."""
    lib = _lib(temperature)
    a, b = rates(current, resistance, time_constant, ambient, copper_loss, alpha_resistance)
    z = a * dt
    small = abs(z) < _SMALL
    if lib is np:
        with np.errstate(over="ignore"):  # a runaway held for long: inf, as the physics says
            phi = np.where(small, 1.0 + 0.5 * z, np.expm1(z) / np.where(small, 1.0, z))
            return temperature + (a * temperature + b) * dt * phi
    phi = lib.where(small, 1.0 + 0.5 * z, lib.expm1(z) / lib.where(small, lib.ones_like(z), z))
    return temperature + (a * temperature + b) * dt * phi
