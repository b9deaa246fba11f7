"""The foot verb: options as typed, converted once to SI, checked in the command's order."""

import math

import pytest

from hound_id.errors import SpecError
from hound_id.foot.run import ContactOptions, FootOptions, RequirementOptions, foot_data, run_foot, write_outputs


def test_the_leg_summary_takes_the_given_angles_and_the_requirements_in_si():
    options = FootOptions(
        contact=ContactOptions(angles="-30,25", margin=5.0),
        requirements=RequirementOptions(grf="1.5 kN", roll=12.0, boss_radius="8 mm", radius="0.05"),
    )
    run = run_foot(options)
    assert run.report is None and run.summary is not None
    assert run.angles.low == pytest.approx(math.radians(-35.0)) and run.angles.high == pytest.approx(math.radians(30))
    req = run.requirements
    assert req.peak_force == pytest.approx(1500.0) and req.roll == pytest.approx(math.radians(12.0))
    assert req.boss_radius == pytest.approx(0.008) and req.radius == pytest.approx(0.05)
    assert foot_data(run)["schema"] == "hound-id/foot-leg/1"
    assert write_outputs(run) == {}  # nothing to write without --optimise


@pytest.mark.parametrize(
    ("options", "match"),
    [
        (FootOptions(contact=ContactOptions(angles="-30,25", gait="x.csv")), "not both"),  # type: ignore[arg-type]
        (FootOptions(plot="foot.png"), "need --optimise"),  # type: ignore[arg-type]
        (FootOptions(knee_angle=200.0), "--knee-angle"),
        (FootOptions(requirements=RequirementOptions(safety=0.5)), "--safety: found 0.5"),
        (FootOptions(requirements=RequirementOptions(boss_radius="2 m")), "--boss-radius"),
    ],
)
def test_bad_options_are_named(options, match, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SpecError, match=match):
        run_foot(options)
