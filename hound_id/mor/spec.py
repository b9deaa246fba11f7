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
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from functools import cached_property
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen
from hound_id.errors import SpecError, where
from hound_id.io import file_stem, read_yaml
from hound_id.mor.current_curve import CurrentCurve, quadratic_cubic_table, sheet_curve
from hound_id.mor.drive import (
    DEFAULT_INDUCTANCE_CONVENTION,
    INDUCTANCE_CONVENTIONS,
    PHASE_FACTOR,
    Drive,
    reactance_per_speed,
)
from hound_id.mor.envelope_effects import EFFECTS
from hound_id.mor.thermal import AMBIENT, Thermal, thermal_from_fields
from hound_id.units import to_celsius, to_si

SCHEMA = "hound-id/motor/1"

#: The spec sheet's current-torque curves (``kt_curve``).
KT_CURVES = ("quadratic", "linear")

#: Relative disagreement between Kt and 1/Kv above which a spec is flagged.
KT_KV_TOLERANCE = 0.15

#: R_model / R_line-to-line for each commutation (see module docstring).
LINE_TO_LINE_FACTOR = {"foc": math.sqrt(3.0) / 2.0, "six_step": 1.0}

# key -> (physical kind, required)
_QUANTITY_KEYS: dict[str, tuple[str, bool]] = {
    "kt": ("torque_constant", True),
    "kv": ("speed_constant", True),
    "resistance": ("resistance", False),
    "resistance_line_to_line": ("resistance", False),
    "bus_voltage": ("voltage", True),
    "peak_torque": ("torque", True),
    "max_current": ("current", False),
    "max_speed": ("angular_velocity", False),
    "rotor_inertia": ("inertia", False),
    "inductance": ("inductance", False),
    "thermal_resistance": ("thermal_resistance", False),
    "thermal_time_constant": ("time", False),
    "continuous_current": ("current", False),
}
#: Temperatures a spec may state [degC] (:func:`hound_id.units.to_celsius`).
_TEMPERATURE_KEYS = ("winding_limit", "ambient_temperature", "derate_start")
#: Temperature coefficients [1/K] -> (lowest, highest): copper's 0.393 %/K and NdFeB's or SmCo's Kt drift, with margin.
_COEFFICIENT_KEYS: dict[str, tuple[float, float]] = {
    "resistance_temperature_coefficient": (0.0, 0.01),
    "kt_temperature_coefficient": (-0.005, 0.001),
}
#: What the thermal model needs besides R_th or the continuous current (one of the two).
_THERMAL_NEEDS = ("thermal_time_constant", "winding_limit")
_THERMAL_EXAMPLE = {"thermal_time_constant": "120 s", "winding_limit": "120 degC"}
#: Temperature key -> (lowest, highest) [degC]: winding limits from enamel class A (105) to above class H (180),
#: ambients a robot meets; a kelvin value written as a plain number (393) falls outside.
_TEMPERATURE_SPAN = {
    "winding_limit": (40.0, 250.0),
    "ambient_temperature": (-60.0, 80.0),
    "derate_start": (-60.0, 250.0),
}
_OTHER_KEYS = (
    "name",
    "source",
    "notes",
    "pole_pairs",
    "commutation",
    "schema",
    "assumed",
    "extrapolated",
    "base",
    "fit",
    "envelope",
    "kt_curve",
    "inductance_convention",
    "field_weakening",
    "bus_voltage_range",
)
KNOWN_KEYS = tuple(sorted((*_QUANTITY_KEYS, *_OTHER_KEYS, *_TEMPERATURE_KEYS, *_COEFFICIENT_KEYS)))

#: key -> (lowest, highest, SI unit): the span of electric motors from a hobby servo to a
#: 100 kW traction motor, with margin. A value outside is a unit slip (mN m read as N m,
#: rpm/V as rad/s/V) or a typo, and would make the region's geometry degenerate.
PLAUSIBLE: dict[str, tuple[float, float, str]] = {
    "kt": (1e-4, 100.0, "N m/A"),
    "kv": (0.1, 1e4, "rad/s/V"),
    "resistance": (1e-4, 1e3, "ohm"),
    "resistance_line_to_line": (1e-4, 1e3, "ohm"),
    "bus_voltage": (0.5, 2000.0, "V"),
    "peak_torque": (1e-4, 1e4, "N m"),
    "max_current": (1e-3, 1e4, "A"),
    "max_speed": (0.1, 1e5, "rad/s"),
    "rotor_inertia": (1e-10, 10.0, "kg m^2"),
    "inductance": (1e-8, 10.0, "H"),
    "thermal_resistance": (1e-3, 1e3, "K/W"),
    "thermal_time_constant": (0.1, 1e5, "s"),
    "continuous_current": (1e-3, 1e4, "A"),
}


