import dataclasses
import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hound_id.dyno.simulate.current import (
    COLUMNS,
    EFFECT_PARAMETERS,
    EFFECTS,
    PARAMETER_UNITS,
    PARAMETERS,
    SHAPE_PARAMETERS,
    SimMotor,
    TestPlan,
    _first_order_filter,
    physical_torque,
    simulate,
    typical_truth,
)
from hound_id.errors import DynoDataError, HoundIdError

EPS = 0.01  # rad/s, sgn(w) = tanh(w / EPS)
ALL_PARAMETERS = {
    "kt", "k_sat", "k_sat3", "k_knee", "knee_current", "offset", "coulomb", "viscous", "stribeck",
    "stribeck_speed", "gear_friction", "cogging_sin_1", "cogging_cos_1", "cogging_sin_2", "cogging_cos_2",
    "cogging_order", "ripple_sin", "ripple_cos", "ripple_order", "kt_temp_coeff", "inertia", "lag_tau", "resonance_f0",
    "resonance_zeta", "delay", "noise_std",
}  # fmt: skip
# a short plan for property tests (a few thousand rows)
SHORT = TestPlan(speeds=(-5.0, 1.0, 8.0), current_levels=2, plateau_time=0.4, pause_time=0.2, hold_time=0.1,
                 transition_time=0.2)  # fmt: skip


def _sgn(w):
    return np.tanh(w / EPS)


def _h(x, knee):
    return np.where(x > knee, x - knee - knee * np.log(np.maximum(x, knee) / knee), 0.0)


# Each effect's contribution to the torque, written out from the specification on the logged signals.
CONTRIBUTION = {
    "saturation": lambda f, p: -p["k_sat"] * f.current * np.abs(f.current),
    "saturation_cubic": lambda f, p: -p["k_sat3"] * f.current**3,
    "saturation_knee": lambda f, p: -p["k_knee"] * np.sign(f.current) * _h(np.abs(f.current), p["knee_current"]),
    "offset": lambda f, p: np.full(len(f), p["offset"]),
    "coulomb": lambda f, p: -p["coulomb"] * _sgn(f.velocity),
    "viscous": lambda f, p: -p["viscous"] * f.velocity,
    "stribeck": lambda f, p: -p["stribeck"] * _sgn(f.velocity) * np.exp(-((f.velocity / p["stribeck_speed"]) ** 2)),
    "gear_friction": lambda f, p: -p["gear_friction"] * np.abs(f.current) * _sgn(f.velocity),
    "cogging": lambda f, p: sum(
        p[f"cogging_sin_{h}"] * np.sin(h * p["cogging_order"] * f.position)
        + p[f"cogging_cos_{h}"] * np.cos(h * p["cogging_order"] * f.position)
        for h in (1, 2)
    ),
    "ripple": lambda f, p: (
        f.current
        * (
            p["ripple_sin"] * np.sin(p["ripple_order"] * f.position)
            + p["ripple_cos"] * np.cos(p["ripple_order"] * f.position)
        )
    ),
    "thermal": lambda f, p: p["kt_temp_coeff"] * f.current * (f.temperature - 20.0),
}


@pytest.fixture(scope="module")
def base():
    """The default plan with only kt, noiseless."""
    return simulate(("linear",), noise_std=0.0)


def column(log, name):
    return log.frame[name].to_numpy()


# --- the registry and the truth ----------------------------------------------------------------------------


def test_effect_names():
    assert EFFECTS == (
        "linear", "saturation", "saturation_cubic", "saturation_knee", "offset", "coulomb", "viscous", "stribeck",
        "gear_friction", "cogging", "ripple", "thermal", "inertia", "lag", "resonance", "delay",
    )  # fmt: skip
    assert set(EFFECT_PARAMETERS) == set(EFFECTS)
    # every additive effect is checked below; inertia, whose formula needs the speed's derivative, and the transducer's
    # filters in their own tests
    assert set(CONTRIBUTION) == set(EFFECTS) - {"linear", "delay", "inertia", "lag", "resonance"}


