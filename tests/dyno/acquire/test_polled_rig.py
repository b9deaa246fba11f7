"""fit-current on a second, independent simulator (tests/dyno/acquire/polledrig.py) with real-rig artefacts.

Each artefact must be detected and named, and no fit on it may be confidently wrong: either the
truth lies within a few standard errors, or the log is flagged (never "at the noise floor"), or the
fit is refused with the reason.
"""

from __future__ import annotations

import dataclasses
import math
from functools import lru_cache

import numpy as np
import pandas as pd
import pytest

from hound_id.dyno.artefacts import PLATEAU_SIGMAS, flipped_at_boundary, noise_sigma
from hound_id.dyno.current.curve import peak_torque
from hound_id.dyno.current.diagnose import auto, diagnose
from hound_id.dyno.current.effects import Signals
from hound_id.dyno.current.fit import fit_model
from hound_id.dyno.current.search import bounds_of, parameters_of
from hound_id.dyno.logs import DynoLog, load_log, parse_mapping
from hound_id.errors import DynoDataError, FitError
from tests.dyno.acquire.polledrig import COLUMNS, Rig, Truth, run, write

MAP = parse_mapping(COLUMNS, "--columns")
DEFAULT = ("linear", "saturation")
FRICTION = Truth(coulomb=0.25, gear_friction=0.05)


@lru_cache(maxsize=32)
def frame(rig: Rig) -> pd.DataFrame:
    return run(rig)


def load(tmp_path, rig: Rig, name: str = "log.csv", columns=MAP, **kw) -> DynoLog:
    return load_log(write(frame(rig), tmp_path / name, **kw), columns=columns)


def ladder_of(log: DynoLog, model=DEFAULT):
    s = Signals.from_log(log)
    return s, auto(s, log.torque, fit_model(s, log.torque, model))


def kinds(log: DynoLog) -> list[str]:
    return [n.kind for n in log.notes]


def note(log: DynoLog, kind: str) -> str:
    return " | ".join(n.message for n in log.notes if n.kind == kind)


def assert_physical(fit) -> None:
    lower, upper = bounds_of(fit.model)
    for (_, par), lo, hi in zip(parameters_of(fit.model), lower, upper, strict=True):
        assert lo <= fit.value(par.name) <= hi, (par.name, fit.value(par.name))


def assert_not_confidently_wrong(fit, diagnosis, kt: float) -> None:
    """Kt within 4 standard errors (plus 1 %) of the truth, unless the log is flagged."""
    assert_physical(fit)
    est = fit.parameters["kt"]
    if not diagnosis.flags:
        assert abs(est.value - kt) <= 4 * est.stderr + 0.01 * kt, (est, kt)
    else:
        assert not diagnosis.at_noise_floor


# --- a clean polled log: late reply, filtered transducer, AR(1) noise, jittered loop ----------------------


def test_a_clean_polled_log_recovers_the_truth_and_names_the_late_current(tmp_path):
    log = load(tmp_path, Rig(truth=FRICTION))
    assert log.n == log.rows_read  # nothing to clean
    signals, ladder = ladder_of(log)
    fit = ladder[-1].fit
    assert set(fit.model) == {"linear", "saturation", "coulomb", "gear_friction", "delay"}
    assert fit.value("kt") == pytest.approx(1.15, rel=0.003)
    assert fit.value("coulomb") == pytest.approx(0.25, abs=0.015)
    assert fit.value("gear_friction") == pytest.approx(0.05, abs=0.004)
    assert_not_confidently_wrong(fit, ladder[-1].diagnosis, 1.15)
    # one loop late (6.7 ms) less the transducer's group delay (2.8 ms at 80 Hz): the current lags
    assert -0.0055 < fit.value("delay") < -0.0025
    step = next(k for k, s in enumerate(ladder) if s.added == "delay")
    reason = next(s.reason for s in ladder[step - 1].diagnosis.suggestions if s.effect == "delay")
    assert "current channel lags" in reason and "one loop late" in reason
    assert not fit.unphysical


@pytest.mark.parametrize(
    ("rig", "low", "high", "words"),
    [
        (Rig(torque_filter_hz=1500.0, current_late=True), -0.0080, -0.0055, "current channel lags"),
        (Rig(torque_filter_hz=30.0, current_late=False), 0.0060, 0.0090, "torque channel lags"),
    ],
    ids=["reply-one-loop-late", "filtered-transducer"],
)
def test_the_delay_is_signed_and_both_signs_are_named(tmp_path, rig, low, high, words):
    log = load(tmp_path, rig)
    signals = Signals.from_log(log)
    fit = fit_model(signals, log.torque, (*DEFAULT, "coulomb", "delay"))
    assert low < fit.value("delay") < high
    d = diagnose(signals, log.torque, fit_model(signals, log.torque, (*DEFAULT, "coulomb")))
    top = next(s for s in d.suggestions if s.effect == "delay")
    assert top.significant and words in top.reason


