"""mor --compare: simulated envelopes with one hidden effect each (and none)."""

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from hound_id.dyno.envelope.compare import compare
from hound_id.dyno.envelope.report import comparison_json
from hound_id.dyno.logs import EnvelopeLog, load_envelope_log
from hound_id.dyno.simulate.envelope import simulate_log, simulate_trajectory
from hound_id.errors import DynoDataError, SpecError
from hound_id.mor.current_curve import polynomial_curve
from hound_id.mor.envelope import EnvelopeInputs, envelope, polyline
from hound_id.mor.robot import load_robot
from hound_id.mor.spec_sheet import load_motor_spec
from tests.conftest import MOTOR, ROBOT

SPEC = load_motor_spec(MOTOR)
#: A curve that needs 30 % more current at 9 N m than Kt says (as fit-current's compensation would give).
CURVE = polynomial_curve(SPEC.kt, (1, 3), (1 / SPEC.kt, 0.3 / (SPEC.kt * 81.0)), torque_range=25.0)


def log_of(spec, truth, *, curve=None, n=8000, seed=3, cmd=False, bus=True, speed=0.9):
    inputs = EnvelopeInputs(spec, curve=curve)
    d = simulate_log(inputs, truth, n=n, noise=0.02, seed=seed, speed_fraction=speed)
    cmd_col = None
    if cmd:  # the command that produced each sample: past the edge where the sample sits on it
        lo, hi = envelope(d["velocity"], truth, EnvelopeInputs(spec, d["temperature"], curve))
        rng = np.random.default_rng(seed + 1)
        at_hi, at_lo = np.isclose(d["torque"], hi, atol=0.1), np.isclose(d["torque"], lo, atol=0.1)
        cmd_col = np.where(
            at_hi, hi + rng.uniform(0.5, 5, n), np.where(at_lo, lo - rng.uniform(0.5, 5, n), d["torque"])
        )
    log = EnvelopeLog(
        torque=d["torque"], velocity=d["velocity"], temperature=d["temperature"], torque_cmd=cmd_col,
        bus_voltage=d["bus_voltage"] if bus else None, current=d["current"],
    )  # fmt: skip
    return log, inputs


CASES = [
    ("bus_sag", {"bus_sag": 0.15}, SPEC, None, 0.9),
    ("inductance", {"inductance": 1.2e-4}, SPEC, None, 0.9),
    ("current_limit", {"current_limit": 50.0}, SPEC, None, 0.9),
    ("thermal_resistance", {"thermal_resistance": 0.0039}, SPEC, None, 0.99),
    ("kt_saturation", {"kt_saturation": 1.0}, replace(SPEC, max_current=None), CURVE, 0.9),
    # a regenerating bus shows only past the no-load speed, where braking needs voltage
    ("regen_rise", {"regen_rise": 0.5}, SPEC, None, 1.06),
]


@pytest.mark.parametrize(("name", "truth", "spec", "curve", "speed"), CASES, ids=[c[0] for c in CASES])
def test_the_hidden_effect_is_named_and_explains_the_envelope(name, truth, spec, curve, speed):
    log, inputs = log_of(spec, truth, curve=curve, speed=speed)
    result = compare(log, inputs, auto=True)
    first = result.ladder[0]
    assert first.suggestions[0].effect == name and first.suggestions[0].significant
    assert result.ladder[1].added == name
    before, after = first.offsets, result.final.offsets
    assert before.rmse > 4 * before.noise  # the spec sheet misses it
    assert after.rmse < 2.5 * after.noise  # near the noise level once added
    assert not any(s.significant for s in result.final.suggestions)  # nothing significant left
    fitted = result.final.model[name]
    assert fitted == pytest.approx(truth[name], rel=0.15)


TRAJECTORIES = [
    ({}, 0.0),
    ({"bus_sag": 0.15}, 0.0),
    ({"bus_sag": 0.15}, 0.9),
    ({"current_limit": 50.0}, 0.9),
    ({"inductance": 1.2e-4}, 0.0),
]


