"""The region of a warm motor: the spec at a winding temperature, and the continuous region beside the peak one.

:mod:`hound_id.mor.thermal` holds the thermal model; this module applies it to a spec. At a winding temperature T
the resistance is s_R R, the torque constant s_K Kt, the speed constant Kv / s_K (the back-EMF constant falls with
the flux), the current-torque curve is scaled by s_K at every current, the inductance is unchanged, and the drive's
current limit is derated (:meth:`hound_id.mor.thermal.Thermal.derating`). :func:`hot_spec` is that motor as a
:class:`~hound_id.mor.spec.MotorSpec`, so every region function applies to it, and the saturation's ``temperature``
must agree with it (a test checks that).

The **continuous** operating point is where the drive's derated current limit meets the current the winding holds in
steady state: the winding settles there whatever is commanded (:func:`continuous_point`). Without derating before the
limit it is the continuous current at the winding limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

from scipy.optimize import brentq

from hound_id.errors import SpecError
from hound_id.mor.region import OperatingRegion, operating_region
from hound_id.mor.region_report import Speeds
from hound_id.mor.spec import MotorSpec
from hound_id.mor.thermal import Thermal

#: Relative tolerance of the continuous point's temperature [-].
_XTOL = 1e-12


def hot_spec(spec: MotorSpec, temperature: float, current_limit: float | None = None) -> MotorSpec:
    """The motor at a winding ``temperature`` [degC] (module docstring), with the drive's current limit
    ``current_limit`` [A] (default: derated at that temperature by the spec's thermal model).

    Raises:
        SpecError: The spec has no thermal model, or carries a measured envelope (measured at its own temperature).
    """
    th = spec.thermal
    if th is None:
        raise SpecError(
            f"{spec.name}: no thermal model; add thermal_time_constant, winding_limit and thermal_resistance or "
            "continuous_current to the spec"
        )
    if spec.envelope is not None:
        raise SpecError(
            f"{spec.name}: a measured envelope holds at the temperature it was measured at; hound-id does not "
            "move it to another temperature (drop the envelope to use the spec sheet's region warm)"
        )
    s_r, s_k = th.scales(temperature)
    if not (s_r > 0 and s_k > 0):
        raise SpecError(f"{spec.name}: at {temperature:g} degC the resistance or Kt scale is not positive")
    if current_limit is None:
        current_limit = float(th.derating(temperature)) * spec.drive_current
    if not current_limit > 0:
        raise SpecError(
            f"{spec.name}: at {temperature:g} degC the drive's current limit is derated to {current_limit:g} A; the "
            f"motor makes no torque (the winding limit is {th.winding_limit:g} degC)"
        )
    curve = spec.current_curve.scaled(s_k, f"{spec.current_curve.source} at {temperature:.4g} degC")
    fit = spec.fit
    if fit is not None and fit.curve is not None:
        fit = replace(fit, curve=curve)
    return replace(
        spec,
        name=spec.name,
        kt=spec.kt * s_k,
        kv=spec.kv / s_k,
        resistance=spec.resistance * s_r,
        peak_torque=spec.peak_torque * s_k,
        max_current=current_limit,
        fit=fit,
    )


def continuous_point(th: Thermal, drive_limit: float) -> tuple[float, float]:
    """(current [A], winding temperature [degC]) the winding settles at when the drive's limit ``drive_limit`` [A],
    derated by ``th``, is commanded for ever (module docstring)."""
    hot = th.steady(drive_limit)
    if hot <= th.derate_start:
        return drive_limit, hot  # the full current never warms the winding into the derating band

    def gap(t: float) -> float:
        return float(th.derating(t)) * drive_limit - th.continuous_current(t)

    lo, hi = max(th.derate_start, th.ambient), th.winding_limit
    if gap(lo) <= 0:  # derating from the limit only (a step): the winding's own continuous current there
        return th.continuous_current(hi), hi
    t = brentq(gap, lo, hi, xtol=_XTOL * max(abs(hi), 1.0))
    return th.continuous_current(t), float(t)


@dataclass(frozen=True)
class Heat:
    """What the winding's temperature does to a spec's region (``mor --spec``): :func:`heat`."""

    thermal: Thermal
    drive_limit: float
    """The drive's current limit at 20 degC [A]."""
    time_to_derate: float
    """Time [s] from the ambient to the start of derating with ``drive_limit`` held (closed form)."""
    time_to_limit: float
    """Time [s] from the ambient to the winding limit with ``drive_limit`` held, were the drive not to derate."""
    continuous_current: float
    """Current [A] the winding settles at under the drive's derating (:func:`continuous_point`)."""
    continuous_temperature: float
    """Its winding temperature [degC]."""
    limit_current: float
    """Current [A] the winding holds at its limit in steady state (no derating)."""
    warm: Speeds
    """The region with the full current at the start of derating (the warmest winding that still has it)."""
    continuous: Speeds
    """The continuous region: ``continuous_current`` at ``continuous_temperature``."""
    warm_torque: float
    """Torque limit of the warm region [N m]."""
    continuous_torque: float
    """Torque limit of the continuous region [N m]."""
    warm_region: OperatingRegion = field(repr=False, compare=False)
    continuous_region: OperatingRegion = field(repr=False, compare=False)

    @property
    def derates(self) -> bool:
        """Whether the drive's current limit, held, warms the winding into the derating band."""
        return self.continuous_temperature >= self.thermal.derate_start

    def to_dict(self) -> dict[str, Any]:
        th = self.thermal
        return {
            "thermal": th.to_dict(),
            "drive_current_limit": self.drive_limit,
            "time_to_derate": None if math.isinf(self.time_to_derate) else self.time_to_derate,
            "time_to_limit": None if math.isinf(self.time_to_limit) else self.time_to_limit,
            "derates": self.derates,
            "runaway_current": None if math.isinf(th.runaway_current) else th.runaway_current,
            "continuous": {
                "current": self.continuous_current,
                "temperature": self.continuous_temperature,
                "torque_limit": self.continuous_torque,
                **self.continuous.to_dict(),
            },
            "warm": {"temperature": th.derate_start, "torque_limit": self.warm_torque, **self.warm.to_dict()},
            "current_held_at_limit": self.limit_current,
            "units": {
                "times": "s",
                "currents": "A",
                "temperatures": "degC",
                "torque_limit, inner_box.torque": "N m (motor side)",
                "speeds": "rad/s (motor side)",
                "meaning": "time_to_derate / time_to_limit: from the ambient with the drive's current limit held "
                "(closed form; null: never, the winding settles below); derates: whether the drive's limit, held, "
                "warms the winding into the derating; continuous: where the drive's derated limit meets the current "
                "the winding holds in steady state; warm: the full current at the start of derating; currents are "
                "peak phase amplitudes under foc",
            },
        }


def heat(spec: MotorSpec) -> Heat | None:
    """The warm and continuous regions of a spec with a thermal model (None without one, or with a measured
    envelope)."""
    th = spec.thermal
    if th is None or spec.envelope is not None:
        return None
    limit = spec.drive_current
    current, temperature = continuous_point(th, limit)
    warm_spec = hot_spec(spec, th.derate_start, limit)
    cont_spec = hot_spec(spec, temperature, current)
    warm, cont = operating_region(warm_spec), operating_region(cont_spec)
    return Heat(
        thermal=th,
        drive_limit=limit,
        time_to_derate=th.time_to(th.derate_start, limit),
        time_to_limit=th.time_to(th.winding_limit, limit),
        continuous_current=current,
        continuous_temperature=temperature,
        limit_current=th.continuous_current(),
        warm=Speeds.of(warm, spec.bus_voltage),
        continuous=Speeds.of(cont, spec.bus_voltage),
        warm_torque=warm.torque_limit,
        continuous_torque=cont.torque_limit,
        warm_region=warm,
        continuous_region=cont,
    )
