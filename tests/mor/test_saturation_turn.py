"""hound_id.mor.clip_turn: how far the coupled clip turns a coupled group's joint-torque vector.

The statistics are checked against closed forms built by hand, not against the module's own formula: for the
hollow-shaft hip/knee, A = [[1/G_h, 0], [-1/(G_h G_k), 1/G_k]], the knee motor torque is tau_k / G_k and
tau_j = A^-T tau_m gives tau_h = G_h tau_m,h + tau_m,k, tau_k = G_k tau_m,k. Clipping the knee motor to L moves
the knee torque to G_k L and the hip torque by d = L - tau_k / G_k: the turn is the difference of the two polar
angles atan2(k, h), and the hip grows by |h + d| - |h|.
"""

import math

import numpy as np
import pytest
import torch

import hound_id.mor.clip_turn as ct
from hound_id.errors import SaturationError
from hound_id.mor.clip_turn import ANGLE_FLOOR, TurnTally, clip_turn, joint_groups
from hound_id.mor.robot import load_robot
from hound_id.mor.saturation import coupled_groups, per_joint_clip, saturation_for
from tests.conftest import ROBOT

GH, GK = 7.5, 6.0
A2 = np.array([[1 / GH, 0.0], [-1 / (GH * GK), 1 / GK]])
NAMES, MOTORS = ("hip", "knee"), ("hip_motor", "knee_motor")


def polar_turn(a, b):
    """Angle between 2-vectors [deg] from their polar angles (independent of the module's formula)."""
    d = np.arctan2(b[:, 1], b[:, 0]) - np.arctan2(a[:, 1], a[:, 0])
    return np.degrees(np.abs((d + np.pi) % (2 * np.pi) - np.pi))


def knee_clip(tau, limit):
    """Clip the knee motor alone to [-limit, limit], by hand: (tau_sat, d)."""
    tm_k = tau[:, 1] / GK
    d = np.clip(tm_k, -limit, limit) - tm_k
    return np.column_stack([tau[:, 0] + d, tau[:, 1] + GK * d]), d


def turn2(tau, sat, **kw):
    return clip_turn(tau, sat, A2, coupled_groups(A2), NAMES, MOTORS, **kw)


def test_hand_built_hollow_shaft_knee_clips_match_the_closed_form():
    rng = np.random.default_rng(16)
    tau = rng.uniform(-120.0, 120.0, (4000, 2))
    limit = 10.0  # knee motor torque limit [N m]: |tau_k| > 60 N m clips
    sat, d = knee_clip(tau, limit)
    result = turn2(tau, sat).groups
    assert len(result) == 1
    g = result[0]
    clipped = np.abs(d) > 0
    angles = polar_turn(tau, sat)[clipped]
    assert g.name == "hip+knee" and g.rows == 4000 and g.clipped == int(clipped.sum()) > 1000
    assert g.angle.count == g.clipped and g.below_floor == 0
    assert g.angle.median == pytest.approx(np.median(angles), abs=1e-9)
    assert g.angle.p95 == pytest.approx(np.quantile(angles, 0.95), abs=1e-9)
    assert g.angle.max == pytest.approx(angles.max(), abs=1e-9)
    growth = (np.abs(tau[:, 0] + d) - np.abs(tau[:, 0]))[clipped]
    assert g.grew.rows == int((growth > ANGLE_FLOOR).sum()) > 0
    assert g.grew.max == pytest.approx(growth.max(), abs=1e-12)
    assert g.grew.joints == (g.grew.rows, 0)  # a knee clip shortens the knee torque, never lengthens it
    # every clip here is the knee motor alone
    (pattern,) = g.patterns
    assert pattern.motors == ("knee_motor",) and pattern.rows == g.clipped and pattern.angle == g.angle


