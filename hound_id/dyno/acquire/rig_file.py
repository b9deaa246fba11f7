"""The rig file (YAML, ``hound-id/rig/1``) to a :class:`~hound_id.dyno.acquire.rig.Rig` and back: the device blocks
and the channels of every registered device type (:data:`~hound_id.dyno.acquire.rig.DEVICE_TYPES`: its settings,
its channel keys), each checked with a one-line error naming the file, the device or channel and the field."""

from __future__ import annotations

import difflib
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from hound_id.dyno.acquire.channel import CHANNEL_COLUMNS, REQUIRED_COLUMNS, Channel, default_unit, unit_conversion
from hound_id.dyno.acquire.device import (
    Device,
    Where,
    check_keys,
    check_number,
    check_text,
    require_mapping,
    suggest,
)
from hound_id.dyno.acquire.rig import DEVICE_TYPES, SCHEMA, Rig, device_type
from hound_id.io import read_yaml

_FREE_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_TOP_KEYS = ("channels", "devices", "name", "schema")


def load_rig(path: str | Path) -> Rig:
    """Read and validate a rig YAML file (schema hound-id/rig/1).

    Raises:
        SpecError: The file is missing, not YAML, or not a valid rig (see :func:`rig_from_mapping`).
    """
    return rig_from_mapping(read_yaml(path, "rig"), source=str(path))


def _device(name: str, value: Any, at: Where) -> Device:
    types = ", ".join(DEVICE_TYPES)
    data = require_mapping(value, at, f"a mapping with 'type' ({types}) and its settings")
    kind = data.get("type")
    if kind is None:
        raise at.error(f"missing; add one of {types}", "type")
    if not isinstance(kind, str) or kind not in DEVICE_TYPES:
        raise at.error(
            f"found {kind!r}, {suggest(str(kind), tuple(DEVICE_TYPES))}; use one of these", "type", found=kind
        )
    declared = DEVICE_TYPES[kind]
    check_keys(data, declared.keys, at, f" for a {kind} device")
    required = [s.key for s in declared.settings if s.required]
    for key in required:
        if key not in data:
            raise at.error(f"missing; a {kind} device needs {', '.join(required)}", key)
    values = {s.key: s.parse(data[s.key], at.field(s.key)) if s.key in data else s.default for s in declared.settings}
    device: Device = declared.device(name=name, **values)
    return device


def _channel_keys() -> tuple[str, ...]:
    """Every key a channel may hold, whatever its device's type (in registry order)."""
    return tuple(dict.fromkeys(k for kind in DEVICE_TYPES.values() for k in kind.channel_keys))


def _column(data: Mapping[Any, Any], at: Where) -> str:
    column = check_text(data.get("column"), at.field("column"))
    where = at.at(f"{at.item} ('{column}')")
    if column == "time":
        raise where.error(
            "found 'time', which the recorder stamps itself and is never read from a device; remove this channel",
            "column",
            found=column,
        )
    if column not in CHANNEL_COLUMNS and not _FREE_NAME.match(column):
        raise where.error(
            f"found {column!r}, expected one of {', '.join(CHANNEL_COLUMNS)} or a name matching "
            "[A-Za-z_][A-Za-z0-9_]*; rename it",
            "column",
            found=column,
        )
    return column


def _channel(index: int, value: Any, devices: Mapping[str, Device], at: Where) -> Channel:
    at = at.at(f"channels[{index}]")
    data = require_mapping(value, at, "a mapping with 'column', 'device' and a 'register' or 'field'")
    check_keys(data, _channel_keys(), at)
    column = _column(data, at)
    at = at.at(f"channels[{index}] ('{column}')")
    device_name = check_text(data.get("device"), at.field("device"))
    if device_name not in devices:
        raise at.error(
            f"found {device_name!r}, which is not a device of this rig; {suggest(device_name, tuple(devices))}; "
            "fix the name or add the device under 'devices'",
            "device",
            found=device_name,
        )
    device = devices[device_name]
    kind = device_type(device)
    allowed = kind.channel_keys
    for key in data:
        if key not in allowed:
            raise at.error(
                f"does not apply: device '{device_name}' is {device.type}; use '{kind.channels.keys[0]}' and "
                f"{', '.join(k for k in allowed if k not in ('column', 'device'))}",
                str(key),
            )
    scale = check_number(data.get("scale", 1.0), at.field("scale"), nonzero=True)
    offset = check_number(data.get("offset", 0.0), at.field("offset"))
    unit = data.get("unit", default_unit(column))
    if not isinstance(unit, str) or not unit.strip():
        raise at.error(f"found {unit!r}, expected a unit such as 'N*m', 'rpm' or 'degC'", "unit", found=unit)
    conversion = unit_conversion(unit.strip(), column)
    if isinstance(conversion, str):
        raise at.error(conversion, "unit", found=unit)
    address = kind.channels.parse(data, device, at)
    return Channel(column=column, device=device_name, scale=scale, offset=offset, unit=unit.strip(), **address)


def rig_from_mapping(data: Any, source: str | None = None) -> Rig:
    """Validate a parsed rig mapping (schema hound-id/rig/1).

    Args:
        data: The parsed YAML.
        source: File name, for messages.

    Raises:
        SpecError: Unknown keys, missing or invalid fields, unknown devices, duplicate or missing columns.
    """
    at = Where(source)
    data = require_mapping(data, at, "a mapping with schema, name, devices and channels")
    check_keys(data, _TOP_KEYS, at)
    schema = data.get("schema", SCHEMA)
    if schema != SCHEMA:
        raise at.error(f"found {schema!r}, expected {SCHEMA!r}; fix the schema line", "schema", found=schema)
    name = check_text(data.get("name"), at.field("name"))
    raw_devices = require_mapping(data.get("devices"), at, "a mapping of device name -> device", "devices")
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
        devices[name] = {"type": dev.type, **{s.key: s.dump(getattr(dev, s.key)) for s in device_type(dev).settings}}
    channels: list[dict[str, Any]] = []
    for ch in rig.channels:
        keys = device_type(rig.devices[ch.device]).channels.keys
        item: dict[str, Any] = {"column": ch.column, "device": ch.device, **{k: ch.key(k) for k in keys}}
        item.update(scale=ch.scale, offset=ch.offset, unit=ch.unit)
        channels.append(item)
    return {"schema": SCHEMA, "name": rig.name, "devices": devices, "channels": channels}
