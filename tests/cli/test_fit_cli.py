import json

import numpy as np
import pandas as pd
import pytest
import yaml

from hound_id.demo import DYNO_COLUMNS
from hound_id.dyno.simulate.current import simulate
from tests.cli.test_mor_cli import PNG_MAGIC, assert_one_line_error
from tests.conftest import MOTOR, SAMPLES, run_cli

DYNO = SAMPLES / "dyno" / "ilm85_dyno.csv"
MAPPING = ",".join(f"{k}={v}" for k, v in DYNO_COLUMNS.items())  # the sample's own column names
TRUTH = json.loads((SAMPLES / "dyno" / "ilm85_dyno_truth.json").read_text())


@pytest.fixture(scope="module")
def canonical_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("logs") / "log.csv"
    simulate(("linear", "saturation", "coulomb"), seed=3).frame.to_csv(path, index=False)
    return path


def test_sample_auto_finds_every_hidden_effect(tmp_path):
    out, plot = tmp_path / "fitted.yaml", tmp_path / "fit.png"
    proc = run_cli(
        "fit-current",
        str(DYNO),
        "--columns",
        MAPPING,
        "--auto",
        "--json",
        "--plot",
        str(plot),
        "--spec",
        str(MOTOR),
        "--out",
        str(out),
    )
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["schema"] == "hound-id/fit/3"
    hidden = set(TRUTH["effects"]) - {"linear", "saturation"}
    assert set(data["model"]) == {"linear", "saturation"} | hidden
    assert [s["added"] for s in data["ladder"][1:]] and set(s["added"] for s in data["ladder"][1:]) == hidden
    rmses = [s["rmse_test"] for s in data["ladder"]]
    assert rmses == sorted(rmses, reverse=True)
    truth = TRUTH["truth"]
    for name in ("kt", "k_sat", "coulomb", "delay", "kt_temp_coeff", "offset"):
        est = data["parameters"][name]
        assert abs(est["value"] - truth[name]) < 5 * est["stderr"] + 1e-3 * abs(truth[name]), name
        assert est["unit"]
    assert data["parameters"]["cogging_order"]["value"] == truth["cogging_order"]
    assert data["rmse"]["test"] <= 1.3 * truth["noise_std"]
    assert data["noise_floor"] == pytest.approx(truth["noise_std"], rel=0.2)
    assert data["at_noise_floor"] and not any(s["significant"] for s in data["suggestions"])
    assert {"torque", "current"} <= set(data["peak_torque"])
    assert data["compensation_polynomial"]["powers"] == [1, 3, 5] and data["current_curve"]["form"] == "quadratic"
    assert data["compensation"]["method"].startswith("closed form") and data["compensation"]["max_error"] == 0.0
    kinds = {n["kind"] for n in data["cleaning"]}
    assert {"nan_rows", "glitch", "duplicate_rows", "unit"} <= kinds  # the duplicated row is a repeated sample
    assert plot.read_bytes().startswith(PNG_MAGIC)
    # the fitted motor is a spec that `hound-id mor` reads, with the fitted Kt and peak torque
    fitted = yaml.safe_load(out.read_text())
    assert fitted["kt"] == pytest.approx(data["parameters"]["kt"]["value"])
    mor = run_cli("mor", "--spec", str(out), "--json")
    assert mor.returncode == 0, mor.stderr
    region = json.loads(mor.stdout)
    assert region["spec"]["kt"] == pytest.approx(fitted["kt"])
    assert region["spec"]["peak_torque"] == pytest.approx(data["peak_torque"]["torque"])
    assert region["spec"]["bus_voltage"] == 81.0  # from the spec sheet


def test_default_model_table_names_the_missing_effect(canonical_log):
    proc = run_cli("fit-current", str(canonical_log))
    assert proc.returncode == 0, proc.stderr
    assert "coulomb" in proc.stdout and "velocity changes sign" in proc.stdout
    assert "add 'coulomb'" in proc.stdout.replace("\n", " ")
    # how the floor was found, printed under it
    assert any(
        line.startswith("noise floor ") and "N m" in line and ("scatter" in line or "sample-to-sample" in line)
        for line in proc.stdout.splitlines()
    ), proc.stdout


