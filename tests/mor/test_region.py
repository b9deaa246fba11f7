import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hound_id.mor.region import halfspace_polygon, linear_region, operating_region, torque_interval
from hound_id.mor.region_report import bindings, overpromise
from hound_id.mor.spec import MotorSpec
from hound_id.mor.spec_sheet import load_motor_spec
from tests.conftest import MOTOR, SMALL_MOTOR
from tests.mor.curve_truth import brute_interval


@st.composite
def specs(draw, with_speed=None):
    kt = draw(st.floats(0.01, 2.0))
    kv = draw(st.floats(0.8, 1.2)) / kt
    has_speed = draw(st.booleans()) if with_speed is None else with_speed
    return MotorSpec(
        name="h",
        kt=kt,
        kv=kv,
        resistance=draw(st.floats(0.01, 5.0)),
        bus_voltage=draw(st.floats(5.0, 400.0)),
        peak_torque=draw(st.floats(0.1, 100.0)),
        max_current=draw(st.one_of(st.none(), st.floats(1.0, 300.0))),
        max_speed=draw(st.floats(10.0, 3000.0)) if has_speed else None,
    )


def signed_area(v):
    x, y = v[:, 0], v[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def test_characteristic_values_of_the_sample():
    spec = load_motor_spec(MOTOR)
    r = linear_region(spec)
    tl = 0.138 * 70
    assert r.stall_torque == pytest.approx(spec.kt * spec.bus_voltage / spec.resistance)
    assert r.no_load_speed == pytest.approx(spec.kv * spec.bus_voltage)
    assert r.corner_speed == pytest.approx(spec.kv * (spec.bus_voltage - spec.resistance * tl / spec.kt))
    assert r.overspeed == pytest.approx(spec.kv * (spec.bus_voltage + spec.resistance * tl / spec.kt))
    # Without a speed limit the region is the voltage band cut by the torque limits: a parallelogram.
    assert len(r.vertices) == 4
    assert np.any(np.all(np.isclose(r.vertices, [tl, r.corner_speed]), axis=1))


def test_speed_limit_cuts_the_corners():
    r = linear_region(load_motor_spec(SMALL_MOTOR))
    assert len(r.vertices) == 6
    assert np.max(np.abs(r.vertices[:, 1])) == pytest.approx(r.max_speed)


@settings(max_examples=200, deadline=None)
@given(specs())
def test_vertices_are_counter_clockwise_and_on_the_boundary(spec):
    r = linear_region(spec)
    v = r.vertices
    assert signed_area(v) > 0
    slack = v @ r.A.T - r.b
    tol = 1e-9 * np.maximum(r.b, 1.0)
    assert np.all(slack <= tol)
    assert np.all(np.sum(np.abs(slack) <= 1e-7 * np.maximum(r.b, 1.0), axis=1) >= 2)  # each vertex: 2 active rows
    assert r.contains(0.0, 0.0)
    # The region is centrally symmetric.
    assert np.allclose(np.sort(v, axis=0), np.sort(-v, axis=0), atol=1e-9 * np.abs(v).max())


@settings(max_examples=200, deadline=None)
@given(specs(), st.floats(-1.5, 1.5))
def test_torque_interval_is_the_slice_of_the_region(spec, frac):
    r = linear_region(spec)
    omega = frac * r.overspeed
    lo, hi = torque_interval(omega, r)
    if r.max_speed is not None and abs(omega) > r.max_speed:
        # Past the rated speed only braking torque passes.
        assert (hi <= 0.0) if omega > 0 else (lo >= 0.0)
        return
    if abs(omega) > r.overspeed:
        # Past overspeed: the braking torque of the current the back-EMF forces, Kt (|omega|/Kv - V)/R.
        forced = -np.sign(omega) * spec.kt * (abs(omega) / spec.kv - spec.bus_voltage) / spec.resistance
        assert lo == pytest.approx(hi) and hi == pytest.approx(forced)
        assert abs(hi) >= r.torque_limit * (1 - 1e-12)
        return
    assert lo <= hi
    assert r.contains(lo, omega) and r.contains(hi, omega)
    scale = max(r.torque_limit, r.stall_torque, 1.0)  # contains() tolerates 1e-9 of each row's bound
    assert not r.contains(hi + 1e-6 * scale, omega)
    assert not r.contains(lo - 1e-6 * scale, omega)


def test_halfspace_polygon_square():
    A = np.array([[1, 0], [-1, 0], [0, 1], [0, -1], [0, 0]])
    v = halfspace_polygon(A, np.array([1.0, 1.0, 2.0, 2.0, 1.0]))
    assert signed_area(v) == pytest.approx(8.0)
    with pytest.raises(ValueError):
        halfspace_polygon(A[:4], np.array([1.0, -1.0, 1.0, 1.0]))


def test_region_json_schema():
    data = operating_region(load_motor_spec(MOTOR)).to_dict()
    assert data["schema"] == "hound-id/mor/3"
    assert data["current_curve"]["form"] == "quadratic" and data["limit_current"] == pytest.approx(70.0)
    assert data["linear_torque_limit"] == pytest.approx(9.66) and data["torque_limit"] == pytest.approx(8.415792)
    for key in ("motor", "halfspaces", "vertices", "stall_torque", "no_load_speed", "corner_speed", "overspeed"):
        assert key in data
    assert len(data["halfspaces"]["A"]) == len(data["halfspaces"]["b"])


def test_corner_speed_is_clipped_and_inner_box_stays_inside():
    # torque limit above the stall torque: no speed has full motoring torque
    weak = linear_region(MotorSpec(name="w", kt=0.1, kv=10.0, resistance=1.0, bus_voltage=24.0, peak_torque=5.0))
    assert weak.corner_speed == 0.0
    t, w = weak.inner_box
    assert t == pytest.approx(weak.stall_torque / 2) and w == pytest.approx(weak.no_load_speed / 2)
    # a rated speed below the voltage-limited corner
    capped = linear_region(
        MotorSpec(name="c", kt=0.083, kv=10.47, resistance=0.31, bus_voltage=24.0, peak_torque=2.4, max_speed=104.7)
    )
    assert capped.corner_speed == pytest.approx(104.7)
    assert capped.inner_box == pytest.approx((2.4, 104.7))


@settings(max_examples=200, deadline=None)
@given(specs())
def test_inner_box_is_inside_and_largest(spec):
    r = linear_region(spec)
    t, w = r.inner_box
    corners = np.array([[sx * t, sy * w] for sx in (-1, 1) for sy in (-1, 1)])
    assert np.all(r.contains(corners[:, 0], corners[:, 1], rtol=1e-9))
    # no box of larger area fits: a brute-force search over the torque half-width
    best = 0.0
    for tt in np.linspace(1e-6, r.torque_limit, 400):
        ww = r.no_load_speed * (1 - tt / r.stall_torque)
        if r.max_speed is not None:
            ww = min(ww, r.max_speed)
        best = max(best, tt * max(ww, 0.0))
    assert t * w >= best * (1 - 1e-3)


def write_envelope_spec(path, effects, motor=MOTOR):
    """A motor spec with a measured envelope (as ``mor --compare --out`` writes it) for hidden ``effects``."""
    import yaml

    from hound_id.mor.envelope import EnvelopeInputs, polyline

    line = polyline(effects, EnvelopeInputs(load_motor_spec(motor)))
    envelope = {k: line.to_dict()[k] for k in ("speeds", "lower", "upper", "tolerance")}
    data = {"schema": "hound-id/motor/1", "base": str(motor), "envelope": {"effects": effects, **envelope}}
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize(
    "effects", [{}, {"bus_sag": 0.15}, {"bus_sag": 0.15, "inductance": 1e-4}, {"current_limit": 50.0}]
)
def test_measured_region_traces_the_polyline_and_cuts_inside_it(tmp_path, effects):
    from hound_id.mor.clip_bounds import polyline_of
    from hound_id.mor.region import _slice, measured_region

    spec = load_motor_spec(write_envelope_spec(tmp_path / "env.yaml", effects))
    region, sheet = measured_region(spec), linear_region(spec)  # the envelope model starts from linear Kt
    w, lower, upper = polyline_of(spec.envelope)
    # the traced vertices follow the edges: every polyline point on the boundary, just past it outside
    ring = np.vstack([region.vertices, region.vertices[:1]])
    from matplotlib.path import Path

    boundary = Path(ring[:, ::-1])  # (omega, tau): speeds on x
    inside = np.column_stack([w, 0.5 * (lower + upper)])
    assert boundary.contains_points(inside).all()
    assert not boundary.contains_points(np.column_stack([w[1:-1], upper[1:-1] + 0.02])).any()
    # the half-spaces are a convex cut inside the polyline, short of it by convexity_loss at most
    grid = np.linspace(w[0], w[-1], 3001)
    lo_cut, hi_cut = _slice(grid, region)
    assert np.all(hi_cut <= np.interp(grid, w, upper) + 1e-9) and np.all(lo_cut >= np.interp(grid, w, lower) - 1e-9)
    assert np.max(np.interp(grid, w, upper) - hi_cut) == pytest.approx(region.convexity_loss, abs=1e-3)
    # the inner box is inside the traced region and reaches the corner of the measured edge (where the full torque
    # the envelope allows ends; a kink between polyline points is read to within a segment)
    T, W = region.inner_box
    assert T <= float(np.min(np.interp(np.linspace(-W, W, 1001), w, upper))) + 1e-9
    assert W == pytest.approx(region.corner_speed, rel=0.01)
    assert T == pytest.approx(float(np.max(upper)), rel=0.01)
    if not effects:  # no effect: the spec sheet's region
        assert region.convexity_loss < 1e-9
        assert T * W == pytest.approx(sheet.inner_box[0] * sheet.inner_box[1], rel=2e-3)
        assert region.corner_speed == pytest.approx(sheet.corner_speed, rel=0.01)


@given(spec=specs())
@settings(max_examples=40, deadline=None)
def test_the_traced_box_of_a_spec_sheet_region_is_its_closed_form(spec):
    from hound_id.mor.region import _traced_box

    region = linear_region(spec)
    T, W = _traced_box(region.vertices)
    assert T * W == pytest.approx(region.inner_box[0] * region.inner_box[1], rel=2e-3)


# The curve-limited region, against an independent computation: at each speed, scan the currents the drive can make
# (|R i + omega/Kv| <= V, |i| <= i_max) and take the torques of the quadratic tau = Kt i - k i|i| (k from the 20 %
# point, written out here, not taken from hound_id) within the peak torque.


def test_the_sample_torque_limit_follows_the_curve():
    spec = dataclasses.replace(load_motor_spec(MOTOR), inductance=None)  # the DC law (the dq model: test_drive.py)
    region = operating_region(spec)
    # Kt i_max - k i_max^2 with k = 0.16 Kt^2 / P: 9.66 - 0.16 * 0.138^2 / 12 * 70^2
    assert region.torque_limit == pytest.approx(9.66 - 0.16 * 0.138**2 / 12 * 4900, rel=1e-12)
    assert region.torque_limit == pytest.approx(8.4158, abs=1e-4)
    assert linear_region(spec).torque_limit == pytest.approx(9.66)
    # the driver's 70 A binds (the 20 % point needs 108.7 A): corner and overspeed at 70 A, as in the linear region
    assert region.corner_speed == pytest.approx(spec.kv * (spec.bus_voltage - spec.resistance * 70.0))
    assert region.overspeed == pytest.approx(spec.kv * (spec.bus_voltage + spec.resistance * 70.0))
    over = overpromise(linear_region(spec), region)
    assert over.largest == pytest.approx(9.66 - region.torque_limit) and over.share == pytest.approx(0.1478, abs=1e-4)
    assert [b.limit for b in bindings(region, spec)] == ["current", "voltage", "voltage", "back-EMF"]


def test_a_peak_limited_motor_has_a_lower_corner_than_linear_kt():
    spec = load_motor_spec(SMALL_MOTOR)  # 2.4 N m peak, 40 A driver: the curve needs 36.1 A for 2.4 N m
    region, linear = operating_region(spec), linear_region(spec)
    k = 0.16 * spec.kt**2 / spec.peak_torque
    current = 2 * spec.peak_torque / (spec.kt + np.sqrt(spec.kt**2 - 4 * k * spec.peak_torque))
    assert current == pytest.approx(36.14, abs=0.01)
    assert region.torque_limit == pytest.approx(2.4)
    assert region.corner_speed == pytest.approx(spec.kv * (spec.bus_voltage - spec.resistance * current))
    assert region.corner_speed < 0.86 * linear.corner_speed
    assert bindings(region, spec)[0].limit == "torque"


@settings(max_examples=60, deadline=None)
@given(specs(), st.floats(-1.6, 1.6))
def test_the_curved_interval_matches_a_brute_force_scan_of_currents(spec, frac):
    region = operating_region(spec)
    omega = frac * region.overspeed
    lo, hi = (float(v) for v in torque_interval(omega, region))
    if region.max_speed is not None and abs(omega) > region.max_speed * (1 + 1e-9):
        assert (hi <= 0.0) if omega > 0 else (lo >= 0.0)
        if abs(omega) <= region.overspeed:
            return
    brute = brute_interval(spec, omega)
    if brute is None or abs(omega) > region.overspeed * (1 + 1e-9):
        # past overspeed: the braking torque of the current the back-EMF forces, (V - omega/Kv)/R for omega > 0
        k = 0.16 * spec.kt**2 / spec.peak_torque
        i = (np.sign(omega) * spec.bus_voltage - omega / spec.kv) / spec.resistance
        m = min(abs(i), spec.kt / (2 * k))
        forced = np.sign(i) * (spec.kt * m - k * m * m)
        assert lo == pytest.approx(forced, rel=1e-9) and hi == pytest.approx(forced, rel=1e-9)
        assert abs(forced) >= region.torque_limit * (1 - 1e-9)
        return
    window = 2 * spec.bus_voltage / spec.resistance if spec.max_current is None else 2 * spec.max_current
    tol = max(1e-6 * region.torque_limit, 2 * spec.kt * window / 200000)  # the scan's step in torque
    if region.max_speed is None or abs(omega) <= region.max_speed:
        assert hi == pytest.approx(brute[1], abs=tol)
        assert lo == pytest.approx(brute[0], abs=tol)


@settings(max_examples=40, deadline=None)
@given(specs())
def test_curved_vertices_lie_on_the_edges_and_the_cut_inside(spec):
    from hound_id.mor.region import _slice

    region = operating_region(spec)
    v = region.vertices
    assert signed_area(v) > 0
    lo, hi = torque_interval(v[:, 1], region)
    on_edge = np.minimum(np.abs(v[:, 0] - lo), np.abs(v[:, 0] - hi))
    assert np.all(on_edge <= 1e-9 * max(region.torque_limit, 1.0))
    # the half-spaces are a convex cut inside the exact edges, short by convexity_loss at most
    w = np.linspace(-region.overspeed, region.overspeed, 2001)
    lo_x, hi_x = torque_interval(w, region)
    lo_cut, hi_cut = _slice(w, region)
    ok = np.isfinite(hi_cut)
    tol = 1e-9 * max(region.torque_limit, 1.0)
    assert np.all(hi_cut[ok] <= hi_x[ok] + tol) and np.all(lo_cut[ok] >= lo_x[ok] - tol)
    assert np.nanmax(hi_x - hi_cut) <= region.convexity_loss + 1e-3 * region.torque_limit
    # the inner box's corners are inside the exact region
    T, W = region.inner_box
    blo, bhi = torque_interval(np.array([-W, W]), region)
    assert np.all(bhi >= T * (1 - 1e-9)) and np.all(blo <= -T * (1 - 1e-9))


@settings(max_examples=40, deadline=None)
@given(specs())
def test_the_straight_line_gap_is_the_largest_over_a_dense_grid(spec):
    from hound_id.mor.region_report import straight_gap
    from hound_id.mor.saturation import dc_motor_clip

    region = operating_region(spec)
    over, under = straight_gap(region)
    w = np.linspace(-region.overspeed, region.overspeed, 400001)
    lo, hi = torque_interval(w, region)
    big = np.full_like(w, 1e9)
    args = (region.stall_torque, region.no_load_speed, region.torque_limit)
    dc_hi, dc_lo = dc_motor_clip(big, w, *args), dc_motor_clip(-big, w, *args)
    dense_over = max(float(np.max(dc_hi - hi)), float(np.max(lo - dc_lo)), 0.0)
    dense_under = max(float(np.max(hi - dc_hi)), float(np.max(dc_lo - lo)), 0.0)
    tol = 1e-9 * max(region.torque_limit, 1.0)
    assert over >= dense_over - tol and under >= dense_under - tol  # the kinks are on its grid
    step = 2 * region.overspeed / 400000 * region.back_emf_damping * 4  # what the dense grid can miss at a kink
    assert over <= dense_over + step + tol and under <= dense_under + step + tol
