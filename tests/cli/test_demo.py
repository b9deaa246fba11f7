import json

from tests.cli.test_mor_cli import PNG_MAGIC
from tests.conftest import run_cli


def test_demo_runs_every_part_on_the_samples(tmp_path):
    proc = run_cli("demo", "--out", "out", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["schema"] == "hound-id/demo/1"
    names = [s["name"] for s in data["steps"]]
    assert names == [
        "motor regions",
        "robot regions and saturation",
        "saturate a command log",
        "fit a dyno log",
        "compare a fleet",
        "compare a log with the region",
        "optimise the foot",
        "export to trainers",
    ]
    for step in data["steps"]:
        assert len(set(step["files"])) == len(step["files"]), step["files"]  # each file listed once
        for name in step["files"]:
            path = tmp_path / "out" / name
            assert path.is_file(), name
            if name.endswith(".png"):
                assert path.read_bytes().startswith(PNG_MAGIC)
            elif name.endswith(".json"):
                assert json.loads(path.read_text())["schema"].startswith("hound-id/")
    step = {s["name"]: s["figures"] for s in data["steps"]}
    robot_step = step["robot regions and saturation"]
    assert robot_step["hound_like.inner_infeasible"] == 0.0
    assert robot_step["hound_like.outer_infeasible"] > 0.5
    motor = json.loads((tmp_path / "out" / "mor_hound_ilm85.json").read_text())
    assert motor["schema"] == "hound-id/mor/3" and "spec" in motor and motor["warnings"] == []
    robot = json.loads((tmp_path / "out" / "mor_robot_hound_like.json").read_text())
    assert all("spec" in m and "warnings" in m for m in robot["motors"])
    fit = json.loads((tmp_path / "out" / "fit_ilm85_dyno.json").read_text())
    assert len(fit["ladder"]) == 6 and fit["at_noise_floor"]
    assert run_cli("mor", "--spec", str(tmp_path / "out" / "hound_ilm85_fitted.yaml")).returncode == 0
    foot = json.loads((tmp_path / "out" / "foot" / "foot.json").read_text())
    assert foot["schema"] == "hound-id/foot/2" and all(c["satisfied"] for c in foot["constraints"].values())
    assert step["optimise the foot"]["mass_ratio"] == foot["mass_ratio"] < 1
    fleet = json.loads((tmp_path / "out" / "fleet.json").read_text())  # every planted fault, no healthy actuator
    assert fleet["schema"] == "hound-id/fleet/2" and fleet["fitted"] == 12 and fleet["engine"]["workers"] >= 1
    assert step["compare a fleet"]["planted_found"] == 4 and step["compare a fleet"]["healthy_flagged"] == 0
    compare = json.loads((tmp_path / "out" / "compare_ilm85_sag.json").read_text())
    assert compare["schema"] == "hound-id/mor-compare/2" and compare["added"] == ["bus_sag"]
    sag = step["compare a log with the region"]  # the sagging pack turns the corner sooner than the spec sheet says
    assert sag["corner_speed_measured"] < 0.9 * sag["corner_speed_spec_sheet"]
    export = json.loads((tmp_path / "out" / "export" / "export.json").read_text())
    assert export["schema"] == "hound-id/export/1" and export["fitted_motors"] == ["hound_ilm85"] and export["foot"]
    # dcmotor's voltage lines are straight; the fitted curve bends the region's: they differ by at most that gap
    check = export["mujoco_check"]
    gap = check["straight_line_gap"]
    assert 0.5 < gap < 5.0  # about 3.79 N m: the fit's quadratic and the winding's reactance bend the edges
    assert check["max_outside"] <= gap + 1e-5 and check["max_difference"] <= gap + 1e-5
    assert export["mujoco_check"]["clipped_fraction"] > 0.5
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["schema"] == "hound-id/demo/1"


def test_demo_table(tmp_path):
    proc = run_cli("demo", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "hound-id demo" in proc.stdout and (tmp_path / "hound-id-demo" / "summary.json").is_file()
