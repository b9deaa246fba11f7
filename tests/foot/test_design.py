"""The whole foot job on the sample leg: Pinocchio before and after, the STL, the patched URDF."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from hound_id.errors import SpecError
from hound_id.foot.angles import gait_angles
from hound_id.foot.design import PAPER, SCHEMA, design_foot, foot_json, leg_summary, write_foot
from hound_id.foot.material import GROUNDS, MATERIALS
from hound_id.foot.optimise import FootRequirements
from hound_id.foot.urdf import read_foot
from tests.conftest import SAMPLES

LEG = SAMPLES / "legs" / "hound_leg.urdf"
GAIT = SAMPLES / "gait" / "hound_running.csv"


def requirements(angles, **kw):
    base = dict(low=angles.low, high=angles.high, material=MATERIALS["aluminium_7075_t6"], ground=GROUNDS["concrete"],
                peak_force=1500.0)  # fmt: skip
    return FootRequirements(**(base | kw))


@pytest.fixture(scope="module")
def report():
    angles = gait_angles(GAIT)
    return design_foot(LEG, angles, requirements(angles), reflected_knee_inertia=0.0095625)


def test_sample_leg_redesign(report):
    # calf+foot before: 0.25 kg calf + 0.458 kg cylinder (URDF)
    assert report.original.calf_foot_mass == pytest.approx(0.708)
    assert 0.2 < report.mass_ratio < 0.6 and 0.1 < report.inertia_ratio < 0.6
    assert report.mass_ratio == pytest.approx((0.25 + report.design.properties.mass) / 0.708)
    assert report.design.feasible
    # Pinocchio on the patched URDF agrees with the closed form's prediction (URDF prints 9 digits)
    assert abs(report.pinocchio_error) < 1e-7
    assert report.mesh_check.watertight
    assert abs(report.mesh_check.mass_error) < 0.01 and report.mesh_check.inertia_error < 0.01


def test_outputs_load_in_their_consumers(report, tmp_path):
    import pinocchio as pin
    import trimesh

    files = write_foot(report, tmp_path / "new")
    stl = trimesh.load(files["stl"], force="mesh")
    assert stl.is_watertight
    assert stl.volume * MATERIALS["aluminium_7075_t6"].density == pytest.approx(report.design.properties.mass, rel=0.01)
    model = pin.buildModelFromUrdf(files["urdf"])
    data = model.createData()
    pin.computeSubtreeMasses(model, data)
    assert data.mass[model.getJointId("KFE")] == pytest.approx(report.new.calf_foot_mass)
    visual = pin.buildGeomFromUrdf(model, files["urdf"], pin.GeometryType.VISUAL, package_dirs=[str(tmp_path / "new")])
    assert visual.ngeoms == 1 and visual.geometryObjects[0].meshPath.endswith("foot.stl")
    collision = pin.buildGeomFromUrdf(model, files["urdf"], pin.GeometryType.COLLISION)
    spheres = report.collision.spheres
    assert collision.ngeoms == len(spheres) >= 3
    g = report.design.geometry
    for obj, (_, _, _, r) in zip(collision.geometryObjects, spheres, strict=True):
        assert obj.geometry.radius == pytest.approx(r, rel=1e-8)
        # each sphere touches the cap's outer sphere from inside: centre at R - r from the cap's centre
        centre = obj.placement.translation - np.array([0.0, 0.0, -0.28 + g.centre_z])
        assert np.linalg.norm(centre) == pytest.approx(g.radius - r, abs=1e-8)
    # straight below, the spheres keep the knee-to-ground length of the original foot, short by at most the
    # rise of the nearest sphere half a spacing away
    lowest = max(-o.placement.translation[2] + o.geometry.radius for o in collision.geometryObjects)
    half = (g.high - g.low) / (len(spheres) - 1) / 2
    assert 0.31 - (g.radius - spheres[0][3]) * (1 - math.cos(half)) - 1e-9 <= lowest <= 0.31 + 1e-8
    data = json.loads((tmp_path / "new" / "foot.json").read_text())
    assert data["schema"] == SCHEMA and data["files"]["stl"] == files["stl"]
    assert sorted(p.name for p in (tmp_path / "new").iterdir()) == [
        "foot.json",
        "foot.stl",
        "hound_leg_light_foot.urdf",
    ]


def test_json_has_the_issue_fields(report):
    data = foot_json(report)
    assert data["schema"] == "hound-id/foot/2"
    assert data["mass_ratio"] == pytest.approx(report.mass_ratio)
    assert data["inertia_ratio"] == pytest.approx(report.inertia_ratio)
    assert data["radius"] == report.design.geometry.radius
    lo, hi = data["coverage_deg"]
    assert lo <= math.degrees(report.angles.low) + 1e-6 and hi >= math.degrees(report.angles.high) - 1e-6
    assert all(set(c) >= {"value", "limit", "satisfied"} for c in data["constraints"].values())
    assert all(c["satisfied"] for c in data["constraints"].values())
    assert data["paper"] == PAPER and "not stated" in data["paper"]["axis"]
    r = data["ratios"]
    assert r["knee_axis_inertia"]["value"] == pytest.approx(report.inertia_ratio)
    assert r["com_pitch_inertia"]["value"] == pytest.approx(data["com_inertia_ratio"])
    assert "knee axis" in r["knee_axis_inertia"]["axis"] and "own centre of mass" in r["com_pitch_inertia"]["axis"]
    # every binding constraint is at its limit, and the stress checks carry their formula and margin
    assert data["binding"] and all(abs(data["constraints"][k]["margin"]) < 1e-5 * max(1.0, abs(
        data["constraints"][k]["limit"])) for k in data["binding"])  # fmt: skip
    for check in data["strength"]["checks"].values():
        assert check["stress"] <= check["allowed"] * (1 + 1e-7) and check["formula"]
    assert data["collision"]["count"] == len(report.collision.spheres)
    # the rotor adds the same inertia before and after, so the ratio with it is closer to 1
    assert report.inertia_ratio < data["inertia_ratio_with_rotor"] < 1
    json.dumps(data)  # plain JSON all the way down


def test_com_inertia_ratio_by_hand(report):
    """The calf + foot about its own centre of mass, by the parallel-axis theorem from the URDF's numbers."""
    calf_m, calf_z, calf_i = 0.25, 0.14, 0.00163  # the sample URDF's calf
    foot = report.mount.foot

    def about_com(m_f, com_f_z, com_f_x, i_f):
        m = calf_m + m_f
        cx, cz = m_f * com_f_x / m, (calf_m * calf_z + m_f * com_f_z) / m
        return calf_i + calf_m * (cx**2 + (calf_z - cz) ** 2) + i_f + m_f * ((com_f_x - cx) ** 2 + (com_f_z - cz) ** 2)

    old = about_com(foot.mass, 0.28, 0.0, foot.inertia[1, 1])
    p = report.design.properties
    new = about_com(p.mass, 0.28 - p.com[2], p.com[0], p.inertia[1, 1])
    assert report.original.com_pitch_inertia == pytest.approx(old, rel=1e-9)
    assert report.com_inertia_ratio == pytest.approx(new / old, rel=1e-7)
    # about its own centre of mass the light foot saves less than about the knee: the axis matters
    assert report.com_inertia_ratio > report.inertia_ratio + 0.1


