"""mor --compare on a second, independent dyno simulator (tests/dyno/envelope/holdrig.py).

An ordinary dynamometer envelope test: a load motor holds speeds in random order, the motor under test gets
trapezoidal pulses past its limit, a second-order transducer lags the torque, the host's command and the
drive's current reply are one loop late, the noise is AR(1) with mains hum, the winding heats. Each effect is
hidden in turn, with and without the torque_cmd channel, at 1 and 2 kHz.
"""

import json
from functools import cache

import numpy as np
import pandas as pd
import pytest

from hound_id.dyno.envelope.compare import compare
from hound_id.dyno.envelope.report import comparison_json
from hound_id.dyno.envelope.walls import command_limits
from hound_id.dyno.logs import EnvelopeLog
from hound_id.errors import SpecError
from hound_id.mor.envelope import EnvelopeInputs
from hound_id.mor.spec_sheet import load_motor_spec
from tests.conftest import MOTOR, run_cli
from tests.dyno.envelope.holdrig import Dyno, Hidden, run

SPEC = load_motor_spec(MOTOR)
INPUTS = EnvelopeInputs(SPEC)

# effect, what the simulator hides, the value to recover, seed, log rate [Hz]
CASES = [
    ("bus_sag", Hidden(r_pack=0.15), 0.15, 1, 1000.0),
    ("inductance", Hidden(inductance=1.0e-4), 1.0e-4, 2, 2000.0),
    ("thermal_resistance", Hidden(alpha=0.0039), 0.0039, 3, 1000.0),
    ("current_limit", Hidden(current_limit=50.0), 50.0, 4, 2000.0),
]


@cache
def simulated(hidden: Hidden, seed: int, log_hz: float, amplitude: tuple[float, float] = (1.2, 2.2)):
    return run(SPEC, Dyno(hidden=hidden, seed=seed, log_hz=log_hz, amplitude=amplitude))


def log_of(d, command: bool, temperature: bool = True) -> EnvelopeLog:
    return EnvelopeLog(
        torque=d["torque"], velocity=d["velocity"], torque_cmd=d["torque_cmd"] if command else None,
        current=d["current"], bus_voltage=d["bus_voltage"], temperature=d["temperature"] if temperature else None,
    )  # fmt: skip


@pytest.mark.parametrize("command", [True, False], ids=["torque_cmd", "no_command"])
@pytest.mark.parametrize(("name", "hidden", "truth", "seed", "hz"), CASES, ids=[c[0] for c in CASES])
def test_the_hidden_effect_is_named_first(name, hidden, truth, seed, hz, command):
    data = comparison_json(compare(log_of(simulated(hidden, seed, hz), command), INPUTS, auto=True))
    assert data["limit_method"] == ("command" if command else "wall")
    assert data["added"][:1] == [name], data["ladder"][0]
    assert data["model"][name] == pytest.approx(truth, rel=0.15)
    rmse = data["envelope_rmse"]
    assert rmse["model"] > 4 * data["noise_level"]  # the spec sheet misses it
    assert rmse["with_added"] <= 3 * data["noise_level"]  # and the effect takes the error to the noise
    assert data["explained"] and not data["flags"]
    assert data["added"] == [name]  # nothing else


@pytest.mark.parametrize("command", [True, False], ids=["torque_cmd", "no_command"])
@pytest.mark.parametrize(("seed", "hz"), [(5, 1000.0), (6, 2000.0)])
def test_a_matching_motor_adds_nothing(seed, hz, command):
    data = comparison_json(compare(log_of(simulated(Hidden(), seed, hz), command), INPUTS, auto=True))
    assert data["added"] == [] and data["explained"] and not data["flags"]
    assert data["envelope_rmse"]["with_added"] <= 3 * data["noise_level"]
    # the walls span the speeds, so the verdict covers the motoring edges at speed
    assert data["coverage"]["upper"][1] > 0.85 * SPEC.no_load_speed
    assert data["coverage"]["lower"][0] < -0.85 * SPEC.no_load_speed


def test_a_sample_far_inside_the_region_is_never_at_the_limit():
    """The rotor's inertia torque during speed ramps (the command resting at 0) and the lag on 15-40 torque limits a
    second of ramp both put the measured torque off the command; neither is a limit."""
    d = simulated(Hidden(r_pack=0.15), 1, 1000.0)
    found = command_limits(log_of(d, True), INPUTS)
    tau_lim = SPEC.linear_torque_limit
    for mask, edge in ((found.upper, d["true_upper"]), (found.lower, d["true_lower"])):
        assert mask.sum() > 1000
        # the transducer's torque against the motor's edge at that row: within 5 % of the limit (noise, filter)
        assert np.max(np.abs(d["torque"][mask] - edge[mask])) < 0.05 * tau_lim
    assert found.noise < 2 * 0.006 * tau_lim  # the sample noise (0.6 % of the limit), not the lags
    assert found.gain == pytest.approx(1.0, abs=0.02)