# --- the transducer's own dynamics: a resonance of the coupling, a first-order amplifier filter -----------------

#: A 500 Hz host loop (the reply still one loop late, the loop jittered), the transducer's Butterworth out of the way.
FAST = {"rate_hz": 500.0, "seconds": 30.0, "torque_filter_hz": 1500.0}


def test_a_transducer_resonance_is_found_named_and_valued(tmp_path):
    rig = Rig(truth=FRICTION, resonance_hz=25.0, resonance_zeta=0.15, **FAST)
    log = load(tmp_path, rig)
    signals, ladder = ladder_of(log)
    assert ladder[1].added == "resonance"  # the largest missing effect: every current step rings
    reason = next(s.reason for s in ladder[0].diagnosis.suggestions if s.effect == "resonance")
    assert "second-order resonance at" in reason and "rings at" in reason
    fit = ladder[-1].fit
    assert {"resonance", "delay", "coulomb", "gear_friction"} <= set(fit.model)
    assert fit.value("resonance_f0") == pytest.approx(25.0, rel=0.15)
    assert fit.value("resonance_zeta") == pytest.approx(0.15, rel=0.15)
    assert fit.parameters["resonance_f0"].stderr > 0 and fit.parameters["resonance_zeta"].stderr > 0
    assert -0.003 < fit.value("delay") < -0.001  # one 2 ms loop late, found with the resonance
    assert fit.value("kt") == pytest.approx(1.15, rel=0.003)
    # the error falls to the transducer's noise (AR(1), 0.03 N m), from 26x that without the resonance
    assert ladder[0].fit.rmse_test > 20 * rig.torque_noise
    assert fit.rmse_test < 1.6 * rig.torque_noise


def test_the_noise_floor_of_a_filtered_transducer_is_honest_without_still_stretches(tmp_path):
    """The rig never holds its inputs still, and its transducer noise is AR(1) with a correlation of 0.95 per loop:
    second differences read it at a fraction of its size. Pairs of far-apart moments with the same inputs read what
    no model of the logged channels removes: the transducer's 0.03 N m and the current reply's 0.02 A through Kt."""
    rig = Rig(truth=FRICTION, torque_noise_rho=0.95, **FAST)
    log = load(tmp_path, rig)
    signals, ladder = ladder_of(log)
    fit, d = ladder[-1].fit, ladder[-1].diagnosis
    assert {"coulomb", "gear_friction", "delay"} <= set(fit.model)
    honest = math.hypot(rig.torque_noise, FRICTION.kt * rig.current_noise)
    assert d.noise is not None and d.noise.still is None
    assert d.noise.method == "neighbours" and d.noise_floor == pytest.approx(honest, rel=0.15)
    assert abs(d.noise_floor - honest) < 3 * d.noise.paired.stderr  # its own error covers the truth
    assert d.noise.white < 0.6 * honest  # the sample-to-sample floor reads low
    assert "correlated" in d.noise.sentence() and d.noise.paired.drift is None
    # the final fit is 1.1x what no model removes; the ratio the tool prints is within the floor's own error of it
    assert fit.rmse_test < 1.2 * honest and fit.rmse_test / d.noise_floor < 1.5, d.summary()
    # and the floor says nothing is left while an effect is missing: the first rung is far from it
    assert ladder[0].fit.rmse_test > 5 * ladder[0].diagnosis.noise_floor


@pytest.mark.parametrize("share", [0.01, 0.05])
def test_a_gear_mesh_ripple_is_noise_that_grows_with_the_load_and_the_floor_counts_it(tmp_path, share):
    """A ripple with the output angle (which the log does not have), in proportion to the torque carried: noise that
    no model of the logged channels removes, loud at high current and quiet at none. Read over the whole log, the
    pairs' robust scatter is the quiet rows' (0.47-0.82x what is left); read in strata of the current, it is the root
    mean square the cross-validated RMSE is compared with."""
    rig = Rig(truth=FRICTION, mesh_ripple=share, **FAST)
    quiet = dataclasses.replace(rig, mesh_ripple=0.0)  # the same draws without the ripple
    ripple = frame(rig).torque_adc - frame(quiet).torque_adc
    honest = math.sqrt(rig.torque_noise**2 + (FRICTION.kt * rig.current_noise) ** 2 + float(np.mean(ripple**2)))
    log = load(tmp_path, rig)
    signals, ladder = ladder_of(log)
    fit, d = ladder[-1].fit, ladder[-1].diagnosis
    assert d.noise is not None and d.noise.load is not None, d.noise.sentence()
    assert d.noise.load.sigma[-1] > 2 * d.noise.load.sigma[0]
    assert d.noise_floor == pytest.approx(honest, rel=0.1), d.noise.sentence()
    assert "grows with the load" in d.noise.sentence()
    assert fit.value("kt") == pytest.approx(FRICTION.kt, rel=0.005)
    assert fit.rmse_test < 1.1 * honest and d.at_noise_floor, d.summary()