def test_truth_has_every_parameter():
    log = simulate(EFFECTS)
    assert set(log.truth) == ALL_PARAMETERS == set(PARAMETERS) == set(PARAMETER_UNITS)
    assert all(isinstance(v, float) and math.isfinite(v) for v in log.truth.values())
    assert log.effects == EFFECTS
    assert all(log.truth[p] != 0.0 for p in PARAMETERS)
    with pytest.raises(TypeError):
        log.truth["kt"] = 1.0  # type: ignore[index]


def test_effects_not_chosen_have_zero_parameters():
    truth = simulate(("coulomb",)).truth
    for effect, names in EFFECT_PARAMETERS.items():
        for name in names:
            assert (truth[name] != 0.0) == (effect in ("linear", "coulomb")), name
    assert truth["delay"] == 0.0
    # shape parameters keep their nominal values (they have no influence when the effect is off)
    assert truth["cogging_order"] == 24.0 and truth["ripple_order"] == 42.0
    assert truth["stribeck_speed"] == 3.0 and set(SHAPE_PARAMETERS) <= set(truth)


def test_typical_magnitudes_sized_to_the_motor():
    motor = SimMotor()
    peak = 0.8 * motor.kt * motor.max_current
    assert motor.peak_torque == pytest.approx(peak)
    p = typical_truth(EFFECTS[:1] + EFFECTS[4:], motor)  # one saturation form: none; check the rest
    assert p["noise_std"] == pytest.approx(0.002 * peak)
    assert p["offset"] == pytest.approx(0.003 * peak)
    assert p["coulomb"] == pytest.approx(0.01 * peak)
    assert p["stribeck"] == pytest.approx(0.4 * p["coulomb"])
    assert p["viscous"] * 40.0 == pytest.approx(0.01 * peak)
    assert math.hypot(p["cogging_sin_1"], p["cogging_cos_1"]) == pytest.approx(0.008 * peak)
    assert math.hypot(p["cogging_sin_2"], p["cogging_cos_2"]) < math.hypot(p["cogging_sin_1"], p["cogging_cos_1"])
    assert math.hypot(p["ripple_sin"], p["ripple_cos"]) == pytest.approx(0.005 * motor.kt)
    assert p["kt_temp_coeff"] == pytest.approx(-0.0011 * motor.kt)
    assert p["gear_friction"] == pytest.approx(0.04 * motor.kt)
    assert p["delay"] == pytest.approx(0.005)


@pytest.mark.parametrize("form", ["saturation", "saturation_cubic", "saturation_knee"])
def test_each_saturation_form_drops_kt_20_percent_at_max_current(form):
    motor = SimMotor()
    imax = np.array([motor.max_current])
    p = typical_truth(("linear", form), motor)
    tau = physical_torque(imax, 0.0, 0.0, 20.0, p)
    assert tau[0] == pytest.approx(0.8 * motor.kt * motor.max_current)
    # all three together still drop 20 % in total
    both = typical_truth(EFFECTS[:4], motor)
    assert physical_torque(imax, 0.0, 0.0, 20.0, both)[0] == pytest.approx(0.8 * motor.kt * motor.max_current)


def test_every_effect_is_well_above_the_default_noise(base):
    noise = typical_truth(EFFECTS)["noise_std"]
    for effect in CONTRIBUTION:
        log = simulate(("linear", effect), noise_std=0.0)
        diff = column(log, "torque") - column(base, "torque")
        assert np.max(np.abs(diff)) > 1.5 * noise, effect  # visible in single samples
        assert np.sqrt(np.sum(diff**2)) / noise > 100, effect  # matched-filter signal-to-noise over the log


# --- determinism and noise ---------------------------------------------------------------------------------


def test_same_seed_same_log():
    a = simulate(EFFECTS, seed=7, current_noise_std=0.1)
    b = simulate(EFFECTS, seed=7, current_noise_std=0.1)
    pd.testing.assert_frame_equal(a.frame, b.frame)
    assert dict(a.truth) == dict(b.truth) and a.seed == b.seed == 7