def test_a_hip_grows_exactly_when_the_knee_motors_share_opposes_it():
    # h = 20, k = 90: knee motor 15 N m clipped to 10 (d = -5): the hip torque 20 -> 15 shrinks;
    # h = -20: -20 -> -25 grows by 5 N m; the turn is known in closed form.
    tau = np.array([[20.0, 90.0], [-20.0, 90.0]])
    sat, d = knee_clip(tau, 10.0)
    assert np.allclose(sat, [[15.0, 60.0], [-25.0, 60.0]])
    g = turn2(tau, sat).groups[0]
    assert g.grew.rows == 1 and g.grew.max == pytest.approx(5.0)
    expected = polar_turn(tau, sat)
    assert expected[1] == pytest.approx(math.degrees(math.atan2(60, -25) - math.atan2(90, -20)))
    assert g.angle.max == pytest.approx(expected.max()) and g.angle.median == pytest.approx(expected.mean())


def test_uncoupled_joints_are_no_group_and_the_sample_has_four_hip_knee_groups():
    A = np.diag([1 / 9.0, -1 / 7.5, 1 / 6.0])
    assert joint_groups(coupled_groups(A)) == ()
    tau = np.array([[100.0, -50.0, 30.0]])
    assert clip_turn(tau, tau * 0.5, A, coupled_groups(A), ("a", "b", "c"), ("ma", "mb", "mc")).groups == ()
    sat = saturation_for(load_robot(ROBOT))
    groups = joint_groups(coupled_groups(sat.A))
    assert [tuple(sat.joints[j] for j in joints) for joints, _ in groups] == [
        (f"{leg}_HFE", f"{leg}_KFE") for leg in ("FL", "FR", "RL", "RR")
    ]
    # a per-joint clip of an uncoupled joint only scales it: the HAA joints are exactly the coupled clip's
    rng = np.random.default_rng(3)
    tau, qd = rng.uniform(-200, 200, (500, 12)), rng.uniform(-30, 30, (500, 12))
    haa = [sat.joints.index(f"{leg}_HAA") for leg in ("FL", "FR", "RL", "RR")]
    assert np.allclose(per_joint_clip(sat, tau, qd)[:, haa], sat(tau, qd)[:, haa], rtol=1e-12, atol=1e-12)


def test_a_group_with_no_clip_reports_zero():
    tau = np.random.default_rng(1).uniform(-50, 50, (300, 2))
    g = turn2(tau, tau.copy(), tau_ref=tau.copy()).groups[0]
    assert (g.clipped, g.below_floor, g.grew.rows, g.grew.max, g.patterns) == (0, 0, 0, 0.0, ())
    assert (g.angle.count, g.angle.median, g.angle.p95, g.angle.max) == (0, 0.0, 0.0, 0.0)
    assert g.reference is not None and (g.reference.rows, g.reference.difference_max) == (0, 0.0)
    assert turn2(tau, tau).scalars()["clip_turn/hip+knee/angle_max_deg"] == 0.0


def test_the_floor_keeps_near_zero_vectors_and_tiny_growth_out():
    # row 0: a real clip; row 1: clipped to almost nothing (a 1e-4 N m vector has no direction worth a number);
    # row 2: the hip grows by 5 mN m only
    tau = np.array([[20.0, 90.0], [3.0, 0.002], [-1.0, 90.0]])
    sat = tau.copy()
    sat[0], sat[1], sat[2] = knee_clip(tau[:1], 10.0)[0][0], [1e-4, 0.0], [-1.005, 89.97]
    g = turn2(tau, sat).groups[0]
    assert g.clipped == 3 and g.angle.count == 2 and g.below_floor == 1
    assert g.grew.rows == 0  # 5 mN m is under the 10 mN m floor
    g0 = turn2(tau, sat, floor=0.0).groups[0]
    assert g0.angle.count == 3 and g0.below_floor == 0 and g0.grew.rows == 1
    assert g0.grew.max == pytest.approx(0.005)
    assert g0.angle.max == pytest.approx(polar_turn(tau, sat).max())
    zero = turn2(tau[:1], np.zeros((1, 2))).groups[0]
    assert zero.clipped == 1 and zero.below_floor == 1 and zero.angle.count == 0  # no NaN, no warning
    with pytest.raises(SaturationError, match="floor"):
        turn2(tau, sat, floor=-1.0)