def test_a_first_order_transducer_lag_is_found_and_valued(tmp_path):
    rig = Rig(truth=FRICTION, lag_ms=6.0, current_late=False, **FAST)
    log = load(tmp_path, rig)
    signals, ladder = ladder_of(log)
    fit = ladder[-1].fit
    assert "lag" in fit.model, [s.added for s in ladder]
    assert fit.value("lag_tau") == pytest.approx(0.006, rel=0.15)
    assert fit.value("kt") == pytest.approx(1.15, rel=0.003)
    assert fit.rmse_test < 1.6 * rig.torque_noise


def test_a_transducer_the_log_cannot_resolve_gives_no_filter(tmp_path):
    # a coupling mode at 70 Hz in a 150 Hz log: past the 67 Hz the log can show, so no resonance value is reported
    rig = Rig(truth=FRICTION, resonance_hz=70.0, resonance_zeta=0.15)
    log = load(tmp_path, rig)
    signals, ladder = ladder_of(log)
    fit = ladder[-1].fit
    assert "resonance" not in fit.model
    why = " ".join(s for step in ladder for s in step.diagnosis.skipped if s.startswith("resonance"))
    assert "edge of what this log can show" in why or "not determined" in why or "no trace" in why, why
    assert_not_confidently_wrong(fit, ladder[-1].diagnosis, 1.15)


def test_a_delay_outside_its_window_is_refused(tmp_path):
    log = load(tmp_path, Rig())
    signals = Signals.from_log(log)
    late = signals.shifted(-0.08)  # the current 80 ms late: no transducer or bus does that
    with pytest.raises(FitError, match="outside the"):
        fit_model(late, log.torque, (*DEFAULT, "coulomb", "delay"))


# --- driver and sensor limits ------------------------------------------------------------------------------


def test_a_driver_current_limit_is_named_kept_and_changes_the_advice(tmp_path):
    log = load(tmp_path, Rig(driver_limit=8.0))
    assert log.n == log.rows_read  # the rows at the limit are data
    assert "current_limit" in kinds(log) and "clamp" not in kinds(log)
    assert log.current_limit == pytest.approx(8.0, abs=0.15)
    assert "driver current limit at 8.0" in note(log, "current_limit")
    signals, ladder = ladder_of(log)
    fit = ladder[-1].fit
    assert_not_confidently_wrong(fit, ladder[-1].diagnosis, 1.15)
    peak = peak_torque(fit, float(np.max(np.abs(signals.current))), current_limit=log.current_limit)
    assert "driver" in peak.note and "test at higher current" not in peak.note


def test_a_reply_held_at_the_top_of_its_range_is_a_protocol_clamp_not_the_driver(tmp_path):
    # the drive gives 8.2 A, the reply's range ends at 8.0 A, and the first reply past it overflows to the other end
    rig = Rig(driver_limit=8.2, current_clamp=8.0, flip_at_clamp=True)
    reply = frame(rig)["iq_meas"].to_numpy()
    flips = int(np.count_nonzero(np.abs(np.abs(reply) - 7.99) < 1e-9))
    assert flips >= 5  # the rig made some
    log = load(tmp_path, rig)
    assert "reply_clamp" in kinds(log) and "current_limit" not in kinds(log) and "clamp" not in kinds(log)
    text = note(log, "reply_clamp")
    assert "held at 8 A, the top of its range" in text and "held at -8 A" in text and "not the driver" in text
    assert log.current_limit is None and log.current_range == pytest.approx(8.0, abs=0.01)
    # the drive gives 2.5 % more than the reply says: those rows are removed
    assert "goes past what the level makes" in text and "rows were removed" in text
    assert log.rows_read - log.n == sum(n.rows for n in log.notes)
    # the overflowed replies are read as crossings of the range's end (a wrap at its edge, restored from the torque)
    # or removed: none is left at the wrong end
    assert "wrap" in kinds(log) or "reply_flip" in kinds(log)
    assert not flipped_at_boundary(log.current, log.torque, 8.0).any()
    assert flipped_at_boundary(reply, frame(rig)["torque_adc"].to_numpy(), 8.0).sum() >= 5  # there were, as read
    signals, ladder = ladder_of(log)
    fit = ladder[-1].fit
    assert_not_confidently_wrong(fit, ladder[-1].diagnosis, 1.15)
    peak = peak_torque(fit, float(np.max(np.abs(signals.current))), reply_range=log.current_range)
    assert "cannot say more than 8" in peak.note and "driver" not in peak.note
    # the drive gives what the reply says (the clamp at the driver's limit, no friction to blur the torque there): the
    # rows are data and kept; with friction the torque cannot show it within 1 %, and they go (tested above)
    held = load(tmp_path, Rig(Truth(coulomb=0.0), driver_limit=8.0, current_clamp=8.0), name="held.csv")
    assert "reply_clamp" in kinds(held) and "stays with the level" in note(held, "reply_clamp")
    assert held.n == held.rows_read