#: Most pole pairs a spec may state: large-diameter torque motors reach a few dozen; more is a typo (or poles, or
#: slots) that would multiply the winding's reactance.
MAX_POLE_PAIRS = 200

#: Fields besides the quantities that ``assumed:`` may name.
_ASSUMABLE = (
    "pole_pairs",
    "inductance_convention",
    "bus_voltage_range",
    "field_weakening",
    *_TEMPERATURE_KEYS,
    *_COEFFICIENT_KEYS,
)


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


def _suggest(key: str) -> str:
    close = [key.lower()] if key.lower() in KNOWN_KEYS else difflib.get_close_matches(key, KNOWN_KEYS, n=1)
    return f"did you mean '{close[0]}'?" if close else f"known keys: {', '.join(KNOWN_KEYS)}"


def motor_spec_from_mapping(data: Any, source: str | None = None) -> MotorSpec:
    """Validate a parsed spec-sheet mapping and convert it to SI.

    Args:
        data: The parsed YAML (a mapping).
        source: File name, for messages.

    Raises:
        SpecError: Missing, unknown or non-physical fields.
        UnitError: A quantity with the wrong dimension.
    """
    if not isinstance(data, Mapping):
        raise SpecError(
            f"{where(source)}: found {type(data).__name__}, expected a mapping of spec fields "
            f"(name, kt, kv, resistance, bus_voltage, peak_torque, ...)",
            found=data,
        )
    unknown = [k for k in data if k not in KNOWN_KEYS]
    if unknown:
        key = str(unknown[0])
        raise SpecError(f"{where(source, key)}: unknown key; {_suggest(key)}", field=key)
    schema = data.get("schema", SCHEMA)
    if schema != SCHEMA:
        raise SpecError(f"{where(source, 'schema')}: found {schema!r}, expected {SCHEMA!r}", field="schema")

    if "fit" in data and "base" not in data:
        missing = [k for k, (_, req) in _QUANTITY_KEYS.items() if req and k not in data]
        if missing:
            raise SpecError(
                f"{where(source)}: a fitted motor without a spec sheet lacks {', '.join(missing)}; add "
                "'base: <your motor spec>.yaml' to it, or rerun hound-id fit-current with --spec MOTOR.yaml",
                field=missing[0],
            )
    values: dict[str, float] = {}
    for key, (kind, required) in _QUANTITY_KEYS.items():
        if key not in data or data[key] is None:
            if required:
                raise SpecError(
                    f"{where(source, key)}: missing; add it (see docs/mor.md)",
                    field=key,
                )
            continue
        value = to_si(data[key], kind, source=source, field=key)
        if not value > 0.0:
            raise SpecError(
                f"{where(source, key)}: found {data[key]!r}, expected a positive value", field=key, found=data[key]
            )
        lo, hi, unit = PLAUSIBLE[key]
        if not lo <= value <= hi:
            advice = "(the span of real motors); check the number and its unit"
            raise _out_of_span(source, key, data[key], value, (lo, hi, unit), advice)
        values[key] = value

    commutation = data.get("commutation", "foc")
    if commutation not in LINE_TO_LINE_FACTOR:
        raise SpecError(
            f"{where(source, 'commutation')}: found {commutation!r}, expected one of "
            f"{', '.join(sorted(LINE_TO_LINE_FACTOR))}",
            field="commutation",
        )
    if "resistance" in values and "resistance_line_to_line" in values:
        raise SpecError(
            f"{where(source, 'resistance_line_to_line')}: both 'resistance' and 'resistance_line_to_line' "
            "given; keep one (the model resistance, or the datasheet line-to-line value to convert)",
            field="resistance_line_to_line",
        )
    if "resistance_line_to_line" in values:
        values["resistance"] = values.pop("resistance_line_to_line") * LINE_TO_LINE_FACTOR[commutation]
    if "resistance" not in values:
        raise SpecError(
            f"{where(source, 'resistance')}: missing; give 'resistance' (model value) or "
            "'resistance_line_to_line' (datasheet value, converted by 'commutation')",
            field="resistance",
        )

    pole_pairs = data.get("pole_pairs")
    if pole_pairs is not None and (
        isinstance(pole_pairs, bool) or not isinstance(pole_pairs, int) or not 1 <= pole_pairs <= MAX_POLE_PAIRS
    ):
        raise SpecError(
            f"{where(source, 'pole_pairs')}: found {pole_pairs!r}, expected a whole number from 1 to {MAX_POLE_PAIRS} "
            "(pole pairs, not poles: a 20-pole motor has 10)",
            field="pole_pairs",
        )
    name = data.get("name")
    if name is None or (isinstance(name, str) and not name.strip()):
        raise SpecError(f"{where(source, 'name')}: missing or empty; give the motor a name", field="name")
    name = file_stem(name, where(source, "name"))
    src = data.get("source")
    if src is not None and not isinstance(src, str):
        raise SpecError(f"{where(source, 'source')}: found {src!r}, expected text", field="source")
    assumed = data.get("assumed", [])
    if not isinstance(assumed, list):
        raise SpecError(
            f"{where(source, 'assumed')}: found {assumed!r}, expected a list of field names", field="assumed"
        )
    for entry in assumed:
        if not isinstance(entry, str):
            raise SpecError(
                f"{where(source, 'assumed')}: found {entry!r} in the list, expected field names (kt, kv, ...)",
                field="assumed",
            )
        if entry not in _QUANTITY_KEYS and entry not in _ASSUMABLE:
            raise SpecError(
                f"{where(source, 'assumed')}: '{entry}' is not a spec field; {_suggest(str(entry))}", field="assumed"
            )
    extrapolated = data.get("extrapolated", [])
    if not isinstance(extrapolated, list) or any(
        not isinstance(e, str) or e not in _QUANTITY_KEYS for e in extrapolated
    ):
        raise SpecError(
            f"{where(source, 'extrapolated')}: found {extrapolated!r}, expected a list of spec fields "
            "(e.g. [peak_torque])",
            field="extrapolated",
        )
    kt_curve = data.get("kt_curve", "quadratic")
    if kt_curve not in KT_CURVES:
        raise SpecError(
            f"{where(source, 'kt_curve')}: found {kt_curve!r}, expected one of {', '.join(KT_CURVES)} (quadratic: "
            "through the 20 % point at peak_torque; linear: tau = Kt i up to peak_torque)",
            field="kt_curve",
        )
    convention = data.get("inductance_convention")
    if convention is not None and convention not in INDUCTANCE_CONVENTIONS:
        raise SpecError(
            f"{where(source, 'inductance_convention')}: found {convention!r}, expected one of "
            f"{', '.join(INDUCTANCE_CONVENTIONS)} (line_to_line: measured across two terminals; phase: one phase of "
            "the wye)",
            field="inductance_convention",
        )
    if convention is not None and "inductance" not in values:
        raise SpecError(
            f"{where(source, 'inductance_convention')}: given without an inductance; add 'inductance' or drop it",
            field="inductance_convention",
        )
    weakening = data.get("field_weakening", False)
    if not isinstance(weakening, bool):
        raise SpecError(
            f"{where(source, 'field_weakening')}: found {weakening!r}, expected true or false",
            field="field_weakening",
        )
    if weakening and commutation != "foc":
        raise SpecError(
            f"{where(source, 'field_weakening')}: field weakening needs a field-oriented drive (commutation: foc), "
            f"found commutation {commutation!r}",
            field="field_weakening",
        )
    if weakening and "max_current" not in values:
        raise SpecError(
            f"{where(source, 'field_weakening')}: field weakening needs the drive's phase-current limit: add "
            "max_current (the amplitude |i_dq| the drive holds)",
            field="field_weakening",
        )
    bus_range = _bus_range(data.get("bus_voltage_range"), values["bus_voltage"], source)
    fit = data.get("fit")
    if fit is not None and not isinstance(fit, Mapping):
        raise SpecError(f"{where(source, 'fit')}: found {type(fit).__name__}, expected the fit mapping")
    fit_record = None if fit is None else FitRecord.from_mapping(fit, source)
    thermal = _thermal(data, values, commutation, fit_record, source)
    spec = MotorSpec(
        name=name.strip(),
        pole_pairs=pole_pairs,
        source=src,
        assumed=tuple(assumed),
        extrapolated=tuple(extrapolated),
        fit=fit_record,
        envelope=_envelope(data.get("envelope"), source),
        kt_curve=kt_curve,
        commutation=commutation,
        inductance_convention=convention,
        field_weakening=weakening,
        bus_voltage_range=bus_range,
        thermal=thermal,
        **{k: v for k, v in values.items() if k not in _THERMAL_QUANTITIES},
    )
    if spec.envelope is not None:  # a measured envelope lies within the torque limit, like every sample it came from
        edges = [abs(v) for edge in (spec.envelope.lower, spec.envelope.upper) for v in edge if v == v]
        slack = spec.envelope.tolerance + 1e-9 * spec.linear_torque_limit
        if edges and max(edges) > spec.linear_torque_limit + slack:  # the envelope model's cap (mor.envelope)
            raise SpecError(
                f"{where(source, 'envelope')}: an edge reaches {max(edges):.4g} N m, past the torque limit "
                f"{spec.linear_torque_limit:.4g} N m; write the envelope with hound-id mor --compare --out"
            )
    return spec