@pytest.mark.parametrize(("truth", "rho"), TRAJECTORIES, ids=[f"{list(t) or 'none'}-rho{r}" for t, r in TRAJECTORIES])
def test_time_ordered_logs_without_a_command(truth, rho):
    """A speed sweep with a smooth random command and no torque_cmd channel: single passes through a speed bin,
    command peaks and dwells pile samples up like walls; the hidden effect must still be named and nothing else."""
    d = simulate_trajectory(EnvelopeInputs(SPEC), truth, n=20000, correlation=rho, seed=1)
    log = EnvelopeLog(torque=d["torque"], velocity=d["velocity"], bus_voltage=d["bus_voltage"])
    result = compare(log, EnvelopeInputs(SPEC), auto=True)
    data = comparison_json(result)
    assert data["limit_method"] == "wall" and data["bins_at_limit"] > 60
    assert data["added"] == list(truth)
    for name, value in truth.items():
        assert data["model"][name] == pytest.approx(value, rel=0.03)
    assert data["explained"] and data["envelope_rmse"]["with_added"] < 2 * data["noise_level"]
    assert not any(s["significant"] for s in data["suggestions"])
    assert len(data["isolated_bins"]) <= 3


def test_the_noise_level_allows_for_correlated_sensor_noise():
    """AR(1) noise with lag-1 correlation 0.9 (a filtered torque sensor): consecutive samples are not independent,
    so std/sqrt(n) would understate how well each bin's offset is known by sqrt(19) = 4.4x."""
    d = simulate_trajectory(EnvelopeInputs(SPEC), {}, n=20000, correlation=0.9, seed=2)
    log = EnvelopeLog(torque=d["torque"], velocity=d["velocity"])
    result = compare(log, EnvelopeInputs(SPEC))
    assert result.walls.rho == pytest.approx(0.9, abs=0.08)
    off = result.final.offsets  # the spec sheet is the truth here: the offsets' scatter is the noise level
    assert 0.5 < off.rmse / off.noise < 2.0
    naive = off.noise / np.sqrt((1 + result.walls.rho) / (1 - result.walls.rho))
    assert off.rmse > 3 * naive


def test_a_wrong_add_does_not_hide_the_right_effect():
    log, inputs = log_of(SPEC, {"bus_sag": 0.15})
    wrong = compare(log, inputs, add=["inductance"])
    top = wrong.final.suggestions[0]
    assert top.effect == "bus_sag" and top.significant and top.value == pytest.approx(0.15, rel=0.05)
    assert top.refit["inductance"] < 0.1 * wrong.final.model["inductance"]  # the wrong effect falls back
    both = compare(log, inputs, add=["inductance", "bus_sag"])
    assert [u.effect for u in both.unneeded] == ["inductance"]
    assert both.final.model["bus_sag"] == pytest.approx(0.15, rel=0.05)
    right = compare(log, inputs, add=["bus_sag"])
    assert right.unneeded == ()


def test_data_that_match_the_model_flag_nothing():
    log, inputs = log_of(SPEC, {})
    result = compare(log, inputs, auto=True)
    assert len(result.ladder) == 1
    assert not any(s.significant for s in result.ladder[0].suggestions)
    assert result.outside.fraction < 0.002  # noise only
    assert comparison_json(result)["explained"] is True
    assert result.ladder[0].offsets.rmse < 2.5 * result.ladder[0].offsets.noise


def test_a_commanded_torque_channel_finds_the_limit_directly():
    log, inputs = log_of(SPEC, {"bus_sag": 0.15}, cmd=True)
    result = compare(log, inputs, add=["bus_sag"])
    assert result.walls.method == "command"
    assert result.final.offsets.rmse < 2.5 * result.final.offsets.noise
    assert result.final.model["bus_sag"] == pytest.approx(0.15, rel=0.15)


def test_a_log_past_the_region_is_measured_and_located():
    """A stronger pack than the spec says (more voltage): the log spills over the motoring edge at speed."""
    strong = replace(SPEC, bus_voltage=SPEC.bus_voltage * 1.08)
    d = simulate_log(EnvelopeInputs(strong), {}, n=8000, noise=0.02, seed=5, speed_fraction=0.99)
    log = EnvelopeLog(torque=d["torque"], velocity=d["velocity"])
    result = compare(log, EnvelopeInputs(SPEC))
    out = result.outside
    assert out.fraction > 0.001 and out.max_excess > 0.5
    q = out.by_quadrant
    assert q["I"] > 0 and q["III"] > 0 and q["I"] + q["III"] > 5 * (q["II"] + q["IV"])  # motoring edges
    assert out.speed_range[0] > 0.85 * SPEC.bus_voltage * SPEC.kv  # only near the no-load speed
    assert comparison_json(result)["explained"] is False  # no candidate adds voltage: said, not hidden


