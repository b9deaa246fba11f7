import math

import numpy as np
import pytest

from hound_id.errors import DynoDataError, SpecError
from hound_id.foot.angles import contact_angles, given_angles


def gait(strides=6, attack=-0.40, detach=0.45, pitch=0.05, legs=("RR",), seed=0):
    """A synthetic gait: during stance the calf's absolute pitch sweeps from attack to detach."""
    rng = np.random.default_rng(seed)
    rate, period, duty = 1000, 0.25, 0.4
    t = np.arange(int(strides * period * rate)) / rate
    phase = (t / period) % 1.0
    stance = phase < duty
    sweep = np.where(stance, attack + (detach - attack) * phase / duty, 0.3 * np.sin(2 * np.pi * phase))
    cols = {"time": t, "pitch": np.full_like(t, pitch)}
    for leg in legs:
        knee = -1.2 + 0.01 * rng.normal(size=t.size)
        cols[f"{leg}_KFE"] = knee
        cols[f"{leg}_HFE"] = sweep - pitch - knee  # so that pitch + hip + knee = sweep
        cols[f"{leg}_contact"] = stance.astype(float)
    return cols


def test_angles_from_a_gait_log():
    cols = gait()
    a = contact_angles(cols, ["RR"], margin_deg=5)
    theta = cols["pitch"] + cols["RR_HFE"] + cols["RR_KFE"]
    stance = cols["RR_contact"] > 0.5
    last_of_stance = np.flatnonzero(stance[:-1] & ~stance[1:])[1:]  # last samples of the complete stances
    assert a.strides == 5  # the log starts in stance: that first stride is incomplete and left out
    assert a.attack == pytest.approx(-0.40, abs=1e-9)
    assert a.detach == pytest.approx(theta[last_of_stance].mean(), abs=1e-12)
    assert 0.43 < a.detach <= 0.45
    # the foot must cover the highest angle of any stance, plus the margin
    assert a.high == pytest.approx(theta[last_of_stance].max() + math.radians(5), abs=1e-9)
    assert a.low == pytest.approx(-0.40 - math.radians(5), abs=1e-9)
    assert a.attack_spread == pytest.approx(0.0, abs=1e-12)
    assert a.to_dict()["coverage"] == pytest.approx(a.high - a.low)


def test_given_angles_and_their_errors():
    a = given_angles(-30, 25, 5)
    assert (math.degrees(a.low), math.degrees(a.high)) == pytest.approx((-35, 30))
    with pytest.raises(SpecError, match="must come before detach"):
        given_angles(25, -30)
    with pytest.raises(SpecError, match="covers less than 180 deg"):
        given_angles(-85, 100, 5)


def test_gait_log_errors():
    cols = gait()
    del cols["RR_KFE"]
    with pytest.raises(DynoDataError, match="column 'RR_KFE' missing"):
        contact_angles(cols, ["RR"])
    cols = gait()
    cols["RR_contact"] = np.zeros_like(cols["time"])
    with pytest.raises(DynoDataError, match="no complete stance"):
        contact_angles(cols, ["RR"])


def test_gait_logs_that_would_give_a_wrong_foot_are_refused():
    cols = gait()
    cols["pitch"] = cols["pitch"].astype(object)
    cols["pitch"][7] = "abc"
    with pytest.raises(DynoDataError, match="column 'pitch' data row 8 is 'abc', expected a number"):
        contact_angles(cols, ["RR"])
    with pytest.raises(SpecError, match="--margin: found -5"):
        contact_angles(gait(), ["RR"], margin_deg=-5)
    flipped = {k: (-v if k != "RR_contact" and k != "time" else v) for k, v in gait().items()}
    with pytest.raises(DynoDataError, match="falls through stance.*negate pitch, HFE and KFE"):
        contact_angles(flipped, ["RR"])
    degrees = {k: (np.degrees(v) if k not in ("RR_contact", "time") else v) for k, v in gait().items()}
    with pytest.raises(SpecError, match="looks like degrees"):
        contact_angles(degrees, ["RR"])