def test_leg_summary(report):
    angles = gait_angles(GAIT)
    s = leg_summary(LEG, angles, requirements(angles), knee_angle=-1.2)
    assert s["schema"] == "hound-id/foot-leg/1"
    assert s["leg_properties"]["calf_foot_mass"] == pytest.approx(0.708)
    assert s["hertz_min_radius"] == pytest.approx(report.design.hertz_min_radius)


BAD_MOUNT = """<?xml version="1.0"?>
<robot name="r"><link name="base"/>
  <joint name="HFE" type="revolute"><parent link="base"/><child link="thigh"/><axis xyz="0 1 0"/>
    <limit effort="1" velocity="1" lower="-3" upper="3"/></joint>
  <link name="thigh"/>
  <joint name="KFE" type="revolute"><parent link="thigh"/><child link="calf"/><origin xyz="0 0 -0.2"/>
    <axis xyz="0 1 0"/><limit effort="1" velocity="1" lower="-3" upper="3"/></joint>
  <link name="calf"/>
  <joint name="foot_fixed" type="fixed"><parent link="calf"/><child link="foot"/><origin xyz="{xyz}"/></joint>
  <link name="foot">{body}</link>
</robot>
"""
BODY = """<inertial><mass value="0.1"/><inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/></inertial>
  <collision><geometry><sphere radius="0.02"/></geometry></collision>"""


