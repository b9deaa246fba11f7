"""Quantity parsing: the only place hound-id converts units.

Inputs may be plain numbers, which are taken as SI (N m/A, rad/s/V, ohm, V, N m,
A, rad/s, kg m^2, H), or strings with units that pint understands
(``"95 rpm/V"``, ``"120 mohm"``, ``"0.087 N*m/A"``). Everything is converted
once, here, to SI floats; code past this module works in SI only.

Two datasheet habits get special treatment:

* ``Nm`` (newton metre) is read as ``N*m``; pint alone would read nanometre.
* ``Hz`` is refused for angular speeds: it is ambiguous between rev/s and rad/s.
  Write ``rps``, ``rpm`` or ``rad/s``.

Units rows of CSV exports write units in other ways; :func:`normalise` reads them too:
``N.mm`` (a dot between units is a product), ``Deg C`` / ``deg F`` / ``°C`` (temperatures).
What a dot means in ``rad.s`` (a speed) is decided where the expected dimension is known
(:func:`slash_reading`).
"""

from __future__ import annotations

import math
import re
from functools import lru_cache
from typing import TYPE_CHECKING, Any

from hound_id.errors import UnitError, where

if TYPE_CHECKING:  # pragma: no cover
    import pint

#: Name of each physical kind hound-id reads -> (SI unit for pint, human label, example).
KINDS: dict[str, tuple[str, str, str]] = {
    "angular_velocity": ("rad/s", "an angular speed", "'6000 rpm' or 628.3 (rad/s)"),
    "current": ("A", "a current", "'70 A' or 70"),
    "density": ("kg/m**3", "a density", "'2.81 g/cm^3' or 2810"),
    "dimensionless": ("dimensionless", "a plain number", "7.5"),
    "inductance": ("H", "an inductance", "'85 uH' or 8.5e-5"),
    "force": ("N", "a force", "'1.5 kN' or 1500"),
    "inertia": ("kg*m**2", "a moment of inertia", "'120 kg*mm^2' or 1.2e-4"),
    "length": ("m", "a length", "'30 mm' or 0.03"),
    "pressure": ("Pa", "a stress or modulus", "'71.7 GPa' or 7.17e10"),
    "resistance": ("ohm", "a resistance", "'120 mohm' or 0.12"),
    "speed_constant": ("rad/s/V", "a speed constant", "'95 rpm/V' or 9.95 (rad/s/V)"),
    "temperature_coefficient": ("1/K", "a temperature coefficient", "'0.393 %/K' or 0.00393 (1/K)"),
    "thermal_resistance": ("K/W", "a thermal resistance", "'2 K/W' or 2"),
    "time": ("s", "a time", "'2 min' or 120 (s)"),
    "torque": ("N*m", "a torque", "'8 N*m' or 8"),
    "torque_constant": ("N*m/A", "a torque constant", "'0.087 N*m/A' or 0.087"),
    "voltage": ("V", "a voltage", "'81 V' or 81"),
}

_NM = re.compile(r"(?<![A-Za-z])([munk]?)Nm(?![A-Za-z])")
_DOT = re.compile(r"(?<=[A-Za-z0-9])\.(?=[A-Za-z])")
_DEGREES = re.compile(r"^(?:deg(?:ree)?s?\.?|°)\s*([CFK])$", re.IGNORECASE)


@lru_cache(maxsize=1)
def registry() -> pint.UnitRegistry:
    """The process-wide pint registry (built on first use; pint is slow to load)."""
    import pint

    return pint.UnitRegistry()


def normalise(text: str) -> str:
    """Unit text as pint should read it.

    ``Nm`` is newton metre, not nanometre; a dot between units is a product (``N.mm``);
    ``Deg C``, ``deg F`` and ``°C`` are degrees Celsius and Fahrenheit.
    """
    stripped = text.strip()
    degrees = _DEGREES.match(stripped)
    if degrees:
        letter = degrees.group(1).upper()
        return "kelvin" if letter == "K" else f"deg{letter}"
    return _DOT.sub("*", _NM.sub(r"\1N*m", stripped))


def slash_reading(text: str) -> str | None:
    """``rad.s`` -> ``rad/s``: the text with its last unit-separating dot read as a slash, or None without one.

    Some exports write ``rad.s`` for rad/s; the caller tries this reading only when the product reading has
    the wrong dimension for the column.
    """
    stripped = text.strip()
    dots = [m.start() for m in _DOT.finditer(stripped)]
    if not dots:
        return None
    k = dots[-1]
    return normalise(stripped[:k]) + "/" + normalise(stripped[k + 1 :])


