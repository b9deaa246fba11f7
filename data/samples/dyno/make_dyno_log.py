"""Regenerate ilm85_dyno.csv: a simulated, deliberately dirty dynamometer log.

Simulated with hound_id.dyno.simulate.current (seed 7, 500 Hz, the default test plan with 10 ms
current edges) on a Hound-like 85 mm motor with these effects hidden besides the
quadratic saturation: offset, Coulomb friction, cogging (24 per revolution), thermal Kt
drift and a 5 ms torque-channel delay. Then made to look like a real rig's export:
its own column names, units in the headers (ms, mN*m, rpm, deg), a few NaN rows, one
165 A current glitch, a duplicated timestamp. The truth is in ilm85_dyno_truth.json.

Run: python data/samples/dyno/make_dyno_log.py [OUT_DIR]
"""

import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from hound_id.dyno.simulate.current import TestPlan, simulate

HERE = Path(__file__).resolve().parent
EFFECTS = ("linear", "saturation", "offset", "coulomb", "cogging", "thermal", "delay")


def main(out_dir: str | Path = HERE) -> list[Path]:
    """Write ilm85_dyno.csv and ilm85_dyno_truth.json into out_dir; return the files written."""
    plan = dataclasses.replace(TestPlan(), current_rise_time=0.01)
    sim = simulate(EFFECTS, plan=plan, rate_hz=500.0, seed=7)
    f = sim.frame.copy()
    rng = np.random.default_rng(7)
    f["time"] = f["time"] * 1e3
    f["torque"] = f["torque"] * 1e3
    f["velocity"] = f["velocity"] * 60 / (2 * np.pi)
    f["position"] = np.degrees(f["position"])
    nan_rows = rng.choice(len(f), 12, replace=False)
    f.loc[nan_rows, "torque"] = np.nan
    f.loc[int(len(f) * 0.43), "current"] = 165.0
    dup = int(len(f) * 0.61)
    f = f.rename(
        columns={
            "time": "timestamp[ms]",
            "current": "iq[A]",
            "torque": "adc_torque[mN*m]",
            "velocity": "speed[rpm]",
            "position": "angle[deg]",
            "temperature": "winding_temp[degC]",
            "bus_voltage": "vbus[V]",
        }
    )
    f = f.iloc[np.r_[0 : dup + 1, dup, dup + 1 : len(f)]]
    log, truth_file = Path(out_dir) / "ilm85_dyno.csv", Path(out_dir) / "ilm85_dyno_truth.json"
    f.to_csv(log, index=False, float_format="%.6g")
    truth = {k: float(v) for k, v in sim.truth.items()}
    truth_file.write_text(json.dumps({"effects": list(EFFECTS), "truth": truth}, indent=2) + "\n")
    return [log, truth_file]


if __name__ == "__main__":
    main(*sys.argv[1:2])