def test_the_lag_is_measured_from_the_log():
    """Delaying the torque by 5 more rows (a slower transducer, a later reply) moves the measured lag by 5 rows."""
    d = simulated(Hidden(), 5, 1000.0)
    base = command_limits(log_of(d, True), INPUTS)
    later = dict(d, torque=np.concatenate([np.full(5, d["torque"][0]), d["torque"][:-5]]))
    shifted = command_limits(log_of(later, True), INPUTS)
    # one loop late, the current loop and the transducer's filter: about 1.5 rows at 1 kHz
    assert 0.8 < base.lag < 3.0
    assert shifted.lag - base.lag == pytest.approx(5.0, abs=0.3)
    assert shifted.persist >= 2 * shifted.lag


def test_a_command_in_another_unit_is_refused():
    d = simulated(Hidden(), 5, 1000.0)
    log = log_of(dict(d, torque_cmd=d["torque_cmd"] / SPEC.kt), True)  # a current command, in A
    with pytest.raises(Exception, match="gain"):
        compare(log, INPUTS)


def test_a_hot_winding_without_its_temperature_is_not_explained():
    """The thermal shortfall cannot be fitted without the winding temperature: the bins at speed sit off the spec
    sheet at many standard errors, and the verdict says so instead of 'explained'."""
    d = simulated(Hidden(alpha=0.0039), 3, 1000.0)
    data = comparison_json(compare(log_of(d, True, temperature=False), INPUTS, auto=True))
    assert not data["explained"]
    flag = next(f for f in data["flags"] if f["kind"] == "bins_off_model")
    assert "off the model" in flag["text"] and flag["bins"] >= 1


def test_an_inflated_noise_level_is_flagged():
    """A table where one stretch of speeds was logged with a sensor 30x noisier: those bins' standard errors would
    pass any model; the noise level is flagged with where it comes from, and the verdict is not 'explained'."""
    from dataclasses import replace

    from tests.dyno.envelope.test_compare import log_of as table_of

    log, inputs = table_of(SPEC, {}, cmd=True, n=20000, seed=4)
    noisy = (log.velocity > 100) & (log.velocity < 200)
    rng = np.random.default_rng(5)
    log = replace(log, torque=log.torque + np.where(noisy, 0.6 * rng.standard_normal(log.n), 0.0))
    data = comparison_json(compare(log, inputs))
    flag = next(f for f in data["flags"] if f["kind"] == "noise_inflated")
    assert flag["bins"] >= 1 and "spread" in flag["text"]
    assert not data["explained"]


def test_pulses_that_never_reach_the_limit_name_nothing_with_the_command():
    """Pulses to 0.6 x the torque limit: with the command the motor is never at a limit below the corner; nothing
    is named there."""
    d = simulated(Hidden(), 7, 1000.0, amplitude=(0.6, 0.6))
    try:
        data = comparison_json(compare(log_of(d, True), INPUTS, auto=True))
    except SpecError as err:  # only the top holds pass the edge: too few bins to compare
        assert "nothing to compare" in str(err)
    else:
        assert data["added"] == []


def test_the_cli_reads_a_hold_protocol_log(tmp_path):
    d = simulated(Hidden(r_pack=0.15), 1, 1000.0)
    frame = pd.DataFrame(
        {
            "t [s]": d["time"],
            "shaft_torque [N*m]": d["torque"],
            "speed [rpm]": d["velocity"] * 30 / np.pi,
            "torque_cmd [N*m]": d["torque_cmd"],
            "iq [A]": d["current"],
            "vbus [V]": d["bus_voltage"],
            "winding [degC]": d["temperature"],
        }
    )
    path = tmp_path / "hold.csv"
    frame.to_csv(path, index=False)
    columns = "torque=shaft_torque,velocity=speed,current=iq,bus_voltage=vbus,temperature=winding"
    proc = run_cli("mor", "--spec", str(MOTOR), "--compare", str(path), "--columns", columns, "--auto", "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["added"] == ["bus_sag"] and data["explained"]
    assert data["limit_detection"]["lag_rows"] > 0.5 and data["limit_detection"]["persist_rows"] >= 3
    text = run_cli("mor", "--spec", str(MOTOR), "--compare", str(path), "--columns", columns, "--auto")
    assert text.returncode == 0 and "lag" in text.stdout and "bus_sag" in text.stdout
