"""Envelope models (the groundwork of mor --compare): the spec boundary, and each effect moving it as physics says."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hound_id.dyno.simulate.envelope import simulate_log
from hound_id.errors import SpecError
from hound_id.mor.current_curve import polynomial_curve
from hound_id.mor.envelope import COPPER_ALPHA, EFFECTS, EnvelopeInputs, edge, effect_names, envelope, feasible
from hound_id.mor.region import linear_region, torque_interval
from hound_id.mor.spec import MotorSpec
from hound_id.mor.spec_sheet import load_motor_spec
from tests.conftest import MOTOR, SMALL_MOTOR

SPEC = load_motor_spec(MOTOR)
INPUTS = EnvelopeInputs(SPEC)
NO_LOAD = SPEC.bus_voltage * SPEC.kv
W = np.linspace(-0.95, 0.95, 41) * NO_LOAD


@pytest.mark.parametrize("motor", [MOTOR, SMALL_MOTOR])
def test_no_effect_is_the_spec_sheet_region(motor):
    spec = load_motor_spec(motor)
    w = np.linspace(-0.99, 0.99, 101) * spec.bus_voltage * spec.kv
    lo, hi = envelope(w, {}, EnvelopeInputs(spec))
    ref_lo, ref_hi = torque_interval(w, linear_region(spec))  # the envelope model starts from linear Kt
    assert np.max(np.abs(lo - ref_lo)) < 1e-9 and np.max(np.abs(hi - ref_hi)) < 1e-9


def test_bus_sag_lowers_only_the_motoring_edge():
    lo0, hi0 = envelope(W, {}, INPUTS)
    lo, hi = envelope(W, {"bus_sag": 0.2}, INPUTS)
    motoring_hi = hi0 * W > 0  # upper edge at positive speed: motoring
    assert np.all(hi[motoring_hi] <= hi0[motoring_hi] + 1e-12)
    assert np.any(hi[motoring_hi] < hi0[motoring_hi] - 0.1)
    # at rest nothing moves. Where the voltage binds the bus is the applied voltage, V = V_req, and the pack drops
    # V_bus - V = R_pack P / V = R_pack i (the bus current P / V is the phase current at full modulation)
    assert hi[20] == pytest.approx(hi0[20]) and lo[20] == pytest.approx(lo0[20])
    k = int(np.argmax(W))
    i = hi[k] / SPEC.kt
    v_req = SPEC.resistance * i + W[k] / SPEC.kv
    assert v_req + 0.2 * i == pytest.approx(SPEC.bus_voltage, rel=1e-9)


def test_regen_rise_matters_only_past_the_no_load_speed():
    """Braking below the no-load speed needs less voltage than the bus has: a higher bus changes nothing."""
    assert np.allclose(envelope(W, {"regen_rise": 1.0}, INPUTS)[0], envelope(W, {}, INPUTS)[0])
    fast = np.array([1.02, 1.05]) * NO_LOAD  # overspeed: a minimum braking torque, which a higher bus lowers
    with_rise, without = envelope(fast, {"regen_rise": 1.0}, INPUTS)[1], envelope(fast, {}, INPUTS)[1]
    assert np.all(np.isfinite(without)) and np.all(without < 0) and np.all(with_rise > without)


def test_a_hot_winding_narrows_the_voltage_lines():
    hot = EnvelopeInputs(SPEC, temperature=np.full(W.shape, 105.0))
    lo, hi = envelope(W, {"thermal_resistance": COPPER_ALPHA}, hot)
    _, hi0 = envelope(W, {}, INPUTS)
    k = int(np.argmax(W))
    r_hot = SPEC.resistance * (1 + COPPER_ALPHA * 80.0)
    assert hi[k] == pytest.approx(SPEC.kt / r_hot * (SPEC.bus_voltage - W[k] / SPEC.kv), rel=1e-9)
    assert hi[k] < hi0[k]


def test_inductance_costs_voltage_at_speed_only():
    lo, hi = envelope(W, {"inductance": 7e-5}, INPUTS)
    lo0, hi0 = envelope(W, {}, INPUTS)
    assert hi[20] == pytest.approx(hi0[20])
    assert np.all(hi <= hi0 + 1e-12) and np.all(lo >= lo0 - 1e-12) and hi[-1] < hi0[-1] - 0.1


def test_current_limit_and_kt_saturation():
    lo, hi = envelope(W, {"current_limit": 40.0}, INPUTS)
    assert np.max(hi) == pytest.approx(SPEC.kt * 40.0) and np.min(lo) == pytest.approx(-SPEC.kt * 40.0)
    # a curve that needs 10 % more current at 9 N m than Kt says: the voltage line bends inwards
    comp = polynomial_curve(SPEC.kt, (1, 3), (1 / SPEC.kt, 0.1 / (SPEC.kt * 81.0)), torque_range=25.0)
    bent = EnvelopeInputs(SPEC, curve=comp)
    _, hi_s = envelope(W, {"kt_saturation": 1.0}, bent)
    _, hi0 = envelope(W, {}, INPUTS)
    assert np.all(hi_s <= hi0 + 1e-12) and hi_s[-1] < hi0[-1]
    assert np.array_equal(envelope(W, {"kt_saturation": 0.0}, bent)[1], hi0)


def test_effects_need_their_inputs_and_sensible_values():
    assert effect_names(INPUTS) == ["bus_sag", "current_limit", "inductance", "regen_rise"]  # sample has pole pairs
    with pytest.raises(SpecError, match="thermal_resistance needs temperature"):
        envelope(W, {"thermal_resistance": 0.004}, INPUTS)
    with pytest.raises(SpecError, match="bus_sag r_pack = -1 ohm is outside"):
        envelope(W, {"bus_sag": -1.0}, INPUTS)
    with pytest.raises(SpecError, match="unknown effect 'sag'"):
        feasible(np.zeros(3), np.zeros(3), {"sag": 1.0}, INPUTS)
    assert sorted(EFFECTS) == list(EFFECTS)


def test_simulated_logs_stay_inside_their_true_envelope():
    log = simulate_log(INPUTS, {"bus_sag": 0.15}, n=4000, noise=0.0, seed=2)
    inputs = EnvelopeInputs(SPEC, temperature=log["temperature"])
    lo, hi = envelope(log["velocity"], {"bus_sag": 0.15}, inputs)
    assert np.all(log["torque"] <= hi + 1e-9) and np.all(log["torque"] >= lo - 1e-9)
    at_edge = np.isclose(log["torque"], hi) | np.isclose(log["torque"], lo)
    assert 0.3 < at_edge.mean() < 0.9  # many commands past the region
    _, hi_spec = envelope(log["velocity"], {}, inputs)
    assert np.mean(log["torque"] > hi_spec + 1e-9) == 0.0 and np.any(hi < hi_spec - 0.1)  # it falls short
    assert np.all(log["bus_voltage"][log["torque"] * log["velocity"] > 0] <= SPEC.bus_voltage + 1e-9)


# --- the edge against an independent reference: the module docstring's conditions, scanned densely and bisected ---


def reference_feasible(tau, omega, params, spec, temperature, curve):
    """The conditions of the module docstring written out again (not the module's code): |V_req| <= V_avail with
    V_avail the high root of V = V_bus - R_x P / V (none past the most the pack delivers), |i| <= I_lim,
    |tau| <= the linear torque limit, and past the rated speed braking only."""
    scale = params.get("kt_saturation", 0.0)
    i = tau / spec.kt
    if scale and curve is not None:
        i = i + scale * (curve.current(tau) - i)
    r = spec.resistance * (1.0 + params.get("thermal_resistance", 0.0) * (temperature - 25.0))
    v_q = r * i + omega / spec.kv
    v_req = np.hypot(v_q, (spec.pole_pairs or 0) * omega * params.get("inductance", 0.0) * i)
    power = v_q * i
    r_x = np.where(power > 0.0, params.get("bus_sag", 0.0), params.get("regen_rise", 0.0))
    disc = spec.bus_voltage**2 - 4.0 * r_x * power
    with np.errstate(invalid="ignore"):
        v_avail = np.where(disc >= 0.0, 0.5 * (spec.bus_voltage + np.sqrt(np.maximum(disc, 0.0))), -np.inf)
        ok = (v_req <= v_avail) & (np.abs(i) <= min(spec.max_current or np.inf, params.get("current_limit", np.inf)))
    ok &= np.abs(tau) <= spec.linear_torque_limit
    if spec.max_speed is not None:
        ok &= ~((np.abs(omega) > spec.max_speed) & (tau * omega > 0))
    return ok


def reference_edge(omega, side, params, spec, temperature, curve, grid=4001, halvings=80):
    """The edge at one speed: from the documented start (the zero-voltage torque within 0.999 of the current limit,
    moved 0.8 of the way to zero up to 40 times until feasible) a dense scan outwards to the torque limit, then
    bisection on :func:`reference_feasible` between the last feasible and the first infeasible grid torque."""

    def ok(t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return reference_feasible(t, np.full_like(t, omega), params, spec, np.full_like(t, temperature), curve)

    cap = spec.linear_torque_limit
    i_limit = min(spec.max_current or np.inf, params.get("current_limit", np.inf))
    start = min(cap, 0.999 * spec.kt * i_limit)
    t = float(np.clip(-spec.kt * omega / (spec.resistance * spec.kv), -start, start))
    for _ in range(41):
        if ok(t)[0]:
            break
        t *= 0.8
    else:
        return np.nan
    scan = np.linspace(t, side * cap, grid)
    fails = np.flatnonzero(~ok(scan))
    if not fails.size:
        return side * cap
    lo, hi = scan[fails[0] - 1], scan[fails[0]]
    for _ in range(halvings):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ok(mid)[0] else (lo, mid)
    return lo


@st.composite
def envelope_cases(draw):
    kt = draw(st.floats(0.02, 1.0))
    spec = MotorSpec(
        name="h",
        kt=kt,
        kv=draw(st.floats(0.8, 1.2)) / kt,
        resistance=draw(st.floats(0.02, 2.0)),
        bus_voltage=draw(st.floats(10.0, 100.0)),
        peak_torque=draw(st.floats(0.5, 50.0)),
        max_current=draw(st.one_of(st.none(), st.floats(5.0, 200.0))),
        max_speed=None,
        pole_pairs=draw(st.integers(1, 20)),
    )
    names = draw(st.sets(st.sampled_from(sorted(EFFECTS)), max_size=3))
    ranges = {"bus_sag": (0.0, 2.0), "regen_rise": (0.0, 2.0), "inductance": (0.0, 2e-3), "kt_saturation": (0.0, 1.5),
              "thermal_resistance": (0.0, 0.006), "current_limit": (1.0, 200.0)}  # fmt: skip
    params = {n: draw(st.floats(*ranges[n])) for n in names}
    omega = draw(st.floats(-1.1, 1.1)) * spec.bus_voltage * spec.kv
    temperature = draw(st.floats(0.0, 150.0))
    return spec, params, omega, temperature, draw(st.sampled_from([1, -1]))


@settings(max_examples=300, deadline=None)
@given(envelope_cases())
def test_the_edge_is_where_a_dense_bisection_on_the_conditions_finds_it(case):
    """The root search (closed-form guess, Illinois steps, each speed leaving on its own tolerance) finds the edge a
    plain bisection on the written-out conditions finds, for random motors and effects; and feasible() agrees with
    those conditions away from the edge."""
    spec, params, omega, temperature, side = case
    curve = polynomial_curve(spec.kt, (1, 3), (1 / spec.kt, 0.1 / (spec.kt * spec.linear_torque_limit**2)),
                             torque_range=2.0 * spec.linear_torque_limit)  # fmt: skip
    inputs = EnvelopeInputs(spec, temperature=np.array([temperature]), curve=curve)
    got = edge(np.array([omega]), side, params, inputs)[0]
    want = reference_edge(omega, side, params, spec, temperature, curve)
    assert np.isnan(got) == np.isnan(want), (got, want)
    if not np.isnan(want):
        assert got == pytest.approx(want, abs=1e-9 * spec.linear_torque_limit), (got, want)
    taus = np.linspace(-1.05, 1.05, 211) * spec.linear_torque_limit
    mine = feasible(
        taus, np.full_like(taus, omega), params, EnvelopeInputs(spec, np.full_like(taus, temperature), curve)
    )
    ref = reference_feasible(taus, np.full_like(taus, omega), params, spec, np.full_like(taus, temperature), curve)
    near = np.abs(taus - np.nan_to_num(want)) < 1e-6 * spec.linear_torque_limit
    assert np.array_equal(mine[~near], ref[~near])
