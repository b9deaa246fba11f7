"""Foot materials, the ground, and the Hertz contact that sets the foot's smallest radius.

A sphere of radius R pressed on a flat with force F (Hertz; Johnson, *Contact Mechanics*,
1985, ch. 4):

* effective modulus 1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2;
* contact radius a = (3 F R / (4 E*))^(1/3);
* peak pressure p0 = 3 F / (2 pi a^2) = (6 F E*^2 / (pi^3 R^2))^(1/3);
* the largest shear stress lies at depth 0.48 a below the surface (nu = 0.3).

Yield first starts below the surface when p0 = 1.60 Y (von Mises, nu = 0.3; Johnson
sec. 6.2), so the allowed peak pressure is 1.60 Y / S for a safety factor S, and the radius
must be at least R_min = sqrt(6 F E*^2 / (pi^3 p_allow^3)).

Hertz assumes solid bodies. A shell foot is checked for the contact stress and for a wall
at least :data:`DEPTH_WALLS` times the depth of the largest shear stress; its bending as a
shell is not analysed (use FEA for the final part).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hound_id.errors import SpecError
from hound_id.io import read_yaml
from hound_id.units import to_si

#: p0 at first yield over the yield stress, for a sphere on a flat (Johnson sec. 6.2, nu = 0.3).
YIELD_PRESSURE_FACTOR = 1.60
#: Depth of the largest shear stress below the contact, over the contact radius (nu = 0.3).
SHEAR_DEPTH_FACTOR = 0.48
#: The wall must be this many times the depth of the largest shear stress (hound-id's rule).
DEPTH_WALLS = 3.0


@dataclass(frozen=True)
class Material:
    """An isotropic material, SI."""

    name: str
    density: float
    """Density [kg/m^3]."""
    youngs_modulus: float
    """Young's modulus E [Pa]."""
    poisson: float
    """Poisson's ratio nu [-]."""
    yield_strength: float
    """Yield (0.2 % proof) strength Y [Pa]; 0 for a ground that is never checked."""
    min_wall: float
    """Thinnest wall the usual process makes reliably [m]; 0 for a ground."""
    source: str
    """Where the numbers come from."""

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


#: Foot materials, typical handbook values (MatWeb/ASM data sheets for the named tempers).
MATERIALS: dict[str, Material] = {
    m.name: m
    for m in sorted(
        [
            Material("aluminium_6061_t6", 2700.0, 68.9e9, 0.33, 276e6, 1.5e-3, "ASM/MatWeb 6061-T6; wall: machined"),
            Material("aluminium_7075_t6", 2810.0, 71.7e9, 0.33, 503e6, 1.5e-3, "ASM/MatWeb 7075-T6; wall: machined"),
            Material("titanium_ti6al4v", 4430.0, 113.8e9, 0.342, 880e6, 1.0e-3, "ASM/MatWeb Ti-6Al-4V annealed"),
            Material("steel_17_4ph_h900", 7800.0, 197e9, 0.27, 1170e6, 1.0e-3, "ASM/MatWeb 17-4PH H900"),
            Material("pa12_sls", 1010.0, 1.70e9, 0.39, 48e6, 2.0e-3, "typical SLS PA12 data sheet (x-y)"),
        ],
        key=lambda m: m.name,
    )
}
#: Grounds the foot runs on.
GROUNDS: dict[str, Material] = {
    "concrete": Material("concrete", 2400.0, 30e9, 0.20, 0.0, 0.0, "typical structural concrete"),
    "steel": Material("steel", 7850.0, 200e9, 0.29, 0.0, 0.0, "structural steel (a rigid treadmill deck)"),
}
DEFAULT_MATERIAL = "aluminium_7075_t6"
DEFAULT_GROUND = "concrete"

_FIELDS = {
    "density": "density",
    "youngs_modulus": "pressure",
    "poisson": "dimensionless",
    "yield_strength": "pressure",
    "min_wall": "length",
}