@pytest.mark.parametrize(
    ("xyz", "body", "foot_link", "message"),
    [
        ("0 0 -0.2", BODY, "toe", "no link named 'toe'"),
        ("0.05 0 -0.2", BODY, "foot", "expected the foot on the calf's -z axis"),
        (
            "0 0 -0.2",
            "<inertial><mass value='0.1'/><inertia ixx='1' iyy='1' izz='1'/></inertial>",
            "foot",
            "no <collision> sphere",
        ),
        (
            "0 0 -0.2",
            '<collision><geometry><sphere radius="0.02"/></geometry></collision>',
            "foot",
            "has no <inertial>",
        ),
        ("0 0 -0.2 1", BODY, "foot", "expected 3 finite numbers"),
        ("0 0 -0.2", BODY.replace('value="0.1"', 'value="-0.1"'), "foot", "expected a positive finite mass"),
        (
            "0 0 -0.2",
            BODY.replace('<geometry><sphere radius="0.02"/>', '<geometry><cylinder radius="0.03" length="0.1"/>'),
            "foot",
            "the foot cylinder's axis is \\[0.0, 0.0, 1.0\\], expected the lateral axis y",
        ),
    ],
)
def test_urdf_layouts_hound_id_cannot_use_are_named(tmp_path, xyz, body, foot_link, message):
    path = tmp_path / "leg.urdf"
    path.write_text(BAD_MOUNT.format(xyz=xyz, body=body))
    with pytest.raises(SpecError, match=message):
        read_foot(path, foot_link)


def test_knee_about_another_axis_is_refused(tmp_path):
    path = tmp_path / "leg.urdf"
    path.write_text(
        BAD_MOUNT.format(xyz="0 0 -0.2", body=BODY).replace(
            '<origin xyz="0 0 -0.2"/>\n    <axis xyz="0 1 0"/>', '<origin xyz="0 0 -0.2"/>\n    <axis xyz="1 0 0"/>'
        )
    )
    with pytest.raises(SpecError, match="joint 'KFE' turns about \\[1.0, 0.0, 0.0\\], expected the pitch axis y"):
        read_foot(path)


def test_other_links_relative_meshes_still_load_from_the_output_folder(tmp_path):
    """The patched URDF lives elsewhere; a thigh mesh given relative to the leg must still be found."""
    import pinocchio as pin
    import trimesh

    leg_dir = tmp_path / "leg"
    (leg_dir / "meshes").mkdir(parents=True)
    trimesh.creation.box((0.04, 0.04, 0.27)).export(leg_dir / "meshes" / "thigh.stl")
    text = LEG.read_text().replace(
        '<link name="thigh">',
        '<link name="thigh">\n    <visual><geometry><mesh filename="meshes/thigh.stl"/></geometry></visual>',
    )
    (leg_dir / "leg.urdf").write_text(text)
    angles = gait_angles(GAIT)
    report = design_foot(leg_dir / "leg.urdf", angles, requirements(angles))
    files = write_foot(report, tmp_path / "out")
    model = pin.buildModelFromUrdf(files["urdf"])
    visual = pin.buildGeomFromUrdf(model, files["urdf"], pin.GeometryType.VISUAL, package_dirs=[str(tmp_path / "out")])
    assert sorted(Path(g.meshPath).name for g in visual.geometryObjects) == ["foot.stl", "thigh.stl"]
    assert 'filename="../leg/meshes/thigh.stl"' in Path(files["urdf"]).read_text()


def test_a_sphere_foot_is_read(tmp_path):
    path = tmp_path / "leg.urdf"
    path.write_text(BAD_MOUNT.format(xyz="0 0 -0.2", body=BODY))
    mount = read_foot(path)
    assert (mount.contact_shape, mount.contact_radius, mount.mount_length) == ("sphere", 0.02, 0.2)
    assert (mount.knee_joint, mount.hip_joint, mount.calf_link) == ("KFE", "HFE", "calf")
    assert np.allclose(mount.foot.inertia, 1e-5 * np.eye(3))