#: The characters a unit or quantity may hold (letters, digits, _, spaces, * / ^ . · ( ) + - and the degree, micro,
#: ohm and percent signs); a power may be at most :data:`MAX_POWER` and never raised again ("9**9**9" would be evaluated
#: by pint's parser, for minutes).
_UNIT_CHARS = re.compile(r"[\w\s*/^.·()+\-°µΩ%]*")
_POWER = re.compile(r"(\*\*|\^)\s*(\(?\s*[+-]?\d*\.?\d+\s*\)?)(\s*(\*\*|\^))?")
MAX_POWER = 4.0


def check_unit_text(text: str) -> None:
    """Raise ValueError unless ``text`` can be handed to pint's parser safely: only the characters of
    :data:`_UNIT_CHARS`, no control characters, each power a plain number of at most :data:`MAX_POWER` in size and
    never raised to another power."""
    if not _UNIT_CHARS.fullmatch(text) or any(ord(c) < 32 for c in text):
        bad = next((c for c in text if not _UNIT_CHARS.fullmatch(c) or ord(c) < 32), "?")
        raise ValueError(f"the character {bad!r} has no place in a unit")
    for match in re.finditer(r"\*\*|\^", text):
        power = _POWER.match(text, match.start())
        if power is None:
            raise ValueError("a power that is not a plain number")
        if power.group(3):
            raise ValueError("a power raised to another power")
        if abs(float(power.group(2).strip("() "))) > MAX_POWER:
            raise ValueError(f"a power of {power.group(2).strip()}, more than {MAX_POWER:g}")


def unit_text_errors() -> tuple[type[BaseException], ...]:
    """What pint's parser raises on text that is no unit or quantity: its own errors, and what its tokenizer and
    evaluator raise on odd text ("N*m/A)" ends in a TokenError, "N*m/" in an AssertionError, a long product in a
    RecursionError)."""
    import tokenize

    import pint

    return (
        pint.errors.PintError,
        ValueError,
        TypeError,
        AttributeError,
        SyntaxError,
        AssertionError,
        RecursionError,
        OverflowError,
        ZeroDivisionError,
        tokenize.TokenError,
    )


def is_unit(text: str) -> bool:
    """Whether pint reads ``text`` (normalised) as a unit; a quick test for units rows."""
    try:
        check_unit_text(text)
        registry().Unit(normalise(text))
    except Exception:  # pint raises many kinds for text that is no unit
        return False
    return True


def to_si(value: Any, kind: str, *, source: str | None = None, field: str | None = None) -> float:
    """Convert a spec value to an SI float of the given physical kind.

    Args:
        value: A plain number (already SI) or a string with units.
        kind: One of :data:`KINDS`.
        source: File the value came from, for messages.
        field: Field name, for messages.

    Returns:
        The value in the SI unit of ``kind`` (see :data:`KINDS`).

    Raises:
        UnitError: The value is not a number or quantity, has the wrong dimension,
            or is not finite.
    """
    si_unit, label, example = KINDS[kind]
    loc = where(source, field)
    if isinstance(value, bool) or value is None:
        raise UnitError(
            f"{loc}: found {value!r}, expected {label} such as {example}",
            found=value,
            expected=si_unit,
        )
    if isinstance(value, (int, float)):
        try:
            result = float(value)
        except OverflowError:  # an integer of hundreds of digits
            result = math.inf
    elif isinstance(value, str) and _is_number(value):
        result = float(value)  # YAML 1.1 reads 1e3 (no dot) as text: a plain number, so SI
    elif isinstance(value, str):
        if kind in _PER_DEGREE:  # a difference of 1 degC is 1 K (pint refuses offset units in products)
            value = _DEGREE_C.sub("K", _DEGREE_F.sub("delta_degF", value))
        result = _parse_string(value, kind, loc)
    else:
        raise UnitError(
            f"{loc}: found {type(value).__name__} {value!r}, expected {label} such as {example}",
            found=value,
            expected=si_unit,
        )
    if not math.isfinite(result):
        raise UnitError(
            f"{loc}: found {value!r}, expected a finite {label.split(' ', 1)[1]}", found=value, expected=si_unit
        )
    return result


