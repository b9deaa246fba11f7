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


def test_a_peak_torque_needs_a_significant_saturation_term():
    """A log whose current stays far below saturation: the quadratic term is not significant, so the peak torque is a
    bound (the 20 % point with k_sat at its upper 95 % limit), never a number; the same log driven into saturation
    gives a number."""
    from dataclasses import replace

    from hound_id.dyno.current.curve import SATURATION_SIGMAS
    from hound_id.dyno.current.effects import Signals
    from hound_id.dyno.logs import log_from_frame
    from hound_id.dyno.simulate.current import TestPlan, simulate

    plan = replace(TestPlan(), overdrive=0.1, hold_time=0.0)  # a tenth of the current where the curve bends 20 %
    low = simulate(("linear", "saturation"), plan=plan, seed=2, noise_std=0.1)
    log = log_from_frame(low.frame, source="low")
    signals, torque = Signals.from_log(log), log.torque
    fit = fit_model(signals, torque, ("linear", "saturation"))
    k = fit.parameters["k_sat"]
    assert not (abs(k.value) >= SATURATION_SIGMAS * k.stderr and not k.at_bound)
    i_max = float(np.abs(signals.current).max())
    peak = peak_torque(fit, i_max)
    assert peak.torque is None and peak.current is None and not peak.extrapolated
    assert peak.note.startswith(f"no saturation seen up to {i_max:.3g} A")
    tau_b, i_b = peak.at_least
    kt, k_up = fit.value("kt"), k.value + SATURATION_SIGMAS * k.stderr
    assert i_b == pytest.approx(0.2 * kt / k_up, rel=2e-3) and tau_b == pytest.approx(0.8 * kt * i_b, rel=2e-3)
    assert peak.to_dict()["at_least"] == {"torque": tau_b, "current": i_b}

    signals, torque, _ = simulated(("linear", "saturation"), 3)
    full = peak_torque(fit_model(signals, torque, ("linear", "saturation")), float(np.abs(signals.current).max()))
    assert full.torque is not None and full.at_least is None


def test_a_saturation_term_held_at_its_bound_does_not_hide_the_next_one():
    """The quadratic term wants a negative value (held at zero), the cubic one is far from zero: saturation is seen,
    and the peak torque is a number, not 'no saturation seen'."""
    from hound_id.dyno.current.effects import Signals

    rng = np.random.default_rng(3)
    t = np.arange(0.0, 60.0, 1.0 / 200.0)
    i = 20.0 * np.sin(2 * np.pi * 0.2 * t)
    signals = Signals(time=t, current=i, velocity=2.0 * np.sin(2 * np.pi * 0.07 * t))
    torque = 1.0 * i + 0.002 * i * np.abs(i) - 0.0004 * i**3 + rng.normal(0, 0.03, t.size)
    fit = fit_model(signals, torque, ("linear", "saturation", "saturation_cubic"))
    assert fit.parameters["k_sat"].at_bound and fit.parameters["k_sat3"].value > 10 * fit.parameters["k_sat3"].stderr
    peak = peak_torque(fit, float(np.abs(i).max()))
    assert peak.torque is not None and not peak.note.startswith("no saturation seen"), peak.note