@pytest.mark.parametrize("seed", range(6))
def test_a_log_that_never_reaches_its_limits_is_refused(seed):
    rng = np.random.default_rng(seed)
    n = 5000
    log = EnvelopeLog(torque=rng.uniform(-3, 3, n), velocity=rng.uniform(-300, 300, n))
    with pytest.raises(SpecError, match="does not push the motor to its envelope"):
        compare(log, EnvelopeInputs(SPEC))


def test_polyline_is_within_its_stated_accuracy():
    inputs = EnvelopeInputs(SPEC)
    line = polyline({"bus_sag": 0.15, "inductance": 1e-4}, inputs)
    assert (
        line.max_error <= line.tolerance == pytest.approx(0.002 * SPEC.linear_torque_limit)
    )  # the envelope model caps at linear Kt
    w = np.linspace(min(line.speeds), max(line.speeds), 2001)
    lo, hi = envelope(w, {"bus_sag": 0.15, "inductance": 1e-4}, inputs)
    ok = np.isfinite(hi)
    assert np.max(np.abs(np.interp(w[ok], line.speeds, line.upper) - hi[ok])) < 2 * line.tolerance


def test_loader_units_mapping_and_joint_side(tmp_path):
    log, _ = log_of(SPEC, {"bus_sag": 0.15}, n=2000)
    rpm = 60 / (2 * np.pi)
    path = tmp_path / "log.csv"
    pd.DataFrame({"speed [rpm]": log.velocity * rpm, "tq [mN*m]": log.torque * 1e3, "vbus": log.bus_voltage}).to_csv(
        path, index=False
    )
    got = load_envelope_log(path, {"velocity": "speed", "torque": "tq", "bus_voltage": "vbus"})
    assert got.velocity == pytest.approx(log.velocity) and got.torque == pytest.approx(log.torque)
    robot = load_robot(ROBOT)
    # an uncoupled HAA (ratio 9): joint torque 9 tau_m, joint speed omega_m / 9
    joint = tmp_path / "haa.csv"
    pd.DataFrame({"torque": log.torque * 9, "velocity": log.velocity / 9}).to_csv(joint, index=False)
    mapped = load_envelope_log(joint, robot=robot, joint="FL_HAA")
    assert mapped.torque == pytest.approx(log.torque) and mapped.velocity == pytest.approx(log.velocity)
    # the coupled hip/knee: both joints' columns, mapped through A
    tx = robot.transmission_of("FL_KFE")
    tau_m = np.column_stack([log.torque, 0.5 * log.torque])
    w_m = np.column_stack([log.velocity, -0.3 * log.velocity])
    tau_j, qd_j = tau_m @ np.linalg.inv(tx.A), w_m @ tx.A.T  # inverse of tau_m = A^T tau_j and omega_m = A^-1 qd
    coupled = tmp_path / "hipknee.csv"
    pd.DataFrame({"FL_HFE_torque": tau_j[:, 0], "FL_KFE_torque": tau_j[:, 1], "FL_HFE_velocity": qd_j[:, 0],
                  "FL_KFE_velocity": qd_j[:, 1]}).to_csv(coupled, index=False)  # fmt: skip
    knee = load_envelope_log(coupled, robot=robot, joint="FL_KFE")
    assert knee.torque == pytest.approx(0.5 * log.torque) and knee.velocity == pytest.approx(-0.3 * log.velocity)
    assert "hollow_shaft" in knee.side
    with pytest.raises(DynoDataError, match="column 'velocity' missing"):
        pd.DataFrame({"torque": log.torque}).to_csv(tmp_path / "t.csv", index=False)
        load_envelope_log(tmp_path / "t.csv")
    with pytest.raises(DynoDataError, match="--columns velocity=spd: no such column"):
        load_envelope_log(path, {"velocity": "spd", "torque": "tq"})
    with pytest.raises(SpecError, match="--robot and --joint go together"):
        load_envelope_log(path, {"velocity": "speed", "torque": "tq"}, robot=robot)


