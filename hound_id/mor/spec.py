"""Motor spec sheets: unit-aware YAML in, an SI :class:`MotorSpec` out.

Conventions (the quasi-static DC model of the paper, eq. 1):

* ``V = R i + omega / Kv`` and ``tau = Kt i``, with ``i`` the current the torque
  constant is quoted for. ``resistance`` is the R that makes this hold for the
  given Kt, i.e. the DC-equivalent resistance of the model.
* A datasheet usually gives the line-to-line resistance instead. Put it under
  ``resistance_line_to_line``; it is converted with the ``commutation`` key:

  - ``foc`` (default; sinusoidal field-oriented control with space-vector
    modulation, Kt per peak phase amp): the phase-voltage amplitude is limited to
    V_bus/sqrt(3) and the q-axis equation is v_q = R_ph i_q + omega_e lambda, so
    scaling by sqrt(3) gives R = sqrt(3) R_ph = (sqrt(3)/2) R_line-to-line.
  - ``six_step`` (trapezoidal commutation, two phases in series, Kt per DC amp):
    R = R_line-to-line.

* Plain numbers are SI; strings carry units (see :mod:`hound_id.units`).
* For a consistent spec Kt * Kv is 1 (DC convention) or about sqrt(3)/2 = 0.87
  (FOC, Kt per peak phase amp, Kv from the line-to-line back-EMF). A product
  outside 1 +/- 15 % is flagged: it is almost always a unit mix-up.

Reading a sheet (the keys, their units and spans, :func:`~hound_id.mor.spec_sheet.load_motor_spec`) is in
:mod:`hound_id.mor.spec_sheet`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from functools import cached_property
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.errors import SpecError, where
from hound_id.mor.current_curve import CurrentCurve, quadratic_cubic_table, sheet_curve
from hound_id.mor.drive import (
    DEFAULT_INDUCTANCE_CONVENTION,
    PHASE_FACTOR,
    Drive,
    reactance_per_speed,
)
from hound_id.mor.thermal import Thermal

SCHEMA = "hound-id/motor/1"


#: The spec sheet's current-torque curves (``kt_curve``).
KT_CURVES = ("quadratic", "linear")


#: Relative disagreement between Kt and 1/Kv above which a spec is flagged.
KT_KV_TOLERANCE = 0.15


#: R_model / R_line-to-line for each commutation (see module docstring).
LINE_TO_LINE_FACTOR = {"foc": math.sqrt(3.0) / 2.0, "six_step": 1.0}


def read_only(value: Any) -> Any:
    """A deep read-only copy of parsed YAML/JSON data: mappings become mapping proxies, lists tuples."""
    if isinstance(value, Mapping):
        return MappingProxyType({k: read_only(v) for k, v in value.items()})
    if isinstance(value, list | tuple):
        return tuple(read_only(v) for v in value)
    return value


def plain(value: Any) -> Any:
    """The plain dicts and lists of data made read-only by a record (the inverse of the read-only copy)."""
    if isinstance(value, Mapping):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return [plain(v) for v in value]
    return value


@dataclass(frozen=True)
class FitParameter:
    """One fitted parameter of a fit record."""

    value: float
    """Fitted value, in ``unit``."""
    stderr: float | None
    """Standard error, in ``unit`` (None where the fit gives none, e.g. a fixed order)."""
    unit: str
    """Unit of the value, e.g. ``N m/A``."""
    at_bound: bool
    """Whether the fit held the parameter at a physical bound."""


@dataclass(frozen=True)
class FitCompensation:
    """The current-compensation polynomial of a fit: current [A] = sum c_k tau^k, tau the torque [N m]."""

    powers: tuple[int, ...]
    """Powers k (odd)."""
    coefficients: tuple[float, ...]
    """Coefficients c_k [A / (N m)^k]."""


@dataclass(frozen=True)
class FitRecord:
    """The dynamometer fit a fitted spec carries (``fit:``, schema hound-id/fit/1 or /2, from ``fit-current --out``).

    The typed fields are what hound-id reads; :meth:`to_dict` gives the block exactly as written.
    """

    schema: str | None
    """The fit's schema, e.g. ``hound-id/fit/2``."""
    model: tuple[str, ...]
    """Effects of the fitted model, e.g. (linear, saturation, coulomb)."""
    parameters: Mapping[str, FitParameter]
    """Fitted parameters by name (read-only)."""
    rmse_test: float | None
    """Cross-validated (held-out) RMSE [N m], if the record gives one."""
    peak_note: str
    """The fit's sentence on its peak torque ('' if none)."""
    compensation: FitCompensation | None
    """The odd current-compensation polynomial, if the fit has one (an approximation: :attr:`curve` is exact)."""
    curve: CurrentCurve | None
    """The fitted current-torque curve (``current_curve``; for a hound-id/fit/2 record rebuilt from its parameters
    where they define it), or None."""
    written: Mapping[str, Any] = field(repr=False, compare=False)
    """The block as written (read-only), for :meth:`to_dict`."""

    def value(self, name: str, default: float = 0.0) -> float:
        """A fitted parameter's value, or ``default`` where the fit has no such parameter."""
        p = self.parameters.get(name)
        return default if p is None else p.value

    def to_dict(self) -> dict[str, Any]:
        """The ``fit:`` block as written (plain dicts and lists)."""
        out: dict[str, Any] = plain(self.written)
        return out

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], source: str | None = None) -> FitRecord:
        """Parse a spec's ``fit:`` block (any fit schema so far); SpecError names a malformed part."""
        raw = data.get("parameters") or {}
        params: dict[str, FitParameter] = {}
        try:
            for name, p in dict(raw).items():
                stderr = p.get("stderr")
                params[str(name)] = FitParameter(
                    value=float(p["value"]),
                    stderr=None if stderr is None else float(stderr),
                    unit=str(p.get("unit", "")),
                    at_bound=bool(p.get("at_bound", False)),
                )
            # fit/3 keeps the odd polynomial in compensation_polynomial (compensation is the exact inverse); fit/2 and
            # older in compensation
            comp = data.get("compensation_polynomial") if "current_curve" in data else data.get("compensation")
            compensation = (
                FitCompensation(tuple(int(k) for k in comp["powers"]), tuple(float(c) for c in comp["coefficients"]))
                if comp
                else None
            )
        except (AttributeError, KeyError, TypeError, ValueError) as err:
            raise SpecError(
                f"{where(source, 'fit')}: malformed fit record ({type(err).__name__}: {err}); give the file that "
                "hound-id fit-current --out wrote"
            ) from err
        model = data.get("model", [])
        rmse = data.get("rmse") or {}
        test = rmse.get("test") if isinstance(rmse, Mapping) else None
        peak = data.get("peak_torque")
        schema = data.get("schema")
        curve = _fitted_curve(data, params, source)
        return cls(
            schema=None if schema is None else str(schema),
            model=tuple(str(m) for m in model) if isinstance(model, list | tuple) else (),
            parameters=MappingProxyType(params),
            rmse_test=test if isinstance(test, float) else None,
            peak_note=str(peak.get("note") or "") if isinstance(peak, Mapping) else "",
            compensation=compensation,
            curve=curve,
            written=read_only(data),
        )


