"""Reading a motor spec sheet (YAML, ``hound-id/motor/1``) into a :class:`~hound_id.mor.spec.MotorSpec`: the known
keys and their units, the plausible spans, the thermal fields, the bus range, a measured envelope and a fitted
motor's ``base:`` sheet; every mistake one line naming the field."""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from hound_id.arrays import frozen
from hound_id.errors import SpecError, where
from hound_id.io import file_stem, read_yaml
from hound_id.mor.drive import (
    INDUCTANCE_CONVENTIONS,
)
from hound_id.mor.envelope_effects import EFFECTS
from hound_id.mor.spec import KT_CURVES, LINE_TO_LINE_FACTOR, SCHEMA, FitRecord, MeasuredEnvelope, MotorSpec, read_only
from hound_id.mor.thermal import AMBIENT, Thermal, thermal_from_fields
from hound_id.units import to_celsius, to_si

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
    _check_keys(data, source)
    values = _quantities(data, source)
    commutation = _commutation(data, source)
    values = _resistance(values, commutation, source)
    pole_pairs = _pole_pairs(data, source)
    name, src = _name_and_source(data, source)
    assumed = _assumed(data, source)
    extrapolated = _extrapolated(data, source)
    kt_curve = _kt_curve(data, source)
    convention = _inductance_convention(data, values, source)
    weakening = _field_weakening(data, values, commutation, source)
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
    _check_envelope_within_limit(spec, source)
    return spec


def _check_keys(data: Any, source: str | None) -> None:
    """Refuse a sheet that is not a mapping, has an unknown key or schema, or is a fitted motor without its sheet."""
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


def _quantities(data: Mapping[str, Any], source: str | None) -> dict[str, float]:
    """The sheet's quantities in SI, each positive and within its plausible span; the required ones present."""
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
    return values


def _commutation(data: Mapping[str, Any], source: str | None) -> str:
    """The drive's commutation (foc unless stated), one of :data:`hound_id.mor.spec.LINE_TO_LINE_FACTOR`'s."""
    commutation = data.get("commutation", "foc")
    if commutation not in LINE_TO_LINE_FACTOR:
        raise SpecError(
            f"{where(source, 'commutation')}: found {commutation!r}, expected one of "
            f"{', '.join(sorted(LINE_TO_LINE_FACTOR))}",
            field="commutation",
        )
    return commutation


def _resistance(values: Mapping[str, float], commutation: str, source: str | None) -> dict[str, float]:
    """``values`` with the model resistance: given, or converted from the line-to-line one (one of the two)."""
    if "resistance" in values and "resistance_line_to_line" in values:
        raise SpecError(
            f"{where(source, 'resistance_line_to_line')}: both 'resistance' and 'resistance_line_to_line' "
            "given; keep one (the model resistance, or the datasheet line-to-line value to convert)",
            field="resistance_line_to_line",
        )
    out = dict(values)
    if "resistance_line_to_line" in out:
        out["resistance"] = out.pop("resistance_line_to_line") * LINE_TO_LINE_FACTOR[commutation]
    if "resistance" not in out:
        raise SpecError(
            f"{where(source, 'resistance')}: missing; give 'resistance' (model value) or "
            "'resistance_line_to_line' (datasheet value, converted by 'commutation')",
            field="resistance",
        )
    return out


def _pole_pairs(data: Mapping[str, Any], source: str | None) -> int | None:
    """The stated pole pairs (a whole number up to :data:`MAX_POLE_PAIRS`), or None."""
    pole_pairs = data.get("pole_pairs")
    if pole_pairs is not None and (
        isinstance(pole_pairs, bool) or not isinstance(pole_pairs, int) or not 1 <= pole_pairs <= MAX_POLE_PAIRS
    ):
        raise SpecError(
            f"{where(source, 'pole_pairs')}: found {pole_pairs!r}, expected a whole number from 1 to {MAX_POLE_PAIRS} "
            "(pole pairs, not poles: a 20-pole motor has 10)",
            field="pole_pairs",
        )
    return pole_pairs


def _name_and_source(data: Mapping[str, Any], source: str | None) -> tuple[str, str | None]:
    """The motor's name (usable as a file stem) and the sheet's ``source`` text."""
    name = data.get("name")
    if name is None or (isinstance(name, str) and not name.strip()):
        raise SpecError(f"{where(source, 'name')}: missing or empty; give the motor a name", field="name")
    name = file_stem(name, where(source, "name"))
    src = data.get("source")
    if src is not None and not isinstance(src, str):
        raise SpecError(f"{where(source, 'source')}: found {src!r}, expected text", field="source")
    return name, src


def _assumed(data: Mapping[str, Any], source: str | None) -> list[str]:
    """The ``assumed:`` list: names of spec fields (quantities or :data:`_ASSUMABLE` ones)."""
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
    return assumed


def _extrapolated(data: Mapping[str, Any], source: str | None) -> list[str]:
    """The ``extrapolated:`` list: names of spec quantities."""
    extrapolated = data.get("extrapolated", [])
    if not isinstance(extrapolated, list) or any(
        not isinstance(e, str) or e not in _QUANTITY_KEYS for e in extrapolated
    ):
        raise SpecError(
            f"{where(source, 'extrapolated')}: found {extrapolated!r}, expected a list of spec fields "
            "(e.g. [peak_torque])",
            field="extrapolated",
        )
    return extrapolated


def _kt_curve(data: Mapping[str, Any], source: str | None) -> str:
    """The current-torque curve the sheet asks for (quadratic unless stated), one of :data:`KT_CURVES`."""
    kt_curve = data.get("kt_curve", "quadratic")
    if kt_curve not in KT_CURVES:
        raise SpecError(
            f"{where(source, 'kt_curve')}: found {kt_curve!r}, expected one of {', '.join(KT_CURVES)} (quadratic: "
            "through the 20 % point at peak_torque; linear: tau = Kt i up to peak_torque)",
            field="kt_curve",
        )
    return kt_curve


def _inductance_convention(data: Mapping[str, Any], values: Mapping[str, float], source: str | None) -> str | None:
    """How the inductance was measured (one of :data:`INDUCTANCE_CONVENTIONS`), or None; only with an inductance."""
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
    return convention


def _field_weakening(
    data: Mapping[str, Any], values: Mapping[str, float], commutation: str, source: str | None
) -> bool:
    """Whether the drive weakens the field: only a field-oriented drive with a phase-current limit can."""
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
    return weakening


def _check_envelope_within_limit(spec: MotorSpec, source: str | None) -> None:
    """Refuse a measured envelope an edge of which passes the torque limit (every sample it came from lies within)."""
    if spec.envelope is not None:  # a measured envelope lies within the torque limit, like every sample it came from
        edges = [abs(v) for edge in (spec.envelope.lower, spec.envelope.upper) for v in edge if v == v]
        slack = spec.envelope.tolerance + 1e-9 * spec.linear_torque_limit
        if edges and max(edges) > spec.linear_torque_limit + slack:  # the envelope model's cap (mor.envelope)
            raise SpecError(
                f"{where(source, 'envelope')}: an edge reaches {max(edges):.4g} N m, past the torque limit "
                f"{spec.linear_torque_limit:.4g} N m; write the envelope with hound-id mor --compare --out"
            )


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