def test_add_and_model_options(canonical_log, tmp_path):
    proc = run_cli("fit-current", str(canonical_log), "--add", "coulomb", "--json", "--plot", str(tmp_path / "p.png"))
    data = json.loads(proc.stdout)
    assert data["model"] == ["linear", "saturation", "coulomb"] and data["at_noise_floor"]
    proc = run_cli("fit-current", str(canonical_log), "--model", "linear", "--json")
    assert json.loads(proc.stdout)["model"] == ["linear"]


def test_user_effect_file(canonical_log, tmp_path):
    effects = tmp_path / "my_effects.py"
    effects.write_text(
        "import numpy as np\n"
        "from hound_id.dyno.current.effects import Effect, Parameter, register\n"
        "register(Effect(name='slope_with_time', physics='a drift of the torque gain over the test',\n"
        "    parameters=(Parameter('k_time', 'N m/A/s'),), regressors=lambda s, h: s.current * s.time))\n"
    )
    proc = run_cli(
        "fit-current", str(canonical_log), "--effects-file", str(effects), "--add", "slope_with_time", "--json"
    )
    assert proc.returncode == 0, proc.stderr
    assert "k_time" in json.loads(proc.stdout)["parameters"]


def test_reversed_torque_sensor(canonical_log, tmp_path):
    frame = pd.read_csv(canonical_log)
    frame["torque"] = -frame["torque"]
    path = tmp_path / "reversed.csv"
    frame.to_csv(path, index=False)
    assert_one_line_error(run_cli("fit-current", str(path)), "reversed", "--flip-torque")
    proc = run_cli("fit-current", str(path), "--flip-torque", "--json")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["parameters"]["kt"]["value"] > 0


def test_units_option(canonical_log, tmp_path):
    frame = pd.read_csv(canonical_log)
    frame["velocity"] = frame["velocity"] * 60 / (2 * np.pi)
    path = tmp_path / "rpm.csv"
    frame.to_csv(path, index=False)
    proc = run_cli("fit-current", str(path), "--units", "velocity=rpm", "--add", "coulomb", "--json")
    data = json.loads(proc.stdout)
    assert data["at_noise_floor"]


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["--model", "linear+colomb"], ["unknown effect 'colomb'"]),
        (["--add", "linear"], ["already has it"]),
        (["--columns", "torque"], ["--columns"]),
        (["--plot", "x.pdf"], ["end in .png"]),
        (["--out", "x.json"], ["end in .yaml"]),
    ],
)
def test_bad_options(canonical_log, args, fragments):
    assert_one_line_error(run_cli("fit-current", str(canonical_log), *args), *fragments)


def test_missing_channel_is_one_line(tmp_path):
    frame = pd.DataFrame({"time": np.arange(100) * 1e-3, "current": np.linspace(-5, 5, 100)})
    frame["torque"] = 0.1 * frame["current"]
    frame.to_csv(tmp_path / "bare.csv", index=False)
    assert_one_line_error(
        run_cli("fit-current", str(tmp_path / "bare.csv"), "--add", "coulomb"),
        "velocity channel",
        "--columns velocity=",
    )


def test_effects_command():
    proc = run_cli("effects", "--json")
    data = json.loads(proc.stdout)
    assert data["schema"] == "hound-id/effects/1"
    assert {e["effect"] for e in data["effects"]} >= {"linear", "saturation", "coulomb", "cogging", "delay"}


def test_logs_that_identify_nothing_are_refused(tmp_path):
    n = 500
    frame = pd.DataFrame({"time": np.arange(n) * 1e-3, "current": np.full(n, 10.0)})
    frame["torque"] = 1.38 + np.random.default_rng(0).normal(0, 0.01, n)
    frame.to_csv(tmp_path / "constant.csv", index=False)
    assert_one_line_error(run_cli("fit-current", str(tmp_path / "constant.csv")), "cannot tell", "vary the current")