#: Effects of the fitted current-torque curve a hound-id/fit/2 record can be rebuilt from (the knee needs its knee
#: current, which that schema did not write).
_REBUILDABLE = {"linear", "saturation", "saturation_cubic"}


def _fitted_curve(
    data: Mapping[str, Any], params: Mapping[str, FitParameter], source: str | None
) -> CurrentCurve | None:
    """The fit's current-torque curve: its ``current_curve`` block, or rebuilt from a fit/2 record's parameters."""
    block = data.get("current_curve")
    if isinstance(block, Mapping):
        return CurrentCurve.from_dict(block, where(source, "fit.current_curve"))
    model = data.get("model", [])
    names = [str(m) for m in model] if isinstance(model, list | tuple) else []
    shape = {m for m in names if m == "linear" or m.startswith("saturation")}
    if "kt" not in params or not shape <= _REBUILDABLE or params["kt"].value <= 0:
        return None
    k2, k3 = max(params["k_sat"].value, 0.0) if "k_sat" in params else 0.0, params.get("k_sat3")
    return quadratic_cubic_table(
        params["kt"].value, k2, max(k3.value, 0.0) if k3 is not None else 0.0, source="fit-current (fit/2 parameters)"
    )


@dataclass(frozen=True)
class MeasuredEnvelope:
    """A measured torque-speed envelope a spec carries (``envelope:``, from ``mor --compare --out``): the
    model's effects and its polyline edges over motor speed, motor side. Arrays are read-only copies.

    The typed fields are what hound-id reads; :meth:`to_dict` gives the block exactly as written.
    """

    effects: Mapping[str, float]
    """Envelope effects and their parameter values (units in :data:`hound_id.mor.envelope_effects.EFFECTS`)."""
    speeds: NDArray[np.float64]
    """Polyline speeds, increasing [rad/s]."""
    lower: NDArray[np.float64]
    """Lowest torque at each speed [N m] (NaN where no torque is feasible)."""
    upper: NDArray[np.float64]
    """Highest torque at each speed [N m] (NaN where no torque is feasible)."""
    tolerance: float
    """Accuracy of the polyline against the model [N m]."""
    coverage: Mapping[str, Any] | None
    """Speed ranges the log covered, per edge (read-only), if given."""
    source: str
    """What measured it (``mor --compare`` if the block does not say)."""
    written: Mapping[str, Any] = field(repr=False, compare=False)
    """The block as written (read-only), for :meth:`to_dict`."""

    @property
    def polyline(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """(speeds [rad/s], lower [N m], upper [N m]), read-only."""
        return self.speeds, self.lower, self.upper

    def to_dict(self) -> dict[str, Any]:
        """The ``envelope:`` block as written (plain dicts and lists)."""
        out: dict[str, Any] = plain(self.written)
        return out


@dataclass(frozen=True)
class MotorSpec:
    """A motor as its spec sheet describes it, in SI units (motor side, before any gearbox)."""

    name: str
    """Motor name."""
    kt: float
    """Torque constant [N m/A]."""
    kv: float
    """Speed constant [rad/s/V]."""
    resistance: float
    """DC-equivalent winding resistance of the model V = R i + omega/Kv [ohm]."""
    bus_voltage: float
    """Supply (bus) voltage [V]."""
    peak_torque: float
    """Peak torque, where the current-torque curve deviates 20 % from linear [N m]."""
    max_current: float | None = None
    """Driver current limit [A], if any."""
    max_speed: float | None = None
    """Rated maximum speed [rad/s], if any."""
    rotor_inertia: float | None = None
    """Rotor inertia [kg m^2], if known."""
    inductance: float | None = None
    """Winding inductance [H], if known."""
    pole_pairs: int | None = None
    """Number of pole pairs, if known."""
    source: str | None = None
    """Where the numbers came from."""
    assumed: tuple[str, ...] = ()
    """Fields whose values are assumed rather than sourced."""
    extrapolated: tuple[str, ...] = ()
    """Fields whose values a fit extrapolated beyond what it measured (e.g. a peak torque past the tested current)."""
    fit: FitRecord | None = field(default=None, compare=False)
    """The dynamometer fit (schema hound-id/fit/2) whose Kt and peak torque this spec carries, if any."""
    envelope: MeasuredEnvelope | None = field(default=None, compare=False)
    """A measured envelope (``mor --compare --out``): effects and polyline edges over speed, or None."""
    kt_curve: str = "quadratic"
    """The spec sheet's current-torque curve when no fit gives one: ``quadratic`` (through the 20 % point at the
    peak torque) or ``linear`` (tau = Kt i up to the peak torque, for a sheet whose peak torque is a thermal or
    demagnetisation limit rather than a 20 % point)."""
    commutation: str = "foc"
    """``foc`` (field-oriented, the dq model of :mod:`hound_id.mor.drive` applies) or ``six_step``."""
    inductance_convention: str | None = None
    """How ``inductance`` is stated: ``line_to_line`` or ``phase`` (None: not stated; taken as
    :data:`hound_id.mor.drive.DEFAULT_INDUCTANCE_CONVENTION`, with a warning)."""
    field_weakening: bool = False
    """Whether the drive weakens the field past base speed (negative d current within the phase-current limit
    ``max_current``); else it holds i_d = 0."""
    bus_voltage_range: tuple[float, float] | None = None
    """(lowest, highest) bus voltage the battery gives over a discharge [V], if stated; ``bus_voltage`` is the
    nominal within it."""
    thermal: Thermal | None = None
    """The winding's thermal model and the drive's derating (:mod:`hound_id.mor.thermal`), if the spec states a
    time constant, a winding limit and a thermal resistance or continuous current; None otherwise."""

    @cached_property
    def drive(self) -> Drive | None:
        """The drive's dq model (:mod:`hound_id.mor.drive`) where it changes the region: an inductance with pole pairs
        under field-oriented control, or field weakening; None for the DC law V = R i + omega/Kv."""
        reactance = 0.0
        convention = phase = None
        if self.inductance is not None and self.pole_pairs is not None and self.commutation == "foc":
            convention = self.inductance_convention or DEFAULT_INDUCTANCE_CONVENTION
            phase = self.inductance * PHASE_FACTOR[convention]
            reactance = reactance_per_speed(self.inductance, convention, self.pole_pairs)
        if reactance == 0.0 and not self.field_weakening:
            return None
        current = self.drive_current
        return Drive(
            reactance=reactance,
            k_rho=reactance * self.kv / self.current_curve.kt,
            circle_x=self.current_curve.kt * current,
            field_weakening=self.field_weakening,
            phase_current_limit=current,
            inductance_phase=phase,
            convention=convention,
            pole_pairs=self.pole_pairs if convention is not None else None,
        )

    @cached_property
    def current_curve(self) -> CurrentCurve:
        """The current-torque curve: the fit's (``fit-current --out``) if this spec carries one that defines it; else
        linear for ``kt_curve: linear`` or a spec with a measured envelope (whose model, :mod:`hound_id.mor.envelope`,
        starts from linear Kt and takes a measured curve as an effect); else the quadratic through the spec sheet's
        20 % point (:func:`hound_id.mor.current_curve.sheet_curve`)."""
        if self.fit is not None and self.fit.curve is not None:
            return self.fit.curve
        if self.kt_curve == "linear":
            return CurrentCurve(kt=self.kt, source="spec sheet: linear (kt_curve: linear)")
        if self.envelope is not None:  # the envelope's model starts from linear Kt; the log, not the sheet, decides
            return CurrentCurve(kt=self.kt, source="linear: the measured envelope's model (mor --compare) starts there")
        return sheet_curve(self.kt, self.peak_torque)

    @property
    def torque_limit(self) -> float:
        """Torque limit actually in force [N m]: the peak torque, or the torque the current-torque curve makes at the
        driver's current limit if that is less (and never past the curve's top)."""
        curve = self.current_curve
        limit = min(self.peak_torque, curve.top_torque)
        if self.max_current is None:
            return limit
        return min(limit, float(curve.torque(self.max_current)))

    @property
    def linear_torque_limit(self) -> float:
        """What a linear-Kt model takes for the torque limit, min(peak torque, Kt * max current) [N m]."""
        if self.max_current is None:
            return self.peak_torque
        return min(self.peak_torque, self.kt * self.max_current)

    @property
    def drive_current(self) -> float:
        """The drive's current limit [A]: ``max_current``, else the current the torque limit needs."""
        return self.max_current if self.max_current is not None else self.limit_current

    @property
    def limit_current(self) -> float:
        """Current the curve needs for the torque limit [A] (the driver's limit when that binds)."""
        return float(self.current_curve.current(self.torque_limit))

    @property
    def stall_torque(self) -> float:
        """Torque at zero speed on the voltage line, Kt V_bus / R [N m]."""
        return self.kt * self.bus_voltage / self.resistance

    @property
    def no_load_speed(self) -> float:
        """Speed at zero torque on the voltage line, Kv V_bus [rad/s]."""
        return self.kv * self.bus_voltage

    @property
    def back_emf_damping(self) -> float:
        """Slope of the voltage line, Kt / (R Kv) [N m s/rad]."""
        return self.kt / (self.resistance * self.kv)

    def to_dict(self) -> dict[str, Any]:
        """SI values keyed by field name, with the units in the key docs (schema hound-id/motor/1)."""
        out: dict[str, Any] = {"schema": SCHEMA}
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, FitRecord | MeasuredEnvelope | Thermal):
                value = value.to_dict()
            out[f.name] = list(value) if isinstance(value, tuple) else value
        return out