def test_different_seeds_differ_only_in_the_noise():
    a, b = simulate(EFFECTS, seed=1), simulate(EFFECTS, seed=2)
    assert not np.array_equal(column(a, "torque"), column(b, "torque"))
    for name in ("time", "current", "velocity", "position", "temperature", "bus_voltage"):
        assert np.array_equal(column(a, name), column(b, name)), name
    assert dict(a.truth) == dict(b.truth)


def test_torque_noise_is_white_with_the_given_std():
    clean = simulate(("linear", "saturation"), noise_std=0.0)
    noisy = simulate(("linear", "saturation"), noise_std=0.05, seed=3)
    e = column(noisy, "torque") - column(clean, "torque")
    assert noisy.truth["noise_std"] == 0.05
    assert np.std(e) == pytest.approx(0.05, rel=0.02)
    assert abs(np.mean(e)) < 4 * 0.05 / math.sqrt(e.size)
    assert abs(np.corrcoef(e[1:], e[:-1])[0, 1]) < 0.02  # white


def test_default_noise_is_typical():
    log = simulate(("linear",))
    assert log.truth["noise_std"] == pytest.approx(0.002 * SimMotor().peak_torque)
    assert simulate(("linear",), truth={"noise_std": 0.01}).truth["noise_std"] == 0.01
    assert simulate(("linear",), truth={"noise_std": 0.01}, noise_std=0.02).truth["noise_std"] == 0.02


def test_current_noise_is_on_the_logged_channel_only():
    clean = simulate(("linear", "saturation"), noise_std=0.0)
    noisy = simulate(("linear", "saturation"), noise_std=0.0, current_noise_std=0.3, seed=5)
    e = column(noisy, "current") - column(clean, "current")
    assert np.std(e) == pytest.approx(0.3, rel=0.02)
    assert np.array_equal(column(noisy, "torque"), column(clean, "torque"))  # torque made by the true current


# --- the physics of the torque -----------------------------------------------------------------------------


def test_linear_and_saturation_exact_without_noise():
    log = simulate(("linear", "saturation"), noise_std=0.0)
    i, p = column(log, "current"), log.truth
    assert np.allclose(column(log, "torque"), p["kt"] * i - p["k_sat"] * i * np.abs(i), rtol=0.0, atol=1e-12)


@pytest.mark.parametrize("effect", sorted(CONTRIBUTION))
def test_each_effect_adds_its_formula(effect, base):
    log = simulate(("linear", effect), noise_std=0.0)
    assert log.effects == ("linear", effect)
    for name in ("time", "current", "velocity", "position", "temperature"):
        assert np.array_equal(column(log, name), column(base, name))
    diff = column(log, "torque") - column(base, "torque")
    expected = CONTRIBUTION[effect](log.frame, log.truth)
    assert np.allclose(diff, expected, rtol=0.0, atol=1e-12 * max(1.0, np.max(np.abs(expected))))


def test_signs_of_the_effects(base):
    f = base.frame
    i, w, temp = f.current.to_numpy(), f.velocity.to_numpy(), f.temperature.to_numpy()

    def diff(effect):
        return column(simulate(("linear", effect), noise_std=0.0), "torque") - column(base, "torque")

    loaded, moving = np.abs(i) > 1.0, np.abs(w) > 0.1
    for effect in ("saturation", "saturation_cubic", "thermal"):  # less torque per amp (T > 20 degC throughout)
        assert np.all(diff(effect)[loaded] * i[loaded] < 0), effect
    assert np.all(diff("saturation_knee") * i <= 0)
    assert np.any(diff("saturation_knee") * i < 0)
    for effect, rows in (("coulomb", moving), ("viscous", moving), ("gear_friction", moving & loaded)):
        assert np.all(diff(effect)[rows] * w[rows] < 0), effect  # friction opposes motion
    slow = moving & (np.abs(w) < 6.0)
    assert np.all(diff("stribeck")[slow] * w[slow] < 0)
    assert np.all(diff("offset") > 0)
    assert np.all(temp >= SimMotor().ambient - 1e-12)


