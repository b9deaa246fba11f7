"""Regenerate ilm85_sag_log.csv: a synthetic torque-speed log of the sample ILM85 motor with a sagging supply.

The file stands in for a robot or dyno log in which the motor was driven past its limits, for
``hound-id mor --spec ../motors/hound_ilm85.yaml --compare ilm85_sag_log.csv``. It is simulated
(hound_id.dyno.simulate.envelope.simulate_log), not recorded.

Sourced: the 20S2P Li-ion pack charged to 81 V (the paper). Assumed: the pack's internal
resistance, 0.15 ohm (20 cells in series at about 15 mohm each, two strings in parallel,
plus wiring), hidden as the ``bus_sag`` effect; speeds uniform within 95 % of the no-load
speed; commands uniform over 1.5 x the torque limit; 0.02 N m torque noise; the winding
sweeping 30-90 degC. The truth is in ilm85_sag_truth.json.

Columns, in a rig's own names: speed [rpm], torque [N*m], iq [A], winding_temp [degC], vbus [V].
Map them with --columns velocity=speed,current=iq,temperature=winding_temp,bus_voltage=vbus.

Run: python data/samples/envelope/make_envelope_log.py [OUT_DIR]
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
TRUTH = {"bus_sag": 0.15}
SEED = 7


def main(out_dir: str | Path = HERE) -> list[Path]:
    """Write ilm85_sag_log.csv and ilm85_sag_truth.json into out_dir; return the files written."""
    from hound_id.dyno.simulate.envelope import simulate_log
    from hound_id.mor.envelope import EnvelopeInputs
    from hound_id.mor.spec_sheet import load_motor_spec

    spec = load_motor_spec(HERE.parent / "motors" / "hound_ilm85.yaml")
    d = simulate_log(EnvelopeInputs(spec), TRUTH, n=12000, noise=0.02, seed=SEED, speed_fraction=0.95)
    path, truth_file = Path(out_dir) / "ilm85_sag_log.csv", Path(out_dir) / "ilm85_sag_truth.json"
    header = "speed [rpm],torque [N*m],iq [A],winding_temp [degC],vbus [V]"
    rows = np.column_stack(
        [d["velocity"] * 60 / (2 * math.pi), d["torque"], d["current"], d["temperature"], d["bus_voltage"]]
    )
    np.savetxt(path, rows, delimiter=",", header=header, comments="", fmt="%.6g")
    truth = {"effects": TRUTH, "noise": 0.02, "seed": SEED, "motor": spec.name, "units": "ohm, N m"}
    truth_file.write_text(json.dumps(truth, indent=2) + "\n")
    return [path, truth_file]


if __name__ == "__main__":
    print(*main(*sys.argv[1:2]), sep="\n")