def test_a_user_effect_with_the_wrong_shape_is_one_line(canonical_log, tmp_path):
    effects = tmp_path / "bad_effect.py"
    effects.write_text(
        "from hound_id.dyno.current.effects import Effect, Parameter, register\n"
        "register(Effect(name='two_params_user', physics='x',\n"
        "    parameters=(Parameter('a_user', 'N m'), Parameter('b_user', 'N m')), regressors=lambda s, h: s.current))\n"
    )
    assert_one_line_error(
        run_cli("fit-current", str(canonical_log), "--effects-file", str(effects), "--add", "two_params_user"),
        "two_params_user",
        "one column per parameter",
    )


def test_writing_an_inadequate_fit_warns(canonical_log, tmp_path):
    proc = run_cli("fit-current", str(canonical_log), "--out", str(tmp_path / "f.yaml"))
    assert proc.returncode == 0
    assert "not at the noise floor" in proc.stderr and (tmp_path / "f.yaml").is_file()


def test_a_units_override_is_said(canonical_log, tmp_path):
    frame = pd.read_csv(canonical_log).rename(columns={"torque": "torque[mN*m]"})
    frame.to_csv(tmp_path / "hdr.csv", index=False)
    proc = run_cli("fit-current", str(tmp_path / "hdr.csv"), "--units", "torque=Nm")
    assert proc.returncode == 0
    assert "overriding the header unit 'mN*m'" in proc.stderr


def test_effects_table_keeps_units():
    proc = run_cli("effects")
    assert "delay [s]" in proc.stdout.replace("\n", " ") or "[s]" in proc.stdout


# --- real-rig checks from the command line --------------------------------------------------------------------


def _polled(tmp_path, name="rig.csv", **rig):
    from tests.dyno.acquire.polledrig import Rig, Truth, run, write

    rig.setdefault("truth", Truth(coulomb=0.25, k_sat=0.01))
    return write(run(Rig(**rig)), tmp_path / name)


def test_a_kt_only_a_wrong_unit_or_side_explains_is_refused_and_nothing_is_written(tmp_path):
    from tests.dyno.acquire.polledrig import COLUMNS

    log, out = _polled(tmp_path), tmp_path / "fitted.yaml"
    proc = run_cli("fit-current", str(log), "--columns", COLUMNS, "--auto", "--spec", str(MOTOR), "--out", str(out))
    # an output-side Kt of an AK80-9-like actuator against a direct-drive motor's sheet: 8x off, both named
    assert_one_line_error(proc, "fitted Kt = 1.1", "the sheet's 0.138 N m/A", "--units")
    assert not out.exists()