def test_float32_rounding_of_an_untouched_motor_is_not_a_clip():
    rng = np.random.default_rng(7)
    tau = rng.uniform(-120.0, 120.0, (2000, 2))
    sat, d = knee_clip(tau, 10.0)
    g64 = turn2(tau, sat).groups[0]
    g32 = turn2(tau.astype(np.float32), sat.astype(np.float32)).groups[0]
    assert [p.motors for p in g32.patterns] == [("knee_motor",)]  # the hip motor did not clip
    assert g32.clipped == g64.clipped
    assert g32.angle.max == pytest.approx(g64.angle.max, abs=1e-3)


def test_streamed_batches_equal_one_batch_and_the_histogram_stays_within_a_bin(monkeypatch):
    rng = np.random.default_rng(9)
    tau = rng.uniform(-120.0, 120.0, (6000, 2))
    sat, _ = knee_clip(tau, 10.0)
    whole = turn2(tau, sat)
    tally = TurnTally(A2, coupled_groups(A2), NAMES, MOTORS)
    for part in np.array_split(np.arange(6000), 7):
        tally.add(tau[part], sat[part])
    assert tally.result() == whole
    monkeypatch.setattr(ct, "EXACT_ANGLES", 100)  # past it: the 0.01 deg histogram
    binned = TurnTally(A2, coupled_groups(A2), NAMES, MOTORS)
    for part in np.array_split(np.arange(6000), 7):
        binned.add(tau[part], sat[part])
    a, b = binned.result().groups[0].angle, whole.groups[0].angle
    assert a.count == b.count and a.max == b.max
    assert a.median == pytest.approx(b.median, abs=ct.ANGLE_BIN) and a.p95 == pytest.approx(b.p95, abs=ct.ANGLE_BIN)


def test_per_joint_reference_statistics():
    rng = np.random.default_rng(11)
    tau = rng.uniform(-120.0, 120.0, (3000, 2))
    sat, d = knee_clip(tau, 10.0)
    ref = np.column_stack([np.clip(tau[:, 0], -75, 75), np.clip(tau[:, 1], -60, 60)])  # a box clip
    violation = np.zeros_like(tau)
    violation[:5, 1] = [0.5, 2.0, 0.0, 0.0, 1e-12]
    r = turn2(tau, sat, tau_ref=ref, ref_violation=violation).groups[0].reference
    changed = np.any(ref != tau, axis=1)
    acted = changed | (np.abs(d) > 0)
    diff = np.hypot(*(sat - ref).T)
    assert r.clipped == int(changed.sum()) and r.rows == int(acted.sum())
    assert r.angle.median == pytest.approx(np.median(polar_turn(tau, ref)[changed]), abs=1e-9)
    assert r.difference_max == pytest.approx(diff[acted].max()) and r.difference_mean == pytest.approx(
        diff[acted].mean()
    )
    assert r.differs == int((diff[acted] > ANGLE_FLOOR).sum())
    assert (r.outside, r.outside_max) == (2, 2.0)  # 1e-12 N m is rounding


def test_torch_gives_what_numpy_gives():
    rng = np.random.default_rng(13)
    tau = rng.uniform(-120.0, 120.0, (512, 2))
    sat, _ = knee_clip(tau, 10.0)
    ref = np.clip(tau, -60, 60)
    expected = turn2(tau, sat, tau_ref=ref, ref_violation=np.abs(ref) * 0)
    got = turn2(torch.tensor(tau), torch.tensor(sat), tau_ref=torch.tensor(ref), ref_violation=torch.zeros(512, 2))
    assert got.to_dict() == approx_tree(expected.to_dict())


def approx_tree(x):
    """pytest.approx for every float of a nested dict/list (torch and numpy round a few operations apart)."""
    if isinstance(x, dict):
        return {k: approx_tree(v) for k, v in x.items()}
    if isinstance(x, list):
        return [approx_tree(v) for v in x]
    return pytest.approx(x, rel=1e-12, abs=1e-12) if isinstance(x, float) else x
