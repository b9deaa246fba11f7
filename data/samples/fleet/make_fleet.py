"""Regenerate the simulated fleet: the twelve actuators of a quadruped, four with planted faults.

Simulated with hound_id.dyno.simulate.fleet (seed 19, 400 Hz, its 12.5 s four-quadrant plan):
one motor type with a production batch's scatter (Kt 1 %, friction and cogging 10 %), every log
with the canonical columns time, current, torque, velocity, position (SI). Planted faults (the
truth, with every unit's parameters, is in fleet_truth.json):

* FR_thigh: weak_magnet (Kt 10 % low)
* RL_hip: bearing (Coulomb friction x3)
* RL_knee: gearbox (load-dependent friction x3)
* RR_thigh: different_motor (cogging order 28 instead of 24)

Run: python data/samples/fleet/make_fleet.py [OUT_DIR]
"""

import json
import sys
from pathlib import Path

from hound_id.dyno.simulate.fleet import FAULTS, FLEET_COLUMNS, FLEET_MODEL, simulate_fleet

HERE = Path(__file__).resolve().parent
NAMES = [f"{leg}_{joint}" for leg in ("FL", "FR", "RL", "RR") for joint in ("hip", "thigh", "knee")]
FAULTY = {"FR_thigh": "weak_magnet", "RL_hip": "bearing", "RL_knee": "gearbox", "RR_thigh": "different_motor"}
SEED = 19


def main(out_dir: str | Path = HERE) -> list[Path]:
    """Write the twelve logs and fleet_truth.json into out_dir; return the files written."""
    out = Path(out_dir)
    faults = {NAMES.index(name): fault for name, fault in FAULTY.items()}
    fleet = simulate_fleet(len(NAMES), faults=faults, seed=SEED, names=NAMES)
    written = []
    for member in fleet:
        frame = member.log.frame[list(FLEET_COLUMNS)]
        written.append(out / f"{member.name}.csv")
        frame.to_csv(written[-1], index=False, float_format="%.6g")
    truth = {
        "model": FLEET_MODEL,
        "faults": {m.name: {"fault": m.fault, "description": FAULTS[m.fault].description} for m in fleet if m.fault},
        "actuators": {m.name: {k: float(v) for k, v in m.log.truth.items()} for m in fleet},
    }
    written.append(out / "fleet_truth.json")
    written[-1].write_text(json.dumps(truth, indent=2) + "\n")
    return written


if __name__ == "__main__":
    main(*sys.argv[1:2])
