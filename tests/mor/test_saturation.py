import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from hound_id.errors import SaturationError
from hound_id.mor.current_curve import CurrentCurve
from hound_id.mor.region import operating_region, torque_interval
from hound_id.mor.robot import load_robot, robot_from_mapping
from hound_id.mor.saturation import coupled_groups, dc_motor_clip, saturation_for
from hound_id.mor.spec import MotorSpec
from tests.conftest import ROBOT, SMALL_MOTOR
from tests.mor.curve_truth import brute_interval

ROBOT_SAT = saturation_for(load_robot(ROBOT))
N = ROBOT_SAT.n
#: Where the sample's drive loses control (its dq window collapses onto the diode bridge's braking).
MOTOR_OVERSPEED = float(operating_region(load_robot(ROBOT).motor_specs["FL_HAA_motor"]).overspeed)
SPECS = [load_robot(ROBOT).motor_specs[m] for m in load_robot(ROBOT).motors]


def quadratic_current(spec, tau):
    """Current [A] for a torque on the quadratic through the spec's 20 % point, written out (not hound_id's)."""
    k = 0.16 * spec.kt**2 / spec.peak_torque
    with np.errstate(invalid="ignore"):  # NaN past the curve's top: only ever compared past overspeed, masked out
        return np.sign(tau) * 2 * np.abs(tau) / (spec.kt + np.sqrt(spec.kt**2 - 4 * k * np.abs(tau)))


DEVICES = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])

unit = st.floats(-1.0, 1.0, allow_nan=False)


def commands(scale_tau=250.0, scale_qd=120.0, batch=8):
    return st.tuples(
        arrays(float, (batch, N), elements=unit).map(lambda u: u * scale_tau),
        arrays(float, (batch, N), elements=unit).map(lambda u: u * scale_qd),
    )


def within_overspeed(qd):
    _, omega = ROBOT_SAT.motor_state(np.zeros_like(qd), qd)
    return np.abs(omega) <= MOTOR_OVERSPEED


@settings(max_examples=150, deadline=None)
@given(commands())
def test_output_is_feasible(cmd):
    tau, qd = cmd
    out = ROBOT_SAT(tau, qd)
    violation = ROBOT_SAT.violation(out, qd)
    assert np.all(violation <= 1e-9 * 250)
    tau_m, omega = ROBOT_SAT.motor_state(out, qd)
    # feasibility against the region itself, motor by motor, inside overspeed
    mask = within_overspeed(qd)
    assert np.all(np.abs(tau_m[mask]) <= np.broadcast_to(ROBOT_SAT.torque_limit, tau_m.shape)[mask] * (1 + 1e-12))
    # the voltage circle |(R i + omega/Kv, X i)| <= V, i the current the 20 % point's quadratic needs and X the
    # winding's reactance sqrt(3) p L_phase omega (70 uH line to line: 35 uH per phase), and the driver's limit
    for m, spec in enumerate(SPECS):
        i = quadratic_current(spec, tau_m[:, m])
        reactance = np.sqrt(3.0) * 10 * 35e-6 * omega[:, m]
        volts = np.hypot(spec.resistance * i + omega[:, m] / spec.kv, reactance * i)
        inside = mask[:, m]
        assert np.all(np.abs(volts[inside]) <= spec.bus_voltage * (1 + 1e-9))
        assert np.all(np.abs(i[inside]) <= spec.max_current * (1 + 1e-9))


@settings(max_examples=150, deadline=None)
@given(commands())
def test_idempotent(cmd):
    tau, qd = cmd
    once = ROBOT_SAT(tau, qd)
    assert np.allclose(ROBOT_SAT(once, qd), once, rtol=1e-12, atol=1e-9)