def test_a_reply_held_at_its_range_is_named_without_a_command_and_in_a_short_log(tmp_path):
    # no command column: the pile at the top of a noisy reply still names the reply's range; the drive's 8.2 A behind
    # it would bias Kt by 1.6 % (13 standard errors) if those rows stayed
    rig = Rig(driver_limit=8.2, current_clamp=8.0, flip_at_clamp=True)
    columns = {k: v for k, v in MAP.items() if k != "current_cmd"}
    log = load(tmp_path, rig, name="nocmd.csv", columns=columns, drop=("iq_cmd",))
    assert "reply_clamp" in kinds(log) and "rows were removed" in note(log, "reply_clamp")
    assert log.current_limit is None
    signals, ladder = ladder_of(log)
    assert_not_confidently_wrong(ladder[-1].fit, ladder[-1].diagnosis, 1.15)
    # ten seconds of the same rig: the wrap-around takes the boundary rows; the reply's range, not the driver, is named
    short = load(tmp_path, dataclasses.replace(rig, seconds=10.0), name="short.csv")
    assert short.current_limit is None and "current_limit" not in kinds(short)
    assert "the reply cannot say more than 8" in note(short, "wrap")


def test_a_clamped_reply_is_named_and_its_rows_removed(tmp_path):
    rig = Rig(current_clamp=7.5)
    log = load(tmp_path, rig)
    text = note(log, "clamp")
    assert "clamped at 7.5 A" in text and "clamped at -7.5 A" in text
    reply = frame(rig)["iq_meas"].to_numpy()
    removed = log.rows_read - log.n
    assert removed == sum(n.rows for n in log.notes if n.kind == "clamp")  # counted once each
    # every row at the clamp, and beside it only rows within the reply's noise of it (PLATEAU_SIGMAS sigmas)
    near = 7.5 - PLATEAU_SIGMAS * noise_sigma(reply) - 1e-9
    assert np.count_nonzero(np.abs(reply) >= 7.5) <= removed <= np.count_nonzero(np.abs(reply) >= near)
    assert not any(n.kind == "glitch" for n in log.notes)  # the rows next to the cut are no spikes
    signals, ladder = ladder_of(log)
    assert_not_confidently_wrong(ladder[-1].fit, ladder[-1].diagnosis, 1.15)


def test_a_held_current_that_the_command_asks_for_is_not_a_clamp(tmp_path):
    # the command itself is clipped at +-10 A for long stretches while friction moves the torque
    log = load(tmp_path, Rig(truth=FRICTION))
    assert "clamp" not in kinds(log) and "current_limit" not in kinds(log)


def test_a_wrap_is_not_restored_from_a_torque_that_flips(tmp_path):
    # the reply wraps at +-7.5 A, and from 40 s the torque amplifier reads -4x: the torque there would ask for
    # currents of several periods, so it does not choose the periods; the channel is folded back instead
    rig = Rig(wrap_period=15.0, torque_fault_from=40.0)
    log = load(tmp_path, rig)
    text = note(log, "wrap")
    assert "wraps around" in text and "folded back into +-7.5 A" in text and "went past" not in text
    assert float(np.max(np.abs(log.current))) <= 7.5 + 0.05
    # the fit names the broken stretch rather than trusting it
    signals, ladder = ladder_of(log)
    d = ladder[-1].diagnosis
    assert d.flags and not d.at_noise_floor
    assert any(signals.time[s.start] >= 38.0 for s in d.stretches)  # the broken stretch is the one flagged


@pytest.mark.parametrize(
    ("column", "channel"), [("torque_adc", "torque"), ("iq_meas", "current"), ("speed", "velocity")]
)
def test_a_stale_channel_is_found_named_and_aligned(tmp_path, column, channel):
    # one column updates on its own clock, every 4 polls on average (37.5 Hz in a 150 Hz log), the instants staggered
    rig = Rig(truth=FRICTION, speed_steps=True, stale=column, stale_every=4.0)
    log = load(tmp_path, rig)
    stale = [n for n in log.notes if n.kind == "stale"]
    assert [n.channel for n in stale] == [channel]
    hold = float(stale[0].message.split("every ")[1].split(" samples")[0])
    assert hold == pytest.approx(4.0, rel=0.15)
    assert stale[0].rows == 0 and log.n >= log.rows_read - 4  # aligned, not refused or cut (a glitch or two aside)
    signals, ladder = ladder_of(log)
    fit = ladder[-1].fit
    assert fit.value("kt") == pytest.approx(1.15, rel=0.01)
    assert_not_confidently_wrong(fit, ladder[-1].diagnosis, 1.15)
    # the error falls against the same model on the channel as read (held values); the speed enters only through
    # friction's sign and the inertia, so there it need only not rise
    raw = frame(rig)
    held = Signals(
        time=raw["loop_time"].to_numpy(), current=raw["iq_meas"].to_numpy(), velocity=raw["speed"].to_numpy()
    )
    before = fit_model(held, raw["torque_adc"].to_numpy(), fit.model)
    factor = 1.05 if channel == "velocity" else 0.9
    assert fit.rmse_test < factor * before.rmse_test, (fit.rmse_test, before.rmse_test)
    # the same rig with every column live: nothing is called stale
    assert "stale" not in kinds(load(tmp_path, Rig(truth=FRICTION, speed_steps=True), name="live.csv"))


