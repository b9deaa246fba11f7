import itertools
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.optimize import linprog

from hound_id.errors import RobotError
from hound_id.mor.joint_space import _group_constraints, robot_regions
from hound_id.mor.region import operating_region
from hound_id.mor.robot import load_robot
from hound_id.mor.saturation import saturation_for
from tests.conftest import ROBOT, SMALL_MOTOR
from tests.mor.test_region import write_envelope_spec

MIXED = f"""
name: mixed
motor_specs: {{s: {SMALL_MOTOR}}}
joints: [a, h, k, p, q]
transmissions:
  - {{type: ratio, joints: [a], motors: [ma], motor_spec: s, ratios: [-6.0]}}
  - {{type: hollow_shaft, joints: [h, k], motors: [mh, mk], motor_spec: s, hip_ratio: 9, knee_ratio: 6}}
  - {{type: matrix, joints: [p, q], motors: [mp, mq], motor_spec: s, matrix: [[0.1, 0.03], [-0.02, 0.12]]}}
"""


@pytest.fixture(scope="module")
def sample():
    robot = load_robot(ROBOT)
    return robot, robot_regions(robot), saturation_for(robot)


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    """The sample robot with its motor's measured envelope (a 0.15 ohm pack: non-convex near no-load)."""
    folder = tmp_path_factory.mktemp("measured")
    write_envelope_spec(folder / "ilm85_envelope.yaml", {"bus_sag": 0.15})
    text = ROBOT.read_text().replace("../motors/hound_ilm85.yaml", "ilm85_envelope.yaml")
    text = text.replace("urdf: hound_like.urdf\n", "")
    (folder / "robot.yaml").write_text(text)
    robot = load_robot(folder / "robot.yaml")
    return robot, robot_regions(robot), saturation_for(robot)


@pytest.fixture
def mixed(write_yaml):
    robot = load_robot(write_yaml("mixed.yaml", MIXED))
    return robot, robot_regions(robot), saturation_for(robot)


def test_uncoupled_inner_box_is_the_motors_box_through_the_ratio(sample):
    robot, regions, _ = sample
    jr = regions.joints[robot.joints.index("FL_HAA")]
    spec = robot.motor_specs["FL_HAA_motor"]
    # the inner box holds at every charge: the motor's box at the battery's lowest voltage
    motor = operating_region(replace(spec, bus_voltage=spec.bus_voltage_range[0]))
    assert jr.inner_box_bus_voltage == (spec.bus_voltage_range[0],)
    assert jr.inner_box.effort == pytest.approx(9.0 * motor.inner_box[0], rel=1e-4)
    assert jr.inner_box.velocity == pytest.approx(motor.inner_box[1] / 9.0, rel=1e-4)
    # the half-spaces' polygon meets the curved edges to within EDGE_TOLERANCE near the steep edge at overspeed
    assert jr.outer_box.velocity == pytest.approx(operating_region(spec).overspeed / 9.0, rel=1e-4)


@pytest.fixture(scope="module")
def dc_sample(tmp_path_factory):
    """The sample robot with its motor's inductance dropped: the paper's DC law, V = R i + omega/Kv."""
    folder = tmp_path_factory.mktemp("dc")
    sheet = (ROBOT.parent.parent / "motors" / "hound_ilm85.yaml").read_text()
    sheet = "\n".join(line for line in sheet.splitlines() if not line.startswith("inductance"))
    (folder / "ilm85_dc.yaml").write_text(sheet.replace(" inductance,", "").replace(" inductance_convention,", ""))
    text = (
        ROBOT.read_text().replace("../motors/hound_ilm85.yaml", "ilm85_dc.yaml").replace("urdf: hound_like.urdf\n", "")
    )
    (folder / "robot.yaml").write_text(text)
    robot = load_robot(folder / "robot.yaml")
    return robot, robot_regions(robot), saturation_for(robot)


def test_uncoupled_inner_box_is_torque_limit_to_corner_speed_under_the_dc_law(dc_sample):
    """Without the winding's reactance the region is the paper's hexagon: the box runs to the corner speed."""
    robot, regions, _ = dc_sample
    jr = regions.joints[robot.joints.index("FL_HAA")]
    spec = next(iter(robot.motor_specs.values()))
    motor = operating_region(replace(spec, bus_voltage=spec.bus_voltage_range[0]))  # the box every charge holds
    assert motor.drive is None
    assert jr.inner_box.effort == pytest.approx(9.0 * motor.torque_limit, rel=1e-6)
    assert jr.inner_box.velocity == pytest.approx(motor.corner_speed / 9.0, rel=1e-6)


