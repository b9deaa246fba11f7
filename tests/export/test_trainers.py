"""hound-id's native trainer exports, loaded and stepped in the real trainers, each in its own virtual environment
under ``.venv-trainers/`` (created once, reused later; a trainer that cannot be installed fails the test with pip's
reason, it is not skipped). The scripts in ``tests/export/in_trainers/`` run there, with hound_id on PYTHONPATH (the
runtime needs numpy and torch only), and print the realised torques' differences from hound_id.runtime."""

import json
import os
import subprocess
from pathlib import Path

import pytest

from hound_id.export.run import formats_from, prepare
from hound_id.export.target import TRAINER_REACH
from hound_id.mor.region import operating_region
from tests.conftest import ROBOT, ROOT
from tests.export.conftest import fitted_motor, write_export

SCRIPTS = Path(__file__).parent / "in_trainers"
#: float32 (MuJoCo-Warp) rounding of torques up to 100 N m.
FLOAT32 = 2e-4


def run_in(python: str, script: str, *args: object, path: tuple[str, ...] = ()) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join((str(ROOT), *path)))
    proc = subprocess.run(
        [python, str(SCRIPTS / script), *map(str, args)], capture_output=True, text=True, timeout=900, env=env
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def exported(tmp_path: Path, fits: list[Path], formats: str, reach: bool = False):
    """(export, its folder, the largest motor speed to draw): just within every motor's overspeed, or with ``reach``
    :data:`TRAINER_REACH` (2) times the no-load speed, where a robot at full tilt or a falling leg can spin them."""
    ex = prepare(ROBOT, fits)
    write_export(ex, formats_from(formats), tmp_path / "out")
    regions = [operating_region(s) for s in ex.robot.motor_specs.values()]
    if reach:
        return ex, tmp_path / "out", TRAINER_REACH * min(r.no_load_speed for r in regions)
    return ex, tmp_path / "out", 0.999 * min(r.overspeed for r in regions)


def stated(ex) -> float:
    """The most the straight-line actuators may differ from the runtime to twice the no-load speed, as the exports
    state it (motor side): the straight-line gap within the overspeed, the braking they cannot hold past it."""
    m = ex.bundle.motors[0].name
    return max(ex.straight_gap(m)[0], ex.past_overspeed(m)[0])


@pytest.mark.parametrize("uncoupled", ["dcmotor", "voltage"])
def test_mjlab_reproduces_the_runtime_for_a_linear_motor(mjlab, tmp_path, uncoupled):
    """A fitted linear motor: every edge is a straight voltage line, so the builtin dcmotor (voltage from the
    runtime, clamped natively) and DcMotor reproduce the runtime's torques to float32 rounding."""
    _, out, speed = exported(tmp_path, [fitted_motor(tmp_path)], "mjlab")
    r = run_in(mjlab, "mjlab_check.py", out, uncoupled, speed)
    assert r["mujoco"] == "3.11.0" and r["finite"] and r["clipped"] > 0.5
    assert r["voltage_columns"] == (12 if uncoupled == "voltage" else 8)
    assert r["max_difference_voltage"] < FLOAT32 and r["max_difference_law"] < FLOAT32
    assert r["max_difference_dcmotor"] < FLOAT32 and r["max_difference_rollout"] < FLOAT32


@pytest.mark.parametrize("uncoupled", ["dcmotor", "voltage"])
def test_mjlab_misses_the_curved_sample_by_at_most_the_stated_gap(mjlab, tmp_path, uncoupled):
    """The sample's curved motor: mjlab's dcmotor follows its own straight law exactly; against the runtime it errs
    where the runtime's voltage is clamped, by no more than the straight-line gap the module's NOT_HELD states."""
    ex, out, speed = exported(tmp_path, [], "mjlab")
    gap = ex.straight_gap(ex.bundle.motors[0].name)[0]
    assert f"{gap:.4g} N m" in (out / "hound_like_mjlab.py").read_text()
    r = run_in(mjlab, "mjlab_check.py", out, uncoupled, speed)
    assert r["finite"] and r["max_difference_law"] < FLOAT32
    # within the drive's overspeed the runtime's voltage stays inside the bus (the region lies in the voltage band)
    assert r["max_difference_voltage"] <= gap + FLOAT32
    gear = 9.0  # HAA: the only uncoupled joints
    assert r["max_difference_dcmotor"] <= gap * gear + FLOAT32 * gear
    assert r["max_difference_rollout"] < FLOAT32  # a PD rollout stays where the bus does not clamp


@pytest.mark.parametrize("fits", ["linear_fit", "sheet_curve"])
def test_mjlab_to_twice_the_no_load_speed_within_the_stated_braking(mjlab, tmp_path, fits):
    """States drawn to twice the no-load speed, and a PD rollout started from the motors spinning there: mjlab's
    dcmotor follows its own law, and differs from the runtime by no more than the export states (NOT_HELD: the
    braking past overspeed it holds at the torque limit), and by that much."""
    ex, out, speed = exported(tmp_path, [fitted_motor(tmp_path)] if fits == "linear_fit" else [], "mjlab", reach=True)
    gap, past = stated(ex), ex.past_overspeed(ex.bundle.motors[0].name)[0]
    assert f"{past:.4g} N m more than the torque limit" in (out / "hound_like_mjlab.py").read_text()
    r = run_in(mjlab, "mjlab_check.py", out, "dcmotor", speed, speed)
    tol = FLOAT32 * max(1.0, gap / 10.0)  # float32 rounding of the larger braking torques
    gear = 9.0  # HAA: the only uncoupled joints
    assert r["finite"] and r["max_difference_law"] < tol
    assert 0.99 * past < r["max_difference_voltage"] <= gap + tol
    assert r["max_difference_dcmotor"] <= gap * gear + tol * gear
    # the rollout spins the motors to the drawn speed and past it (a coupled knee motor adds the hip's speed); the
    # stated braking holds to twice the no-load speed, so the steps within it are compared
    assert r["rollout_top_motor_speed"] >= 0.99 * speed
    assert r["max_difference_rollout_within_speed"] <= gap * gear + tol * gear


@pytest.mark.parametrize("engine", ["warp", "cpu"])
def test_newton_reproduces_the_runtime_for_a_linear_motor(newton, tmp_path, engine):
    """The generated add_actuators on the exported open URDF, in SolverMuJoCo (MuJoCo-Warp and MuJoCo's CPU engine):
    realised motor torques equal the runtime's to float32 rounding of the voltage."""
    _, out, speed = exported(tmp_path, [fitted_motor(tmp_path)], "newton")
    r = run_in(newton, "newton_check.py", out, speed, engine)
    assert r["newton"] == "1.8.0" and r["actuators"] == 12 and r["finite"] and r["clipped"] > 0.5
    assert r["max_difference"] < FLOAT32 and r["max_difference_law"] < FLOAT32
    assert r["max_difference_rollout"] < FLOAT32 and r["finite"]


def test_newton_misses_the_curved_sample_by_at_most_the_stated_gap(newton, tmp_path):
    ex, out, speed = exported(tmp_path, [], "newton")
    gap = ex.straight_gap(ex.bundle.motors[0].name)[0]
    assert f"{gap:.4g} N m" in (out / "hound_like_newton.py").read_text()
    r = run_in(newton, "newton_check.py", out, speed, "warp")
    assert r["finite"] and r["max_difference_law"] < FLOAT32
    assert r["max_difference"] <= gap + FLOAT32
    assert r["max_difference_rollout"] < FLOAT32 and r["finite"]


@pytest.mark.parametrize("fits", ["linear_fit", "sheet_curve"])
def test_newton_to_twice_the_no_load_speed_within_the_stated_braking(newton, tmp_path, fits):
    ex, out, speed = exported(tmp_path, [fitted_motor(tmp_path)] if fits == "linear_fit" else [], "newton", reach=True)
    gap, past = stated(ex), ex.past_overspeed(ex.bundle.motors[0].name)[0]
    assert f"{past:.4g} N m more than the torque limit" in (out / "hound_like_newton.py").read_text()
    r = run_in(newton, "newton_check.py", out, speed, "warp", speed)
    tol = FLOAT32 * max(1.0, gap / 10.0)
    assert r["finite"] and r["max_difference_law"] < tol
    assert 0.99 * past < r["max_difference"] <= gap + tol
    assert r["rollout_top_motor_speed"] >= 0.99 * speed and r["max_difference_rollout_within_speed"] <= gap + tol


@pytest.mark.parametrize("fitted", [True, False], ids=["linear_fit", "sheet_curve"])
def test_isaaclab_dcmotor_fields_and_the_hound_id_actuator_in_isaac_lab(isaaclab, tmp_path, fitted):
    """Isaac Lab's own DCMotor with the exported 2.x fields on the uncoupled joints: the runtime's torques to float32
    rounding for a linear motor, within the stated dcmotor_error for the curved sample; HoundIdActuator (Isaac Lab's
    IdealPDActuator with the runtime's clip) on all joints in Isaac Lab's order: its PD torque clipped exactly as
    the runtime clips it."""
    python, source = isaaclab
    _, out, speed = exported(tmp_path, [fitted_motor(tmp_path)] if fitted else [], "bundle,isaaclab")
    r = run_in(python, "isaaclab_check.py", out, speed, path=(source,))
    assert r["isaaclab"] == "0.54.2" and r["dcmotor_joints"] == ["FL_HAA", "FR_HAA", "RL_HAA", "RR_HAA"]
    if fitted:
        assert r["dcmotor_stated_gap"] == 0.0 and r["dcmotor_max_difference"] < FLOAT32
    else:
        assert 0.5 * r["dcmotor_stated_gap"] < r["dcmotor_max_difference"] <= r["dcmotor_stated_gap"] + FLOAT32
    assert r["hound_max_difference"] == 0.0 and r["hound_clipped"] > 0.5
    # float32 rounds the speed; just before the drive loses control its edge falls steeply (the i_d = 0 chord's end),
    # so there the rounding moves the torque more than elsewhere: 3.6e-4 N m on the sample
    assert r["hound_float32_dtype"] == "torch.float32" and r["hound_max_difference_float32"] < 5 * FLOAT32
    assert r["warnings"] == []  # no deprecation (or other) warning while Isaac Lab builds the actuators


@pytest.mark.parametrize("fitted", [True, False], ids=["linear_fit", "sheet_curve"])
def test_isaaclab_to_twice_the_no_load_speed_within_the_stated_braking(isaaclab, tmp_path, fitted):
    """Past the overspeed Isaac Lab's DCMotor holds its torque limit where hound-id's clip forces more braking: the
    fields' dcmotor_error.past_overspeed states how much; HoundIdActuator is the runtime there too."""
    python, source = isaaclab
    fits = [fitted_motor(tmp_path)] if fitted else []
    ex, out, speed = exported(tmp_path, fits, "bundle,isaaclab", reach=True)
    r = run_in(python, "isaaclab_check.py", out, speed, path=(source,))
    past = ex.past_overspeed(ex.bundle.motors[0].name)[0] * 9.0  # HAA joints, gear 9
    tol = FLOAT32 * max(1.0, r["dcmotor_stated_gap"] / 10.0)
    assert r["dcmotor_stated_gap"] == pytest.approx(max(past, r["dcmotor_stated_gap"]))
    assert 0.99 * past < r["dcmotor_max_difference"] <= r["dcmotor_stated_gap"] + tol
    assert r["hound_max_difference"] == 0.0 and r["hound_max_difference_float32"] < 5 * FLOAT32 * max(1.0, past / 50)


@pytest.mark.parametrize("trainer", ["mjlab", "newton"])
def test_installing_hound_id_beside_a_trainer_leaves_its_mujoco_alone(request, tmp_path, trainer):
    """pip's own plan for installing hound-id into the trainer's environment: MuJoCo, MuJoCo-Warp, Warp and torch
    stay as the trainer has them (hound-id needs mujoco >= 3.11, which every trainer here already has)."""
    python = request.getfixturevalue(trainer)
    report = tmp_path / "report.json"
    proc = subprocess.run(
        [python, "-m", "pip", "install", "--dry-run", "--quiet", "--report", str(report), str(ROOT)],
        capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    planned = {i["metadata"]["name"].lower() for i in json.loads(report.read_text())["install"]}
    assert "hound-id" in planned
    assert not planned & {"mujoco", "mujoco-warp", "warp-lang", "torch", "numpy"}, sorted(planned)


def test_genesis_applies_the_runtime_torques_from_the_open_urdf_and_fights_the_inner_one(genesis, tmp_path):
    """Genesis enforces URDF effort limits: with urdf-open's limits and the armature sidecar it applies the runtime's
    saturated torques to float32 rounding; with the inner boxes (format urdf) it clips them, as the review saw."""
    ex, out, speed = exported(tmp_path, [], "bundle,urdf,urdf-open")
    r = run_in(genesis, "genesis_check.py", out, "hound_like_open_limits.urdf", speed)
    assert r["genesis"] == "1.4.5" and r["max_difference"] < FLOAT32
    assert r["armature"] == pytest.approx(r["expected_armature"], rel=1e-6)
    inner = run_in(genesis, "genesis_check.py", out, "hound_like_limits.urdf", speed)
    assert inner["max_difference"] > 1.0
    # to twice the no-load speed: the open limits hold the diode bridge's braking too
    reach = TRAINER_REACH * min(operating_region(s).no_load_speed for s in ex.robot.motor_specs.values())
    far = run_in(genesis, "genesis_check.py", out, "hound_like_open_limits.urdf", reach)
    assert far["max_difference"] < FLOAT32
