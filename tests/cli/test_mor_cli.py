import json
import math

import pytest

from tests.conftest import MOTOR, ROBOT, SMALL_MOTOR, run_cli

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def assert_one_line_error(proc, *fragments):
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, proc.stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    assert proc.stdout == ""


def test_mor_spec_json(tmp_path):
    proc = run_cli("mor", "--spec", str(MOTOR), "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout, parse_constant=lambda c: pytest.fail(f"not JSON: {c}"))  # no Infinity or NaN
    assert data["schema"] == "hound-id/mor/3"
    assert data["bindings"][-1]["speeds"][1] is None  # the open end past overspeed
    assert data["motor"] == "hound_ilm85"
    assert len(data["halfspaces"]["A"]) == len(data["halfspaces"]["b"]) > 4  # voltage, torque and curve rows
    # the curve-limited torque limit and what linear Kt over-promises (the 20 % point's quadratic at 70 A)
    tl = 0.138 * 70 - 0.16 * 0.138**2 / 12 * 70**2
    assert data["torque_limit"] == pytest.approx(tl) and data["linear_torque_limit"] == pytest.approx(9.66)
    # from rest linear Kt over-promises 9.66 - tl; near the drive's loss of control (532.5 rad/s, where the
    # reactance has pulled the edge in) the most, 2.94 N m
    assert data["linear_kt"]["largest_excess"] >= 9.66 - tl
    assert data["linear_kt"]["largest_excess"] == pytest.approx(2.94, abs=0.01)
    assert [b["limit"] for b in data["bindings"]] == ["current", "voltage", "voltage", "back-EMF"]
    # at speed: the sheet's 70 uH line to line (35 uH per phase) against the DC law, and the battery's 66-84 V
    speed = data["at_speed"]
    assert speed["drive"]["corner_speed"] == pytest.approx(450.74, abs=0.01)
    assert speed["dc_law"]["corner_speed"] == pytest.approx(465.13, abs=0.01)
    assert speed["largest_motoring_cost"]["torque"] == pytest.approx(1.59, abs=0.01)
    assert [b["bus_voltage"] for b in speed["battery"]] == [66.0, 84.0]
    assert data["drive"]["inductance_phase"] == pytest.approx(35e-6) and data["drive"]["field_weakening"] is False
    assert data["corner_speed"] < data["no_load_speed"] < data["overspeed"]
    assert data["stall_torque"] == pytest.approx(0.138 * 81 / (math.sqrt(3) / 2 * 0.115))


def test_mor_spec_table_and_plot(tmp_path):
    plot = tmp_path / "region.png"
    proc = run_cli("mor", "--spec", str(SMALL_MOTOR), "--plot", str(plot))
    assert proc.returncode == 0, proc.stderr
    # the curve needs 36.14 A for the 2.4 N m peak (linear Kt: 28.9 A): corner Kv (V - R I) = 134.0 rad/s, 1280 rpm
    assert "corner speed" in proc.stdout and "1280 rpm" in proc.stdout and "1504 rpm" not in proc.stdout
    assert "linear-Kt region" in proc.stdout and "157.5 rad/s" in proc.stdout
    assert plot.read_bytes().startswith(PNG_MAGIC)
    assert [p.name for p in tmp_path.iterdir()] == ["region.png"]  # no temporary left behind


def test_user_spec_in_other_units_and_line_to_line(write_yaml):
    spec = write_yaml(
        "mine.yaml",
        """
name: my_motor
kt: 52 mNm/A
kv: 190 rpm/V
resistance_line_to_line: 0.25 ohm
bus_voltage: 24000 mV
peak_torque: 1.6 N*m
max_current: 30 A
max_speed: 4500 rpm
rotor_inertia: 0.3 kg*cm^2
""",
    )
    proc = run_cli("mor", "--spec", str(spec), "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["spec"]["kv"] == pytest.approx(190 * 2 * math.pi / 60)
    assert data["spec"]["resistance"] == pytest.approx(0.25 * math.sqrt(3) / 2)
    assert data["max_speed"] == pytest.approx(4500 * 2 * math.pi / 60)
    assert data["warnings"] == []


def test_kt_kv_mixup_is_a_warning_not_an_error(write_yaml):
    spec = write_yaml("mix.yaml", "name: m\nkt: 0.087\nkv: 95\nresistance: 0.12\nbus_voltage: 48\npeak_torque: 3\n")
    proc = run_cli("mor", "--spec", str(spec), "--json")
    assert proc.returncode == 0
    assert "warning:" in proc.stderr and "disagree" in proc.stderr
    assert json.loads(proc.stdout)["warnings"]


@pytest.mark.parametrize(
    ("text", "fragments"),
    [
        ("name: m\nkv: 10\nresistance: 1\nbus_voltage: 24\npeak_torque: 1\n", ["field 'kt': missing"]),
        ("name: m\nkt: 0.1\nkv: 10 V\nresistance: 1\nbus_voltage: 24\npeak_torque: 1\n", ["field 'kv'", "10 V"]),
        (
            "name: m\nkt: 0.1\nkv: 10\nresistnace: 1\nbus_voltage: 24\npeak_torque: 1\n",
            ["'resistnace'", "did you mean 'resistance'"],
        ),
        ("name: m\nkt: 0.1\nkv: 10\nresistance: -1\nbus_voltage: 24\npeak_torque: 1\n", ["positive"]),
        ("name: m\nkt: [0.1\n", ["not valid YAML"]),
    ],
)
def test_bad_spec_files(write_yaml, text, fragments):
    path = write_yaml("bad.yaml", text)
    assert_one_line_error(run_cli("mor", "--spec", str(path), "--json"), "bad.yaml", *fragments)


def test_bad_invocations(tmp_path):
    assert_one_line_error(run_cli("mor", "--spec", str(tmp_path / "none.yaml")), "file not found")
    assert_one_line_error(run_cli("mor", "--spec", str(MOTOR), "--robot", str(ROBOT)), "exactly one of")
    assert_one_line_error(
        run_cli("mor", "--spec", str(MOTOR), "--plot", str(tmp_path / "no" / "x.png")), "does not exist"
    )
    assert_one_line_error(run_cli("mor", "--spec", str(MOTOR), "--plot", str(tmp_path / "x.pdf")), "end in .png")
    assert list(tmp_path.iterdir()) == []


def test_mor_robot_json_and_plot(tmp_path):
    plot = tmp_path / "robot.png"
    proc = run_cli("mor", "--robot", str(ROBOT), "--json", "--plot", str(plot))
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["schema"] == "hound-id/mor-robot/1"
    assert len(data["joints"]) == 12
    kfe = next(j for j in data["joints"] if j["joint"] == "FL_KFE")
    assert kfe["coupled"] and kfe["inner_box"]["velocity"] < kfe["outer_box"]["velocity"]
    assert plot.read_bytes().startswith(PNG_MAGIC)


def test_mor_robot_table():
    proc = run_cli("mor", "--robot", str(ROBOT))
    assert proc.returncode == 0, proc.stderr
    assert "FL_KFE" in proc.stdout and "inner box" in proc.stdout


def test_bad_robot_file(write_yaml):
    path = write_yaml("r.yaml", f"name: r\nmotor_specs: {{m: {MOTOR}}}\njoints: [a]\ntransmissions: []\n")
    assert_one_line_error(run_cli("mor", "--robot", str(path)), "r.yaml", "transmissions")


def test_help_and_version():
    proc = run_cli("--help")
    assert proc.returncode == 0 and "mor" in proc.stdout and "demo" in proc.stdout
    assert run_cli("--version").stdout.startswith("hound-id ")


def test_outputs_are_checked_before_work_and_get_normal_permissions(tmp_path):
    import os

    from tests.conftest import SAMPLES

    log = SAMPLES / "commands" / "hound_like_running.csv"
    proc = run_cli(
        "saturate",
        str(log),
        "--robot",
        str(ROBOT),
        "--out",
        str(tmp_path / "y.csv"),
        "--plot",
        str(tmp_path / "nodir" / "y.png"),
    )
    assert_one_line_error(proc, "does not exist")
    assert not (tmp_path / "y.csv").exists()
    old = os.umask(0o022)
    try:
        assert run_cli("mor", "--spec", str(MOTOR), "--plot", str(tmp_path / "m.png")).returncode == 0
    finally:
        os.umask(old)
    assert (tmp_path / "m.png").stat().st_mode & 0o777 == 0o644


def test_demo_refuses_bad_output_folders(tmp_path):
    (tmp_path / "afile").write_text("x")
    assert_one_line_error(run_cli("demo", "--out", str(tmp_path / "afile")), "is a file; give a folder")
    assert_one_line_error(run_cli("demo", "--out", str(tmp_path / "no" / "deeper")), "does not exist")
    assert not (tmp_path / "no").exists()
