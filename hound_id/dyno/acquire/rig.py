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

**Values.** A channel's value in hound-id units is ``(raw * scale + offset)`` read in
``unit`` and converted to the column's unit: SI for current, torque, velocity, position
and bus_voltage, degC for temperature (as in :mod:`hound_id.dyno.logs`). Free column names
convert to the SI base units of their ``unit`` (degC for temperatures). The conversion is
folded once into :attr:`Channel.si_factor` and :attr:`Channel.si_offset`.

**Registers.** A 32-bit value spans two registers. ``word_order: big`` puts the most
significant register first; ``byte_order: big`` is the Modbus byte order inside a register
(high byte first), ``little`` swaps the two bytes of every register.

**Reads.** :meth:`Rig.reads` merges the registers of one device and one register kind into
blocks, each read with one request: a block may skip up to :data:`MAX_GAP` unused registers
and holds at most :data:`MAX_BLOCK` registers (the Modbus limit for one read).

pymodbus and pyserial are not imported here; decoding uses :mod:`struct`.

Reading and writing the rig file is :mod:`hound_id.dyno.acquire.rig_file`.
"""

from __future__ import annotations

import dataclasses
import math
import re
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from types import MappingProxyType
from typing import ClassVar

from hound_id.dyno.logs import CANONICAL, UNITS
from hound_id.errors import DynoDataError, SpecError
from hound_id.units import as_number, check_unit_text, normalise, registry, unit_text_errors

SCHEMA = "hound-id/rig/1"


#: Device types a rig file may use.
DEVICE_TYPES: tuple[str, ...] = ("modbus_rtu", "modbus_tcp", "serial_lines")
#: Modbus register kinds: holding registers (function 3) and input registers (function 4).
KINDS: tuple[str, ...] = ("holding", "input")
#: Register data types -> (struct code, registers per value).
DTYPES: dict[str, tuple[str, int]] = {
    "int16": ("h", 1),
    "uint16": ("H", 1),
    "int32": ("i", 2),
    "uint32": ("I", 2),
    "float32": ("f", 2),
}
#: Word and byte orders.
ORDERS: tuple[str, ...] = ("big", "little")
#: Serial parities: even, none, odd.
PARITIES: tuple[str, ...] = ("E", "N", "O")
#: Columns a rig may read, in log order (time is stamped by the recorder, never read).
CHANNEL_COLUMNS: tuple[str, ...] = tuple(c for c in CANONICAL if c != "time")
#: Columns every rig must read.
REQUIRED_COLUMNS: tuple[str, ...] = ("current", "torque")
#: Most unused registers one read block may skip between two channels.
MAX_GAP = 8
#: Most registers in one read (Modbus: 125 holding or input registers per request).
MAX_BLOCK = 125
#: Highest Modbus register address.
MAX_REGISTER = 65535
#: Largest finite float32.
FLOAT32_MAX = 3.4028234663852886e38


_INT_RANGE: dict[str, tuple[int, int]] = {
    "int16": (-(2**15), 2**15 - 1),
    "uint16": (0, 2**16 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "uint32": (0, 2**32 - 1),
}


DEFAULT_TIMEOUT = 0.2


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


@dataclass(frozen=True)
class LineFormat:
    """How to split one text line of a :class:`SerialLinesDevice` into named numbers.

    Either ``delimiter`` and ``fields`` (a delimited line), or ``regex`` with named groups.
    """

    delimiter: str | None = None
    """Separator of a delimited line (None for a regex format)."""
    fields: tuple[str, ...] | None = None
    """Names of the delimited fields, in line order (None for a regex format)."""
    regex: str | None = None
    """Regular expression whose named groups are the fields (None for a delimited format)."""

    @property
    def names(self) -> tuple[str, ...]:
        """Field names the format yields."""
        if self.regex is not None:
            return tuple(compiled_pattern(self.regex).groupindex)
        return self.fields or ()


@dataclass(frozen=True)
class SerialLinesDevice:
    """A serial port that prints one text line per sample (a microcontroller console)."""

    type: ClassVar[str] = "serial_lines"
    name: str
    """Device name in the rig file."""
    port: str
    """Serial port (``/dev/ttyACM0``, ``COM3``)."""
    baud: int
    """Baud rate [bit/s]."""
    format: LineFormat
    """How a line splits into fields."""
    timeout: float = DEFAULT_TIMEOUT
    """Read timeout [s]."""


Device = ModbusTcpDevice | ModbusRtuDevice | SerialLinesDevice


@dataclass(frozen=True)
class Channel:
    """One log column and where it comes from: a Modbus register or a serial text field."""

    column: str
    """Log column: one of :data:`CHANNEL_COLUMNS` or a free name."""
    device: str
    """Name of the device that gives it."""
    register: int | None = None
    """First Modbus register address, 0-65535 (None for a serial channel)."""
    kind: str = "holding"
    """Register kind: holding or input (Modbus channels)."""
    dtype: str = "int16"
    """Raw type: int16, uint16, int32, uint32 or float32 (Modbus channels)."""
    word_order: str = "big"
    """Register order of a 32-bit value: big (most significant register first) or little."""
    byte_order: str = "big"
    """Byte order inside each register: big (Modbus standard) or little (bytes swapped)."""
    scale: float = 1.0
    """Raw value -> value in ``unit``: ``raw * scale + offset`` [unit / raw count]."""
    offset: float = 0.0
    """Added after scaling [unit]."""
    unit: str = ""
    """pint unit of ``raw * scale + offset``; empty means the column's own unit."""
    field: str | None = None
    """Field of the serial line format (None for a Modbus channel)."""
    si_unit: str = dataclasses.field(init=False)
    """Unit of the decoded value: the column's hound-id unit (SI; degC for temperature)."""
    si_factor: float = dataclasses.field(init=False)
    """Value in ``si_unit`` = raw * si_factor + si_offset [si_unit / raw count]."""
    si_offset: float = dataclasses.field(init=False)
    """See ``si_factor`` [si_unit]."""

    def __post_init__(self) -> None:
        unit = self.unit or default_unit(self.column)
        object.__setattr__(self, "unit", unit)
        conversion = unit_conversion(unit, self.column)
        if isinstance(conversion, str):
            raise SpecError(f"channel '{self.column}': field 'unit': {conversion}", field="unit", found=unit)
        si_unit, a, b = conversion
        object.__setattr__(self, "si_unit", si_unit)
        object.__setattr__(self, "si_factor", self.scale * a)
        object.__setattr__(self, "si_offset", self.offset * a + b)

    @property
    def is_modbus(self) -> bool:
        """Whether the channel reads Modbus registers (else a serial text field)."""
        return self.register is not None

    @property
    def count(self) -> int:
        """Registers to read: 1 (16-bit) or 2 (32-bit); 0 for a serial channel."""
        return DTYPES[self.dtype][1] if self.is_modbus else 0

    def raw_to_si(self, raw: float) -> float:
        """The decoded value [si_unit] of a raw register or field value."""
        return raw * self.si_factor + self.si_offset

    def si_to_raw(self, value_si: float) -> float:
        """The raw value (not rounded) that decodes to ``value_si`` [si_unit]."""
        return (value_si - self.si_offset) / self.si_factor


