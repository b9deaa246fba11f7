"""Regenerate hound_like_running.csv: synthetic joint torque commands of an aggressive gait.

The file stands in for a log of a policy trained WITHOUT the MOR: a 4 Hz trot
(0.25 s stride, as at the paper's 6.5 m/s) whose knee commands reach 95 N m while
the knees swing at up to 60 rad/s. The numbers are synthetic (sinusoids with
phase offsets), not recorded; they exist so `hound-id saturate` and the demo have
something to clip. Columns: time [s], tau_<joint> [N m], qd_<joint> [rad/s].

Run: python data/samples/commands/make_commands.py [OUT_DIR]
"""

import sys
from pathlib import Path

import numpy as np

RATE_HZ, DURATION_S, STRIDE_HZ = 500, 0.5, 4.0
LEGS = {"FL": 0.0, "FR": 0.5, "RL": 0.5, "RR": 0.0}  # trot: diagonal pairs in phase
# joint -> (torque amplitude [N m], torque phase, speed amplitude [rad/s], speed phase)
HERE = Path(__file__).resolve().parent
JOINTS = {"HAA": (30.0, 0.3, 10.0, 1.2), "HFE": (70.0, 3.4, 45.0, 0.2), "KFE": (95.0, 1.35, 60.0, 1.0)}


def main(out_dir: str | Path = HERE) -> list[Path]:
    """Write hound_like_running.csv into out_dir; return the files written."""
    t = np.arange(int(RATE_HZ * DURATION_S)) / RATE_HZ
    cols = {"time": t}
    for leg, phase in LEGS.items():
        for joint, (a_tau, p_tau, a_qd, p_qd) in JOINTS.items():
            angle = 2 * np.pi * (STRIDE_HZ * t + phase)
            cols[f"tau_{leg}_{joint}"] = a_tau * np.sin(angle + p_tau)
            cols[f"qd_{leg}_{joint}"] = a_qd * np.sin(angle + p_qd)
    names = list(cols)
    data = np.column_stack([cols[n] for n in names])
    out = Path(out_dir) / "hound_like_running.csv"
    header = "# synthetic, see make_commands.py\n" + ",".join(names)
    np.savetxt(out, data, delimiter=",", header=header, comments="", fmt="%.6g")
    return [out]


if __name__ == "__main__":
    main(*sys.argv[1:2])
