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


def run_in(python: str, script: str, *args: object) -> dict:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
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
    assert r["max_difference_dcmotor"] < FLOAT32


@pytest.mark.parametrize("uncoupled", ["dcmotor", "voltage"])
def test_mjlab_misses_the_curved_sample_by_at_most_the_stated_gap(mjlab, tmp_path, uncoupled):
    """The sample's curved motor: mjlab's dcmotor follows its own straight law exactly; against the runtime it errs
    where the runtime's voltage is clamped, by no more than the straight-line gap the module's NOT_HELD states."""
    ex, out, speed = exported(tmp_path, [], "mjlab")
    gap = ex.straight_gap(ex.bundle.motors[0].name)[0]
    assert f"{gap:.4g} N m" in (out / "hound_like_mjlab.py").read_text()
    r = run_in(mjlab, "mjlab_check.py", out, uncoupled, speed)
    assert r["finite"] and r["max_difference_law"] < FLOAT32
    assert 0.1 * gap < r["max_difference_voltage"] <= gap + FLOAT32
    gear = 9.0  # HAA: the only uncoupled joints
    assert r["max_difference_dcmotor"] <= gap * gear + FLOAT32 * gear


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


def test_newton_misses_the_curved_sample_by_at_most_the_stated_gap(newton, tmp_path):
    ex, out, speed = exported(tmp_path, [], "newton")
    gap = ex.straight_gap(ex.bundle.motors[0].name)[0]
    assert f"{gap:.4g} N m" in (out / "hound_like_newton.py").read_text()
    r = run_in(newton, "newton_check.py", out, speed, "warp")
    assert r["finite"] and r["max_difference_law"] < FLOAT32
    assert 0.1 * gap < r["max_difference"] <= gap + FLOAT32
