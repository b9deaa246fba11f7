"""The torque channel's own dynamics: the transducer and the coupling between motor and sensor.

A torque flange, its amplifier's filter and the shaft between the motor and the sensor do not
pass the air-gap torque through unchanged. Two named effects describe what the sensor adds:

* ``lag``: a first-order low-pass, ``1 / (1 + s tau)`` (an amplifier's filter; a step shows as an
  exponential approach of time constant tau);
* ``resonance``: a second-order low-pass, ``w0^2 / (s^2 + 2 zeta w0 s + w0^2)`` with ``w0 = 2 pi f0``
  (the coupling's torsional mode with the sensor's inertia; below ``zeta = 0.7`` a current step rings
  at about ``f0`` and decays over ``1 / (zeta w0)``).

Both have unit gain at rest, so every other effect keeps its meaning: the measured torque is the
model's torque passed through the filter. The model stays linear in its parameters, because a
linear time-invariant filter of a sum is the sum of the filtered regressor columns; the filter's
own parameters (tau, or f0 and zeta) are found by search, as the delay's are.

The filter is discretised exactly for inputs that are straight between samples (first-order hold,
as the other channels are interpolated), on the log's median sample interval; a log whose sample
times jitter is resampled onto a uniform grid for the filter and read back at its own times. It
starts at rest at the first sample's value.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hound_id.errors import FitError

Array = NDArray[np.float64]

#: The effects that filter the model's torque (fit.py treats them apart: they add no column).
FILTERS: tuple[str, ...] = ("lag", "resonance")
#: Sample intervals may scatter by this share of their median before the filter works on a resampled uniform grid
#: (a host loop's jitter of a few per cent changes a filter's discretisation by less than its own noise). Calibrated
#: on test_transducer::test_a_jittered_log_is_filtered_as_a_uniform_one_would_be.
JITTER = 0.02
#: The search range of the filter's frequency, as shares of the sample rate: from a hundredth (slower than that, the
#: filter would smear the current's own changes, which the model sees) to just below the Nyquist rate (faster, the log
#: cannot show it). Calibrated on test_polled_rig::test_a_transducer_resonance_is_found_named_and_valued and
#: test_polled_rig::test_a_first_order_transducer_lag_is_found_and_valued.
FREQUENCY_RANGE = (0.01, 0.45)
#: Damping ratios searched for a resonance: from a lightly damped coupling (0.05) to an overdamped one (1.5, which
#: no longer rings). Calibrated on test_polled_rig::test_a_transducer_resonance_is_found_named_and_valued.
DAMPING_RANGE = (0.05, 1.5)


def sample_interval(time: Array) -> float:
    """The log's median sample interval [s]."""
    steps = np.diff(np.asarray(time, float))
    steps = steps[steps > 0]
    if steps.size == 0:
        raise FitError("the sample times do not advance; a filter of the torque channel needs real sample times")
    return float(np.median(steps))


def frequency_range(time: Array) -> tuple[float, float]:
    """The filter frequencies [Hz] this log can show (:data:`FREQUENCY_RANGE` of its sample rate)."""
    rate = 1.0 / sample_interval(time)
    return FREQUENCY_RANGE[0] * rate, FREQUENCY_RANGE[1] * rate


def to_point(name: str, hypers: Mapping[str, float]) -> Array:
    """The filter's hypers as a search point: the logarithms of ``lag_tau``, or of ``resonance_f0`` and
    ``resonance_zeta``."""
    if name == "lag":
        return np.log([hypers["lag_tau"]])
    return np.log([hypers["resonance_f0"], hypers["resonance_zeta"]])


def from_point(name: str, point: Array) -> dict[str, float]:
    """The filter's hypers from a search point (:func:`to_point`)."""
    if name == "lag":
        return {"lag_tau": float(np.exp(point[0]))}
    return {"resonance_f0": float(np.exp(point[0])), "resonance_zeta": float(np.exp(point[1]))}


def search_bounds(name: str, time: Array) -> tuple[Array, Array]:
    """Bounds of the search point (:func:`to_point`): the frequencies this log can show, and the damping range."""
    lo, hi = frequency_range(time)
    if name == "lag":
        return np.log([1.0 / (2 * math.pi * hi)]), np.log([1.0 / (2 * math.pi * lo)])
    return np.log([lo, DAMPING_RANGE[0]]), np.log([hi, DAMPING_RANGE[1]])


@dataclass(frozen=True)
class Coordinate:
    """One of a filter's values as a user reads it, with the range this log can show."""

    hyper: str
    """The hyper it comes from."""
    label: str
    """How a sentence names it ("its bandwidth", "f0", "its damping")."""
    value: float
    low: float
    high: float
    unit: str
    """Its unit ("" for a ratio)."""


