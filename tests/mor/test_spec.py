import math

import pytest

from hound_id.errors import SpecError, UnitError
from hound_id.mor.spec import LINE_TO_LINE_FACTOR, spec_warnings
from hound_id.mor.spec_sheet import load_motor_spec, motor_spec_from_mapping
from tests.conftest import MOTOR, SMALL_MOTOR

BASE = {"name": "m", "kt": 0.1, "kv": 10.0, "resistance": 0.2, "bus_voltage": 48.0, "peak_torque": 3.0}


def test_samples_load_with_units_converted():
    small = load_motor_spec(SMALL_MOTOR)
    assert small.kv == pytest.approx(100 * 2 * math.pi / 60)
    assert small.resistance == pytest.approx(0.31)
    assert small.max_speed == pytest.approx(2000 * 2 * math.pi / 60)
    assert small.rotor_inertia == pytest.approx(0.6e-4)
    hound = load_motor_spec(MOTOR)
    # driver-limited below the 12 N m peak: the 20 % point's quadratic at 70 A, Kt i - 0.16 Kt^2 / P i^2
    assert hound.linear_torque_limit == pytest.approx(0.138 * 70)
    assert hound.torque_limit == pytest.approx(0.138 * 70 - 0.16 * 0.138**2 / 12 * 70**2)
    assert hound.limit_current == pytest.approx(70.0)
    assert spec_warnings(hound) == () and spec_warnings(small) == ()


def test_same_motor_in_si_numbers_and_in_datasheet_units_is_the_same_spec():
    si = motor_spec_from_mapping(dict(BASE, max_speed=500.0, rotor_inertia=1e-4))
    units = motor_spec_from_mapping(
        {
            "name": "m",
            "kt": "100 mNm/A",
            "kv": f"{10 * 60 / (2 * math.pi)} rpm/V",
            "resistance": "200 mohm",
            "bus_voltage": "48000 mV",
            "peak_torque": "3 N*m",
            "max_speed": f"{500 / (2 * math.pi)} rps",
            "rotor_inertia": "1 kg*cm^2",
        }
    )
    for field in ("kt", "kv", "resistance", "bus_voltage", "peak_torque", "max_speed", "rotor_inertia"):
        assert getattr(units, field) == pytest.approx(getattr(si, field), rel=1e-12), field


@pytest.mark.parametrize(("commutation", "factor"), [("foc", math.sqrt(3) / 2), ("six_step", 1.0)])
def test_line_to_line_resistance_is_converted(commutation, factor):
    data = {k: v for k, v in BASE.items() if k != "resistance"}
    spec = motor_spec_from_mapping(dict(data, resistance_line_to_line="0.3 ohm", commutation=commutation))
    assert spec.resistance == pytest.approx(0.3 * factor)
    assert LINE_TO_LINE_FACTOR[commutation] == pytest.approx(factor)


def test_foc_conversion_matches_the_physics_notes():
    # Feeding R_ll into the DC formula overstates the slope by about 15 %.
    assert 1 / LINE_TO_LINE_FACTOR["foc"] - 1 == pytest.approx(0.155, abs=0.005)


@pytest.mark.parametrize(
    ("change", "error", "match"),
    [
        ({"kt": None}, SpecError, "field 'kt': missing"),
        ({"peak_torque": None}, SpecError, "field 'peak_torque': missing"),
        ({"kvv": 3}, SpecError, "field 'kvv': unknown key; did you mean 'kv'"),
        ({"kv": "10 V"}, UnitError, "field 'kv'.*dimension"),
        ({"resistance": -0.1}, SpecError, "field 'resistance'.*positive"),
        ({"bus_voltage": 0}, SpecError, "field 'bus_voltage'.*positive"),
        ({"resistance_line_to_line": 0.2}, SpecError, "both 'resistance' and"),
        ({"commutation": "trapezoid"}, SpecError, "commutation"),
        ({"pole_pairs": 2.5}, SpecError, "pole_pairs.*whole number from 1 to 200"),
        ({"name": ""}, SpecError, "field 'name'"),
        ({"schema": "hound-id/motor/9"}, SpecError, "schema"),
        ({"assumed": ["colour"]}, SpecError, "assumed"),
    ],
)
def test_bad_specs_name_the_field(change, error, match):
    data = dict(BASE)
    for key, value in change.items():
        if value is None:
            data.pop(key, None)
        else:
            data[key] = value
    with pytest.raises(error, match=match):
        motor_spec_from_mapping(data, source="motor.yaml")


