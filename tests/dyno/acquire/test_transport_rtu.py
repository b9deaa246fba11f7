"""Modbus RTU over a real serial line: two pseudo-terminals joined by a null-modem relay."""

import asyncio
import os
import select
import struct
import threading
import time

import pytest

from hound_id.dyno.acquire.rig_file import rig_from_mapping
from hound_id.dyno.acquire.transport import RigReader


def null_modem():
    """Two pty slave paths whose masters are joined: bytes written on one arrive on the other."""
    (ma, sa), (mb, sb) = os.openpty(), os.openpty()
    stop = threading.Event()

    def relay():
        while not stop.is_set():
            ready, _, _ = select.select([ma, mb], [], [], 0.05)
            for fd in ready:
                try:
                    data = os.read(fd, 4096)
                except OSError:
                    return
                os.write(mb if fd == ma else ma, data)

    thread = threading.Thread(target=relay, daemon=True)
    thread.start()

    def close():
        stop.set()
        thread.join(timeout=2)
        for fd in (ma, sa, mb, sb):
            os.close(fd)

    return os.ttyname(sa), os.ttyname(sb), close


def serve_rtu(port: str, registers: list[int], ready: threading.Event, done: threading.Event):
    from pymodbus.server import ModbusSerialServer
    from pymodbus.simulator import DataType, SimData, SimDevice

    async def main():
        device = SimDevice(
            id=3,
            simdata=[SimData(0, count=len(registers), values=registers, datatype=DataType.REGISTERS, readonly=True)],
        )
        server = ModbusSerialServer(device, port=port, baudrate=115200)
        await server.serve_forever(background=True)
        ready.set()
        while not done.is_set():
            await asyncio.sleep(0.02)
        await server.shutdown()

    asyncio.run(main())


def test_rtu_reads_over_a_serial_line():
    server_port, client_port, close = null_modem()
    torque = struct.unpack(">2H", struct.pack(">f", 1.5))
    registers = [*torque, 1234, 0, 0]  # torque float32 at 0-1, current int16 (x0.01 A) at 2
    ready, done = threading.Event(), threading.Event()
    thread = threading.Thread(target=serve_rtu, args=(server_port, registers, ready, done), daemon=True)
    thread.start()
    try:
        assert ready.wait(10), "RTU server did not start"
        rig = rig_from_mapping(
            {
                "schema": "hound-id/rig/1",
                "name": "rtu",
                "devices": {
                    "drive": {"type": "modbus_rtu", "port": client_port, "baud": 115200, "unit": 3, "timeout": 0.5}
                },
                "channels": [
                    {"column": "torque", "device": "drive", "register": 0, "dtype": "float32", "unit": "N*m"},
                    {
                        "column": "current",
                        "device": "drive",
                        "register": 2,
                        "dtype": "int16",
                        "scale": 0.01,
                        "unit": "A",
                    },
                ],
            },
            source="rtu",
        )
        with RigReader(rig) as reader:
            deadline = time.monotonic() + 10
            while True:
                try:
                    values = reader.read_sample()
                    break
                except Exception:
                    if time.monotonic() > deadline:
                        raise
                    time.sleep(0.1)
        assert values["torque"] == pytest.approx(1.5)
        assert values["current"] == pytest.approx(12.34)
    finally:
        done.set()
        thread.join(timeout=5)
        close()
