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
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from types import MappingProxyType
from typing import Any, ClassVar

from hound_id.dyno.logs import CANONICAL, UNITS
from hound_id.errors import DynoDataError, SpecError
from hound_id.io import read_yaml
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
_FREE_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_TOP_KEYS = ("channels", "devices", "name", "schema")
_DEVICE_KEYS: dict[str, tuple[str, ...]] = {
    "modbus_tcp": ("type", "host", "port", "unit", "timeout"),
    "modbus_rtu": ("type", "port", "baud", "parity", "stopbits", "bytesize", "unit", "timeout"),
    "serial_lines": ("type", "port", "baud", "format", "timeout"),
}
_DEVICE_REQUIRED: dict[str, tuple[str, ...]] = {
    "modbus_tcp": ("host", "port"),
    "modbus_rtu": ("port", "baud"),
    "serial_lines": ("port", "baud", "format"),
}
_FORMAT_KEYS = ("delimiter", "fields", "regex")
_MODBUS_CHANNEL_KEYS = (
    "column",
    "device",
    "register",
    "kind",
    "dtype",
    "word_order",
    "byte_order",
    "scale",
    "offset",
    "unit",
)
_SERIAL_CHANNEL_KEYS = ("column", "device", "field", "scale", "offset", "unit")
_CHANNEL_KEYS = tuple(dict.fromkeys((*_MODBUS_CHANNEL_KEYS, *_SERIAL_CHANNEL_KEYS)))
_DEFAULT_TIMEOUT = 0.2


# --- data ------------------------------------------------------------------------------------------------------


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
    timeout: float = _DEFAULT_TIMEOUT
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
    timeout: float = _DEFAULT_TIMEOUT
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
            return tuple(_compiled(self.regex).groupindex)
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
    timeout: float = _DEFAULT_TIMEOUT
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
        unit = self.unit or _default_unit(self.column)
        object.__setattr__(self, "unit", unit)
        conversion = _conversion(unit, self.column)
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


# --- units -----------------------------------------------------------------------------------------------------


def _default_unit(column: str) -> str:
    return UNITS.get(column, "dimensionless")


@lru_cache(maxsize=256)
def _conversion(unit: str, column: str) -> tuple[str, float, float] | str:
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


# --- decoding --------------------------------------------------------------------------------------------------


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
def _compiled(regex: str) -> re.Pattern[str]:
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
        match = _compiled(fmt.regex).search(text)
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


# --- reading and writing rig files -----------------------------------------------------------------------------


def load_rig(path: str | Path) -> Rig:
    """Read and validate a rig YAML file (schema hound-id/rig/1).

    Raises:
        SpecError: The file is missing, not YAML, or not a valid rig (see :func:`rig_from_mapping`).
    """
    return rig_from_mapping(read_yaml(path, "rig"), source=str(path))


class _Where:
    """Builds the one-line messages: 'file: item: field 'key': text'."""

    def __init__(self, source: str | None, item: str | None = None) -> None:
        self.source = source or "rig"
        self.item = item

    def at(self, item: str) -> _Where:
        return _Where(self.source, item)

    def error(self, text: str, key: str | None = None, **details: Any) -> SpecError:
        parts = [self.source, self.item, f"field '{key}'" if key else None, text]
        return SpecError(": ".join(p for p in parts if p), field=key, item=self.item, **details)


def _suggest(key: str, known: Sequence[str]) -> str:
    close = difflib.get_close_matches(key, known, n=1)
    hint = f"did you mean '{close[0]}'? " if close else ""
    return f"{hint}expected one of {', '.join(known)}"


def _check_keys(data: Mapping[Any, Any], known: Sequence[str], at: _Where, extra: str = "") -> None:
    for key in data:
        if key not in known:
            raise at.error(
                f"unknown key '{key}'; {_suggest(str(key), known)}{extra}; rename or remove it", str(key), found=key
            )


def _require_mapping(value: Any, at: _Where, what: str, key: str | None = None) -> Mapping[Any, Any]:
    if not isinstance(value, Mapping):
        raise at.error(f"found {type(value).__name__} {value!r}, expected {what}; fix its layout", key, found=value)
    return value


def _text(data: Mapping[Any, Any], key: str, at: _Where, default: str | None = None) -> str:
    value = data.get(key, default)
    if value is None:
        raise at.error("missing; add it", key)
    if not isinstance(value, str) or not value.strip():
        raise at.error(f"found {value!r}, expected non-empty text; fix the value", key, found=value)
    return value.strip()


