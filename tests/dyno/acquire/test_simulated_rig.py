"""The simulated rig against real peers: a pymodbus TCP client on 127.0.0.1 and pyserial on the pty.

Served values are checked against the simulated log over the playback-time window that brackets
each request (read the rig's clock, send the request, read the clock again): the interpolated value
served lies between the extremes of the signal over that window, up to the register quantisation.
Every wait is bounded; every rig is stopped by its context manager.
"""

from __future__ import annotations

import math
import re
import socket
import struct
import time
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest

from hound_id.dyno.acquire.simulated_rig import CONSOLE_REGEX, SimulatedRig
from hound_id.dyno.simulate.current import TestPlan
from hound_id.errors import DynoDataError

# A short plan (11.5 s) with two speeds; no test lasts long enough to see the loop wrap, and reads retry if it does.
PLAN = TestPlan(speeds=(-10.0, 10.0), plateau_time=2.0, pause_time=2.0, hold_time=0.5)
TIMEOUT = 1.0  # client request timeout [s]
DEADLINE = 5.0  # bound on every polling loop [s]
TWO_PI = 2.0 * math.pi


@pytest.fixture
def rig() -> Iterator[SimulatedRig]:
    with SimulatedRig(("linear", "saturation", "coulomb"), seed=3, plan=PLAN) as r:
        yield r


@contextmanager
def client_for(rig: SimulatedRig, timeout: float = TIMEOUT) -> Iterator[object]:
    from pymodbus.client import ModbusTcpClient

    host, port = rig.address
    client = ModbusTcpClient(host, port=port, timeout=timeout, retries=0, reconnect_delay=0.05)
    try:
        assert client.connect()
        yield client
    finally:
        client.close()


@contextmanager
def console(rig: SimulatedRig) -> Iterator[object]:
    import serial

    assert rig.serial_port is not None
    port = serial.Serial(rig.serial_port, 115200, timeout=0.2)
    try:
        port.reset_input_buffer()
        yield port
    finally:
        port.close()


def timed_read(rig: SimulatedRig, client, unit: int, count: int):
    """(registers, t_before, t_after) in playback time; retries when the playback loop wrapped meanwhile."""
    for _ in range(3):
        ta = rig.playback_time()
        rr = client.read_input_registers(0, count=count, device_id=unit)
        tb = rig.playback_time()
        assert not rr.isError(), rr
        if tb >= ta:
            return rr.registers, ta, tb
    pytest.fail("the playback loop wrapped during every read")


def window(rig: SimulatedRig, column: str, ta: float, tb: float) -> tuple[float, float]:
    """Extremes of the linearly interpolated signal over playback times [ta, tb]."""
    frame = rig.log.frame
    t, y = frame["time"].to_numpy(), frame[column].to_numpy()
    inside = y[(t > ta) & (t < tb)]
    ends = np.interp([ta, tb], t, y)
    values = np.concatenate((ends, inside))
    return float(values.min()), float(values.max())


def assert_in_window(value: float, bounds: tuple[float, float], tol: float, what: str) -> None:
    lo, hi = bounds
    assert lo - tol <= value <= hi + tol, f"{what}: served {value}, signal over the read window in [{lo}, {hi}]"


def assert_angle_in_window(angle: float, bounds: tuple[float, float], tol: float) -> None:
    """``angle`` in [0, 2 pi) equals some unwrapped position in ``bounds`` modulo 2 pi."""
    lo, hi = bounds
    assert 0.0 <= angle <= TWO_PI + tol
    k = math.ceil((lo - tol - angle) / TWO_PI)
    assert angle + k * TWO_PI <= hi + tol, f"position: served {angle}, unwrapped window [{lo}, {hi}]"


def decode_drive(registers: list[int]) -> dict[str, float]:
    current, velocity, position, temperature, bus = struct.unpack(">ffihH", struct.pack(">8H", *registers))
    return {
        "current": current,
        "velocity": velocity,
        "position": position * 1e-4,
        "temperature": temperature * 0.1,
        "bus_voltage": bus * 0.01,
    }


def f32_tol(x: float) -> float:
    return 1e-6 * abs(x) + 1e-9


