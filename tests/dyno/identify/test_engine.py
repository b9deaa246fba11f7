"""The identification engine: one significance rule, one ranking, one ladder, for both model families."""

import math

import pytest

from hound_id.dyno.identify import ALPHA, Parameter, Step, Suggestion, best, climb, corrected, f_pvalue, rank
from hound_id.dyno.identify import significant as is_significant
from hound_id.errors import FitError, HoundIdError, SpecError


def sug(effect, explained, significant=False, physical=True, supported=False, **kw):
    return Suggestion(
        effect=effect,
        explained=explained,
        significant=significant,
        p_value=kw.pop("p_value", 0.5),
        p_adjusted=kw.pop("p_adjusted", 0.5),
        rmse=kw.pop("rmse", 1.0),
        reason=kw.pop("reason", ""),
        physical=physical,
        supported=supported,
        **kw,
    )


# --- the significance rule ---------------------------------------------------------------------------------------


def test_bonferroni_multiplies_by_the_search_trials_and_the_candidates():
    assert corrected(1e-4, 30, 5) == pytest.approx(1.5e-2)
    assert corrected(1e-4) == 1e-4
    assert corrected(1e-4, 511, 1) == pytest.approx(5.11e-2)
    assert corrected(0.2, 10, 3) == 1.0  # capped: a probability
    assert corrected(1e-3, 1, 0) == 1e-3  # no candidates counts as one


def test_a_p_value_just_below_alpha_after_correction_is_significant_and_just_above_is_not():
    candidates = 4
    assert is_significant(corrected(0.99 * ALPHA / candidates, 1, candidates), material=True)
    assert not is_significant(corrected(1.01 * ALPHA / candidates, 1, candidates), material=True)
    # the uncorrected p-value alone would pass: the correction decides
    assert not is_significant(corrected(0.5 * ALPHA, 30, candidates), material=True)


@pytest.mark.parametrize(
    "gate",
    [{"material": False}, {"physical": False}, {"identified": False}, {"refuted": True}],
    ids=["immaterial", "unphysical", "at-bound", "refuted"],
)
def test_every_gate_vetoes_a_tiny_p_value(gate):
    args = {"material": True, **gate}
    assert not is_significant(1e-12, **args)
    assert is_significant(1e-12, material=True)


def test_alpha_is_a_parameter_of_the_rule():
    assert is_significant(0.03, material=True, alpha=0.05)
    assert not is_significant(0.03, material=True)
    assert not is_significant(math.nan, material=True)  # not tested: never significant


def test_f_pvalue_matches_the_f_distribution():
    from scipy.stats import f

    for stat, dfn, dfd in [(4.9646, 1, 10), (0.3, 3, 40), (25.0, 1, 7), (0.0, 2, 5)]:
        assert f_pvalue(stat, dfn, dfd) == pytest.approx(f.sf(stat, dfn, dfd), rel=1e-9, abs=1e-15)
    assert f_pvalue(4.9646, 1, 10) == pytest.approx(0.05, abs=1e-4)  # the table's critical value


def test_both_families_use_the_one_rule_and_types():
    from hound_id.dyno.current import diagnose
    from hound_id.dyno.envelope import compare

    assert diagnose.Suggestion is compare.Suggestion is Suggestion
    assert diagnose.Step is compare.Step is Step
    assert diagnose.ALPHA == compare.ALPHA == ALPHA


# --- the ranking --------------------------------------------------------------------------------------------------

SUGGESTIONS = [
    sug("a", 0.30),
    sug("b", 0.10, significant=True),
    sug("c", 0.60, physical=False),
    sug("d", 0.05, significant=True, supported=True),
    sug("e", 0.20, significant=True),
    sug("f", 0.90, supported=True),  # supported but not significant: no head start
]


def test_current_family_ranks_significant_then_physical_then_explained():
    assert [s.effect for s in rank(SUGGESTIONS)] == ["d", "e", "b", "f", "a", "c"]
    # the family's own key before the engine (supported is never set there)
    plain = [s for s in SUGGESTIONS if not s.supported]
    old = sorted(plain, key=lambda s: (-s.significant, -s.physical, -s.explained))
    assert rank(plain) == old


def test_envelope_family_ranks_supported_significant_first_then_explained():
    got = rank(SUGGESTIONS, verdict_first=False)
    assert [s.effect for s in got] == ["d", "f", "c", "a", "e", "b"]
    old = sorted(SUGGESTIONS, key=lambda s: (-int(s.supported and s.significant), -s.explained))
    assert got == old


def test_ranking_is_stable_and_best_is_the_first_significant():
    tied = [sug("x", 0.5, significant=True), sug("y", 0.5, significant=True)]
    assert [s.effect for s in rank(tied)] == ["x", "y"]
    assert best(rank(SUGGESTIONS)).effect == "d"
    assert best(rank(SUGGESTIONS, verdict_first=False)).effect == "d"
    assert best([sug("a", 0.9)]) is None


# --- the ladder ---------------------------------------------------------------------------------------------------

TRUTH = {"coulomb": 0.5, "cogging": 0.3, "viscous": 0.1}
LIBRARY = (*TRUTH, "offset", "ripple")


class Toy:
    """A family whose hidden effects are TRUTH: each missing one is significant, explaining its share."""

    def __init__(self, floor_at=None):
        self.floor_at = floor_at
        self.grown = []

    def rung(self, model, added):
        suggestions = rank(
            [sug(e, TRUTH.get(e, 0.001), significant=e in TRUTH, value=TRUTH.get(e, 0.0)) for e in LIBRARY
             if e not in model]
        )  # fmt: skip
        return Step(tuple(model), added, len(model), tuple(suggestions))

    def grow(self, step, chosen):
        self.grown.append(chosen.effect)
        return self.rung((*step.model, chosen.effect), chosen.effect)

    def at_floor(self, step):
        return self.floor_at is not None and len(step.model) >= self.floor_at


