"""The winding's heat (hound_id/mor/thermal.py, hound_id/mor/heat.py): the thermal model against an independent
integrator, the clip at a temperature against a brute-force scan of the phase equations written out here, the
runtime's temperature state against the closed form, and the spec's thermal fields."""

import dataclasses
import math

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from hound_id import runtime
from hound_id.errors import HoundIdError, SaturationError
from hound_id.export.bundle import build_bundle
from hound_id.mor.heat import continuous_point, heat, hot_spec
from hound_id.mor.region import operating_region, torque_interval
from hound_id.mor.robot import load_robot
from hound_id.mor.saturation import saturation_for
from hound_id.mor.spec_sheet import load_motor_spec, motor_spec_from_mapping
from hound_id.mor.thermal import COPPER, LOSS_FACTOR, REFERENCE, Thermal
from hound_id.units import to_celsius
from tests.conftest import MOTOR, ROBOT, run_cli

SPEC = load_motor_spec(MOTOR)
TH = SPEC.thermal
ROBOT_ = load_robot(ROBOT)
SAT = saturation_for(ROBOT_)


def thermal(**changes):
    return dataclasses.replace(TH, **changes)


def test_the_sample_states_a_thermal_model_and_its_figures():
    assert TH is not None and TH.resistance == 2.0 and TH.time_constant == 120.0
    assert (TH.ambient, TH.derate_start, TH.winding_limit) == (25.0, 100.0, 120.0)
    assert TH.alpha_resistance == COPPER and TH.alpha_kt == pytest.approx(-0.0011)
    # the copper loss of field-oriented control: 3/2 R_ph i^2 with R = sqrt(3) R_ph
    assert TH.copper_loss == pytest.approx(1.5 * (SPEC.resistance / math.sqrt(3.0)))
    # continuous current at the limit: (T_lim - T_amb) = c R(T_lim) R_th I^2
    i_c = TH.continuous_current()
    assert TH.copper_loss * (1 + COPPER * 100) * TH.resistance * i_c**2 == pytest.approx(95.0)
    assert i_c == pytest.approx(19.88, abs=0.01)
    assert TH.time_to(100.0, 70.0) == pytest.approx(9.511, abs=1e-3)
    assert TH.runaway_current == pytest.approx(38.41, abs=0.01)


@settings(max_examples=40, deadline=None)
@given(
    amps=st.floats(0.0, 60.0),
    r_th=st.floats(0.3, 5.0),
    tau=st.floats(5.0, 600.0),
    start=st.floats(0.0, 90.0),
)
def test_the_closed_form_is_the_ode_integrated_independently(amps, r_th, tau, start):
    """scipy's Runge-Kutta on C dT/dt = c R20 (1 + a (T - 20)) i^2 - (T - T_amb) / R_th, the textbook form."""
    th = thermal(resistance=r_th, time_constant=tau)
    c = tau / r_th

    def rhs(_t, y):
        return [(th.copper_loss * (1 + COPPER * (y[0] - REFERENCE)) * amps**2 - (y[0] - th.ambient) / r_th) / c]

    horizon = 3.0 * tau
    sol = solve_ivp(rhs, (0.0, horizon), [start], rtol=1e-10, atol=1e-10, dense_output=True)
    for t in (0.1 * tau, tau, horizon):
        exact = float(sol.sol(t)[0])
        assert float(th.step(np.array(start), amps, t)) == pytest.approx(exact, rel=1e-7, abs=1e-7)
        many = np.array(start)
        for _ in range(50):
            many = th.step(many, amps, t / 50)
        assert float(many) == pytest.approx(exact, rel=1e-7, abs=1e-7)  # exact steps compose
    target = start + 0.5 * (min(float(sol.sol(horizon)[0]), 500.0) - start)
    if target > start + 1e-3:
        t_hit = th.time_to(target, amps, start)
        assert float(sol.sol(t_hit)[0]) == pytest.approx(target, abs=1e-6)


def test_steady_state_runaway_and_a_continuous_current_given_instead_of_r_th():
    assert TH.steady(TH.continuous_current()) == pytest.approx(TH.winding_limit)
    assert math.isinf(TH.steady(TH.runaway_current * 1.01))
    assert TH.time_to(500.0, 10.0) == math.inf  # 10 A never gets there
    text = MOTOR.read_text().replace("thermal_resistance: 2.0 K/W", f"continuous_current: {TH.continuous_current()} A")
    spec = motor_spec_from_mapping(_yaml(text), "m.yaml")
    assert spec.thermal.resistance == pytest.approx(2.0, rel=1e-12)


