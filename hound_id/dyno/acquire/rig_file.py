"""The rig file (YAML, ``hound-id/rig/1``) to a :class:`~hound_id.dyno.acquire.rig.Rig` and back: its keys per device
type and per channel, each checked with a one-line error naming the device or channel and the field."""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from hound_id.dyno.acquire.rig import (
    CHANNEL_COLUMNS,
    DEFAULT_TIMEOUT,
    DEVICE_TYPES,
    DTYPES,
    KINDS,
    MAX_REGISTER,
    ORDERS,
    PARITIES,
    REQUIRED_COLUMNS,
    SCHEMA,
    Channel,
    Device,
    LineFormat,
    ModbusRtuDevice,
    ModbusTcpDevice,
    Rig,
    SerialLinesDevice,
    compiled_pattern,
    default_unit,
    unit_conversion,
)
from hound_id.errors import SpecError
from hound_id.io import read_yaml
from hound_id.units import as_number, check_unit_text, normalise, registry, unit_text_errors

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
    value = data.get(key, DEFAULT_TIMEOUT)
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
            pattern = compiled_pattern(regex)
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
    unit = data.get("unit", default_unit(column))
    if not isinstance(unit, str) or not unit.strip():
        raise at.error(f"found {unit!r}, expected a unit such as 'N*m', 'rpm' or 'degC'", "unit", found=unit)
    conversion = unit_conversion(unit.strip(), column)
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