#: The quantities the thermal model takes (carried by :attr:`MotorSpec.thermal`, not as fields of their own).
_THERMAL_QUANTITIES = ("thermal_resistance", "thermal_time_constant", "continuous_current")


def _out_of_span(
    source: str | None, key: str, found: Any, value: float, span: tuple[float, float, str], advice: str
) -> SpecError:
    """The one-line refusal of a value outside its span (lowest, highest, unit)."""
    lo, hi, unit = span
    sep = "" if advice.startswith(";") else " "
    return SpecError(
        f"{where(source, key)}: found {found!r} = {value:.4g} {unit}, expected {lo:g} to {hi:g} {unit}{sep}{advice}",
        field=key,
        found=found,
    )


def _thermal(
    data: Mapping[str, Any], values: Mapping[str, float], commutation: str, fit: FitRecord | None, source: str | None
) -> Thermal | None:
    """The spec's thermal model (:mod:`hound_id.mor.thermal`), or None where it states none of its fields."""
    stated = [k for k in (*_THERMAL_QUANTITIES, *_TEMPERATURE_KEYS, *_COEFFICIENT_KEYS) if data.get(k) is not None]
    if not stated:
        return None
    missing = [k for k in _THERMAL_NEEDS if data.get(k) is None]
    heat = [k for k in ("thermal_resistance", "continuous_current") if k in values]
    if missing:
        raise SpecError(
            f"{where(source, missing[0])}: missing; the thermal model ({stated[0]} is given) needs "
            f"{' and '.join(missing)}: add {', '.join(f'{k}: {_THERMAL_EXAMPLE[k]}' for k in missing)}, or drop the "
            "thermal fields",
            field=missing[0],
        )
    if not heat:
        raise SpecError(
            f"{where(source, 'thermal_resistance')}: missing; the thermal model needs thermal_resistance (winding to "
            "ambient, e.g. '2 K/W') or continuous_current (the peak phase current the winding holds at its limit)",
            field="thermal_resistance",
        )
    if len(heat) == 2:
        raise SpecError(
            f"{where(source, 'continuous_current')}: give only one of thermal_resistance and continuous_current (the "
            "other follows from it); drop one",
            field="continuous_current",
        )
    temps = {k: to_celsius(data[k], source=source, field=k) for k in _TEMPERATURE_KEYS if data.get(k) is not None}
    for key, value in temps.items():
        lo, hi = _TEMPERATURE_SPAN[key]
        if not lo <= value <= hi:
            advice = "; a plain number is degC: write a kelvin value with its unit ('393 K')"
            raise _out_of_span(source, key, data[key], value, (lo, hi, "degC"), advice)
    coefficients: dict[str, float] = {}
    for key, (lo, hi) in _COEFFICIENT_KEYS.items():
        if data.get(key) is None:
            continue
        value = to_si(data[key], "temperature_coefficient", source=source, field=key)
        if not lo <= value <= hi:
            raise SpecError(
                f"{where(source, key)}: found {data[key]!r} = {value * 100:.4g} %/K, expected {lo * 100:g} to "
                f"{hi * 100:g} %/K (copper 0.393 %/K; NdFeB's Kt -0.09 to -0.12 %/K); check the unit (%/K or 1/K)",
                field=key,
                found=data[key],
            )
        coefficients[key] = value
    limit = temps["winding_limit"]
    ambient = temps.get("ambient_temperature")
    start = temps.get("derate_start")
    amb = AMBIENT if ambient is None else ambient
    if not amb < limit:
        raise SpecError(
            f"{where(source, 'winding_limit')}: {limit:g} degC is not above the ambient {amb:g} degC; the winding "
            "could never carry current",
            field="winding_limit",
        )
    if start is not None and not amb <= start <= limit:
        raise SpecError(
            f"{where(source, 'derate_start')}: {start:g} degC, expected between the ambient and the winding limit "
            f"{limit:g} degC (the drive lowers its current limit from there to zero at the limit)",
            field="derate_start",
        )
    alpha_kt, alpha_source = coefficients.get("kt_temperature_coefficient"), "spec"
    if alpha_kt is None and fit is not None and "kt_temp_coeff" in fit.parameters and fit.value("kt") > 0:
        alpha_kt = fit.value("kt_temp_coeff") / fit.value("kt")
        alpha_source = "fit (kt_temp_coeff / kt)"
    return thermal_from_fields(
        resistance_20=values["resistance"],
        commutation=commutation,
        time_constant=values["thermal_time_constant"],
        winding_limit=limit,
        thermal_resistance=values.get("thermal_resistance"),
        continuous_current=values.get("continuous_current"),
        ambient=ambient,
        derate_start=start,
        alpha_resistance=coefficients.get("resistance_temperature_coefficient"),
        alpha_kt=alpha_kt,
        alpha_kt_source=alpha_source if alpha_kt is not None else "",
    )