def _yaml(text):
    import yaml

    return yaml.safe_load(text)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (("thermal_time_constant: 120 s", ""), "field 'thermal_time_constant': missing; the thermal model"),
        (("thermal_resistance: 2.0 K/W", ""), "field 'thermal_resistance': missing; the thermal model needs"),
        (("thermal_resistance: 2.0 K/W", "thermal_resistance: 2.0 K/W\ncontinuous_current: 20 A"), "give only one"),
        (("winding_limit: 120 degC", "winding_limit: 393"), "393 degC, expected 40 to 250 degC; a plain number"),
        (("ambient_temperature: 25 degC", "ambient_temperature: 298"), "field 'ambient_temperature'"),
        (("winding_limit: 120 degC", "winding_limit: -300 degC"), "below absolute zero"),
        (("ambient_temperature: 25 degC", "ambient_temperature: 25 degC\nderate_start: 20 degC"), "derate_start"),
        (("winding_limit: 120 degC", "winding_limit: hot"), "expected a temperature"),
        (("ambient_temperature: 25 degC", "ambient_temperature: 25 degC\nderate_start: 130 degC"), "derate_start"),
        (("ambient_temperature: 25 degC", "ambient_temperature: 25 degC\nkt_temperature_coefficient: -11"), "%/K"),
        (("thermal_resistance: 2.0 K/W", "thermal_resistance: 2.0 ohm"), "thermal resistance"),
    ],
)
def test_a_bad_thermal_field_is_one_clear_line(edit, message):
    text = MOTOR.read_text().replace(*edit)
    with pytest.raises(HoundIdError, match=message):
        motor_spec_from_mapping(_yaml(text), "m.yaml")


def test_a_winding_limit_not_above_the_ambient_is_refused():
    text = MOTOR.read_text().replace("winding_limit: 120 degC", "winding_limit: 60 degC")
    text = text.replace("ambient_temperature: 25 degC", "ambient_temperature: 70 degC")
    with pytest.raises(HoundIdError, match="60 degC is not above the ambient 70 degC"):
        motor_spec_from_mapping(_yaml(text), "m.yaml")


def test_temperatures_read_in_any_unit():
    assert to_celsius("393.15 K") == pytest.approx(120.0)
    assert to_celsius("248 degF") == pytest.approx(120.0)
    assert to_celsius(120) == 120.0 and to_celsius("120 °C") == 120.0 and to_celsius("120 celsius") == 120.0
    text = MOTOR.read_text().replace("thermal_resistance: 2.0 K/W", "thermal_resistance: 2 °C/W")
    text = text.replace(
        "ambient_temperature: 25 degC", "ambient_temperature: 25 degC\nkt_temperature_coefficient: -0.1 %/°C"
    )
    spec = motor_spec_from_mapping(_yaml(text), "m.yaml")  # datasheets' per-degree units: a difference of 1 degC is 1 K
    assert spec.thermal.resistance == 2.0 and spec.thermal.alpha_kt == pytest.approx(-0.001)


def test_a_warm_ambient_moves_the_default_derating_start_and_a_small_drive_never_derates(tmp_path):
    import json

    text = MOTOR.read_text().replace("ambient_temperature: 25 degC", "ambient_temperature: 80 degC")
    text = text.replace("winding_limit: 120 degC", "winding_limit: 95 degC")
    assert motor_spec_from_mapping(_yaml(text), "m.yaml").thermal.derate_start == 80.0  # not below the ambient
    small = tmp_path / "small.yaml"
    small.write_text(MOTOR.read_text().replace("max_current: 70 A ", "max_current: 15 A "))
    out = run_cli("mor", "--spec", str(small), "--json")
    assert out.returncode == 0, out.stderr
    h = json.loads(out.stdout, parse_constant=lambda c: pytest.fail(f"{c} is not JSON"))["heat"]
    assert h["time_to_derate"] is None and h["derates"] is False and h["continuous"]["current"] == 15.0
    text_out = run_cli("mor", "--spec", str(small)).stdout
    assert "settles at 71.7 degC, below the derating" in text_out and "inf s" not in text_out