def test_auto_adds_the_best_significant_effect_until_none_is_left():
    toy = Toy()
    ladder = climb(toy.rung((), None), toy.grow, auto=True)
    assert [s.added for s in ladder] == [None, "coulomb", "cogging", "viscous"]
    assert ladder[-1].model == ("coulomb", "cogging", "viscous")
    assert best(ladder[-1].suggestions) is None
    assert ladder[2].fit == ladder[2].offsets == ladder[2].result == 2


def test_without_auto_or_add_the_ladder_is_the_start():
    toy = Toy()
    assert len(climb(toy.rung((), None), toy.grow)) == 1 and toy.grown == []


def test_the_ladder_stops_at_the_family_floor():
    toy = Toy(floor_at=1)
    ladder = climb(toy.rung((), None), toy.grow, auto=True, at_floor=toy.at_floor)
    assert [s.added for s in ladder] == [None, "coulomb"]
    assert best(ladder[-1].suggestions) is not None  # something significant is left, but the floor is reached


def test_max_steps_bounds_the_automatic_rungs():
    toy = Toy()
    ladder = climb(toy.rung((), None), toy.grow, auto=True, max_steps=2)
    assert [s.added for s in ladder] == [None, "coulomb", "cogging"]
    assert toy.grown == ["coulomb", "cogging"]  # no fit beyond the last rung
    assert len(climb(toy.rung((), None), toy.grow, auto=True, max_steps=0)) == 1


def test_the_add_queue_comes_first_in_its_order_and_then_auto():
    toy = Toy()
    ladder = climb(toy.rung((), None), toy.grow, add=["offset", "viscous"], auto=True, max_steps=3)
    assert [s.added for s in ladder] == [None, "offset", "viscous", "coulomb"]
    only = climb(toy.rung((), None), toy.grow, add=["ripple", "offset"], max_steps=0)
    assert [s.added for s in only] == [None, "ripple", "offset"]  # added even past max_steps, without auto


def test_an_effect_not_on_offer_is_refused_with_the_family_error():
    toy = Toy()
    with pytest.raises(HoundIdError, match="not a candidate"):
        climb(toy.rung((), None), toy.grow, add=["offset", "offset"])
    with pytest.raises(SpecError, match="--add nonsense"):
        climb(toy.rung((), None), toy.grow, add=["nonsense"], untestable=lambda n: SpecError(f"--add {n}: no"))


def test_on_step_sees_every_rung_the_first_included():
    toy = Toy()
    seen = []
    ladder = climb(toy.rung((), None), toy.grow, add=["offset"], auto=True, on_step=seen.append)
    assert seen == ladder and len(seen) == 5


# --- the parameter ------------------------------------------------------------------------------------------------


def test_parameter_bounds_and_at_bound():
    p = Parameter("r_pack", "ohm", lower=0.0, upper=5.0, neutral=0.0, bound_reason="a resistance")
    assert p.outside(-0.1) == "r_pack < 0" and p.outside(5.1) == "r_pack > 5" and p.outside(1.0) is None
    assert p.at_bound(4.9999) and p.at_bound(5.0)
    assert not p.at_bound(0.0)  # the neutral value: the effect is absent, which the data did identify
    assert p.at_bound(0.0001, 0.0001, 1.0)  # at the lower end of a narrower search
    assert not p.at_bound(2.5) and not p.at_bound(0.01)
    limit = Parameter("i_limit", "A", lower=0.0, upper=math.inf, neutral=math.inf)
    assert limit.at_bound(99.999, 5.0, 100.0) and not limit.at_bound(50.0, 5.0, 100.0)
    with pytest.raises(FitError, match="lower bound 1.0 is not below upper bound 0.0"):
        Parameter("x", "-", lower=1.0, upper=0.0)


def test_envelope_effects_describe_their_parameter_with_the_one_type():
    from hound_id.mor.envelope import EFFECTS

    sag = EFFECTS["bus_sag"]
    assert isinstance(sag.param, Parameter)
    assert (sag.parameter, sag.unit, sag.bounds, sag.neutral) == ("r_pack", "ohm", (0.0, 5.0), 0.0)
    assert EFFECTS["current_limit"].bounds == (0.0, math.inf) and EFFECTS["current_limit"].neutral == math.inf


# --- the families' renderers: one type, each family's own JSON -----------------------------------------------------


def test_each_family_renders_its_own_keys_from_the_one_type():
    from hound_id.dyno.current.fit_report import suggestion_dict as current_dict
    from hound_id.dyno.envelope.report import suggestion_dict as envelope_dict

    s = sug("bus_sag", 0.8, significant=True, p_value=1e-6, p_adjusted=6e-6, rmse=0.1, statistic=40.0, value=0.15,
            unit="ohm", refit={"inductance": 1e-5})  # fmt: skip
    assert list(current_dict(s)) == ["effect", "explained", "significant", "physical", "p_value", "rmse_test", "reason"]
    assert current_dict(s)["p_value"] == 6e-6  # the corrected one
    assert list(envelope_dict(s)) == [
        "effect", "value", "unit", "explained", "rmse", "f_statistic", "p_value", "significant", "reason",
        "supported", "refit",
    ]  # fmt: skip
    assert envelope_dict(s)["p_value"] == 1e-6 and envelope_dict(s)["f_statistic"] == 40.0
    blank = sug("x", 0.0, p_adjusted=math.nan, rmse=math.nan)
    assert current_dict(blank)["p_value"] is None and current_dict(blank)["rmse_test"] is None
