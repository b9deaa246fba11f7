import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from hound_id.errors import TransmissionError
from hound_id.mor.transmission import from_matrix, from_ratios, hollow_shaft

finite = st.floats(-50, 50, allow_nan=False)


@st.composite
def invertible(draw, k=None):
    k = k or draw(st.integers(1, 4))
    A = draw(arrays(float, (k, k), elements=st.floats(-2, 2)))
    A = A + np.eye(k) * draw(st.floats(0.05, 1.0)) * (1 + k)  # diagonally dominant enough
    if np.linalg.cond(A) > 1e6:
        A = np.eye(k) * 0.1
    return A


@settings(max_examples=300, deadline=None)
@given(invertible(), st.data())
def test_power_balance(A, data):
    k = A.shape[0]
    tx = from_matrix([f"j{i}" for i in range(k)], [f"m{i}" for i in range(k)], A)
    tau_j = data.draw(arrays(float, (k,), elements=finite))
    qd = data.draw(arrays(float, (k,), elements=finite))
    tau_m, thetad = tx.motor_torque(tau_j), tx.motor_velocity(qd)
    assert float(tau_m @ thetad) == pytest.approx(float(tau_j @ qd), rel=1e-9, abs=1e-9)
    # and the maps are inverses
    assert np.allclose(tx.joint_torque(tau_m), tau_j, atol=1e-9)
    assert np.allclose(tx.joint_velocity(thetad), qd, atol=1e-9)


def test_the_papers_inverse_transpose_does_not_conserve_power():
    tx = hollow_shaft(["hfe", "kfe"], ["mh", "mk"], 7.5, 7.5)
    tau_j, qd = np.array([40.0, 30.0]), np.array([10.0, -5.0])
    paper_tau_m = np.linalg.inv(tx.A).T @ tau_j
    paper_power = paper_tau_m @ tx.motor_velocity(qd)
    assert abs(paper_power - tau_j @ qd) > 10 * abs(tau_j @ qd)  # off by a factor of ~G^2
    assert tx.motor_torque(tau_j) @ tx.motor_velocity(qd) == pytest.approx(tau_j @ qd)


def test_hollow_shaft_kinematics():
    gh, gk = 7.0, 11.0
    tx = hollow_shaft(["hfe", "kfe"], ["mh", "mk"], gh, gk)
    assert np.allclose(tx.A, [[1 / gh, 0], [-1 / (gh * gk), 1 / gk]])
    # the knee motor also turns with the hip
    assert np.allclose(tx.A_inv, [[gh, 0], [1, gk]])
    assert np.allclose(tx.motor_velocity([1.0, 0.0]), [gh, 1.0])
    assert tx.coupled


def test_reflected_inertia():
    tx = from_ratios(["j"], ["m"], [9.0])
    assert tx.reflected_inertia([2e-4]) == pytest.approx(2e-4 * 81)
    assert not tx.coupled
    hs = hollow_shaft(["h", "k"], ["mh", "mk"], 7.0, 11.0)
    J = np.array([1e-4, 2e-4])
    qd = np.array([3.0, -2.0])
    thetad = hs.motor_velocity(qd)
    # kinetic energy of the rotors is the same in both spaces
    assert 0.5 * qd @ hs.reflected_inertia(J) @ qd == pytest.approx(0.5 * thetad @ (J * thetad))


def test_batched_maps():
    tx = hollow_shaft(["h", "k"], ["mh", "mk"], 7.0, 11.0)
    batch = np.random.default_rng(0).normal(size=(5, 3, 2))
    assert tx.motor_torque(batch).shape == (5, 3, 2)
    assert np.allclose(tx.motor_torque(batch)[2, 1], tx.A.T @ batch[2, 1])


@pytest.mark.parametrize(
    ("build", "match"),
    [
        (lambda: from_matrix(["a", "b"], ["x", "y"], [[1, 2], [2, 4]]), "singular"),
        (lambda: from_matrix(["a"], ["x", "y"], [[1]]), "one motor per joint"),
        (lambda: from_matrix(["a", "b"], ["x", "y"], [[1, 2, 3]]), "square"),
        (lambda: from_matrix(["a"], ["x"], [["fast"]]), "not numeric"),
        (lambda: from_ratios(["a"], ["x"], [0.0]), "non-zero"),
        (lambda: hollow_shaft(["a", "b"], ["x", "y"], 0.0, 3.0), "non-zero"),
    ],
)
def test_bad_transmissions(build, match):
    with pytest.raises(TransmissionError, match=match):
        build()
