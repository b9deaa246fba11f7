"""A toy transport in one file: ``udp_query``, a device on a UDP port that answers a query with one line of
numbers. Importing this file registers it (its last line), as a user's transport file would.

The client sends ``<query> <n>`` (n counts the reads); the device answers ``<n> <v0> <v1> ...``. A channel names
the position of its number in that list (``index``); a reply to an earlier query (late, after a timeout) is
skipped. Device block: ``{type: udp_query, host: 127.0.0.1, port: 9000, query: READ, timeout: 0.5}``.
"""

from __future__ import annotations

import re
import socket
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

from hound_id.dyno.acquire.channel import Channel
from hound_id.dyno.acquire.device import (
    DEFAULT_TIMEOUT,
    DeviceType,
    Setting,
    Where,
    integer,
    keyed,
    seconds,
    text,
)
from hound_id.dyno.acquire.recorder import ReadError
from hound_id.dyno.acquire.rig import register

#: Most numbers in one answer.
MAX_VALUES = 64
_QUERY = re.compile(r"^[!-~]{1,32}$")


@dataclass(frozen=True)
class UdpQueryDevice:
    """A device on a UDP port that answers a query with a line of numbers."""

    type: ClassVar[str] = "udp_query"
    name: str
    """Device name in the rig file."""
    host: str
    """Host name or IP address."""
    port: int
    """UDP port, 1-65535."""
    query: str = "READ"
    """What the client sends before the read counter: 1-32 printable ASCII characters, no spaces."""
    timeout: float = DEFAULT_TIMEOUT
    """Answer timeout [s]."""


def check_query(value: Any, at: Where) -> str:
    if not isinstance(value, str) or not _QUERY.match(value):
        raise at.bad(value, "expected 1-32 printable ASCII characters without spaces, such as READ; fix the value")
    return value


class UdpQueryTransport:
    """One socket per device; a read is one query and its answer."""

    def __init__(self, devices: Sequence[UdpQueryDevice], channels: Sequence[Channel]) -> None:
        (self.device,) = devices
        self.channels = list(channels)
        self.sent = 0
        self.errors = 0
        self._sock: socket.socket | None = None

    @property
    def label(self) -> str:
        return f"udp {self.device.host}:{self.device.port}"

    def open(self) -> None:
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.connect((self.device.host, self.device.port))

    def _fail(self, why: str) -> ReadError:
        self.errors += 1
        return ReadError(f"{self.label}: {why}")

    def read(self) -> dict[str, float]:
        if self._sock is None:
            self.open()
        assert self._sock is not None
        self.sent += 1
        end = time.monotonic() + self.device.timeout
        try:
            self._sock.send(f"{self.device.query} {self.sent}".encode())
            while True:
                self._sock.settimeout(max(end - time.monotonic(), 1e-3))
                words = self._sock.recv(4096).decode("ascii", "replace").split()
                if words and words[0] == str(self.sent):
                    break  # an older answer is skipped
        except OSError as err:  # a timeout, or the port refused (ICMP)
            raise self._fail(f"no answer to read {self.sent} within {self.device.timeout:g} s ({err})") from err
        values = words[1:]
        try:
            return {ch.column: ch.raw_to_si(float(values[ch.address["index"]])) for ch in self.channels}
        except (IndexError, ValueError) as err:
            raise self._fail(f"malformed answer {' '.join(words)!r} ({err})") from err

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None


UDP_QUERY = DeviceType(
    name="udp_query",
    device=UdpQueryDevice,
    settings=(
        text("host"),
        integer("port", 1, 65535),
        Setting("query", check_query, default="READ"),
        seconds(),
    ),
    channels=keyed(integer("index", 0, MAX_VALUES - 1)),
    transport=UdpQueryTransport,
)

register(UDP_QUERY)
