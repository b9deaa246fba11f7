"""A rig's channels: which device gives a log column, where the value is, and how it decodes to SI.

**Values.** A channel's value in hound-id units is ``(raw * scale + offset)`` read in
``unit`` and converted to the column's unit: SI for current, torque, velocity, position
and bus_voltage, degC for temperature (as in :mod:`hound_id.dyno.logs`). Free column names
convert to the SI base units of their ``unit`` (degC for temperatures). The conversion is
folded once into :attr:`Channel.si_factor` and :attr:`Channel.si_offset`.

**Where the value is.** A Modbus channel names a register (:attr:`Channel.register` and its kind, type and
orders), a serial_lines channel a field of the device's lines (:attr:`Channel.field`); a device type that
addresses its channels by other keys keeps them in :attr:`Channel.address` (see
:mod:`hound_id.dyno.acquire.device`).

**Registers.** A 32-bit value spans two registers. ``word_order: big`` puts the most
significant register first; ``byte_order: big`` is the Modbus byte order inside a register
(high byte first), ``little`` swaps the two bytes of every register.

**Reads.** :func:`merge_reads` merges the registers of one device and one register kind into
blocks, each read with one request: a block may skip up to :data:`MAX_GAP` unused registers
and holds at most :data:`MAX_BLOCK` registers (the Modbus limit for one read).

pymodbus and pyserial are not imported here; decoding uses :mod:`struct`.
"""

from __future__ import annotations

import dataclasses
import math
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from types import MappingProxyType
from typing import Any

from hound_id.dyno.logs import CANONICAL, UNITS
from hound_id.errors import DynoDataError, SpecError
from hound_id.units import check_unit_text, normalise, registry, unit_text_errors

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
    address: Mapping[str, Any] = dataclasses.field(default_factory=dict, hash=False)
    """Where the value is, for a device type whose channels name it by other keys than a register or a line
    field: its channel keys and their values (read-only; empty for Modbus and serial_lines channels)."""
    si_unit: str = dataclasses.field(init=False)
    """Unit of the decoded value: the column's hound-id unit (SI; degC for temperature)."""
    si_factor: float = dataclasses.field(init=False)
    """Value in ``si_unit`` = raw * si_factor + si_offset [si_unit / raw count]."""
    si_offset: float = dataclasses.field(init=False)
    """See ``si_factor`` [si_unit]."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "address", MappingProxyType(dict(self.address)))
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

    def key(self, name: str) -> Any:
        """The value of channel key ``name`` of the rig file: an entry of :attr:`address`, else the attribute
        (register, kind, dtype, word_order, byte_order, field, scale, offset, unit)."""
        return self.address[name] if name in self.address else getattr(self, name)

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