def test_the_fits_kt_drift_is_taken_when_the_spec_gives_none():
    data = _yaml(MOTOR.read_text())
    data["fit"] = {
        "schema": "hound-id/fit/2",
        "model": ["kt", "thermal"],
        "parameters": {
            "kt": {"value": 0.14, "stderr": 1e-4, "unit": "N m/A"},
            "kt_temp_coeff": {"value": -0.14 * 0.0009, "stderr": 1e-6, "unit": "N m/A/K"},
        },
    }
    spec = motor_spec_from_mapping(data, "m.yaml")
    assert spec.thermal.alpha_kt == pytest.approx(-0.0009) and spec.thermal.alpha_kt_source.startswith("fit")


def phase_scan_hot(spec, th, omega, temperature, points=40001):
    """(lowest, highest) torque [N m] the drive holds at ``omega`` with the winding at ``temperature``, from the phase
    equations with i_d = 0: v_q = R_ph(T) i_q + w_e psi(T), v_d = -w_e L i_q, |v| <= V/sqrt(3), |i_q| <= the derated
    limit; torque = Kt(T)/Kt20 x the 20 degC curve at i_q. Written from the physics, not from hound-id's scaling."""
    s_r = 1 + th.alpha_resistance * (temperature - REFERENCE)
    s_k = 1 + th.alpha_kt * (temperature - REFERENCE)
    band = th.winding_limit - th.derate_start
    derate = 1.0 if temperature < th.derate_start else max(0.0, (th.winding_limit - temperature) / band)
    limit = min(spec.limit_current, derate * spec.max_current)
    r_ph = s_r * spec.resistance / math.sqrt(3.0)
    x = spec.pole_pairs * omega * spec.drive.inductance_phase
    e = s_k * omega / (math.sqrt(3.0) * spec.kv)
    i_q = np.linspace(-limit, limit, points)
    ok = (r_ph * i_q + e) ** 2 + (x * i_q) ** 2 <= (spec.bus_voltage / math.sqrt(3.0)) ** 2
    held = i_q[ok]
    if not held.size:
        return None
    curve = spec.current_curve
    return s_k * float(curve.torque(held.min())), s_k * float(curve.torque(held.max())), 2 * limit / (points - 1)


@pytest.mark.parametrize("temperature", [20.0, 60.0, 100.0, 108.0, 116.0])
def test_the_clip_at_a_temperature_is_the_phase_equations_scanned(temperature):
    spec = SPEC
    hip = np.array([[1.0] + [0.0] * 11])
    gear = 1.0 / float(SAT.A[0, 0])  # motor speed per joint speed of motor 0
    for omega in np.linspace(0.0, 1.05 * spec.no_load_speed, 23):
        scan = phase_scan_hot(spec, TH, omega, temperature)
        lo, hi = SAT.torque_bounds(hip * omega / gear, temperature=np.full((1, 1), temperature))
        if scan is None:
            continue  # past control: the diode bridge, checked at 20 degC in test_drive
        slope = spec.kt * 1.0  # N m per A at most
        assert hi[0, 0] == pytest.approx(scan[1], abs=2 * slope * scan[2] + 1e-9)
        assert lo[0, 0] == pytest.approx(scan[0], abs=2 * slope * scan[2] + 1e-9)


@settings(max_examples=60, deadline=None)
@given(temperature=st.floats(-20.0, 130.0), speed=st.floats(-2.0, 2.0), volts=st.floats(66.0, 84.0))
def test_the_clip_at_a_temperature_is_the_region_of_the_warm_spec(temperature, speed, volts):
    omega = speed * SPEC.no_load_speed
    gear = 1.0 / float(SAT.A[0, 0])
    lo, hi = SAT.torque_bounds(
        np.array([[omega / gear] + [0.0] * 11]), bus_voltage=volts, temperature=np.array([[temperature]])
    )
    if TH.derating(temperature) == 0:  # no current: only the diode bridge's braking, or nothing
        assert lo[0, 0] == hi[0, 0]
        return
    warm = dataclasses.replace(hot_spec(SPEC, temperature), bus_voltage=volts)
    want_lo, want_hi = torque_interval(np.array([omega]), operating_region(warm))
    assert lo[0, 0] == pytest.approx(want_lo[0], abs=1e-9) and hi[0, 0] == pytest.approx(want_hi[0], abs=1e-9)