_TEMPERATURE = re.compile(
    r"\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*"
    r"(degC|°C|deg C|C|celsius|degF|°F|deg F|F|fahrenheit|K|kelvin)\s*$",
    re.IGNORECASE,
)
_TEMPERATURE_UNITS = {"degc": "degC", "°c": "degC", "deg c": "degC", "c": "degC", "celsius": "degC", "degf": "degF",
                      "°f": "degF", "deg f": "degF", "f": "degF", "fahrenheit": "degF", "k": "kelvin",
                      "kelvin": "kelvin"}  # fmt: skip


def to_celsius(value: Any, *, source: str | None = None, field: str | None = None) -> float:
    """A temperature [degC] from a plain number (degC, as in the dyno logs) or text such as '120 degC', '248 degF' or
    '393.15 K' (pint converts; a temperature is not a product of units, so it is read on its own).

    Raises:
        UnitError: Not a temperature, or not finite, or below absolute zero.
    """
    loc = where(source, field)
    number = as_number(value)
    if number is None and isinstance(value, str):
        match = _TEMPERATURE.match(value)
        if match:
            unit = _TEMPERATURE_UNITS[match.group(2).lower()]
            number = float(registry().Quantity(float(match.group(1)), unit).to("degC").magnitude)
    if number is not None and number < -273.15:
        raise UnitError(f"{loc}: found {value!r}, below absolute zero (-273.15 degC)", found=value, expected="degC")
    if number is None or not math.isfinite(number):
        raise UnitError(
            f"{loc}: found {value!r}, expected a temperature such as '120 degC', '393 K' or 120 (degC)",
            found=value,
            expected="degC",
        )
    return number


#: Kinds whose units may name a temperature difference in degrees (``%/degC``, ``degC/W``).
_PER_DEGREE = ("temperature_coefficient", "thermal_resistance")
_DEGREE_C = re.compile(r"(?:°|deg\s?)C\b")
_DEGREE_F = re.compile(r"(?:°|deg\s?)F\b")


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def as_number(value: Any) -> float | None:
    """A plain number from a YAML value (int, float or numeric text such as '1e3'), else None."""
    if isinstance(value, bool):
        return None
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, str) and _is_number(value):
        return float(value)
    return None


#: The longest text read as a quantity [characters]; "0.138 N*m/A" is 11 (pint's parser recurses on a long one).
QUANTITY_MAX_CHARS = 200
#: A quantity's text starts with its number (pint would read "N*m/A" alone as 1 N m/A).
_LEADING_NUMBER = re.compile(r"\s*[+-]?(\d+\.?\d*|\.\d+|inf|nan)([eE][+-]?\d+)?", re.IGNORECASE)


def _parse_string(text: str, kind: str, loc: str) -> float:

    si_unit, label, example = KINDS[kind]
    if len(text) > QUANTITY_MAX_CHARS:
        raise UnitError(
            f"{loc}: found {len(text):,} characters, too long for a quantity (at most {QUANTITY_MAX_CHARS}); expected "
            f"{label} such as {example}",
            found=text[:QUANTITY_MAX_CHARS],
            expected=si_unit,
        )
    ureg = registry()
    try:
        check_unit_text(text)
        quantity: Any = ureg.Quantity(normalise(text))
    except unit_text_errors() as err:
        why = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise UnitError(
            f"{loc}: cannot read {text!r} as a quantity ({why}); expected {label} such as {example}",
            found=text,
            expected=si_unit,
        ) from err
    if kind == "angular_velocity" or kind == "speed_constant":
        if "hertz" in str(quantity.units) or "Hz" in text:
            raise UnitError(
                f"{loc}: {text!r} uses Hz, which is ambiguous for an angular speed "
                "(rev/s or rad/s?); write it in rps, rpm or rad/s",
                found=text,
                expected=si_unit,
            )
    if not _LEADING_NUMBER.match(text):  # pint reads a bare unit as 1 of it
        raise UnitError(
            f"{loc}: found {text!r}, a unit without a number; expected {label} such as {example}",
            found=text,
            expected=si_unit,
        )
    target = ureg.Unit(si_unit)
    if quantity.dimensionality != target.dimensionality:
        raise UnitError(
            f"{loc}: found {text!r} with dimension {quantity.dimensionality}, expected {label} "
            f"in units of {si_unit} (for example {example}); fix the unit",
            found=text,
            expected=si_unit,
        )
    return float(quantity.to(target).magnitude)


#: Factors for derived display units (SI value * factor = display value).
RPM_PER_RAD_S = 60.0 / (2.0 * math.pi)
#: deg/s per rad/s.
DEG_S_PER_RAD_S = 180.0 / math.pi
#: N cm and mN m per N m.
NCM_PER_NM = 100.0
MNM_PER_NM = 1000.0
