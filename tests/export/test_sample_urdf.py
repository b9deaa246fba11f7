"""The sample quadruped data/samples/robots/hound_like.urdf and its generator make_hound_urdf.py."""

import re

import numpy as np
import pinocchio as pin
import pytest
import yaml

from hound_id.foot.urdf import read_foot
from tests.conftest import SAMPLES

ROBOTS = SAMPLES / "robots"
URDF = ROBOTS / "hound_like.urdf"
JOINTS = yaml.safe_load((ROBOTS / "hound_like.yaml").read_text())["joints"]
TOTAL_MASS = 45.0  # KAIST Hound (the paper)
CALF, FOOT = 0.25, 0.458  # hound_leg.urdf
LEG_MASS = 1.0 + 1.20 + CALF + FOOT  # hip (assumed) + thigh + calf + foot
STANCE = np.array([0.0, 0.7, -1.4] * 4)  # HAA, HFE, KFE per leg: knees bent, inside the limits


@pytest.fixture(scope="module")
def mujoco():
    return pytest.importorskip("mujoco")


def test_pinocchio_loads_the_joints_of_the_robot_file():
    model = pin.buildModelFromUrdf(str(URDF))  # fixed base, as the URDF has no floating joint
    names = list(model.names)[1:]
    # Pinocchio numbers joints depth first, leg by leg, in the file's (and the YAML's) order
    assert names == JOINTS
    assert model.nq == model.nv == 12
    for joint_id, name in enumerate(names, start=1):
        expected = "JointModelRX" if name.endswith("_HAA") else "JointModelRY"  # revolute about x or y
        assert model.joints[joint_id].shortname() == expected, name
    lower, upper = model.lowerPositionLimit, model.upperPositionLimit
    assert lower[2::3] == pytest.approx([-2.8] * 4) and upper[2::3] == pytest.approx([-0.3] * 4)
    assert lower[0::3] == pytest.approx([-0.8] * 4) and upper[1::3] == pytest.approx([3.14] * 4)


def test_pinocchio_masses():
    model = pin.buildModelFromUrdf(str(URDF))
    data = model.createData()
    # With a fixed base the trunk's inertia sits on the universe, which computeTotalMass leaves out
    assert pin.computeTotalMass(model) == pytest.approx(4 * LEG_MASS)
    assert pin.computeTotalMass(model) + model.inertias[0].mass == pytest.approx(TOTAL_MASS)
    floating = pin.buildModelFromUrdf(str(URDF), pin.JointModelFreeFlyer())
    assert pin.computeTotalMass(floating) == pytest.approx(TOTAL_MASS)
    pin.computeSubtreeMasses(model, data)
    for leg in ("FL", "FR", "RL", "RR"):
        assert data.mass[model.getJointId(f"{leg}_KFE")] == pytest.approx(CALF + FOOT)
        assert data.mass[model.getJointId(f"{leg}_HAA")] == pytest.approx(LEG_MASS)


def test_feet_have_the_layout_the_foot_patcher_expects():
    for leg in ("FL", "FR", "RL", "RR"):
        mount = read_foot(URDF, f"{leg}_foot")
        assert (mount.calf_link, mount.knee_joint, mount.hip_joint) == (f"{leg}_calf", f"{leg}_KFE", f"{leg}_HFE")
        assert mount.mount_length == pytest.approx(0.28)
        assert mount.foot.mass == pytest.approx(FOOT)
        assert (mount.contact_shape, mount.contact_radius, mount.contact_width) == ("cylinder", 0.03, 0.06)


def test_no_collision_geometry_touches_at_the_nominal_and_a_standing_pose():
    model = pin.buildModelFromUrdf(str(URDF))
    geoms = pin.buildGeomFromUrdf(model, str(URDF), pin.GeometryType.COLLISION)
    geoms.addAllCollisionPairs()  # every pair on different joints, trunk against legs included
    data, geom_data = model.createData(), pin.GeometryData(geoms)
    for q in (np.zeros(12), STANCE):
        pin.computeDistances(model, data, geoms, geom_data, q)
        assert min(r.min_distance for r in geom_data.distanceResults) > 0.02


def test_mujoco_compiles_and_steps(mujoco):
    model = mujoco.MjModel.from_xml_path(str(URDF))
    hinges = [model.joint(i).name for i in range(model.njnt)]
    assert hinges == JOINTS
    assert all(model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE)
    assert model.nq == 12  # fixed base: no free joint
    assert model.body_mass.sum() == pytest.approx(TOTAL_MASS)
    assert model.body("base").mass[0] == pytest.approx(TOTAL_MASS - 4 * LEG_MASS)
    data = mujoco.MjData(model)
    for q in (np.zeros(12), STANCE):
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        assert data.ncon == 0
    data = mujoco.MjData(model)
    for _ in range(200):
        mujoco.mj_step(model, data)
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))


def test_mujoco_keeps_each_foot_a_body_with_its_cylinder(mujoco):
    model = mujoco.MjModel.from_xml_path(str(URDF))
    for leg in ("FL", "FR", "RL", "RR"):
        foot = model.body(f"{leg}_foot")
        assert model.body(foot.parentid[0]).name == f"{leg}_calf"
        assert foot.mass[0] == pytest.approx(FOOT)
        geoms = np.flatnonzero(model.geom_bodyid == foot.id)
        assert len(geoms) == 1 and model.geom_type[geoms[0]] == mujoco.mjtGeom.mjGEOM_CYLINDER
        assert model.geom_size[geoms[0]][:2] == pytest.approx([0.03, 0.03])  # radius, half width


def test_without_the_extension_mujoco_fuses_the_static_links(mujoco):
    """Why the URDF carries <compiler fusestatic="false"/>: MuJoCo's URDF default merges fixed links."""
    text = re.sub(r"\s*<mujoco>.*?</mujoco>", "", URDF.read_text(), flags=re.S)
    assert "<mujoco>" not in text
    model = mujoco.MjModel.from_xml_string(text)
    bodies = {model.body(i).name for i in range(model.nbody)}
    assert "base" not in bodies and "FL_foot" not in bodies and "FL_calf" in bodies
    assert model.body_mass.sum() == pytest.approx(4 * LEG_MASS)  # the trunk went into the world body
    assert model.body("FL_calf").mass[0] == pytest.approx(CALF + FOOT)
    assert np.count_nonzero(model.geom_bodyid == model.body("FL_calf").id) == 2  # calf and foot cylinders