@pytest.mark.parametrize("which", ["sample", "mixed", "measured"])
def test_every_corner_of_the_inner_boxes_is_feasible_and_the_boxes_are_tight(which, request):
    robot, regions, sat = request.getfixturevalue(which)
    T = np.array([j.inner_box.effort for j in regions.joints])
    W = np.array([j.inner_box.velocity for j in regions.joints])
    # the boxes hold at the battery's lowest voltage (each group's motors'), and are tight there
    low = {m: v for j in regions.joints for m, v in zip(j.motors, j.inner_box_bus_voltage, strict=True)}
    volts = np.array([low[m] for m in robot.motors])
    for tx in robot.transmissions:
        idx = [robot.joints.index(j) for j in tx.joints]
        corners = []
        for signs in itertools.product([-1.0, 1.0], repeat=2 * len(idx)):
            tau, qd = np.zeros(robot_n := len(robot.joints)), np.zeros(robot_n)
            tau[idx] = np.array(signs[: len(idx)]) * T[idx]
            qd[idx] = np.array(signs[len(idx) :]) * W[idx]
            corners.append((tau, qd))
        tau = np.array([c[0] for c in corners])
        qd = np.array([c[1] for c in corners])
        assert sat.violation(tau, qd, bus_voltage=volts).max() <= 1e-7
        grown = sat.violation(tau * 1.001, qd * 1.001, bus_voltage=volts)
        assert grown.max() > 0.0, f"inner box of {tx.joints} is not tight"


@pytest.mark.parametrize("which", ["sample", "mixed"])
def test_outer_box_matches_an_independent_linear_program(which, request):
    robot, regions, _ = request.getfixturevalue(which)
    from scipy.spatial import ConvexHull

    for tx in robot.transmissions:
        # each motor's region as the convex hull of its traced vertices (the outer box is what the motors reach:
        # the hull of their curved regions), not the conservative half-space cut hound-id keeps
        hulls = []
        for m in tx.motors:
            v = operating_region(robot.motor_specs[m]).vertices
            scale = np.abs(v).max(axis=0)
            eq = ConvexHull(v / scale).equations  # a . (x / scale) + c <= 0
            hulls.append(SimpleNamespace(A=eq[:, :2] / scale, b=-eq[:, 2]))
        G, h = _group_constraints(tx, hulls)
        k = len(tx.joints)
        for i, joint in enumerate(tx.joints):
            jr = regions.joints[robot.joints.index(joint)]
            for col, bound in ((i, jr.outer_box.effort), (k + i, jr.outer_box.velocity)):
                c = np.zeros(2 * k)
                c[col] = -1.0
                res = linprog(c, A_ub=G, b_ub=h, bounds=[(None, None)] * (2 * k), method="highs")
                assert res.status == 0
                assert -res.fun == pytest.approx(bound, rel=1e-7)


def test_sections_lie_inside_projections_and_are_feasible(mixed):
    robot, regions, sat = mixed
    for i, jr in enumerate(regions.joints):
        tau = np.zeros((len(jr.section), len(robot.joints)))
        qd = np.zeros_like(tau)
        tau[:, i], qd[:, i] = jr.section[:, 0], jr.section[:, 1]
        assert sat.violation(tau, qd).max() <= 1e-7 * np.abs(jr.section).max()
        assert np.abs(jr.section[:, 0]).max() <= jr.outer_box.effort * (1 + 1e-9)
        assert np.abs(jr.section[:, 1]).max() <= jr.outer_box.velocity * (1 + 1e-9)


def test_json(sample):
    data = sample[1].to_dict()
    assert data["schema"] == "hound-id/mor-robot/1"
    assert [j["joint"] for j in data["joints"]] == list(sample[0].joints)
    assert {"inner_box", "outer_box", "section_vertices", "projection_vertices"} <= set(data["joints"][1])


def test_single_motor_inner_box_matches_the_motor_region(write_yaml):
    text = f"""
name: one
motor_specs: {{s: {SMALL_MOTOR}}}
joints: [a]
transmissions:
  - {{type: ratio, joints: [a], motors: [ma], motor_spec: s, ratios: [1]}}
"""
    robot = load_robot(write_yaml("one.yaml", text))
    jr = robot_regions(robot).joints[0]
    region = operating_region(robot.motor_specs["ma"])
    assert (jr.inner_box.effort, jr.inner_box.velocity) == pytest.approx(region.inner_box, rel=1e-6)