def load_material(name_or_path: str, table: dict[str, Material] | None = None, what: str = "--material") -> Material:
    """A material by name from ``table`` (the foot materials by default) or from a YAML file.

    A file has ``name``, ``density``, ``youngs_modulus``, ``poisson``, ``yield_strength``,
    ``min_wall`` (values with units allowed, e.g. ``71.7 GPa``) and an optional ``source``.
    """
    table = MATERIALS if table is None else table
    if name_or_path in table:
        return table[name_or_path]
    path = Path(name_or_path)
    if path.suffix.lower() not in (".yaml", ".yml"):
        raise SpecError(
            f"{what}: unknown material '{name_or_path}'; expected one of {', '.join(table)} or a YAML file",
            found=name_or_path,
        )
    data = read_yaml(path, "material")
    if not isinstance(data, dict):
        raise SpecError(f"{path}: expected a mapping of material properties, found {type(data).__name__}")
    unknown = sorted(str(k) for k in set(data) - set(_FIELDS) - {"name", "source", "schema"})
    if unknown:
        raise SpecError(f"{path}: unknown field(s) {', '.join(unknown)}; expected {', '.join(_FIELDS)}, name, source")
    values: dict[str, float] = {}
    for field, kind in _FIELDS.items():
        if field not in data:
            raise SpecError(f"{path}: field '{field}' missing; a material needs {', '.join(_FIELDS)}", field=field)
        values[field] = to_si(data[field], kind, source=str(path), field=field)
    # plausible ranges for solids, so that a value in the wrong unit is caught
    ranges = {
        "density": (100.0, 25000.0, "kg/m^3"),
        "youngs_modulus": (1e6, 1.5e12, "Pa"),
        "poisson": (0.0, 0.5, ""),
        "yield_strength": (1e5, 1e10, "Pa"),
        "min_wall": (0.0, 0.02, "m"),
    }
    for field, (lo, hi, unit) in ranges.items():
        if not lo <= values[field] < hi:
            raise SpecError(
                f"{path}: field '{field}' is {values[field]:g} {unit}, expected {lo:g} to {hi:g} {unit}; "
                "write the unit (e.g. '0.8 mm', '110 GPa') if the number is not SI",
                field=field,
            )
    if values["youngs_modulus"] <= values["yield_strength"]:
        raise SpecError(
            f"{path}: youngs_modulus {values['youngs_modulus']:g} Pa is not above yield_strength "
            f"{values['yield_strength']:g} Pa; check their units",
            field="youngs_modulus",
        )
    return Material(name=str(data.get("name", path.stem)), source=str(data.get("source", str(path))), **values)


def effective_modulus(a: Material, b: Material) -> float:
    """Hertz effective modulus E* of two bodies [Pa]."""
    return 1.0 / ((1 - a.poisson**2) / a.youngs_modulus + (1 - b.poisson**2) / b.youngs_modulus)


def allowed_pressure(material: Material, safety: float) -> float:
    """Largest Hertz peak pressure before subsurface yield, over the safety factor [Pa]."""
    return YIELD_PRESSURE_FACTOR * material.yield_strength / safety


def peak_pressure(force: Any, radius: Any, e_star: float) -> Any:
    """Hertz peak pressure p0 of a sphere on a flat [Pa] (force [N], radius [m])."""
    return (6 * force * e_star**2 / (math.pi**3 * radius**2)) ** (1 / 3)


def contact_radius(force: Any, radius: Any, e_star: float) -> Any:
    """Hertz contact radius a [m]."""
    return (3 * force * radius / (4 * e_star)) ** (1 / 3)


def min_radius(force: float, e_star: float, p_allow: float) -> float:
    """Smallest sphere radius whose Hertz peak pressure stays at or below p_allow [m]."""
    return math.sqrt(6 * force * e_star**2 / (math.pi**3 * p_allow**3))
