"""The optimised foot in exports: foot.json /2 gives the collision spheres, /1 still reads (one sphere),
and the robot URDF with the feet put on loads in Pinocchio and compiles in MuJoCo."""

import json
import xml.etree.ElementTree as ET

import pytest

from hound_id.errors import SpecError
from hound_id.export.bundle import foot_from_json
from hound_id.export.target import put_feet
from hound_id.foot.urdf import parse_urdf
from tests.conftest import SAMPLES, run_cli

ROBOT_URDF = SAMPLES / "robots" / "hound_like.urdf"


@pytest.fixture(scope="module")
def foot_json(tmp_path_factory):
    out = tmp_path_factory.mktemp("foot")
    proc = run_cli("foot", "--optimise", "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    return out / "foot.json"


def feet_on_robot(foot):
    root = parse_urdf(ROBOT_URDF)
    put_feet(root, foot, ROBOT_URDF)
    return ET.tostring(root, encoding="unicode")


def test_v2_feet_get_the_spheres_in_both_simulators(foot_json):
    import mujoco
    import pinocchio as pin

    data = json.loads(foot_json.read_text())
    foot = foot_from_json(foot_json)
    spheres = data["collision"]["spheres"]
    assert foot["collision_spheres"] == spheres and len(spheres) >= 3
    text = feet_on_robot(foot)
    model = pin.buildModelFromXML(text)
    geom = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.COLLISION)
    on_feet = [g for g in geom.geometryObjects if g.name.startswith("FL_foot_")]
    assert len(on_feet) == len(spheres)
    mj = mujoco.MjModel.from_xml_string(text)
    foot_body = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, "FL_foot")  # the URDF importer keeps it a body
    radii = sorted(mj.geom_size[g, 0] for g in range(mj.ngeom)
                   if mj.geom_bodyid[g] == foot_body and mj.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE)  # fmt: skip
    assert radii == pytest.approx([s[3] for s in spheres])


def test_v1_foot_json_still_reads_with_its_one_sphere(foot_json, tmp_path):
    data = json.loads(foot_json.read_text())
    v1 = {k: v for k, v in data.items() if k not in ("collision", "ratios", "strength", "binding")}
    v1["schema"] = "hound-id/foot/1"
    path = tmp_path / "foot_v1.json"
    path.write_text(json.dumps(v1))
    foot = foot_from_json(path)
    assert "collision_spheres" not in foot
    text = feet_on_robot(foot)
    link = next(link for link in ET.fromstring(text).iter("link") if link.get("name") == "FL_foot")
    (sphere,) = link.iter("sphere")
    assert float(sphere.get("radius")) == pytest.approx(data["geometry"]["radius"])
    path.write_text(json.dumps(v1 | {"schema": "hound-id/foot/9"}))
    with pytest.raises(SpecError, match="expected the hound-id/foot/2"):
        foot_from_json(path)