def test_20_degc_changes_nothing_and_numpy_torch_agree():
    rng = np.random.default_rng(5)
    tau, qd = rng.normal(0.0, 80.0, (256, 12)), rng.normal(0.0, 60.0, (256, 12))
    assert np.allclose(SAT(tau, qd, temperature=np.full((256, 1), 20.0)), SAT(tau, qd), atol=1e-12, rtol=0)
    temps = rng.uniform(20.0, 125.0, (256, 12))
    got = SAT(tau, qd, temperature=temps)
    t = SAT(torch.tensor(tau), torch.tensor(qd), temperature=torch.tensor(temps)).numpy()
    assert np.allclose(got, t, atol=1e-10, rtol=0)
    with pytest.raises(SaturationError, match="temperature has shape"):
        SAT(tau, qd, temperature=np.ones(3))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_the_fused_loop_at_a_temperature_is_the_general_path(dtype, monkeypatch):
    """Ordinary commands take the fused loop (numba) with the temperatures; the general path (fresh arrays, numpy's
    steps) gives the same torques to the correction's rounding, NaN where it gives NaN, and so do CPU tensors."""
    rng = np.random.default_rng(9)
    n = 2048
    tau = rng.uniform(-300.0, 300.0, (n, 12)).astype(dtype)
    qd = rng.uniform(-60.0, 60.0, (n, 12)).astype(dtype)
    temps = rng.uniform(-10.0, 130.0, (n, 12)).astype(dtype)
    volts = rng.uniform(66.0, 84.0, (n, 1)).astype(dtype)
    temps[5, 3] = np.nan
    fused = SAT(tau, qd, volts, temps)
    monkeypatch.setenv("HOUND_ID_FUSED", "0")
    general = SAT(tau, qd, volts, temps)
    monkeypatch.delenv("HOUND_ID_FUSED")
    assert np.array_equal(np.isnan(fused), np.isnan(general)) and np.isnan(fused[5]).any()
    tol = 1e-12 if dtype == np.float64 else 2e-4
    assert np.nanmax(np.abs(fused - general)) <= tol * 300
    t = SAT(torch.from_numpy(tau), torch.from_numpy(qd), torch.from_numpy(volts), torch.from_numpy(temps)).numpy()
    assert np.array_equal(t, fused, equal_nan=True)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_the_derated_clip_is_feasible_for_every_state(seed):
    """Every clipped command lies in its motor's interval at that winding temperature (and bus), in float32 too."""
    rng = np.random.default_rng(seed)
    n = 64
    tau = rng.normal(0.0, 10.0 ** rng.uniform(0, 3), (n, 12))
    qd = rng.normal(0.0, 10.0 ** rng.uniform(0, 2.5), (n, 12))
    temps = rng.uniform(-20.0, 140.0, (n, 12))
    volts = rng.uniform(66.0, 84.0, (n, 1))
    for dtype, tol in ((np.float64, 1e-9), (np.float32, 1e-3)):
        out = SAT(tau.astype(dtype), qd.astype(dtype), bus_voltage=volts.astype(dtype), temperature=temps.astype(dtype))
        v = SAT.violation(out, qd.astype(dtype), bus_voltage=volts.astype(dtype), temperature=temps.astype(dtype))
        assert float(np.max(v)) <= tol * (1 + float(np.max(np.abs(out))))
        lo, hi = SAT.torque_bounds(qd.astype(dtype), bus_voltage=volts.astype(dtype), temperature=temps.astype(dtype))
        gone = temps >= TH.winding_limit  # no current left: one torque, the diode bridge's braking (or 0)
        assert np.all(lo[gone] == hi[gone]) and np.all(lo <= hi)


@pytest.fixture(scope="module")
def rt(tmp_path_factory):
    import json

    path = tmp_path_factory.mktemp("bundle") / "b.json"
    path.write_text(json.dumps(build_bundle(ROBOT_).to_dict()))
    return runtime.load(path)


def _hold(rt, dt, seconds, thermal_rows=None):
    temps = np.tile(rt.ambient, (2, 1))
    cmd = np.full((2, rt.n), 1e4)
    qd = np.zeros((2, rt.n))
    trace = []
    for _ in range(int(round(seconds / dt))):
        tau = rt.saturate(cmd, qd, temperature=temps)
        temps = rt.step_temperature(temps, tau, dt)
        trace.append(temps[0].copy())
    return np.array(trace)


