import math

import pytest

from hound_id.errors import SpecError
from hound_id.foot.leg import leg_properties, load_leg
from tests.conftest import SAMPLES

LEG = SAMPLES / "legs" / "hound_leg.urdf"

ONE_LINK = """<?xml version="1.0"?>
<robot name="one">
  <link name="base"/>
  <joint name="HFE" type="revolute"><parent link="base"/><child link="thigh"/>
    <axis xyz="0 1 0"/><limit effort="1" velocity="1" lower="-3" upper="3"/></joint>
  <link name="thigh"><inertial><origin xyz="0 0 -0.1"/><mass value="0.001"/>
    <inertia ixx="1e-9" ixy="0" ixz="0" iyy="1e-9" iyz="0" izz="1e-9"/></inertial></link>
  <joint name="KFE" type="revolute"><parent link="thigh"/><child link="calf"/><origin xyz="0 0 -0.2"/>
    <axis xyz="0 1 0"/><limit effort="1" velocity="1" lower="-3" upper="3"/></joint>
  <link name="calf"><inertial><origin xyz="0.03 0 -0.15"/><mass value="0.8"/>
    <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.003" iyz="0" izz="0.001"/></inertial></link>
</robot>
"""


def test_pinocchio_inertia_matches_a_hand_calculation(tmp_path):
    path = tmp_path / "one.urdf"
    path.write_text(ONE_LINK)
    props = leg_properties(load_leg(path), knee_angle=0.0)
    # parallel axis theorem about the knee's y axis: Iyy + m (x^2 + z^2)
    assert props.knee_pitch_inertia == pytest.approx(0.003 + 0.8 * (0.03**2 + 0.15**2), rel=1e-9)
    assert props.calf_foot_mass == pytest.approx(0.8)
    # about the hip: the calf's COM is 0.35 m below, 0.03 m ahead; plus the (tiny) thigh
    hip = 0.003 + 0.8 * (0.03**2 + 0.35**2) + 1e-9 + 0.001 * 0.1**2
    assert props.hip_pitch_inertia == pytest.approx(hip, rel=1e-9)


def test_bent_knee_moves_the_calf_closer_to_the_hip(tmp_path):
    path = tmp_path / "one.urdf"
    path.write_text(ONE_LINK)
    model = load_leg(path)
    straight, bent = leg_properties(model, knee_angle=0.0), leg_properties(model, knee_angle=-math.pi / 2)
    assert bent.knee_pitch_inertia == pytest.approx(straight.knee_pitch_inertia)
    assert bent.hip_pitch_inertia < straight.hip_pitch_inertia


def test_sample_leg():
    props = leg_properties(load_leg(LEG), rotor_inertia=1.7e-4, knee_ratio=7.5)
    assert props.calf_foot_mass == pytest.approx(0.25 + 0.458)
    # calf about the knee: 0.00163 + 0.25 * 0.14^2; foot: 0.000206 + 0.458 * 0.28^2
    expected = 0.00163 + 0.25 * 0.14**2 + 0.000206 + 0.458 * 0.28**2
    assert props.knee_pitch_inertia == pytest.approx(expected, rel=1e-9)
    assert props.reflected_knee_inertia == pytest.approx(1.7e-4 * 56.25)
    assert props.hip_pitch_inertia > props.knee_pitch_inertia


def test_bad_inputs(tmp_path):
    with pytest.raises(SpecError, match="file not found"):
        load_leg(tmp_path / "none.urdf")
    (tmp_path / "bad.urdf").write_text("<robot name='x'><link></robot>")
    with pytest.raises(SpecError, match="not valid XML"):
        load_leg(tmp_path / "bad.urdf")
    with pytest.raises(SpecError, match="no joint named 'knee'"):
        leg_properties(load_leg(LEG), knee_joint="knee")