def test_delay_lags_the_torque_channel_only():
    base = simulate(("linear", "saturation", "cogging"), noise_std=0.0)
    lag = simulate(("linear", "saturation", "cogging", "delay"), noise_std=0.0)
    d = lag.truth["delay"]
    assert d == pytest.approx(0.005)
    for name in ("time", "current", "velocity", "position", "temperature", "bus_voltage"):
        assert np.array_equal(column(lag, name), column(base, name)), name  # not delayed
    t = column(base, "time")
    after = t >= d
    expected = np.interp(t - d, t, column(base, "torque"))
    assert np.allclose(column(lag, "torque")[after], expected[after], rtol=0.0, atol=1e-9)
    assert np.max(np.abs(column(lag, "torque") - column(base, "torque"))) > 1.0  # at the current steps


def test_fractional_delay_interpolates():
    plan = TestPlan(shape="ramps", hold_time=0.0)  # no current edges: torque is smooth between samples
    base = simulate(("linear", "saturation"), plan=plan, noise_std=0.0)
    lag = simulate(("linear", "saturation", "delay"), plan=plan, noise_std=0.0, truth={"delay": 0.0025})
    t = column(base, "time")
    after = t >= 0.0025
    expected = np.interp(t - 0.0025, t, column(base, "torque"))
    assert np.allclose(column(lag, "torque")[after], expected[after], rtol=0.0, atol=1e-4)
    # torque at t equals the model at the current half a sample before: between the logged samples
    i_mid = np.interp(t - 0.0025, t, column(base, "current"))
    p = lag.truth
    assert np.allclose(column(lag, "torque")[after], (p["kt"] * i_mid - p["k_sat"] * i_mid * np.abs(i_mid))[after],
                       rtol=0.0, atol=1e-4)  # fmt: skip