@settings(max_examples=150, deadline=None)
@given(commands(scale_tau=1.0, scale_qd=1.0))
def test_commands_inside_the_region_pass_unchanged(cmd):
    u_tau, u_qd = cmd
    # scale into the inner boxes: everything there is feasible
    regions = _regions()
    T = np.array([j.inner_box.effort for j in regions.joints]) * 0.999
    W = np.array([j.inner_box.velocity for j in regions.joints]) * 0.999
    tau, qd = u_tau * T, u_qd * W
    assert np.array_equal(ROBOT_SAT.violation(tau, qd), np.zeros_like(tau))
    assert np.allclose(ROBOT_SAT(tau, qd), tau, rtol=1e-12, atol=1e-12)


_cache: dict = {}


def _regions():
    if "r" not in _cache:
        from hound_id.mor.joint_space import robot_regions

        _cache["r"] = robot_regions(load_robot(ROBOT))
    return _cache["r"]


@st.composite
def uncoupled_robot(draw, curve="linear"):
    k = draw(st.integers(1, 4))
    specs, transmissions, ratios = {}, [], []
    for i in range(k):
        kt = draw(st.floats(0.02, 1.0))
        specs[f"m{i}"] = MotorSpec(
            name=f"m{i}",
            kt=kt,
            kv=draw(st.floats(0.85, 1.1)) / kt,
            resistance=draw(st.floats(0.02, 3.0)),
            bus_voltage=draw(st.floats(12.0, 100.0)),
            peak_torque=draw(st.floats(0.2, 20.0)),
            max_current=draw(st.one_of(st.none(), st.floats(2.0, 100.0))),
            kt_curve=curve,
        )
        g = draw(st.floats(1.0, 30.0)) * draw(st.sampled_from([1.0, -1.0]))
        ratios.append(g)
        transmissions.append(
            {"type": "ratio", "joints": [f"j{i}"], "motors": [f"m{i}"], "motor_spec": f"m{i}", "ratios": [g]}
        )
    return specs, transmissions, np.array(ratios)


def uncoupled_saturation(robot_def):
    """The saturation and the motor regions of an :func:`uncoupled_robot`."""
    import hound_id.mor.robot as robot_mod

    specs, transmissions, ratios = robot_def
    k = len(ratios)
    robot = robot_mod.Robot(
        name="u",
        joints=tuple(f"j{i}" for i in range(k)),
        transmissions=tuple(robot_mod.from_ratios(t["joints"], t["motors"], t["ratios"]) for t in transmissions),
        motor_specs={f"m{i}": specs[f"m{i}"] for i in range(k)},
    )
    return saturation_for(robot), [operating_region(specs[f"m{i}"]) for i in range(k)]


@settings(max_examples=100, deadline=None)
@given(uncoupled_robot(), st.data())
def test_uncoupled_joints_equal_the_per_joint_dc_motor_clip(robot_def, data):
    specs, _, ratios = robot_def
    k = len(ratios)
    sat, regions = uncoupled_saturation(robot_def)
    g = np.abs(ratios)
    saturation_effort = np.array([r.stall_torque for r in regions]) * g
    velocity_limit = np.array([r.no_load_speed for r in regions]) / g
    effort_limit = np.array([r.torque_limit for r in regions]) * g
    # speeds up to twice the overspeed, so past-overspeed behaviour is compared too
    u = data.draw(arrays(float, (2, 16, k), elements=unit))
    tau = u[0] * effort_limit * 2.0
    qd = u[1] * np.array([r.overspeed for r in regions]) / g * 2.0
    ours = sat(tau, qd)
    # a reversing gear (negative ratio) flips torque and speed together
    theirs = np.where(
        ratios < 0,
        -dc_motor_clip(-tau, -qd, saturation_effort, velocity_limit, effort_limit),
        dc_motor_clip(tau, qd, saturation_effort, velocity_limit, effort_limit),
    )
    # past overspeed the DC clip gives the torque limit; the back-EMF forces Kt (|omega|/Kv - V)/R of braking
    omega = qd * ratios
    over = np.abs(omega) > np.array([r.overspeed for r in regions])
    kt, kv, res, volts = (
        np.array([getattr(specs[f"m{i}"], a) for i in range(k)]) for a in ("kt", "kv", "resistance", "bus_voltage")
    )
    forced = -np.sign(omega) * kt * (np.abs(omega) / kv - volts) / res * ratios
    theirs = np.where(over, forced, theirs)
    assert np.allclose(ours, theirs, rtol=1e-9, atol=1e-9 * effort_limit.max())


