import numpy as np
import pytest

from hound_id.dyno.current import effects as fx
from hound_id.dyno.current.effects import REGISTRY, Effect, Parameter, get, load_effects_file, parse_model, register
from hound_id.dyno.simulate.current import EFFECTS as SIMULATED
from hound_id.errors import FitError
from tests.dyno.conftest import simulated


def test_every_builtin_effect_is_simulated_and_described():
    assert set(fx.BUILTIN) == set(SIMULATED)
    names = [p.name for e in REGISTRY.values() for p in (*e.parameters, *e.hypers)]
    assert len(names) == len(set(names))
    for effect in REGISTRY.values():
        assert effect.physics and "\n" not in effect.physics
        assert all(p.unit for p in (*effect.parameters, *effect.hypers))
        assert effect.evidence is not None
    assert list(REGISTRY) == sorted(REGISTRY)


@pytest.mark.parametrize("name", fx.BUILTIN)
def test_every_builtin_effect_says_how_a_trainer_feels_it(name):
    """An effect names the friction term that carries it to the bundle, the runtime and the exports, with the fit's
    parameters and units; or it says in one sentence how a trainer feels it or why it does not. Every friction term
    is some effect's."""
    from hound_id.mor.friction import TERMS

    effect = get(name)
    assert (effect.friction is None) != (not effect.trainer), "a friction term or a trainer sentence, not both"
    if effect.friction is not None:
        term = TERMS[effect.friction]
        fitted = [(p.name, p.unit) for p in (*effect.parameters, *effect.hypers)]
        assert [(n, u) for n, u, _ in term.parameters] == fitted
    else:
        assert "\n" not in effect.trainer and effect.trainer.strip() == effect.trainer
    assert {e.friction for e in REGISTRY.values()} - {None} == set(TERMS)


@pytest.mark.parametrize("name", fx.BUILTIN)
def test_columns_have_one_finite_column_per_parameter(name):
    signals, torque, sim = simulated(("linear", "saturation"))
    effect = get(name)
    hypers = {h.name: float(sim.truth.get(h.name, 1.0)) for h in effect.hypers}
    cols = effect.columns(signals, hypers)
    assert cols.shape == (torque.shape[0], len(effect.parameters))
    assert np.all(np.isfinite(cols))


def test_parse_model():
    assert parse_model("linear + saturation+coulomb") == ("linear", "saturation", "coulomb")
    with pytest.raises(FitError, match="unknown effect 'colomb'"):
        parse_model("linear+colomb")
    with pytest.raises(FitError, match="twice"):
        parse_model("linear+linear")
    with pytest.raises(FitError, match="names no effect"):
        parse_model("+")


USER_EFFECT = """
import numpy as np
from hound_id.dyno.current.effects import Effect, Parameter, register

register(Effect(
    name="bus_ripple_user",
    physics="torque ripple proportional to the bus voltage ripple",
    parameters=(Parameter("k_bus_user", "N m/A", "gain"),),
    regressors=lambda s, h: s.current * np.sin(2 * np.pi * 50 * s.time),
))
"""


def test_user_effects_from_a_file(tmp_path):
    path = tmp_path / "mine.py"
    path.write_text(USER_EFFECT)
    try:
        assert load_effects_file(path) == ["bus_ripple_user"]
        assert "bus_ripple_user" in parse_model("linear+bus_ripple_user")
        with pytest.raises(FitError, match="already registered"):
            load_effects_file(path)
    finally:
        REGISTRY.pop("bus_ripple_user", None)
    (tmp_path / "empty.py").write_text("x = 1\n")
    with pytest.raises(FitError, match="registered no effect"):
        load_effects_file(tmp_path / "empty.py")
    (tmp_path / "broken.py").write_text("raise RuntimeError('boom')\n")
    with pytest.raises(FitError, match="importing it failed.*boom"):
        load_effects_file(tmp_path / "broken.py")
    with pytest.raises(FitError, match="not found"):
        load_effects_file(tmp_path / "none.py")


def test_parameter_names_must_be_unique():
    with pytest.raises(FitError, match="'kt' is already used by effect 'linear'"):
        register(
            Effect(
                name="dup_user", physics="x", parameters=(Parameter("kt", "N m/A"),), regressors=lambda s, h: s.current
            )
        )
    assert "dup_user" not in REGISTRY