def test_modbus_registers_hold_the_simulated_signals(rig):
    with client_for(rig) as client:
        regs, ta, tb = timed_read(rig, client, 1, 2)
        torque = client.convert_from_registers(regs, client.DATATYPE.FLOAT32)
        assert torque == pytest.approx(struct.unpack(">f", struct.pack(">2H", *regs))[0])
        assert_in_window(torque, window(rig, "torque", ta, tb), f32_tol(torque), "torque")

        for _ in range(20):
            regs, ta, tb = timed_read(rig, client, 2, 8)
            drive = decode_drive(regs)
            for column in ("current", "velocity"):
                assert_in_window(drive[column], window(rig, column, ta, tb), f32_tol(drive[column]), column)
            assert_in_window(drive["temperature"], window(rig, "temperature", ta, tb), 0.05 + 1e-9, "temperature")
            assert_in_window(drive["bus_voltage"], window(rig, "bus_voltage", ta, tb), 0.005 + 1e-9, "bus_voltage")
            assert_angle_in_window(drive["position"], window(rig, "position", ta, tb), 0.5e-4 + 1e-9)
            time.sleep(0.01)


def test_one_request_reads_one_instant(rig):
    # bus = 48 V - 0.02 V/A |i| holds at every instant; two instants 1 ms apart on a current edge would break it
    # by up to 0.02 V/A * 91 A
    worst = 0.0
    with client_for(rig) as client:
        deadline = time.monotonic() + 1.5
        while time.monotonic() < deadline:
            drive = decode_drive(timed_read(rig, client, 2, 8)[0])
            expected = PLAN.bus_voltage - PLAN.bus_sag * abs(drive["current"])
            worst = max(worst, abs(drive["bus_voltage"] - expected))
    assert worst <= 0.0051


def test_time_advances_between_reads(rig):
    with client_for(rig) as client:
        first, ta1, tb1 = timed_read(rig, client, 2, 8)
        time.sleep(0.05)
        second, ta2, tb2 = timed_read(rig, client, 2, 8)
    assert ta2 - tb1 >= 0.04  # playback clock follows the wall clock
    p1, p2 = decode_drive(first)["position"], decode_drive(second)["position"]
    assert_angle_in_window(p1, window(rig, "position", ta1, tb1), 0.5e-4 + 1e-9)
    assert_angle_in_window(p2, window(rig, "position", ta2, tb2), 0.5e-4 + 1e-9)
    assert abs(p2 - p1) > 0.1  # the lead-in turns at 10 rad/s: 0.5 rad in 50 ms


def test_other_registers_units_and_functions_are_refused(rig):
    with client_for(rig) as client:
        assert client.read_input_registers(0, count=9, device_id=2).exception_code == 0x02
        assert client.read_input_registers(2, count=1, device_id=1).exception_code == 0x02
        assert client.read_holding_registers(0, count=2, device_id=1).exception_code == 0x01
        assert client.write_register(0, 1, device_id=2).isError()
        assert client.read_input_registers(0, count=2, device_id=9).exception_code == 0x0B


def test_serial_console_lines_parse_with_the_rig_regex(rig):
    pattern = re.compile(CONSOLE_REGEX)
    frame = rig.log.frame
    good: list[dict[str, float]] = []
    with console(rig) as port:
        start = time.monotonic()
        port.readline()  # may be a partial line
        while len(good) < 100 and time.monotonic() - start < DEADLINE:
            line = port.readline()
            if not line:
                continue
            assert line.endswith(b"\n"), line
            match = pattern.fullmatch(line.decode("ascii").rstrip("\n"))
            assert match is not None, line
            good.append({k: float(v) for k, v in match.groupdict().items()})
        elapsed = time.monotonic() - start
    assert len(good) == 100, f"only {len(good)} lines in {elapsed:.1f} s"
    assert elapsed < 100 / 500 * 10  # 500 lines/s nominal; generous on a loaded machine
    for values in good:
        for column in ("current", "velocity", "temperature"):
            lo, hi = frame[column].min(), frame[column].max()
            assert lo - 1e-5 * abs(lo) - 1e-9 <= values[column] <= hi + 1e-5 * abs(hi) + 1e-9