@settings(max_examples=60, deadline=None)
@given(uncoupled_robot(curve="quadratic"), st.data())
def test_uncoupled_curved_joints_clip_to_the_brute_force_interval(robot_def, data):
    """The clip's fused numpy arithmetic against the brute-force current scan of tests/mor/test_region.py."""
    specs, _, ratios = robot_def
    k = len(ratios)
    sat, regions = uncoupled_saturation(robot_def)
    u = data.draw(arrays(float, (2, 4, k), elements=unit))
    tau_m = u[0] * np.array([r.torque_limit for r in regions]) * 1.5
    omega = u[1] * np.array([r.overspeed for r in regions]) * 0.999
    out_m = sat(tau_m * ratios, omega / ratios) / ratios  # joint torque g tau_m, joint speed omega / g
    for m in range(k):
        spec = specs[f"m{m}"]
        top = spec.peak_torque / (0.32 * spec.kt)  # the quadratic's top current: the scan spans at most twice it
        scale = 2e-4 * regions[m].torque_limit + 2 * spec.kt * 2 * top / 200000  # two steps of the scan
        for row in range(4):
            lo, hi = brute_interval(spec, omega[row, m])
            want = min(max(tau_m[row, m], lo), hi)
            assert out_m[row, m] == pytest.approx(want, abs=scale)


def small_motor_robot():
    """One joint on the small sample motor (which has a rated max_speed), ratio 1."""
    return robot_from_mapping(
        {
            "name": "s",
            "motor_specs": {"s": str(SMALL_MOTOR)},
            "joints": ["j"],
            "transmissions": [{"type": "ratio", "joints": ["j"], "motors": ["m"], "motor_spec": "s", "ratios": [1.0]}],
        },
        source="inline",
        base=SMALL_MOTOR.parent,
    )


def test_past_overspeed_full_braking_and_past_max_speed_braking_only(write_yaml):
    robot = small_motor_robot()
    sat = saturation_for(robot)
    spec = robot.motor_specs["m"]
    region = operating_region(spec)
    far = np.array([[region.overspeed * 1.5]])
    # past overspeed, whatever is commanded: the braking torque of the current the back-EMF forces
    i = (spec.bus_voltage - far[0, 0] / spec.kv) / spec.resistance
    k = 0.16 * spec.kt**2 / spec.peak_torque
    i = max(i, -spec.kt / (2 * k))  # the curve is held at its top beyond its top current
    forced = spec.kt * i + k * i * i  # i < 0: Kt i - k i|i|
    assert forced < -region.torque_limit and forced == pytest.approx(-spec.peak_torque / 0.64)
    for command in (5.0, 0.0, -5.0, -100.0):
        assert sat(np.array([[command]]), far)[0, 0] == pytest.approx(forced)
        assert sat(np.array([[-command]]), -far)[0, 0] == pytest.approx(-forced)
    # between max_speed and no-load speed the voltage line would allow motoring; the speed limit does not
    w = np.array([[region.max_speed * 1.05]])
    assert region.max_speed * 1.05 < region.no_load_speed
    assert sat(np.array([[1.0]]), w)[0, 0] == 0.0
    assert sat(np.array([[-1.0]]), w)[0, 0] == -1.0