def test_a_hold_at_the_peak_current_reaches_the_derating_at_the_closed_form_time_and_settles(rt):
    dt = 1e-3
    trace = _hold(rt, dt, 40.0)
    limit = SPEC.max_current
    t_hit = (np.argmax(trace[:, 0] >= TH.derate_start) + 1) * dt
    assert t_hit == pytest.approx(TH.time_to(TH.derate_start, limit), abs=dt)
    assert trace.max() < TH.winding_limit  # the derating holds the winding below its limit, whatever is commanded
    current, temperature = continuous_point(TH, limit)
    assert trace[-1, 0] == pytest.approx(temperature, abs=0.1)  # settling towards the continuous point
    assert trace[-1, 0] < temperature + 1e-9


def test_without_a_derating_band_the_hold_reaches_the_limit_at_the_closed_form_time():
    text = MOTOR.read_text().replace(
        "ambient_temperature: 25 degC", "ambient_temperature: 25 degC\nderate_start: 120 degC"
    )
    spec = motor_spec_from_mapping(_yaml(text), "m.yaml")
    robot = dataclasses.replace(ROBOT_, motor_specs={k: spec for k in ROBOT_.motor_specs})
    rt = runtime.from_bundle(build_bundle(robot).to_dict())
    dt = 1e-3
    trace = _hold(rt, dt, 14.0)
    t_hit = (np.argmax(trace[:, 0] >= 120.0) + 1) * dt
    assert t_hit == pytest.approx(spec.thermal.time_to(120.0, spec.max_current), abs=dt)
    assert t_hit == pytest.approx(11.777, abs=2e-3)


def test_the_runtime_steps_in_torch_and_float32_like_numpy(rt):
    temps = np.tile(rt.ambient, (3, 1)) + np.array([[0.0], [40.0], [90.0]])
    tau = np.random.default_rng(1).normal(0.0, 20.0, (3, rt.n))
    tau = rt.saturate(tau, np.zeros_like(tau), temperature=temps)
    a = rt.step_temperature(temps, tau, 0.01)
    b = rt.step_temperature(torch.tensor(temps), torch.tensor(tau), 0.01).numpy()
    c = rt.step_temperature(temps.astype(np.float32), tau.astype(np.float32), 0.01)
    assert np.allclose(a, b, atol=1e-10) and c.dtype == np.float32 and np.allclose(a, c, atol=1e-3)
    cool = rt.step_temperature(np.full((1, rt.n), 100.0), np.zeros((1, rt.n)), 1e6)
    assert np.allclose(cool, rt.ambient)  # with no current every winding cools to the ambient


def test_a_bundle_without_a_thermal_model_refuses_a_temperature(tmp_path):
    text = MOTOR.read_text()
    for key in ("thermal_resistance", "thermal_time_constant", "winding_limit", "ambient_temperature"):
        text = "\n".join(line for line in text.splitlines() if not line.startswith(key + ":"))
    text = text.replace(", thermal_resistance, thermal_time_constant, winding_limit, ambient_temperature]", "]")
    spec = motor_spec_from_mapping(_yaml(text), "m.yaml")
    assert spec.thermal is None and heat(spec) is None
    robot = dataclasses.replace(ROBOT_, motor_specs={k: spec for k in ROBOT_.motor_specs})
    rt = runtime.from_bundle(build_bundle(robot).to_dict())
    with pytest.raises(SaturationError, match="no thermal model"):
        rt.step_temperature(np.zeros((1, 12)), np.zeros((1, 12)), 0.01)
    with pytest.raises(SaturationError, match="no motor has a thermal model"):
        rt.saturate(np.zeros((1, 12)), np.zeros((1, 12)), temperature=np.zeros((1, 1)))


def test_mor_prints_and_writes_the_warm_and_continuous_regions(tmp_path):
    import json

    out = run_cli("mor", "--spec", str(MOTOR), "--json")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    h = data["heat"]
    assert h["time_to_derate"] == pytest.approx(9.511, abs=1e-3)
    assert h["continuous"]["current"] == pytest.approx(19.45, abs=0.01)
    assert h["continuous"]["temperature"] == pytest.approx(114.44, abs=0.01)
    assert h["warm"]["torque_limit"] == pytest.approx(SPEC.torque_limit * (1 - 0.0011 * 80), rel=1e-9)
    text = run_cli("mor", "--spec", str(MOTOR), "--plot", str(tmp_path / "r.png"))
    assert text.returncode == 0, text.stderr
    assert (
        "continuous: 19.45 A (peak phase) at 114.4 degC" in text.stdout and "reaches 100 degC in 9.51 s" in text.stdout
    )
    assert (tmp_path / "r.png").stat().st_size > 0


