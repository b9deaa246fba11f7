"""hound_id.runtime: the trainer-side clip, friction and current compensation, numpy and torch."""

import os
import re
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest
import torch

import hound_id.runtime
from hound_id.errors import SaturationError, SpecError
from hound_id.export.bundle import apply_fits, build_bundle
from hound_id.mor.robot import load_robot
from hound_id.mor.saturation import saturation_for
from hound_id.mor.spec_sheet import load_motor_spec
from tests.conftest import ROBOT
from tests.export.conftest import fitted_motor


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    robot = apply_fits(load_robot(ROBOT), [load_motor_spec(fitted_motor(tmp_path_factory.mktemp("fit")))])
    return robot, hound_id.runtime.from_bundle(build_bundle(robot))


def test_runtime_clip_is_the_robots_clip(fitted):
    robot, sat = fitted
    rng = np.random.default_rng(0)
    tau, qd = rng.uniform(-150, 150, (256, 12)), rng.uniform(-80, 80, (256, 12))
    assert np.array_equal(sat.saturate(tau, qd), saturation_for(robot)(tau, qd))
    t = torch.tensor(tau, dtype=torch.float32, requires_grad=True)
    out = sat(t, torch.tensor(qd, dtype=torch.float32))
    out.sum().backward()
    assert out.dtype == torch.float32 and t.grad is not None
    assert np.allclose(out.detach().numpy(), sat.saturate(tau, qd), atol=1e-3)


def test_friction_dissipates_and_maps_through_the_gears(fitted):
    _, sat = fitted
    rng = np.random.default_rng(1)
    qd = rng.uniform(-30, 30, (500, 12))
    tau_f = sat.friction_torque(qd)
    # power balance: the friction power at the joints equals the motors' and is never positive
    w_m = sat.motor_velocity(qd)
    f_m = sat.motor_torque(tau_f)
    assert np.allclose((tau_f * qd).sum(-1), (f_m * w_m).sum(-1))
    assert np.all((tau_f * qd).sum(-1) <= 1e-12)
    # an uncoupled HAA (ratio 9) far from rest: -(9 * 0.08 sgn + 81 * 2e-4 qd)
    i = 0
    assert tau_f[:, i] == pytest.approx(-(9 * 0.08 * np.sign(qd[:, i]) + 81 * 2e-4 * qd[:, i]), abs=1e-6)
    assert sat.friction_torque(torch.tensor(qd)).dtype == torch.float64


def test_current_compensation(fitted):
    _, sat = fitted
    tau_m = np.array([[1.0, -2.0] + [0.5] * 10])
    # the fitted motor's model has no saturation: its exact inverse is tau / Kt with the fitted Kt
    i = sat.current(tau_m)
    assert i[0, :2] == pytest.approx(np.array([1.0, -2.0]) / 0.1375)
    # its odd polynomial stays as an option
    i = sat.current(tau_m, method="polynomial")
    assert i[0, 0] == pytest.approx(7.2727 + 0.001) and i[0, 1] == pytest.approx(-2 * 7.2727 - 0.008)
    assert sat.current(torch.tensor(tau_m)).shape == (1, 12)
    with pytest.raises(SaturationError, match="method 'poly'"):
        sat.current(tau_m, method="poly")


