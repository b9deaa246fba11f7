import numpy as np
import pytest

from hound_id.dyno.current.curve import compensation, curve_torque, peak_torque
from hound_id.dyno.current.fit import fit_model
from tests.dyno.conftest import simulated


def test_peak_torque_of_the_quadratic_curve():
    signals, torque, sim = simulated(("linear", "saturation"), 3)
    fit = fit_model(signals, torque, ("linear", "saturation"))
    kt, k = fit.value("kt"), fit.value("k_sat")
    # (kt i - (kt i - k i^2)) / (kt i) = k i / kt = 0.2
    i_peak = 0.2 * kt / k
    peak = peak_torque(fit, float(np.abs(signals.current).max()))
    assert peak.current == pytest.approx(i_peak, rel=1e-6)
    assert peak.torque == pytest.approx(0.8 * kt * i_peak, rel=1e-6)
    # the simulator's truth: 20 % drop at max_current
    assert peak.current == pytest.approx(sim.motor.max_current, rel=0.02)
    assert not peak.extrapolated


def test_compensation_inverts_the_curve():
    signals, torque, _ = simulated(("linear", "saturation"), 3)
    fit = fit_model(signals, torque, ("linear", "saturation"))
    peak = peak_torque(fit, float(np.abs(signals.current).max()))
    comp = compensation(fit, peak.current)
    i = np.linspace(-peak.current, peak.current, 101)
    assert np.max(np.abs(comp.current(curve_torque(fit, i)) - i)) <= comp.max_error * 1.0001
    assert comp.max_error < 0.005 * peak.current
    assert comp.powers == (1, 3, 5)


def test_no_saturation_no_peak():
    signals, torque, _ = simulated(("linear", "saturation"), 3)
    fit = fit_model(signals, torque, ("linear",))
    peak = peak_torque(fit, float(np.abs(signals.current).max()))
    if peak.torque is None:
        assert "add a saturation effect" in peak.note
    else:  # a linear fit of saturated data can still bend only through other shape terms: none here
        raise AssertionError("a linear-only model cannot have a 20 % point")