def _bus_range(
    data: Any, nominal: float, source: str | None, key: str | None = "bus_voltage_range"
) -> tuple[float, float] | None:
    """A spec's ``bus_voltage_range`` ([lowest, highest], with units), checked: 0 < lowest <= nominal <= highest."""
    if data is None:
        return None
    if not isinstance(data, list | tuple) or len(data) != 2:
        raise SpecError(
            f"{where(source, key)}: found {data!r}, expected [lowest, highest], e.g. [66 V, 84 V]",
            field="bus_voltage_range",
        )
    low, high = (to_si(v, "voltage", source=source, field=key) for v in data)
    lo, hi, _ = PLAUSIBLE["bus_voltage"]
    if not (lo <= low <= nominal <= high <= hi):
        raise SpecError(
            f"{where(source, key)}: found {low:.4g} V to {high:.4g} V, expected a range holding "
            f"bus_voltage {nominal:.4g} V (lowest <= bus_voltage <= highest, within {lo:g} to {hi:g} V)",
            field="bus_voltage_range",
        )
    return (low, high)


def with_bus_range(spec: MotorSpec, text: str, option: str = "--bus-range") -> MotorSpec:
    """The spec with the battery's range given on the command line, ``"66 V,84 V"`` (or ``"66,84"``, volts), in place
    of its own ``bus_voltage_range``; SpecError names what is wrong."""
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 2 or not all(parts):
        raise SpecError(
            f"{option}: found {text!r}, expected the lowest and highest bus voltage separated by a comma, e.g. "
            "'66 V,84 V' or 66,84",
            field="bus_voltage_range",
        )
    return replace(spec, bus_voltage_range=_bus_range(parts, spec.bus_voltage, option, None))


