"""The MuJoCo export in MuJoCo 3.x: a separate virtual environment with mujoco 3.11 (what mjlab 1.6 and Newton 1.8
pin), created once under ``.venv-trainers/`` (reused by later runs), loads the default voltage-input MJCF and applies
the runtime's voltages; hound-id's export writer runs there too, with MuJoCo 3.11 and the few libraries it imports
(what ``pip install hound-id`` beside a trainer leaves). A MuJoCo that cannot be installed fails the test with the
reason: it is not skipped."""

import json
import subprocess

import numpy as np
import pytest

import hound_id.runtime
from hound_id.export.run import formats_from, prepare
from tests.conftest import ROBOT, ROOT
from tests.export.conftest import fitted_motor, trainer_python, write_export

MUJOCO_3 = "3.11.0"
#: What the export writer imports besides numpy and mujoco.
WRITER = ("scipy", "pyyaml", "pint", "typer", "rich")

SCRIPT = """
import json, sys
import mujoco
import numpy as np
xml, states = sys.argv[1], json.loads(sys.stdin.read())
model = mujoco.MjModel.from_xml_path(xml)
data = mujoco.MjData(model)
act = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in states["motors"]]
dof = [model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n)] for n in states["joints"]]
out = []
for qd, v in zip(states["qd"], states["voltage"]):
    data.qvel[dof] = qd
    data.ctrl[act] = v
    mujoco.mj_forward(model, data)
    out.append(data.actuator_force[act].tolist())
mujoco.mj_resetDataKeyframe(model, data, 0)
for _ in range(200):
    mujoco.mj_step(model, data)
print(json.dumps({"version": mujoco.__version__, "forces": out, "finite": bool(np.all(np.isfinite(data.qpos)))}))
"""


@pytest.fixture(scope="module")
def mujoco3() -> str:
    return trainer_python(f"mujoco-{MUJOCO_3}-writer", (f"mujoco=={MUJOCO_3}", *WRITER))


def test_the_voltage_dcmotor_export_loads_steps_and_matches_the_runtime_in_mujoco_3(mujoco3, tmp_path):
    ex = prepare(ROBOT, [fitted_motor(tmp_path)])  # a linear curve: the dcmotor's straight lines are exact
    write_export(ex, formats_from("bundle,mujoco"), tmp_path / "out")
    sat = hound_id.runtime.load(tmp_path / "out" / "hound_like_bundle.yaml")
    rng = np.random.default_rng(3)
    omega = rng.uniform(-1, 1, (200, 12)) * 540.0  # motor speeds across the region
    qd = omega @ sat.clip.A.T
    tau = rng.uniform(-1, 1, (200, 12)) * 150.0
    volts = sat.voltage(tau, qd)
    states = {"motors": list(sat.motors), "joints": list(sat.joints), "qd": qd.tolist(), "voltage": volts.tolist()}
    proc = subprocess.run(
        [mujoco3, "-c", SCRIPT, str(tmp_path / "out" / "hound_like.xml")],
        input=json.dumps(states), capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    result = json.loads(proc.stdout)
    assert result["version"] == MUJOCO_3 and result["finite"]
    expected = sat.motor_torque(sat.saturate(tau, qd))
    assert np.max(np.abs(np.array(result["forces"]) - expected)) < 1e-9


WRITE = """
import sys
from pathlib import Path
from hound_id.errors import SpecError
from hound_id.export.run import ExportOptions, run_export, write_outputs
robot, out, fit = Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3])
write_outputs(run_export(robot, out, ExportOptions("bundle,mujoco", (fit,))))
try:
    write_outputs(run_export(robot, out / "ff", ExportOptions("mujoco", mujoco_actuator="dcmotor-ff")))
except SpecError as err:
    print(err)
"""


def test_the_export_writer_runs_with_mujoco_3(mujoco3, tmp_path):
    """hound-id's writer under MuJoCo 3.11 writes the voltage MJCF, which MuJoCo 4.0 (here) realises like the runtime;
    the torque-input variant is refused with the version named."""
    import mujoco

    from hound_id.export.mujoco import rollout_check

    env = {"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"}
    proc = subprocess.run(
        [mujoco3, "-c", WRITE, str(ROBOT), str(tmp_path / "out"), str(fitted_motor(tmp_path))],
        capture_output=True, text=True, timeout=300, env=env,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "dcmotor-ff: the dcmotor's torque input needs MuJoCo >= 4.0, this is 3.11.0" in proc.stdout
    assert not (tmp_path / "out" / "ff").exists()
    stats = rollout_check(tmp_path / "out" / "hound_like.xml", tmp_path / "out" / "hound_like_bundle.yaml", 0.5)
    assert mujoco.__version__.startswith("4.") and stats["max_difference"] < 1e-9 and stats["clipped_fraction"] > 0.5
