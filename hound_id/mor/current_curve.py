"""A motor's current-torque curve, tau = g(i), and its exact inverse, the current compensation i = g^-1(tau).

The curve is odd and rises monotonically up to its top (the most torque any current makes); past the top it is
held flat (the fit or the spec sheet says nothing there, and a curve that bends back down is not physical). Three
forms:

* ``linear``: tau = Kt i;
* ``quadratic`` (the paper's, and every spec sheet's): tau = Kt i - k i|i|, which rises up to i = Kt / (2k).
  Its inverse is closed-form, i = 2 tau / (Kt + sqrt(Kt^2 - 4 k |tau|)) (the stable root: no cancellation at
  small torque, slope exactly 1/Kt at zero);
* ``table``: points (i, tau) from 0 up to the top, for any other fitted curve (cubic, knee); both directions
  interpolate linearly between the points, and the table states its own error against the curve it samples.

A spec sheet gives the 20 % point: the peak torque P is where the curve has fallen :data:`PEAK_DEVIATION` below
Kt i. The quadratic through it has k = d (1 - d) Kt^2 / P (d = 0.2: k = 0.16 Kt^2 / P); :func:`sheet_curve`.

Only numpy is needed: the saturation and the runtime use this module.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hound_id.arrays import frozen
from hound_id.errors import SpecError

Array = NDArray[np.float64]

SCHEMA = "hound-id/current-curve/1"

#: Relative deviation from the linear line Kt i that defines the peak torque (the 20 % point): where the torque has
#: fallen 20 % below Kt i, the spec sheets' (RoboDrive's, the paper's) and the simulator's convention for the end of
#: the useful current range (each saturation form of the simulator drops Kt by 20 % at the motor's maximum current).
#: Calibrated on test_curve::test_peak_torque_of_the_quadratic_curve and
#: test_current::test_each_saturation_form_drops_kt_20_percent_at_max_current.
PEAK_DEVIATION = 0.20

FORMS = ("linear", "quadratic", "table")


@dataclass(frozen=True)
class CurrentCurve:
    """An odd, monotone current-torque curve (module docstring); SI units."""

    kt: float
    """Slope at zero current, the torque constant [N m/A]."""
    k_sat: float = 0.0
    """Quadratic saturation coefficient k [N m/A^2] of tau = Kt i - k i|i| (0: linear; unused by a table)."""
    currents: Array | None = None
    """Table form: currents from 0, increasing [A]."""
    torques: Array | None = None
    """Table form: the torques at ``currents``, increasing from 0 [N m]."""
    table_error: float = 0.0
    """Table form: the largest current error of interpolating the table's inverse, against the curve it samples [A]."""
    source: str = ""
    """Where the curve comes from (the spec sheet's 20 % point, or a fit)."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.kt) and self.kt > 0):
            raise SpecError(f"current-torque curve: Kt = {self.kt!r} N m/A; expected a positive number")
        if not (math.isfinite(self.k_sat) and self.k_sat >= 0):
            raise SpecError(f"current-torque curve: k_sat = {self.k_sat!r} N m/A^2; expected a number >= 0")
        if (self.currents is None) != (self.torques is None):
            raise SpecError("current-torque curve: a table needs both currents and torques")
        if self.currents is not None and self.torques is not None:
            i, t = self.currents, self.torques
            ok = i.ndim == 1 and i.shape == t.shape and i.size >= 2 and i[0] == 0.0 and t[0] == 0.0
            if not (ok and np.all(np.isfinite(i)) and np.all(np.isfinite(t))):
                raise SpecError(
                    "current-torque curve: the table needs two or more finite points starting at (0 A, 0 N m)"
                )
            if not (np.all(np.diff(i) > 0) and np.all(np.diff(t) > 0)):
                raise SpecError(
                    "current-torque curve: the table's currents and torques must both increase (a monotone curve)"
                )

    @property
    def form(self) -> str:
        """``linear``, ``quadratic`` or ``table``."""
        if self.currents is not None:
            return "table"
        return "quadratic" if self.k_sat > 0 else "linear"

    @property
    def top_current(self) -> float:
        """Current [A] at which the curve stops rising (inf for a linear curve)."""
        if self.currents is not None:
            return float(self.currents[-1])
        return self.kt / (2.0 * self.k_sat) if self.k_sat > 0 else math.inf

    @property
    def top_torque(self) -> float:
        """The most torque any current makes [N m] (inf for a linear curve)."""
        if self.torques is not None:
            return float(self.torques[-1])
        return self.kt**2 / (4.0 * self.k_sat) if self.k_sat > 0 else math.inf

    @property
    def q(self) -> float:
        """k / Kt^2 [1/(N m)]: in the linear-equivalent torque x = Kt i, a quadratic curve is x - q x|x|."""
        return self.k_sat / self.kt**2 if self.form == "quadratic" else 0.0

    def torque(self, current: ArrayLike) -> Array:
        """Torque [N m] at each current [A] (flat past the top)."""
        i = np.asarray(current, dtype=float)
        mag = np.minimum(np.abs(i), self.top_current)
        if self.currents is not None and self.torques is not None:
            out = np.interp(mag, self.currents, self.torques)
        else:
            out = self.kt * mag - self.k_sat * mag * mag
        return np.asarray(np.sign(i) * out, dtype=float)

    def current(self, torque: ArrayLike) -> Array:
        """Current [A] the curve needs for each torque [N m], its exact inverse (module docstring); +-inf past the
        top, where no current makes the torque."""
        tau = np.asarray(torque, dtype=float)
        mag = np.abs(tau)
        if self.currents is not None and self.torques is not None:
            out = np.interp(mag, self.torques, self.currents)
        elif self.k_sat > 0:  # odd as written: tau itself in the numerator (its slope at zero is 1/Kt)
            root = np.sqrt(np.maximum(self.kt**2 - 4.0 * self.k_sat * mag, 0.0))
            return np.asarray(np.where(mag > self.top_torque, np.copysign(np.inf, tau), 2.0 * tau / (self.kt + root)))
        else:
            return np.asarray(tau / self.kt, dtype=float)
        out = np.where(mag > self.top_torque, np.inf, out)
        return np.asarray(np.sign(tau) * out, dtype=float)

    def scaled(self, factor: float, source: str | None = None) -> CurrentCurve:
        """The curve with every torque times ``factor`` > 0 at the same current (the magnets' flux at another
        temperature, :mod:`hound_id.mor.thermal`); its top stays at the same current."""
        return CurrentCurve(
            kt=self.kt * factor,
            k_sat=self.k_sat * factor,
            currents=self.currents,
            torques=None if self.torques is None else frozen(self.torques * factor),
            table_error=self.table_error,
            source=self.source if source is None else source,
        )

    def compensation(self) -> dict[str, Any]:
        """The ``compensation`` block of a fit report and a bundle: how the exact inverse is computed and its
        error [A] (0 for the closed form: rounding only)."""
        method = {
            "linear": "i = tau / Kt",
            "quadratic": "closed form: i = 2 tau / (Kt + sqrt(Kt^2 - 4 k_sat |tau|))",
            "table": "linear interpolation of the current_curve table",
        }[self.form]
        return {
            "method": method,
            "torque_range": None if math.isinf(self.top_torque) else self.top_torque,
            "max_error": self.table_error,
            "units": "current [A] for a torque [N m] (odd); max_error [A]: 0 for the closed form (rounding only)",
        }

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready content (SI units), schema ``hound-id/current-curve/1``."""
        out: dict[str, Any] = {"schema": SCHEMA, "form": self.form, "kt": self.kt}
        if self.form == "quadratic":
            out["k_sat"] = self.k_sat
        if self.currents is not None and self.torques is not None:
            out.update(currents=self.currents.tolist(), torques=self.torques.tolist(), table_error=self.table_error)
        out.update(
            top_current=None if math.isinf(self.top_current) else self.top_current,
            top_torque=None if math.isinf(self.top_torque) else self.top_torque,
            source=self.source,
            units="current [A], torque [N m], kt [N m/A], k_sat [N m/A^2]",
        )
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], where: str = "current_curve") -> CurrentCurve:
        """Read :meth:`to_dict`'s content; SpecError names what is malformed."""
        try:
            form = data.get("form")
            if form not in FORMS:
                raise ValueError(f"form {form!r}, expected one of {', '.join(FORMS)}")
            table = form == "table"
            return cls(
                kt=float(data["kt"]),
                k_sat=float(data.get("k_sat", 0.0)) if form == "quadratic" else 0.0,
                currents=frozen(data["currents"]) if table else None,
                torques=frozen(data["torques"]) if table else None,
                table_error=float(data.get("table_error", 0.0)) if table else 0.0,
                source=str(data.get("source", "")),
            )
        except (AttributeError, KeyError, TypeError, ValueError) as err:
            raise SpecError(
                f"{where}: malformed current-torque curve ({type(err).__name__}: {err}); write it with "
                "hound-id fit-current --out"
            ) from err


