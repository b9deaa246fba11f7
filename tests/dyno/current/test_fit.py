import numpy as np
import pytest

from hound_id.dyno.current.effects import Signals
from hound_id.dyno.current.fit import fit_model
from hound_id.dyno.current.stats import FOLDS, MAX_BLOCKS, Blocks
from hound_id.errors import FitError
from tests.dyno.conftest import simulated


@pytest.mark.parametrize("n", [20, 99, 1000, 123_457])
def test_blocks_cover_every_row_once_and_folds_are_contiguous(n):
    b = Blocks.of(n)
    assert b.edges[0] == 0 and b.edges[-1] == n and np.all(np.diff(b.edges) > 0)
    assert 2 <= b.count <= MAX_BLOCKS
    assert b.folds == min(FOLDS, b.count)
    assert np.all(np.diff(b.fold) >= 0) and set(b.fold) == set(range(b.folds))
    covered = np.zeros(n, int)
    for k in range(b.folds):
        covered[b.rows_of_fold(k)] += 1
    assert np.all(covered == 1)  # every row is held out exactly once


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_linear_and_saturation_recover_the_truth(seed):
    signals, torque, sim = simulated(("linear", "saturation"), seed)
    fit = fit_model(signals, torque, ("linear", "saturation"))
    for name in ("kt", "k_sat"):
        est = fit.parameters[name]
        assert abs(est.value - sim.truth[name]) < 4 * est.stderr, name
        assert est.stderr < 0.01 * abs(sim.truth[name])
    assert fit.rmse_test == pytest.approx(sim.truth["noise_std"], rel=0.05)
    assert fit.bic > fit.aic - 1e9  # both defined


@pytest.mark.parametrize(
    ("effect", "hyper", "rel"),
    [
        ("stribeck", "stribeck_speed", 0.1),
        ("cogging", "cogging_order", 0.0),
        ("ripple", "ripple_order", 0.0),
        ("saturation_knee", "knee_current", 0.1),
        ("delay", "delay", 0.02),
    ],
)
def test_nonlinear_parameters_are_found(effect, hyper, rel):
    model = ("linear", "saturation", effect)
    signals, torque, sim = simulated(model, 5)
    fit = fit_model(signals, torque, model)
    assert fit.value(hyper) == pytest.approx(sim.truth[hyper], rel=rel, abs=1e-12)
    assert fit.rmse_test < 1.05 * sim.truth["noise_std"]


def test_delay_has_a_standard_error():
    model = ("linear", "saturation", "delay")
    signals, torque, sim = simulated(model, 6)
    est = fit_model(signals, torque, model).parameters["delay"]
    assert abs(est.value - sim.truth["delay"]) < 5 * est.stderr + 1e-6
    assert 0 < est.stderr < 1e-4


def test_a_shift_of_the_inputs_is_found_by_its_declaration_not_its_name(monkeypatch):
    """An effect declared a shift of the inputs (Effect.shift) under another name and hyper fits, is tried by the
    diagnosis and is refused outside its window exactly as the delay is: nothing reads the name "delay"."""
    import dataclasses

    from hound_id.dyno.current.effects import REGISTRY, Hyper, get
    from hound_id.dyno.current.trials import shift_trial

    skew = dataclasses.replace(
        get("delay"), name="skew_user", hypers=(Hyper("skew_s", "s", lambda s, r: np.array([0.0])),)
    )
    monkeypatch.setitem(REGISTRY, "skew_user", skew)
    model = ("linear", "saturation", "delay")
    signals, torque, _ = simulated(model, 6)
    by_name = fit_model(signals, torque, model)
    declared = fit_model(signals, torque, ("linear", "saturation", "skew_user"))
    assert declared.parameters["skew_s"] == dataclasses.replace(by_name.parameters["delay"], effect="skew_user")
    assert declared.values()["kt"] == by_name.values()["kt"]
    assert declared.rmse_test == by_name.rmse_test
    base = fit_model(signals, torque, ("linear", "saturation"))
    tried, named = shift_trial("skew_user", signals, torque, base), shift_trial("delay", signals, torque, base)
    assert not isinstance(tried, str) and not isinstance(named, str)
    assert tried.values["skew_s"] == named.values["delay"] and tried.wald == named.wald
    late = signals.shifted(-0.08)  # the current 80 ms late: beyond any transducer or bus
    with pytest.raises(FitError, match=r"the delay fits only at .* or leave 'skew_user' out"):
        fit_model(late, torque, ("linear", "saturation", "skew_user"))


def test_robust_fit_resists_outliers():
    signals, torque, sim = simulated(("linear", "saturation"), 7)
    dirty = torque.copy()
    rng = np.random.default_rng(0)
    hit = rng.choice(dirty.size, dirty.size // 50, replace=False)
    dirty[hit] += 50 * sim.truth["noise_std"] * np.sign(rng.normal(size=hit.size)) + 30 * sim.truth["noise_std"]
    plain = fit_model(signals, dirty, ("linear", "saturation", "offset"))
    robust = fit_model(signals, dirty, ("linear", "saturation", "offset"), robust=True)
    err_plain = abs(plain.value("kt") - sim.truth["kt"])
    err_robust = abs(robust.value("kt") - sim.truth["kt"])
    assert err_robust < err_plain
    assert abs(robust.value("offset")) < abs(plain.value("offset"))


def test_missing_channel_and_too_few_rows():
    signals, torque, _ = simulated(("linear", "saturation"))
    bare = Signals(time=signals.time, current=signals.current)
    with pytest.raises(FitError, match="needs the velocity channel.*--columns velocity="):
        fit_model(bare, torque, ("linear", "coulomb"))
    with pytest.raises(FitError, match="only 9 rows; a fit needs at least 10"):
        fit_model(bare.take(slice(0, 9)), torque[:9], ("linear",))