def test_json_has_the_issue_fields():
    log, inputs = log_of(SPEC, {"bus_sag": 0.15})
    data = comparison_json(compare(log, inputs, add=["bus_sag"]))
    assert data["schema"] == "hound-id/mor-compare/2"
    assert set(data["envelope_rmse"]) == {"model", "with_added"}
    assert data["envelope_rmse"]["with_added"] < data["envelope_rmse"]["model"]
    assert all(set(s) >= {"effect", "explained", "significant", "reason"} for s in data["suggestions"])
    assert 0.0 <= data["outside_fraction"] <= 1.0
    import json

    json.dumps(data)


def test_measured_envelope_reaches_the_saturation_the_bundle_and_the_runtime(tmp_path):
    """mor --compare --out writes a spec whose polyline the clip, the bundle and the runtime all use."""
    import torch
    import yaml

    import hound_id.runtime
    from hound_id.dyno.envelope.report import envelope_spec
    from hound_id.export.bundle import build_bundle
    from hound_id.mor.saturation import Saturation

    log, inputs = log_of(SPEC, {"bus_sag": 0.15})
    result = compare(log, inputs, auto=True)
    out = tmp_path / "ilm85_envelope.yaml"
    out.write_text(yaml.safe_dump(envelope_spec(MOTOR, out, result)))
    spec = load_motor_spec(out)
    assert spec.kt == SPEC.kt and spec.envelope.effects["bus_sag"] == pytest.approx(0.15, rel=0.15)
    robot = load_robot(ROBOT)
    robot = replace(robot, motor_specs={m: spec for m in robot.motor_specs})
    sat = Saturation.from_robot(robot)
    assert len(sat.polylines) == 12
    rng = np.random.default_rng(9)
    tau, qd = rng.uniform(-200, 200, (400, 12)), rng.uniform(-70, 70, (400, 12))
    tau_m = sat(tau, qd) @ sat.A
    omega = qd @ sat.A_inv.T
    lo, hi = envelope(omega.ravel(), spec.envelope.effects, EnvelopeInputs(SPEC))
    tol = spec.envelope.tolerance * 2 + 1e-9
    inside = np.isfinite(hi) & (np.abs(omega.ravel()) <= spec.envelope.speeds[-1])  # past it: the spec's lines
    assert inside.mean() > 0.5
    t = tau_m.ravel()[inside]
    assert np.all(t <= hi[inside] + tol) and np.all(t >= lo[inside] - tol)
    assert np.any(tau_m.ravel() < SPEC.linear_torque_limit - 0.5)  # the sag bites at speed
    t = torch.tensor(tau, requires_grad=True)
    out_t = sat(t, torch.tensor(qd))
    out_t.sum().backward()
    assert np.allclose(out_t.detach().numpy(), sat(tau, qd), atol=1e-9) and t.grad is not None
    runtime = hound_id.runtime.from_bundle(build_bundle(robot))
    assert np.allclose(runtime.saturate(tau, qd), sat(tau, qd), atol=1e-12)


@pytest.mark.parametrize(("amplitude", "seed"), [(0.8, 0), (0.8, 1), (0.8, 3), (1.5, 3), (2.0, 1), (2.0, 3)])
def test_a_slow_command_is_not_taken_for_a_limit(amplitude, seed):
    """A motor that matches its spec, driven by a slow command (sines under 1 Hz) with AR(1) noise: passes of the
    command that plateau across bins pile up like walls. No effect may be added (a 'current limit' at the plateau
    would be refuted by the samples above it elsewhere), and a log that never reaches its limits is refused or
    not explained."""
    d = simulate_trajectory(EnvelopeInputs(SPEC), {}, n=20000, correlation=0.9, amplitude=amplitude, band=1.0,
                            seed=seed, noise=0.02)  # fmt: skip
    log = EnvelopeLog(torque=d["torque"], velocity=d["velocity"])
    try:
        data = comparison_json(compare(log, EnvelopeInputs(SPEC), auto=True))
    except SpecError as err:
        assert amplitude < 1 and "does not push the motor to its envelope" in str(err)
        return
    assert data["added"] == []
    if amplitude < 1:
        assert not data["explained"]