def test_physical_torque_matches_the_log():
    # inertia and the transducer's filters: own tests
    log = simulate(tuple(e for e in EFFECTS if e not in ("delay", "inertia", "lag", "resonance")), noise_std=0.0)
    f = log.frame
    tau = physical_torque(f.current, f.velocity, f.position, f.temperature, log.truth)
    assert np.allclose(f.torque.to_numpy(), tau + log.truth["offset"], rtol=0.0, atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(st.sets(st.sampled_from(sorted(CONTRIBUTION)), min_size=1, max_size=6), st.integers(0, 2**32 - 1))
def test_effects_add_up(chosen, seed):
    base = column(simulate(("linear",), plan=SHORT, noise_std=0.0), "torque")
    together = column(simulate(tuple(chosen), plan=SHORT, noise_std=0.0, seed=seed), "torque")
    # the typical 20 % drop at max_current is shared among the chosen saturation forms
    shared = len(chosen & {"saturation", "saturation_cubic", "saturation_knee"})
    total = np.zeros_like(base)
    for effect in chosen:
        part = column(simulate(("linear", effect), plan=SHORT, noise_std=0.0), "torque") - base
        total += part / shared if effect.startswith("saturation") else part
    assert np.allclose(together - base, total, rtol=0.0, atol=1e-9)


# --- the signals and the plan ------------------------------------------------------------------------------


def test_columns_and_rate():
    log = simulate(rate_hz=250.0)
    assert tuple(log.frame.columns) == COLUMNS
    t = column(log, "time")
    assert t[0] == 0.0 and np.allclose(np.diff(t), 1 / 250.0, rtol=0.0, atol=1e-12)
    assert len(t) == int(round(log.plan.duration * 250.0)) + 1 and log.rate_hz == 250.0
    assert len(simulate(rate_hz=2000.0).frame) == int(round(log.plan.duration * 2000.0)) + 1


def test_default_log_length():
    log = simulate()
    assert 60.0 <= log.plan.duration <= 120.0
    assert len(log.frame) == 60001


def test_four_quadrants_and_overdrive(base):
    i, w = column(base, "current"), column(base, "velocity")
    imax = SimMotor().max_current
    assert i.max() == pytest.approx(1.3 * imax) and i.min() == pytest.approx(-1.3 * imax)
    assert np.sum(i > imax) > 100 and np.sum(i < -imax) > 100
    for sign_i in (1, -1):
        for sign_w in (1, -1):
            assert np.sum((sign_i * i > 0.5 * imax) & (sign_w * w > 1.0)) > 100, (sign_i, sign_w)
    assert np.sum((np.abs(w) > 0.0) & (np.abs(w) < 3.0)) > 1000  # near zero speed (Coulomb, Stribeck)


def test_velocity_holds_the_plateaus_and_position_is_its_integral(base):
    t, w, theta = column(base, "time"), column(base, "velocity"), column(base, "position")
    plan = base.plan
    for speed in plan.speeds:
        held = np.sum(w == speed) / base.rate_hz
        assert held >= plan.plateau_time + plan.pause_time - 1e-6, speed
    # smooth (raised-cosine) transitions: the largest change per sample is pi/2 * jump / transition_time
    jump = np.max(np.abs(np.diff(plan.speeds)))
    assert np.max(np.abs(np.diff(w))) <= 1.0001 * np.pi / 2 * jump / plan.transition_time / base.rate_hz
    assert theta[0] == 0.0
    assert np.allclose(np.diff(theta), 0.5 * (w[1:] + w[:-1]) * np.diff(t), rtol=0.0, atol=1e-5)
    assert np.ptp(theta) > 2 * np.pi * 50  # unwrapped, many revolutions


def test_cogging_and_ripple_cycle_many_times_at_every_plateau(base):
    w, theta = column(base, "velocity"), column(base, "position")
    for speed in base.plan.speeds:
        rows = w == speed
        cycles = np.ptp(theta[rows]) * 24 / (2 * np.pi)
        assert cycles > 40, speed


def test_steps_are_fast_and_reach_every_level(base):
    i = column(base, "current")
    imax, plan = SimMotor().max_current, base.plan
    levels = 1.3 * imax * np.arange(1, plan.current_levels + 1) / plan.current_levels
    for level in levels:
        for sign in (1, -1):
            assert np.sum(np.isclose(i, sign * level)) >= plan.step_time * base.rate_hz - 2
    assert np.max(np.abs(np.diff(i))) == pytest.approx(1.3 * imax)  # a full edge within one sample at 1 kHz


def test_temperature_swing_and_thermal_model(base):
    temp, i, t = column(base, "temperature"), column(base, "current"), column(base, "time")
    motor = SimMotor()
    assert temp[0] == motor.ambient
    assert np.ptp(temp) >= 15.0
    assert temp.max() < 100.0  # bounded heating
    # C dT/dt = R i^2 - (T - ambient)/R_th, central differences away from the current edges
    dt = np.diff(t)[0]
    dTdt = (temp[2:] - temp[:-2]) / (2 * dt)
    rhs = motor.resistance * i[1:-1] ** 2 - (temp[1:-1] - motor.ambient) / motor.thermal_resistance
    smooth = np.abs(np.diff(i, 2)) < 1e-9
    assert np.allclose(motor.thermal_capacitance * dTdt[smooth], rhs[smooth], rtol=0.0, atol=0.05)


def test_temperature_reaches_steady_state_with_a_fast_motor():
    motor = SimMotor(thermal_capacitance=0.01, thermal_resistance=1.0)  # 10 ms time constant
    plan = TestPlan(hold_time=0.5)
    log = simulate(motor=motor, plan=plan)
    temp, i = column(log, "temperature"), column(log, "current")
    holding = np.flatnonzero(i == motor.max_current)
    late = holding[holding > holding[0] + 300]  # 30 time constants into the hold
    steady = motor.ambient + motor.thermal_resistance * motor.resistance * motor.max_current**2
    assert np.allclose(temp[late], steady, rtol=1e-9)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(0.0, 100.0), min_size=1, max_size=3000),
    st.floats(1e-160, 1.0, exclude_max=True),
)
def test_first_order_filter_matches_the_recursion(drive, decay):
    d = np.array(drive)
    y = _first_order_filter(d, decay)
    ref, acc = np.empty_like(d), 0.0
    for n, value in enumerate(d):
        acc = decay * acc + value
        ref[n] = acc
    assert np.allclose(y, ref, rtol=1e-9, atol=1e-9)