@dataclass(frozen=True)
class ReadBlock:
    """Registers of one device and kind read with one Modbus request."""

    device: str
    """Device name."""
    kind: str
    """Register kind: holding or input."""
    start: int
    """First register address."""
    count: int
    """Number of registers, at most :data:`MAX_BLOCK`."""
    channels: tuple[Channel, ...]
    """Channels decoded from the block, by register."""
    offsets: tuple[int, ...]
    """Index of each channel's first register in the block."""


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


def merge_reads(channels: Sequence[Channel], device_order: Sequence[str] = ()) -> list[ReadBlock]:
    """Merge Modbus channels into as few read blocks as the rules allow.

    Channels of the same device and register kind, sorted by address, go into one block while
    the next channel starts at most :data:`MAX_GAP` unused registers after the block's end and the
    block stays within :data:`MAX_BLOCK` registers. Different devices or kinds are never merged.
    Greedy filling by address gives the fewest blocks for these rules.

    Args:
        channels: Channels (serial ones are skipped).
        device_order: Device names in the order blocks should come; others follow by name.
    """
    groups: dict[tuple[str, str], list[Channel]] = {}
    for ch in channels:
        if ch.is_modbus:
            groups.setdefault((ch.device, ch.kind), []).append(ch)
    rank = {name: i for i, name in enumerate(device_order)}
    blocks: list[ReadBlock] = []
    for device, kind in sorted(groups, key=lambda k: (rank.get(k[0], len(rank)), k[0], k[1])):
        members = sorted(groups[(device, kind)], key=lambda c: (c.register, -c.count))
        current: list[Channel] = []
        start = end = 0
        for ch in members:
            reg = int(ch.register)  # type: ignore[arg-type]  # is_modbus
            if current and reg - end <= MAX_GAP and max(end, reg + ch.count) - start <= MAX_BLOCK:
                current.append(ch)
                end = max(end, reg + ch.count)
                continue
            if current:
                blocks.append(_block(device, kind, start, end, current))
            current, start, end = [ch], reg, reg + ch.count
        if current:
            blocks.append(_block(device, kind, start, end, current))
    return blocks