def test_a_candidate_the_log_passes_is_refuted():
    """Walls from a slow command at 1.4 N m would fit a 10 A current limit; the log's samples above it elsewhere
    refute it."""
    d = simulate_trajectory(EnvelopeInputs(SPEC), {}, n=20000, correlation=0.9, amplitude=0.8, band=1.0, seed=3,
                            noise=0.02)  # fmt: skip
    log = EnvelopeLog(torque=d["torque"], velocity=d["velocity"])
    first = compare(log, EnvelopeInputs(SPEC)).ladder[0].suggestions
    limit = next(s for s in first if s.effect == "current_limit")
    assert not limit.significant and "refuted" in limit.reason


def test_an_empty_optional_column_is_left_out_and_implausible_units_are_refused(tmp_path):
    log, _ = log_of(SPEC, {"bus_sag": 0.15}, n=2000)
    path = tmp_path / "log.csv"
    pd.DataFrame({"velocity": log.velocity, "torque": log.torque, "bus_voltage": np.nan}).to_csv(path, index=False)
    got = load_envelope_log(path)
    assert got.bus_voltage is None and got.ignored == ("bus_voltage",) and got.n == 2000
    pd.DataFrame({"velocity": log.velocity, "torque": log.torque * 1e3}).to_csv(path, index=False)  # mN m, unlabeled
    with pytest.raises(DynoDataError, match=r"torque reaches .* check its unit.*--units torque=mN\*m"):
        compare(load_envelope_log(path), EnvelopeInputs(SPEC))
    pd.DataFrame({"velocity": log.velocity * 60 / (2 * np.pi), "torque": log.torque}).to_csv(path, index=False)
    with pytest.raises(DynoDataError, match="velocity reaches .* check its unit"):
        compare(load_envelope_log(path), EnvelopeInputs(SPEC))


def test_a_measured_envelope_sends_isaac_lab_joints_to_the_runtime(tmp_path):
    """DCMotor holds straight lines: joints whose motor has a measured envelope point to the runtime, saying by how
    much the straight lines over-promise."""
    from hound_id.export.bundle import build_bundle
    from hound_id.export.formats import Export, isaaclab_fields
    from tests.mor.test_region import write_envelope_spec

    spec = load_motor_spec(write_envelope_spec(tmp_path / "env.yaml", {"bus_sag": 0.15}))
    robot = load_robot(ROBOT)
    robot = replace(robot, motor_specs={m: spec for m in robot.motor_specs})
    fields = isaaclab_fields(Export(robot=robot, bundle=build_bundle(robot)))
    haa = fields["joints"]["FL_HAA"]
    assert haa["use"] == "hound_id.runtime" and "measured envelope" in haa["reason"]
    # the largest gap is at the straight line's corner, where it leaves the torque limit (not a polyline point)
    corner = (SPEC.stall_torque - SPEC.linear_torque_limit) / SPEC.back_emf_damping
    gap = 9.0 * (SPEC.linear_torque_limit - np.interp(corner, spec.envelope.speeds, spec.envelope.upper))
    assert float(haa["reason"].split("allow up to ")[1].split(" N m")[0]) == pytest.approx(gap, rel=0.01)


def test_a_jump_at_the_end_of_an_edge_is_isolated_but_a_departure_is_not():
    """The last bin of an edge jumps 12 N m from a neighbour that fits: no edge changes that fast between
    neighbouring speeds. A last bin that departs by what the back-EMF slope allows stays (effects show there)."""
    from hound_id.dyno.envelope.offsets import Offsets, isolated_bins
    from hound_id.dyno.envelope.walls import Walls

    slope = SPEC.back_emf_damping
    speeds = np.array([400.0, 412.0, 424.0, 436.0])
    walls = Walls(centres=speeds, upper=tuple(np.arange(10) + 10 * k for k in range(4)), lower=(), method="wall")

    def offsets_with(last):
        n = speeds.size
        return Offsets(speeds, np.ones(n, dtype=np.int8), np.array([0.0, 0.001, -0.001, last]), np.full(n, 0.005),
                       np.full(n, 0.03))  # fmt: skip

    kept, found = isolated_bins(walls, offsets_with(-12.2), slope)
    assert len(found) == 1 and found[0].speed == 436.0 and kept.upper[3].size == 0
    kept, found = isolated_bins(walls, offsets_with(-1.5), slope)  # 1.5 N m < 2 x 0.22 x 12 N m: a real departure
    assert found == [] and kept.upper[3].size == 10