def test_serial_lines_are_not_sent_faster_than_500_hz(rig):
    with console(rig) as port:
        port.readline()
        start = time.monotonic()
        count = 0
        while time.monotonic() - start < 0.5:
            count += port.read(port.in_waiting or 1).count(b"\n")
        elapsed = time.monotonic() - start
    assert count <= 500 * elapsed * 1.1 + 5
    assert count >= 10


def test_send_garbage_puts_malformed_lines_on_the_console(rig):
    pattern = re.compile(CONSOLE_REGEX)

    def malformed(line: bytes) -> bool:
        try:
            match = pattern.fullmatch(line.decode("ascii").rstrip("\n"))
            return match is None or not all(math.isfinite(float(v)) for v in match.groupdict().values())
        except (UnicodeDecodeError, ValueError):
            return True

    with console(rig) as port:
        port.readline()  # may be a partial line
        rig.send_garbage(5)
        bad = good = 0
        deadline = time.monotonic() + DEADLINE
        while (bad < 5 or good < 20) and time.monotonic() < deadline:
            line = port.readline()
            if line:
                bad, good = bad + malformed(line), good + (not malformed(line))
    assert bad == 5
    assert good >= 20


def test_pause_and_resume_modbus(rig):
    from pymodbus.exceptions import ModbusException

    with client_for(rig, timeout=0.5) as client:
        timed_read(rig, client, 1, 2)
        rig.pause_modbus()
        for _ in range(2):  # the open connection is dropped, and new connections are refused
            start = time.monotonic()
            try:
                rr = client.read_input_registers(0, count=2, device_id=1)
                failed = rr.isError()
            except ModbusException:
                failed = True
            assert failed
            assert time.monotonic() - start < 0.5 + 1.0
        rig.pause_modbus()  # idempotent
        rig.resume_modbus()
        deadline = time.monotonic() + DEADLINE
        while True:
            try:
                rr = client.read_input_registers(0, count=2, device_id=1)
                if not rr.isError():
                    break
            except ModbusException:
                pass
            assert time.monotonic() < deadline, "no answer after resume_modbus()"
            time.sleep(0.05)


def test_set_exception_answers_with_an_exception_response(rig):
    with client_for(rig) as client:
        rig.set_exception(1, True)
        rr = client.read_input_registers(0, count=2, device_id=1)
        assert rr.isError()
        assert rr.exception_code == 0x06  # SLAVE_DEVICE_BUSY
        timed_read(rig, client, 2, 8)  # the other unit still answers
        rig.set_exception(2, True, code=0x02)
        assert client.read_input_registers(0, count=8, device_id=2).exception_code == 0x02
        rig.set_exception(1, False)
        rig.set_exception(2, False)
        timed_read(rig, client, 1, 2)
        timed_read(rig, client, 2, 8)
    with pytest.raises(DynoDataError, match="code 99"):
        rig.set_exception(1, True, code=99)


def test_stop_releases_the_port_and_is_idempotent():
    rig = SimulatedRig(plan=PLAN, serial=True)
    try:
        rig.start()
        host, port = rig.address
        pty = rig.serial_port
        with client_for(rig) as client:
            timed_read(rig, client, 1, 2)
    finally:
        rig.stop()
    rig.stop()
    assert not rig.running
    assert rig.serial_port is None
    assert pty is not None
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection((host, port), timeout=TIMEOUT).close()
    # the same port can be taken again, by a new rig
    with SimulatedRig(plan=PLAN, port=port, serial=False) as again:
        assert again.address == (host, port)
        assert again.serial_port is None
        with client_for(again) as client:
            timed_read(again, client, 2, 8)


def test_start_on_a_taken_port_fails_cleanly(rig):
    other = SimulatedRig(plan=PLAN, port=rig.address[1], serial=False)
    with pytest.raises(DynoDataError, match="could not listen"):
        other.start()
    assert not other.running
    other.stop()


