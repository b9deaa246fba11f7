"""The Modbus transports: device types ``modbus_tcp`` (a server on the network) and ``modbus_rtu`` (a slave on a
serial bus), their settings, their register channels and :class:`ModbusTransport`.

Devices that share a connection (several unit ids behind one TCP host and port, or on one RS-485 port) share
one client. Registers are read in the rig's merged blocks (:func:`~hound_id.dyno.acquire.channel.merge_reads`),
one request per block. pymodbus is imported when a transport opens.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

from hound_id.dyno.acquire.channel import (
    DTYPES,
    KINDS,
    MAX_REGISTER,
    ORDERS,
    Channel,
    ReadBlock,
    decode_block,
    merge_reads,
)
from hound_id.dyno.acquire.device import (
    DEFAULT_TIMEOUT,
    Addressing,
    DeviceType,
    Where,
    check_choice,
    check_integer,
    integer,
    one_of,
    seconds,
    text,
)
from hound_id.dyno.acquire.recorder import ReadError
from hound_id.errors import DynoDataError

#: Serial parities: even, none, odd.
PARITIES: tuple[str, ...] = ("E", "N", "O")


@dataclass(frozen=True)
class ModbusTcpDevice:
    """A Modbus TCP server (a transducer's Ethernet interface, a drive gateway)."""

    type: ClassVar[str] = "modbus_tcp"
    name: str
    """Device name in the rig file."""
    host: str
    """Host name or IP address."""
    port: int
    """TCP port, 1-65535."""
    unit: int = 1
    """Modbus unit (slave) id, 0-247."""
    timeout: float = DEFAULT_TIMEOUT
    """Response timeout [s]."""


@dataclass(frozen=True)
class ModbusRtuDevice:
    """A Modbus RTU slave on a serial line (a motor drive, an RS-485 transducer)."""

    type: ClassVar[str] = "modbus_rtu"
    name: str
    """Device name in the rig file."""
    port: str
    """Serial port (``/dev/ttyUSB0``, ``COM3``)."""
    baud: int
    """Baud rate [bit/s]."""
    parity: str = "N"
    """Parity: N, E or O."""
    stopbits: int = 1
    """Stop bits: 1 or 2."""
    bytesize: int = 8
    """Data bits: 7 or 8."""
    unit: int = 1
    """Modbus unit (slave) id, 0-247."""
    timeout: float = DEFAULT_TIMEOUT
    """Response timeout [s]."""


def register_address(data: Mapping[Any, Any], device: Any, at: Where) -> dict[str, Any]:
    """A register channel's keys: ``register`` (0-65535), ``kind``, ``dtype``, ``word_order``, ``byte_order``."""
    if "register" not in data:
        raise at.error(
            f"missing; a channel of Modbus device '{device.name}' needs a register address 0-65535", "register"
        )
    register = check_integer(data["register"], at.field("register"), 0, MAX_REGISTER)
    dtype = check_choice(data.get("dtype", "int16"), at.field("dtype"), tuple(DTYPES))
    if register + DTYPES[dtype][1] - 1 > MAX_REGISTER:
        raise at.error(
            f"found {register}, but {dtype} needs 2 registers and the last address is {MAX_REGISTER}; fix the address",
            "register",
            found=register,
        )
    return {
        "register": register,
        "kind": check_choice(data.get("kind", "holding"), at.field("kind"), KINDS),
        "dtype": dtype,
        "word_order": check_choice(data.get("word_order", "big"), at.field("word_order"), ORDERS),
        "byte_order": check_choice(data.get("byte_order", "big"), at.field("byte_order"), ORDERS),
    }


#: Channels of both Modbus device types name a register.
REGISTERS = Addressing(("register", "kind", "dtype", "word_order", "byte_order"), register_address)


def block_decoder(block: ReadBlock) -> Callable[[Sequence[int]], dict[str, float]]:
    """A fast decoder of one read block, equal to :func:`~hound_id.dyno.acquire.channel.decode_block`.

    Blocks whose channels are all big-endian (word and byte order, the Modbus default) are
    unpacked with precompiled structs from one packed buffer; others use ``decode_block``.
    """
    import struct

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

    def __init__(self, devices: Sequence[ModbusTcpDevice | ModbusRtuDevice], channels: Sequence[Channel]) -> None:
        self.devices = {d.name: d for d in devices}
        self.blocks = merge_reads(channels, tuple(self.devices))
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


_UNIT = integer("unit", 0, 247, 1)

MODBUS_TCP = DeviceType(
    name="modbus_tcp",
    device=ModbusTcpDevice,
    settings=(text("host"), integer("port", 1, 65535), _UNIT, seconds()),
    channels=REGISTERS,
    transport=ModbusTransport,
    connection=lambda d: (d.host, d.port),
)

MODBUS_RTU = DeviceType(
    name="modbus_rtu",
    device=ModbusRtuDevice,
    settings=(
        text("port"),
        integer("baud", 1, 100_000_000),
        one_of("parity", PARITIES, "N", "expected N, E or O; use one of these"),
        one_of("stopbits", (1, 2), 1, "expected 1 or 2; fix the value"),
        integer("bytesize", 7, 8, 8),
        _UNIT,
        seconds(),
    ),
    channels=REGISTERS,
    transport=ModbusTransport,
    connection=lambda d: d.port,
)
