from pathlib import Path

from tests.conftest import SAMPLES


def fitted_motor(folder: Path, base: str = "hound_ilm85.yaml") -> Path:
    """A fitted-motor YAML as fit-current --out writes it (Kt, Coulomb and viscous friction, compensation)."""
    path = folder / f"fitted_{base}"
    path.write_text(
        f"""schema: hound-id/motor/1
base: {SAMPLES / "motors" / base}
kt: 0.1375
fit:
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