def test_a_current_wrapped_past_its_range_is_restored_from_the_torque(tmp_path):
    rig = Rig(wrap_period=15.0)
    log = load(tmp_path, rig)
    text = note(log, "wrap")
    assert "wraps around" in text and "went past the range" in text and "+-7.5 A" in text
    assert log.n == log.rows_read
    clean = load(tmp_path, Rig(), name="clean.csv")
    assert np.max(np.abs(log.current - clean.current)) < 0.05  # every row back to its true value
    signals, ladder = ladder_of(log)
    assert ladder[-1].fit.value("kt") == pytest.approx(1.15, rel=0.003)


def test_a_current_sitting_at_the_edge_of_its_range_flips_sign_and_is_named_a_wrap(tmp_path):
    # the driver holds the current at the reply's range: noise flips the reply between +7.5 and -7.5 A
    rig = Rig(wrap_period=15.0, driver_limit=7.5)
    log = load(tmp_path, rig)
    assert "wraps around" in note(log, "wrap") and "+-7.5 A" in note(log, "wrap")
    assert not any(n.kind == "glitch" and n.channel == "current" for n in log.notes)
    # no row left with the wrong sign (beyond the transients of steps, where the late reply trails the torque)
    assert np.mean(log.current[log.torque > 5.0] < 0) < 0.005
    signals, ladder = ladder_of(log)
    assert_not_confidently_wrong(ladder[-1].fit, ladder[-1].diagnosis, 1.15)


# --- files as rigs write them -------------------------------------------------------------------------------