def _block(device: str, kind: str, start: int, end: int, members: list[Channel]) -> ReadBlock:
    return ReadBlock(
        device=device,
        kind=kind,
        start=start,
        count=end - start,
        channels=tuple(members),
        offsets=tuple(int(c.register) - start for c in members),  # type: ignore[arg-type]
    )


def default_unit(column: str) -> str:
    return UNITS.get(column, "dimensionless")


@lru_cache(maxsize=256)
def unit_conversion(unit: str, column: str) -> tuple[str, float, float] | str:
    """(target unit, a, b) with target = a * x + b for x in ``unit``; or why the unit is refused."""

    ureg = registry()
    text = normalise(unit)
    try:
        check_unit_text(text)
        parsed = ureg.Unit(text)
    except unit_text_errors() as err:
        return f"found {unit!r}, which is not a unit ({err}); expected a pint unit such as 'N*m', 'rpm', 'degC'"
    if column in UNITS:
        target = UNITS[column]
        if column == "velocity" and ("hertz" in str(parsed) or "Hz" in text):
            return (
                f"found {unit!r}: Hz is ambiguous for an angular speed (rev/s or rad/s?); "
                "write rad/s, rps, rpm or deg/s"
            )
        target_unit = ureg.Unit(target)
        angle = column in ("velocity", "position")
        base = str(ureg.Quantity(1.0, parsed).to_base_units().units)
        if parsed.dimensionality != target_unit.dimensionality or (angle and "radian" not in base):
            return (
                f"found {unit!r} (dimension {parsed.dimensionality}), expected a unit of {column} "
                f"convertible to {target} (for example {_EXAMPLE_UNITS[column]}); fix the unit"
            )
    elif parsed.dimensionality == ureg.Unit("degC").dimensionality:
        target = "degC"
    else:
        target = str(ureg.Quantity(1.0, parsed).to_base_units().units)
    b = float(ureg.Quantity(0.0, parsed).to(target).magnitude)
    a = float(ureg.Quantity(1.0, parsed).to(target).magnitude) - b
    return target, a, b


_EXAMPLE_UNITS = {
    "current": "A, mA",
    "torque": "N*m, mN*m",
    "velocity": "rad/s, rpm, deg/s",
    "position": "rad, deg, turn",
    "temperature": "degC, degF, K",
    "bus_voltage": "V, mV",
}


def _modbus_only(channel: Channel) -> tuple[str, int]:
    if not channel.is_modbus:
        raise DynoDataError(
            f"channel '{channel.column}': reads serial field '{channel.field}', not Modbus registers; "
            "decode its lines with parse_line",
            column=channel.column,
        )
    if channel.dtype not in DTYPES:
        raise DynoDataError(
            f"channel '{channel.column}': found dtype {channel.dtype!r}, expected one of {', '.join(DTYPES)}",
            column=channel.column,
        )
    return DTYPES[channel.dtype]


def _swap_bytes(data: bytes) -> bytes:
    out = bytearray(data)
    out[0::2], out[1::2] = data[1::2], data[0::2]
    return bytes(out)


def decode(registers: Sequence[int], channel: Channel) -> float:
    """The value of a Modbus channel [channel.si_unit] from its raw registers.

    Args:
        registers: The channel's ``channel.count`` registers, first address first (0-65535 each).
        channel: A Modbus channel.

    Raises:
        DynoDataError: Wrong number of registers, a register out of 0-65535, or a serial channel.
    """
    code, count = _modbus_only(channel)
    words = list(registers)
    if len(words) != count:
        raise DynoDataError(
            f"channel '{channel.column}': found {len(words)} registers, expected {count} for {channel.dtype}; "
            "pass the channel's registers only",
            column=channel.column,
            found=len(words),
        )
    for word in words:
        if isinstance(word, bool) or not isinstance(word, int) or not 0 <= word <= 0xFFFF:
            raise DynoDataError(
                f"channel '{channel.column}': found register value {word!r}, expected an integer 0-65535",
                column=channel.column,
                found=word,
            )
    if channel.word_order == "little":
        words.reverse()
    data = b"".join(w.to_bytes(2, "big") for w in words)
    if channel.byte_order == "little":
        data = _swap_bytes(data)
    (raw,) = struct.unpack(">" + code, data)
    return channel.raw_to_si(float(raw))


