"""The recorder against real protocol peers: the simulated rig's pymodbus server and its pty."""

import threading
import time

import pandas as pd
import pytest

from hound_id.dyno.acquire.recorder import RetryPolicy, record
from hound_id.dyno.acquire.rig_file import rig_from_mapping
from hound_id.dyno.acquire.simulated_rig import SimulatedRig
from hound_id.dyno.acquire.transport import TRANSPORTS, RigReader


@pytest.fixture
def rig_sim():
    sim = SimulatedRig(("linear", "saturation"), seed=2, serial=True)
    sim.start()
    try:
        yield sim
    finally:
        sim.stop()


def with_serial_channel(mapping):
    mapping = dict(mapping)
    mapping["channels"] = [
        *mapping["channels"],
        {"column": "console_current", "device": "console", "field": "current", "unit": "A"},
    ]
    return mapping


def run_later(delay, fn):
    timer = threading.Timer(delay, fn)
    timer.start()
    return timer


def test_registry_is_sorted():
    assert list(TRANSPORTS) == sorted(TRANSPORTS)


def test_records_every_channel_from_modbus_and_serial(rig_sim, tmp_path):
    rig = rig_from_mapping(with_serial_channel(rig_sim.rig_mapping()), source="sim")
    with RigReader(rig) as reader:
        result = record(reader.read_sample, list(rig.columns), tmp_path / "run.csv", rate_hz=200.0, duration=1.0)
    frame = pd.read_csv(tmp_path / "run.csv")
    assert result.status == "complete" and len(frame) == result.samples > 100
    assert set(rig.columns) <= set(frame.columns)
    # the serial console and the Modbus drive report the same current (within a line period and rounding)
    assert (frame["console_current"] - frame["current"]).abs().median() < 5.0


def test_server_stopped_mid_run_leaves_a_gap_and_recording_goes_on(rig_sim, tmp_path):
    rig = rig_from_mapping(rig_sim.rig_mapping(), source="sim")
    run_later(0.5, rig_sim.pause_modbus)
    run_later(1.0, rig_sim.resume_modbus)
    with RigReader(rig) as reader:
        result = record(
            reader.read_sample,
            list(rig.columns),
            tmp_path / "gap.csv",
            rate_hz=200.0,
            duration=2.0,
            policy=RetryPolicy(retries=1, give_up_after=5.0),
        )
    assert result.status == "complete"
    assert result.failed > 0 and len(result.gaps) >= 1
    frame = pd.read_csv(tmp_path / "gap.csv")
    assert len(frame) == result.samples and frame["time"].iloc[-1] > 1.5  # it came back


def test_exception_responses_are_failed_ticks_with_the_reason(rig_sim, tmp_path):
    rig = rig_from_mapping(rig_sim.rig_mapping(), source="sim")
    rig_sim.set_exception(1, True)
    run_later(0.4, lambda: rig_sim.set_exception(1, False))
    with RigReader(rig) as reader:
        result = record(reader.read_sample, list(rig.columns), tmp_path / "exc.csv", rate_hz=200.0, duration=1.0)
    assert result.failed > 0 and any("exception" in g.reason for g in result.gaps)
    assert result.samples > 50


def test_garbage_lines_are_counted_and_skipped(rig_sim, tmp_path):
    rig = rig_from_mapping(with_serial_channel(rig_sim.rig_mapping()), source="sim")
    with RigReader(rig) as reader:
        time.sleep(0.3)
        rig_sim.send_garbage(20)
        result = record(reader.read_sample, list(rig.columns), tmp_path / "g.csv", rate_hz=100.0, duration=0.8)
        faults = reader.faults()
    assert result.samples > 40
    assert sum(faults.values()) >= 1
    assert not pd.read_csv(tmp_path / "g.csv").isna().any().any()


def test_a_dead_rig_fails_with_a_message(rig_sim, tmp_path):
    rig = rig_from_mapping(rig_sim.rig_mapping(), source="sim")
    rig_sim.stop()
    with RigReader(rig) as reader:
        result = record(
            reader.read_sample,
            list(rig.columns),
            tmp_path / "dead.csv",
            rate_hz=50.0,
            policy=RetryPolicy(retries=0, give_up_after=0.5),
        )
    assert result.status == "failed" and "Modbus 127.0.0.1" in result.message
    assert not (tmp_path / "dead.csv").exists()  # no sample: no header-only log left behind


def test_fast_block_decoder_equals_the_reference():
    import numpy as np

    from hound_id.dyno.acquire.rig import decode_block
    from hound_id.dyno.acquire.transport import block_decoder

    rig = rig_from_mapping(
        {
            "schema": "hound-id/rig/1",
            "name": "codec",
            "devices": {
                "d": {"type": "modbus_tcp", "host": "127.0.0.1", "port": 5020, "unit": 1},
                "e": {"type": "modbus_tcp", "host": "127.0.0.1", "port": 5020, "unit": 2},
            },
            "channels": [
                {"column": "torque", "device": "d", "register": 0, "dtype": "float32", "unit": "N*m"},
                {"column": "current", "device": "d", "register": 2, "dtype": "int16", "scale": 0.01, "unit": "A"},
                {"column": "velocity", "device": "d", "register": 3, "dtype": "int32", "scale": 1e-3, "unit": "rpm"},
                {
                    "column": "temperature",
                    "device": "d",
                    "register": 5,
                    "dtype": "uint16",
                    "scale": 0.1,
                    "unit": "degF",
                },
                {
                    "column": "position",
                    "device": "e",
                    "register": 0,
                    "dtype": "uint32",
                    "word_order": "little",
                    "unit": "deg",
                },
            ],
        },
        source="codec",
    )
    rng = np.random.default_rng(0)
    for block in rig.reads():
        fast = block_decoder(block)
        for _ in range(200):
            regs = [int(x) for x in rng.integers(0, 0x10000, block.count)]
            want, got = decode_block(block, regs), fast(regs)
            assert got.keys() == want.keys()
            for k in want:
                assert got[k] == want[k] or (np.isnan(got[k]) and np.isnan(want[k]))
