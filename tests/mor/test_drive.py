"""The drive's dq model (hound_id/mor/drive.py) and what it does to the region, the clip and the spec.

The window is checked against a brute-force scan of the dq current plane written out here (the voltage circle of
the phase equations and the current limits, in phase quantities: not hound_id's DC-equivalent form), and against
the figures the model must reproduce on the sample sheet (35 uH per phase, 10 pole pairs, 81 V, 70 A)."""

import dataclasses
import math

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from hound_id.errors import HoundIdError, SaturationError
from hound_id.mor.drive import dq_window
from hound_id.mor.region import drive_region, operating_region, torque_interval
from hound_id.mor.region_report import at_speed
from hound_id.mor.robot import load_robot
from hound_id.mor.saturation import saturation_for
from hound_id.mor.spec_sheet import load_motor_spec, motor_spec_from_mapping
from tests.conftest import ROBOT, SAMPLES

SHEET = SAMPLES / "motors" / "hound_ilm85.yaml"
SPEC = load_motor_spec(SHEET)


def phase_scan(spec, omega, weakening, points=20001):
    """(lowest, highest) q current [A] a drive can hold at ``omega`` [rad/s], scanning i_q: per phase,
    v_d = R i_d - w_e L i_q, v_q = R i_q + w_e L i_d + w_e psi, |v| <= V_bus/sqrt(3), |i_q| <= I and (field
    weakening) |i| <= I_max, i_d <= 0, or (without) i_d = 0. For each i_q the voltage circle allows an interval of
    i_d (a quadratic's roots), intersected with the current's. None where no current is held."""
    r_ph = spec.resistance / math.sqrt(3.0)
    x = spec.pole_pairs * omega * spec.drive.inductance_phase  # reactance [ohm]
    e = omega / (math.sqrt(3.0) * spec.kv)  # the phase back-EMF
    v_max = spec.bus_voltage / math.sqrt(3.0)
    i_max = spec.max_current
    i_q = np.linspace(-i_max, i_max, points)
    # (R^2 + X^2) i_d^2 + 2 X e i_d + (X i_q)^2 + (R i_q + e)^2 - V^2 <= 0
    a, b, c = r_ph**2 + x**2, 2 * x * e, (x * i_q) ** 2 + (r_ph * i_q + e) ** 2 - v_max**2
    disc = b * b - 4 * a * c
    root = np.sqrt(np.maximum(disc, 0.0))
    d_lo, d_hi = (-b - root) / (2 * a), (-b + root) / (2 * a)
    if weakening:
        reach = np.sqrt(np.maximum(i_max**2 - i_q**2, 0.0))
        ok = (disc >= 0) & (np.maximum(d_lo, -reach) <= np.minimum(d_hi, 0.0))
    else:
        ok = (disc >= 0) & (d_lo <= 0.0) & (d_hi >= 0.0)
    held = i_q[ok]
    return (float(held.min()), float(held.max())) if held.size else None


@pytest.mark.parametrize("weakening", [False, True])
@pytest.mark.parametrize("convention", ["line_to_line", "phase"])
def test_the_window_is_the_brute_force_scan_of_the_dq_plane(weakening, convention):
    spec = dataclasses.replace(SPEC, inductance_convention=convention, field_weakening=weakening)
    region = operating_region(spec)
    kt = region.curve.kt
    step = 2 * spec.max_current / 20000
    for omega in np.linspace(0.0, 1.6 * spec.no_load_speed, 41):
        scan = phase_scan(spec, omega, weakening)
        x_lo, x_hi = dq_window(
            region.back_emf_damping * omega, region.stall_torque, spec.drive.k_rho, region.limit_x,
            spec.drive.circle_x, weakening,
        )  # fmt: skip
        if scan is None:
            assert x_lo == x_hi  # past control: one torque, the diode bridge's
            continue
        assert x_lo < x_hi
        assert float(x_hi) / kt == pytest.approx(scan[1], abs=2 * step)
        assert float(x_lo) / kt == pytest.approx(scan[0], abs=2 * step)


def test_the_sample_sheets_figures_at_speed():
    """The figures a motor engineer can check by hand (line to line 70 uH is 35 uH per phase)."""
    ll = operating_region(SPEC)
    ph = operating_region(dataclasses.replace(SPEC, inductance_convention="phase"))
    assert ll.corner_speed == pytest.approx(450.7, abs=0.1) and ph.corner_speed == pytest.approx(414.6, abs=0.1)
    assert ll.no_load_speed == pytest.approx(SPEC.kv * SPEC.bus_voltage)  # zero current drops no voltage
    # at the DC law's corner speed the bus drives 55.1 A (35 uH) or 39.3 A (70 uH), not 70 A
    kt = ll.curve.kt
    for region, amps in ((ll, 55.1), (ph, 39.3)):
        x = torque_interval(np.array([465.0]), dataclasses.replace(region, curve=None))[1][0]
        assert x / kt == pytest.approx(amps, abs=0.1)
    # past control the diode bridge brakes by 9.8 N m (35 uH) or 6.3 N m (70 uH) at 600 rad/s, not 14.7
    assert torque_interval(np.array([600.0]), ll)[1][0] == pytest.approx(-9.77, abs=0.01)
    assert torque_interval(np.array([600.0]), ph)[1][0] == pytest.approx(-6.30, abs=0.01)
    dc = operating_region(dataclasses.replace(SPEC, inductance=None))
    assert torque_interval(np.array([600.0]), dc)[1][0] == pytest.approx(-14.70, abs=0.01)
    cost = at_speed(SPEC)
    assert cost.largest_cost[0] == pytest.approx(1.59, abs=0.01) and cost.largest_cost[1] == pytest.approx(465.1, 0.1)


