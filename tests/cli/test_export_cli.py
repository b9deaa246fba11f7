import json

import pytest

from tests.cli.test_mor_cli import assert_one_line_error
from tests.conftest import ROBOT, SAMPLES, run_cli
from tests.export.conftest import fitted_motor


def test_export_everything_from_the_command_line(tmp_path):
    foot = run_cli("foot", "--optimise", "--out", str(tmp_path / "foot"))
    assert foot.returncode == 0, foot.stderr
    fit, foot_json = str(fitted_motor(tmp_path)), str(tmp_path / "foot" / "foot.json")
    proc = run_cli("export", "--robot", str(ROBOT), "--format", "all", "--out", str(tmp_path / "out"),
                   "--fit", fit, "--foot", foot_json, "--json")  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["schema"] == "hound-id/export/1"
    assert list(data["formats"]) == ["bundle", "isaaclab", "mjlab", "mujoco", "newton", "urdf", "urdf-open"]
    assert data["fitted_motors"] == ["hound_ilm85"] and data["foot"]
    names = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert names == ["hound_like.xml", "hound_like_armature.yaml", "hound_like_bundle.json", "hound_like_bundle.yaml",
                     "hound_like_isaaclab.yaml", "hound_like_limits.urdf", "hound_like_mjlab.py",
                     "hound_like_mjlab.xml", "hound_like_newton.py", "hound_like_newton.urdf",
                     "hound_like_open_limits.urdf"]  # fmt: skip
    bundle = json.loads((tmp_path / "out" / "hound_like_bundle.json").read_text())
    assert bundle["foot"]["mass"] < 0.05 and bundle["motors"][0]["friction"]["coulomb"] == 0.08
    # the optimised foot is on every leg, in the URDF (Pinocchio) and in the MJCF (mujoco)
    import mujoco
    import pinocchio as pin

    for urdf in ("hound_like_limits.urdf", "hound_like_newton.urdf"):
        model = pin.buildModelFromUrdf(str(tmp_path / "out" / urdf))
        data = model.createData()
        pin.computeSubtreeMasses(model, data)
        for leg in ("FL", "FR", "RL", "RR"):
            assert data.mass[model.getJointId(f"{leg}_KFE")] == pytest.approx(0.25 + bundle["foot"]["mass"], rel=1e-8)
    mj = mujoco.MjModel.from_xml_path(str(tmp_path / "out" / "hound_like.xml"))
    foot_id = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, "FL_foot")
    assert mj.body_mass[foot_id] == pytest.approx(bundle["foot"]["mass"], rel=1e-5)  # MJCF prints 6 digits
    table = run_cli("export", "--robot", str(ROBOT), "--format", "mujoco,bundle", "--out", str(tmp_path / "t"))
    assert table.returncode == 0 and "motor constant" in table.stdout


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["--format", "mjcf"], ["--format: found 'mjcf'", "bundle, isaaclab, mjlab, mujoco, newton, urdf, urdf-open"]),
        (["--fit", str(SAMPLES / "motors" / "hound_ilm85.yaml")], ["has no 'fit:' block"]),
        (["--foot", str(ROBOT)], ["--foot", "not JSON"]),
        (["--mujoco-actuator", "servo"], ["--mujoco-actuator: found 'servo'"]),
        (["--urdf", "missing.urdf"], ["--urdf missing.urdf: file not found"]),
    ],
)
def test_export_bad_input_is_one_line(tmp_path, args, fragments):
    proc = run_cli("export", "--robot", str(ROBOT), "--out", "out", *args, cwd=tmp_path)
    assert_one_line_error(proc, *fragments)
    assert not (tmp_path / "out").exists()


def test_the_format_help_names_every_registered_format():
    """`--format`'s help is written out (importing the registry would load numpy at every start of hound-id):
    a new format added to FORMATS must be named there too."""
    from hound_id.export.formats import FORMATS

    proc = run_cli("export", "--help")
    assert proc.returncode == 0
    help_text = " ".join(proc.stdout.split())
    assert all(name in help_text for name in FORMATS), (sorted(FORMATS), help_text)