def test_loss_factor_per_commutation():
    assert LOSS_FACTOR["six_step"] == 1.0 and LOSS_FACTOR["foc"] == pytest.approx(math.sqrt(3) / 2)
    assert isinstance(TH, Thermal)


def test_step_temperature_refuses_what_it_cannot_step(rt):
    tau = np.full((4, rt.n), 5.0)
    for bad, message in (
        (np.zeros((4, 13)), r"temperature has shape \(4, 13\); expected tau's \(4, 12\)"),
        (np.zeros((2, 4, 12)), r"temperature has shape \(2, 4, 12\)"),
    ):
        with pytest.raises(SaturationError, match=message):
            rt.step_temperature(bad, tau, 0.01)
    for dt in (-1.0, float("nan"), 0.0):
        with pytest.raises(SaturationError, match="expected a positive, finite time step"):
            rt.step_temperature(np.full((4, 1), 25.0), tau, dt)
    per_env = rt.step_temperature(np.full((4, 1), 25.0), tau, 0.01)
    assert per_env.shape == (4, rt.n)
    assert rt.step_temperature(np.full((4, 1), 25.0), tau.astype(np.float32), 0.01).dtype == np.float64
    mixed = rt.step_temperature(np.full((4, 1), 25.0), torch.tensor(tau), 0.01)
    assert isinstance(mixed, torch.Tensor) and np.allclose(mixed.numpy(), per_env)


def test_the_current_at_a_temperature_follows_the_weaker_flux(rt):
    """i = g20^-1(tau / s_K): a warm motor needs more current for the same torque, and the runtime's current and
    voltage take the temperature."""
    tau = np.full((1, rt.n), 5.0)
    temps = np.full((1, rt.n), 100.0)
    s_k = 1 + TH.alpha_kt * 80.0
    want = SPEC.current_curve.current(5.0 / s_k)
    assert np.allclose(rt.current(tau, temperature=temps), want, rtol=1e-12)
    assert np.all(rt.current(tau, temperature=temps) > rt.current(tau))
    tensor = rt.current(torch.tensor(tau), temperature=torch.tensor(temps)).numpy()
    assert np.allclose(tensor, want, rtol=1e-12)
    qd = np.zeros((1, rt.n))
    cmd = np.full((1, rt.n), 1e3)
    v_cold, v_warm = rt.voltage(cmd, qd), rt.voltage(cmd, qd, temperature=np.full((1, 1), 110.0))
    assert np.all(np.abs(v_warm) < np.abs(v_cold))  # derated to half the current at 110 degC


def test_the_exported_inner_boxes_hold_at_the_lowest_battery_voltage():
    """The joint inner boxes (mor --robot, the bundle, the inner URDF, Isaac Lab) are the boxes every charge holds:
    their corners are feasible at 66 V in every combination of signs, for every coupled group together."""
    from itertools import product

    from hound_id.mor.joint_space import robot_regions

    regions = robot_regions(ROBOT_)
    box = np.array([[j.inner_box.effort for j in regions.joints], [j.inner_box.velocity for j in regions.joints]])
    assert all(v == (66.0,) * len(j.motors) for j in regions.joints for v in [j.inner_box_bus_voltage])
    corners = np.array(list(product([-1.0, 1.0], repeat=6)))  # one leg's three joints, torque and speed signs
    for leg in range(4):
        cols = [3 * leg, 3 * leg + 1, 3 * leg + 2]
        tau = np.zeros((len(corners), 12))
        qd = np.zeros((len(corners), 12))
        tau[:, cols] = corners[:, :3] * box[0, cols] * (1 - 1e-9)
        qd[:, cols] = corners[:, 3:] * box[1, cols] * (1 - 1e-9)
        assert np.max(SAT.violation(tau, qd, bus_voltage=66.0)) <= 1e-9
    # at 66 V the box is the 66 V corner speed (359.6 rad/s at the motor), not the nominal 450.7
    assert regions.joints[0].inner_box.velocity == pytest.approx(359.65 / 9.0, rel=1e-3)


def test_current_refuses_a_temperature_of_the_wrong_shape(rt):
    with pytest.raises(SaturationError, match=r"runtime.current: temperature has shape \(3, 2\)"):
        rt.current(np.ones((3, rt.n)), temperature=np.full((3, 2), 100.0))
