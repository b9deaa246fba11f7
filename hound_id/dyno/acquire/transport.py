"""Transports: how the recorder reads a rig's devices (Modbus TCP, Modbus RTU, line-based serial).

Each transport serves the channels of one connection and returns their values in SI
(:meth:`Transport.read`), or raises :class:`~hound_id.dyno.acquire.recorder.ReadError` on a
timeout, an exception response, a disconnect or a malformed line. Modbus devices that
share a connection (several unit ids behind one TCP port or one RS-485 bus) share one
client. Registers are read in the rig's merged blocks, one request per block.

A serial device streams lines on its own; a background thread parses them and keeps
the newest complete sample. A read returns it when it is younger than the device's
timeout, so a silent or garbled line stream turns into read errors (gaps), not stale data.

:data:`TRANSPORTS` maps a device type to its transport class (one sorted registry).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from hound_id.dyno.acquire.recorder import ReadError
from hound_id.dyno.acquire.rig import (
    ModbusRtuDevice,
    ModbusTcpDevice,
    ReadBlock,
    Rig,
    SerialLinesDevice,
    decode_block,
    parse_line,
)
from hound_id.errors import DynoDataError


def block_decoder(block: ReadBlock) -> Callable[[Sequence[int]], dict[str, float]]:
    """A fast decoder of one read block, equal to :func:`~hound_id.dyno.acquire.rig.decode_block`.

    Blocks whose channels are all big-endian (word and byte order, the Modbus default) are
    unpacked with precompiled structs from one packed buffer; others use ``decode_block``.
    """
    import struct

    from hound_id.dyno.acquire.rig import DTYPES

    if not all(ch.word_order == "big" and ch.byte_order == "big" for ch in block.channels):
        return lambda registers: decode_block(block, registers)
    packer = struct.Struct(f">{block.count}H")
    parts = [
        (ch.column, struct.Struct(">" + DTYPES[ch.dtype][0]), 2 * off, ch.si_factor, ch.si_offset)
        for ch, off in zip(block.channels, block.offsets, strict=True)
    ]

    def decode(registers: Sequence[int]) -> dict[str, float]:
        try:
            buffer = packer.pack(*registers)
        except struct.error as err:
            raise DynoDataError(f"device '{block.device}' registers {block.start}+{block.count}: {err}") from err
        return {col: s.unpack_from(buffer, o)[0] * f + c for col, s, o, f, c in parts}

    return decode


class ModbusTransport:
    """Modbus TCP or RTU: one client for a connection, one request per read block."""

    def __init__(self, devices: Sequence[ModbusTcpDevice | ModbusRtuDevice], blocks: Sequence[ReadBlock]) -> None:
        self.devices = {d.name: d for d in devices}
        self.blocks = list(blocks)
        self.decoders = [block_decoder(b) for b in self.blocks]
        self.client: Any = None
        self.errors = 0

    @property
    def label(self) -> str:
        first = next(iter(self.devices.values()))
        where = f"{first.host}:{first.port}" if isinstance(first, ModbusTcpDevice) else first.port
        return f"Modbus {where}"

    def open(self) -> None:
        from pymodbus.client import ModbusSerialClient, ModbusTcpClient

        first = next(iter(self.devices.values()))
        timeout = max(d.timeout for d in self.devices.values())
        if isinstance(first, ModbusTcpDevice):
            self.client = ModbusTcpClient(first.host, port=first.port, timeout=timeout, retries=0)
        else:
            self.client = ModbusSerialClient(
                first.port,
                baudrate=first.baud,
                parity=first.parity,
                stopbits=first.stopbits,
                bytesize=first.bytesize,
                timeout=timeout,
                retries=0,
            )
        self.client.connect()  # a failure here is not fatal: every read tries again

    def read(self) -> dict[str, float]:
        from pymodbus.exceptions import ModbusException

        if self.client is None:
            self.open()
        values: dict[str, float] = {}
        for block, decode in zip(self.blocks, self.decoders, strict=True):
            unit = self.devices[block.device].unit
            try:
                call = self.client.read_input_registers if block.kind == "input" else self.client.read_holding_registers
                response = call(block.start, count=block.count, device_id=unit)
            except ModbusException as err:
                self.errors += 1
                raise ReadError(f"{self.label} unit {unit}: {err}") from err
            except OSError as err:
                self.errors += 1
                raise ReadError(f"{self.label} unit {unit}: {err}") from err
            if response.isError():
                self.errors += 1
                raise ReadError(f"{self.label} unit {unit}: exception response {response}")
            try:
                values.update(decode(response.registers))
            except DynoDataError as err:
                raise ReadError(str(err)) from err
        return values

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
            self.client = None


class SerialLinesTransport:
    """A device that streams text lines; the newest parsed line is the sample."""

    def __init__(
        self, device: SerialLinesDevice, columns: Mapping[str, Callable[[float], float]], fields: Mapping[str, str]
    ) -> None:
        self.device = device
        self.columns = dict(columns)  # column -> raw-to-SI conversion
        self.fields = dict(fields)  # column -> field name in the line
        self._latest: tuple[float, dict[str, float]] | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._port: Any = None
        self.malformed = 0
        self.last_error = ""

    @property
    def label(self) -> str:
        return f"serial {self.device.port}"

    def open(self) -> None:
        import serial

        try:
            self._port = serial.Serial(self.device.port, self.device.baud, timeout=0.05)
        except (serial.SerialException, OSError) as err:
            raise ReadError(f"{self.label}: cannot open ({err})") from err
        self._thread = threading.Thread(target=self._run, name=f"serial-{self.device.name}", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        buffer = b""
        while not self._stop.is_set():
            try:
                chunk = self._port.read(4096)
            except Exception as err:  # noqa: BLE001 - a device gone away: report through read()
                self.last_error = f"{self.label}: {err}"
                time.sleep(0.01)
                continue
            if not chunk:
                continue
            buffer += chunk
            *lines, buffer = buffer.split(b"\n")
            for raw in lines:
                try:
                    parsed = parse_line(raw.decode("utf-8", "replace"), self.device.format)
                    sample = {col: conv(parsed[self.fields[col]]) for col, conv in self.columns.items()}
                except (DynoDataError, KeyError) as err:
                    self.malformed += 1
                    self.last_error = str(err)
                    continue
                with self._lock:
                    self._latest = (time.monotonic(), sample)

    def read(self) -> dict[str, float]:
        if self._thread is None:
            self.open()
        with self._lock:
            latest = self._latest
        if latest is None or time.monotonic() - latest[0] > self.device.timeout:
            reason = self.last_error or "no line received"
            raise ReadError(f"{self.label}: no valid line within {self.device.timeout:g} s ({reason})")
        return dict(latest[1])

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
            self._thread = None
        if self._port is not None:
            self._port.close()
            self._port = None


def transports_for(rig: Rig) -> list[ModbusTransport | SerialLinesTransport]:
    """One transport per connection of the rig."""
    out: list[ModbusTransport | SerialLinesTransport] = []
    blocks = rig.reads()
    groups: dict[tuple[str, ...], list[ModbusTcpDevice | ModbusRtuDevice]] = {}
    for device in rig.devices.values():
        if isinstance(device, ModbusTcpDevice):
            groups.setdefault(("tcp", device.host, str(device.port)), []).append(device)
        elif isinstance(device, ModbusRtuDevice):
            groups.setdefault(("rtu", device.port), []).append(device)
    for devices in groups.values():
        names = {d.name for d in devices}
        mine = [b for b in blocks if b.device in names]
        if mine:
            out.append(ModbusTransport(devices, mine))
    for device in rig.devices.values():
        if isinstance(device, SerialLinesDevice):
            channels = [c for c in rig.channels if c.device == device.name]
            if channels:
                out.append(
                    SerialLinesTransport(
                        device,
                        {c.column: c.raw_to_si for c in channels},
                        {c.column: str(c.field) for c in channels},
                    )
                )
    return out


class RigReader:
    """All of a rig's transports as one ``read_sample()`` for the recorder (a context manager)."""

    def __init__(self, rig: Rig) -> None:
        self.rig = rig
        self.transports = transports_for(rig)

    def __enter__(self) -> RigReader:
        for t in self.transports:
            try:
                t.open()
            except ReadError:
                pass  # reads retry; the recorder records the gap
        return self

    def __exit__(self, *exc: object) -> None:
        for t in self.transports:
            t.close()

    def read_sample(self) -> dict[str, float]:
        """Every column of the rig, SI; raises ReadError naming every device that failed."""
        values: dict[str, float] = {}
        errors = []
        for t in self.transports:
            try:
                values.update(t.read())
            except ReadError as err:
                errors.append(str(err))
        if errors:
            raise ReadError("; ".join(errors))
        return values

    def faults(self) -> dict[str, int]:
        """Error counters per transport."""
        out = {}
        for t in self.transports:
            out[t.label] = t.errors if isinstance(t, ModbusTransport) else t.malformed
        return out


TRANSPORTS: dict[str, type] = dict(
    sorted(
        {
            "modbus_rtu": ModbusTransport,
            "modbus_tcp": ModbusTransport,
            "serial_lines": SerialLinesTransport,
        }.items()
    )
)