def _integer(data: Mapping[Any, Any], key: str, at: _Where, lo: int, hi: int, default: int | None = None) -> int:
    value = data.get(key, default)
    if value is None:
        raise at.error(f"missing; add an integer {lo}-{hi}", key)
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise at.error(f"found {value!r}, expected an integer {lo}-{hi}; fix the value", key, found=value)
    return value


def _choice(data: Mapping[Any, Any], key: str, at: _Where, choices: Sequence[str], default: str) -> str:
    value = data.get(key, default)
    if value not in choices:
        raise at.error(f"found {value!r}, {_suggest(str(value), choices)}; use one of these", key, found=value)
    return str(value)


def _number(data: Mapping[Any, Any], key: str, at: _Where, default: float, nonzero: bool = False) -> float:
    value = data.get(key, default)
    number = as_number(value)
    if number is None or not math.isfinite(number) or (nonzero and number == 0.0):
        expected = "a finite non-zero number" if nonzero else "a finite number"
        raise at.error(f"found {value!r}, expected {expected}; fix the value", key, found=value)
    return number


def _seconds(data: Mapping[Any, Any], key: str, at: _Where) -> float:
    value = data.get(key, _DEFAULT_TIMEOUT)
    number = as_number(value)
    if number is None and isinstance(value, str):
        ureg = registry()
        try:
            check_unit_text(value)
            number = float(ureg.Quantity(normalise(value)).to("s").magnitude)
        except unit_text_errors():
            number = None
    if number is None or not math.isfinite(number) or number <= 0.0:
        raise at.error(
            f"found {value!r}, expected a positive time such as 0.2 (s) or '200 ms'; fix the value", key, found=value
        )
    return number


def _line_format(value: Any, at: _Where) -> LineFormat:
    data = _require_mapping(value, at, "a mapping with 'delimiter' and 'fields', or 'regex'", "format")
    fmt_at = at.at(f"{at.item}.format")
    _check_keys(data, _FORMAT_KEYS, fmt_at)
    if "regex" in data:
        if "fields" in data or "delimiter" in data:
            raise fmt_at.error(
                "found both 'regex' and 'delimiter'/'fields', expected one of the two; keep one", "regex"
            )
        regex = _text(data, "regex", fmt_at)
        try:
            pattern = _compiled(regex)
        except re.error as err:
            raise fmt_at.error(f"found {regex!r}, not a valid regular expression ({err}); fix it", "regex") from err
        if not pattern.groupindex:
            raise fmt_at.error(
                f"found {regex!r} without named groups, expected groups such as (?P<current>...); name the fields",
                "regex",
            )
        return LineFormat(regex=regex)
    if "fields" not in data:
        raise fmt_at.error("missing; give 'fields' (with 'delimiter', default ',') or 'regex'", "fields")
    delimiter = data.get("delimiter", ",")
    if not isinstance(delimiter, str) or delimiter == "":
        raise fmt_at.error(f"found {delimiter!r}, expected a non-empty separator such as ','", "delimiter")
    names = data["fields"]
    if not isinstance(names, list) or not names:
        raise fmt_at.error(f"found {names!r}, expected a non-empty list of field names", "fields")
    for name in names:
        if not isinstance(name, str) or not _FREE_NAME.match(name) or names.count(name) > 1:
            raise fmt_at.error(
                f"found {name!r}, expected unique names matching [A-Za-z_][A-Za-z0-9_]*; rename it", "fields"
            )
    return LineFormat(delimiter=delimiter, fields=tuple(names))