def test_a_shift_of_the_inputs_is_declared_once_and_checked():
    """The delay is a shift of the inputs (Effect.shift): no column, one hyper; the signals every column is built from
    are read that much earlier. A shift with a column or without its one hyper is refused, and so is a model with
    two."""
    import dataclasses

    from hound_id.dyno.current.effects import Hyper, Signals, inputs, shift_of

    delay = get("delay")
    assert delay.shift and delay.regressors is None and not delay.parameters and len(delay.hypers) == 1
    assert [e.name for e in REGISTRY.values() if e.shift] == ["delay"]
    assert shift_of(("linear", "lag")) is None and shift_of(("linear", "delay")) is delay
    t = np.arange(10) * 1e-3
    s = Signals(time=t, current=2.0 * t, velocity=3.0 * t)
    assert inputs(s, ("linear",), {"delay": 2e-3}) is s  # no shift in the model: the inputs as logged
    late = inputs(s, ("linear", "delay"), {"delay": 2e-3})
    np.testing.assert_allclose(late.current[2:], 2.0 * (t[2:] - 2e-3), atol=1e-15)
    np.testing.assert_allclose(late.velocity[2:], 3.0 * (t[2:] - 2e-3), atol=1e-15)
    grid = Hyper("skew_user", "s", lambda s, r: np.array([0.0]))
    with pytest.raises(FitError, match="'skew_user': a shift of the inputs has one hyper .* 1 parameters, 1 hypers"):
        register(dataclasses.replace(delay, name="skew_user", parameters=(Parameter("skew_k", "1"),), hypers=(grid,)))
    with pytest.raises(FitError, match="'skew_user': a shift .* 0 parameters, 0 hypers and regressors"):
        register(dataclasses.replace(delay, name="skew_user", hypers=(), regressors=lambda s, h: s.current))
    assert "skew_user" not in REGISTRY
    try:
        register(dataclasses.replace(delay, name="skew_user", hypers=(grid,), builtin=False))
        with pytest.raises(FitError, match=r"the model names 2 shifts of the inputs \(delay, skew_user\); keep one"):
            shift_of(("linear", "delay", "skew_user"))
    finally:
        REGISTRY.pop("skew_user", None)


def test_why_a_log_cannot_identify_a_parameter_comes_from_its_effect(monkeypatch):
    """The identifiability check asks the pair's effects for the reason in the log's terms: a held current (the
    curve), one quadrant (load-dependent friction), one direction (friction against an offset), and a toy effect's
    own reason from one register call; with none, the regressors are nearly collinear."""
    import numpy as np

    from hound_id.dyno.current.effects import OFFSET, REGISTRY, Effect, Parameter, Signals
    from hound_id.dyno.current.identifiable import _why

    t = np.linspace(0.0, 10.0, 1000)
    sweep = 10.0 * np.sin(t)
    held = Signals(time=t, current=5.0 + 0.01 * np.sin(t), velocity=np.cos(t))
    assert "the current hardly varies" in _why("kt", OFFSET, held, 1e5)
    assert "the current hardly varies" in _why("offset", "k_sat", held, 1e5)
    motoring = Signals(time=t, current=sweep, velocity=3.0 * np.sign(sweep))
    assert "all four quadrants" in _why("kt", "gear_friction", motoring, 1e5)
    assert "all four quadrants" in _why("gear_friction", "kt", motoring, 1e5)
    one_way = Signals(time=t, current=sweep, velocity=np.full_like(t, 2.0))
    assert "record both directions of rotation" in _why("offset", "coulomb", one_way, 1e5)
    assert "record both directions of rotation" in _why("viscous", OFFSET, one_way, 1e5)
    assert "nearly collinear" in _why("coulomb", "viscous", one_way, 1e5)
    toy = Effect(
        name="windage",
        physics="air drag on the rotor grows with the square of speed",
        parameters=(Parameter("windage", "N m s^2/rad^2", "windage coefficient", 0.0),),
        regressors=lambda s, h: -s.channel("velocity") * abs(s.channel("velocity")),
        requires=("velocity",),
        unidentified=lambda partner, s: "the speed stays low; spin it faster" if partner == "viscous" else None,
        trainer="too small to matter in a trainer",
    )  # fmt: skip
    monkeypatch.setitem(REGISTRY, "windage", toy)
    assert _why("viscous", "windage", one_way, 1e5) == "the speed stays low; spin it faster"
    assert "nearly collinear" in _why("windage", "coulomb", one_way, 1e5)
