"""The fleet comparison on reports with known values: the median, the robust spread and the flag rule."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hound_id.dyno.current.curve import PeakTorque
from hound_id.dyno.current.stats import Estimate
from hound_id.dyno.fleet.analyse import (
    MAD_TO_SIGMA,
    MIN_FLEET,
    ActuatorFit,
    analyse,
    parse_tolerances,
    values_of,
)
from hound_id.dyno.identify.engine import Suggestion
from hound_id.errors import FleetError
from tests.dyno.fleet.conftest import typed_report

MODEL = ["linear", "saturation", "coulomb", "cogging"]


def report(
    kt=0.14,
    coulomb=0.08,
    order=24.0,
    cogging=0.06,
    noise=0.015,
    peak=7.7,
    at_floor=True,
    kt_err=1e-4,
    coulomb_bound=False,
    model=MODEL,
):
    """A fit report with the values the fleet reads set, the rest neutral."""
    half = cogging / math.sqrt(2)
    params = {"kt": Estimate(kt, kt_err, "N m/A", "linear"), "k_sat": Estimate(4e-4, 1e-6, "N m/A^2", "saturation")}
    if "coulomb" in model:
        params["coulomb"] = Estimate(0.0 if coulomb_bound else coulomb, 3e-4, "N m", "coulomb", at_bound=coulomb_bound)
    if "cogging" in model:
        for name, value in (("cogging_sin_1", half), ("cogging_cos_1", half), ("cogging_sin_2", 0.0)):
            params[name] = Estimate(value, 2e-4, "N m", "cogging")
        params["cogging_cos_2"] = Estimate(0.0, 2e-4, "N m", "cogging")
        params["cogging_order"] = Estimate(order, math.nan, "1/rev", "cogging")
    suggestions = () if at_floor else (Suggestion("stribeck", 0.5, True, 1e-6, 1e-5, noise, "it explains half"),)
    return typed_report(
        model,
        params,
        peak=PeakTorque(peak, 60.0, 70.0, False, ""),
        noise_floor=noise,
        at_noise_floor=at_floor,
        summary="at the noise floor" if at_floor else "missing: stribeck",
        suggestions=suggestions,
    )


def fleet(n=10, **changes):
    """``n`` healthy actuators with a small deterministic scatter; ``changes`` maps an index to report overrides."""
    out = []
    for i in range(n):
        wobble = (i - (n - 1) / 2) / n  # -0.5 .. 0.5
        kw = dict(kt=0.14 * (1 + 0.01 * wobble), coulomb=0.08 * (1 + 0.1 * wobble), cogging=0.06 * (1 - 0.1 * wobble))
        kw.update(changes.get(f"a{i:02d}", {}))
        out.append(ActuatorFit(f"a{i:02d}", f"a{i:02d}.csv", report(**kw)))
    return out


def flagged(result):
    return sorted((f.actuator, f.metric) for f in result.flags)


def test_a_healthy_fleet_flags_nothing_and_reports_median_and_robust_spread():
    result = analyse(fleet())
    assert result.flags == ()
    kt = next(s for s in result.stats if s.metric.key == "kt")
    values = np.array([0.14 * (1 + 0.01 * (i - 4.5) / 10) for i in range(10)])
    assert kt.median == pytest.approx(np.median(values), rel=1e-12)
    assert kt.spread == pytest.approx(MAD_TO_SIGMA * np.median(np.abs(values - np.median(values))), rel=1e-12)
    assert result.fleet_order == 24.0
    assert {s.metric.key for s in result.stats} == {"kt", "peak_torque", "coulomb", "cogging_amplitude", "noise_floor"}


def test_each_fault_gets_its_reading():
    result = analyse(
        fleet(
            a02={"kt": 0.125},
            a04={"coulomb": 0.25},
            a06={"order": 28.0},
            a08={"noise": 0.05},
            a09={"cogging": 0.15},
        )
    )
    assert flagged(result) == [
        ("a02", "kt"),
        ("a04", "coulomb"),
        ("a06", "cogging_order"),
        ("a08", "noise_floor"),
        ("a09", "cogging_amplitude"),
    ]
    reading = {f.actuator: f.reading for f in result.flags}
    assert reading["a02"].startswith("Kt low: a weakened (demagnetised) magnet or a wrong winding")
    assert "bearing or gearbox" in reading["a04"]
    assert "a different motor" in reading["a06"] and "28" in reading["a06"]
    assert "not the motor" in reading["a08"]
    assert "magnet" in reading["a09"]


def test_low_friction_and_low_noise_are_no_fault_but_low_and_high_kt_are():
    result = analyse(fleet(a01={"coulomb": 0.01}, a03={"noise": 0.001}, a05={"kt": 0.16}, a07={"kt": 0.12}))
    assert flagged(result) == [("a05", "kt"), ("a07", "kt")]
    assert next(f for f in result.flags if f.actuator == "a05").reading.startswith("Kt high")


def test_a_difference_below_the_tolerance_is_not_flagged_however_tight_the_fleet():
    exact = [ActuatorFit(f"a{i}", "x", report(kt=0.14, kt_err=1e-7)) for i in range(8)]
    exact.append(ActuatorFit("b", "x", report(kt=0.14 * 0.98, kt_err=1e-7)))  # 2 % low: within Kt's 3 %
    assert analyse(exact).flags == ()
    assert flagged(analyse(exact, tolerances={"kt": 0.01})) == [("b", "kt")]


def test_a_noisy_log_is_not_flagged_by_a_deviation_within_its_own_error():
    fits = fleet(a03={"kt": 0.125, "kt_err": 0.01})  # 11 % low, but +- 7 %
    assert ("a03", "kt") not in flagged(analyse(fits))


def test_unidentified_values_are_left_out_and_never_flagged():
    result = analyse(fleet(a02={"coulomb_bound": True}))
    assert result.values["a02"]["coulomb"].value is None
    assert "bound" in result.values["a02"]["coulomb"].why
    assert next(s for s in result.stats if s.metric.key == "coulomb").n == 9


def test_too_few_actuators_flag_nothing_and_say_why():
    result = analyse(fleet(n=MIN_FLEET - 1, a00={"kt": 0.1}))
    assert result.flags == ()
    assert any("cannot show an outlier" in note for note in result.notes)


def test_a_split_cogging_order_is_not_judged():
    result = analyse(fleet(n=6, a00={"order": 28.0}, a01={"order": 28.0}, a02={"order": 28.0}))
    assert result.fleet_order is None and not [f for f in result.flags if f.metric == "cogging_order"]
    assert any("cogging order" in note for note in result.notes)


def test_a_log_missing_an_effect_is_flagged_only_against_a_fleet_at_its_floor():
    result = analyse(fleet(a03={"at_floor": False}))
    assert flagged(result) == [("a03", "verdict")]
    assert "stribeck" in result.flags[0].reading
    assert analyse(fleet(**{f"a{i:02d}": {"at_floor": False} for i in range(6)})).flags == ()


def test_an_outlier_whose_own_fit_is_flagged_says_the_log_may_be_the_cause():
    fits = fleet(a02={"kt": 0.09})
    fits[2] = replace(
        fits[2], report=replace(fits[2].report, flags=("Kt = 0.09 +- 0.12 N m/A is not determined by this log",))
    )
    (flag,) = analyse(fits).flags
    assert not flag.trusted and flag.reading.startswith("Kt low")
    assert "own fit is flagged (Kt = 0.09 +- 0.12 N m/A is not determined by this log)" in flag.reading
    assert analyse(fleet(a02={"kt": 0.09})).flags[0].trusted


def test_failed_logs_are_listed_not_compared():
    fits = [*fleet(), ActuatorFit("broken", "broken.csv", None, "broken.csv: no torque column")]
    result = analyse(fits)
    assert [a.name for a in result.failed] == ["broken"] and result.flags == ()
    data = result.to_dict()
    assert data["failed"] == [{"name": "broken", "source": "broken.csv", "error": "broken.csv: no torque column",
                               "bug": False}]  # fmt: skip
    header, rows = result.table()
    assert header[0] == "actuator" and "kt[N*m/A]" in header and len(rows) == 11
    assert rows[0][0] == "a00" and rows[-1][:3] == ["broken", "broken.csv", "failed"]


def test_fits_with_different_models_are_refused():
    fits = [*fleet(), ActuatorFit("other", "o.csv", report(model=["linear", "saturation"]))]
    with pytest.raises(FleetError, match="different models"):
        analyse(fits)


def test_the_cogging_amplitude_carries_its_propagated_error():
    values, order = values_of(report(cogging=0.05))
    assert values["cogging_amplitude"].value == pytest.approx(0.05)
    assert values["cogging_amplitude"].stderr == pytest.approx(2e-4)  # equal errors: the same error
    assert order == 24.0
    _, order = values_of(report(cogging=5e-4))  # below four standard errors: its order is noise
    assert order is None


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("kt", "expected METRIC=FRACTION"),
        ("torque=0.1", "unknown metric 'torque'"),
        ("kt=-1", "expected a fraction >= 0"),
        ("kt=abc", "expected a fraction >= 0"),
        ("kt=nan", "expected a fraction >= 0"),
    ],
)
def test_bad_tolerances_are_one_clear_error(text, message):
    with pytest.raises(FleetError, match=message):
        parse_tolerances(text)


def test_z_must_be_positive():
    with pytest.raises(FleetError, match="--z"):
        analyse(fleet(), z=0.0)


@settings(max_examples=40, deadline=None)
@given(
    scale=st.floats(1e-3, 1e3),
    shift=st.integers(0, 9),
    fault=st.sampled_from([("kt", 0.12), ("coulomb", 0.3), ("noise", 0.06), (None, None)]),
)
def test_flags_do_not_depend_on_units_or_on_the_order_of_the_logs(scale, shift, fault):
    """Every quantity times one factor (another unit) and the actuators in another order: the same flags."""
    key, value = fault
    changes = {"a03": {key: value}} if key else {}
    base = fleet(**changes)
    scaled = []
    for a in base[shift:] + base[:shift]:
        r = a.report
        kw = dict(
            kt=r.parameters["kt"].value * scale,
            kt_err=r.parameters["kt"].stderr * scale,
            coulomb=r.parameters["coulomb"].value * scale,
            noise=r.noise_floor * scale,
            peak=r.peak.torque * scale,
        )
        rs = report(**kw)
        params = dict(rs.parameters)
        for p in ("cogging_sin_1", "cogging_cos_1", "cogging_sin_2", "cogging_cos_2", "coulomb"):
            params[p] = replace(params[p] if p == "coulomb" else r.parameters[p], stderr=r.parameters[p].stderr * scale)
            if p != "coulomb":
                params[p] = replace(params[p], value=r.parameters[p].value * scale)
        rs = replace(rs, parameters=params)
        scaled.append(ActuatorFit(a.name, a.source, rs))
    assert flagged(analyse(scaled)) == flagged(analyse(base))


def test_a_fleet_with_no_spread_gives_valid_json_and_notes_what_it_cannot_flag():
    import json

    fits = [ActuatorFit(f"a{i}", "x", report(kt=0.14, at_floor=False)) for i in range(6)]
    fits.append(ActuatorFit("b", "x", report(kt=0.14, peak=9.0, at_floor=False)))  # spread 0, no stderr: z infinite
    result = analyse(fits, z=2.0)
    assert ("b", "peak_torque") in flagged(result)
    json.loads(json.dumps(result.to_dict(), allow_nan=False))
    assert any("run again with --auto" in n for n in result.notes)
    assert any("above the 2 asked for" in n for n in result.notes)


def test_current_scale_groups_are_named_and_not_flagged():
    """Twelve healthy logs, four of them with the current logged as an amplitude where the rest log RMS: Kt is
    sqrt(2) lower there. The two groups are named, nothing is flagged for Kt, and a weak magnet inside the smaller
    group is still found against its own group."""
    from hound_id.dyno.fleet.scale import scale_groups

    rms = {f"a{i:02d}": {"kt": 0.14 * (1 + 0.01 * ((i - 5.5) / 12)) / math.sqrt(2)} for i in (0, 3, 6, 9)}
    result = analyse(fleet(12, **rms))
    assert not [f for f in result.flags if f.metric == "kt"]
    names = [g.reading for g in result.scale_groups]
    assert len(result.scale_groups) == 2 and "an amplitude against an RMS current (sqrt 2)" in names
    small = next(g for g in result.scale_groups if g.reading)
    assert sorted(small.members) == ["a00", "a03", "a06", "a09"] and small.ratio == pytest.approx(2**-0.5, rel=0.01)
    assert any("Kt falls into 2 groups" in n for n in result.notes)
    assert result.to_dict()["scale_groups"][0]["members"]

    weak = dict(rms, a06={"kt": 0.9 * 0.14 / math.sqrt(2)})  # a weak magnet in the smaller group
    flags = [f for f in analyse(fleet(12, **weak)).flags if f.metric == "kt"]
    assert [f.actuator for f in flags] == ["a06"] and "current-scale group" in flags[0].reading

    # a ratio that is no convention is another current scale; two outliers make no group; one group is none
    assert "another current scale in the logging (x0.808)" in {
        g.reading
        for g in scale_groups(
            {**{f"x{i}": 1.0 + 0.001 * i for i in range(5)}, "y0": 0.81, "y1": 0.81, "y2": 0.811}
        )  # fmt: skip
    }
    assert scale_groups({**{f"x{i}": 1.0 for i in range(5)}, "y0": 0.7, "y1": 0.71}) == ()
    # logs that show their current's encoding range: grouped by it when Kt x range is one value (a scale change)
    kt = {"a": 1.06, "b": 1.07, "c": 1.09, "d": 0.78, "e": 0.79, "f": 0.75, "k": 0.76, "g": 0.62, "h": 0.61, "i": 0.62}
    kt["j"] = 0.77  # shows no range
    rng = {"a": 12.95, "b": 12.94, "c": 12.97, "d": 18.0, "e": 18.01, "f": 18.0, "k": 17.99}
    rng |= {"g": 21.94, "h": 21.93, "i": 21.95}
    groups = scale_groups(kt, rng)
    assert len(groups) == 3 and {round(g.current_range, 2) for g in groups} == {12.95, 18.0, 21.94}
    ref = next(g for g in groups if not g.reading)
    assert "j" in ref.members and ref.current_range == pytest.approx(18.0, rel=1e-3)  # j shows no range: nearest Kt
    assert all("another current scale" in g.reading and "Kt x range" in g.reading for g in groups if g.reading)
    assert scale_groups({**kt, "a": 2.0, "b": 2.0, "c": 2.0}, rng) != groups  # Kt x range no longer one value


def test_an_effect_that_declares_a_fleet_metric_is_compared_with_no_edit_to_the_fleet(monkeypatch):
    """A toy effect (windage) registered with its FleetMetric: the fleet compares it in its declared column, flags
    the actuator whose value is high with the effect's own reading, and accepts --tolerance on its key."""
    from hound_id.dyno.current.effects import REGISTRY, Effect, FleetMetric, Parameter
    from hound_id.dyno.fleet.analyse import metric_keys, parse_tolerances

    toy = Effect(
        name="windage",
        physics="air drag on the rotor grows with the square of speed",
        parameters=(Parameter("windage", "N m s^2/rad^2", "windage coefficient", 0.0),),
        regressors=lambda s, h: -s.channel("velocity") * abs(s.channel("velocity")),
        requires=("velocity",),
        trainer="too small to matter in a trainer",
        fleet=(FleetMetric("windage", "windage", "wind.", "N m s^2/rad^2", "high", 0.5, ("windage",), rank=25,
                           high="windage high: a fan blade or a rubbing cover"),),
    )  # fmt: skip
    monkeypatch.setitem(REGISTRY, "windage", toy)
    assert metric_keys().index("windage") == metric_keys().index("gear_friction") + 1  # its rank, 25
    assert parse_tolerances("windage=0.2") == {"windage": 0.2}
    fits = []
    for a in fleet():
        value = 4e-6 if a.name == "a04" else 1e-6 * (1 + 0.01 * int(a.name[1:]))
        params = {**a.report.parameters, "windage": Estimate(value, 1e-8, "N m s^2/rad^2", "windage")}
        fits.append(replace(a, report=replace(a.report, model=(*a.report.model, "windage"), parameters=params)))
    result = analyse(fits)
    assert flagged(result) == [("a04", "windage")]
    assert result.flags[0].reading.startswith("windage high: a fan blade or a rubbing cover (+")
    assert "windage" in result.to_dict()["fleet"]