@pytest.mark.parametrize("separator", [",", ", ", ";", "\t"])
def test_title_line_units_row_separators_and_a_trailing_field_are_read(tmp_path, separator):
    rig = Rig(seconds=10.0)
    units = {"loop_time": "ms", "iq_meas": "mA", "iq_cmd": "A", "torque_adc": "N.mm", "speed": "rad.s"}
    scale = {"loop_time": 1e3, "iq_meas": 1e3, "torque_adc": 1e3}
    log = load(
        tmp_path,
        rig,
        title="AK80-9 opposing-motor test, 2026-11-23 10:41",
        units=units,
        separator=separator,
        trailing="0",
        scale=scale,
    )
    text = " | ".join(n.message for n in log.notes)
    assert "skipped 1 line above the header" in text and "units row" in text
    assert "the last field is always '0' and was dropped" in text
    plain = load(tmp_path, rig, name="plain.csv")
    np.testing.assert_allclose(log.time, plain.time, atol=1e-6)
    np.testing.assert_allclose(log.current, plain.current, atol=1e-5)
    np.testing.assert_allclose(log.torque, plain.torque, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(log.velocity, plain.velocity, rtol=1e-5)


def test_a_varying_extra_field_is_kept_not_shifted(tmp_path):
    f = frame(Rig(seconds=10.0)).copy()
    path = tmp_path / "extra.csv"
    lines = [",".join(f.columns)] + [",".join(f"{v:.6g}" for v in row) + f",{k % 7}" for k, row in enumerate(f.values)]
    path.write_text("\n".join(lines) + "\n")
    log = load_log(path, columns=MAP)
    assert log.current == pytest.approx(load(tmp_path, Rig(seconds=10.0), name="p.csv").current)


def test_time_in_ms_without_a_unit_is_a_warning_and_no_delay_is_fitted(tmp_path):
    log = load(tmp_path, Rig(), scale={"loop_time": 1e3})
    assert "if it is in ms" in " ".join(n.message for n in log.notes)
    signals = Signals.from_log(log)
    d = diagnose(signals, log.torque, fit_model(signals, log.torque, DEFAULT))
    assert any(s.startswith("delay (the samples are") and "--units time=ms" in s for s in d.skipped)
    with pytest.raises(FitError, match="cannot be seen"):
        fit_model(signals, log.torque, (*DEFAULT, "delay"))


# --- broken logs are flagged, never at the noise floor ---------------------------------------------------------


@pytest.mark.parametrize(
    ("rig", "start", "seen", "kind"),
    [
        (Rig(truth=FRICTION, motor_off_at=40.0), 40.0, 0.5, "current frozen"),
        (Rig(truth=FRICTION, runaway_from=35.0), 35.0, 2.0, "torque ignores the current"),
    ],
    ids=["motor-off", "current-runs-away"],
)
def test_a_log_that_breaks_midway_is_flagged_with_its_times(tmp_path, rig, start, seen, kind):
    """Flagged from the block where it breaks (a runaway shows once it has run `seen` seconds)."""
    log = load(tmp_path, rig)
    signals, ladder = ladder_of(log)
    for step in ladder:
        assert not step.diagnosis.at_noise_floor
    d = ladder[-1].diagnosis
    first = next(f for f in d.flags if f.startswith("blocks"))
    t0 = float(first.split("t = ")[1].split("-")[0])
    assert start - 1.5 < t0 <= start + seen, first
    assert d.disagreeing[-1] and not d.disagreeing[0]
    # outside the flagged blocks the model is far closer to its floor, and the summary says how close
    assert d.rmse_outside is not None and d.rmse_outside < 0.5 * d.rmse_test
    if "does not follow any model" in d.summary():
        assert f"outside the flagged stretches the cross-validated residual is {d.rmse_outside:.3g} N m" in d.summary()
    # the headline leaves the broken end out, says what it is from the channels, and repeats with an accepted option
    from hound_id.dyno.current.run import FitCurrentOptions, fit_current

    path = write(frame(rig), tmp_path / "again.csv")
    result = fit_current(path, FitCurrentOptions(columns=MAP, auto=True))
    report = result.report_json()
    assert report["whole_log"]["flags"]
    left = sorted(report["left_out"], key=lambda s: s["time"][0])
    assert start - 1.5 < left[0]["time"][0] <= start + seen + 1.0 and left[-1]["time"][1] > 59
    # the fault is named from its channels; its onset, where the channels still look ordinary, is left out as what
    # it looks like, and nothing before the break is
    kinds = {s["kind"] for s in left}
    assert kind in kinds and kinds <= {kind, "another regime", "step transient"}, kinds
    assert all(s["time"][0] > start - 1.5 for s in left)
    for flag in (f for f in report["flags"] if f.startswith("blocks")):
        assert float(flag.split("t = ")[1].split("-")[0]) > start - 1.5, flag
    assert result.fit.value("kt") == pytest.approx(1.15, rel=0.005)
    option = report["headline"]["option"]
    assert option.startswith("--window ")
    again = fit_current(path, FitCurrentOptions(columns=MAP, auto=True, window=option.split(" ", 1)[1]))
    assert again.fit.value("kt") == pytest.approx(result.fit.value("kt"), rel=1e-9) and again.report.headline is None


def test_a_flagged_training_fold_is_not_hidden_by_a_good_held_out_error(tmp_path):
    # the broken part sits in most folds' training rows: the fold's train error is far above its held-out one
    log = load(tmp_path, Rig(motor_off_at=40.0))
    signals = Signals.from_log(log)
    fit = fit_model(signals, log.torque, DEFAULT)
    d = diagnose(signals, log.torque, fit)
    assert d.flags and not d.at_noise_floor
    assert "disagree" in d.summary() or any("disagree" in f for f in d.flags)


# --- regimes that cannot identify a parameter -------------------------------------------------------------------


def test_one_quadrant_cannot_tell_kt_from_gear_friction(tmp_path):
    log = load(tmp_path, Rig(quadrants="motoring", truth=FRICTION))
    signals = Signals.from_log(log)
    with pytest.raises(FitError, match="cannot tell kt from gear_friction.*all four quadrants.*leave out 'gear_fric"):
        fit_model(signals, log.torque, (*DEFAULT, "gear_friction"))
    d = diagnose(signals, log.torque, fit_model(signals, log.torque, DEFAULT))
    assert any(s.startswith("gear_friction (this log cannot tell") for s in d.skipped)


def test_one_speed_sign_cannot_tell_coulomb_from_an_offset(tmp_path):
    log = load(tmp_path, Rig(quadrants="one_speed_sign"))
    signals, ladder = ladder_of(log)
    final = ladder[-1]
    assert "coulomb" not in final.fit.model
    assert any(
        s.startswith("coulomb (this log cannot tell") and "both directions" in s for s in final.diagnosis.skipped
    )
    if "offset" in final.fit.model:  # the step it stands for is named as either
        step = next(k for k, s in enumerate(ladder) if s.added == "offset")
        reason = next(s.reason for s in ladder[step - 1].diagnosis.suggestions if s.effect == "offset")
        assert "Coulomb friction" in reason and "cannot be told apart" in reason


def test_a_held_current_cannot_identify_kt(tmp_path):
    log = load(tmp_path, Rig(constant_current=6.0))
    assert "clamp" not in kinds(log)
    signals = Signals.from_log(log)
    with pytest.raises(FitError, match="cannot tell kt from a torque offset: the current hardly varies"):
        fit_model(signals, log.torque, DEFAULT)


# --- physically possible models only ---------------------------------------------------------------------------


def test_friction_with_the_wrong_sign_is_reported_and_never_added(tmp_path):
    f = frame(Rig()).copy()
    # a torque that rises with the speed's sign: Coulomb friction would have to be negative to explain it
    f["torque_adc"] = f["torque_adc"] + 0.5 * np.tanh(f["speed"] / 0.02)
    path = tmp_path / "wrong.csv"
    f.to_csv(path, index=False)
    log = load_log(path, columns=MAP)
    signals, ladder = ladder_of(log)
    for step in ladder:
        assert step.added not in ("coulomb", "stribeck")
        assert_physical(step.fit)
    first = ladder[0].diagnosis
    coulomb = next(s for s in first.suggestions if s.effect == "coulomb")
    assert not coulomb.significant and coulomb.reason.startswith("fits only with coulomb < 0")


@pytest.mark.parametrize("model", [DEFAULT, ("linear",), ("linear", "offset", "coulomb"), ("linear", "viscous")])
@pytest.mark.parametrize("robust", [False, True])
def test_negative_kt_is_never_accepted(tmp_path, model, robust):
    log = load(tmp_path, Rig())
    signals = Signals.from_log(log)
    with pytest.raises(DynoDataError, match="reversed"):
        fit_model(signals, -log.torque, model, robust=robust)


def test_a_reversed_sensor_is_refused_by_the_loader_with_the_fix(tmp_path):
    f = frame(Rig()).copy()
    f["torque_adc"] = -f["torque_adc"]
    path = tmp_path / "reversed.csv"
    f.to_csv(path, index=False)
    with pytest.raises(DynoDataError, match="--flip-torque"):
        load_log(path, columns=MAP)
    flipped = load_log(path, columns=MAP, flip_torque=True)
    fit = fit_model(Signals.from_log(flipped), flipped.torque, DEFAULT)
    assert fit.value("kt") == pytest.approx(1.15, rel=0.01)


# --- a steady-state table --------------------------------------------------------------------------------------


def steady_state_table(path, truth: Truth = FRICTION, seed: int = 0):
    """An ODrive-style dyno table: date line, units row, ', ' separators, one quadrant, no time column."""
    rng = np.random.default_rng(seed)
    rows = []
    for speed in (0.5, 1.0, 1.5, 2.0, 2.5, 3.0):
        for current in np.linspace(0.5, 10.0, 20):
            torque = truth.kt * current - truth.coulomb - truth.gear_friction * current - 0.05 * speed
            rows.append((current * 1e3, (torque + rng.normal(0, 0.02)) * 1e3, speed, 25 + 2 * current))
    lines = [
        "Dyno run 2026-11-23 14:02, motor D5065",
        "Test motor q-axis current, Output Torque, Output Speed, Test Motor Temperature",
        "mA, N.mm, rad.s, Deg C",
    ]
    lines += [", ".join(f"{v:.6g}" for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


STEADY = parse_mapping(
    "current=Test motor q-axis current,torque=Output Torque,velocity=Output Speed,temperature=Test Motor Temperature",
    "--columns",
)


def test_a_steady_state_table_loads_with_only_columns_and_reports_what_it_cannot_show(tmp_path):
    log = load_log(steady_state_table(tmp_path / "dyno.csv"), columns=STEADY)
    assert not log.timed and "steady_state" in kinds(log)
    assert log.current.max() == pytest.approx(10.0)
    signals, ladder = ladder_of(log)
    final = ladder[-1]
    skipped = " ".join(final.diagnosis.skipped)
    assert "delay (a steady-state table has no sample times)" in skipped
    assert "gear_friction (this log cannot tell" in skipped
    assert "gear_friction" not in final.fit.model and "delay" not in final.fit.model
    # Kt here is the plain slope: load-dependent friction cannot be taken out of it on one quadrant
    assert final.fit.value("kt") == pytest.approx(1.15 - 0.05, rel=0.01)
    assert_physical(final.fit)
    for f in final.diagnosis.flags:
        assert "data rows" in f or "Kt" in f  # spans are named in the table's own rows


def test_a_steady_state_table_cannot_fit_a_delay(tmp_path):
    log = load_log(steady_state_table(tmp_path / "dyno.csv"), columns=STEADY)
    with pytest.raises(FitError, match="steady-state table"):
        fit_model(Signals.from_log(log), log.torque, (*DEFAULT, "delay"))
    assert math.isfinite(fit_model(Signals.from_log(log), log.torque, DEFAULT).rmse_test)


def test_a_torque_sensor_the_motor_does_not_load_gives_no_kt(tmp_path):
    f = frame(Rig()).copy()
    rng = np.random.default_rng(3)
    f["torque_adc"] = 0.2 * np.sin(np.linspace(0, 40, len(f))) + rng.normal(0, 0.05, len(f))  # drift and noise only
    path = tmp_path / "unloaded.csv"
    f.to_csv(path, index=False)
    log = load_log(path, columns=MAP)
    with pytest.raises(FitError, match="the torque does not follow the current.*no different from zero"):
        fit_model(Signals.from_log(log), log.torque, DEFAULT)


def test_a_torque_channel_stuck_at_one_value_is_refused(tmp_path):
    f = frame(Rig()).copy()
    f["torque_adc"] = -2.741623e16  # an ADC never read: one huge value on every row
    path = tmp_path / "stuck.csv"
    f.to_csv(path, index=False)
    with pytest.raises(DynoDataError, match="torque channel holds one value .* on every row"):
        load_log(path, columns=MAP)


# --- the rig's own dynamics and a logger's habits -----------------------------------------------------------------


def test_the_inertia_before_the_sensor_is_found_and_measured(tmp_path):
    """An opposing motor stepping the speed: the rotor and coupling between motor and sensor take J dw/dt; --auto
    names it, with J within 15 %, and the error falls."""
    from hound_id.dyno.current.run import FitCurrentOptions, fit_current

    rig = Rig(truth=Truth(coulomb=0.25, inertia=0.02), speed_steps=True, speed_amplitude=4.0)
    result = fit_current(write(frame(rig), tmp_path / "inertia.csv"), FitCurrentOptions(columns=MAP, auto=True))
    assert "inertia" in result.fit.model
    est = result.fit.parameters["inertia"]
    assert est.value == pytest.approx(0.02, rel=0.15) and abs(est.value - 0.02) < 4 * est.stderr + 0.003
    step = next(s for s in result.ladder if s.added == "inertia")
    before = result.ladder[result.ladder.index(step) - 1]
    assert step.fit.rmse_test < 0.8 * before.fit.rmse_test
    assert any("inertia between the motor and the torque sensor" in s.reason for s in before.suggestions)


def test_a_logger_that_writes_each_sample_four_times_gives_the_same_fit(tmp_path):
    plain = load(tmp_path, Rig(truth=FRICTION), "plain.csv")
    repeated = load(tmp_path, Rig(truth=FRICTION, repeat=4), "repeated.csv")
    note_text = note(repeated, "duplicate_rows")
    assert f"collapsed {3 * plain.n} rows" in note_text and "up to 4 times" in note_text
    assert repeated.n == plain.n and np.array_equal(repeated.torque, plain.torque)


def test_a_coarse_torque_adc_sets_the_floor_at_its_rounding(tmp_path):
    q = 0.2  # N m per count, against 0.03 N m of noise
    log = load(tmp_path, Rig(truth=FRICTION, torque_quantum=q))
    signals = Signals.from_log(log)
    d = diagnose(signals, log.torque, fit_model(signals, log.torque, (*DEFAULT, "coulomb", "gear_friction")))
    assert d.noise is not None and d.noise.quantisation == pytest.approx(q / math.sqrt(12), rel=1e-6)
    assert d.noise_floor >= q / math.sqrt(12) - 1e-12


@pytest.mark.parametrize(("seed", "size", "seconds"), [(0, 0.1, 1.5), (1, 0.1, 1.5), (2, 0.3, 0.7), (0, 0.03, 1.5)])
def test_a_transducer_zero_that_wanders_is_named_slow_with_its_size(tmp_path, seed, size, seconds):
    """A strain-gauge zero that creeps over seconds (a Gauss-Markov process): no logged channel follows it, so no
    effect may claim it. Either the residual stays above the floor and the excess is called slow, or a floor read
    from far-apart moments holds the wander and the summary says half or more of that floor is the wander; either
    way with its size, and Kt stays right."""
    rig = Rig(truth=FRICTION, zero_wander=size, zero_wander_s=seconds, seed=seed, **FAST)
    quiet = dataclasses.replace(rig, zero_wander=0.0)  # the same draws without the wander
    zero = (frame(rig).torque_adc - frame(quiet).torque_adc).to_numpy()
    log = load(tmp_path, rig)
    signals, ladder = ladder_of(log)
    fit, d = ladder[-1].fit, ladder[-1].diagnosis
    assert d.wander is not None and d.wander.slow == pytest.approx(float(np.std(zero)), rel=0.15), (
        d.wander,
        float(np.std(zero)),
    )
    # the fast part is the noise plus the wander's own roughness within the window (0.1 N m for 0.3 N m over 0.7 s)
    noise = math.hypot(rig.torque_noise, FRICTION.kt * rig.current_noise)  # the transducer's and the reply's
    assert d.wander.fast < noise + size * math.sqrt(d.wander.window / (3 * seconds)), (d.wander.fast, noise)
    assert d.wander.follows is not None and d.wander.follows < 0.5  # the sweep comes back: no input predicts it
    if d.at_noise_floor:
        assert d.wander.floor_is_wander and "half or more of that floor's variance is slow" in d.summary(), d.summary()
    else:
        assert d.wander.is_slow and "is slow: the residual wanders by" in d.summary(), d.summary()
    assert_not_confidently_wrong(fit, d, FRICTION.kt)


def test_no_wander_is_read_where_the_log_reaches_its_floor(tmp_path):
    """AR(1) transducer noise (a correlation time of a few loops) is fast: no wander is claimed at the floor."""
    log = load(tmp_path, Rig(truth=FRICTION, **FAST))
    signals, ladder = ladder_of(log)
    d = ladder[-1].diagnosis
    assert d.at_noise_floor and d.wander is not None and not d.wander.floor_is_wander, d.summary()
    assert d.wander.slow < 0.5 * d.wander.fast
    assert "wander" not in d.summary()
