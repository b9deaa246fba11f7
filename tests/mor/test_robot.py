import numpy as np
import pytest

from hound_id.errors import HoundIdError, RobotError, SpecError
from hound_id.mor.robot import load_robot
from tests.conftest import MOTOR, ROBOT

GOOD = f"""
name: r
motor_specs: {{m: {MOTOR}}}
joints: [a, h, k]
transmissions:
  - {{type: ratio, joints: [a], motors: [ma], motor_spec: m, ratios: [9.0]}}
  - {{type: hollow_shaft, joints: [h, k], motors: [mh, mk], motor_spec: m, hip_ratio: 7, knee_ratio: 11}}
"""


def test_sample_robot():
    robot = load_robot(ROBOT)
    assert len(robot.joints) == 12
    assert sum(tx.coupled for tx in robot.transmissions) == 4
    A = robot.velocity_map()
    i, j = robot.joints.index("RR_HFE"), robot.joints.index("RR_KFE")
    assert A[j, i] == pytest.approx(-1 / (7.5 * 7.5))
    assert A[i, j] == 0.0
    assert robot.motors[j] == "RR_KFE_motor"


def test_joint_order_is_the_listed_order(write_yaml):
    robot = load_robot(write_yaml("r.yaml", GOOD.replace("joints: [a, h, k]", "joints: [k, a, h]")))
    assert robot.joints == ("k", "a", "h")
    A = robot.velocity_map()
    assert A[0, 2] == pytest.approx(-1 / 77) and A[0, 0] == pytest.approx(1 / 11)


@pytest.mark.parametrize(
    ("old", "new", "match"),
    [
        ("joints: [a, h, k]", "joints: [a, h, k, z]", "joints without a transmission: z"),
        ("joints: [a, h, k]", "joints: [a, h, h, k]", "repeated: h"),
        ("joints: [a, h, k]", "joints: [a, h]", "joint 'k' is not in 'joints'"),
        ("motors: [mh, mk]", "motors: [ma, mk]", "used twice"),
        ("motor_spec: m, hip", "motor_spec: q, hip", "uses spec 'q'"),
        ("type: ratio", "type: belt", "expected one of"),
        ("ratios: [9.0]", "ratios: [0.0]", "non-zero"),
        ("ratios: [9.0]", "ratios: [9.0, 3.0]", "2 ratios for 1 joints"),
        ("hip_ratio: 7, ", "", "field 'hip_ratio': missing"),
        ("name: r", "nmae: r", "did you mean 'name'"),
        ("knee_ratio: 11", "knee_ratio: 11, gear: 3", "field 'gear': unknown"),
    ],
)
def test_bad_robots(write_yaml, old, new, match):
    assert old in GOOD
    with pytest.raises(RobotError, match=match):
        load_robot(write_yaml("r.yaml", GOOD.replace(old, new)))


def test_bad_spec_inside_robot_names_both_files(write_yaml, tmp_path):
    spec = write_yaml("bad_motor.yaml", "name: x\nkt: 0.1\nkv: 10 V\nresistance: 1\nbus_voltage: 24\npeak_torque: 1\n")
    text = GOOD.replace(str(MOTOR), spec.name)
    with pytest.raises(HoundIdError, match=r"r\.yaml: motor_specs\.m: .*bad_motor\.yaml: field 'kv'"):
        load_robot(write_yaml("r.yaml", text))
    with pytest.raises(SpecError, match="file not found"):
        load_robot(write_yaml("r2.yaml", GOOD.replace(str(MOTOR), "missing.yaml")))


def test_matrix_transmission(write_yaml):
    text = GOOD.replace(
        "{type: hollow_shaft, joints: [h, k], motors: [mh, mk], motor_spec: m, hip_ratio: 7, knee_ratio: 11}",
        "{type: matrix, joints: [h, k], motors: [mh, mk], motor_spec: m, matrix: [[0.1, 0.0], [0.05, 0.1]]}",
    )
    robot = load_robot(write_yaml("r.yaml", text))
    assert np.allclose(robot.transmission_of("k").A, [[0.1, 0.0], [0.05, 0.1]])
    with pytest.raises(RobotError, match="singular"):
        load_robot(write_yaml("s.yaml", text.replace("[[0.1, 0.0], [0.05, 0.1]]", "[[0.1, 0.2], [0.05, 0.1]]")))