def test_current_is_the_exact_inverse_of_the_sheet_curve():
    """An unfitted robot: the quadratic through the 20 % point, inverted in closed form (numpy and torch), against
    the forward curve written out here; the odd polynomial used before missed by 3 % at small torque."""
    sat = hound_id.runtime.from_bundle(build_bundle(load_robot(ROBOT)))
    kt, k = 0.138, 0.16 * 0.138**2 / 12.0
    current = np.linspace(-120.0, 120.0, 12 * 101).reshape(101, 12)
    torque = kt * current - k * current * np.abs(current)
    got = sat.current(torque)
    assert got == pytest.approx(current, rel=1e-12, abs=1e-12)
    got_t = sat.current(torch.tensor(torque)).numpy()
    assert got_t == pytest.approx(current, rel=1e-12, abs=1e-12)
    # the slope at zero torque is exactly 1/Kt; the 20 % point (12 N m) needs 108.7 A
    assert sat.current(np.full((1, 12), 1e-6))[0, 0] == pytest.approx(1e-6 / kt, rel=1e-9)
    assert sat.current(np.full((1, 12), 12.0))[0, 0] == pytest.approx(12.0 / (0.8 * kt), rel=1e-12)
    # past the curve's top (Kt^2 / 4k = 18.75 N m) no current makes the torque
    assert np.isinf(sat.current(np.full((1, 12), 19.0))).all()
    assert np.all(sat.current(np.full((1, 12), -19.0)) == -np.inf)
    # autograd gives the slope 1/Kt at zero torque too (the closed form is written odd, tau in the numerator)
    t = torch.zeros((1, 12), dtype=torch.float64, requires_grad=True)
    sat.current(t).sum().backward()
    assert t.grad[0] == pytest.approx(np.full(12, 1 / kt), rel=1e-12)


def test_a_damaged_bundle_2_is_refused(tmp_path):
    """The clip's curve arrays must agree with the motors' current_curve and torque limit in the same file."""
    import copy

    good = build_bundle(load_robot(ROBOT)).to_dict()
    hound_id.runtime.from_bundle(good)
    cases = [
        (lambda b: b["saturation"].pop("curve_q"), "saturation.curve_q needs 12 numbers"),
        (lambda b: b["saturation"]["curve_q"].__setitem__(0, 0.5), "saturation.curve_q of motor 0 is 0.5, but"),
        (lambda b: b["saturation"]["limit_x"].__setitem__(3, 9.0), "saturation.limit_x of motor 3"),
        (lambda b: b["saturation"]["top_torque"].__setitem__(1, 4.0), "saturation.top_torque of motor 1"),
        (lambda b: b["motors"][2].pop("current_curve"), "motor 'FL_KFE_motor' has no current_curve"),
        (lambda b: b["saturation"].__setitem__("curve_q", "x"), "saturation.curve_q"),
    ]
    for damage, message in cases:
        bundle = copy.deepcopy(good)
        damage(bundle)
        with pytest.raises(SpecError, match=re.escape(message)):
            hound_id.runtime.from_bundle(bundle)


