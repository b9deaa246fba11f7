"""Load-dependent friction from a dyno log to the trainer: the fit, the bundle, the runtime, and what each export
that cannot hold it states."""

import json

import numpy as np
import pytest

import hound_id.runtime
from hound_id.dyno.simulate.current import simulate
from hound_id.export.formats import FORMATS
from hound_id.mor.friction import TERMS
from tests.conftest import MOTOR, ROBOT, run_cli


def test_gear_friction_from_a_log_reaches_the_runtime_and_every_export_states_what_it_loses(tmp_path):
    """A simulated dyno log with load-dependent friction, fitted and exported from the command line: the bundle
    carries the fitted value, the runtime's friction at the log's speeds and torques is the fit's friction model at
    the log's currents (the curve's exact inverse gives the current back), and every format without a home for it
    says how much it loses: c times the current at the torque limit, motor side."""
    sim = simulate(("linear", "saturation", "coulomb", "viscous", "gear_friction"), seed=5)
    log = tmp_path / "gear.csv"
    sim.frame.to_csv(log, index=False)
    fitted = tmp_path / "fitted.yaml"
    model = "linear+saturation+coulomb+viscous+gear_friction"
    r = run_cli("fit-current", str(log), "--model", model, "--spec", str(MOTOR), "--out", str(fitted), "--json")
    assert r.returncode == 0, r.stderr
    p = {k: v["value"] for k, v in json.loads(r.stdout)["parameters"].items()}
    stderr = json.loads(r.stdout)["parameters"]["gear_friction"]["stderr"]
    assert p["gear_friction"] == pytest.approx(sim.truth["gear_friction"], abs=4 * stderr)
    out = tmp_path / "out"
    r = run_cli("export", "--robot", str(ROBOT), "--fit", str(fitted), "--format", "all", "--out", str(out), "--json")
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout)

    sat = hound_id.runtime.load(out / "hound_like_bundle.json")
    motor = json.loads((out / "hound_like_bundle.json").read_text())["motors"][0]
    assert motor["friction"]["gear_friction"] == p["gear_friction"]
    # the log's rows at every motor: motor speed w and the torque the curve makes of the logged current
    rows = sim.frame.iloc[::50]
    w = np.repeat(rows["velocity"].to_numpy()[:, None], 12, axis=1)
    i = rows["current"].to_numpy()
    tau_m = np.repeat((p["kt"] * i - p["k_sat"] * i * np.abs(i))[:, None], 12, axis=1)
    qd, tau = w @ sat.clip.A.T, tau_m @ sat.clip.A_inv
    f_motor = sat.motor_torque(sat.friction_torque(qd, tau))
    sgn = np.tanh(rows["velocity"].to_numpy() / 0.01)
    fit = -(p["coulomb"] * sgn + p["viscous"] * rows["velocity"].to_numpy() + p["gear_friction"] * np.abs(i) * sgn)
    assert np.allclose(f_motor, fit[:, None], rtol=1e-9, atol=1e-9)

    limit_current = motor["limit_current"]
    lost = f"load-dependent friction (gear_friction): up to {p['gear_friction'] * limit_current:.4g} N m at the motor"
    for fmt in FORMATS:
        notes = report["formats"][fmt]["notes"]
        stated = [n for n in notes if n.startswith(lost)]
        assert bool(stated) == (fmt not in TERMS["gear_friction"].homes), (fmt, notes)
    isaaclab = (out / "hound_like_isaaclab.yaml").read_text()
    assert lost in isaaclab
    assert lost in (out / "hound_like_mjlab.py").read_text() and lost in (out / "hound_like_newton.py").read_text()
