"""The bundle: content against the robot's regions, YAML = JSON, old files still load, clear refusals."""

import json

import numpy as np
import pytest

from hound_id.errors import SpecError
from hound_id.export.bundle import SCHEMA, apply_fits, build_bundle, load_bundle
from hound_id.mor.joint_space import robot_regions
from hound_id.mor.robot import load_robot
from hound_id.mor.spec_sheet import load_motor_spec
from tests.conftest import ROBOT, ROOT

V1 = ROOT / "tests" / "data" / "bundle_v1_hound_like.yaml"


@pytest.fixture(scope="module")
def robot():
    return load_robot(ROBOT)


def test_bundle_carries_the_robot(robot):
    b = build_bundle(robot).to_dict()
    assert b["schema"] == SCHEMA and b["joints"] == list(robot.joints)
    regions = robot_regions(robot)
    for j in regions.joints:
        assert b["joint_boxes"][j.joint]["inner"] == pytest.approx(j.inner_box.to_dict())
        assert b["joint_boxes"][j.joint]["outer"] == pytest.approx(j.outer_box.to_dict())
    A = np.asarray(b["saturation"]["A"])
    assert A.shape == (12, 12) and np.allclose(A, robot.velocity_map())
    m = b["motors"][2]  # FL_KFE's motor on the sample spec sheet, no fit
    assert (m["joint"], m["kt"], m["bus_voltage"], m["fitted"]) == ("FL_KFE", 0.138, 81.0, False)
    assert m["friction"] == {
        "coulomb": 0.0,
        "gear_friction": 0.0,
        "stribeck": 0.0,
        "stribeck_speed": 0.0,
        "viscous": 0.0,
    }
    # the drive's dq model (35 uH per phase): torque and speed rows, then one under each segment of the curved edges
    assert m["halfspaces"]["labels"][:4] == ["torque+", "torque-", "speed+", "speed-"]
    assert all(label.startswith("drive") for label in m["halfspaces"]["labels"][4:])
    assert m["drive"]["inductance_phase"] == pytest.approx(35e-6) and m["drive"]["field_weakening"] is False
    assert m["bus_voltage_range"] == [66.0, 84.0] and b["saturation"]["bus_voltage"] == [81.0] * 12
    # the curve-limited torque limit: the 20 % point's quadratic at the driver's 70 A, and its exact inverse
    assert m["torque_limit"] == pytest.approx(9.66 - 0.16 * 0.138**2 / 12 * 70**2)
    assert m["linear_torque_limit"] == pytest.approx(9.66) and m["limit_current"] == pytest.approx(70.0)
    assert m["current_curve"]["form"] == "quadratic" and m["current_curve"]["k_sat"] == pytest.approx(
        0.16 * 0.138**2 / 12
    )
    assert m["compensation"]["method"].startswith("closed form") and m["compensation_polynomial"] is None
    assert b["saturation"]["limit_x"][2] == pytest.approx(9.66)
    assert b["saturation"]["curve_q"][2] == pytest.approx(0.16 / 12)
    # the reflected inertia is A^-T diag(J) A^-1: for HAA (ratio 9) J 9^2
    assert b["reflected_inertia"][0][0] == pytest.approx(1.7e-4 * 81)
    assert b["foot"] is None
    json.dumps(b)


def test_fits_replace_the_spec_sheet(robot, tmp_path):
    from tests.export.conftest import fitted_motor

    fitted = apply_fits(robot, [load_motor_spec(fitted_motor(tmp_path))])
    b = build_bundle(fitted).to_dict()
    m = b["motors"][0]
    assert m["fitted"] and m["kt"] == pytest.approx(0.1375)
    assert m["friction"]["coulomb"] == pytest.approx(0.08) and m["friction"]["viscous"] == pytest.approx(2e-4)
    assert m["effects"]["coulomb"]["unit"] == "N m" and m["compensation_polynomial"]["powers"] == [1, 3]
    # the fit has no saturation term: its curve is linear with the fitted Kt; the polynomial's error against it
    assert m["current_curve"]["form"] == "linear" and m["compensation"]["method"] == "i = tau / Kt"
    tau = np.linspace(0, m["torque_limit"], 2001)
    poly = 7.2727 * tau + 0.001 * tau**3
    assert m["compensation_polynomial"]["error_vs_exact"] == pytest.approx(np.max(np.abs(poly - tau / 0.1375)))