def encode(value_si: float, channel: Channel) -> list[int]:
    """The registers that :func:`decode` turns into ``value_si`` (integer types round to nearest).

    Args:
        value_si: Value [channel.si_unit].
        channel: A Modbus channel.

    Raises:
        DynoDataError: The raw value is not finite or outside the range of the channel's dtype.
    """
    code, _ = _modbus_only(channel)
    raw = channel.si_to_raw(float(value_si))
    bad = not math.isfinite(raw)
    packed = b""
    if not bad and channel.dtype in _INT_RANGE:
        lo, hi = _INT_RANGE[channel.dtype]
        bad = not lo <= round(raw) <= hi
        if not bad:
            packed = struct.pack(">" + code, round(raw))
    elif not bad:
        try:
            packed = struct.pack(">f", raw) if abs(raw) <= FLOAT32_MAX else b""
        except OverflowError:
            packed = b""
        bad = not packed
    if bad:
        lo_hi = _INT_RANGE.get(channel.dtype, (-FLOAT32_MAX, FLOAT32_MAX))
        raise DynoDataError(
            f"channel '{channel.column}': value {value_si!r} {channel.si_unit} is raw {raw!r}, outside the "
            f"{channel.dtype} range [{lo_hi[0]:g}, {lo_hi[1]:g}]; change the value, scale/offset or dtype",
            column=channel.column,
            found=value_si,
        )
    if channel.byte_order == "little":
        packed = _swap_bytes(packed)
    words = [int.from_bytes(packed[i : i + 2], "big") for i in range(0, len(packed), 2)]
    if channel.word_order == "little":
        words.reverse()
    return words


def decode_block(block: ReadBlock, registers: Sequence[int]) -> dict[str, float]:
    """Values [each channel's si_unit] of every channel of a read block, keyed by column.

    Raises:
        DynoDataError: ``registers`` does not hold ``block.count`` values, or one is out of range.
    """
    if len(registers) != block.count:
        raise DynoDataError(
            f"device '{block.device}' {block.kind} registers {block.start}-{block.start + block.count - 1}: "
            f"found {len(registers)} registers, expected {block.count}; read the whole block",
            found=len(registers),
        )
    return {
        ch.column: decode(registers[off : off + ch.count], ch)
        for ch, off in zip(block.channels, block.offsets, strict=True)
    }


@lru_cache(maxsize=64)
def compiled_pattern(regex: str) -> re.Pattern[str]:
    return re.compile(regex)


def _shown(line: str) -> str:
    text = line.rstrip("\r\n")
    return repr(text if len(text) <= 80 else text[:77] + "...")


def parse_line(line: str, fmt: LineFormat) -> dict[str, float]:
    """The raw numbers of one text line, keyed by field name.

    Raises:
        DynoDataError: The line does not match the format or a field is not a number.
    """
    text = line.strip()
    raw: dict[str, str | None]
    if fmt.regex is not None:
        match = compiled_pattern(fmt.regex).search(text)
        if match is None:
            raise DynoDataError(
                f"serial line {_shown(line)}: does not match the format regex {fmt.regex!r}; "
                "check the device output or the rig's format",
                line=line,
            )
        raw = match.groupdict()
    else:
        names = fmt.fields or ()
        parts = text.split(fmt.delimiter if fmt.delimiter is not None else ",")
        if len(parts) != len(names):
            raise DynoDataError(
                f"serial line {_shown(line)}: found {len(parts)} fields, expected {len(names)} "
                f"({', '.join(names)}) separated by {fmt.delimiter!r}; check the device output or the rig's format",
                line=line,
            )
        raw = dict(zip(names, parts, strict=True))
    out: dict[str, float] = {}
    for name, value in raw.items():
        number = None if value is None else as_number(value.strip())
        if number is None:
            raise DynoDataError(
                f"serial line {_shown(line)}: field '{name}' is {value!r}, expected a number; "
                "check the device output or the rig's format",
                line=line,
                field=name,
            )
        out[name] = number
    return out