def spec_warnings(spec: MotorSpec) -> tuple[str, ...]:
    """Plausibility checks that do not make a spec invalid but usually mean a mistake."""
    out: list[str] = []
    product = spec.kt * spec.kv
    if abs(product - 1.0) > KT_KV_TOLERANCE:
        out.append(
            f"{spec.name}: Kt = {spec.kt:.4g} N m/A and 1/Kv = {1 / spec.kv:.4g} V s/rad disagree by "
            f"{abs(product - 1) * 100:.0f} % (Kt*Kv = {product:.3g}, expected 0.87 (FOC) to 1 (DC)); "
            "check for rpm/V given as rad/s/V, or Kt per RMS amp"
        )
    if spec.inductance is not None and spec.commutation == "foc":
        if spec.pole_pairs is None:
            out.append(
                f"{spec.name}: inductance given without pole_pairs; the voltage edge ignores it (the reactance is "
                "p omega L): add pole_pairs"
            )
        elif spec.inductance_convention is None:
            out.append(
                f"{spec.name}: inductance {spec.inductance * 1e6:.4g} uH without inductance_convention; taken as "
                f"{DEFAULT_INDUCTANCE_CONVENTION} (what a meter across two terminals reads). A phase value has twice "
                "the reactance and costs more torque at speed: add 'inductance_convention: line_to_line' or 'phase'"
            )
    if spec.field_weakening and (spec.drive is None or spec.drive.reactance == 0.0):
        out.append(
            f"{spec.name}: field_weakening without a winding reactance (an inductance with pole_pairs): negative d "
            "current lowers the voltage only through the reactance, so it changes nothing here; add inductance, "
            "inductance_convention and pole_pairs"
        )
    if spec.inductance is not None and spec.commutation == "six_step":
        out.append(
            f"{spec.name}: inductance with six_step commutation; the dq model of the voltage edge applies to "
            "field-oriented drives (commutation: foc) only, so the inductance is not used"
        )
    if spec.torque_limit > spec.stall_torque:
        out.append(
            f"{spec.name}: torque limit {spec.torque_limit:.4g} N m exceeds the stall torque "
            f"{spec.stall_torque:.4g} N m; the voltage limit, not the peak torque, bounds the region at rest"
        )
    for key in spec.extrapolated:
        out.append(
            f"{spec.name}: {key} = {getattr(spec, key):.4g} is extrapolated beyond the measured range"
            + (f" ({_fit_peak(spec)})" if key == "peak_torque" and _fit_peak(spec) else "")
            + "; measure at higher current to confirm it"
        )
    return tuple(out)


def _fit_peak(spec: MotorSpec) -> str:
    """The fit's sentence on its peak torque, if the spec carries one."""
    return spec.fit.peak_note if spec.fit is not None else ""