def sheet_curve(kt: float, peak_torque: float, deviation: float = PEAK_DEVIATION, source: str = "") -> CurrentCurve:
    """The quadratic through a spec sheet's 20 % point: Kt i - k i|i| falls ``deviation`` below Kt i at the peak
    torque, so k = d (1 - d) Kt^2 / P."""
    return CurrentCurve(
        kt=kt,
        k_sat=deviation * (1.0 - deviation) * kt**2 / peak_torque,
        source=source or f"spec sheet: quadratic through the {deviation:.0%} point at {peak_torque:.4g} N m",
    )


def quadratic_cubic_table(kt: float, k2: float, k3: float, points: int = 257, source: str = "") -> CurrentCurve:
    """The table of tau = Kt i - k2 i|i| - k3 i^3 from 0 to its top, where its slope Kt - 2 k2 i - 3 k3 i^2 reaches 0
    (a fit with the cubic saturation term); its inverse error is measured at the midpoints."""
    if k3 <= 0:
        return CurrentCurve(kt=kt, k_sat=max(k2, 0.0), source=source)
    top = (-2 * k2 + math.sqrt(4 * k2 * k2 + 12 * k3 * kt)) / (6 * k3)

    def f(i: Array) -> Array:
        return np.asarray(kt * i - k2 * i * np.abs(i) - k3 * i**3, dtype=float)

    return table_of(f, kt, top, points, source)


