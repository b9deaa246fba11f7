"""The sample running log data/samples/gait/hound_running.csv and its generator."""

import math

import numpy as np
import pytest

from hound_id.foot.angles import contact_angles
from hound_id.tables import read_table
from tests.conftest import SAMPLES

GAIT = SAMPLES / "gait"
LOG = GAIT / "hound_running.csv"
LEGS = ("RR", "RL", "FR", "FL")
THIGH, CALF = 0.27, 0.28  # hound_leg.urdf


@pytest.fixture(scope="module")
def log():
    return read_table(LOG)


def test_contact_angles_of_the_sample(log):
    a = contact_angles(log, LEGS, margin_deg=5)
    deg = {k: math.degrees(v) for k, v in a.to_dict().items() if isinstance(v, float)}
    assert a.strides == 32  # 8 complete stances per leg
    # the calf (which carries the foot) points ahead of the hip-to-foot line: about -49 to +10 deg
    assert -53 < deg["attack"] < -45
    assert 6 < deg["detach"] < 15
    assert 0.3 < deg["attack_spread"] < 2.5
    assert 0.3 < deg["detach_spread"] < 3.0
    assert deg["low"] < deg["attack"] - 5 and deg["high"] > deg["detach"] + 5
    assert deg["margin"] == pytest.approx(5)
    for leg in LEGS:
        assert contact_angles(log, [leg]).strides == 8


def test_trot_timing_of_the_sample(log):
    time = log["time"].to_numpy()
    assert np.diff(time) == pytest.approx(0.002)
    assert time[-1] == pytest.approx(1.998)
    contact = {leg: log[f"{leg}_contact"].to_numpy() > 0.5 for leg in LEGS}
    for leg in LEGS:
        assert 0.29 < contact[leg].mean() < 0.35  # duty about 0.32: 80 ms of a 0.25 s stride
    # diagonal pairs land together, the two legs of a side never do
    assert (contact["RR"] == contact["FL"]).mean() > 0.97 and (contact["RL"] == contact["FR"]).mean() > 0.97
    assert not np.any(contact["RR"] & contact["RL"]) and not np.any(contact["FR"] & contact["FL"])


def test_leg_line_sweeps_as_in_the_physics_notes(log):
    """The hip-to-foot line, not the calf, sweeps roughly 21-36 deg either side of vertical at 6.5 m/s."""
    touch, lift = [], []
    for leg in LEGS:
        thigh = log["pitch"].to_numpy() + log[f"{leg}_HFE"].to_numpy()
        calf = thigh + log[f"{leg}_KFE"].to_numpy()
        x = -THIGH * np.sin(thigh) - CALF * np.sin(calf)
        z = -THIGH * np.cos(thigh) - CALF * np.cos(calf)
        line = np.degrees(np.arctan2(-x, -z))
        edges = np.diff((log[f"{leg}_contact"].to_numpy() > 0.5).astype(int))
        starts, ends = np.flatnonzero(edges == 1) + 1, np.flatnonzero(edges == -1) + 1
        for s in starts:
            later = ends[ends > s]
            if later.size:
                touch.append(line[s])
                lift.append(line[later[0] - 1])
        assert np.all(log[f"{leg}_KFE"] < 0)  # the knee bends the URDF's way
    assert len(touch) == 32
    assert -32 < np.mean(touch) < -25 and 25 < np.mean(lift) < 32
    assert -36 < min(touch) and max(touch) < -21 and 21 < min(lift) and max(lift) < 36
