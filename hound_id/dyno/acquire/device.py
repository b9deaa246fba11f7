"""What a transport declares to be a device type of the rig file (:class:`DeviceType`), and the checks of its keys.

A device type is one value, written beside its transport class in the transport's own module
(:mod:`~hound_id.dyno.acquire.modbus`, :mod:`~hound_id.dyno.acquire.serial_lines`) and registered with one
:func:`hound_id.dyno.acquire.rig.register` call:

- its ``name``, the ``type:`` of a device block in the rig file;
- its ``device``: a frozen dataclass with a ``type`` class variable (the name), ``name`` (the device's name in
  the file) and one field per setting;
- its ``settings``: the other keys of the device block, each a :class:`Setting` (its key, how a value is
  checked and converted to SI, its default, how it is written back); :func:`text`, :func:`integer`,
  :func:`seconds` and :func:`one_of` make the usual ones, and a bad value is a one-line :class:`SpecError`
  naming the file, the device, the field, what was found, what was expected and how to fix it;
- its ``channels``: how a channel of such a device says where its value is (:class:`Addressing`: the channel
  keys and the function that checks them; :func:`keyed` makes one from settings, whose values land in
  :attr:`~hound_id.dyno.acquire.channel.Channel.address`);
- its ``transport``: the class that reads it (:class:`Transport`: ``open``, ``read``, ``close``, built from the
  devices of one connection and their channels), and which devices share a connection (``connection``).

Nothing here imports a protocol library.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
from collections.abc import Callable, Hashable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from hound_id.dyno.acquire.channel import Channel
from hound_id.errors import SpecError
from hound_id.units import as_number, check_unit_text, normalise, registry, unit_text_errors

#: Response or read timeout of a device when its block gives none [s].
DEFAULT_TIMEOUT = 0.2
#: Keys every channel has, whatever its device's type; a device type's channel keys come between
#: ``device`` and ``scale`` in the rig file's key lists.
COMMON_CHANNEL_KEYS: tuple[str, ...] = ("column", "device", "scale", "offset", "unit")
#: What a device type's name looks like.
TYPE_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


class Where:
    """A place in a rig file (the file, a device or channel, a key) that builds the one-line messages
    ``file: item: field 'key': text``."""

    def __init__(self, source: str | None, item: str | None = None, key: str | None = None) -> None:
        self.source = source or "rig"
        self.item = item
        self.key = key

    def at(self, item: str) -> Where:
        """Another item of the same file."""
        return Where(self.source, item)

    def field(self, key: str) -> Where:
        """A key of the same item."""
        return Where(self.source, self.item, key)

    def error(self, text: str, key: str | None = None, **details: Any) -> SpecError:
        """The error ``file: item: field 'key': text`` (``key`` defaults to this place's key)."""
        key = key or self.key
        parts = [self.source, self.item, f"field '{key}'" if key else None, text]
        return SpecError(": ".join(p for p in parts if p), field=key, item=self.item, **details)

    def bad(self, value: Any, expected: str) -> SpecError:
        """The error for a bad value here: ``found <value>, <expected; how to fix>``."""
        return self.error(f"found {value!r}, {expected}", found=value)


def suggest(key: str, known: Sequence[str]) -> str:
    """'did you mean ...? expected one of ...' for a name not in ``known``."""
    close = difflib.get_close_matches(key, list(known), n=1)
    hint = f"did you mean '{close[0]}'? " if close else ""
    return f"{hint}expected one of {', '.join(known)}"


def check_keys(data: Mapping[Any, Any], known: Sequence[str], at: Where, extra: str = "") -> None:
    """Refuse a key of ``data`` not in ``known`` (with a 'did you mean')."""
    for key in data:
        if key not in known:
            raise at.error(
                f"unknown key '{key}'; {suggest(str(key), known)}{extra}; rename or remove it", str(key), found=key
            )


def require_mapping(value: Any, at: Where, what: str, key: str | None = None) -> Mapping[Any, Any]:
    """``value`` if it is a mapping; else the error 'found ..., expected <what>'."""
    if not isinstance(value, Mapping):
        raise at.error(f"found {type(value).__name__} {value!r}, expected {what}; fix its layout", key, found=value)
    return value


def check_text(value: Any, at: Where) -> str:
    """Non-empty text, stripped."""
    if value is None:
        raise at.error("missing; add it")
    if not isinstance(value, str) or not value.strip():
        raise at.bad(value, "expected non-empty text; fix the value")
    return value.strip()


def check_integer(value: Any, at: Where, lo: int, hi: int) -> int:
    """An integer from ``lo`` to ``hi`` (not a bool)."""
    if value is None:
        raise at.error(f"missing; add an integer {lo}-{hi}")
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise at.bad(value, f"expected an integer {lo}-{hi}; fix the value")
    return value


def check_choice(value: Any, at: Where, choices: Sequence[str]) -> str:
    """One of ``choices`` (with a 'did you mean')."""
    if value not in choices:
        raise at.bad(value, f"{suggest(str(value), choices)}; use one of these")
    return str(value)


def check_number(value: Any, at: Where, nonzero: bool = False) -> float:
    """A finite number (non-zero if asked); text such as '1e-3' is read as a number."""
    number = as_number(value)
    if number is None or not math.isfinite(number) or (nonzero and number == 0.0):
        raise at.bad(value, f"expected {'a finite non-zero number' if nonzero else 'a finite number'}; fix the value")
    return number


def check_seconds(value: Any, at: Where) -> float:
    """A positive time [s]: a number of seconds or a quantity with a unit ('200 ms')."""
    number = as_number(value)
    if number is None and isinstance(value, str):
        ureg = registry()
        try:
            check_unit_text(value)
            number = float(ureg.Quantity(normalise(value)).to("s").magnitude)
        except unit_text_errors():
            number = None
    if number is None or not math.isfinite(number) or number <= 0.0:
        raise at.bad(value, "expected a positive time such as 0.2 (s) or '200 ms'; fix the value")
    return number


def _same(value: Any) -> Any:
    return value


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


#: The default of a :class:`Setting` that a device block must give.
REQUIRED: Any = _Required()


@dataclass(frozen=True)
class Setting:
    """One key of a device block: its check, its default, and how it is written back."""

    key: str
    """Key in the device block and field of the device dataclass."""
    parse: Callable[[Any, Where], Any]
    """(value found in the file, where it is) -> the field's value (SI); raises ``where.bad(...)`` or
    ``where.error(...)``, a one-line :class:`SpecError`, for a bad value."""
    default: Any = REQUIRED
    """The field's value when the key is left out; :data:`REQUIRED` makes the key required."""
    dump: Callable[[Any], Any] = _same
    """The field's value -> what the rig file holds (plain YAML)."""

    @property
    def required(self) -> bool:
        """Whether a device block must give the key."""
        return self.default is REQUIRED


def text(key: str) -> Setting:
    """A required non-empty text (stripped): a host, a port name."""
    return Setting(key, check_text)


def integer(key: str, lo: int, hi: int, default: int | None = None) -> Setting:
    """An integer from ``lo`` to ``hi``; required unless a ``default`` is given."""
    return Setting(key, lambda value, at: check_integer(value, at, lo, hi), REQUIRED if default is None else default)


def seconds(key: str = "timeout", default: float = DEFAULT_TIMEOUT) -> Setting:
    """A positive time [s], given as seconds or with a unit ('200 ms')."""
    return Setting(key, check_seconds, default)


def one_of(key: str, values: Sequence[Any], default: Any, expected: str) -> Setting:
    """One of ``values`` (a bool is none of them); ``expected`` ends the message, e.g. 'expected 1 or 2; fix
    the value'. The value kept is the listed one (1.0 given for 1 is kept as 1)."""
    listed = tuple(values)

    def parse(value: Any, at: Where) -> Any:
        if isinstance(value, bool) or value not in listed:
            raise at.bad(value, expected)
        return listed[listed.index(value)]

    return Setting(key, parse, default)


#: (the channel's mapping in the file, its device, where it is) -> the channel's address: keyword arguments of
#: :class:`~hound_id.dyno.acquire.channel.Channel` (``register=``... for Modbus, ``field=`` for serial lines,
#: ``address=`` for the others).
AddressParser = Callable[[Mapping[Any, Any], Any, Where], dict[str, Any]]


@dataclass(frozen=True)
class Addressing:
    """How a channel of a device type says where its value is."""

    keys: tuple[str, ...]
    """Its channel keys besides column, device, scale, offset and unit; the main one first."""
    parse: AddressParser
    """Checks those keys of one channel (one-line errors through the ``Where``) and returns the channel's address."""


def keyed(*settings: Setting) -> Addressing:
    """Addressing by the keys of ``settings``, each checked by its setting; the values go to ``Channel.address``.
    A required key left out is 'missing; a channel of <type> device '<name>' needs <keys>'."""
    keys = tuple(s.key for s in settings)

    def parse(data: Mapping[Any, Any], device: Any, at: Where) -> dict[str, Any]:
        address = {}
        for s in settings:
            if s.key in data:
                address[s.key] = s.parse(data[s.key], at.field(s.key))
            elif s.required:
                needs = ", ".join(r.key for r in settings if r.required)
                raise at.error(f"missing; a channel of {device.type} device '{device.name}' needs {needs}", s.key)
            else:
                address[s.key] = s.default
        return {"address": address}

    return Addressing(keys, parse)


class Device(Protocol):
    """A device of a rig: a frozen dataclass of its device type."""

    @property
    def type(self) -> str:
        """The device type's name."""

    @property
    def name(self) -> str:
        """The device's name in the rig file."""


class Transport(Protocol):
    """What the recorder reads a connection with: built from the devices that share it (file order) and their
    channels (file order); ``read`` returns every channel's value [SI] by column or raises
    :class:`~hound_id.dyno.acquire.recorder.ReadError` (a timeout, a disconnect, a malformed reply)."""

    @property
    def label(self) -> str:
        """The connection, as read errors and the sidecar's error counts name it ('Modbus 127.0.0.1:5020')."""

    @property
    def errors(self) -> int:
        """Failed or malformed reads so far."""

    def open(self) -> None:
        """Connect (may raise ReadError: reads try again)."""

    def read(self) -> dict[str, float]:
        """One sample of every channel [SI], by column."""

    def close(self) -> None:
        """Disconnect; ``read`` after ``close`` opens again."""


def _own(device: Any) -> Hashable:
    return device.name


@dataclass(frozen=True)
class DeviceType:
    """A device type of the rig file, declared by its transport: see the module's docstring."""

    name: str
    """The ``type:`` of its device blocks."""
    device: type[Any]
    """The frozen dataclass of its devices: ``type`` (class variable, = name), ``name``, one field per setting."""
    settings: tuple[Setting, ...]
    """The keys of its device block besides ``type``, in the order messages list them."""
    channels: Addressing
    """How its channels say where their value is."""
    transport: Callable[[Sequence[Any], Sequence[Channel]], Transport]
    """The transport class, built from the devices of one connection and their channels."""
    connection: Callable[[Any], Hashable] = _own
    """Devices of this type with equal keys share one transport (default: each device its own)."""

    @property
    def keys(self) -> tuple[str, ...]:
        """Every key its device block may hold."""
        return ("type", *(s.key for s in self.settings))

    @property
    def channel_keys(self) -> tuple[str, ...]:
        """Every key a channel of such a device may hold, in the order messages list them."""
        return ("column", "device", *self.channels.keys, "scale", "offset", "unit")

    def check(self) -> None:
        """Refuse a declaration whose parts do not fit together.

        Raises:
            SpecError: A bad name, a device class that is not a frozen dataclass with the fields of the settings,
                a repeated or reserved key, or no channel key.
        """
        where = f"device type '{self.name}'"
        if not isinstance(self.name, str) or not TYPE_NAME.match(self.name):
            raise SpecError(f"{where}: expected a name matching [a-z][a-z0-9_]*; rename it")
        params = getattr(self.device, "__dataclass_params__", None)
        if params is None or not params.frozen or getattr(self.device, "type", None) != self.name:
            raise SpecError(
                f"{where}: its device class {getattr(self.device, '__name__', self.device)!r} must be a frozen "
                f"dataclass with the class variable type = {self.name!r}; fix the class"
            )
        fields = [f.name for f in dataclasses.fields(self.device) if f.init]
        keys = [s.key for s in self.settings]
        if len(set(keys)) != len(keys) or {"type", "name"} & set(keys) or sorted(fields) != sorted(["name", *keys]):
            raise SpecError(
                f"{where}: its settings ({', '.join(keys)}) must be the fields of {self.device.__name__} besides "
                f"name ({', '.join(f for f in fields if f != 'name')}), each once, none called type or name"
            )
        address = self.channels.keys
        if not address or len(set(address)) != len(address) or set(address) & set(COMMON_CHANNEL_KEYS):
            raise SpecError(
                f"{where}: its channel keys ({', '.join(address) or 'none'}) must be one or more distinct keys "
                f"other than {', '.join(COMMON_CHANNEL_KEYS)}"
            )
