"""The mor --compare verb on seeded logs with known truth: verdict, coverage policy, --out refused."""

import dataclasses

import numpy as np
import pytest

from hound_id.dyno.envelope.run import COVERAGE_FRACTION, CompareOptions, compare_envelope, write_outputs
from hound_id.dyno.simulate.envelope import simulate_log
from hound_id.errors import SpecError
from hound_id.mor.envelope import EnvelopeInputs
from hound_id.mor.spec_sheet import load_motor_spec
from tests.conftest import MOTOR


def _log(path, spec, speed_fraction, seed=5):
    d = simulate_log(EnvelopeInputs(spec), {}, n=8000, noise=0.02, seed=seed, speed_fraction=speed_fraction)
    np.savetxt(path, np.column_stack([d["velocity"], d["torque"]]), delimiter=",", header="velocity,torque",
               comments="")  # fmt: skip
    return path


def test_a_log_of_the_spec_itself_is_explained_and_its_envelope_written(tmp_path):
    spec = load_motor_spec(MOTOR)
    log = _log(tmp_path / "same.csv", spec, 0.99)
    out, plot = tmp_path / "env.yaml", tmp_path / "env.png"
    result = compare_envelope(MOTOR, log, CompareOptions(auto=True, out=out, plot=plot))
    assert result.verdict == "explained" and result.data["explained"] and result.suggestion is None
    assert result.warnings == ()
    forward, backward = result.motoring_speeds
    assert min(forward, backward) >= COVERAGE_FRACTION * spec.no_load_speed and result.covers_speed
    write_outputs(result)
    assert plot.read_bytes()[:4] == b"\x89PNG"
    assert load_motor_spec(out).envelope  # the written spec carries the measured envelope


def test_a_log_below_the_speeds_where_the_effects_act_does_not_cover_them(tmp_path):
    spec = load_motor_spec(MOTOR)
    result = compare_envelope(MOTOR, _log(tmp_path / "slow.csv", spec, 0.5))
    assert max(result.motoring_speeds) <= 0.5 * spec.no_load_speed
    assert not result.covers_speed


def test_out_is_refused_when_the_model_does_not_explain_the_log(tmp_path):
    """A supply 8 % stronger than the sheet: no effect adds voltage, so the log stays unexplained."""
    spec = load_motor_spec(MOTOR)
    log = _log(tmp_path / "strong.csv", dataclasses.replace(spec, bus_voltage=spec.bus_voltage * 1.08), 0.99)
    result = compare_envelope(MOTOR, log, CompareOptions(auto=True))
    assert result.verdict == "unexplained" and not result.data["explained"]
    assert result.flag_warnings == tuple(f["text"] for f in result.data["flags"])
    out = tmp_path / "env.yaml"
    with pytest.raises(SpecError, match="does not explain .* run without --out"):
        compare_envelope(MOTOR, log, CompareOptions(auto=True, out=out))
    assert not out.exists()