@pytest.mark.parametrize("device", DEVICES)
def test_torch_matches_numpy_and_stays_in_torch(device):
    rng = np.random.default_rng(1)
    tau = rng.uniform(-250, 250, size=(64, N))
    qd = rng.uniform(-120, 120, size=(64, N))
    expected = ROBOT_SAT(tau, qd)
    t_tau = torch.tensor(tau, device=device, requires_grad=True)
    t_qd = torch.tensor(qd, device=device)
    out = ROBOT_SAT(t_tau, t_qd)
    assert isinstance(out, torch.Tensor) and out.device.type == device and out.dtype == torch.float64
    assert np.allclose(out.detach().cpu().numpy(), expected, rtol=1e-12, atol=1e-9)
    # autograd flows through: proof that no numpy round trip happened
    out.sum().backward()
    assert t_tau.grad is not None and torch.isfinite(t_tau.grad).all()
    out32 = ROBOT_SAT(t_tau.detach().float(), t_qd.float())
    assert out32.dtype == torch.float32
    assert np.allclose(out32.cpu().numpy(), expected, rtol=1e-4, atol=1e-3)


def test_batch_shapes_and_errors():
    tau = np.zeros((3, 5, N))
    assert ROBOT_SAT(tau, tau).shape == (3, 5, N)
    assert ROBOT_SAT(np.zeros(N, dtype=int), np.zeros(N)).dtype == np.float64
    with pytest.raises(SaturationError, match=r"expected both \(\.\.\., 12\), the same shape"):
        ROBOT_SAT(np.zeros((4, 11)), np.zeros((4, 11)))
    with pytest.raises(SaturationError, match=r"tau has shape \(10, 12\) and qd \(5, 12\)"):
        ROBOT_SAT(np.zeros((10, N)), np.zeros((5, N)))
    with pytest.raises(SaturationError, match="both be numpy arrays or both torch"):
        ROBOT_SAT(torch.zeros(N), np.zeros(N))


