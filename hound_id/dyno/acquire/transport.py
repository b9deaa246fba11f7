"""Transports: how the recorder reads a rig's devices, one transport per connection (:func:`transports_for`),
all of them as one ``read_sample()`` (:class:`RigReader`).

Each transport serves the channels of one connection and returns their values in SI
(:meth:`~hound_id.dyno.acquire.device.Transport.read`), or raises
:class:`~hound_id.dyno.acquire.recorder.ReadError` on a timeout, an exception response, a disconnect or a
malformed line. Which class reads a device, and which devices share a connection, its device type says
(:data:`~hound_id.dyno.acquire.rig.DEVICE_TYPES`, the one registry, which :data:`TRANSPORTS` names too): Modbus
devices behind one TCP host and port or on one RS-485 port share a client
(:mod:`~hound_id.dyno.acquire.modbus`), a serial line console is read by its own thread
(:mod:`~hound_id.dyno.acquire.serial_lines`).
"""

from __future__ import annotations

from collections.abc import Hashable

from hound_id.dyno.acquire.device import Device, Transport
from hound_id.dyno.acquire.modbus import ModbusTransport, block_decoder
from hound_id.dyno.acquire.recorder import ReadError
from hound_id.dyno.acquire.rig import DEVICE_TYPES, Rig, device_type
from hound_id.dyno.acquire.serial_lines import SerialLinesTransport

__all__ = [
    "TRANSPORTS",
    "ModbusTransport",
    "RigReader",
    "SerialLinesTransport",
    "Transport",
    "block_decoder",
    "transports_for",
]

#: The device types by name (sorted), each with its transport class: the registry of
#: :mod:`~hound_id.dyno.acquire.rig` (the same dict), under the name the recorder's side knows it by.
TRANSPORTS = DEVICE_TYPES


def transports_for(rig: Rig) -> list[Transport]:
    """One transport per connection of the rig that has channels.

    Devices whose device types give them the same connection share a transport, built from those devices and
    their channels in file order. Transports come class by class, in the registry order of each class's first
    device type (the built-in ones: Modbus, then serial lines), connections of one class in file order.
    """
    groups: dict[tuple[str, Hashable], list[Device]] = {}
    for device in rig.devices.values():
        kind = device_type(device)
        groups.setdefault((kind.name, kind.connection(device)), []).append(device)
    first: dict[object, int] = {}  # transport class -> registry index of its first device type
    for i, kind in enumerate(DEVICE_TYPES.values()):
        first.setdefault(kind.transport, i)
    file_order = {name: i for i, name in enumerate(rig.devices)}

    def rank(key: tuple[str, Hashable]) -> tuple[int, int]:
        return first[DEVICE_TYPES[key[0]].transport], file_order[groups[key][0].name]

    out: list[Transport] = []
    for key in sorted(groups, key=rank):
        members = {d.name for d in groups[key]}
        channels = [c for c in rig.channels if c.device in members]
        if channels:
            out.append(DEVICE_TYPES[key[0]].transport(groups[key], channels))
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
        return {t.label: t.errors for t in self.transports}
