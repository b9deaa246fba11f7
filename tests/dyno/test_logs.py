"""Loading dyno logs: channels, units and the cleaning of dirty real logs.

The data follow a known model, torque = KT * current + noise, with seeded noise, so every
test knows which rows are genuine and which were spoiled on purpose.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hound_id.dyno.logs import (
    CANONICAL,
    CORE,
    MIN_ROWS,
    NOTE_KINDS,
    UNITS,
    CleaningNote,
    DynoLog,
    load_log,
    log_from_frame,
    parse_mapping,
)
from hound_id.errors import DynoDataError, TableError

KT = 0.1  # N m/A
RATE = 1000.0  # Hz
# Note kinds whose rows are removed from the log.
REMOVING = ("nan_rows", "glitch", "duplicate_time", "duplicate_rows", "adc_saturation")


def truth(n: int = 2000, seed: int = 0, current: np.ndarray | None = None, amplitude: float = 13.0) -> pd.DataFrame:
    """A clean log in SI: a current sweep (or the given current) and torque = KT * current + noise."""
    rng = np.random.default_rng(seed)
    n = n if current is None else current.size
    time = np.arange(n) / RATE
    if current is None:
        current = amplitude * np.sin(2 * np.pi * 0.5 * time) + rng.normal(0.0, 0.05, n)
    velocity = 20.0 + 5.0 * np.sin(2 * np.pi * 0.2 * time) + rng.normal(0.0, 0.1, n)
    return pd.DataFrame(
        {
            "time": time,
            "current": current,
            "torque": KT * current + rng.normal(0.0, 0.01, n),
            "velocity": velocity,
            "position": np.cumsum(velocity) / RATE,
            "temperature": 25.0 + 10.0 * time / time[-1] + rng.normal(0.0, 0.05, n),
            "bus_voltage": 48.0 + rng.normal(0.0, 0.1, n),
            "torque_cmd": KT * current,
            "current_cmd": current,
        }
    )


def write(frame: pd.DataFrame, path: Path) -> Path:
    if path.suffix == ".csv":
        frame.to_csv(path, index=False)
    else:
        frame.to_parquet(path, index=False)
    return path


def kinds(log: DynoLog) -> list[str]:
    return [note.kind for note in log.notes]


def notes_of(log: DynoLog, kind: str) -> list[CleaningNote]:
    return [note for note in log.notes if note.kind == kind]


# --- happy paths ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_a_clean_log_with_canonical_names_loads_unchanged(tmp_path, suffix):
    frame = truth()
    log = load_log(write(frame, tmp_path / f"log{suffix}"))
    assert log.notes == ()
    assert log.n == log.rows_read == len(frame)
    assert log.source == str(tmp_path / f"log{suffix}")
    assert log.sample_rate == pytest.approx(RATE)
    for name in CANONICAL:
        assert log.has(name)
        np.testing.assert_allclose(log.column(name), frame[name].to_numpy(), rtol=1e-12, atol=0)
        assert getattr(log, name) is log.column(name)
        with pytest.raises(ValueError, match="read-only"):
            log.column(name)[0] = 1.0


def test_the_log_does_not_alias_the_frame():
    frame = truth()
    log = log_from_frame(frame)
    frame["current"] = 0.0
    assert log.current[0] != 0.0 or log.current[1] != 0.0


def test_only_the_required_channels_are_needed():
    log = log_from_frame(truth()[list(CORE)])
    assert (log.velocity, log.position, log.temperature, log.bus_voltage) == (None, None, None, None)
    assert not log.has("velocity") and log.has("torque")
    assert UNITS["torque"] == "N*m" and set(UNITS) == set(CANONICAL)


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_columns_with_other_names_are_mapped(tmp_path, suffix):
    frame = truth()
    renamed = frame.rename(columns={"time": "t", "current": "iq", "torque": "adc_torque", "velocity": "speed"})
    path = write(renamed, tmp_path / f"log{suffix}")
    log = load_log(path, columns=parse_mapping("torque=adc_torque,current=iq,time=t,velocity=speed", "--columns"))
    np.testing.assert_allclose(log.torque, frame["torque"], rtol=1e-12)
    np.testing.assert_allclose(log.velocity, frame["velocity"], rtol=1e-12)
    assert log.position is not None  # still found by its canonical name
    assert log.notes == ()


@pytest.mark.parametrize("mapped", ["iq", "iq[mA]"])
def test_a_mapped_name_matches_a_header_with_a_unit_suffix(mapped):
    frame = truth()
    renamed = frame.assign(current=frame["current"] * 1000.0).rename(columns={"current": "iq[mA]"})
    log = log_from_frame(renamed, columns={"current": mapped})
    np.testing.assert_allclose(log.current, frame["current"], rtol=1e-12)
    assert [n.message for n in log.notes] == ["current converted from mA to A (unit from the header 'iq[mA]')"]


def test_header_unit_suffixes_are_converted_to_si(tmp_path):
    frame = truth()
    in_file = pd.DataFrame(
        {
            "time[ms]": frame["time"] * 1e3,
            "current[mA]": frame["current"] * 1e3,
            "torque [mN*m]": frame["torque"] * 1e3,
            "velocity[rpm]": frame["velocity"] * 60.0 / (2 * math.pi),
            "position[deg]": np.degrees(frame["position"]),
            "temperature[degF]": frame["temperature"] * 9.0 / 5.0 + 32.0,
            "bus_voltage [mV]": frame["bus_voltage"] * 1e3,
            "torque_cmd[mN*m]": frame["torque_cmd"] * 1e3,
            "current_cmd[mA]": frame["current_cmd"] * 1e3,
        }
    )
    log = load_log(write(in_file, tmp_path / "log.csv"))
    for name in CANONICAL:
        np.testing.assert_allclose(log.column(name), frame[name], rtol=1e-9, atol=1e-9, err_msg=name)
    assert kinds(log) == ["unit"] * len(CANONICAL)
    messages = [n.message for n in log.notes]
    assert "velocity converted from rpm to rad/s (unit from the header 'velocity[rpm]')" in messages
    assert "temperature converted from degF to degC (unit from the header 'temperature[degF]')" in messages
    assert all(n.rows == len(frame) for n in log.notes)


@pytest.mark.parametrize(("unit", "to_file"), [("K", lambda c: c + 273.15), ("degF", lambda c: c * 1.8 + 32.0)])
def test_temperatures_in_offset_units_become_degrees_celsius(unit, to_file):
    frame = truth()
    celsius = np.array([-40.0, 0.0, 20.0, 100.0])
    frame["temperature"] = np.resize(celsius, len(frame))
    log = log_from_frame(frame.assign(temperature=to_file(frame["temperature"])), units={"temperature": unit})
    np.testing.assert_allclose(log.temperature, frame["temperature"], atol=1e-9)


def test_si_units_in_the_header_are_kept_without_a_note_and_nm_is_newton_metre():
    frame = truth()[list(CORE)].rename(columns={"time": "time[s]", "torque": "torque[Nm]"})
    log = log_from_frame(frame)
    assert log.notes == ()
    assert log.torque == pytest.approx(frame["torque[Nm]"].to_numpy())


def test_units_option_overrides_the_header_and_converts_unsuffixed_columns():
    frame = truth()
    in_file = frame.assign(
        velocity=frame["velocity"] * 60.0 / (2 * math.pi), position=np.degrees(frame["position"])
    ).rename(columns={"velocity": "velocity[deg/s]"})
    log = log_from_frame(in_file, units=parse_mapping("velocity=rpm, position=deg", "--units"))
    np.testing.assert_allclose(log.velocity, frame["velocity"], rtol=1e-12)
    np.testing.assert_allclose(log.position, frame["position"], rtol=1e-12)
    velocity_note = [n for n in log.notes if n.channel == "velocity"][0]
    assert velocity_note.message == (
        "velocity converted from rpm to rad/s (unit from --units, overriding the header unit 'deg/s')"
    )


@pytest.mark.parametrize(
    ("header", "units", "match"),
    [
        ("velocity[V]", None, r"column 'velocity\[V\]' has the unit 'V' .*dimension .*expected an angular speed"),
        ("velocity[Hz]", None, r"'velocity\[Hz\]'.*Hz, which is ambiguous for an angular speed.*rpm"),
        ("velocity", {"velocity": "kHz"}, r"ambiguous for an angular speed"),
        ("velocity", {"velocity": "1/s"}, r"'velocity' has the unit '1/s' \(from --units\).*expected an angular"),
        ("position[count]", None, r"'position\[count\]' has the unit 'count'.*expected an angle"),
        ("temperature[A]", None, r"expected a temperature in a unit such as degC, degF, K"),
        ("torque[foo]", None, r"column 'torque\[foo\]': cannot read the unit 'foo'.*--units torque=<unit>"),
    ],
)
def test_wrong_units_are_refused(header, units, match):
    name = header.split("[")[0]
    frame = truth().rename(columns={name: header})
    with pytest.raises(DynoDataError, match=match):
        log_from_frame(frame, source="dyno.csv", units=units)


# --- dirty logs: non-finite and non-numeric values --------------------------------------------------------------


def test_rows_with_nan_or_inf_in_a_required_channel_are_dropped():
    frame = truth()
    frame.loc[[10, 11, 500], "current"] = np.nan
    frame.loc[900, "torque"] = np.inf
    log = log_from_frame(frame)
    assert log.n == len(frame) - 4
    (note,) = log.notes
    assert note.kind == "nan_rows" and note.rows == 4
    assert note.message == (
        "dropped 4 rows with NaN or inf in a required channel ('current': 3; 'torque': 1) at rows 11, 12, 501, 901"
    )
    assert np.isfinite(log.current).all() and np.isfinite(log.torque).all()


def test_non_numeric_cells_are_reported_with_their_value(tmp_path):
    path = write(truth(), tmp_path / "log.csv")
    lines = path.read_text().splitlines()
    cells = lines[17].split(",")
    cells[1] = "ERR"
    lines[17] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    log = load_log(path)
    (note,) = log.notes
    assert note.rows == 1
    assert "'current': 1 (1 not a number, such as 'ERR' at row 17)" in note.message


def test_a_few_nans_in_an_optional_channel_drop_their_rows():
    frame = truth()
    frame.loc[[3, 4, 5], "velocity"] = np.nan
    log = log_from_frame(frame)
    assert log.n == len(frame) - 3 and log.velocity is not None
    (note,) = log.notes
    assert (note.kind, note.channel, note.rows) == ("nan_rows", "velocity", 3)
    assert "(0.15 % of rows, under 5 %) at rows 4, 5, 6" in note.message


def test_many_nans_in_an_optional_channel_drop_the_channel_not_the_rows():
    frame = truth()
    frame.loc[::10, "temperature"] = np.nan  # 10 % of rows
    log = log_from_frame(frame)
    assert log.n == len(frame) and log.temperature is None and not log.has("temperature")
    (note,) = log.notes
    assert (note.kind, note.channel, note.rows) == ("nan_rows", "temperature", 0)
    assert note.message == (
        "dropped column 'temperature': 10 % of its values are NaN or inf (200 of 2000; more than 5 %), "
        "so its rows were kept"
    )
    with pytest.raises(DynoDataError, match=r"'temperature' channel was dropped while loading \(dropped column"):
        log.column("temperature")


# --- dirty logs: glitches ---------------------------------------------------------------------------------------


def steady_13_amps(n: int = 10_000, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return 13.0 + 0.3 * np.sin(np.arange(n) / 700.0) + rng.normal(0.0, 0.05, n)


def test_a_165_amp_spike_in_a_13_amp_test_is_removed_and_reported():
    frame = truth(current=steady_13_amps())
    frame.loc[5011, "current"] = 165.0  # data row 5012
    log = log_from_frame(frame, source="dyno.csv")
    assert log.n == len(frame) - 1
    assert frame["time"][5011] not in log.time
    (note,) = log.notes
    assert (note.kind, note.rows, note.channel) == ("glitch", 1, "current")
    assert note.message.startswith("removed 1 single-sample glitch in 'current' (165 A against a local median of 1")
    assert note.message.endswith(" A) at row 5012")
    assert log.current.max() < 14.0


def test_a_torque_glitch_and_a_two_sample_glitch_are_removed():
    frame = truth(current=steady_13_amps())
    frame.loc[[300, 301], "current"] = [-40.0, -38.0]
    frame.loc[7000, "torque"] = 9.0
    log = log_from_frame(frame)
    assert log.n == len(frame) - 3
    current, torque = notes_of(log, "glitch")
    assert (current.channel, current.rows, torque.channel, torque.rows) == ("current", 2, "torque", 1)
    assert "at rows 301, 302" in current.message and "-40 A" in current.message
    assert re.search(r"'torque' \(9 N m against a local median of 1\.2\d* N m\) at row 7001$", torque.message)


def test_a_three_sample_pulse_is_a_real_step_not_a_glitch():
    frame = truth(current=steady_13_amps())
    frame.loc[[300, 301, 302], "current"] += 20.0
    log = log_from_frame(frame)
    assert log.n == len(frame) and log.notes == ()


def staircase(levels: list[float], dwell: list[int], seed: int = 2) -> np.ndarray:
    rng = np.random.default_rng(seed)
    steps = np.repeat(np.asarray(levels, dtype=float), dwell)
    return steps + rng.normal(0.0, 0.01, steps.size)


def test_a_staircase_of_current_steps_is_not_flagged():
    levels = [0.0, 2.0, 4.0, 8.0, 16.0, 4.0, -10.0, -2.0, 0.0, 20.0, 0.0]
    current = staircase(levels, [300] * len(levels))
    log = log_from_frame(truth(n=current.size, current=current))
    assert log.n == current.size and log.notes == ()


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(-40, 40).map(lambda k: 0.5 * k), st.integers(4, 60)),
        min_size=13,
        max_size=40,
    )
)
def test_no_staircase_with_steps_of_four_samples_or_more_loses_a_row(steps):
    levels, dwell = zip(*steps, strict=True)
    current = staircase(list(levels), list(dwell))
    log = log_from_frame(truth(n=current.size, current=current))
    assert "glitch" not in kinds(log)
    assert log.n == current.size


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 1999), st.floats(3.0, 200.0), st.sampled_from([-1.0, 1.0]))
def test_a_spike_anywhere_is_removed_and_nothing_else(row, size, sign):
    frame = truth(current=steady_13_amps(2000))
    frame.loc[row, "current"] += sign * size
    log = log_from_frame(frame)
    assert kinds(log) == ["glitch"]
    assert f"at row {row + 1}" in log.notes[0].message
    np.testing.assert_array_equal(log.time, np.delete(frame["time"].to_numpy(), row))


# --- dirty logs: timestamps -------------------------------------------------------------------------------------


def test_duplicated_timestamps_keep_the_first_row():
    frame = truth()
    frame.loc[[101, 102, 700], "time"] = frame["time"][[100, 100, 699]].to_numpy()
    log = log_from_frame(frame)
    assert log.n == len(frame) - 3
    (note,) = log.notes
    assert (note.kind, note.rows) == ("duplicate_time", 3)
    assert note.message == (
        "dropped 3 rows repeating the previous timestamp, keeping the first of each "
        "(first at row 102, t = 0.1 s; rows 102, 103, 701)"
    )
    assert log.current[100] == frame["current"][100]
    assert np.all(np.diff(log.time) > 0)


def test_out_of_order_timestamps_are_sorted_and_counted():
    frame = truth()
    order = np.arange(len(frame))
    order[[50, 51]] = [51, 50]
    order[1000:1003] = [1002, 1000, 1001]
    shuffled = frame.iloc[order].reset_index(drop=True)
    log = log_from_frame(shuffled)
    (note,) = log.notes
    assert (note.kind, note.rows) == ("unsorted_time", 3)
    assert "time goes backwards: 3 rows came after a later timestamp (first at row 52: 0.05 s after 0.051 s)" in (
        note.message
    )
    np.testing.assert_array_equal(log.time, frame["time"])
    np.testing.assert_array_equal(log.current, frame["current"])


# --- dirty logs: ADC saturation and reversed sensors ------------------------------------------------------------


def test_a_clipped_torque_channel_loses_its_clipped_rows():
    frame = truth(amplitude=130.0)
    clipped = frame["torque"] >= 12.0
    frame["torque"] = np.minimum(frame["torque"], 12.0)
    log = log_from_frame(frame)
    (note,) = log.notes
    count = int(clipped.sum())
    assert (note.kind, note.channel, note.rows) == ("adc_saturation", "torque", count)
    assert note.message.startswith(f"torque channel clipped at 12 N m in {count} rows (ADC saturation")
    assert note.message.endswith("those rows were removed")
    assert log.n == len(frame) - count and log.torque.max() < 12.0


def test_a_current_reading_stuck_at_full_scale_is_clipping_but_a_flat_commanded_step_is_not():
    frame = truth(amplitude=130.0)
    frame["current"] = np.minimum(frame["current"], 120.0)  # the current ADC saturates; the torque keeps rising
    log = log_from_frame(frame)
    (note,) = log.notes
    assert (note.kind, note.channel) == ("clamp", "current")
    assert note.message.startswith("the reported current is clamped at 120 A in ")
    assert "while the torque keeps moving" in note.message and note.message.endswith("those rows were removed")
    assert log.current.max() < 120.0
    # A staircase of commanded currents, exactly flat: the top step is held, and the torque with it.
    levels = [0.0, 5.0, 10.0, 15.0, 20.0, 15.0, 10.0, 20.0, 5.0, 0.0]
    commanded = np.repeat(levels, 300)
    log = log_from_frame(truth(current=commanded))
    assert log.notes == () and log.n == commanded.size


def test_an_idle_stretch_at_exactly_zero_is_not_clipping():
    current = steady_13_amps(2000)
    current[:500] = 0.0
    log = log_from_frame(truth(current=current))
    assert "adc_saturation" not in kinds(log) and log.n == 2000


def test_a_reversed_torque_sensor_is_refused_with_the_fix():
    frame = truth()
    frame["torque"] = -frame["torque"]
    with pytest.raises(
        DynoDataError,
        match=r"^dyno\.csv: torque falls as current rises \(slope -0\.1 N m/A, correlation -1\.00\): "
        r"the torque sensor looks mounted reversed; rerun with --flip-torque$",
    ) as info:
        log_from_frame(frame, source="dyno.csv")
    assert info.value.slope == pytest.approx(-KT, rel=1e-3)


def test_flip_torque_fixes_a_reversed_sensor(tmp_path):
    frame = truth()
    path = write(frame.assign(torque=-frame["torque"]), tmp_path / "log.parquet")
    log = load_log(path, flip_torque=True)
    np.testing.assert_array_equal(log.torque, frame["torque"])
    (note,) = log.notes
    assert (note.kind, note.rows) == ("flipped_torque", len(frame))
    assert note.message == "negated the torque as asked by --flip-torque (slope now 0.1 N m/A)"


def test_auto_sign_lets_each_log_decide_and_says_so():
    reversed_frame = truth().assign(torque=lambda f: -f["torque"])
    flipped = log_from_frame(reversed_frame, auto_sign=True)
    note = next(n for n in flipped.notes if n.kind == "flipped_torque")
    assert "negated the torque: it falls as current rises (slope -0.1 N m/A" in note.message
    assert "--auto-sign" in note.message and np.allclose(flipped.torque, truth()["torque"])
    kept = log_from_frame(truth(), auto_sign=True, flip_torque=True)  # --flip-torque yields to the log's own slope
    assert np.array_equal(kept.torque, truth()["torque"]) and not any(n.kind == "flipped_torque" for n in kept.notes)
    assert any("kept the torque's sign" in n.message for n in kept.notes)


def test_flip_torque_on_a_sensor_mounted_the_right_way_is_refused():
    with pytest.raises(DynoDataError, match=r"after --flip-torque negated it .*rerun without --flip-torque"):
        log_from_frame(truth(), flip_torque=True)


# --- every note is accounted for -------------------------------------------------------------------------------


@settings(max_examples=30, deadline=None)
@given(
    st.sets(st.integers(1, 399), max_size=12),
    st.sets(st.integers(1, 399), max_size=12),
    st.sets(st.integers(1, 398), max_size=8),
)
def test_removed_rows_add_up_and_time_ends_strictly_increasing(nan_rows, duplicate_rows, swapped_rows):
    frame = truth(n=400)
    order = np.arange(400)
    for row in swapped_rows:
        order[[row, row + 1]] = order[[row + 1, row]]
    frame = frame.iloc[order].reset_index(drop=True)
    for row in duplicate_rows:
        frame.loc[row, "time"] = frame["time"][row - 1]
    frame.loc[sorted(nan_rows), "torque"] = np.nan
    log = log_from_frame(frame)
    assert set(kinds(log)) <= set(NOTE_KINDS)
    assert log.n + sum(n.rows for n in log.notes if n.kind in REMOVING) == log.rows_read == 400
    assert np.all(np.diff(log.time) > 0)
    assert all(np.isfinite(log.column(name)).all() for name in CANONICAL)


# --- errors -----------------------------------------------------------------------------------------------------


def test_missing_required_columns_are_named_with_the_mapping_hint():
    frame = truth().rename(columns={"torque": "adc_torque"})
    with pytest.raises(
        DynoDataError,
        match=r"^dyno\.csv: missing required column\(s\) 'torque'; the file has columns 'time', 'current', "
        r"'adc_torque', .*--columns torque=<your column>$",
    ):
        log_from_frame(frame, source="dyno.csv")


@pytest.mark.parametrize(
    ("columns", "match"),
    [
        (
            {"torq": "adc_torque"},
            r"--columns names an unknown channel 'torq' \(did you mean 'torque'\?\); "
            r"expected one of time, current, torque, velocity, position, temperature, bus_voltage",
        ),
        (
            {"torque": "adc_torqe"},
            r"--columns maps torque to 'adc_torqe', which is not a column of the file "
            r"\(did you mean 'adc_torque'\?\); the file has columns 'time', 'current', 'adc_torque'",
        ),
        ({"torque": "adc_torque", "current": "adc_torque"}, r"maps both torque and current to column 'adc_torque'"),
    ],
)
def test_bad_column_mappings_are_refused(columns, match):
    frame = truth()[list(CORE)].rename(columns={"torque": "adc_torque"})
    with pytest.raises(DynoDataError, match=match):
        log_from_frame(frame, source="dyno.csv", columns=columns)


def test_two_columns_for_one_channel_are_ambiguous():
    frame = truth().rename(columns={"torque": "torque[Nm]"}).assign(**{"torque [mN*m]": 1.0})
    with pytest.raises(DynoDataError, match=r"columns 'torque\[Nm\]', 'torque \[mN\*m\]' all look like the 'torque' "):
        log_from_frame(frame)


@pytest.mark.parametrize(
    ("units", "match"),
    [
        ({"speed": "rpm"}, r"--units names an unknown channel 'speed'"),
        ({"velocity": "rpm"}, r"--units gives a unit for 'velocity', but the file has no velocity column"),
    ],
)
def test_bad_unit_options_are_refused(units, match):
    with pytest.raises(DynoDataError, match=match):
        log_from_frame(truth()[list(CORE)], units=units)


def test_a_text_column_is_refused():
    frame = truth().assign(current="n/a")
    with pytest.raises(DynoDataError, match=r"column 'current' is not numeric \(row 1 holds 'n/a'\); expected numbers"):
        log_from_frame(frame)


def test_duplicated_column_names_are_refused():
    frame = truth()[list(CORE)]
    frame = pd.concat([frame, frame[["torque"]]], axis=1)
    with pytest.raises(DynoDataError, match=r"more than one column named 'torque'; rename one"):
        log_from_frame(frame)


@pytest.mark.parametrize(("n", "spoil", "match"), [(60, 51, r"only 9 of 60 rows"), (20, 11, r"only 9 of 20 rows")])
def test_too_few_rows_are_refused(n, spoil, match):
    frame = truth(n=n)
    frame.loc[: spoil - 1, "current"] = np.nan
    with pytest.raises(DynoDataError, match=match + rf".*expected at least {MIN_ROWS} rows"):
        log_from_frame(frame)


def test_asking_for_an_absent_or_unknown_channel_says_how_to_supply_it():
    log = log_from_frame(truth()[list(CORE)], source="dyno.csv")
    with pytest.raises(
        DynoDataError, match=r"^dyno\.csv: no 'velocity' channel; .*'velocity\[unit\]'.*--columns velocity="
    ):
        log.column("velocity")
    with pytest.raises(DynoDataError, match=r"unknown channel 'speed'; expected one of time, current"):
        log.has("speed")


def test_a_log_built_by_hand_checks_its_shapes():
    with pytest.raises(DynoDataError, match=r"channel 'torque' has shape \(3,\), expected \(4,\)"):
        DynoLog(time=np.arange(4.0), current=np.ones(4), torque=np.ones(3))


def test_an_unknown_file_format_is_a_table_error(tmp_path):
    with pytest.raises(TableError, match="unknown table format .txt"):
        load_log(tmp_path / "log.txt")


# --- timestamps as dates ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_timestamp_columns_become_seconds_after_the_first(tmp_path, suffix):
    frame = truth()
    start = pd.Timestamp("2025-03-01 12:00:00", tz="UTC")
    stamped = frame.assign(time=start + pd.to_timedelta(frame["time"], unit="s"))
    log = load_log(write(stamped, tmp_path / f"log{suffix}"))
    np.testing.assert_allclose(log.time, frame["time"], atol=1e-9)
    (note,) = log.notes
    assert note.kind == "unit" and note.message.startswith("time converted from timestamps to seconds after 2025-03-01")


# --- the option parser ------------------------------------------------------------------------------------------


def test_parse_mapping_reads_pairs():
    assert parse_mapping(" torque = adc torque , current=iq[mA],", "--columns") == {
        "torque": "adc torque",
        "current": "iq[mA]",
    }
    assert parse_mapping(None, "--columns") == {} and parse_mapping("  ", "--units") == {}


KEYS = st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,10}", fullmatch=True)
VALUES = st.text(st.sampled_from("abcXYZ019_-[]*/.() °µ"), min_size=1, max_size=12).map(str.strip).filter(bool)


@given(st.dictionaries(KEYS, VALUES, max_size=6))
def test_parse_mapping_reads_back_what_was_written(mapping):
    text = ",".join(f"{key}={value}" for key, value in mapping.items())
    assert parse_mapping(text, "--columns") == mapping


@pytest.mark.parametrize(
    ("text", "option", "match"),
    [
        (
            "torque",
            "--columns",
            r"^--columns: cannot read 'torque' in 'torque'; expected name=value pairs separated "
            r"by commas, e.g. --columns torque=adc_torque,current=iq$",
        ),
        ("velocity:rpm", "--units", r"^--units: cannot read 'velocity:rpm'.*e\.g\. --units velocity=rpm,position=deg$"),
        ("=iq", "--columns", r"cannot read '=iq'"),
        ("torque=", "--columns", r"cannot read 'torque='"),
        ("torque=a,torque=b", "--columns", r"^--columns: 'torque' is given twice in 'torque=a,torque=b'"),
    ],
)
def test_parse_mapping_refuses_bad_syntax(text, option, match):
    with pytest.raises(DynoDataError, match=match):
        parse_mapping(text, option)


def test_a_spike_at_the_start_of_a_ramp_is_still_a_glitch():
    # the spike drags its neighbours' window medians, so three samples look off; only the spike is removed
    current = np.concatenate([np.zeros(50), np.linspace(0, 90, 6), np.full(50, 90.0)])
    current = np.concatenate([current, current[::-1]])
    torque = 0.1 * current + 0.001 * np.sin(np.arange(current.size))
    current[50] = 165.0
    n = current.size
    frame = pd.DataFrame({"time": np.arange(n) * 1e-3, "current": current, "torque": torque})
    log = log_from_frame(frame)
    assert log.n == n - 1
    assert np.max(log.current) == 90.0
    (note,) = [x for x in log.notes if x.kind == "glitch"]
    assert "165 A" in note.message


def test_a_noisy_torque_clipped_during_flat_current_steps_is_caught():
    # flat current steps (noise-free set-points) and a noisy torque channel clipped at 6 N m
    rng = np.random.default_rng(3)
    levels = np.repeat([0.0, 30.0, 60.0, 90.0, 60.0, 30.0, 0.0, -30.0, -60.0, -90.0, -60.0, -30.0], 200)
    torque = 0.1 * levels + rng.normal(0, 0.02, levels.size)
    frame = pd.DataFrame({"time": np.arange(levels.size) * 1e-3, "current": levels, "torque": np.clip(torque, -6, 6)})
    log = log_from_frame(frame)
    clipped = [n for n in log.notes if n.kind == "adc_saturation"]
    assert {n.channel for n in clipped} == {"torque"} and len(clipped) == 2
    assert np.abs(log.torque).max() < 6.0


def test_an_envelope_log_needs_envelope_min_rows(tmp_path):
    """ENVELOPE_MIN_ROWS has no scenario of its own elsewhere: one usable row fewer is refused, that many load."""
    import numpy as np

    from hound_id.dyno.logs import ENVELOPE_MIN_ROWS, load_envelope_log
    from hound_id.errors import DynoDataError

    path = tmp_path / "envelope.csv"
    n = ENVELOPE_MIN_ROWS + 1
    speed = np.linspace(0.0, 300.0, n)
    rows = "\n".join(f"{t:.6g},{w:.6g}" for t, w in zip(5.0 - 0.01 * speed, speed, strict=True))
    path.write_text("torque,velocity\nnan,0\n" + rows + "\n")
    assert load_envelope_log(path).torque.size == n
    path.write_text("torque,velocity\nnan,0\n" + "\n".join(rows.splitlines()[2:]) + "\n")
    with pytest.raises(DynoDataError, match=rf"{ENVELOPE_MIN_ROWS - 1} usable rows; .* at least {ENVELOPE_MIN_ROWS}"):
        load_envelope_log(path)


def test_a_table_of_26_operating_points_and_a_burst_written_16_times_are_read(tmp_path):
    """Small data: a test stand's steady-state table (note lines above the header, one averaged row per operating
    point) and a burst whose logger wrote every sample 16 times, with and without its time column; a noiseless table
    (its noise floor is zero). Each is fitted from the command line, with no traceback."""
    import json

    from tests.conftest import run_cli

    rng = np.random.default_rng(0)
    i = np.linspace(-20, 20, 26)
    w = np.tile([-5.0, 5.0], 13)
    tau = 0.8 * i - 0.002 * i * np.abs(i) - 0.25 * np.tanh(w / 0.01) + rng.normal(0, 0.02, 26)
    table = tmp_path / "table.csv"
    lines = ["Test stand XY-200, averaged over 2 s per point", "operator: someone", "current_A,torque_Nm,speed_rad_s"]
    table.write_text("\n".join(lines + [f"{a:.4f},{b:.5f},{c:.3f}" for a, b, c in zip(i, tau, w, strict=True)]) + "\n")
    proc = run_cli(
        "fit-current", str(table), "--columns", "current=current_A,torque=torque_Nm,velocity=speed_rad_s", "--auto",
        "--json",
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["rows"]["fitted"] == 26 and data["rows"]["blocks"] == 10  # blocks of two or three operating points
    p = data["parameters"]
    assert abs(p["kt"]["value"] - 0.8) < 4 * p["kt"]["stderr"] + 0.002
    # one speed magnitude cannot tell Coulomb from Stribeck friction: either carries the 0.25 N m
    friction = next(p[name] for name in ("coulomb", "stribeck") if name in p)
    assert abs(friction["value"] - 0.25) < 4 * friction["stderr"] + 0.005
    # five rows per parameter: the ladder stops where 26 rows cannot carry more
    assert len(data["model"]) <= 26 // 5
    assert any("rows cannot carry its parameters" in s for s in data["skipped"]) or data["at_noise_floor"]

    t = np.arange(40) / 1000.0
    ib = 8 * np.sin(2 * np.pi * 25 * t)
    yb = 0.8 * ib + rng.normal(0, 0.01, 40)
    burst = [f"{a:.6f},{b:.5f},{c:.5f}" for a, b, c in zip(t, ib, yb, strict=True) for _ in range(16)]
    (tmp_path / "burst.csv").write_text("time,current,torque\n" + "\n".join(burst) + "\n")
    (tmp_path / "burst_notime.csv").write_text(
        "current,torque\n" + "\n".join(line.split(",", 1)[1] for line in burst) + "\n"
    )
    for name in ("burst.csv", "burst_notime.csv"):
        proc = run_cli("fit-current", str(tmp_path / name), "--auto", "--json")
        assert proc.returncode == 0, proc.stderr
        data = json.loads(proc.stdout)
        note = next(c for c in data["cleaning"] if c["kind"] == "duplicate_rows")
        assert note["rows"] == 600 and "up to 16 times" in note["message"]
        assert data["rows"]["fitted"] == 40
        assert data["parameters"]["kt"]["value"] == pytest.approx(0.8, abs=0.005)

    exact = tmp_path / "exact.csv"
    exact.write_text("current,torque\n" + "\n".join(f"{a:.3f},{0.5 * a:.4f}" for a in np.linspace(-10, 10, 30)) + "\n")
    proc = run_cli("fit-current", str(exact), "--auto", "--json")
    assert proc.returncode == 0, proc.stderr  # a zero noise floor divides nothing
    assert json.loads(proc.stdout)["parameters"]["kt"]["value"] == pytest.approx(0.5, abs=1e-4)  # 4 printed digits


@pytest.mark.parametrize("n", [15, 30, 50])
def test_clean_small_tables_keep_every_row(n):
    """Clean tables of operating points: nothing is left out of the headline, Kt is within its error, and a noiseless
    table on an integer grid is not given a rounding floor it does not show."""
    from hound_id.dyno.current.run import FitCurrentOptions, fit_current

    kts = []
    for seed in range(8):
        rng = np.random.default_rng(100 + seed)
        i = rng.uniform(-20, 20, n)
        frame = pd.DataFrame({"current": i, "torque": 0.138 * i + rng.normal(0, 0.02, n)})
        result = fit_current_frame(frame, FitCurrentOptions())
        assert result.report.headline is None and result.report.rows.fitted == n
        kt = result.report.parameters["kt"]
        kts.append(abs(kt.value - 0.138) / kt.stderr)
    assert max(kts) < 4.5
    exact = pd.DataFrame({"current": np.round(np.linspace(-10.0, 10.0, n)), "torque": 0.0})
    exact["torque"] = 0.5 * exact["current"]
    report = fit_current_frame(exact, FitCurrentOptions()).report_json()
    assert report["noise"]["method"] != "quantisation" and not any("worse on its own" in f for f in report["flags"])
    del fit_current


def fit_current_frame(frame, options):
    """fit-current on a frame written to a temporary CSV."""
    import tempfile
    from pathlib import Path

    from hound_id.dyno.current.run import fit_current

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "table.csv"
        frame.to_csv(path, index=False)
        return fit_current(path, options)