def test_speedup_plays_faster():
    speed, speedup = 0.5, 5.0  # one constant speed: position = speed * t measures playback time
    plan = TestPlan(speeds=(speed,))
    quantum = 1e-4 / speed / speedup  # wall time of one position count
    with SimulatedRig(plan=plan, speedup=speedup, serial=False) as rig, client_for(rig) as client:
        assert rig.period / speedup > 2.0
        for _ in range(3):  # retry if the playback loop wraps between the reads
            w1 = time.monotonic()
            first, ta1, _ = timed_read(rig, client, 2, 8)
            w2 = time.monotonic()
            time.sleep(0.2)
            w3 = time.monotonic()
            second, _, tb2 = timed_read(rig, client, 2, 8)
            w4 = time.monotonic()
            if tb2 > ta1:
                break
        else:
            pytest.fail("the playback loop wrapped every time")
    played = ((decode_drive(second)["position"] - decode_drive(first)["position"]) % TWO_PI) / speed / speedup
    assert w3 - w2 - 2 * quantum <= played <= w4 - w1 + 2 * quantum


def test_rig_mapping_describes_the_rig(rig):
    host, port = rig.address
    mapping = rig.rig_mapping()
    assert mapping["schema"] == "hound-id/rig/1"
    assert mapping["name"] == "simulated-rig"
    assert mapping["devices"] == {
        "transducer": {"type": "modbus_tcp", "host": host, "port": port, "unit": 1, "timeout": 0.2},
        "drive": {"type": "modbus_tcp", "host": host, "port": port, "unit": 2, "timeout": 0.2},
        "console": {
            "type": "serial_lines",
            "port": rig.serial_port,
            "baud": 115200,
            "format": {"regex": "I=(?P<current>[^,]+),W=(?P<velocity>[^,]+),T=(?P<temperature>[^,\\s]+)"},
        },
    }
    assert mapping["channels"] == [
        {"column": "torque", "device": "transducer", "register": 0, "kind": "input", "dtype": "float32", "unit": "N*m"},
        {"column": "current", "device": "drive", "register": 0, "kind": "input", "dtype": "float32", "unit": "A"},
        {"column": "velocity", "device": "drive", "register": 2, "kind": "input", "dtype": "float32", "unit": "rad/s"},
        {"column": "position", "device": "drive", "register": 4, "kind": "input", "dtype": "int32", "scale": 1e-4,
         "unit": "rad"},
        {"column": "temperature", "device": "drive", "register": 6, "kind": "input", "dtype": "int16", "scale": 0.1,
         "unit": "degC"},
        {"column": "bus_voltage", "device": "drive", "register": 7, "kind": "input", "dtype": "uint16", "scale": 0.01,
         "unit": "V"},
    ]  # fmt: skip
    assert rig.truth["kt"] > 0 and rig.truth["coulomb"] > 0


def test_mapping_without_serial_has_no_console():
    with SimulatedRig(plan=PLAN, serial=False) as rig:
        assert set(rig.rig_mapping()["devices"]) == {"transducer", "drive"}
        with pytest.raises(DynoDataError, match="no serial console"):
            rig.send_garbage(1)


@pytest.mark.parametrize(("kwargs", "match"), [({"speedup": 0.0}, "speedup"), ({"port": -1}, "port")])
def test_bad_arguments_are_refused(kwargs, match):
    with pytest.raises(DynoDataError, match=match):
        SimulatedRig(plan=PLAN, **kwargs)


def test_not_started():
    rig = SimulatedRig(plan=PLAN)
    with pytest.raises(DynoDataError, match="not been started"):
        rig.rig_mapping()
    with pytest.raises(DynoDataError, match="not running"):
        rig.pause_modbus()
    rig.stop()


def test_sample_interpolates_the_log():
    rig = SimulatedRig(plan=PLAN, serial=False)
    frame = rig.log.frame
    t = float(frame["time"].iloc[1000]) + 0.25e-3
    expected = 0.75 * frame.iloc[1000] + 0.25 * frame.iloc[1001]
    got = rig.sample(t)
    for column, value in got.items():
        assert value == pytest.approx(expected[column], rel=1e-12, abs=1e-12)
    assert rig.sample(t + rig.period) == pytest.approx(got)