def test_first_order_filter_chains_blocks():
    d = np.ones(100_000)
    decay = math.exp(-0.05)  # blocks of 6900 samples, chained twice
    y = _first_order_filter(d, decay)
    assert np.allclose(y, (1 - decay ** np.arange(1, d.size + 1)) / (1 - decay), rtol=1e-12)


def test_bus_voltage_sags_with_current(base):
    bus, i = column(base, "bus_voltage"), column(base, "current")
    assert np.allclose(bus, 48.0 - 0.02 * np.abs(i))


def test_shapes():
    ramps = column(simulate(plan=TestPlan(shape="ramps")), "current")
    steps = column(simulate(plan=TestPlan(shape="steps")), "current")
    assert np.sum(np.abs(np.diff(ramps)) > 1.0) == 2  # no edges but the hold's rise and fall
    assert np.max(np.abs(np.diff(steps))) > 50.0
    assert TestPlan(shape="steps").step_time == pytest.approx(2.0 / 20)
    assert TestPlan().step_time == pytest.approx(1.0 / 20) and TestPlan().ramp_time == 1.0


def test_scaled_motor():
    small, big = SimMotor(), SimMotor().scaled(2.0)
    assert big.kt == 2 * small.kt and big.max_current == small.max_current
    assert big.thermal_time_constant == pytest.approx(small.thermal_time_constant)
    a, b = simulate(EFFECTS, motor=small, noise_std=0.0), simulate(EFFECTS, motor=big, noise_std=0.0)
    assert np.allclose(column(a, "temperature"), column(b, "temperature"), rtol=1e-12)
    for name in ("kt", "coulomb", "viscous", "offset", "cogging_sin_1", "ripple_sin", "kt_temp_coeff", "noise_std"):
        assert b.truth[name] == pytest.approx(2 * a.truth[name]), name
    assert b.truth["cogging_order"] == a.truth["cogging_order"]
    assert np.allclose(column(b, "torque"), 2 * column(a, "torque"), rtol=1e-12, atol=1e-12)


def test_truth_overrides():
    log = simulate(("linear", "coulomb"), truth={"coulomb": 0.2, "kt": 0.1}, noise_std=0.0)
    assert log.truth["coulomb"] == 0.2 and log.truth["kt"] == 0.1
    f = log.frame
    assert np.allclose(f.torque, 0.1 * f.current - 0.2 * np.tanh(f.velocity / EPS), atol=1e-12)
    assert simulate(("linear",), truth={"coulomb": 0.0}).truth["coulomb"] == 0.0


def test_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        SimMotor().kt = 1.0  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        TestPlan().speeds = (1.0,)  # type: ignore[misc]
    assert TestPlan(speeds=[1.0, -1.0]).speeds == (1.0, -1.0)  # type: ignore[arg-type]


def test_single_string_effect_and_linear_always_present():
    assert simulate("saturation", plan=SHORT).effects == ("linear", "saturation")
    assert simulate(("delay", "saturation", "saturation"), plan=SHORT).effects == ("linear", "saturation", "delay")


# --- errors ------------------------------------------------------------------------------------------------