def test_results_are_not_aliased_and_threads_do_not_share_scratch():
    import threading

    rng = np.random.default_rng(3)
    inputs = [(rng.uniform(-250, 250, (256, N)), rng.uniform(-120, 120, (256, N))) for _ in range(8)]
    expected = [ROBOT_SAT(t, q).copy() for t, q in inputs]
    first = ROBOT_SAT(*inputs[0])
    ROBOT_SAT(*inputs[1])
    assert np.array_equal(first, expected[0])  # a later call does not overwrite an earlier result
    results: dict[int, list[np.ndarray]] = {}

    def work(k: int) -> None:
        results[k] = [ROBOT_SAT(t, q) for _ in range(50) for t, q in [inputs[k]]]

    threads = [threading.Thread(target=work, args=(k,)) for k in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for k in range(8):
        assert all(np.array_equal(r, expected[k]) for r in results[k])


def test_float32_numpy_path():
    rng = np.random.default_rng(4)
    tau = rng.uniform(-250, 250, (128, N))
    qd = rng.uniform(-120, 120, (128, N))
    out32 = ROBOT_SAT(tau.astype(np.float32), qd.astype(np.float32))
    assert out32.dtype == np.float32
    assert np.allclose(out32, ROBOT_SAT(tau, qd), rtol=1e-4, atol=1e-3)


def test_torque_bounds_are_the_motor_intervals():
    from hound_id.mor.region import torque_interval

    rng = np.random.default_rng(5)
    qd = rng.uniform(-80, 80, (32, N))
    lo, hi = ROBOT_SAT.torque_bounds(qd)
    _, omega = ROBOT_SAT.motor_state(np.zeros_like(qd), qd)
    robot = load_robot(ROBOT)
    for m, motor in enumerate(robot.motors):
        want_lo, want_hi = torque_interval(omega[:, m], operating_region(robot.motor_specs[motor]))
        assert np.allclose(lo[:, m], want_lo) and np.allclose(hi[:, m], want_hi)


# --- feasibility for every finite input ------------------------------------------------------------------------

DTYPES = [np.float32, np.float64]
#: "torch-gpu": CPU tensors through the path GPU tensors take (torch operations only, always exact).
BACKENDS = ["numpy", "torch", "torch-gpu"]
#: Joint speeds the property tests draw [rad/s]: past every motor's overspeed, both ways.
QD_SCALE = 120.0
#: Worst mapping gain |A^-1| |A| (column sums): how much a rounding of the clipped motor torques can grow.
GAIN = float((np.abs(ROBOT_SAT.A_inv) @ np.abs(ROBOT_SAT.A)).sum(axis=0).max())


def to_backend(x, backend, dtype, **kw):
    if backend.startswith("torch"):
        return torch.tensor(np.asarray(x, dtype=dtype), **kw)
    return np.asarray(x, dtype=dtype)


def saturate(sat, tau, qd, backend, dtype, **kw):
    """sat(tau, qd) in the backend; "torch-gpu" takes the GPU tensors' path on the CPU."""
    from unittest import mock

    import hound_id.mor.saturation as saturation

    views = (lambda *a: None) if backend == "torch-gpu" else saturation.numpy_views
    with mock.patch.object(saturation, "numpy_views", views):
        return sat(to_backend(tau, backend, dtype, **kw), to_backend(qd, backend, dtype))


def to_numpy(x):
    return x.detach().cpu().numpy() if isinstance(x, torch.Tensor) else np.asarray(x)


def feasibility_error(sat, out, qd, dtype):
    """Largest motor-torque excess past the motor's interval, in units of tolerance (<= 1 passes).

    The saturated torques are mapped to motor space in float64, the interval taken at the float64
    speeds of the given (dtype) velocities. The tolerance is relative to the limits, not to the input:
    a few roundings of the clipped motor torques through A^-1 and back, and of the voltage line.
    """
    out64, qd64 = to_numpy(out).astype(np.float64), to_numpy(qd).astype(np.float64)
    assert np.all(np.isfinite(out64)), "saturated torques must be finite"
    tau_m = out64 @ sat.A
    lo, hi = sat.torque_bounds(qd64)
    u = np.abs(qd64 @ (sat.A_inv.T * sat.back_emf_damping))
    scale = (1.0 + GAIN) * sat.torque_limit.max() + sat.stall_torque + u
    tol = 16 * np.finfo(dtype).eps * scale
    excess = np.maximum(tau_m - hi, lo - tau_m)
    return float(np.max(excess / tol)), float(np.max(excess / sat.torque_limit))


@st.composite
def huge_commands(draw, dtype, batch=6):
    """Commands from 1e-3 to 1e30 N m (and zeros) in every sign and joint; speeds within QD_SCALE."""
    magnitude = st.one_of(
        st.just(0.0),
        st.builds(lambda m, e: m * 10.0**e, st.floats(1.0, 9.99), st.integers(-3, 30)),
    )
    signed = st.builds(lambda s, m: s * m, st.sampled_from([1.0, -1.0]), magnitude)
    tau = np.array(draw(st.lists(signed, min_size=batch * N, max_size=batch * N))).reshape(batch, N)
    qd = draw(arrays(np.float64, (batch, N), elements=unit)) * QD_SCALE
    return tau.astype(dtype), qd.astype(dtype)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("dtype", DTYPES)
@settings(max_examples=120, deadline=None)
@given(data=st.data())
def test_saturated_torques_are_feasible_for_commands_up_to_1e30(dtype, backend, data):
    tau, qd = data.draw(huge_commands(dtype))
    out = saturate(ROBOT_SAT, tau, qd, backend, dtype)
    assert to_numpy(out).dtype == dtype
    assert feasibility_error(ROBOT_SAT, out, qd, dtype)[0] <= 1.0


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("dtype", DTYPES)
def test_largest_finite_commands_and_speeds(dtype, backend):
    """Commands and speeds at the dtype's largest finite value, both signs, in every joint, and inf."""
    big = float(np.finfo(dtype).max)
    eye = np.eye(N)
    tau = np.vstack([eye * big, -eye * big, np.full((1, N), big), np.full((1, N), -big), np.full((1, N), np.inf)])
    qd = np.zeros_like(tau)
    out = saturate(ROBOT_SAT, tau, qd, backend, dtype)
    assert feasibility_error(ROBOT_SAT, out, qd, dtype)[0] <= 1.0
    # at the largest speeds every motor is far past overspeed: full braking torque, finite
    fast = np.vstack([np.full((1, N), big), np.full((1, N), -big)])
    out = saturate(ROBOT_SAT, fast * 0.0 + 1.0, fast, backend, dtype)
    out64 = to_numpy(out).astype(np.float64)
    assert np.all(np.isfinite(out64))
    _, omega = ROBOT_SAT.motor_state(np.zeros((2, N)), fast.astype(np.float64))
    tau_m = out64 @ ROBOT_SAT.A
    # with the winding's reactance the diode bridge's braking fades at such speeds (the current turns into the d
    # axis); the window is held where it is at SPEED_CAP no-load speeds: a few mN m of braking, finite in every dtype
    far = [torque_interval(np.array([1e30]), operating_region(spec)) for spec in SPECS]
    braking = -np.sign(omega) * np.array([abs(float(lo[0])) for lo, _ in far])
    assert np.all(np.abs(braking) < 0.01) and np.all(np.abs(braking) > 0)
    assert np.allclose(tau_m, braking, rtol=1e-3 if dtype == np.float32 else 1e-9)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("dtype", DTYPES)
def test_the_reported_extreme_commands(dtype, backend):
    """Before the exact float32 path a 1e7 N m command gave 86 N m, not 86.94; 1e8 broke the limit; 1e12 gave 0."""
    expected = ROBOT_SAT(np.full((1, N), 100.0), np.zeros((1, N)))  # 86.94, 82.11, 72.45 N m ...
    for magnitude in (1e7, 1e8, 1e12, 1e16, 1e30):
        tau = np.full((1, N), magnitude)
        out = saturate(ROBOT_SAT, tau, np.zeros((1, N)), backend, dtype)
        assert np.allclose(to_numpy(out), expected, rtol=8 * np.finfo(dtype).eps * GAIN, atol=0), magnitude


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("dtype", DTYPES)
@settings(max_examples=60, deadline=None)
@given(cmd=commands(scale_tau=1.0, scale_qd=1.0))
def test_commands_inside_pass_bit_for_bit_in_every_dtype(dtype, backend, cmd):
    u_tau, u_qd = cmd
    regions = _regions()
    T = np.array([j.inner_box.effort for j in regions.joints]) * 0.999
    W = np.array([j.inner_box.velocity for j in regions.joints]) * 0.999
    out = saturate(ROBOT_SAT, u_tau * T, u_qd * W, backend, dtype)
    assert np.array_equal(to_numpy(out), (u_tau * T).astype(dtype))


@settings(max_examples=150, deadline=None)
@given(commands(scale_tau=400.0, scale_qd=150.0))
def test_ordinary_commands_give_what_the_correction_formula_gave(cmd):
    """For ordinary commands the new back-map (the clipped motor torques through A^-T) equals, to rounding,
    the former one (the command plus the mapped correction)."""
    tau, qd = cmd
    lo, hi = ROBOT_SAT.torque_bounds(qd)
    tau_m = tau @ ROBOT_SAT.A
    former = tau + (np.clip(tau_m, lo, hi) - tau_m) @ ROBOT_SAT.A_inv
    assert np.allclose(ROBOT_SAT(tau, qd), former, rtol=1e-12, atol=1e-11)


def test_joints_of_unclipped_groups_pass_exactly_and_others_follow_the_clip():
    """A clipped knee motor changes both joints of its hollow-shaft group, nothing else."""
    tau = np.zeros((1, N))
    knee = ROBOT_SAT.joints.index("FL_KFE")
    tau[0, knee] = 1e6
    tau[0, 0] = 3.3  # FL_HAA, its own group, not clipped
    out = ROBOT_SAT(tau, np.zeros((1, N)))
    groups = coupled_groups(ROBOT_SAT.A)
    touched = groups[:, knee] > 0  # motors of the knee's group
    joints_touched = groups[touched].sum(axis=0) > 0
    assert joints_touched.sum() == 2
    assert out[0, 0] == 3.3 and np.all(out[0, ~joints_touched] == tau[0, ~joints_touched])


@pytest.mark.parametrize("where", ["tau", "qd"])
@pytest.mark.parametrize("dtype", DTYPES)
def test_nan_propagates_alike_in_numpy_and_torch(dtype, where):
    """NaN is not refused (a check would cost a device sync): it comes back NaN, never as a finite number,
    and the same joints are NaN in numpy and torch (CPU and GPU paths)."""
    rng = np.random.default_rng(7)
    groups = coupled_groups(ROBOT_SAT.A)
    for j in range(N):
        tau, qd = rng.uniform(-50, 50, (2, N)), rng.uniform(-20, 20, (2, N))
        (tau if where == "tau" else qd)[0, j] = np.nan
        results = [to_numpy(saturate(ROBOT_SAT, tau, qd, b, dtype)) for b in BACKENDS]
        group = groups[groups[:, j] > 0].sum(axis=0) > 0
        for out in results:
            assert np.all(np.isnan(out[0, group]))  # the NaN's coupled group at least
            assert not np.any(np.isnan(out[1]))  # other rows untouched
        assert all(np.array_equal(np.isnan(results[0]), np.isnan(r)) for r in results[1:])
        # autograd path too
        t = torch.tensor(tau.astype(dtype), requires_grad=True)
        assert np.array_equal(np.isnan(to_numpy(ROBOT_SAT(t, torch.tensor(qd.astype(dtype))))), np.isnan(results[0]))


def _with_polylines(sat):
    """The same robot with each motor's straight-line interval given as a measured polyline."""
    import dataclasses

    from hound_id.mor.region import torque_interval

    lines = []
    for m in range(sat.n):
        region = SimpleRegion(sat, m)
        w = np.linspace(-region.overspeed, region.overspeed, 41)
        lo, hi = torque_interval(w, region)
        lines.append((w, lo, hi))
    return dataclasses.replace(sat, polylines=tuple(lines), _cache={})


class SimpleRegion:
    """What :func:`torque_interval` reads from a region, for motor m of a Saturation."""

    def __init__(self, sat, m):
        self.stall_torque = float(sat.stall_torque[m])
        self.back_emf_damping = float(sat.back_emf_damping[m])
        self.torque_limit = float(sat.torque_limit[m])
        self.max_speed = None if not np.isfinite(sat.max_speed[m]) else float(sat.max_speed[m])
        self.limit_x = float(sat.torque_limit[m] if sat.limit_x is None else sat.limit_x[m])
        q = 0.0 if sat.curve_q is None else float(sat.curve_q[m])
        self.curve = CurrentCurve(kt=1.0, k_sat=q) if q > 0 else None  # in x = Kt i: torque x - q x|x|
        self.overspeed = (self.stall_torque + self.limit_x) / self.back_emf_damping
        self.drive = None
        if sat.drive_k_rho is not None:  # the drive's dq window (its fields the window reads)
            from hound_id.mor.drive import Drive

            self.drive = Drive(
                reactance=0.0,
                k_rho=float(sat.drive_k_rho[m]),
                circle_x=float(sat.drive_circle_x[m]),
                field_weakening=bool(sat.drive_fw[m]),
                phase_current_limit=0.0,
            )
            # past control the window is the diode bridge's braking, which peaks near the short-circuit current
            self.overspeed *= 4.0


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("dtype", DTYPES)
@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_general_path_is_feasible_too(dtype, backend, data):
    """Measured envelopes (polylines) and autograd take the allocating path: the same guarantee."""
    tau, qd = data.draw(huge_commands(dtype))
    for sat in (POLY_SAT, ROBOT_SAT):
        kw = {"requires_grad": True} if backend == "torch" and sat is ROBOT_SAT else {}
        if backend != "torch" and sat is ROBOT_SAT:
            continue  # the in-place paths, tested above
        out = saturate(sat, tau, qd, backend, dtype, **kw)
        assert feasibility_error(sat, out, qd, dtype)[0] <= 1.0


POLY_SAT = _with_polylines(ROBOT_SAT)


def test_huge_commands_keep_finite_gradients():
    t = torch.tensor(np.full((3, N), 1e30), requires_grad=True)
    out = ROBOT_SAT(t, torch.zeros(3, N, dtype=torch.float64))
    out.sum().backward()
    assert torch.isfinite(t.grad).all() and torch.all(t.grad == 0)  # every motor clipped: no gradient


def test_motor_state_and_violation_do_not_overflow():
    big = np.finfo(np.float64).max
    tau = np.array([[big, -big] * (N // 2)])
    tau_m, _ = ROBOT_SAT.motor_state(tau, np.zeros_like(tau))
    assert not np.any(np.isnan(tau_m))
    assert np.all(ROBOT_SAT.violation(tau, np.zeros_like(tau)) > 0)


def test_coupled_groups_of_the_sample_robot():
    groups = coupled_groups(ROBOT_SAT.A)
    assert groups.sum() == 4 * (1 + 4)  # per leg: HAA alone, HFE/KFE with both motors
    assert np.array_equal(groups, groups @ groups > 0)  # a partition


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("dtype", DTYPES)
@settings(max_examples=120, deadline=None)
@given(cmd=commands(scale_tau=1.0, scale_qd=QD_SCALE), size=st.floats(0.01, 1.5))
def test_ordinary_commands_are_feasible_in_every_dtype(dtype, backend, cmd, size):
    """Commands up to 1.5x the largest ordinary one (the short path, :data:`ORDINARY`, and just past it)."""
    u_tau, qd = cmd
    tau = u_tau * size * ROBOT_SAT._constants(np.zeros((1, N))).ordinary
    out = saturate(ROBOT_SAT, tau, qd, backend, dtype)
    assert feasibility_error(ROBOT_SAT, out, qd.astype(dtype), dtype)[0] <= 1.0


@pytest.mark.parametrize("backend", ["numpy", "torch", "torch-gpu", "runtime"])
def test_a_table_curve_brakes_like_its_region_past_overspeed(tmp_path, backend):
    """A fit with a cubic term is a table curve, carried to the clip as a polyline out to where the forced braking
    current reaches the curve's top, and held at the top beyond: the clip equals the region everywhere."""
    from hound_id.export.bundle import build_bundle
    from hound_id.mor.region import torque_interval
    from hound_id.mor.spec_sheet import load_motor_spec
    from hound_id.runtime import from_bundle
    from tests.export.conftest import cubic_fitted_motor

    spec = load_motor_spec(cubic_fitted_motor(tmp_path))
    region = operating_region(spec)
    assert region.curve.form == "table"
    robot = robot_from_mapping(
        {"name": "t", "motor_specs": {"s": str(tmp_path / "fitted_cubic.yaml")}, "joints": ["j"],
         "transmissions": [{"type": "ratio", "joints": ["j"], "motors": ["m"], "motor_spec": "s", "ratios": [9.0]}]},
        source="inline", base=tmp_path,
    )  # fmt: skip
    sat = saturation_for(robot) if backend != "runtime" else from_bundle(build_bundle(robot)).clip
    omega = np.concatenate([np.linspace(-6, 6, 241) * region.overspeed, [-1e4, 1e4]])
    for command in (-1e3, -3.0, 0.0, 3.0, 1e3):
        tau_j = np.full((omega.size, 1), command * 9.0)
        qd = (omega / 9.0)[:, None]
        out = saturate(sat, tau_j, qd, "numpy" if backend == "runtime" else backend, np.float64)
        got = to_numpy(out)[:, 0] / 9.0
        lo, hi = torque_interval(omega, region)
        want = np.minimum(np.maximum(command, lo), hi)
        assert got == pytest.approx(want, abs=2e-4 * region.torque_limit)  # the polyline's accuracy
    far_lo, far_hi = torque_interval(np.array([1e4]), region)
    # with the winding's reactance the diode bridge's braking fades before it reaches the curve's top
    assert -region.curve.top_torque < far_hi[0] < 0.0
