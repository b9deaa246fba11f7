"""The manual's trainer snippets, executed as printed in their trainers' virtual environments.

docs/export.md holds one Python block per trainer that starts ``# runs in: TRAINER (tests/...::test_name; ...)``. Each
test here reads that block verbatim from the manual (:func:`tests.test_docs.snippet`), exports the sample robot with a
fitted motor into ``out/`` of a scratch folder, and runs ``tests/export/in_trainers/TRAINER_snippet.py`` there, in the
trainer's environment (made by :func:`tests.export.conftest.trainer_python`, as for tests/export/test_trainers.py).
That script puts in the namespace the block runs in only what the block leaves to the user (a task's config, a
controller's ``tau_cmd``), runs the block unchanged with ``exec``, and reports what can fail: the exported robot
loaded, the actuators and armature the snippet configured are the exported ones, and the torques of the step it ran
are hound_id.runtime's clip of ``tau_cmd``. tests/test_docs.py fails a ``# runs in`` block whose test does not call
:func:`run_snippet` with its trainer. Speeds to twice the no-load speed and the stated gaps are tested in
tests/export/test_trainers.py; the Genesis, mjlab and Newton snippets here run from rest."""

import json
import os
import subprocess
from pathlib import Path

import pytest

from tests.conftest import ROOT
from tests.export.conftest import fitted_motor
from tests.export.test_trainers import FLOAT32, SCRIPTS, exported
from tests.test_docs import snippet

#: The prefix of the line a snippet script reports on (trainers log to stdout too).
RESULT = "snippet result: "


def run_snippet(python: str, trainer: str, folder: Path, *args: object, path: tuple[str, ...] = ()) -> dict:
    """Write the manual's ``trainer`` snippet as printed to ``folder``, run ``in_trainers/<trainer>_snippet.py`` on it
    with ``python`` in ``folder`` (where the snippet finds ``out/``), hound_id and ``path`` on PYTHONPATH; its
    report."""
    text = snippet(trainer)
    file = folder / f"{trainer}_snippet.py"
    file.write_text(text)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join((str(ROOT), *path)))
    proc = subprocess.run(
        [python, str(SCRIPTS / file.name), file.name, *map(str, args)],
        cwd=folder, capture_output=True, text=True, timeout=900, env=env,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = [line for line in proc.stdout.splitlines() if line.startswith(RESULT)]
    assert len(lines) == 1, proc.stdout[-2000:]
    return json.loads(lines[0].removeprefix(RESULT))


def test_the_genesis_snippet_runs_in_genesis(genesis, tmp_path):
    """Genesis 1.4.5 on the CPU, 4096 environments as printed: the snippet loads the open-limits URDF (floating base:
    18 DOFs), sets the sidecar's armature, and its step applies the runtime's clip of tau_cmd (to float32 rounding)."""
    ex, _, _ = exported(tmp_path, [fitted_motor(tmp_path)], "bundle,urdf-open")
    r = run_snippet(genesis, "genesis", tmp_path)
    assert r["genesis"] == "1.4.5" and r["urdf"] == "hound_like_open_limits.urdf" and r["dofs"] == 6 + 12
    assert r["joints"] == list(ex.bundle.joints) and r["shape"] == [4096, 12]
    assert r["armature"] == pytest.approx(r["expected_armature"], rel=1e-6) and min(r["armature"]) > 1e-3
    assert r["max_difference"] < FLOAT32 and r["clipped"] > 0.9 and r["finite"]


def test_the_mjlab_snippet_runs_in_mjlab(mjlab, tmp_path):
    """mjlab 1.6.0 on the CPU: the snippet builds a ManagerBasedRlEnv (64 environments of a minimal task) with the
    generated entity, and the voltages it sends make the coupled motors' dcmotors apply the runtime's clip of
    tau_cmd (float32)."""
    ex, _, _ = exported(tmp_path, [fitted_motor(tmp_path)], "mjlab")
    r = run_snippet(mjlab, "mjlab", tmp_path)
    assert r["mujoco"] == "3.11.0" and r["robot_joints"] == list(ex.bundle.joints)
    assert len(r["tendons"]) == 8 and r["actuators"] == 8 + 4  # MODE dcmotor: 4 DcMotor joints
    assert r["max_difference"] < FLOAT32 and r["clipped"] > 0.9 and r["finite"]
    assert 0.0 < r["max_volts"] <= 81.0  # within the sample's bus


def test_the_newton_snippet_runs_in_newton(newton, tmp_path):
    """Newton 1.8.0 (SolverMuJoCo on MuJoCo-Warp, CPU): the snippet builds the robot with the generated tendons and
    dcmotors, and its step applies the runtime's clip of tau_cmd at every motor (float32)."""
    exported(tmp_path, [fitted_motor(tmp_path)], "newton")
    r = run_snippet(newton, "newton", tmp_path)
    assert r["newton"] == "1.8.0" and r["tendon_actuators"] == 12
    assert r["max_difference"] < FLOAT32 and r["clipped"] and r["finite"]


def test_the_isaaclab_snippet_builds_its_actuator(isaaclab, tmp_path):
    """Isaac Lab 2.3.2 without Isaac Sim: the snippet runs as printed; the actuator group it configures, built as
    Isaac Lab's Articulation builds it, is HoundIdActuator on the 12 joints in PhysX's order with the snippet's gains
    and the export's armature and friction, and applies exactly the runtime's clip of its PD torque.

    Not run (Isaac Lab's assets and simulation import Isaac Sim, which is not on the package index): ``robot_cfg`` is a
    configclass with ArticulationCfg's ``actuators`` field (its declaration is checked against Isaac Lab's source), not
    an ArticulationCfg; the Articulation that turns it into actuators and writes armature and friction into PhysX
    (its calls are made instead, see in_trainers/isaaclab_snippet.py); and a PhysX step (the actuator gets random
    joint states, as Articulation passes them)."""
    python, source = isaaclab
    _, _, speed = exported(tmp_path, [fitted_motor(tmp_path)], "bundle,isaaclab")
    r = run_snippet(python, "isaaclab", tmp_path, speed, path=(source,))
    assert r["isaaclab"] == "0.54.2" and r["declared"] == "actuators: dict[str, ActuatorBaseCfg] = MISSING"
    assert r["missing"] == [] and r["groups"] == ["legs"] and r["class"] == "HoundIdActuator"
    assert r["joint_names"] == [f"{leg}_{j}" for j in ("HAA", "HFE", "KFE") for leg in ("FL", "FR", "RL", "RR")]
    assert set(r["stiffness"].values()) == {40.0} and set(r["damping"].values()) == {1.5}
    for key in ("armature", "friction", "viscous_friction"):
        assert r[key] == pytest.approx(r["exported"][key], rel=1e-6), key
        assert min(r[key].values()) > 0.0, key  # the fitted motor's: a dropped field would read 0
    assert r["dtype"] == "torch.float32" and r["pd_difference"] < FLOAT32
    assert r["max_difference"] == 0.0 and r["clipped"] > 0.9 and r["finite"]
