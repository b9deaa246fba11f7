"""hound_id.mor.friction: the friction terms a trainer feels, their torque, their size, where exports hold them."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from hound_id.mor.friction import EPS_SPEED, TERMS, parameters


def test_the_registry_is_sorted_and_its_parameters_are_unique():
    assert list(TERMS) == sorted(TERMS)
    names = [name for name, _, _ in parameters()]
    assert len(names) == len(set(names))
    for term in TERMS.values():
        assert term.homes.get("bundle"), f"{term.name}: the bundle (the runtime) holds every term"


@given(
    st.floats(-2000.0, 2000.0),
    st.floats(0.0, 5.0),
    st.floats(0.0, 100.0),
    st.floats(0.05, 50.0),
)
def test_every_term_opposes_the_motion(w, value, load, speed):
    """Friction dissipates: each term's torque times the speed is never positive, for every parameter >= 0."""
    w_arr = np.array([w])
    for term in TERMS.values():
        p = {name: (speed if name == "stribeck_speed" else value) for name, _, _ in term.parameters}
        f = term.torque(p, w_arr, np.tanh(w_arr / EPS_SPEED), np.array([load]), np.exp)
        assert float(f[0] * w) <= 0.0


@pytest.mark.parametrize("name", sorted(TERMS))
def test_the_largest_torque_an_export_loses_is_what_a_scan_finds(name):
    """``largest`` (what an export that cannot hold a term states) is the most the term makes over speeds up to
    the top speed and currents up to the torque limit's: a scan never passes it and reaches it within 2 % (the smooth
    sign keeps the static friction's peak 1.5 % below f_s at a Stribeck speed of 0.3 rad/s)."""
    term = TERMS[name]
    p = {n: (0.3 if n == "stribeck_speed" else 0.07) for n, _, _ in term.parameters}
    limit_current, top = 40.0, 500.0
    w = np.linspace(-top, top, 400_001)
    most = 0.0
    for load in np.linspace(0.0, limit_current, 9):
        f = term.torque(p, w, np.tanh(w / EPS_SPEED), np.full_like(w, load), np.exp)
        most = max(most, float(np.max(np.abs(f))))
    stated = term.largest(p, limit_current, top)
    assert most <= stated * (1 + 1e-12)
    assert most >= 0.98 * stated
