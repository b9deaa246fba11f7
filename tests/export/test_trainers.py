"""hound-id's native trainer exports, loaded and stepped in the real trainers, each in its own virtual environment
under ``.venv-trainers/`` (created once, reused later; a trainer that cannot be installed fails the test with pip's
reason, it is not skipped). The scripts in ``tests/export/in_trainers/`` run there, with hound_id on PYTHONPATH (the
runtime needs numpy and torch only), and print the realised torques' differences from hound_id.runtime."""

import json
import os
import subprocess
from pathlib import Path

import pytest

from hound_id.export.run import export_robot, formats_from, prepare
from hound_id.mor.region import operating_region
from tests.conftest import ROBOT, ROOT
from tests.export.conftest import fitted_motor, trainer_python

SCRIPTS = Path(__file__).parent / "in_trainers"
MJLAB = ("mjlab==1.6.0", "torch==2.13.0")
#: float32 (MuJoCo-Warp) rounding of torques up to 100 N m.
FLOAT32 = 2e-4


@pytest.fixture(scope="module")
def mjlab() -> str:
    return trainer_python("mjlab-1.6.0", MJLAB)


def run_in(python: str, script: str, *args: object, path: tuple[str, ...] = ()) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join((str(ROOT), *path)))
    proc = subprocess.run(
        [python, str(SCRIPTS / script), *map(str, args)], capture_output=True, text=True, timeout=900, env=env
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def exported(tmp_path: Path, fits: list[Path], formats: str):
    ex = prepare(ROBOT, fits)
    export_robot(ex, formats_from(formats), tmp_path / "out")
    overspeed = min(operating_region(s).overspeed for s in ex.robot.motor_specs.values())
    return ex, tmp_path / "out", 0.999 * overspeed


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


NEWTON = ("newton[sim]==1.8.0",)


@pytest.fixture(scope="module")
def newton() -> str:
    return trainer_python("newton-1.8.0", NEWTON)


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


ISAACLAB = ("isaaclab==2.3.2.post1", "torch==2.13.0", "usd-core")


@pytest.fixture(scope="module")
def isaaclab() -> tuple[str, str]:
    """Isaac Lab 2.3.2 (the newest on the package index; 3.0 is not there) without Isaac Sim: the wheel's source
    folder goes on PYTHONPATH (its top-level package bootstraps Isaac Sim), usd-core gives the pxr it imports."""
    python = trainer_python("isaaclab-2.3.2", ISAACLAB)
    proc = subprocess.run(
        [python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], capture_output=True, text=True
    )
    source = Path(proc.stdout.strip()) / "isaaclab" / "source" / "isaaclab"
    assert (source / "isaaclab" / "actuators" / "actuator_pd.py").is_file(), f"no Isaac Lab source in {source}"
    return python, str(source)


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


GENESIS = ("genesis-world==1.4.5", "torch==2.13.0")


@pytest.fixture(scope="module")
def genesis() -> str:
    return trainer_python("genesis-1.4.5", GENESIS)


def test_genesis_applies_the_runtime_torques_from_the_open_urdf_and_fights_the_inner_one(genesis, tmp_path):
    """Genesis enforces URDF effort limits: with urdf-open's limits and the armature sidecar it applies the runtime's
    saturated torques to float32 rounding; with the inner boxes (format urdf) it clips them, as the review saw."""
    _, out, speed = exported(tmp_path, [], "bundle,urdf,urdf-open")
    r = run_in(genesis, "genesis_check.py", out, "hound_like_open_limits.urdf", speed)
    assert r["genesis"] == "1.4.5" and r["max_difference"] < FLOAT32
    assert r["armature"] == pytest.approx(r["expected_armature"], rel=1e-6)
    inner = run_in(genesis, "genesis_check.py", out, "hound_like_limits.urdf", speed)
    assert inner["max_difference"] > 1.0
