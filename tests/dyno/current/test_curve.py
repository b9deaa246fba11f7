import numpy as np
import pytest

from hound_id.dyno.current.curve import compensation, curve_torque, fitted_curve, peak_torque
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


def test_the_quadratic_fit_gets_its_closed_form_inverse():
    signals, torque, _ = simulated(("linear", "saturation"), 3)
    fit = fit_model(signals, torque, ("linear", "saturation"))
    curve = fitted_curve(fit, float(np.abs(signals.current).max()))
    assert curve.form == "quadratic" and curve.k_sat == fit.value("k_sat") and curve.kt == fit.value("kt")
    i = np.linspace(-1.5, 1.5, 301) * float(np.abs(signals.current).max())
    assert curve.current(curve_torque(fit, i)) == pytest.approx(i, rel=1e-12, abs=1e-12)
    # the odd polynomial stays an option: its slope at zero torque misses 1/Kt (it cannot follow tau|tau|)
    comp = compensation(fit, peak_torque(fit, float(np.abs(signals.current).max())).current)
    assert abs(comp.slope_error) > 0.01 and comp.slope_error == pytest.approx(comp.coefficients[0] * curve.kt - 1)


def test_a_cubic_fit_gets_a_table_curve_with_its_error():
    signals, torque, _ = simulated(("linear", "saturation_cubic"), 3)
    fit = fit_model(signals, torque, ("linear", "saturation_cubic"))
    top = float(np.abs(signals.current).max())
    curve = fitted_curve(fit, top)
    assert curve.form == "table" and curve.torques is not None and curve.currents is not None
    # the table ends where the cubic stops rising, Kt - 3 k i^2 = 0, or at ten times the measured current
    kt, k3 = fit.value("kt"), fit.value("k_sat3")
    assert curve.top_current == pytest.approx(min(np.sqrt(kt / (3 * k3)), 10 * top), rel=2e-3)
    # its inverse error, measured here at points between the table's, is within what it states, and small
    i = np.linspace(0.0, curve.top_current, 5001)
    err = np.max(np.abs(curve.current(curve_torque(fit, i)) - i))
    assert err <= curve.table_error * 1.5 + 1e-9 and curve.table_error < 0.01