def at_edge(name: str, hypers: Mapping[str, float], time: Array, share: float) -> list[Coordinate]:
    """The filter's values within ``share`` of an end of the range this log can show (a lag by its bandwidth), in
    the order of its hypers."""
    lo, hi = frequency_range(time)
    if name == "lag":
        values = [Coordinate("lag_tau", "its bandwidth", 1.0 / (2 * math.pi * hypers["lag_tau"]), lo, hi, "Hz")]
    else:
        values = [
            Coordinate("resonance_f0", "f0", hypers["resonance_f0"], lo, hi, "Hz"),
            Coordinate("resonance_zeta", "its damping", hypers["resonance_zeta"], *DAMPING_RANGE, ""),
        ]
    return [c for c in values if c.value <= c.low * (1 + share) or c.value >= c.high / (1 + share)]


def _state_space(name: str, hypers: Mapping[str, float]) -> tuple[Array, Array, Array, Array]:
    if name == "lag":
        tau = float(hypers["lag_tau"])
        if not tau > 0:
            raise FitError(f"the lag's time constant must be positive, found {tau:g} s")
        return np.array([[-1.0 / tau]]), np.array([[1.0 / tau]]), np.array([[1.0]]), np.array([[0.0]])
    if name == "resonance":
        f0, zeta = float(hypers["resonance_f0"]), float(hypers["resonance_zeta"])
        if not (f0 > 0 and zeta > 0):
            raise FitError(f"a resonance needs f0 > 0 and zeta > 0, found f0 = {f0:g} Hz, zeta = {zeta:g}")
        w0 = 2.0 * math.pi * f0
        A = np.array([[0.0, 1.0], [-(w0**2), -2.0 * zeta * w0]])
        return A, np.array([[0.0], [w0**2]]), np.array([[1.0, 0.0]]), np.array([[0.0]])
    raise FitError(f"'{name}' is not a filter of the torque channel; known: {', '.join(FILTERS)}")


def coefficients(name: str, hypers: Mapping[str, float], dt: float) -> tuple[Array, Array]:
    """Numerator and denominator of the discrete filter (first-order hold) at sample interval ``dt`` [s]."""
    from scipy.signal import cont2discrete, ss2tf

    Ad, Bd, Cd, Dd, _ = cont2discrete(_state_space(name, hypers), dt, method="foh")
    b, a = ss2tf(Ad, Bd, Cd, Dd)
    b = np.atleast_1d(np.asarray(b, float).ravel())
    a = np.asarray(a, float)
    return b / a[0], a / a[0]


def apply(name: str, hypers: Mapping[str, float], time: Array, columns: Array) -> Array:
    """The columns (n, k) passed through the named filter, each starting at rest at its first value."""
    from scipy.signal import lfilter, lfilter_zi

    X = np.asarray(columns, float)
    flat = X.ndim == 1
    if flat:
        X = X[:, None]
    t = np.asarray(time, float)
    if X.shape[0] < 2:
        return X[:, 0] if flat else X
    dt = sample_interval(t)
    steps = np.diff(t)
    uniform = bool(np.max(np.abs(steps - dt)) <= JITTER * dt)
    if uniform:
        grid, values = t, X
    else:  # resample onto a uniform grid, filter, read back at the log's own times
        grid = t[0] + dt * np.arange(int(math.floor((t[-1] - t[0]) / dt)) + 1)
        values = np.column_stack([np.interp(grid, t, X[:, j]) for j in range(X.shape[1])])
    b, a = coefficients(name, hypers, dt)
    zi = lfilter_zi(b, a)
    out = np.empty_like(values)
    for j in range(values.shape[1]):
        out[:, j] = lfilter(b, a, values[:, j], zi=zi * values[0, j])[0]
    if not uniform:
        out = np.column_stack([np.interp(t, grid, out[:, j]) for j in range(out.shape[1])])
    return out[:, 0] if flat else out


def step_response(name: str, hypers: Mapping[str, float], duration: float, dt: float) -> tuple[Array, Array]:
    """Time [s] and the filter's response to a unit step (for plots and evidence)."""
    t = np.arange(0.0, duration, dt)
    u = np.ones_like(t)
    u[0] = 0.0
    return t, apply(name, hypers, t, u)


def overshoot(zeta: float) -> float:
    """A second-order low-pass's step overshoot, as a share of the step (0 at zeta >= 1)."""
    if zeta >= 1.0:
        return 0.0
    return math.exp(-math.pi * zeta / math.sqrt(1.0 - zeta**2))


__all__ = [
    "DAMPING_RANGE",
    "FILTERS",
    "FREQUENCY_RANGE",
    "JITTER",
    "Coordinate",
    "apply",
    "at_edge",
    "coefficients",
    "frequency_range",
    "from_point",
    "overshoot",
    "sample_interval",
    "search_bounds",
    "step_response",
    "to_point",
]
