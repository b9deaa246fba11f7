import math

import pytest

from hound_id.errors import SpecError, UnitError
from hound_id.foot.material import (
    GROUNDS,
    MATERIALS,
    allowed_pressure,
    contact_radius,
    effective_modulus,
    load_material,
    min_radius,
    peak_pressure,
)


def test_hertz_formulas_agree_with_each_other():
    al, concrete = MATERIALS["aluminium_7075_t6"], GROUNDS["concrete"]
    e_star = effective_modulus(al, concrete)
    # 1/E* = (1 - 0.33^2)/71.7 GPa + (1 - 0.2^2)/30 GPa
    assert e_star == pytest.approx(1 / ((1 - 0.33**2) / 71.7e9 + (1 - 0.2**2) / 30e9))
    F, R = 1500.0, 0.03
    a = contact_radius(F, R, e_star)
    assert peak_pressure(F, R, e_star) == pytest.approx(3 * F / (2 * math.pi * a**2))  # p0 = 1.5 x mean pressure
    p_allow = allowed_pressure(al, 1.5)
    assert p_allow == pytest.approx(1.6 * 503e6 / 1.5)
    r_min = min_radius(F, e_star, p_allow)
    assert peak_pressure(F, r_min, e_star) == pytest.approx(p_allow, rel=1e-12)
    # larger force or weaker material: larger radius
    assert min_radius(2 * F, e_star, p_allow) > r_min
    assert min_radius(F, e_star, allowed_pressure(MATERIALS["aluminium_6061_t6"], 1.5)) > r_min


def test_material_from_a_file_with_units(write_yaml):
    path = write_yaml(
        "ti.yaml",
        "name: ti_printed\ndensity: 4.41 g/cm^3\nyoungs_modulus: 110 GPa\npoisson: 0.32\n"
        "yield_strength: 950 MPa\nmin_wall: 0.8 mm\nsource: vendor sheet\n",
    )
    m = load_material(str(path))
    assert (m.name, m.density, m.youngs_modulus, m.yield_strength, m.min_wall) == pytest.approx(
        ("ti_printed", 4410.0, 110e9, 950e6, 0.0008)
    )


def test_material_errors(write_yaml):
    with pytest.raises(SpecError, match="unknown material 'unobtainium'.*aluminium_7075_t6"):
        load_material("unobtainium")
    base = "density: 2700\npoisson: 0.3\nyield_strength: 2e8\n"
    with pytest.raises(SpecError, match="field 'min_wall' missing"):
        load_material(str(write_yaml("a.yaml", base + "youngs_modulus: 70e9\n")))
    with pytest.raises(UnitError, match="youngs_modulus"):
        load_material(str(write_yaml("b.yaml", base + "youngs_modulus: 70 kg\nmin_wall: 1e-3\n")))
    with pytest.raises(SpecError, match="unknown field"):
        load_material(str(write_yaml("c.yaml", "densty: 2700\n")))
    with pytest.raises(SpecError, match="--ground: unknown material 'sand'"):
        load_material("sand", GROUNDS, "--ground")


def test_values_in_the_wrong_unit_are_caught(write_yaml):
    base = "density: 2700\npoisson: 0.3\nyield_strength: 276 MPa\n"
    with pytest.raises(SpecError, match="field 'min_wall' is 0.8 m, expected 0 to 0.02 m; write the unit"):
        load_material(str(write_yaml("a.yaml", base + "youngs_modulus: 69 GPa\nmin_wall: 0.8\n")))
    with pytest.raises(SpecError, match="youngs_modulus .* is not above yield_strength"):
        load_material(str(write_yaml("b.yaml", base + "youngs_modulus: 110 MPa\nmin_wall: 1 mm\n")))
    with pytest.raises(SpecError, match="field 'poisson' is 0.7"):
        load_material(
            str(write_yaml("c.yaml", base.replace("0.3", "0.7") + "youngs_modulus: 69 GPa\nmin_wall: 1 mm\n"))
        )