def test_missing_resistance_says_which_keys_work():
    data = {k: v for k, v in BASE.items() if k != "resistance"}
    with pytest.raises(SpecError, match="resistance_line_to_line"):
        motor_spec_from_mapping(data)


def test_file_problems(write_yaml, tmp_path):
    with pytest.raises(SpecError, match="file not found"):
        load_motor_spec(tmp_path / "nope.yaml")
    with pytest.raises(SpecError, match="line 3 is not valid YAML"):
        load_motor_spec(write_yaml("bad.yaml", "name: x\nkt: [1,\n"))
    with pytest.raises(SpecError, match="expected a mapping"):
        load_motor_spec(write_yaml("list.yaml", "- 1\n- 2\n"))


def test_kt_kv_mixup_warns():
    # Kv in rpm/V typed as rad/s/V: off by 9.5x.
    spec = motor_spec_from_mapping(dict(BASE, kt=0.087, kv=95.0))
    (warning,) = spec_warnings(spec)
    assert "disagree" in warning and "rpm/V" in warning
    # FOC convention (Kt = 8.27 / Kv[rpm/V]) is within tolerance.
    foc = motor_spec_from_mapping(dict(BASE, kt=8.27 / 95, kv="95 rpm/V"))
    assert spec_warnings(foc) == ()


def test_torque_limit_above_stall_warns():
    spec = motor_spec_from_mapping(dict(BASE, resistance=5.0))  # stall 0.96 N m < 3 N m peak
    assert any("stall torque" in w for w in spec_warnings(spec))


def test_yaml_numbers_without_a_dot_and_duplicate_keys(write_yaml):
    # YAML 1.1 reads 1e-1 as text; it is still a plain (SI) number
    spec = load_motor_spec(
        write_yaml("e.yaml", "name: m\nkt: 1e-1\nkv: 1e1\nresistance: 2e-1\nbus_voltage: 48\npeak_torque: 3\n")
    )
    assert spec.kt == pytest.approx(0.1) and spec.kv == pytest.approx(10.0)
    with pytest.raises(SpecError, match="line 3: key 'kt' appears twice"):
        load_motor_spec(write_yaml("d.yaml", "name: m\nkt: 0.1\nkt: 0.2\nkv: 10\nresistance: 0.2\n"))


def test_assumed_names_the_bad_entry():
    with pytest.raises(SpecError, match="'kvv' is not a spec field; did you mean 'kv'"):
        motor_spec_from_mapping(dict(BASE, assumed=["kt", "kvv"]))


