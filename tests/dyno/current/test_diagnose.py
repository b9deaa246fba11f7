import pytest

from hound_id.dyno.current.diagnose import auto, diagnose, noise_floor
from hound_id.dyno.current.effects import BUILTIN
from hound_id.dyno.current.fit import fit_model
from tests.dyno.conftest import RIGS, simulated

DEFAULT = ("linear", "saturation")
HIDDEN = [e for e in BUILTIN if e not in DEFAULT]


@pytest.mark.parametrize("k", range(len(HIDDEN)), ids=HIDDEN)
def test_each_hidden_effect_is_named_first_and_adding_it_reaches_the_noise(k):
    effect = HIDDEN[k]
    rig = k % len(RIGS)
    signals, torque, sim = simulated((*DEFAULT, effect), 10 + k, rig)
    noise = sim.truth["noise_std"]
    before = diagnose(signals, torque, fit_model(signals, torque, DEFAULT))
    assert before.suggestions[0].effect == effect
    assert before.suggestions[0].significant
    assert not before.at_noise_floor
    fit = fit_model(signals, torque, (*DEFAULT, effect))
    assert fit.rmse_test <= 1.3 * noise
    after = diagnose(signals, torque, fit)
    assert [s.effect for s in after.suggestions if s.significant] == []
    assert after.at_noise_floor
    assert after.noise_floor == pytest.approx(noise, rel=0.15)


@pytest.mark.parametrize("rig", range(len(RIGS)))
def test_noise_only_data_has_nothing_significant(rig):
    signals, torque, sim = simulated(DEFAULT, 40 + rig, rig)
    d = diagnose(signals, torque, fit_model(signals, torque, DEFAULT))
    assert not any(s.significant for s in d.suggestions)
    assert d.at_noise_floor
    assert "noise floor" in d.summary()
    # white noise has no time scale: no wander is read into it
    assert d.wander is None or not d.wander.floor_is_wander, d.wander
    assert "wander" not in d.summary() and "is slow" not in d.summary()


def test_two_hidden_effects_are_found_one_after_the_other():
    signals, torque, sim = simulated((*DEFAULT, "coulomb", "cogging"), 50)
    ladder = auto(signals, torque, fit_model(signals, torque, DEFAULT))
    added = [step.added for step in ladder[1:]]
    assert sorted(added) == ["cogging", "coulomb"]
    errors = [step.fit.rmse_test for step in ladder]
    assert errors == sorted(errors, reverse=True)
    assert ladder[-1].fit.rmse_test <= 1.3 * sim.truth["noise_std"]
    assert ladder[-1].diagnosis.best is None


def test_evidence_sentence_for_coulomb():
    signals, torque, sim = simulated((*DEFAULT, "coulomb"), 60)
    d = diagnose(signals, torque, fit_model(signals, torque, DEFAULT))
    top = d.suggestions[0]
    step = 2 * sim.truth["coulomb"]
    assert "velocity changes sign" in top.reason and f"{step:.2g}"[:3] in top.reason


def test_noise_floor_of_white_noise():
    import numpy as np

    r = np.random.default_rng(0).normal(0, 0.03, 50_000) + np.sin(np.linspace(0, 20, 50_000))
    assert noise_floor(r) == pytest.approx(0.03, rel=0.03)


def test_a_long_glitch_is_named_as_outliers_not_a_missing_effect():
    signals, torque, sim = simulated(DEFAULT, 70)
    dirty = torque.copy()
    dirty[15_000:15_003] += 5.0  # three samples in a held-out block: kept by the loader as data
    d = diagnose(signals, dirty, fit_model(signals, dirty, DEFAULT))
    assert d.outliers is not None and "3 rows" in d.outliers
    assert "inspect them" in d.summary()


COMBINATIONS = [
    ("thermal", "delay"),  # where saturation_knee used to be added at the floor for a 0.03 % gain
    ("coulomb", "viscous"),
    ("cogging", "gear_friction"),
    ("offset", "ripple"),
    ("saturation_cubic", "coulomb"),
    ("coulomb", "stribeck", "delay"),
    ("thermal", "delay", "coulomb"),
    ("viscous", "cogging", "offset"),
]


@pytest.mark.parametrize("k", range(len(COMBINATIONS)), ids=["+".join(c) for c in COMBINATIONS])
def test_combinations_of_hidden_effects_are_found_exactly_with_nothing_extra(k):
    hidden = COMBINATIONS[k]
    signals, torque, sim = simulated((*DEFAULT, *hidden), 80 + k, k % len(RIGS))
    ladder = auto(signals, torque, fit_model(signals, torque, DEFAULT))
    assert sorted(step.added for step in ladder[1:]) == sorted(hidden)
    final = ladder[-1]
    assert final.diagnosis.at_noise_floor and not final.diagnosis.flags
    assert final.fit.rmse_test <= 1.05 * sim.truth["noise_std"]
    assert not final.fit.unphysical


@pytest.mark.parametrize(("share", "flagged"), [(0.25, False), (0.45, True)])
def test_kt_is_undetermined_past_a_third_of_its_value(share, flagged):
    """The boundary of KT_UNDETERMINED (1/3): a standard error of 25 % of Kt is a determined Kt, 45 % is not."""
    import dataclasses

    signals, torque, _ = simulated(DEFAULT, 70)
    fit = fit_model(signals, torque, DEFAULT)
    kt = fit.parameters["kt"]
    loose = dataclasses.replace(kt, stderr=share * abs(kt.value))
    d = diagnose(signals, torque, dataclasses.replace(fit, parameters={**fit.parameters, "kt": loose}))
    assert any("is not determined by this log" in f for f in d.flags) is flagged
    assert d.at_noise_floor is not flagged


@pytest.mark.parametrize(("coulomb", "material"), [(0.0029, False), (0.0041, True)])
def test_a_real_effect_is_suggested_only_when_material(coulomb, material):
    """The boundary of MATERIAL (5 % of the noise variance): a Coulomb step of 0.0029 N m against 0.0155 N m of noise
    lowers the cross-validated error by about 3.6 % of the noise variance, 0.0041 N m by about 7 %. Both are real
    (p < 1e-30); only the second is worth a parameter."""
    from hound_id.dyno.current.effects import Signals
    from hound_id.dyno.logs import log_from_frame
    from hound_id.dyno.simulate.current import simulate

    sim = simulate((*DEFAULT, "coulomb"), seed=80, truth={"coulomb": coulomb})
    log = log_from_frame(sim.frame, source="material")
    signals = Signals.from_log(log)
    d = diagnose(signals, log.torque, fit_model(signals, log.torque, DEFAULT))
    top = next(s for s in d.suggestions if s.effect == "coulomb")
    assert top.p_adjusted < 1e-30
    assert top.significant is material
    assert ("immaterial" in top.reason) is not material
