"""The serial_lines transport: a serial port that prints one text line per sample (a microcontroller console),
its settings (the port, the baud rate, the line format), its field channels and :class:`SerialLinesTransport`.

A serial device streams lines on its own; a background thread parses them and keeps
the newest complete sample. A read returns it when it is younger than the device's
timeout, so a silent or garbled line stream turns into read errors (gaps), not stale data.
pyserial is imported when a transport opens.
"""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, ClassVar

from hound_id.dyno.acquire.channel import Channel
from hound_id.dyno.acquire.device import (
    DEFAULT_TIMEOUT,
    Addressing,
    DeviceType,
    Setting,
    Where,
    check_keys,
    check_text,
    integer,
    require_mapping,
    seconds,
    suggest,
    text,
)
from hound_id.dyno.acquire.recorder import ReadError
from hound_id.errors import DynoDataError
from hound_id.units import as_number

_FIELD_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_FORMAT_KEYS = ("delimiter", "fields", "regex")


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


def line_format(value: Any, at: Where) -> LineFormat:
    """The ``format`` setting: ``{delimiter, fields}`` or ``{regex}`` with named groups."""
    data = require_mapping(value, at, "a mapping with 'delimiter' and 'fields', or 'regex'", "format")
    fmt_at = at.at(f"{at.item}.format")
    check_keys(data, _FORMAT_KEYS, fmt_at)
    if "regex" in data:
        if "fields" in data or "delimiter" in data:
            raise fmt_at.error(
                "found both 'regex' and 'delimiter'/'fields', expected one of the two; keep one", "regex"
            )
        regex = check_text(data["regex"], fmt_at.field("regex"))
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
        if not isinstance(name, str) or not _FIELD_NAME.match(name) or names.count(name) > 1:
            raise fmt_at.error(
                f"found {name!r}, expected unique names matching [A-Za-z_][A-Za-z0-9_]*; rename it", "fields"
            )
    return LineFormat(delimiter=delimiter, fields=tuple(names))


def format_mapping(fmt: LineFormat) -> dict[str, Any]:
    """A line format as the rig file writes it."""
    if fmt.regex is not None:
        return {"regex": fmt.regex}
    return {"delimiter": fmt.delimiter, "fields": list(fmt.fields or ())}


def field_address(data: Mapping[Any, Any], device: Any, at: Where) -> dict[str, Any]:
    """A field channel's key: ``field``, one of the names of the device's line format."""
    names = device.format.names
    if "field" not in data:
        raise at.error(
            f"missing; a channel of serial_lines device '{device.name}' names one of its fields ({', '.join(names)})",
            "field",
        )
    name = data["field"]
    if name not in names:
        raise at.error(
            f"found {name!r}, which is not a field of device '{device.name}'; "
            f"{suggest(str(name), names)}; fix the name or the device's format",
            "field",
            found=name,
        )
    return {"field": str(name)}


class SerialLinesTransport:
    """A device that streams text lines; the newest parsed line is the sample."""

    def __init__(self, devices: Sequence[SerialLinesDevice], channels: Sequence[Channel]) -> None:
        (self.device,) = devices  # a serial port is one device's
        self.columns = {c.column: c.raw_to_si for c in channels}  # column -> raw-to-SI conversion
        self.fields = {c.column: str(c.field) for c in channels}  # column -> field name in the line
        self._latest: tuple[float, dict[str, float]] | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._port: Any = None
        self.malformed = 0
        self.last_error = ""

    @property
    def label(self) -> str:
        return f"serial {self.device.port}"

    @property
    def errors(self) -> int:
        """Malformed lines so far."""
        return self.malformed

    def open(self) -> None:
        import serial

        try:
            self._port = serial.Serial(self.device.port, self.device.baud, timeout=0.05)
        except (serial.SerialException, OSError) as err:
            raise ReadError(f"{self.label}: cannot open ({err})") from err
        self._thread = threading.Thread(target=self._run, name=f"serial-{self.device.name}", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        buffer = b""
        while not self._stop.is_set():
            try:
                chunk = self._port.read(4096)
            except Exception as err:  # noqa: BLE001 - a device gone away: report through read()
                self.last_error = f"{self.label}: {err}"
                time.sleep(0.01)
                continue
            if not chunk:
                continue
            buffer += chunk
            *lines, buffer = buffer.split(b"\n")
            for raw in lines:
                try:
                    parsed = parse_line(raw.decode("utf-8", "replace"), self.device.format)
                    sample = {col: conv(parsed[self.fields[col]]) for col, conv in self.columns.items()}
                except (DynoDataError, KeyError) as err:
                    self.malformed += 1
                    self.last_error = str(err)
                    continue
                with self._lock:
                    self._latest = (time.monotonic(), sample)

    def read(self) -> dict[str, float]:
        if self._thread is None:
            self.open()
        with self._lock:
            latest = self._latest
        if latest is None or time.monotonic() - latest[0] > self.device.timeout:
            reason = self.last_error or "no line received"
            raise ReadError(f"{self.label}: no valid line within {self.device.timeout:g} s ({reason})")
        return dict(latest[1])

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
            self._thread = None
        if self._port is not None:
            self._port.close()
            self._port = None


SERIAL_LINES = DeviceType(
    name="serial_lines",
    device=SerialLinesDevice,
    settings=(
        text("port"),
        integer("baud", 1, 100_000_000),
        Setting("format", line_format, dump=format_mapping),
        seconds(),
    ),
    channels=Addressing(("field",), field_address),
    transport=SerialLinesTransport,
)