def _envelope(data: Any, source: str | None) -> MeasuredEnvelope | None:
    """A spec's ``envelope`` block, checked: increasing speeds, lower <= upper, equal lengths."""
    if data is None:
        return None
    if not isinstance(data, Mapping):
        raise SpecError(
            f"{where(source, 'envelope')}: found {type(data).__name__}, expected a mapping with speeds, lower and "
            "upper; write it with hound-id mor --compare --out"
        )
    try:
        speeds = [float(v) for v in data["speeds"]]
        lower = [float("nan") if v is None else float(v) for v in data["lower"]]
        upper = [float("nan") if v is None else float(v) for v in data["upper"]]
    except (KeyError, TypeError, ValueError) as err:
        raise SpecError(f"{where(source, 'envelope')}: expected speeds, lower and upper lists ({err})") from err
    effects, tolerance = data.get("effects", {}), data.get("tolerance", 0.0)
    if not isinstance(effects, Mapping):
        raise SpecError(f"{where(source, 'envelope.effects')}: found {effects!r}, expected a mapping effect: value")
    if isinstance(tolerance, bool) or not isinstance(tolerance, int | float) or not tolerance >= 0:
        raise SpecError(f"{where(source, 'envelope.tolerance')}: found {tolerance!r}, expected a number >= 0 [N m]")
    for key, value in effects.items():
        effect = EFFECTS.get(str(key))
        if effect is None:
            raise SpecError(
                f"{where(source, 'envelope.effects')}: unknown effect {key!r}; effects are {', '.join(EFFECTS)}"
            )
        lo, hi = effect.bounds
        if isinstance(value, bool) or not isinstance(value, int | float) or not lo <= value <= hi:
            raise SpecError(
                f"{where(source, f'envelope.effects.{key}')}: found {value!r}, expected {effect.parameter} in "
                f"[{lo:g}, {hi:g}] {effect.unit}"
            )
    ok = len(speeds) == len(lower) == len(upper) >= 2 and all(np.diff(speeds) > 0)
    if not ok or any(lo > hi for lo, hi in zip(lower, upper, strict=True) if lo == lo and hi == hi):
        raise SpecError(
            f"{where(source, 'envelope')}: needs at least two increasing speeds with lower <= upper at each; "
            "write it with hound-id mor --compare --out"
        )
    coverage = data.get("coverage")
    return MeasuredEnvelope(
        effects=MappingProxyType({str(k): float(v) for k, v in effects.items()}),
        speeds=frozen(speeds),
        lower=frozen(lower),
        upper=frozen(upper),
        tolerance=float(tolerance),
        coverage=read_only(coverage) if isinstance(coverage, Mapping) else None,
        source=str(data.get("source", "mor --compare")),
        written=read_only(data),
    )


