import math

import pytest

from hound_id.errors import HoundIdError, UnitError
from hound_id.units import to_si


@pytest.mark.parametrize(
    ("value", "kind", "expected"),
    [
        ("95 rpm/V", "speed_constant", 95 * 2 * math.pi / 60),
        (9.95, "speed_constant", 9.95),
        ("120 mohm", "resistance", 0.12),
        ("0.087 Nm/A", "torque_constant", 0.087),
        ("87 mNm/A", "torque_constant", 0.087),
        ("0.087 N m/A", "torque_constant", 0.087),
        ("0.087 V*s/rad", "torque_constant", 0.087),
        ("3000 rpm", "angular_velocity", 100 * math.pi),
        ("50 rps", "angular_velocity", 100 * math.pi),
        ("1.7 kg*cm^2", "inertia", 1.7e-4),
        ("70 uH", "inductance", 7e-5),
        (48, "voltage", 48.0),
    ],
)
def test_quantities_convert_to_si(value, kind, expected):
    assert to_si(value, kind) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize(
    ("value", "kind", "match"),
    [
        ("10 V", "speed_constant", "dimension"),
        ("3 Hz", "angular_velocity", "Hz, which is ambiguous"),
        ("fast", "angular_velocity", "cannot read"),
        (True, "voltage", "expected a voltage"),
        (None, "voltage", "expected a voltage"),
        ([1, 2], "voltage", "expected a voltage"),
        (float("nan"), "voltage", "finite"),
        ("inf V", "voltage", "finite"),
    ],
)
def test_bad_quantities_raise_one_error_family(value, kind, match):
    with pytest.raises(UnitError, match=match) as info:
        to_si(value, kind, source="m.yaml", field="x")
    assert isinstance(info.value, HoundIdError) and isinstance(info.value, ValueError)
    assert str(info.value).startswith("m.yaml: field 'x'")