def table_of(f: Any, kt: float, top: float, points: int = 257, source: str = "") -> CurrentCurve:
    """A table curve (slope ``kt`` [N m/A] at zero) sampling the monotone ``f`` (currents [A] to torques [N m]) on
    [0, top] (denser towards the top), with the largest error
    of its interpolated inverse at the midpoints (:attr:`CurrentCurve.table_error`). Points where f stops rising are
    dropped (the table ends at the last rising point)."""
    i = _towards_top(top, points)  # where the inverse is steep
    i, t = _rising(i, np.asarray(f(i), dtype=float))
    mid = 0.5 * (i[:-1] + i[1:])
    error = float(np.max(np.abs(np.interp(np.asarray(f(mid), dtype=float), t, i) - mid))) if mid.size else 0.0
    return CurrentCurve(kt=kt, currents=frozen(i), torques=frozen(t), table_error=error, source=source)


def _towards_top(top: float, points: int) -> Array:
    """``points`` values from 0 to ``top``, denser towards the top (sine spacing; the last exactly ``top``)."""
    x = top * np.sin(np.linspace(0.0, 0.5 * np.pi, points))
    x[-1] = top
    return x


def _rising(x: Array, y: Array) -> tuple[Array, Array]:
    """(x, y) up to the last point before y stops rising."""
    stop = np.flatnonzero(np.diff(y) <= 0)
    return (x[: stop[0] + 1], y[: stop[0] + 1]) if stop.size else (x, y)


def polynomial(powers: tuple[int, ...], coefficients: tuple[float, ...], torque: Any) -> Any:
    """A compensation polynomial's current, sum_k c_k tau^k [A], at torques [N m] (numpy arrays or torch tensors)."""
    return sum(c * torque**p for p, c in zip(powers, coefficients, strict=True))


def polynomial_curve(
    kt: float, powers: tuple[int, ...], coefficients: tuple[float, ...], torque_range: float, points: int = 257
) -> CurrentCurve:
    """The table curve of a compensation polynomial, current [A] = sum c_k tau^k, over 0..``torque_range`` [N m] (a
    hound-id/fit/2 record whose curve its parameters do not define; a test's hand-made curve). The polynomial must
    rise over the range; the table ends where it stops."""

    def current(t: Array) -> Array:
        return np.asarray(polynomial(powers, coefficients, t), dtype=float)

    taus = _towards_top(torque_range, points)
    taus, i = _rising(taus, current(taus))
    mid = 0.5 * (taus[:-1] + taus[1:])
    error = float(np.max(np.abs(np.interp(mid, taus, i) - current(mid)))) if mid.size else 0.0
    return CurrentCurve(
        kt=kt, currents=frozen(i), torques=frozen(taus), table_error=error, source="compensation polynomial"
    )
