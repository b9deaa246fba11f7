"""Dynamometer rig files: which device gives each channel, and how to decode it (schema ``hound-id/rig/1``).

A rig file names the devices of the data acquisition (Modbus TCP servers, Modbus RTU
slaves on a serial bus, serial ports that print text lines) and maps each log column to a
register or a text field of one device::

    schema: hound-id/rig/1
    name: bench-1
    devices:
      transducer: {type: modbus_tcp, host: 127.0.0.1, port: 5020}
      console: {type: serial_lines, port: /dev/ttyACM0, baud: 115200,
                format: {delimiter: ",", fields: [current, velocity]}}
    channels:
      - {column: torque, device: transducer, register: 0, kind: input, dtype: float32, unit: "N*m"}
      - {column: current, device: console, field: current, unit: A}

**Device types.** :data:`DEVICE_TYPES` is the registry of the device types a rig file may use; the rig file's
reader (:mod:`~hound_id.dyno.acquire.rig_file`), :func:`device_type` and the recorder's transports
(:func:`~hound_id.dyno.acquire.transport.transports_for`) all read it. A device type is declared by its
transport, in the transport's module, as one :class:`~hound_id.dyno.acquire.device.DeviceType` (its name, its
settings, how its channels are addressed, its transport class), and added with one :func:`register` call:
:mod:`~hound_id.dyno.acquire.modbus` (modbus_rtu, modbus_tcp), :mod:`~hound_id.dyno.acquire.serial_lines`.

What a channel is and how its value decodes (units, registers, read blocks) is
:mod:`hound_id.dyno.acquire.channel`; reading and writing the rig file is :mod:`hound_id.dyno.acquire.rig_file`.
pymodbus and pyserial are not imported here.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

from hound_id.dyno.acquire.channel import (
    CHANNEL_COLUMNS,
    DTYPES,
    FLOAT32_MAX,
    KINDS,
    MAX_BLOCK,
    MAX_GAP,
    MAX_REGISTER,
    ORDERS,
    REQUIRED_COLUMNS,
    Channel,
    ReadBlock,
    decode,
    decode_block,
    default_unit,
    encode,
    merge_reads,
    unit_conversion,
)
from hound_id.dyno.acquire.device import DEFAULT_TIMEOUT, Device, DeviceType
from hound_id.dyno.acquire.modbus import MODBUS_RTU, MODBUS_TCP, PARITIES, ModbusRtuDevice, ModbusTcpDevice
from hound_id.dyno.acquire.serial_lines import (
    SERIAL_LINES,
    LineFormat,
    SerialLinesDevice,
    compiled_pattern,
    parse_line,
)
from hound_id.dyno.logs import CANONICAL
from hound_id.errors import SpecError

__all__ = [
    "CHANNEL_COLUMNS",
    "DEFAULT_TIMEOUT",
    "DEVICE_TYPES",
    "DTYPES",
    "FLOAT32_MAX",
    "KINDS",
    "MAX_BLOCK",
    "MAX_GAP",
    "MAX_REGISTER",
    "ORDERS",
    "PARITIES",
    "REQUIRED_COLUMNS",
    "SCHEMA",
    "Channel",
    "Device",
    "DeviceType",
    "LineFormat",
    "ModbusRtuDevice",
    "ModbusTcpDevice",
    "ReadBlock",
    "Rig",
    "SerialLinesDevice",
    "compiled_pattern",
    "decode",
    "decode_block",
    "default_unit",
    "device_type",
    "encode",
    "merge_reads",
    "parse_line",
    "register",
    "unit_conversion",
]

SCHEMA = "hound-id/rig/1"

#: The device types a rig file may use, by name (sorted): the registry. Add one with :func:`register`.
DEVICE_TYPES: dict[str, DeviceType] = {}


def register(kind: DeviceType, *, replace: bool = False) -> DeviceType:
    """Add a device type (kept sorted by name); from then on rig files may use it and the recorder reads it.

    Raises:
        SpecError: The name is taken (pass ``replace=True`` to replace it), or the declaration does not hold
            together (:meth:`~hound_id.dyno.acquire.device.DeviceType.check`).
    """
    kind.check()
    if kind.name in DEVICE_TYPES and not replace:
        raise SpecError(f"device type '{kind.name}' is already registered; pick another name or pass replace=True")
    DEVICE_TYPES[kind.name] = kind
    for key in sorted(DEVICE_TYPES):
        DEVICE_TYPES[key] = DEVICE_TYPES.pop(key)
    return kind


register(MODBUS_RTU)
register(MODBUS_TCP)
register(SERIAL_LINES)


def device_type(device: Device) -> DeviceType:
    """The registered device type of a device.

    Raises:
        SpecError: Its type is not registered.
    """
    kind = DEVICE_TYPES.get(device.type)
    if kind is None:
        raise SpecError(
            f"device '{device.name}': type {device.type!r} is not registered; expected one of "
            f"{', '.join(DEVICE_TYPES)}; register it first"
        )
    return kind


@dataclass(frozen=True)
class Rig:
    """A dynamometer's data acquisition: devices and the channels read from them."""

    name: str
    """Rig name."""
    devices: Mapping[str, Device]
    """Devices by name, in file order (read-only)."""
    channels: tuple[Channel, ...]
    """Channels in file order."""
    source: str | None = dataclasses.field(default=None, compare=False)
    """File the rig came from, if any."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "devices", MappingProxyType(dict(self.devices)))

    @property
    def columns(self) -> tuple[str, ...]:
        """Columns read: canonical ones in log order, then free names in file order."""
        names = [c.column for c in self.channels]
        return tuple(c for c in CHANNEL_COLUMNS if c in names) + tuple(n for n in names if n not in CANONICAL)

    def channel(self, column: str) -> Channel:
        """The channel of ``column`` (KeyError if the rig does not read it)."""
        for ch in self.channels:
            if ch.column == column:
                return ch
        raise KeyError(column)

    def reads(self) -> list[ReadBlock]:
        """The Modbus read blocks: per device (file order) and kind, by address (see :func:`merge_reads`)."""
        return merge_reads(self.channels, tuple(self.devices))