def test_fitted_spec_on_a_base_sheet(write_yaml, tmp_path):
    write_yaml(
        "sheet.yaml",
        "name: m\nkt: 0.1\nkv: 10\nresistance: 0.2\nbus_voltage: 48\npeak_torque: 3\n"
        "assumed: [kt, peak_torque, resistance]\n",
    )
    fitted = load_motor_spec(
        write_yaml("fitted.yaml", "base: sheet.yaml\nkt: 0.093\npeak_torque: 2.6\nfit: {schema: hound-id/fit/1}\n")
    )
    assert fitted.kt == 0.093 and fitted.peak_torque == 2.6 and fitted.kv == 10
    assert fitted.assumed == ("resistance",)
    assert fitted.fit.to_dict() == {"schema": "hound-id/fit/1"}
    with pytest.raises(SpecError, match="field 'base': the spec sheet .*nope.yaml it names is not there"):
        load_motor_spec(write_yaml("orphan.yaml", "base: nope.yaml\nkt: 0.1\n"))
    with pytest.raises(SpecError, match="a fitted motor without a spec sheet lacks kv, bus_voltage.*--spec"):
        load_motor_spec(write_yaml("bare.yaml", "name: m\nkt: 0.1\npeak_torque: 2\nfit: {schema: hound-id/fit/1}\n"))


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"effects": "bus_sag"}, r"envelope.effects': found 'bus_sag', expected a mapping"),
        ({"effects": {"warp_drive": 1}}, "unknown effect 'warp_drive'"),
        ({"effects": {"bus_sag": -3}}, r"envelope.effects.bus_sag': found -3, expected r_pack in \[0, 5\] ohm"),
        ({"tolerance": "x"}, "envelope.tolerance': found 'x', expected a number"),
        ({"upper": [50.0, 50.0]}, "an edge reaches 50 N m, past the torque limit 9.66 N m"),  # the envelope's (linear)
        ({"speeds": [1.0, 0.0]}, "needs at least two increasing speeds"),
    ],
)
def test_a_measured_envelope_block_is_checked(write_yaml, change, match):
    """The envelope of mor --compare --out bounds the saturation and the export: a damaged one is refused."""
    import yaml

    from tests.conftest import MOTOR

    envelope = {"effects": {"bus_sag": 0.15}, "speeds": [-500.0, 500.0], "lower": [-9.0, -9.0],
                "upper": [9.0, 9.0], "tolerance": 0.02, **change}  # fmt: skip
    path = write_yaml("env.yaml", yaml.safe_dump({"schema": "hound-id/motor/1", "base": str(MOTOR),
                                                  "envelope": envelope}))  # fmt: skip
    with pytest.raises(SpecError, match=match):
        load_motor_spec(path)


def test_fit_and_envelope_are_frozen_typed_records(tmp_path):
    """A fitted spec's fit and a measured envelope are frozen records with read-only arrays; each writes its block
    back exactly as the file holds it."""
    import dataclasses

    import numpy as np
    import yaml

    from hound_id.mor.envelope import fitted_curve
    from hound_id.mor.spec import FitCompensation, FitRecord, MeasuredEnvelope
    from tests.export.conftest import fitted_motor
    from tests.mor.test_region import write_envelope_spec

    path = fitted_motor(tmp_path)
    spec = load_motor_spec(path)
    assert isinstance(spec.fit, FitRecord) and spec.fit.model == ("linear", "coulomb", "viscous")
    assert spec.fit.parameters["coulomb"].value == 0.08 and spec.fit.parameters["coulomb"].unit == "N m"
    assert spec.fit.value("viscous") == 2e-4 and spec.fit.value("stribeck") == 0.0
    assert spec.fit.compensation == FitCompensation((1, 3), (7.2727, 0.001))
    # a fit/2 record of a model without saturation: its curve is linear with the fitted Kt (the polynomial is kept)
    assert fitted_curve(spec) is spec.fit.curve and spec.fit.curve.form == "linear"
    assert spec.fit.curve.kt == spec.fit.value("kt") and spec.current_curve is spec.fit.curve
    assert spec.fit.to_dict() == yaml.safe_load(path.read_text())["fit"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        spec.fit.model = ()  # type: ignore[misc]
    with pytest.raises(TypeError):
        spec.fit.parameters["kt"] = None  # type: ignore[index]

    env_path = write_envelope_spec(tmp_path / "env.yaml", {"bus_sag": 0.15})
    env = load_motor_spec(env_path).envelope
    assert isinstance(env, MeasuredEnvelope) and env.effects == {"bus_sag": 0.15}
    assert env.source == "mor --compare" and env.coverage is None
    written = yaml.safe_load(env_path.read_text())["envelope"]
    assert env.to_dict() == written and env.tolerance == written["tolerance"]
    for array in env.polyline:
        assert not array.flags.writeable
    assert np.array_equal(env.speeds, written["speeds"])
    with pytest.raises(SpecError, match=r"field 'fit': malformed fit record \(KeyError"):
        motor_spec_from_mapping(dict(BASE, fit={"parameters": {"kt": {"unit": "N m/A"}}}))