def test_field_weakening_reaches_further_and_never_takes_away():
    plain = operating_region(SPEC)
    weak = operating_region(dataclasses.replace(SPEC, field_weakening=True))
    assert weak.corner_speed == pytest.approx(plain.corner_speed)  # full current leaves no room for i_d
    assert weak.no_load_speed == pytest.approx(691.4, abs=0.5) and weak.overspeed > weak.no_load_speed
    w = np.linspace(0.0, plain.overspeed * 0.999, 2001)
    lo_p, hi_p = torque_interval(w, plain)
    lo_w, hi_w = torque_interval(w, weak)
    assert np.all(hi_w >= hi_p - 1e-12) and np.all(lo_w <= lo_p + 1e-12)


@settings(max_examples=60, deadline=None)
@given(volts=st.floats(66.0, 84.0), speed=st.floats(-1.5, 1.5))
def test_a_bus_voltage_per_environment_is_the_region_at_that_voltage(volts, speed):
    """The clip with bus_voltage = V holds the torques of the region built at V (the spec with bus_voltage V)."""
    sat = saturation_for(load_robot(ROBOT))
    omega = speed * SPEC.kv * volts
    region = drive_region(SPEC, bus_voltage=volts)
    lo, hi = sat.torque_bounds(np.full((1, 12), omega / 9.0) * np.array([[1.0] + [0.0] * 11]), bus_voltage=volts)
    want_lo, want_hi = torque_interval(np.array([omega]), region)
    assert lo[0, 0] == pytest.approx(want_lo[0], abs=1e-9) and hi[0, 0] == pytest.approx(want_hi[0], abs=1e-9)


def test_the_nominal_bus_voltage_changes_nothing_and_every_path_agrees():
    sat = saturation_for(load_robot(ROBOT))
    rng = np.random.default_rng(3)
    tau, qd = rng.normal(0.0, 60.0, (512, 12)), rng.normal(0.0, 60.0, (512, 12))
    assert np.array_equal(sat(tau, qd, bus_voltage=np.full((512, 1), 81.0)), sat(tau, qd))
    volts = rng.uniform(66.0, 84.0, (512, 1))
    out = sat(tau, qd, bus_voltage=volts)
    assert np.max(sat.violation(out, qd, bus_voltage=volts)) < 1e-9
    per_motor = sat(tau, qd, bus_voltage=np.repeat(volts, 12, axis=1))
    assert np.array_equal(out, per_motor)
    graded = torch.tensor(tau, requires_grad=True)  # the allocating torch path
    t = sat(graded, torch.tensor(qd), bus_voltage=torch.tensor(volts))
    assert np.allclose(t.detach().numpy(), out, atol=1e-9)
    t.sum().backward()
    assert torch.isfinite(graded.grad).all()
    with pytest.raises(SaturationError, match=r"bus_voltage has shape \(3,\)"):
        sat(tau, qd, bus_voltage=np.ones(3))


def test_a_lower_battery_shrinks_the_region_and_mor_reports_the_range():
    speed = at_speed(SPEC)
    low, high = speed.battery
    assert (low.bus_voltage, high.bus_voltage) == (66.0, 84.0)
    assert low.corner_speed < speed.drive.corner_speed < high.corner_speed
    assert low.inner_box[1] < speed.drive.inner_box[1]
    assert speed.dc_law.corner_speed == pytest.approx(SPEC.kv * (81.0 - SPEC.resistance * 70.0))


BASE = {
    "name": "m", "kt": "0.138 N*m/A", "kv": "60 rpm/V", "resistance": "0.1 ohm", "bus_voltage": "81 V",
    "peak_torque": "12 N*m", "max_current": "70 A", "inductance": "70 uH", "pole_pairs": 10,
}  # fmt: skip


@pytest.mark.parametrize(
    ("extra", "drop", "message"),
    [
        ({"inductance_convention": "star"}, (), "inductance_convention': found 'star', expected one of line_to_line"),
        ({"inductance_convention": "phase"}, ("inductance",), "given without an inductance"),
        ({"field_weakening": "yes"}, (), "field_weakening': found 'yes', expected true or false"),
        ({"field_weakening": True}, ("max_current",), "needs the drive's phase-current limit: add max_current"),
        ({"field_weakening": True, "commutation": "six_step"}, (), "needs a field-oriented drive"),
        ({"bus_voltage_range": ["66 V", "80 V"]}, (), "expected a range holding bus_voltage 81 V"),
        ({"bus_voltage_range": "66-84 V"}, (), r"expected \[lowest, highest\]"),
        ({"bus_voltage_range": ["66 A", "84 V"]}, (), "bus_voltage_range"),
    ],
)
def test_drive_fields_are_checked(extra, drop, message):
    data = {k: v for k, v in BASE.items() if k not in drop} | extra
    with pytest.raises(HoundIdError, match=message):
        motor_spec_from_mapping(data, "m.yaml")