def load_motor_spec(path: str | Path) -> MotorSpec:
    """Read and validate a motor spec YAML file (see module docstring for its conventions)."""
    data = read_yaml(path, "motor spec")
    if isinstance(data, Mapping) and "base" in data:
        data = _merge_base(data, Path(path))
    return motor_spec_from_mapping(data, source=str(path))


def _merge_base(data: Mapping[str, Any], path: Path) -> dict[str, Any]:
    """A fitted spec's own fields on top of the spec sheet it names with ``base:``."""
    base_ref = data["base"]
    if not isinstance(base_ref, str):
        raise SpecError(f"{where(str(path), 'base')}: found {base_ref!r}, expected the path of a motor spec file")
    base_path = path.parent / base_ref
    if not base_path.is_file():
        raise SpecError(
            f"{where(str(path), 'base')}: the spec sheet {base_path} it names is not there (base paths are relative "
            "to this file); fix 'base:' or rerun hound-id fit-current with --spec",
            field="base",
        )
    base = read_yaml(base_path, "motor spec")
    if not isinstance(base, Mapping):
        raise SpecError(f"{base_path}: expected a mapping of spec fields (named by 'base' in {path})")
    if "base" in base:
        raise SpecError(f"{base_path}: a base spec cannot itself have a 'base' (named by {path})")
    merged = {**base, **{k: v for k, v in data.items() if k != "base"}}
    # Fields the fit measured are no longer assumed.
    overridden = [k for k in data if k in _QUANTITY_KEYS]
    if "assumed" in base and "assumed" not in data:
        merged["assumed"] = [a for a in base["assumed"] if a not in overridden]
    return merged