def test_spec_checks_name_both_numbers_and_an_extrapolated_peak_is_marked(tmp_path):
    from tests.dyno.acquire.polledrig import COLUMNS

    log, out = _polled(tmp_path), tmp_path / "fitted.yaml"
    sheet = tmp_path / "ak80.yaml"  # the actuator's own sheet, output side, Kt 1.35x off the fit
    sheet.write_text(
        "name: ak80\nkt: 0.85 N*m/A\nkv: 1.18 rad/s/V\nresistance: 0.2\nbus_voltage: 48\npeak_torque: 18\n"
    )
    proc = run_cli("fit-current", str(log), "--columns", COLUMNS, "--auto", "--spec", str(sheet), "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    assert "fitted Kt = 1.1" in proc.stderr and "the sheet's 0.85 N m/A" in proc.stderr
    # k_sat = 0.01 N m/A^2 puts the 20 % point at 23 A, beyond the 10 A measured: marked, with the range
    written = yaml.safe_load(out.read_text())
    assert written["extrapolated"] == ["peak_torque"]
    assert "is extrapolated beyond the measured currents (|i| <= 10" in proc.stderr
    assert run_cli("mor", "--spec", str(out), "--json").returncode == 0  # the marked file still loads
    assert "extrapolated" in run_cli("mor", "--spec", str(out)).stderr


def test_window_option_and_its_errors(tmp_path):
    from tests.dyno.acquire.polledrig import COLUMNS

    log = _polled(tmp_path, motor_off_at=40.0)
    flagged = run_cli("fit-current", str(log), "--columns", COLUMNS, "--json")
    assert flagged.returncode == 0
    data = json.loads(flagged.stdout)
    # the headline leaves the motor-off end out and names the window that repeats it; the whole log is beside it
    assert data["whole_log"]["flags"] and not data["whole_log"]["at_noise_floor"]
    assert not any(f.startswith("blocks") for f in data["flags"])
    assert data["left_out"][0]["kind"] == "current frozen" and "--whole-log" in data["headline"]["sentence"]
    window = data["headline"]["option"].split("--window ")[1]
    assert window.startswith(":")  # from the log's start
    good = json.loads(
        run_cli("fit-current", str(log), "--columns", COLUMNS, "--json", "--auto", "--window", window).stdout
    )
    assert not any(f.startswith("blocks") for f in good["flags"]) and "headline" not in good
    assert good["parameters"]["kt"]["value"] == pytest.approx(1.15, rel=0.01)
    whole = json.loads(run_cli("fit-current", str(log), "--columns", COLUMNS, "--json", "--whole-log").stdout)
    assert "headline" not in whole and any(f.startswith("blocks") for f in whole["flags"])
    two = json.loads(run_cli("fit-current", str(log), "--columns", COLUMNS, "--json", "--window", "0:15,20:30").stdout)
    assert two["rows"]["fitted"] < good["rows"]["fitted"] and "kept 0 to 15, 20 to 30 s" in " ".join(
        c["message"] for c in two["cleaning"]
    )
    assert_one_line_error(
        run_cli("fit-current", str(log), "--columns", COLUMNS, "--window", "0:15,10:30"), "in order and apart"
    )
    assert_one_line_error(run_cli("fit-current", str(log), "--columns", COLUMNS, "--window", "x"), "START:STOP")
    assert_one_line_error(run_cli("fit-current", str(log), "--columns", COLUMNS, "--window", "5:1"), "not before")
    assert_one_line_error(
        run_cli("fit-current", str(log), "--columns", COLUMNS, "--window", "70:"), "keeps 0 rows", "spans 0 to"
    )


def test_the_plot_drops_missing_channels_and_shows_the_blocks(tmp_path):
    from hound_id.dyno.current.curve import peak_torque
    from hound_id.dyno.current.diagnose import diagnose
    from hound_id.dyno.current.effects import Signals
    from hound_id.dyno.current.fit import fit_model
    from hound_id.dyno.current.plot import plot_fit
    from hound_id.dyno.logs import load_log, parse_mapping
    from tests.dyno.acquire.polledrig import COLUMNS

    path = _polled(tmp_path, motor_off_at=40.0)
    for columns, absent in (
        (COLUMNS, ("position", "temperature")),
        ("time=loop_time,current=iq_meas,torque=torque_adc", ("velocity",)),
    ):
        log = load_log(path, columns=parse_mapping(columns, "--columns"))
        signals = Signals.from_log(log)
        fit = fit_model(signals, log.torque, ("linear", "saturation"))
        d = diagnose(signals, log.torque, fit)
        fig = plot_fit(signals, log.torque, fit, peak_torque(fit, 10.0), diagnosis=d)
        labels = [ax.get_xlabel() for ax in fig.axes if ax.axison]
        assert not any(name in label for label in labels for name in absent)
        block = next(ax for ax in fig.axes if ax.axison and "block" in ax.get_title().lower())
        reds = [p for p in block.patches if p.get_facecolor()[:3] == pytest.approx((0.839, 0.153, 0.157), abs=0.01)]
        assert len(reds) == int(d.disagreeing.sum()) > 0  # the blocks after the motor was switched off
    proc = run_cli("fit-current", str(path), "--columns", COLUMNS, "--plot", str(tmp_path / "p.png"))
    assert proc.returncode == 0 and (tmp_path / "p.png").read_bytes().startswith(PNG_MAGIC)


def test_a_warning_prints_units_in_brackets_as_written(capsys):
    from hound_id.cli._render import warn

    warn("the time column looks like milliseconds: write 'time[ms]' in the header")
    assert "write 'time[ms]' in the header" in capsys.readouterr().err
