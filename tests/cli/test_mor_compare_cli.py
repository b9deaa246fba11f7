import json

import pytest

from tests.cli.test_mor_cli import PNG_MAGIC, assert_one_line_error
from tests.conftest import MOTOR, SAMPLES, run_cli

LOG = SAMPLES / "envelope" / "ilm85_sag_log.csv"
COLUMNS = "velocity=speed,current=iq,temperature=winding_temp,bus_voltage=vbus"


def test_sample_sag_is_named_and_explained(tmp_path):
    plot = tmp_path / "compare.png"
    proc = run_cli("mor", "--spec", str(MOTOR), "--compare", str(LOG), "--columns", COLUMNS, "--auto",
                   "--plot", str(plot), "--json")  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    truth = json.loads((SAMPLES / "envelope" / "ilm85_sag_truth.json").read_text())
    assert data["schema"] == "hound-id/mor-compare/2" and data["added"] == ["bus_sag"]
    assert data["model"]["bus_sag"] == pytest.approx(truth["effects"]["bus_sag"], rel=0.1)
    assert data["envelope_rmse"]["with_added"] < 2 * data["noise_level"] and data["explained"]
    assert data["envelope_rmse"]["model"] > 100 * data["noise_level"]  # the spec misses the sag by up to ~5 N m
    assert data["coverage"]["upper"][1] > 0.9 * 81 * 60 * 2 * 3.14159 / 60  # the evidence reaches 90 % of no-load
    assert data["ladder"][1]["why"]["significant"] and "logged bus voltage" in data["ladder"][1]["why"]["reason"]
    assert data["ladder"][1]["walls_found_again"] and data["ladder"][1]["bins"] == data["bins_at_limit"]
    assert not any(s["significant"] for s in data["suggestions"])
    assert plot.read_bytes().startswith(PNG_MAGIC)


def test_out_spec_is_a_motor_spec_that_says_it_has_an_envelope(tmp_path):
    out = tmp_path / "ilm85_envelope.yaml"
    proc = run_cli("mor", "--spec", str(MOTOR), "--compare", str(LOG), "--columns", COLUMNS, "--add", "bus_sag",
                   "--out", str(out))  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    plot = tmp_path / "region.png"
    shown = run_cli("mor", "--spec", str(out), "--plot", str(plot))
    assert shown.returncode == 0
    assert "the region is the measured envelope (bus_sag = 0.1" in " ".join(shown.stdout.split())
    assert "spec sheet" in shown.stdout and plot.read_bytes().startswith(PNG_MAGIC)
    data = json.loads(run_cli("mor", "--spec", str(out), "--json").stdout)
    assert data["spec"]["envelope"]["effects"]["bus_sag"] == pytest.approx(0.15, rel=0.05)
    assert data["source"].startswith("measured envelope") and data["spec_sheet"]["source"] == "spec sheet"
    # the sagging pack turns the corner sooner: the table, vertices and boxes say so
    assert data["corner_speed"] < 0.9 * data["spec_sheet"]["corner_speed"]
    assert data["inner_box"]["speed"] == pytest.approx(data["corner_speed"], rel=0.01)
    plain = json.loads(run_cli("mor", "--spec", str(MOTOR), "--json").stdout)
    assert plain["source"] == "spec sheet" and plain["spec_sheet"] is None


def test_a_wrong_add_names_the_right_effect_and_then_says_it_is_not_needed():
    proc = run_cli("mor", "--spec", str(MOTOR), "--compare", str(LOG), "--columns", COLUMNS, "--add", "inductance")
    assert proc.returncode == 0, proc.stderr
    # inductance also shortens the edge at speed; refitted together with it, the sag takes over
    text = " ".join(proc.stdout.split())
    assert "+ inductance" in text and "suggested: --add bus_sag" in text and "inductance refitted" in text
    both = run_cli("mor", "--spec", str(MOTOR), "--compare", str(LOG), "--columns", COLUMNS, "--add", "inductance",
                   "--add", "bus_sag", "--json")  # fmt: skip
    data = json.loads(both.stdout)
    assert [u["effect"] for u in data["unneeded"]] == ["inductance"]
    assert data["model"]["bus_sag"] == pytest.approx(0.15, rel=0.02) and data["explained"]
    table = run_cli("mor", "--spec", str(MOTOR), "--compare", str(LOG), "--columns", COLUMNS, "--add", "inductance",
                    "--add", "bus_sag")  # fmt: skip
    text = " ".join(table.stdout.split())  # rich wraps long lines
    assert "not needed: inductance" in text and "leave out --add inductance" in text


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["--compare", str(LOG)], ["mor --compare: give --spec"]),
        (["--spec", str(MOTOR), "--columns", COLUMNS], ["go with --compare LOG"]),
        (["--spec", str(MOTOR), "--compare", str(LOG)], ["column 'velocity' missing", "map with --columns"]),
        (["--spec", str(MOTOR), "--compare", str(LOG), "--columns", COLUMNS, "--add", "sag"],
         ["--add: unknown effect"]),
        (["--spec", str(MOTOR), "--compare", str(LOG), "--columns", COLUMNS, "--joint", "FL_HAA"],
         ["--robot and --joint go together"]),
    ],
)  # fmt: skip
def test_compare_bad_input_is_one_line(args, fragments):
    assert_one_line_error(run_cli("mor", *args), *fragments)


def test_out_is_refused_when_the_model_does_not_explain_the_log(tmp_path):
    """A supply stronger than the spec says: no effect adds voltage, so the log stays unexplained and no measured
    envelope may be written from it (it would bound the saturation and the export)."""
    import dataclasses

    import numpy as np

    from hound_id.dyno.simulate.envelope import simulate_log
    from hound_id.mor.envelope import EnvelopeInputs
    from hound_id.mor.spec_sheet import load_motor_spec

    spec = load_motor_spec(MOTOR)
    strong = dataclasses.replace(spec, bus_voltage=spec.bus_voltage * 1.08)
    d = simulate_log(EnvelopeInputs(strong), {}, n=8000, noise=0.02, seed=5, speed_fraction=0.99)
    log = tmp_path / "strong.csv"
    np.savetxt(log, np.column_stack([d["velocity"], d["torque"]]), delimiter=",", header="velocity,torque",
               comments="")  # fmt: skip
    out = tmp_path / "env.yaml"
    proc = run_cli("mor", "--spec", str(MOTOR), "--compare", str(log), "--auto", "--out", str(out))
    assert_one_line_error(proc, "--out", "does not explain", "run without --out")
    assert not out.exists()