def test_unknown_effect_lists_the_valid_ones():
    with pytest.raises(DynoDataError, match=r"unknown effect 'friction'; expected one of: linear, saturation, .*delay"):
        simulate(("linear", "friction"))
    with pytest.raises(ValueError):  # DynoDataError is a ValueError too
        typical_truth(("bogus",))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"truth": {"kt_20": 1.0}}, r"unknown parameter 'kt_20'; expected one of: kt, "),
        ({"truth": {"coulomb": 0.1}}, r"effect 'coulomb' is not simulated"),
        ({"effects": ("cogging",), "truth": {"cogging_order": 2.5}}, r"cogging_order.*positive integer"),
        ({"truth": {"kt": -1.0}}, r"'kt'.*positive"),
        ({"effects": ("delay",), "truth": {"delay": -0.001}}, r"'delay'.*>= 0"),
        ({"truth": {"kt": float("nan")}}, r"finite"),
        ({"rate_hz": 0.0}, r"rate_hz.*positive"),
        ({"noise_std": -1.0}, r"noise_std.*>= 0"),
        ({"current_noise_std": float("inf")}, r"current_noise_std.*finite"),
        ({"seed": -1}, r"seed: found -1"),
        ({"rate_hz": 0.001}, r"expected at least 2"),
    ],
)
def test_bad_arguments(kwargs, match):
    with pytest.raises(DynoDataError, match=match):
        simulate(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"shape": "sine"}, r"TestPlan.shape: found 'sine', expected one of ramps, ramps_and_steps, steps"),
        ({"current_levels": 0}, r"current_levels: found 0"),
        ({"speeds": ()}, r"no speeds"),
        ({"speeds": "fast"}, r"expected a sequence"),
        ({"plateau_time": 0.0}, r"plateau_time.*positive"),
        ({"pause_time": -1.0}, r"pause_time.*>= 0"),
        ({"current_levels": 1000}, r"shortest step.*current_rise_time"),
    ],
)
def test_bad_plans(kwargs, match):
    with pytest.raises(DynoDataError, match=match):
        TestPlan(**kwargs)


def test_bad_motor_and_scale():
    with pytest.raises(DynoDataError, match=r"SimMotor.kt: found 0.0, expected a positive number"):
        SimMotor(kt=0.0)
    with pytest.raises(HoundIdError, match=r"scale factor"):
        SimMotor().scaled(-1.0)


@pytest.mark.parametrize("effects", [("lag",), ("resonance",), ("lag", "resonance")])
def test_the_transducer_filters_agree_with_the_fits_discretisation(effects):
    """The simulator integrates the transducer on a 10 kHz grid by the trapezoidal rule; the fit filters the log's own
    samples exactly for straight lines between them (hound_id.dyno.current.transducer). On the unfiltered torque of the
    same run they agree to far below the typical noise (0.2 % of peak torque), steps and all."""
    from hound_id.dyno.current.transducer import apply

    plan = TestPlan(shape="ramps_and_steps")
    a = simulate(("linear", *effects), plan=plan, seed=3, noise_std=0.0, truth={"delay": 0.0})
    b = simulate(("linear",), plan=plan, seed=3, noise_std=0.0, truth={"delay": 0.0})
    t, raw = b.frame["time"].to_numpy(), b.frame["torque"].to_numpy()
    filtered = raw
    for name in effects:
        filtered = apply(name, a.truth, t, filtered)
    diff = a.frame["torque"].to_numpy() - filtered
    assert np.sqrt(np.mean(diff**2)) < 0.002 * a.motor.peak_torque
    # one filter after the other on samples: the lag's output is not straight between samples just after a step
    assert np.max(np.abs(diff)) < (0.02 if len(effects) > 1 else 0.002) * a.motor.peak_torque
    # and the filter is there: the reading differs from the shaft torque by far more at the steps
    assert np.max(np.abs(a.frame["torque"].to_numpy() - raw)) > 0.05 * a.motor.peak_torque


def test_inertia_takes_j_times_the_acceleration_during_speed_changes():
    """The shaft torque less J dw/dt, with dw/dt the exact derivative of the plan's raised-cosine speed changes
    (checked against a finite difference of the logged speed), and nothing at constant speed."""
    a = simulate(("linear", "inertia"), seed=3, noise_std=0.0, truth={"delay": 0.0})
    b = simulate(("linear",), seed=3, noise_std=0.0, truth={"delay": 0.0})
    t, w = a.frame["time"].to_numpy(), a.frame["velocity"].to_numpy()
    diff = a.frame["torque"].to_numpy() - b.frame["torque"].to_numpy()
    rate = np.gradient(w, t)
    J = a.truth["inertia"]
    inner = slice(2, -2)
    assert np.allclose(diff[inner], -J * rate[inner], atol=J * 0.05 * np.abs(rate).max())
    assert np.abs(rate).max() > 10 and np.all(diff[np.abs(rate) < 1e-9] == 0.0)