def test_an_uncoupled_transmission_of_several_joints_gives_each_joint_its_own_motor_box(write_yaml):
    """A ``ratio`` with two joints (two motors of different specs) and a diagonal ``matrix``: each joint gets its own
    motor's box through its own gear (the review found one box for the whole transmission, then a crash)."""
    from tests.conftest import MOTOR

    text = f"""
name: two
motor_specs: {{s: {SMALL_MOTOR}, big: {MOTOR}}}
joints: [a, b, c, d]
transmissions:
  - {{type: ratio, joints: [a, b], motors: [ma, mb], motor_spec: s, ratios: [6.0, -7.5]}}
  - {{type: matrix, joints: [c, d], motors: [mc, md], motor_spec: big, matrix: [[0.1, 0.0], [0.0, 0.125]]}}
"""
    robot = load_robot(write_yaml("two.yaml", text))
    joints = robot_regions(robot).joints
    for joint, motor, gear in (("a", "ma", 6.0), ("b", "mb", 7.5), ("c", "mc", 10.0), ("d", "md", 8.0)):
        box = joints[robot.joints.index(joint)].inner_box
        spec = robot.motor_specs[motor]  # the box every charge holds: at the battery's lowest voltage, if stated
        low = spec.bus_voltage_range[0] if spec.bus_voltage_range else spec.bus_voltage
        T, W = operating_region(replace(spec, bus_voltage=low)).inner_box
        assert (box.effort, box.velocity) == pytest.approx((T * gear, W / gear), rel=1e-9)


def test_extreme_gear_ratios_do_not_break_the_geometry_and_beyond_real_gearboxes_are_refused(write_yaml):
    def robot(a: str, b: str) -> str:
        return f"""
name: extreme
motor_specs: {{s: {SMALL_MOTOR}}}
joints: [a, b]
transmissions:
  - {{type: matrix, joints: [a], motors: [ma], motor_spec: s, matrix: [[{a}]]}}
  - {{type: ratio, joints: [b], motors: [mb], motor_spec: s, ratios: [{b}]}}
"""

    # the span's edges: a 10,000:1 reduction and a 1:100 speed-up
    regions = robot_regions(load_robot(write_yaml("x.yaml", robot("1e-4", "1e-2"))))
    a, b = regions.joints
    assert a.outer_box.effort == pytest.approx(2.4e4, rel=1e-9)
    assert b.outer_box.effort == pytest.approx(2.4e-2, rel=1e-9)
    assert len(a.section) >= 4
    with pytest.raises(RobotError, match="reductions up to 10000"):
        load_robot(write_yaml("y.yaml", robot("1e-9", "9")))
    with pytest.raises(RobotError, match="speed-ups up to 100"):
        load_robot(write_yaml("z.yaml", robot("0.1", "1e-3")))


def test_a_measured_envelope_shrinks_the_joint_boxes_to_its_corner(dc_sample, measured):
    """Against the sheet's DC law, which the envelope's model starts from (its inductance is an effect it fits)."""
    sample = dc_sample
    robot, regions, _ = measured
    motor = regions.motors[0]
    assert motor.source.startswith("measured envelope")
    haa = robot.joints.index("FL_HAA")
    assert regions.joints[haa].inner_box.velocity == pytest.approx(motor.corner_speed / 9.0, rel=1e-6)
    assert motor.corner_speed < 0.9 * sample[1].motors[0].corner_speed  # the sagging pack turns the corner sooner
    # the envelope's model starts from linear Kt (9.66 N m at the driver's 70 A), the sheet's region from the 20 %
    # point's curve (8.416 N m there): the measured box may be that much stronger, never more
    linear_over_curve = motor.torque_limit / sample[1].motors[0].torque_limit
    assert linear_over_curve == pytest.approx(9.66 / 8.415792)
    # the envelope was measured at the nominal bus, where its box holds (the sheet's boxes hold at the battery's lowest
    # voltage, 66 V); against the sheet's box at the same 81 V
    nominal = robot_regions(replace(sample[0], motor_specs={
        k: replace(s, bus_voltage_range=None) for k, s in sample[0].motor_specs.items()
    }))  # fmt: skip
    assert all(j.inner_box_bus_voltage == (81.0,) * len(j.motors) for j in regions.joints)
    for mine, sheet in zip(regions.joints, nominal.joints, strict=True):
        assert mine.inner_box.velocity < sheet.inner_box.velocity
        assert mine.inner_box.effort <= sheet.inner_box.effort * linear_over_curve * (1 + 1e-9)
