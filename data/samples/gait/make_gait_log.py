"""Regenerate hound_running.csv: a synthetic 2 s running log of a Hound-like quadruped at 6.5 m/s.

The file stands in for a recorded gait log for `hound_id.foot.angles.contact_angles`. It is
synthetic (planar kinematics with seeded jitter), not recorded.

Sourced: the speed (6.5 m/s) and the 0.25 s stride at that speed (the paper); the leg
geometry of data/samples/legs/hound_leg.urdf (thigh 0.27 m, calf 0.28 m to the foot centre,
original foot radius 0.03 m, knee angle negative: KFE limits -2.8..-0.3 rad).
Assumed: a flying trot (diagonal pairs RR+FL and RL+FR in stance together, 80 ms stance,
duty 0.32); hip height 0.48 m; the stance stroke (6.5 m/s * stance time) centred under the
hip (Raibert's neutral point); hips 0.30 m ahead of / behind the body's pitch axis; body
pitch 2 deg at twice the stride frequency, extreme at mid-stance; 0.09 m swing clearance;
seeded stride-to-stride jitter (standard deviations: touchdown 2 ms, stance duration 1.5 ms,
each leg 1 ms on its own, foot placement 5 mm) and 0.2 deg sensor noise on pitch and joints.

Kinematics (REP-103: x forward, z up, pitch about +y, 0 = link pointing straight down):
thigh angle th_t = pitch + HFE, calf angle th_c = th_t + KFE, foot centre relative to the
hip in the world (x, z) = -l1 (sin th_t, cos th_t) - l2 (sin th_c, cos th_c). In stance the
foot centre stays at height r above flat ground while the hip runs forward at 6.5 m/s (the
foot's rolling is neglected: its centre moves in a straight line); each hip's height follows
the body pitch. In swing the foot returns on a cubic Hermite path in x, leaving and meeting
the ground while moving backward relative to the hip at half the running speed (swing-leg
retraction; the full speed would overreach the leg), with a half-sine bump in z. HFE and KFE
come from the planar inverse kinematics with the knee behind the hip-foot line (KFE < 0).

What comes out (contact_angles, all legs): the hip-to-foot line sweeps about -29.5 to +29.5
deg, but the calf, which carries the foot, points ahead of that line by about half the knee bend,
so its contact angle runs from about -49 deg at touchdown to about +10 deg at liftoff.

Columns (SI): time [s], pitch [rad], then for RR, RL, FR, FL: <leg>_HFE [rad],
<leg>_KFE [rad], <leg>_contact (1 stance, 0 flight). 500 Hz, 1000 rows.

Run: python data/samples/gait/make_gait_log.py [OUT_DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SEED = 65

RATE_HZ, DURATION_S = 500, 2.0
SPEED = 6.5  # [m/s]
STRIDE_S, STANCE_S = 0.25, 0.080  # [s]
THIGH, CALF, FOOT_R = 0.27, 0.28, 0.03  # [m], from hound_leg.urdf
KFE_MAX = -0.3  # [rad], the URDF upper limit (the knee never straightens fully)
HIP_HEIGHT = 0.48  # [m] above the ground at zero pitch
CLEARANCE = 0.09  # [m] swing bump of the foot
RETRACT = 0.5  # foot speed backward relative to the hip at liftoff and touchdown, fraction of SPEED
PITCH_AMP = np.radians(2.0)  # [rad]
FIRST_TOUCHDOWN = 0.01  # [s], pair RR+FL; pair RL+FR half a stride later
# leg -> (hip x along the body [m], half-stride offset of its diagonal pair)
LEGS = {"RR": (-0.30, 0.0), "RL": (-0.30, 0.5), "FR": (0.30, 0.5), "FL": (0.30, 0.0)}
# jitter (standard deviations): touchdown [s], stance duration [s], per-leg timing [s], placement [m]
SD_TOUCHDOWN, SD_STANCE, SD_LEG, SD_PLACE = 0.002, 0.0015, 0.001, 0.005
SD_NOISE = np.radians(0.2)  # [rad]


def _stances(rng: np.random.Generator, offset: float) -> tuple[np.ndarray, np.ndarray]:
    """Touchdown and liftoff times of one diagonal pair, covering the log with a stride to spare."""
    k = np.arange(-1, int(DURATION_S / STRIDE_S) + 2)
    touchdown = FIRST_TOUCHDOWN + (k + offset) * STRIDE_S + rng.normal(0, SD_TOUCHDOWN, k.size)
    return touchdown, touchdown + STANCE_S + rng.normal(0, SD_STANCE, k.size)


def _foot_path(t: np.ndarray, touchdown: np.ndarray, liftoff: np.ndarray, centre: np.ndarray):
    """Foot centre x relative to the hip, height above the ground, and the contact flag."""
    x_td = centre + SPEED * (liftoff - touchdown) / 2  # where each stance starts and ends, hip-relative
    x_lo = centre - SPEED * (liftoff - touchdown) / 2
    j = np.searchsorted(touchdown, t, side="right") - 1  # the last touchdown at or before t
    stance = t < liftoff[j]
    x = np.empty_like(t)
    x[stance] = x_td[j[stance]] - SPEED * (t[stance] - touchdown[j[stance]])
    # swing from liftoff j to touchdown j+1: cubic Hermite with velocity -RETRACT * SPEED at both ends
    s = ~stance
    js = j[s]
    dur = touchdown[js + 1] - liftoff[js]
    tau = (t[s] - liftoff[js]) / dur
    h00, h10 = 2 * tau**3 - 3 * tau**2 + 1, tau**3 - 2 * tau**2 + tau
    h01, h11 = -2 * tau**3 + 3 * tau**2, tau**3 - tau**2
    x[s] = h00 * x_lo[js] + h01 * x_td[js + 1] - RETRACT * SPEED * dur * (h10 + h11)
    height = np.full_like(t, FOOT_R)
    height[s] += CLEARANCE * np.sin(np.pi * tau)
    return x, height, stance


def _inverse_kinematics(x: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World thigh and calf angles putting the foot centre at (x, z) from the hip, knee behind."""
    reach = np.hypot(x, z)
    leg = np.arctan2(-x, -z)  # hip-to-foot line, 0 straight down, positive with the foot behind
    at_hip = np.arccos((THIGH**2 + reach**2 - CALF**2) / (2 * THIGH * reach))
    at_foot = np.arccos((CALF**2 + reach**2 - THIGH**2) / (2 * CALF * reach))
    return leg + at_hip, leg - at_foot


