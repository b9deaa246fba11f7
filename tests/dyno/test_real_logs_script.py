"""benchmarks/real_logs.py, run as a user runs it on a folder of logs: one line per log and the summary."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "real_logs.py"


def _log(path: Path, seed: int, drift: float = 0.0, wander: float = 0.0) -> Path:
    """A 40 s sweep at 100 Hz with Coulomb friction and AR(1) transducer noise; ``drift`` [N m] an offset creeping,
    ``wander`` [N m RMS] a zero that wanders over 2 s (a Gauss-Markov process)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 40.0, 0.01)
    i = 8 * np.sin(2 * np.pi * 0.23 * t) + rng.normal(0, 0.01, t.size)
    w = 3 * np.sin(2 * np.pi * 0.13 * t)
    noise = np.zeros(t.size)
    for k in range(1, t.size):
        noise[k] = 0.9 * noise[k - 1] + rng.normal(0, 0.05 * np.sqrt(1 - 0.81))
    zero = np.zeros(t.size)
    for k in range(1, t.size):
        zero[k] = 0.995 * zero[k - 1] + rng.normal(0, wander * np.sqrt(1 - 0.995**2))
    torque = 0.9 * i - 0.2 * np.tanh(w / 0.05) + noise + drift * t / t[-1] + zero
    pd.DataFrame({"time": t, "current": i, "torque": torque, "velocity": w}).to_csv(path, index=False)
    return path


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("logs")
    _log(root / "clean.csv", 1)
    (root / "rig b").mkdir()
    _log(root / "rig b" / "creeping.csv", 2, drift=0.6)
    _log(root / "wandering.csv", 3, wander=0.3)
    pd.DataFrame({"time": np.arange(300) * 0.01, "current": np.full(300, 2.0), "torque": np.full(300, 1.8)}).to_csv(
        root / "held.csv", index=False
    )
    return root


def test_every_log_gets_a_line_and_the_summary_counts_them(folder):
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), str(folder), "--json"], capture_output=True, text=True, check=False, timeout=600
    )
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["schema"] == "hound-id/real-logs/1"
    logs = {r["log"]: r for r in out["logs"]}
    assert set(logs) == {"clean.csv", "held.csv", "rig b/creeping.csv", "wandering.csv"}
    assert "error" in logs["held.csv"] and logs["held.csv"]["exit"] == 2  # one current: refused with the reason
    s = out["summary"]
    assert s["logs"] == 4 and s["fitted"] == 3
    ratios = sorted(r["rmse"]["test"] / r["noise_floor"] for r in out["logs"] if "error" not in r)
    assert s["median_ratio"] == pytest.approx(float(np.median(ratios)))
    assert s["ratio_range"] == pytest.approx([ratios[0], ratios[-1]])
    assert sum(s["floor_methods"].values()) == 3
    # the clean sweep never holds still: its correlated noise is read between far-apart moments
    clean = logs["clean.csv"]["noise"]
    assert clean["neighbours"] is not None and clean["neighbours"] == pytest.approx(0.05, rel=0.3)
    # the creeping offset is named, not counted as noise
    creeping = logs["rig b/creeping.csv"]["noise"]
    assert creeping["drift"] is not None and "drifts" in creeping["sentence"]
    assert s["drift_named"] >= 1
    # the wandering zero is named as what it is, with its size, and counted as a named cause
    wandering = logs["wandering.csv"]
    assert wandering["wander"] is not None and wandering["wander"]["slow_rms"] == pytest.approx(0.3, rel=0.35)
    assert "wander" in wandering["summary"]
    above = [r for r in out["logs"] if "error" not in r and r["rmse"]["test"] / r["noise_floor"] > 2.0]
    assert s["above_2x"] == len(above)
    assert "wandering.csv" not in s["no_cause_above_2x"]
    assert sum(s["causes_above_2x"].values()) >= len(above) - len(s["no_cause_above_2x"])


def test_the_plain_output_ends_with_the_summary(folder):
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), str(folder)], capture_output=True, text=True, check=False, timeout=600
    )
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    assert len(lines) == 5 and lines[0].startswith("clean.csv: rows ")
    assert lines[-1].startswith("3 of 4 logs fitted; cross-validated RMSE / noise floor: median ")
    assert "with no cause named" in lines[-1]
    assert "outside the flagged stretches" in lines[-1]
