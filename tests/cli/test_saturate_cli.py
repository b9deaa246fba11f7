import json

import numpy as np
import pandas as pd
import pytest

from hound_id.mor.robot import load_robot
from hound_id.mor.saturation import saturation_for
from tests.cli.test_mor_cli import PNG_MAGIC, assert_one_line_error
from tests.conftest import ROBOT, SAMPLES, run_cli

LOG = SAMPLES / "commands" / "hound_like_running.csv"


def test_saturate_sample_log(tmp_path):
    out, plot = tmp_path / "sat.parquet", tmp_path / "sat.png"
    proc = run_cli("saturate", str(LOG), "--robot", str(ROBOT), "--out", str(out), "--plot", str(plot), "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["schema"] == "hound-id/saturate/2" and data["rows"] == 250
    assert 0.0 < data["violating_fraction"] < 1.0
    knee = next(m for m in data["motors"] if m["motor"] == "FL_KFE_motor")
    assert knee["clipped_fraction"] > 0.3
    frame = pd.read_parquet(out)
    robot = load_robot(ROBOT)
    tau_sat = frame[[f"tau_sat_{j}" for j in robot.joints]].to_numpy()
    qd = frame[[f"qd_{j}" for j in robot.joints]].to_numpy()
    tau = frame[[f"tau_{j}" for j in robot.joints]].to_numpy()
    sat = saturation_for(robot)
    assert sat.violation(tau_sat, qd).max() < 1e-9
    # joints whose motors were never clipped pass exactly
    assert np.array_equal(tau_sat[:, 0], tau[:, 0])
    assert plot.read_bytes().startswith(PNG_MAGIC)


def test_saturate_table_output(tmp_path):
    proc = run_cli("saturate", str(LOG), "--robot", str(ROBOT))
    assert proc.returncode == 0, proc.stderr
    assert "outside some motor's region" in proc.stdout and "FL_KFE_motor" in proc.stdout


def test_saturate_bad_logs(tmp_path):
    frame = pd.read_csv(LOG, comment="#")
    frame.drop(columns=["qd_RR_KFE"]).to_csv(tmp_path / "missing.csv", index=False)
    assert_one_line_error(
        run_cli("saturate", str(tmp_path / "missing.csv"), "--robot", str(ROBOT)),
        "missing.csv",
        "column 'qd_RR_KFE' missing",
    )
    bad = frame.copy()
    bad.loc[7, "tau_FL_HFE"] = np.nan
    bad.to_csv(tmp_path / "nan.csv", index=False)
    assert_one_line_error(
        run_cli("saturate", str(tmp_path / "nan.csv"), "--robot", str(ROBOT)), "column 'tau_FL_HFE' data row 8"
    )
    (tmp_path / "log.txt").write_text("x")
    assert_one_line_error(run_cli("saturate", str(tmp_path / "log.txt"), "--robot", str(ROBOT)), "unknown table format")
    (tmp_path / "empty.csv").write_text("")
    assert_one_line_error(run_cli("saturate", str(tmp_path / "empty.csv"), "--robot", str(ROBOT)), "empty.csv")
    assert_one_line_error(
        run_cli("saturate", str(LOG), "--robot", str(ROBOT), "--out", str(tmp_path / "o.xlsx")), "table files end in"
    )


def test_text_in_a_numeric_column_names_row_and_value(tmp_path):
    frame = pd.read_csv(LOG, comment="#")
    frame["qd_FL_KFE"] = frame["qd_FL_KFE"].astype(object)
    frame.loc[4, "qd_FL_KFE"] = "fast"
    frame.to_csv(tmp_path / "text.csv", index=False)
    assert_one_line_error(
        run_cli("saturate", str(tmp_path / "text.csv"), "--robot", str(ROBOT)),
        "column 'qd_FL_KFE' data row 5 holds 'fast'",
    )


# --- extreme numbers, streaming, messages -------------------------------------------------------------------------

ROBOT_JOINTS = load_robot(ROBOT).joints


def strict_json(text):
    """json.loads that refuses NaN and Infinity (not JSON)."""

    def refuse(token):
        raise ValueError(f"not JSON: {token}")

    return json.loads(text, parse_constant=refuse)


def sample_frame():
    return pd.read_csv(LOG, comment="#")


def test_commands_of_1e308_give_finite_feasible_torques_and_valid_json(tmp_path):
    frame = sample_frame()
    for k, joint in enumerate(ROBOT_JOINTS):
        frame[f"tau_{joint}"] = (1.0 if k % 2 else -1.0) * 1e308
    frame.loc[3, [f"tau_{j}" for j in ROBOT_JOINTS]] = np.finfo(float).max
    frame.to_csv(tmp_path / "huge.csv", index=False)
    out = tmp_path / "sat.csv"
    proc = run_cli("saturate", str(tmp_path / "huge.csv"), "--robot", str(ROBOT), "--out", str(out), "--json")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""  # no overflow warnings either
    data = strict_json(proc.stdout)
    assert data["violating_fraction"] == 1.0
    assert all(np.isfinite(j["max_clip"]) and np.isfinite(j["mean_clip"]) for j in data["joints"])
    assert all(j["mean_clip"] == pytest.approx(1e308, rel=0.01) for j in data["joints"])  # 249 of 250 rows
    assert all(m["clipped_fraction"] == 1.0 for m in data["motors"])
    result = pd.read_csv(out)
    tau_sat = result[[f"tau_sat_{j}" for j in ROBOT_JOINTS]].to_numpy()
    qd = result[[f"qd_{j}" for j in ROBOT_JOINTS]].to_numpy()
    assert np.all(np.isfinite(tau_sat)) and np.abs(tau_sat).max() < 1e3
    assert saturation_for(load_robot(ROBOT)).violation(tau_sat, qd).max() < 1e-9


def test_summary_is_the_in_memory_summary_and_the_table_round_trips(tmp_path):
    from hound_id.mor.saturate_log import saturate_log

    out = tmp_path / "sat.parquet"
    proc = run_cli("saturate", str(LOG), "--robot", str(ROBOT), "--out", str(out), "--json")
    data = strict_json(proc.stdout)
    expected = saturate_log(load_robot(ROBOT), sample_frame(), source=str(LOG)).to_dict()
    assert {k: v for k, v in data.items() if k not in ("out", "plot")} == expected  # one batch: bit for bit
    frame, written = sample_frame(), pd.read_parquet(out)
    assert list(written.columns) == list(frame.columns) + [f"tau_sat_{j}" for j in ROBOT_JOINTS]
    assert np.array_equal(written[frame.columns].to_numpy(), frame.to_numpy())


def test_csv_to_csv_copies_the_cells_as_written(tmp_path):
    out = tmp_path / "sat.csv"
    assert run_cli("saturate", str(LOG), "--robot", str(ROBOT), "--out", str(out)).returncode == 0
    source = [line for line in LOG.read_text().splitlines() if not line.startswith("#")]
    written = out.read_text().splitlines()
    n = len(source[0].split(","))
    assert [",".join(line.split(",")[:n]) for line in written] == source
    assert written[0].split(",")[n:] == [f"tau_sat_{j}" for j in ROBOT_JOINTS]


@pytest.mark.parametrize(
    ("value", "shown"), [("nan", "holds nan"), ("inf", "holds inf"), ("-1e400", "holds -inf"), ("", "holds nan")]
)
def test_non_finite_cells_are_refused_naming_file_column_and_row(tmp_path, value, shown):
    lines = LOG.read_text().splitlines()
    header = lines[1].split(",")
    row = lines[2 + 40].split(",")
    row[header.index("qd_RL_HFE")] = value
    lines[2 + 40] = ",".join(row)
    (tmp_path / "bad.csv").write_text("\n".join(lines) + "\n")
    out = tmp_path / "o.parquet"
    assert_one_line_error(
        run_cli("saturate", str(tmp_path / "bad.csv"), "--robot", str(ROBOT), "--out", str(out), "--json"),
        "bad.csv",
        f"column 'qd_RL_HFE' data row 41 {shown}",
        "expected a finite number",
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv"]  # nothing left behind


def test_a_trailing_comma_on_some_rows_names_the_line(tmp_path):
    lines = LOG.read_text().splitlines()
    lines[9] += ","
    (tmp_path / "comma.csv").write_text("\n".join(lines) + "\n")
    assert_one_line_error(
        run_cli("saturate", str(tmp_path / "comma.csv"), "--robot", str(ROBOT)),
        "comma.csv: line 10 (data row 8) has 26 fields, the header has 25; a trailing separator?",
    )


def test_a_trailing_comma_on_every_row_is_read_as_before(tmp_path):
    lines = LOG.read_text().splitlines()
    text = "\n".join(lines[:2] + [line + "," for line in lines[2:]]) + "\n"
    (tmp_path / "trailing.csv").write_text(text)
    plain = strict_json(run_cli("saturate", str(LOG), "--robot", str(ROBOT), "--json").stdout)
    proc = run_cli("saturate", str(tmp_path / "trailing.csv"), "--robot", str(ROBOT), "--json")
    assert proc.returncode == 0, proc.stderr
    assert strict_json(proc.stdout) == plain


def test_a_trailing_comma_on_the_header_only_is_read_as_before(tmp_path):
    lines = LOG.read_text().splitlines()
    lines[1] += ","
    (tmp_path / "header.csv").write_text("\n".join(lines) + "\n")
    proc = run_cli("saturate", str(tmp_path / "header.csv"), "--robot", str(ROBOT), "--json")
    assert proc.returncode == 0, proc.stderr
    assert strict_json(proc.stdout) == strict_json(
        run_cli("saturate", str(LOG), "--robot", str(ROBOT), "--json").stdout
    )


def test_a_leading_comma_is_refused_not_read_shifted(tmp_path):
    """Every row one field more than the header, at the front: before, each column silently got its
    left neighbour's values (qd_RR_KFE holding tau_RR_KFE)."""
    lines = LOG.read_text().splitlines()
    (tmp_path / "shifted.csv").write_text("\n".join(lines[:2] + ["," + line for line in lines[2:]]) + "\n")
    assert_one_line_error(
        run_cli("saturate", str(tmp_path / "shifted.csv"), "--robot", str(ROBOT)),
        "shifted.csv: the rows have 26 fields but the header names 25",
        "shifted against the column names",
    )


def test_boolean_column_in_parquet_is_refused(tmp_path):
    frame = sample_frame()
    frame["tau_FL_HAA"] = frame["tau_FL_HAA"] > 0
    frame.to_parquet(tmp_path / "bool.parquet")
    assert_one_line_error(
        run_cli("saturate", str(tmp_path / "bool.parquet"), "--robot", str(ROBOT)),
        "bool.parquet: column 'tau_FL_HAA' holds booleans (true/false); expected numbers (N m)",
    )


def test_header_only_and_empty_tables(tmp_path):
    (tmp_path / "header.csv").write_text(LOG.read_text().splitlines()[1] + "\n")
    assert_one_line_error(run_cli("saturate", str(tmp_path / "header.csv"), "--robot", str(ROBOT)), "has no rows")
    sample_frame().iloc[:0].to_parquet(tmp_path / "empty.parquet")
    assert_one_line_error(run_cli("saturate", str(tmp_path / "empty.parquet"), "--robot", str(ROBOT)), "has no rows")


def long_log(rows, seed=0):
    """The sample log repeated with noise to ``rows`` rows (several streaming batches)."""
    frame = sample_frame()
    rng = np.random.default_rng(seed)
    big = pd.concat([frame] * (rows // len(frame) + 1), ignore_index=True).iloc[:rows].copy()
    big["time"] = np.arange(rows) * 0.002
    for column in big.columns[1:]:
        big[column] = np.round(big[column] + rng.normal(0.0, 2.0, rows), 4)
    return big


def test_long_log_streams_with_rows_counted_over_the_whole_file(tmp_path):
    big = long_log(30_000)
    big.to_csv(tmp_path / "long.csv", index=False)
    big.to_parquet(tmp_path / "long.parquet", row_group_size=7_000)
    results = []
    for name in ("long.csv", "long.parquet"):
        out = tmp_path / f"out_{name}"
        proc = run_cli("saturate", str(tmp_path / name), "--robot", str(ROBOT), "--out", str(out), "--json")
        assert proc.returncode == 0, proc.stderr
        results.append(strict_json(proc.stdout))
        written = pd.read_csv(out) if name.endswith(".csv") else pd.read_parquet(out)
        assert len(written) == 30_000 and np.allclose(written[big.columns].to_numpy(), big.to_numpy())
    assert results[0]["rows"] == results[1]["rows"] == 30_000
    assert results[0]["motors"] == results[1]["motors"]
    # the summary of a file streamed in batches: the in-memory one, to rounding
    from hound_id.mor.saturate_log import saturate_log

    whole = saturate_log(load_robot(ROBOT), big).to_dict()
    for got in results:
        assert got["violating_fraction"] == whole["violating_fraction"] and got["motors"] == whole["motors"]
        for a, b in zip(got["joints"], whole["joints"], strict=True):
            assert a["max_clip"] == pytest.approx(b["max_clip"], rel=1e-12)
            assert a["mean_clip"] == pytest.approx(b["mean_clip"], rel=1e-12)
    # a bad row far into the file is named by its row in the file
    big.loc[27_345, "tau_RR_HFE"] = np.nan
    big.to_csv(tmp_path / "late.csv", index=False)
    out = tmp_path / "late_out.csv"
    assert_one_line_error(
        run_cli("saturate", str(tmp_path / "late.csv"), "--robot", str(ROBOT), "--out", str(out)),
        "column 'tau_RR_HFE' data row 27346 holds nan",
    )
    assert not out.exists() and not list(tmp_path.glob(".late_out*"))
    lines = (tmp_path / "long.csv").read_text().splitlines()
    lines[20_001] = lines[20_001].replace(",", ",,", 1)
    (tmp_path / "split.csv").write_text("\n".join(lines) + "\n")
    assert_one_line_error(
        run_cli("saturate", str(tmp_path / "split.csv"), "--robot", str(ROBOT)),
        "split.csv: line 20002 (data row 20001) has 26 fields, the header has 25",
    )
    lines = (tmp_path / "long.csv").read_text().splitlines()
    header = lines[0].split(",")
    cells = lines[25_001].split(",")
    cells[header.index("qd_FR_KFE")] = "fast"
    lines[25_001] = ",".join(cells)
    (tmp_path / "text.csv").write_text("\n".join(lines) + "\n")
    for out in ("t.csv", "t.parquet", None):
        args = ("--out", str(tmp_path / out)) if out else ()
        assert_one_line_error(
            run_cli("saturate", str(tmp_path / "text.csv"), "--robot", str(ROBOT), *args),
            "column 'qd_FR_KFE' data row 25001 holds 'fast'; expected a number",
        )


def test_long_log_plot_draws_a_thinned_sample(tmp_path):
    long_log(45_000).to_parquet(tmp_path / "long.parquet")
    plot = tmp_path / "p.png"
    proc = run_cli("saturate", str(tmp_path / "long.parquet"), "--robot", str(ROBOT), "--plot", str(plot))
    assert proc.returncode == 0, proc.stderr
    assert plot.read_bytes().startswith(PNG_MAGIC)
    assert "the plot draws one row in 4 (11250 of 45000)" in proc.stdout


def test_a_passed_through_column_that_changes_type_late_is_read_again_wider(tmp_path):
    """pyarrow types CSV columns from the first block (1 MB): a count that turns into a fraction, or an
    empty column that fills with words, 25,000 rows in, makes the stream start again with a wider type."""
    big = long_log(30_000)
    big["step"] = np.arange(30_000).astype(object)
    big.loc[25_000, "step"] = 0.5
    big["note"] = ""
    big.loc[26_000, "note"] = "fell"
    big.to_csv(tmp_path / "late.csv", index=False)
    out = tmp_path / "out.parquet"
    proc = run_cli("saturate", str(tmp_path / "late.csv"), "--robot", str(ROBOT), "--out", str(out), "--json")
    assert proc.returncode == 0, proc.stderr
    written = pd.read_parquet(out)
    assert written["step"].dtype == float and written.loc[25_000, "step"] == 0.5 and written["step"][29_999] == 29_999
    assert written.loc[26_000, "note"] == "fell"
    assert strict_json(proc.stdout)["rows"] == 30_000


# --- the direction change of the coupled clip -------------------------------------------------------------------


def polar_turn(a, b):
    """Angle between 2-vectors [deg] from their polar angles (not the formula hound_id.mor.clip_turn uses)."""
    d = np.arctan2(b[:, 1], b[:, 0]) - np.arctan2(a[:, 1], a[:, 0])
    return np.degrees(np.abs((d + np.pi) % (2 * np.pi) - np.pi))


def test_json_carries_the_turn_of_each_hip_knee_group_as_an_independent_computation_gives(tmp_path):
    from hound_id.mor.region import operating_region

    out = tmp_path / "sat.csv"
    proc = run_cli("saturate", str(LOG), "--robot", str(ROBOT), "--out", str(out), "--json")
    assert proc.returncode == 0, proc.stderr
    turn = json.loads(proc.stdout)["clip_turn"]
    assert turn["floor"] == 0.01 and "DC-motor" in turn["reference"]
    assert [g["group"] for g in turn["groups"]] == [f"{leg}_HFE+{leg}_KFE" for leg in ("FL", "FR", "RL", "RR")]
    frame = pd.read_csv(out)
    region = operating_region(load_robot(ROBOT).motor_specs["FL_KFE_motor"])
    G = 7.5  # the sample's hip and knee ratios
    for g in turn["groups"]:
        hip, knee = g["joints"]
        tau = frame[[f"tau_{hip}", f"tau_{knee}"]].to_numpy()
        sat = frame[[f"tau_sat_{hip}", f"tau_sat_{knee}"]].to_numpy()
        qd = frame[[f"qd_{hip}", f"qd_{knee}"]].to_numpy()
        # motor torques by hand: tau_m = A^T tau, tau_m,h = tau_h / G - tau_k / G^2, tau_m,k = tau_k / G
        motor = np.column_stack([tau[:, 0] / G - tau[:, 1] / G**2, tau[:, 1] / G])
        motor_sat = np.column_stack([sat[:, 0] / G - sat[:, 1] / G**2, sat[:, 1] / G])
        moved = np.abs(motor_sat - motor) > 1e-6
        clipped = moved.any(axis=1)
        angles = polar_turn(tau, sat)[clipped]
        assert g["clipped_rows"] == int(clipped.sum()) > 100
        assert g["angle"]["median"] == pytest.approx(np.median(angles), abs=1e-6)
        assert g["angle"]["p95"] == pytest.approx(np.quantile(angles, 0.95), abs=1e-6)
        assert g["angle"]["max"] == pytest.approx(angles.max(), abs=1e-6)
        growth = (np.abs(sat) - np.abs(tau))[clipped]
        assert g["grew"]["rows"] == int((growth > 0.01).any(axis=1).sum()) > 0
        assert g["grew"]["max"] == pytest.approx(growth.max(), abs=1e-6)
        knee_only = moved[:, 1] & ~moved[:, 0]
        (pattern,) = [p for p in g["by_motors"] if p["motors"] == [f"{knee}_motor"]]
        assert pattern["rows"] == int(knee_only.sum())
        assert pattern["grew"]["by_joint"][hip] == int((growth[knee_only[clipped], 0] > 0.01).sum())
        # the per-joint DC clip by hand, each joint through its own 7.5 gear at its own speed
        stall, no_load, limit = region.stall_torque * G, region.no_load_speed / G, region.torque_limit * G
        v = np.clip(qd, -no_load * (1 + limit / stall), no_load * (1 + limit / stall))
        ref = np.clip(tau, np.maximum(stall * (-1 - v / no_load), -limit), np.minimum(stall * (1 - v / no_load), limit))
        changed = np.any(ref != tau, axis=1)
        acted = changed | clipped
        per_joint = g["per_joint"]
        assert per_joint["clipped_rows"] == int(changed.sum())
        assert per_joint["angle"]["median"] == pytest.approx(np.median(polar_turn(tau, ref)[changed]), abs=1e-6)
        assert per_joint["difference_max"] == pytest.approx(np.hypot(*(sat - ref).T)[acted].max(), abs=1e-6)
        assert 0 < per_joint["outside_rows"] <= per_joint["rows"] == int(acted.sum())


def test_table_shows_the_turn_and_the_per_joint_comparison():
    proc = run_cli("saturate", str(LOG), "--robot", str(ROBOT))
    assert proc.returncode == 0, proc.stderr
    for text in ("direction change of the coupled clip", "FL_HFE+FL_KFE", "FL_KFE_motor alone", "per-joint clip"):
        assert text in proc.stdout