def _device(name: str, value: Any, at: _Where) -> Device:
    data = _require_mapping(value, at, f"a mapping with 'type' ({', '.join(DEVICE_TYPES)}) and its settings")
    kind = data.get("type")
    if kind is None:
        raise at.error(f"missing; add one of {', '.join(DEVICE_TYPES)}", "type")
    if kind not in DEVICE_TYPES:
        raise at.error(f"found {kind!r}, {_suggest(str(kind), DEVICE_TYPES)}; use one of these", "type", found=kind)
    _check_keys(data, _DEVICE_KEYS[kind], at, f" for a {kind} device")
    for key in _DEVICE_REQUIRED[kind]:
        if key not in data:
            raise at.error(f"missing; a {kind} device needs {', '.join(_DEVICE_REQUIRED[kind])}", key)
    timeout = _seconds(data, "timeout", at)
    if kind == "modbus_tcp":
        return ModbusTcpDevice(
            name=name,
            host=_text(data, "host", at),
            port=_integer(data, "port", at, 1, 65535),
            unit=_integer(data, "unit", at, 0, 247, 1),
            timeout=timeout,
        )
    port = _text(data, "port", at)
    baud = _integer(data, "baud", at, 1, 100_000_000)
    if kind == "modbus_rtu":
        parity = data.get("parity", "N")
        if parity not in PARITIES:
            raise at.error(f"found {parity!r}, expected N, E or O; use one of these", "parity", found=parity)
        stopbits = data.get("stopbits", 1)
        if stopbits not in (1, 2) or isinstance(stopbits, bool):
            raise at.error(f"found {stopbits!r}, expected 1 or 2; fix the value", "stopbits", found=stopbits)
        return ModbusRtuDevice(
            name=name,
            port=port,
            baud=baud,
            parity=parity,
            stopbits=int(stopbits),
            bytesize=_integer(data, "bytesize", at, 7, 8, 8),
            unit=_integer(data, "unit", at, 0, 247, 1),
            timeout=timeout,
        )
    return SerialLinesDevice(name=name, port=port, baud=baud, format=_line_format(data["format"], at), timeout=timeout)


def _channel(index: int, value: Any, devices: Mapping[str, Device], at: _Where) -> Channel:
    at = at.at(f"channels[{index}]")
    data = _require_mapping(value, at, "a mapping with 'column', 'device' and a 'register' or 'field'")
    _check_keys(data, _CHANNEL_KEYS, at)
    column = _text(data, "column", at)
    at = at.at(f"channels[{index}] ('{column}')")
    if column == "time":
        raise at.error(
            "found 'time', which the recorder stamps itself and is never read from a device; remove this channel",
            "column",
            found=column,
        )
    if column not in CHANNEL_COLUMNS and not _FREE_NAME.match(column):
        raise at.error(
            f"found {column!r}, expected one of {', '.join(CHANNEL_COLUMNS)} or a name matching "
            "[A-Za-z_][A-Za-z0-9_]*; rename it",
            "column",
            found=column,
        )
    device_name = _text(data, "device", at)
    if device_name not in devices:
        known = tuple(devices)
        raise at.error(
            f"found {device_name!r}, which is not a device of this rig; {_suggest(device_name, known)}; "
            "fix the name or add the device under 'devices'",
            "device",
            found=device_name,
        )
    device = devices[device_name]
    serial = isinstance(device, SerialLinesDevice)
    allowed = _SERIAL_CHANNEL_KEYS if serial else _MODBUS_CHANNEL_KEYS
    for key in data:
        if key not in allowed:
            use = "'field'" if serial else "'register'"
            raise at.error(
                f"does not apply: device '{device_name}' is {device.type}; use {use} and "
                f"{', '.join(k for k in allowed if k not in ('column', 'device'))}",
                str(key),
            )
    scale = _number(data, "scale", at, 1.0, nonzero=True)
    offset = _number(data, "offset", at, 0.0)
    unit = data.get("unit", _default_unit(column))
    if not isinstance(unit, str) or not unit.strip():
        raise at.error(f"found {unit!r}, expected a unit such as 'N*m', 'rpm' or 'degC'", "unit", found=unit)
    conversion = _conversion(unit.strip(), column)
    if isinstance(conversion, str):
        raise at.error(conversion, "unit", found=unit)
    if serial:
        assert isinstance(device, SerialLinesDevice)
        if "field" not in data:
            raise at.error(
                f"missing; a channel of serial_lines device '{device_name}' names one of its fields "
                f"({', '.join(device.format.names)})",
                "field",
            )
        name = data["field"]
        if name not in device.format.names:
            raise at.error(
                f"found {name!r}, which is not a field of device '{device_name}'; "
                f"{_suggest(str(name), device.format.names)}; fix the name or the device's format",
                "field",
                found=name,
            )
        return Channel(column=column, device=device_name, field=str(name), scale=scale, offset=offset, unit=unit)
    if "register" not in data:
        raise at.error(
            f"missing; a channel of Modbus device '{device_name}' needs a register address 0-65535", "register"
        )
    register = _integer(data, "register", at, 0, MAX_REGISTER)
    dtype = _choice(data, "dtype", at, tuple(DTYPES), "int16")
    if register + DTYPES[dtype][1] - 1 > MAX_REGISTER:
        raise at.error(
            f"found {register}, but {dtype} needs 2 registers and the last address is {MAX_REGISTER}; fix the address",
            "register",
            found=register,
        )
    return Channel(
        column=column,
        device=device_name,
        register=register,
        kind=_choice(data, "kind", at, KINDS, "holding"),
        dtype=dtype,
        word_order=_choice(data, "word_order", at, ORDERS, "big"),
        byte_order=_choice(data, "byte_order", at, ORDERS, "big"),
        scale=scale,
        offset=offset,
        unit=unit.strip(),
    )