def test_an_inductance_without_its_convention_is_taken_line_to_line_with_a_warning():
    from hound_id.mor.spec import spec_warnings

    spec = motor_spec_from_mapping(BASE, "m.yaml")
    assert spec.drive.inductance_phase == pytest.approx(35e-6)
    assert any("without inductance_convention; taken as line_to_line" in w for w in spec_warnings(spec))
    no_poles = motor_spec_from_mapping({k: v for k, v in BASE.items() if k != "pole_pairs"}, "m.yaml")
    assert no_poles.drive is None
    assert any("without pole_pairs; the voltage edge ignores it" in w for w in spec_warnings(no_poles))


def test_a_bus_at_zero_volts_still_brakes_and_odd_shapes_are_refused():
    """0 V (or a negative voltage, taken as 0): the shorted winding's current brakes, it is not a free wheel."""
    sat = saturation_for(load_robot(ROBOT))
    qd = np.zeros((2, 12))
    qd[:, 0] = [100.0 / 9.0, -100.0 / 9.0]  # FL_HAA's motor at +-100 rad/s
    for volts in (0.0, -5.0):
        lo, hi = sat.torque_bounds(qd, bus_voltage=np.full((2, 1), volts))
        assert hi[0, 0] < -1.0 and lo[1, 0] > 1.0 and lo[0, 0] == hi[0, 0]
    with pytest.raises(SaturationError, match=r"bus_voltage has shape \(2, 1, 1\)"):
        sat(np.zeros((2, 12)), qd, bus_voltage=np.full((2, 1, 1), 81.0))
    with pytest.raises(SaturationError, match="does not broadcast"):
        sat(torch.zeros((2, 12)), torch.tensor(qd, dtype=torch.float32), bus_voltage=torch.full((2, 1, 1), 81.0))


def test_field_weakening_without_a_reactance_is_named():
    from hound_id.mor.spec import spec_warnings

    data = {k: v for k, v in BASE.items() if k != "inductance"} | {"field_weakening": True}
    spec = motor_spec_from_mapping(data, "m.yaml")
    assert any("field_weakening without a winding reactance" in w for w in spec_warnings(spec))


def test_the_runtime_carries_the_batterys_range(tmp_path):
    import hound_id.runtime
    from hound_id.export.run import formats_from, prepare
    from tests.export.conftest import write_export

    write_export(prepare(ROBOT, []), formats_from("bundle"), tmp_path / "out")
    rt = hound_id.runtime.load(tmp_path / "out" / "hound_like_bundle.yaml")
    assert rt.bus_voltage_range is not None and np.array_equal(rt.bus_voltage_range, np.tile([66.0, 84.0], (12, 1)))
    tau, qd = np.full((3, 12), 200.0), np.full((3, 12), 30.0)
    volts = np.array([[66.0], [81.0], [84.0]])
    assert np.array_equal(rt.saturate(tau, qd, bus_voltage=volts), rt.clip(tau, qd, volts))


def test_the_battery_range_from_the_command_line():
    import json

    from tests.conftest import run_cli

    out = run_cli("mor", "--spec", str(SHEET), "--bus-range", "60 V,84 V", "--json")
    assert out.returncode == 0, out.stderr
    battery = json.loads(out.stdout)["at_speed"]["battery"]
    assert [b["bus_voltage"] for b in battery] == [60.0, 84.0]
    want = operating_region(dataclasses.replace(SPEC, bus_voltage=60.0))
    assert battery[0]["corner_speed"] == pytest.approx(want.corner_speed)
    for args, message in (
        (("--spec", str(SHEET), "--bus-range", "90,100"), "--bus-range: found 90 V to 100 V, expected a range holding"),
        (("--spec", str(SHEET), "--bus-range", "66"), "separated by a comma"),
        (("--spec", str(SHEET), "--bus-range", "66 A,84 V"), "expected a voltage"),
        (("--robot", str(ROBOT), "--bus-range", "66,84"), "--bus-range goes with --spec"),
    ):
        bad = run_cli("mor", *args)
        assert bad.returncode == 2 and message in bad.stderr and "Traceback" not in bad.stderr
        assert len(bad.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("pairs", [0, 201, 2.5, True])
def test_pole_pairs_outside_the_span_of_motors_are_refused(pairs):
    import yaml

    data = yaml.safe_load(SHEET.read_text())
    data["pole_pairs"] = pairs
    with pytest.raises(HoundIdError, match="pole_pairs.*expected a whole number from 1 to 200"):
        motor_spec_from_mapping(data, "m.yaml")