def test_bundle_files_of_version_1_still_load():
    b = load_bundle(V1).to_dict()
    assert b["schema"] == "hound-id/bundle/1" and len(b["joints"]) == 12
    assert b["motors"][0]["fitted"] and b["foot"]["mass"] < 0.05
    from hound_id.runtime import from_bundle

    sat = from_bundle(b)
    tau = np.full((3, 12), 500.0)
    assert np.all(np.abs(sat.saturate(tau, np.zeros((3, 12)))) < 500.0)


def test_bad_bundles_and_fits_are_refused(robot, tmp_path, write_yaml):
    with pytest.raises(SpecError, match="schema 'hound-id/bundle/9'; this hound-id reads hound-id/bundle/1"):
        load_bundle(write_yaml("b.yaml", "schema: hound-id/bundle/9\n"))
    with pytest.raises(SpecError, match="field 'saturation' missing"):
        load_bundle(write_yaml("c.yaml", "schema: hound-id/bundle/1\njoints: []\nmotors: []\n"))
    bad = tmp_path / "d.json"
    bad.write_text("{")
    with pytest.raises(SpecError, match="not JSON"):
        load_bundle(bad)
    with pytest.raises(SpecError, match="has no 'fit:' block"):
        apply_fits(robot, [load_motor_spec(ROOT / "data" / "samples" / "motors" / "hound_ilm85.yaml")])
    from tests.export.conftest import fitted_motor

    other = load_motor_spec(fitted_motor(tmp_path, base="qdd_small.yaml"))
    with pytest.raises(SpecError, match="the fitted motor is 'qdd_small', but the robot's motors are hound_ilm85"):
        apply_fits(robot, [other])


def test_the_bundle_is_a_frozen_value_that_writes_the_same_file(robot, tmp_path):
    """build_bundle gives a frozen Bundle; its file content survives a write and a load unchanged, and the
    version-1 sample (written before measured envelopes) loads with no envelope."""
    import dataclasses

    from hound_id.export.bundle import Bundle, BundleMotor
    from tests.export.conftest import fitted_motor

    b = build_bundle(apply_fits(robot, [load_motor_spec(fitted_motor(tmp_path))]))
    assert isinstance(b, Bundle) and isinstance(b.motors[0], BundleMotor)
    assert b.motors[0].friction["coulomb"] == pytest.approx(0.08) and b.joints == robot.joints
    with pytest.raises(dataclasses.FrozenInstanceError):
        b.robot = "other"  # type: ignore[misc]
    with pytest.raises(TypeError):
        b.saturation["A"] = None  # type: ignore[index]
    path = tmp_path / "b.json"
    path.write_text(json.dumps(b.to_dict()))
    assert load_bundle(path) == b and load_bundle(path).to_dict() == b.to_dict()
    assert json.dumps(load_bundle(path).to_dict()) == path.read_text()
    old = load_bundle(V1)
    assert all(m.envelope is None for m in old.motors) and "polylines" not in old.saturation


def test_a_fit_3_polynomial_keeps_its_own_error(robot, tmp_path):
    """fit/3 keeps the polynomial apart from the exact compensation: the bundle takes the polynomial's own range,
    error and slope error, and measures its error against the exact inverse."""
    from tests.export.conftest import fit3_motor

    b = build_bundle(apply_fits(robot, [load_motor_spec(fit3_motor(tmp_path))])).to_dict()
    poly = b["motors"][0]["compensation_polynomial"]
    assert (poly["torque_range"], poly["max_error"], poly["slope_error"]) == (7.73, 0.1319, 0.034)
    assert b["motors"][0]["compensation"]["method"].startswith("closed form")
    kt, k = 0.138, 3.94e-4
    tau = np.linspace(0, b["motors"][0]["torque_limit"], 2001)
    exact = 2 * tau / (kt + np.sqrt(kt**2 - 4 * k * tau))
    poly_i = 7.493 * tau + 0.03008 * tau**3 - 6.941e-05 * tau**5
    assert poly["error_vs_exact"] == pytest.approx(np.max(np.abs(poly_i - exact)))
