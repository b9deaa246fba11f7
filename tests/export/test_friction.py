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


#: A toy effect that trainers should feel, in one file: the effect (dyno) and its friction term (the trainer side),
#: each with one register call, as a user's --effects-file holds them.
WINDAGE = """
import numpy as np
from hound_id.dyno.current.effects import Effect, Parameter, register
from hound_id.mor import friction

friction.register(friction.FrictionTerm(
    "windage", "windage", (("windage", "N m s^2/rad^2", 0.0),), "the rotor's air drag, in the square of its speed",
    lambda p, w, sgn, load, exp: -p["windage"] * w * abs(w), {"bundle": "friction (hound_id.runtime)"},
    size=lambda p, i, w: abs(p["windage"]) * w * w,
))
register(Effect(
    name="windage",
    physics="the rotor's air drag grows with the square of its speed",
    parameters=(Parameter("windage", "N m s^2/rad^2", "windage coefficient", 0.0, bound_reason="drag opposes motion"),),
    regressors=lambda s, h: -s.channel("velocity") * np.abs(s.channel("velocity")),
    requires=("velocity",),
    evidence=lambda p, s: f"air drag of {p['windage']:.3g} N m s^2/rad^2",
    friction="windage",
))
"""


def test_a_new_friction_effect_reaches_the_trainer_from_one_file(tmp_path):
    """A toy effect (windage, -c w|w|) in one effects file, with one registration for the fit and one for the
    trainer: fit-current finds it on a log that has it, the bundle carries it, the runtime applies it, and every
    export states what it loses (none holds it), with nothing else edited."""
    from hound_id.dyno.current import effects
    from hound_id.export.run import formats_from, prepare
    from tests.export.conftest import write_export

    sim = simulate(("linear", "saturation", "coulomb"), seed=6)
    frame = sim.frame.copy()
    c = 1e-4  # N m s^2/rad^2: 0.16 N m at the log's top speed, 40 rad/s
    frame["torque"] -= c * frame["velocity"] * frame["velocity"].abs()
    log = tmp_path / "windy.csv"
    frame.to_csv(log, index=False)
    toy = tmp_path / "windage.py"
    toy.write_text(WINDAGE)
    fitted = tmp_path / "fitted.yaml"
    model = "linear+saturation+coulomb+windage"
    r = run_cli("fit-current", str(log), "--effects-file", str(toy), "--model", model, "--spec", str(MOTOR),
                "--out", str(fitted), "--json")  # fmt: skip
    assert r.returncode == 0, r.stderr
    fit = json.loads(r.stdout)["parameters"]["windage"]
    assert fit["value"] == pytest.approx(c, abs=4 * fit["stderr"]) and fit["stderr"] < 0.1 * c

    saved_terms, saved_effects = dict(TERMS), dict(effects.REGISTRY)
    try:
        effects.load_effects_file(toy)  # the trainer side registers the same file
        ex = prepare(ROBOT, [fitted])
        report = write_export(ex, formats_from("bundle,mujoco,urdf"), tmp_path / "out")
        sat = hound_id.runtime.load(tmp_path / "out" / "hound_like_bundle.json")
        assert np.all(sat.friction["windage"] == fit["value"])
        w = np.linspace(-400.0, 400.0, 81)[:, None] * np.ones((1, 12))
        f_motor = sat.motor_torque(sat.friction_torque(w @ sat.clip.A.T))
        p = {k: v["value"] for k, v in json.loads(r.stdout)["parameters"].items()}
        expected = -(p["coulomb"] * np.tanh(w / 0.01) + p["windage"] * w * np.abs(w))
        assert np.allclose(f_motor, expected, rtol=1e-9, atol=1e-12)
        top = max(m.no_load_speed for m in ex.bundle.motors)
        lost = f"windage (windage): up to {p['windage'] * top**2:.4g} N m at the motor"
        for fmt in ("mujoco", "urdf"):
            assert any(n.startswith(lost) for n in report["formats"][fmt]["notes"]), report["formats"][fmt]["notes"]
        assert not any("windage" in n for n in report["formats"]["bundle"]["notes"])
    finally:
        TERMS.clear()
        TERMS.update(saved_terms)
        effects.REGISTRY.clear()
        effects.REGISTRY.update(saved_effects)
