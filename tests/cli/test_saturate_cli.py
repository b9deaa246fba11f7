import json

import numpy as np
import pandas as pd

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
    assert data["schema"] == "hound-id/saturate/1" and data["rows"] == 250
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
