import json

import pytest

from tests.cli.test_mor_cli import PNG_MAGIC, assert_one_line_error
from tests.conftest import ROBOT, SAMPLES, run_cli

LEG = SAMPLES / "legs" / "hound_leg.urdf"
GAIT = SAMPLES / "gait" / "hound_running.csv"


def test_foot_optimise_end_to_end(tmp_path):
    out, plot = tmp_path / "foot", tmp_path / "foot" / "foot.png"
    proc = run_cli("foot", "--optimise", "--leg", str(LEG), "--gait", str(GAIT), "--robot", str(ROBOT),
                   "--out", str(out), "--plot", str(plot), "--json")  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["schema"] == "hound-id/foot/2"
    assert all(c["satisfied"] for c in data["constraints"].values())
    assert data["reflected_knee_inertia"] == pytest.approx(1.7e-4 * 7.5**2)
    assert plot.read_bytes().startswith(PNG_MAGIC)
    assert sorted(p.name for p in out.iterdir()) == ["foot.json", "foot.png", "foot.stl", "hound_leg_light_foot.urdf"]
    assert json.loads((out / "foot.json").read_text())["mass_ratio"] == data["mass_ratio"]


def test_foot_table_prints_the_paper_next_to_ours():
    proc = run_cli("foot", "--optimise", "--angles", "-45,15", "--material", "titanium_ti6al4v")
    assert proc.returncode == 0, proc.stderr
    assert "paper (KAIST Hound, its own leg; axis not stated)" in proc.stdout
    assert "0.380" in proc.stdout and "0.374" in proc.stdout
    assert "about the knee axis" in proc.stdout and "about its own centre of mass" in proc.stdout
    assert "hertz_pressure" in proc.stdout and "NO" not in proc.stdout
    assert "Stress at the peak ground force 1500 N" in proc.stdout and "binding:" in proc.stdout
    assert "collision:" in proc.stdout and "spheres" in proc.stdout
    assert "titanium_ti6al4v" in proc.stdout


def test_foot_without_optimise_describes_the_leg():
    proc = run_cli("foot", "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["schema"] == "hound-id/foot-leg/1"
    assert data["angles"]["strides"] == 32
    assert data["leg_properties"]["calf_foot_mass"] == pytest.approx(0.708)


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["--angles", "30,-25"], ["attack 30 deg must come before detach -25 deg", "--angles -30,25"]),
        (["--angles", "-85,100"], ["covers less than 180 deg"]),
        (["--angles", "-30"], ["--angles", "expected two numbers"]),
        (["--radius", "10 mm", "--grf", "3 kN"], ["--radius 10.0 mm is too small for the load", "at least"]),
        (["--boss-radius", "10"], ["--boss-radius", "write the unit"]),
        (["--grf", "1500 m"], ["--grf", "a force"]),
        (["--material", "cheese"], ["unknown material 'cheese'"]),
        (["--leg", "missing.urdf", "--angles", "-30,25"], ["missing.urdf", "not found"]),
        (["--angles", "-30,25", "--gait", str(GAIT)], ["not both"]),
        (["--gait", str(LEG)], ["hound_leg.urdf"]),
        (["--plot", "foot.jpg"], ["end in .png"]),
        (["--robot", str(ROBOT), "--robot-knee", "KNEE"], ["no joint named 'KNEE'"]),
        (["--leg", str(LEG)], ["needs --angles ATTACK,DETACH or --gait LOG"]),
        (["--angles", "-30,25", "--legs", "RR"], ["--legs picks legs of a gait log"]),
        (["--knee-angle", "nan"], ["--knee-angle", "finite"]),
        (["--margin", "-5"], ["--margin: found -5"]),
        (["--mesh-resolution", "0.1"], ["expected 0.5 to 10 deg"]),
        (["--grf", "3 kN"], ["change by 6.1 mm, more than --length-tolerance 5.0 mm"]),
        (["--bolt", "M7"], ["--bolt: found 'M7'", "M4"]),
        (["--boss-radius", "3 mm"], ["--boss-radius: 3.00 mm is too thin for the M4 bolt", "4.00 mm"]),
        (["--friction", "-1"], ["--friction: found -1"]),
        (["--collision-tolerance", "0 mm"], ["--collision-tolerance"]),
    ],
)
def test_foot_bad_input_is_one_line(tmp_path, args, fragments):
    proc = run_cli("foot", "--optimise", *args, cwd=tmp_path)
    assert_one_line_error(proc, *fragments)
    assert list(tmp_path.iterdir()) == []  # nothing half-written


def test_light_load_succeeds_quietly():
    proc = run_cli("foot", "--optimise", "--material", "steel_17_4ph_h900", "--grf", "100 N", "--json")
    assert proc.returncode == 0 and proc.stderr == ""  # no solver chatter on stderr
    data = json.loads(proc.stdout)
    assert data["constraints"]["leg_length_stance"]["satisfied"]
    assert data["angles"]["source"].endswith("hound_running.csv")


def test_foot_out_must_be_a_folder(tmp_path):
    target = tmp_path / "file"
    target.write_text("x")
    assert_one_line_error(run_cli("foot", "--optimise", "--out", str(target)), "is a file")
    assert_one_line_error(run_cli("foot", "--out", str(tmp_path)), "need --optimise")


def test_old_boss_option_still_fixes_the_boss(tmp_path):
    """--boss-radius 10 mm --bolt none is the 0.x foot's solid boss; the boss is then given, not optimised."""
    proc = run_cli("foot", "--optimise", "--boss-radius", "10 mm", "--bolt", "none", "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["geometry"]["boss_radius"] == pytest.approx(0.010) and data["geometry"]["bore_radius"] == 0.0
    assert data["requirements"]["fastener"] is None and "boss_wall" not in data["constraints"]
    free = json.loads(run_cli("foot", "--optimise", "--json").stdout)
    assert free["foot"]["closed_form"]["mass"] < data["foot"]["closed_form"]["mass"]
