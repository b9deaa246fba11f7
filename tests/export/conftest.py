import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT, SAMPLES

#: Where the trainers' virtual environments live (gitignored; reused by later runs, delete to rebuild).
TRAINER_VENVS = ROOT / ".venv-trainers"


def trainer_python(name: str, packages: tuple[str, ...], timeout: float = 1500) -> str:
    """The Python of a separate virtual environment ``.venv-trainers/<name>`` with ``packages`` installed (created
    once). A trainer that cannot be installed fails the calling test with pip's last line: it is never skipped."""
    venv = TRAINER_VENVS / name
    python = venv / "bin" / "python"
    done = venv / ".installed"
    if not done.exists():
        steps = (
            [sys.executable, "-m", "venv", "--clear", str(venv)],
            [str(python), "-m", "pip", "install", "-q", *packages],
        )
        for cmd in steps:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
            if proc.returncode != 0:
                lines = [x for x in proc.stderr.strip().splitlines() if "pypi-more" not in x] or ["no output"]
                pytest.fail(f"could not install {' '.join(packages)} in {venv}: {lines[-1]}")
        done.write_text(" ".join(packages) + "\n")
    return str(python)


#: What each trainer's environment installs (the versions the exports are for).
MJLAB = ("mjlab==1.6.0", "torch==2.13.0")
NEWTON = ("newton[sim]==1.8.0",)
ISAACLAB = ("isaaclab==2.3.2.post1", "torch==2.13.0", "usd-core")
GENESIS = ("genesis-world==1.4.5", "torch==2.13.0")


@pytest.fixture(scope="module")
def mjlab() -> str:
    return trainer_python("mjlab-1.6.0", MJLAB)


@pytest.fixture(scope="module")
def newton() -> str:
    return trainer_python("newton-1.8.0", NEWTON)


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


@pytest.fixture(scope="module")
def genesis() -> str:
    return trainer_python("genesis-1.4.5", GENESIS)


def fitted_motor(folder: Path, base: str = "hound_ilm85.yaml", dc_law: bool = True) -> Path:
    """A fitted-motor YAML as fit-current --out writes it (Kt, Coulomb and viscous friction, compensation). With
    ``dc_law`` (default) the sheet's inductance is dropped: a linear motor under the DC law, V = R i + omega/Kv,
    whose every edge is a straight voltage line (the exports' exact case)."""
    path = folder / f"fitted_{base}"
    dc = "inductance: null\ninductance_convention: null\n" if dc_law else ""
    path.write_text(
        f"""schema: hound-id/motor/1
base: {SAMPLES / "motors" / base}
kt: 0.1375
{dc}fit:
  schema: hound-id/fit/1
  model: [linear, coulomb, viscous]
  parameters:
    kt: {{value: 0.1375, stderr: 1.0e-5, unit: N m/A}}
    coulomb: {{value: 0.08, stderr: 1.0e-4, unit: N m}}
    viscous: {{value: 2.0e-4, stderr: 1.0e-6, unit: N m s/rad}}
  compensation:
    powers: [1, 3]
    coefficients: [7.2727, 0.001]
    units: current [A] = sum c_k * torque[N m]^k
"""
    )
    return path


def cubic_fitted_motor(folder: Path) -> Path:
    """A fitted-motor YAML of schema hound-id/fit/2 whose curve has a cubic saturation term (rebuilt as a table: the
    form whose saturation runs through a polyline), with its compensation polynomial."""
    path = folder / "fitted_cubic.yaml"
    path.write_text(
        f"""schema: hound-id/motor/1
base: {SAMPLES / "motors" / "hound_ilm85.yaml"}
kt: 0.138
peak_torque: 8.7
fit:
  schema: hound-id/fit/2
  model: [linear, saturation_cubic, coulomb]
  parameters:
    kt: {{value: 0.138, stderr: 1.0e-5, unit: N m/A}}
    k_sat3: {{value: 5.0e-6, stderr: 1.0e-8, unit: N m/A^3}}
    coulomb: {{value: 0.05, stderr: 1.0e-4, unit: N m}}
  compensation:
    powers: [1, 3, 5]
    coefficients: [7.25, 0.02, 1.0e-4]
    torque_range: 8.7
    max_error: 0.66
"""
    )
    return path


def fit3_motor(folder: Path) -> Path:
    """A fitted-motor YAML of schema hound-id/fit/3 (the quadratic curve, its exact compensation and the polynomial
    apart), as fit-current --out now writes it."""
    path = folder / "fitted_fit3.yaml"
    path.write_text(
        f"""schema: hound-id/motor/1
base: {SAMPLES / "motors" / "hound_ilm85.yaml"}
kt: 0.138
peak_torque: 7.73
fit:
  schema: hound-id/fit/3
  model: [linear, saturation]
  parameters:
    kt: {{value: 0.138, stderr: 1.0e-5, unit: N m/A}}
    k_sat: {{value: 3.94e-4, stderr: 1.0e-7, unit: N m/A^2}}
  current_curve: {{form: quadratic, kt: 0.138, k_sat: 3.94e-4}}
  compensation: {{method: closed form, torque_range: 12.08, max_error: 0.0}}
  compensation_polynomial:
    powers: [1, 3, 5]
    coefficients: [7.493, 0.03008, -6.941e-05]
    torque_range: 7.73
    max_error: 0.1319
    slope_error: 0.034
"""
    )
    return path


def write_export(ex, formats, out: Path) -> dict:
    """What ``hound-id export`` does with a prepared export: build the formats' files for ``out``, write them; the
    ``hound-id/export/1`` report."""
    from hound_id.export.run import export_robot, write_outputs

    result = export_robot(ex, formats, out)
    write_outputs(result)
    return result.to_json()