def test_runtime_imports_nothing_heavy():
    code = (
        "import sys, hound_id.runtime; "
        "print(sorted(m for m in ('torch','pinocchio','mujoco','matplotlib','scipy','pandas','pint','casadi') "
        "if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_runtime_imports_numpy_and_its_own_modules_only(fitted, tmp_path):
    """``import hound_id.runtime`` and loading a JSON bundle import numpy, the standard library and the hound_id
    modules tests/test_architecture.py names: no yaml, pint, scipy or spec files (torch only for tensors)."""
    import json

    from tests.test_architecture import RUNTIME_LOADS

    robot, _ = fitted
    path = tmp_path / "bundle.json"
    path.write_text(json.dumps(build_bundle(robot).to_dict()))
    code = (
        "import json, sys\n"
        "before = set(sys.modules)\n"
        "import hound_id.runtime\n"
        "sat = hound_id.runtime.load(sys.argv[1])\n"
        "sat.current(sat.motor_torque(sat.saturate([[1e3] * 12], [[50.0] * 12])))\n"
        "new = set(sys.modules) - before\n"
        "print(json.dumps({'libraries': sorted({m.split('.')[0] for m in new} - set(sys.stdlib_module_names)), "
        "'hound_id': sorted(m for m in new if m.split('.')[0] == 'hound_id')}))"
    )

    def run(fused: str, script: str = code) -> dict:
        env = {**os.environ, "HOUND_ID_FUSED": fused}
        out = subprocess.run(
            [sys.executable, "-c", script, str(path)], capture_output=True, text=True, check=True, env=env
        )
        return json.loads(out.stdout)  # type: ignore[no-any-return]

    loaded = run("0")
    assert loaded["libraries"] == ["hound_id", "numpy"]
    assert set(loaded["hound_id"]) == RUNTIME_LOADS
    # with numba installed (hound-id[fast]) the clip's fused loop adds numba and what numba itself imports to compile
    # (numpy.f2py, and what f2py finds installed, e.g. charset_normalizer)
    fused = run("1")
    compile_alone = "import numba\nnumba.njit(lambda x: x + 1)(1.0)\n"
    numba_alone = run(
        "1",
        code.replace("import hound_id.runtime\n", compile_alone).split("sat = ")[0] + code[code.index("new = ") :],
    )
    assert set(fused["libraries"]) == {"hound_id", "numpy"} | set(numba_alone["libraries"])
    assert "numba" in fused["libraries"]
    assert set(fused["hound_id"]) == RUNTIME_LOADS


def readme_example(tag: str) -> str:
    """The manual's Python block tagged ``# example: TAG`` (README.md or docs/)."""
    from tests.test_docs import example

    return example(tag)


@pytest.fixture
def bundle_dir(tmp_path, monkeypatch):
    """The README's export command, run where the examples expect its output."""
    from tests.conftest import run_cli

    proc = run_cli("export", "--robot", str(ROBOT), "--format", "bundle", "--out", "out", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_readme_isaaclab_actuator_example(bundle_dir):
    ns: dict = {}
    exec(readme_example("isaaclab"), ns)
    n = 64
    breadth_first = [f"{leg}_{j}" for j in ("HAA", "HFE", "KFE") for leg in ("FL", "FR", "RL", "RR")]
    actuator = ns["HoundIdActuator"]("out/hound_like_bundle.yaml", breadth_first, stiffness=80.0, damping=2.0)
    action = SimpleNamespace(  # stand-in for isaaclab.utils.types.ArticulationActions
        joint_positions=torch.full((n, 12), 1.5),
        joint_velocities=torch.zeros(n, 12),
        joint_efforts=torch.zeros(n, 12),
    )
    joint_pos, joint_vel = torch.zeros(n, 12), torch.linspace(-40, 40, n)[:, None].repeat(1, 12)
    result = actuator.compute(action, joint_pos, joint_vel)
    assert result.joint_positions is None and result.joint_efforts.shape == (n, 12)
    sat = hound_id.runtime.load("out/hound_like_bundle.yaml", joint_names=breadth_first)
    lo, hi = sat.clip.torque_bounds(joint_vel.double())
    tau_m = sat.motor_torque(result.joint_efforts.double())
    assert torch.all(tau_m <= hi + 1e-4) and torch.all(tau_m >= lo - 1e-4)
    assert torch.any(actuator.computed_effort != actuator.applied_effort)  # the commands went past the region


def test_readme_legged_gym_example(bundle_dir):
    ns: dict = {}
    exec(readme_example("legged_gym"), ns)
    n = 32
    env = SimpleNamespace(  # stand-in for a legged_gym LeggedRobot
        cfg=SimpleNamespace(control=SimpleNamespace(action_scale=0.25)),
        p_gains=torch.full((12,), 80.0),
        d_gains=torch.full((12,), 2.0),
        default_dof_pos=torch.zeros(12),
        dof_pos=torch.zeros(n, 12),
        dof_vel=torch.linspace(-50, 50, n)[:, None].repeat(1, 12),
        torque_limits=torch.full((12,), 100.0),
    )
    torques = ns["_compute_torques"](env, torch.full((n, 12), 8.0))
    sat = hound_id.runtime.load("out/hound_like_bundle.yaml")
    assert torch.allclose(torques, sat.saturate(80.0 * 2.0 - 2.0 * env.dof_vel, env.dof_vel))


def test_readme_runtime_example(bundle_dir):
    """The runtime snippet, in a simulator whose joints are ordered breadth-first."""
    n = 16
    breadth_first = [f"{leg}_{j}" for j in ("HAA", "HFE", "KFE") for leg in ("FL", "FR", "RL", "RR")]
    rng = np.random.default_rng(5)
    ns: dict = {
        "sim_joint_names": breadth_first,
        "tau_cmd": rng.uniform(-150, 150, (n, 12)),
        "qd": rng.uniform(-40, 40, (n, 12)),
    }
    exec(readme_example("runtime"), ns)
    sat = ns["sat"]
    assert sat.joints == tuple(breadth_first)
    assert np.array_equal(ns["tau_sim"], ns["tau"] + sat.friction_torque(ns["qd"], ns["tau"]))
    assert ns["current"].shape == ns["volts"].shape == (n, 12) and np.all(np.isfinite(ns["current"]))
    assert np.all(np.abs(ns["volts"]) <= sat.bus_voltage + 1e-9)  # motor order: within each motor's bus


def test_readme_heat_example(bundle_dir):
    ns: dict = {}
    exec(readme_example("heat"), ns)
    rt, temps = ns["rt"], ns["temps"]
    assert temps.shape == (4096, 12) and np.all(temps > rt.ambient)  # 50 N m held for 2 ms warms every winding
    assert np.all(temps < rt.ambient + 0.1)


def test_wrong_shapes_are_named(fitted):
    from hound_id.errors import SaturationError

    _, sat = fitted
    for call in (sat.friction_torque, sat.motor_velocity, sat.motor_torque, sat.current):
        with pytest.raises(SaturationError, match=r"has shape \(4, 11\); expected \(\.\.\., 12\)"):
            call(np.zeros((4, 11)))
    with pytest.raises(SaturationError, match="expected"):
        sat.saturate(np.zeros((4, 11)), np.zeros((4, 11)))


def test_simulator_joint_order(fitted, tmp_path):
    """Isaac Lab orders joints breadth-first; the runtime follows joint_names, or would clip the wrong joints."""
    from hound_id.errors import SpecError

    robot, sat = fitted
    bundle = build_bundle(robot)
    order = [f"{leg}_{j}" for j in ("HAA", "HFE", "KFE") for leg in ("FL", "FR", "RL", "RR")]
    mine = hound_id.runtime.from_bundle(bundle, joint_names=order)
    perm = [list(robot.joints).index(j) for j in order]
    rng = np.random.default_rng(5)
    tau, qd = rng.uniform(-150, 150, (200, 12)), rng.uniform(-60, 60, (200, 12))
    assert np.allclose(mine.saturate(tau[:, perm], qd[:, perm]), sat.saturate(tau, qd)[:, perm], atol=1e-12)
    assert np.allclose(mine.friction_torque(qd[:, perm]), sat.friction_torque(qd)[:, perm], atol=1e-12)
    assert np.allclose(mine.motor_torque(tau[:, perm]), sat.motor_torque(tau), atol=1e-12)
    with pytest.raises(SpecError, match=r"missing \['RR_KFE'\], not in the bundle \['RR_knee'\]"):
        hound_id.runtime.from_bundle(bundle, joint_names=[*order[:-1], "RR_knee"])


def test_damaged_bundles_are_named(fitted):
    from hound_id.errors import SpecError

    robot, _ = fitted
    bundle = build_bundle(robot).to_dict()
    del bundle["saturation"]["A"]
    with pytest.raises(SpecError, match="not a complete hound-id bundle"):
        hound_id.runtime.from_bundle(bundle)
    bundle = build_bundle(robot).to_dict()
    bundle["motors"] = bundle["motors"][:11]
    with pytest.raises(SpecError, match="12 joints but A is \\(12, 12\\), 11 motors"):
        hound_id.runtime.from_bundle(bundle)
    bundle = build_bundle(robot).to_dict()
    bundle["saturation"]["A"] = np.zeros((12, 12)).tolist()
    with pytest.raises(SpecError, match="singular"):
        hound_id.runtime.from_bundle(bundle)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("backend", ["numpy", "torch"])
def test_runtime_clip_is_feasible_for_any_finite_command(fitted, dtype, backend):
    """The trainer's clip (in a simulator's breadth-first joint order) keeps every motor inside its region
    for commands from 1 to the dtype's largest value, and passes commands inside it bit for bit."""
    robot, _ = fitted
    order = [f"{leg}_{j}" for j in ("HAA", "HFE", "KFE") for leg in ("FL", "FR", "RL", "RR")]
    sat = hound_id.runtime.from_bundle(build_bundle(robot), joint_names=order)
    rng = np.random.default_rng(11)
    big = float(np.finfo(dtype).max)
    magnitude = 10.0 ** rng.uniform(0, np.log10(big), (512, 12))
    tau = (rng.choice([-1.0, 1.0], (512, 12)) * magnitude).astype(dtype)
    tau[:12] = np.eye(12) * big
    qd = rng.uniform(-100, 100, (512, 12)).astype(dtype)
    small = rng.uniform(-1, 1, (64, 12)).astype(dtype)  # inside: the inner box is at least 1 N m everywhere
    if backend == "torch":
        out = sat.saturate(torch.from_numpy(tau), torch.from_numpy(qd)).numpy()
        inside = sat.saturate(torch.from_numpy(small), torch.zeros(64, 12, dtype=torch.from_numpy(small).dtype))
        inside = inside.numpy()
    else:
        out = sat.saturate(tau, qd)
        inside = sat.saturate(small, np.zeros_like(small))
    assert out.dtype == dtype and np.all(np.isfinite(out))
    tau_m = out.astype(np.float64) @ sat.clip.A
    lo, hi = sat.clip.torque_bounds(qd.astype(np.float64))
    tol = 1e3 * np.finfo(dtype).eps * sat.clip.torque_limit
    assert np.all(tau_m <= hi + tol) and np.all(tau_m >= lo - tol)
    assert np.array_equal(inside, small)


def test_clip_turn_of_a_batch_is_what_saturate_reports(fitted):
    """Runtime.clip_turn gives the statistics of `hound-id saturate` (same robot, same rows), in numpy and torch,
    in any joint order."""
    import pandas as pd

    from hound_id.errors import SaturationError
    from hound_id.mor.saturate_log import saturate_log
    from tests.conftest import SAMPLES

    robot, sat = fitted
    frame = pd.read_csv(SAMPLES / "commands" / "hound_like_running.csv", comment="#")
    expected = saturate_log(robot, frame).turn
    tau = frame[[f"tau_{j}" for j in robot.joints]].to_numpy()
    qd = frame[[f"qd_{j}" for j in robot.joints]].to_numpy()
    got = sat.clip_turn(tau, sat.saturate(tau, qd), qd)
    assert got == expected and len(got.groups) == 4 and got.groups[0].angle.max > 1.0
    assert got.groups[0].reference is not None and got.groups[0].reference.outside > 0
    scalars = got.scalars()
    assert scalars["clip_turn/FL_HFE+FL_KFE/angle_p95_deg"] == got.groups[0].angle.p95
    # torch, 3-D batch (envs x steps x joints): the same statistics
    t_tau, t_qd = torch.tensor(tau).reshape(5, 50, 12), torch.tensor(qd).reshape(5, 50, 12)
    t_got = sat.clip_turn(t_tau, sat.saturate(t_tau, t_qd), t_qd)
    assert t_got.groups[0].clipped == expected.groups[0].clipped
    assert t_got.groups[0].angle.median == pytest.approx(expected.groups[0].angle.median, abs=1e-9)
    assert t_got.groups[0].reference.outside == expected.groups[0].reference.outside
    # in the simulator's (breadth-first) order: the same groups, the per-joint clip pairs each joint with its motor
    order = [f"{leg}_{j}" for j in ("HAA", "HFE", "KFE") for leg in ("FL", "FR", "RL", "RR")]
    mine = hound_id.runtime.from_bundle(build_bundle(robot), joint_names=order)
    perm = [list(robot.joints).index(j) for j in order]
    reordered = mine.clip_turn(tau[:, perm], mine.saturate(tau[:, perm], qd[:, perm]), qd[:, perm])
    assert reordered.to_dict() == expected.to_dict()
    without = sat.clip_turn(tau, sat.saturate(tau, qd))
    assert without.groups[0].reference is None and without.groups[0].angle == expected.groups[0].angle
    with pytest.raises(SaturationError, match="tau_sat has shape"):
        sat.clip_turn(tau, tau[:, :11])


def _gear_fitted(folder, gear=0.05):
    """The fitted sample motor with load-dependent friction of ``gear`` [N m/A] besides Coulomb and viscous."""
    text = fitted_motor(folder).read_text()
    text = text.replace("model: [linear, coulomb, viscous]", "model: [linear, coulomb, viscous, gear_friction]")
    text = text.replace(
        "  compensation:", f"    gear_friction: {{value: {gear}, stderr: 1.0e-4, unit: N m/A}}\n  compensation:"
    )
    path = folder / "gear.yaml"
    path.write_text(text)
    return path


def test_load_dependent_friction_takes_the_current_of_the_joint_torques(tmp_path):
    """Gear friction per amp reaches the runtime: at the motors, f = -(f_c sgn + b w + c |i| sgn) with i the current
    the curve needs for the motor torques (tau / Kt on this linear fit), mapped back through A^-T; it dissipates;
    without the joint torques the runtime refuses rather than leave it out; torch agrees and carries gradients."""
    robot = apply_fits(load_robot(ROBOT), [load_motor_spec(_gear_fitted(tmp_path))])
    bundle = build_bundle(robot)
    assert {m.friction["gear_friction"] for m in bundle.motors} == {0.05}
    sat = hound_id.runtime.from_bundle(bundle.to_dict())
    assert sat.load_friction == sat.motors
    rng = np.random.default_rng(3)
    qd = rng.uniform(-30, 30, (400, 12))
    tau = sat.saturate(rng.uniform(-150, 150, (400, 12)), qd)
    tau_f = sat.friction_torque(qd, tau)
    w, tau_m = sat.motor_velocity(qd), sat.motor_torque(tau)
    sgn = np.tanh(w / 0.01)
    expected = -(0.08 * sgn + 2e-4 * w + 0.05 * np.abs(tau_m / 0.1375) * sgn)
    assert np.allclose(sat.motor_torque(tau_f), expected, rtol=1e-10, atol=1e-12)
    assert np.all((tau_f * qd).sum(-1) <= 1e-12)
    # at rest on the load, the load-dependent part alone: twice the load current, twice that part
    part = sat.friction_torque(qd, 2 * tau) - sat.friction_torque(qd, 0 * tau)
    half = sat.friction_torque(qd, tau) - sat.friction_torque(qd, 0 * tau)
    assert np.allclose(part, 2 * half, atol=1e-9)
    with pytest.raises(SaturationError, match=r"load-dependent friction .*friction_torque\(qd, tau\)"):
        sat.friction_torque(qd)
    with pytest.raises(SaturationError, match="tau has shape"):
        sat.friction_torque(qd, tau[:1])
    t = torch.tensor(tau, dtype=torch.float32, requires_grad=True)
    out = sat.friction_torque(torch.tensor(qd, dtype=torch.float32), t)
    out.sum().backward()
    assert out.dtype == torch.float32 and t.grad is not None
    assert np.allclose(out.detach().numpy(), tau_f, atol=2e-3)


def test_a_bundle_before_load_dependent_friction_reads_it_as_none(fitted):
    """A bundle/4 has no gear_friction: the runtime reads 0 and needs no joint torques for its friction."""
    robot, sat = fitted
    old = build_bundle(robot).to_dict()
    old["schema"] = "hound-id/bundle/4"
    for m in old["motors"]:
        del m["friction"]["gear_friction"]
    read = hound_id.runtime.from_bundle(old)
    qd = np.random.default_rng(4).uniform(-30, 30, (50, 12))
    assert read.load_friction == ()
    assert np.array_equal(read.friction_torque(qd), sat.friction_torque(qd))