def build(seed: int = SEED) -> dict[str, np.ndarray]:
    """The log's columns, noise included, in file order."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(RATE_HZ * DURATION_S))) / RATE_HZ
    pitch = PITCH_AMP * np.cos(2 * np.pi * 2 * (t - FIRST_TOUCHDOWN - STANCE_S / 2) / STRIDE_S)
    pairs = {offset: _stances(rng, offset) for offset in sorted({o for _, o in LEGS.values()})}
    cols: dict[str, np.ndarray] = {"time": t, "pitch": pitch + rng.normal(0, SD_NOISE, t.size)}
    for leg, (hip_x, offset) in LEGS.items():
        touchdown, liftoff = (times + rng.normal(0, SD_LEG, times.size) for times in pairs[offset])
        centre = rng.normal(0, SD_PLACE, touchdown.size)
        x, height, stance = _foot_path(t, touchdown, liftoff, centre)
        hip_z = HIP_HEIGHT - hip_x * np.sin(pitch)  # positive pitch is nose down
        th_t, th_c = _inverse_kinematics(x, height - hip_z)
        knee = th_c - th_t
        if not (np.all(np.isfinite(knee)) and knee.max() < KFE_MAX and knee.min() > -2.8):
            raise ValueError(f"{leg}: foot path out of the leg's reach or knee limits; check the parameters")
        cols[f"{leg}_HFE"] = th_t - pitch + rng.normal(0, SD_NOISE, t.size)
        cols[f"{leg}_KFE"] = knee + rng.normal(0, SD_NOISE, t.size)
        cols[f"{leg}_contact"] = stance.astype(float)
    return cols


def main(out_dir: str | Path = HERE) -> list[Path]:
    """Write hound_running.csv (6 significant digits) into out_dir; return the files written."""
    cols = build()
    names = list(cols)
    header = "# synthetic Hound-like running log at 6.5 m/s, see make_gait_log.py (SI: s, rad)\n" + ",".join(names)
    out = Path(out_dir) / "hound_running.csv"
    np.savetxt(out, np.column_stack([cols[n] for n in names]), delimiter=",", header=header, comments="", fmt="%.6g")
    return [out]


if __name__ == "__main__":
    main(*sys.argv[1:2])
