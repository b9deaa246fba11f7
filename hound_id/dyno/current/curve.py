"""The current-torque curve of a fit: peak torque and the driver's current compensation.

The curve is the sum of the model's shape terms (``linear`` and the saturation
family) at rest, at 20 degC, without offset, friction, cogging or ripple.

* Peak torque (paper, after RoboDrive): the torque where the curve falls 20 % below
  the linear line Kt i.
* Current compensation (paper, "Motor torque saturation"): the current a driver must
  command for a wanted torque, i(tau). The exact inverse of the fitted curve is the
  compensation (:func:`fitted_curve`: closed form for the paper's quadratic, a monotone
  table with its stated error otherwise; :class:`hound_id.mor.current_curve.CurrentCurve`).
  The paper's odd polynomial i = c1 tau + c3 tau^3 + c5 tau^5 fitted over [0, tau_peak]
  (:func:`compensation`) is kept as an option for drivers that take a polynomial, with its
  error: it cannot follow the tau|tau| term (3 % off the slope at zero torque for the sample).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from hound_id.dyno.current.effects import Signals, get
from hound_id.dyno.current.fit import FitResult
from hound_id.dyno.current.stats import Array
from hound_id.mor.current_curve import PEAK_DEVIATION, CurrentCurve, polynomial, table_of

__all__ = [
    "EXTRAPOLATION_LIMIT", "PEAK_DEVIATION", "TABLE_POINTS", "Compensation", "PeakTorque", "compensation",
    "curve_torque", "fitted_curve", "peak_torque", "SATURATION_SIGMAS",
]  # fmt: skip

#: How far past the measured current the peak may be extrapolated before giving up: ten times, beyond which the fitted
#: curve says nothing and the advice is to test at higher current. Calibrated on test_curve::test_no_saturation_no_peak
#: and test_fit_cli::test_spec_checks_name_both_numbers_and_an_extrapolated_peak_is_marked.
EXTRAPOLATION_LIMIT = 10.0


#: Points of a table curve (a fitted curve other than the paper's quadratic), denser towards its top; the table states
#: its own inverse error (under 3 mA for a cubic saturation up to its top). Calibrated on
#: test_curve::test_a_cubic_fit_gets_a_table_curve_with_its_error.
TABLE_POINTS = 257


def fitted_curve(fit: FitResult, max_measured_current: float) -> CurrentCurve:
    """The fit's current-torque curve: linear (Kt only), the paper's quadratic in closed form (Kt and k_sat only), or a
    table of the shape terms from 0 to the curve's top (where it stops rising) or :data:`EXTRAPOLATION_LIMIT` x the
    measured current, whichever comes first."""
    shape = {name for name in fit.model if get(name).shape}
    kt = fit.value("kt")
    source = f"fit-current ({'+'.join(n for n in fit.model if n in shape)})"
    if shape <= {"linear"}:
        return CurrentCurve(kt=kt, source=source)
    if shape == {"linear", "saturation"} and fit.value("k_sat") > 0:
        return CurrentCurve(kt=kt, k_sat=fit.value("k_sat"), source=source)
    top = EXTRAPOLATION_LIMIT * max_measured_current
    grid = np.linspace(0.0, top, 4001)
    falling = np.flatnonzero(np.diff(curve_torque(fit, grid)) <= 0)
    if falling.size:
        top = float(grid[falling[0]])
    return table_of(lambda i: curve_torque(fit, i), kt, top, TABLE_POINTS, source)


def curve_torque(fit: FitResult, current: ArrayLike, values: dict[str, float] | None = None) -> Array:
    """Torque of the fitted current-torque curve [N m] at the given currents [A] (``values`` in place of the fit's)."""
    i = np.atleast_1d(np.asarray(current, float))
    s = Signals(time=np.zeros_like(i), current=i)
    values = fit.values() if values is None else values
    total = np.zeros_like(i)
    for name in fit.model:
        e = get(name)
        if not e.shape:
            continue
        beta = np.array([values[p.name] for p in e.parameters])
        total += e.columns(s, values) @ beta
    return total


@dataclass(frozen=True)
class PeakTorque:
    """Where the fitted curve deviates 20 % from linear."""

    torque: float | None
    """Peak torque [N m], None when the curve never deviates that much."""
    current: float | None
    """Current at the peak torque [A]."""
    max_measured_current: float
    """Largest |current| in the log [A]."""
    extrapolated: bool
    """Whether the peak lies beyond the measured current."""
    note: str
    """One sentence for the user."""
    at_least: tuple[float, float] | None = None
    """When the log shows no significant saturation: (torque [N m], current [A]) the peak lies beyond, from the
    saturation terms at their upper 95 % limits (value + 2 standard errors); ``torque`` is then None."""

    def to_dict(self) -> dict[str, Any]:
        return {
            "torque": self.torque,
            "current": self.current,
            "extrapolated": self.extrapolated,
            "max_measured_current": self.max_measured_current,
            "at_least": None if self.at_least is None else {"torque": self.at_least[0], "current": self.at_least[1]},
            "note": self.note,
        }


#: A saturation term is seen when its value is this many standard errors from zero (two-sided 5 %); its upper limit,
#: value + this many standard errors, bounds the peak torque when none is seen. Calibrated on
#: test_curve::test_a_peak_torque_needs_a_significant_saturation_term.
SATURATION_SIGMAS = 2.0


def _saturation_seen(fit: FitResult) -> tuple[bool, dict[str, float] | None]:
    """(whether any saturation term of the curve is significant, the values with every saturation term at its upper
    95 % limit, or None when a term has no standard error). A curve without saturation terms counts as seen: its
    straight line is what the model says, and the advice is to add one."""
    values = fit.values()
    upper: dict[str, float] | None = dict(values)
    seen = not any(get(name).shape and name != "linear" for name in fit.model)
    for name in fit.model:
        e = get(name)
        if not e.shape:
            continue
        for par in e.parameters:
            if par.name == "kt":
                continue
            est = fit.parameters[par.name]
            # every term is looked at: one held at its bound says nothing of the next (a cubic term 10 standard
            # errors from zero beside a quadratic one held at zero is a saturation seen)
            if est.stderr > 0 and abs(est.value) >= SATURATION_SIGMAS * est.stderr and not est.at_bound:
                seen = True
            if est.at_bound or not est.stderr > 0:  # held at zero, or no error: no interval to bound it with
                upper = None
            elif upper is not None:
                upper[par.name] = est.value + SATURATION_SIGMAS * est.stderr
    return seen, upper


def peak_torque(
    fit: FitResult,
    max_measured_current: float,
    deviation: float = PEAK_DEVIATION,
    current_limit: float | None = None,
    reply_range: float | None = None,
) -> PeakTorque:
    """Peak torque where (Kt i - tau(i)) / (Kt i) reaches ``deviation``.

    Args:
        current_limit: The driver's current limit seen in the log [A], if any: the advice then
            says that this drive cannot test higher currents.
        reply_range: Where the current reply's range ends [A], when the log shows the reply cut off
            there (clamped, held at its top, wrapped): the advice then names the reply.
    """
    from scipy.optimize import brentq

    kt = fit.value("kt")
    if kt <= 0:
        return PeakTorque(None, None, max_measured_current, False, "no positive Kt in the model")
    top = EXTRAPOLATION_LIMIT * max_measured_current
    grid = np.linspace(top / 4000, top, 4000)
    seen, upper = _saturation_seen(fit)
    if not seen:
        return _bound(
            fit, kt, grid, upper, max_measured_current, deviation, _advice(current_limit, "test", reply_range)
        )
    dev = 1.0 - curve_torque(fit, grid) / (kt * grid)
    above = np.flatnonzero(dev >= deviation)
    if above.size == 0:
        advice = _advice(current_limit, "add a saturation effect or test", reply_range)
        return PeakTorque(
            None,
            None,
            max_measured_current,
            False,
            f"the fitted curve stays within {deviation:.0%} of linear up to {top:.3g} A; {advice}",
        )
    k = int(above[0])
    if k == 0:
        i_peak = float(grid[0])
    else:
        i_peak = float(brentq(lambda x: 1.0 - curve_torque(fit, x)[0] / (kt * x) - deviation, grid[k - 1], grid[k]))
    tau = float(curve_torque(fit, i_peak)[0])
    extrapolated = i_peak > max_measured_current
    note = f"peak torque {tau:.4g} N m at {i_peak:.4g} A, where the curve is {deviation:.0%} below Kt i" + (
        f" (extrapolated beyond the measured currents, |i| <= {max_measured_current:.3g} A)" if extrapolated else ""
    )
    return PeakTorque(tau, i_peak, max_measured_current, extrapolated, note)


def _advice(current_limit: float | None, test: str, reply_range: float | None = None) -> str:
    """What to do for a peak torque the log cannot show: test at higher current, widen the reply's range, or use a
    stronger driver."""
    if reply_range is not None:
        return (
            f"the current reading cannot say more than {reply_range:.3g} A (the end of its range), so this log cannot "
            "show higher current: widen the reply's current range or log the current from a sensor of its own, and "
            "test at higher current"
        )
    if current_limit is not None:
        return (
            f"the driver held the current at its limit of {current_limit:.3g} A, so this drive cannot test higher "
            "current: raise the driver's current limit or test on a stronger driver"
        )
    return f"{test} at higher current"


def _bound(
    fit: FitResult,
    kt: float,
    grid: Array,
    upper: dict[str, float] | None,
    max_measured_current: float,
    deviation: float,
    advice: str,
) -> PeakTorque:
    """No significant saturation: the peak torque is not a number the log shows, only a bound (module docs)."""
    head = f"no saturation seen up to {max_measured_current:.3g} A (no saturation term is {SATURATION_SIGMAS:g} "
    head += "standard errors from zero)"
    if upper is None:
        return PeakTorque(None, None, max_measured_current, False, f"{head}; {advice}")
    dev = 1.0 - curve_torque(fit, grid, upper) / (kt * grid)
    above = np.flatnonzero(dev >= deviation)
    if above.size == 0:
        return PeakTorque(
            None,
            None,
            max_measured_current,
            False,
            f"{head}: even with its saturation at the upper 95 % limit the curve stays within {deviation:.0%} of "
            f"linear up to {grid[-1]:.3g} A; {advice}",
        )
    i_bound = float(grid[above[0]])
    tau_bound = float(curve_torque(fit, i_bound, upper)[0])
    if i_bound <= max_measured_current:  # the log reaches there: its saturation is not determined, not unseen
        advice = (
            f"the log reaches {max_measured_current:.3g} A but its saturation is too uncertain to place the peak: a "
            "longer or cleaner test at high current would"
        )
    return PeakTorque(
        None,
        None,
        max_measured_current,
        False,
        f"{head}: the peak torque (where the curve is {deviation:.0%} below Kt i) lies beyond {tau_bound:.4g} N m at "
        f"{i_bound:.4g} A (95 %: the saturation at its upper limit); not a number this log shows: {advice}",
        (tau_bound, i_bound),
    )


@dataclass(frozen=True)
class Compensation:
    """The odd-polynomial approximation of the curve's inverse, i = sum c_k tau^k over odd k (an option: the exact
    inverse is :func:`fitted_curve`'s)."""

    powers: tuple[int, ...]
    """Odd powers of torque."""
    coefficients: tuple[float, ...]
    """c_k [A / (N m)^k], in the order of ``powers``."""
    torque_range: float
    """Fitted over |tau| <= this [N m]."""
    max_error: float
    """Largest current error of the polynomial over the range [A]."""
    slope_error: float = 0.0
    """Relative error of its slope at zero torque against the exact 1/Kt, c1 Kt - 1 [-]."""

    def current(self, torque: Array) -> Array:
        """Current [A] the driver should command for a torque [N m]."""
        tau = np.asarray(torque, float)
        return np.asarray(polynomial(self.powers, self.coefficients, tau), dtype=float)

    def to_dict(self) -> dict[str, Any]:
        return {
            "powers": list(self.powers),
            "coefficients": list(self.coefficients),
            "torque_range": self.torque_range,
            "max_error": self.max_error,
            "slope_error": self.slope_error,
            "units": "current [A] = sum c_k * torque[N m]^k; max_error [A] against the fitted curve; slope_error: "
            "c1 Kt - 1, its relative error at small torque",
        }


def compensation(fit: FitResult, current_range: float, degree: int = 5) -> Compensation:
    """Fit the inverse curve i(tau) over currents 0..current_range [A] (up to the peak torque's current)."""
    i = np.linspace(0.0, current_range, 400)
    tau = curve_torque(fit, i)
    powers = tuple(range(1, degree + 1, 2))
    A = np.column_stack([tau**p for p in powers])
    scale = np.max(np.abs(A), axis=0)
    scale[scale == 0] = 1.0
    coef, *_ = np.linalg.lstsq(A / scale, i, rcond=None)
    coef = coef / scale
    err = float(np.max(np.abs(A @ coef - i)))
    kt = fit.value("kt")
    slope = float(coef[0] * kt - 1.0) if kt > 0 else 0.0
    return Compensation(powers, tuple(float(c) for c in coef), float(np.max(np.abs(tau))), err, slope)