def rig_from_mapping(data: Any, source: str | None = None) -> Rig:
    """Validate a parsed rig mapping (schema hound-id/rig/1).

    Args:
        data: The parsed YAML.
        source: File name, for messages.

    Raises:
        SpecError: Unknown keys, missing or invalid fields, unknown devices, duplicate or missing columns.
    """
    at = _Where(source)
    data = _require_mapping(data, at, "a mapping with schema, name, devices and channels")
    _check_keys(data, _TOP_KEYS, at)
    schema = data.get("schema", SCHEMA)
    if schema != SCHEMA:
        raise at.error(f"found {schema!r}, expected {SCHEMA!r}; fix the schema line", "schema", found=schema)
    name = _text(data, "name", at)
    raw_devices = _require_mapping(data.get("devices"), at, "a mapping of device name -> device", "devices")
    if not raw_devices:
        raise at.error("empty; add at least one device", "devices")
    devices: dict[str, Device] = {}
    for dev_name, dev in raw_devices.items():
        if not isinstance(dev_name, str) or not dev_name.strip():
            raise at.error(f"found device name {dev_name!r}, expected non-empty text; rename it", "devices")
        devices[dev_name] = _device(dev_name, dev, at.at(f"devices.{dev_name}"))
    raw_channels = data.get("channels")
    if not isinstance(raw_channels, list) or not raw_channels:
        raise at.error(f"found {raw_channels!r}, expected a non-empty list of channels; add them", "channels")
    channels: list[Channel] = []
    seen: dict[str, int] = {}
    for index, value in enumerate(raw_channels):
        ch = _channel(index, value, devices, at)
        if ch.column in seen:
            raise at.at(f"channels[{index}] ('{ch.column}')").error(
                f"found {ch.column!r}, already read by channels[{seen[ch.column]}]; each column is read once, "
                "remove or rename one",
                "column",
                found=ch.column,
            )
        seen[ch.column] = index
        channels.append(ch)
    for column in REQUIRED_COLUMNS:
        if column not in seen:
            free = [c for c in seen if c not in CHANNEL_COLUMNS]
            close = difflib.get_close_matches(column, free, n=1)
            hint = f" (is '{close[0]}' meant to be '{column}'?)" if close else ""
            raise at.error(
                f"no '{column}' channel{hint}; expected channels for {' and '.join(REQUIRED_COLUMNS)}; add one",
                "channels",
            )
    return Rig(name=name, devices=devices, channels=tuple(channels), source=source)


def rig_to_mapping(rig: Rig) -> dict[str, Any]:
    """The rig as a YAML-ready mapping that :func:`rig_from_mapping` reads back to an equal rig."""
    devices: dict[str, Any] = {}
    for name, dev in rig.devices.items():
        entry: dict[str, Any] = {"type": dev.type}
        for f in dataclasses.fields(dev):
            if f.name == "name":
                continue
            value = getattr(dev, f.name)
            if isinstance(value, LineFormat):
                value = (
                    {"regex": value.regex}
                    if value.regex is not None
                    else {
                        "delimiter": value.delimiter,
                        "fields": list(value.fields or ()),
                    }
                )
            entry[f.name] = value
        devices[name] = entry
    channels: list[dict[str, Any]] = []
    for ch in rig.channels:
        item: dict[str, Any] = {"column": ch.column, "device": ch.device}
        if ch.is_modbus:
            item.update(
                register=ch.register,
                kind=ch.kind,
                dtype=ch.dtype,
                word_order=ch.word_order,
                byte_order=ch.byte_order,
            )
        else:
            item["field"] = ch.field
        item.update(scale=ch.scale, offset=ch.offset, unit=ch.unit)
        channels.append(item)
    return {"schema": SCHEMA, "name": rig.name, "devices": devices, "channels": channels}
