"""A simulated dynamometer rig: a simulated log served in real time over Modbus TCP and a serial pty.

:class:`SimulatedRig` plays back :func:`hound_id.dyno.simulate.current.simulate` on the wall clock: the playback
time is ``t = ((monotonic() - t0) * speedup) mod T``, with ``t0`` the moment :meth:`SimulatedRig.start`
was called and ``T`` the time of the log's last sample (the log loops). Every value served is the
simulated signal linearly interpolated to ``t`` at the moment the request is answered.

Register map (Modbus TCP, one server, function code 4 "read input registers" only; big-endian word
and byte order; scaled integers hold ``round(value / scale)``, clamped to the type's range):

==========  ==============  ========  =========  =======  ===========  ===============================
unit        name            register  dtype      scale    column       unit
==========  ==============  ========  =========  =======  ===========  ===============================
1           transducer      0-1       float32    1        torque       N m
2           drive           0-1       float32    1        current      A
2           drive           2-3       float32    1        velocity     rad/s
2           drive           4-5       int32      1e-4     position     rad, wrapped to [0, 2 pi) first
2           drive           6         int16      0.1      temperature  degC (winding)
2           drive           7         uint16     0.01     bus_voltage  V
==========  ==============  ========  =========  =======  ===========  ===============================

Reads beyond these registers answer ILLEGAL_ADDRESS (0x02), other function codes ILLEGAL_FUNCTION
(0x01), writes ILLEGAL_ADDRESS (the registers are read-only), other unit ids GATEWAY_NO_RESPONSE (0x0B).

Serial: a pseudo-terminal (its slave path is :attr:`SimulatedRig.serial_port`, raw mode, 115200 baud
nominal) carries ASCII lines ``I=<current>,W=<velocity>,T=<temperature>\\n`` (``%.6g``) at
``min(rate_hz, 500)`` Hz. Lines nobody reads are dropped once the pty buffer is full, so a reader
should discard its input buffer after opening the port (pyserial ``reset_input_buffer()``).

Atomic reads: pymodbus 3.16 serves from ``SimDevice`` register blocks and calls the device's async
``action`` on every request before it copies the requested registers; the action here writes the whole
block of the unit from one instant of the playback clock. The server's event loop runs the action and
the copy without yielding, so one request always sees one instant.

The server runs in a background thread with its own asyncio loop, the serial writer in another thread;
:meth:`SimulatedRig.stop` ends both. pymodbus is imported only when the rig starts.
"""

from __future__ import annotations

import asyncio
import functools
import math
import os
import struct
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from hound_id.dyno.simulate.current import SimMotor, SimulatedLog, TestPlan, simulate
from hound_id.errors import DynoDataError

if TYPE_CHECKING:  # pragma: no cover
    from types import TracebackType

    from pymodbus.server import ModbusTcpServer

__all__ = [
    "CHANNELS",
    "CONSOLE_REGEX",
    "DEVICES",
    "RIG_SCHEMA",
    "SERIAL_BAUD",
    "SPEEDUP_LIMITS",
    "RigChannel",
    "SimulatedRig",
    "check_speedup",
]

#: Schema tag of the rig mapping (:meth:`SimulatedRig.rig_mapping`).
RIG_SCHEMA = "hound-id/rig/1"
#: Modbus unit id of each device.
DEVICES: Mapping[str, int] = {"transducer": 1, "drive": 2}
#: Nominal baud rate of the serial console.
SERIAL_BAUD = 115200
#: Highest rate of serial lines [Hz]; 500 lines of ~40 bytes fit 115200 baud (11.5 kB/s) with margin.
SERIAL_MAX_RATE_HZ = 500.0
#: Pattern of a console line, for the rig mapping.
CONSOLE_REGEX = r"I=(?P<current>[^,]+),W=(?P<velocity>[^,]+),T=(?P<temperature>[^,\s]+)"
#: Timeout of a Modbus request written into the rig mapping [s].
MODBUS_TIMEOUT = 0.2
#: Bound on every wait for a background thread or the event loop [s].
THREAD_TIMEOUT = 5.0

# Malformed console lines for send_garbage: truncated, binary, non-numeric, a missing field, empty.
_GARBAGE: tuple[bytes, ...] = (
    b"I=1.25,W=\n",
    b"\xfe\xff\x00\x13\x80garbage\n",
    b"I=abc,W=def,T=ghi\n",
    b"I=1.0,T=25.0\n",
    b"\n",
)


@dataclass(frozen=True)
class RigChannel:
    """One simulated channel held in Modbus input registers."""

    column: str
    """Log column served (see ``hound_id.dyno.simulate.current.COLUMNS``)."""
    device: str
    """Device name, a key of ``DEVICES``."""
    register: int
    """First input register."""
    dtype: str
    """Register encoding: "float32", "int32", "int16" or "uint16" (big-endian words and bytes)."""
    unit: str
    """Physical unit of the decoded value."""
    scale: float = 1.0
    """Value per count for integer dtypes [unit]."""
    wrap: float = 0.0
    """Period the value is wrapped to [0, wrap) by before encoding (0: not wrapped) [unit]."""


# dtype -> (struct code, registers, lowest count, highest count)
_DTYPES: Mapping[str, tuple[str, int, int, int]] = {
    "float32": ("f", 2, 0, 0),
    "int32": ("i", 2, -(2**31), 2**31 - 1),
    "int16": ("h", 1, -(2**15), 2**15 - 1),
    "uint16": ("H", 1, 0, 2**16 - 1),
}

#: The register map, in register order per device.
CHANNELS: tuple[RigChannel, ...] = (
    RigChannel("torque", "transducer", 0, "float32", "N*m"),
    RigChannel("current", "drive", 0, "float32", "A"),
    RigChannel("velocity", "drive", 2, "float32", "rad/s"),
    RigChannel("position", "drive", 4, "int32", "rad", scale=1e-4, wrap=2.0 * math.pi),
    RigChannel("temperature", "drive", 6, "int16", "degC", scale=0.1),
    RigChannel("bus_voltage", "drive", 7, "uint16", "V", scale=0.01),
)


def _layout(device: str) -> tuple[str, tuple[RigChannel, ...], int]:
    """(struct format, channels, register count) of one device's contiguous block."""
    chans = tuple(sorted((c for c in CHANNELS if c.device == device), key=lambda c: c.register))
    fmt = ">" + "".join(_DTYPES[c.dtype][0] for c in chans)
    return fmt, chans, struct.calcsize(fmt) // 2


_LAYOUTS = {name: _layout(name) for name in DEVICES}


def encode_registers(device: str, values: Mapping[str, float]) -> list[int]:
    """The input registers of ``device`` holding ``values``.

    Args:
        device: A key of ``DEVICES``.
        values: Column -> physical value (SI units of the register map).

    Returns:
        The 16-bit register words from register 0 on.
    """
    fmt, chans, n_words = _LAYOUTS[device]
    fields: list[float | int] = []
    for chan in chans:
        x = float(values[chan.column])
        if chan.wrap > 0:
            x %= chan.wrap
        if chan.dtype == "float32":
            fields.append(x)
        else:
            _, _, low, high = _DTYPES[chan.dtype]
            fields.append(min(max(round(x / chan.scale), low), high) if math.isfinite(x) else 0)
    return list(struct.unpack(f">{n_words}H", struct.pack(fmt, *fields)))


#: Playback speeds accepted [-]. Above 1000 a 60 s plan loops in under 60 ms, faster than a polled rig samples;
#: the product with the clock must also stay finite.
SPEEDUP_LIMITS: tuple[float, float] = (1e-3, 1e3)


def check_speedup(value: object, what: str = "speedup") -> float:
    """``value`` as a playback speed within :data:`SPEEDUP_LIMITS`, or DynoDataError naming ``what``."""
    lo, hi = SPEEDUP_LIMITS
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as err:
        raise DynoDataError(f"{what}: found {value!r}, expected a number from {lo:g} to {hi:g}", value=value) from err
    if not lo <= x <= hi:
        raise DynoDataError(f"{what}: found {x:g}, expected {lo:g} to {hi:g} (times faster than real time)", value=x)
    return x


class SimulatedRig:
    """A dyno rig that serves a simulated log in real time over Modbus TCP and a serial pty.

    Use as a context manager (``with SimulatedRig() as rig: ...``) or call :meth:`start` and
    :meth:`stop`. The register map is in the module docstring.

    Args:
        effects: Simulated effects (see ``hound_id.dyno.simulate.current.EFFECTS``).
        seed: Noise seed of the simulation.
        motor: The motor under test (default ``SimMotor()``).
        plan: The test plan (default ``TestPlan()``).
        rate_hz: Sample rate of the simulated log [Hz]; values are interpolated between samples.
        host: Address the Modbus server binds to.
        port: TCP port; 0 takes a free one (see :attr:`address`).
        serial: Whether to open the serial console pty.
        speedup: Playback speed relative to the wall clock [-].

    Raises:
        DynoDataError: A non-physical argument (from the simulator or ``speedup``).
    """

    def __init__(
        self,
        effects: Sequence[str] = ("linear", "saturation"),
        *,
        seed: int = 0,
        motor: SimMotor | None = None,
        plan: TestPlan | None = None,
        rate_hz: float = 1000.0,
        host: str = "127.0.0.1",
        port: int = 0,
        serial: bool = True,
        speedup: float = 1.0,
    ) -> None:
        self._speedup = check_speedup(speedup)
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise DynoDataError(f"port: found {port!r}, expected an integer in 0..65535 (0: any free port)", value=port)
        self._log = simulate(
            effects, motor=motor if motor is not None else SimMotor(), plan=plan, seed=seed, rate_hz=rate_hz
        )
        frame = self._log.frame
        self._columns: tuple[str, ...] = tuple(c for c in frame.columns if c != "time")
        signals = frame[list(self._columns)].to_numpy(dtype=np.float64, copy=True)
        signals.setflags(write=False)
        self._signals = signals
        self._rate = float(self._log.rate_hz)
        self._period = float(frame["time"].iloc[-1])
        self._host = host
        self._port = port
        self._serial = bool(serial)
        self._t0 = time.monotonic()
        self._exceptions: dict[int, Any] = {}  # unit -> pymodbus ExcCodes; read by the loop thread
        self._address: tuple[str, int] | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: ModbusTcpServer | None = None
        self._server_thread: threading.Thread | None = None
        self._start_error: BaseException | None = None
        self._stopping = threading.Event()
        self._writer: threading.Thread | None = None
        self._pty: tuple[int, int] | None = None  # (master, slave) fds
        self._pty_path: str | None = None
        self._pty_lock = threading.Lock()

    # ------------------------------------------------------------------ playback

    @property
    def log(self) -> SimulatedLog:
        """The simulated log being played back."""
        return self._log

    @property
    def truth(self) -> Mapping[str, float]:
        """The simulator's truth (parameter -> value, read-only)."""
        return self._log.truth

    @property
    def period(self) -> float:
        """Length of one playback loop, the time of the log's last sample [s]."""
        return self._period

    @property
    def speedup(self) -> float:
        """Playback speed relative to the wall clock [-]."""
        return self._speedup

    def playback_time(self) -> float:
        """The log time being served now, ``((monotonic() - t0) * speedup) mod period`` [s]."""
        return ((time.monotonic() - self._t0) * self._speedup) % self._period

    def sample(self, t: float | None = None) -> dict[str, float]:
        """The simulated signals at log time ``t``, linearly interpolated between samples.

        Args:
            t: Log time [s], wrapped into the playback loop; None takes :meth:`playback_time`.

        Returns:
            Column -> value for every log column but "time"; position is unwrapped as in the log.
        """
        t = self.playback_time() if t is None else float(t) % self._period
        x = t * self._rate
        i = min(max(int(x), 0), self._signals.shape[0] - 2)
        f = min(max(x - i, 0.0), 1.0)
        a, b = self._signals[i], self._signals[i + 1]
        return dict(zip(self._columns, (a + f * (b - a)).tolist(), strict=True))

    # ------------------------------------------------------------------ life cycle

    @property
    def running(self) -> bool:
        """Whether the rig has been started and not stopped."""
        return self._server_thread is not None

    @property
    def address(self) -> tuple[str, int]:
        """The (host, port) the Modbus server is bound to (kept after :meth:`stop`).

        Raises:
            DynoDataError: The rig was never started.
        """
        if self._address is None:
            raise DynoDataError("SimulatedRig.address: the rig has not been started; call start() first")
        return self._address

    @property
    def serial_port(self) -> str | None:
        """Path of the serial console (pty slave, e.g. /dev/pts/7); None without serial or before start."""
        return self._pty_path

    def start(self) -> None:
        """Start the Modbus server and the serial writer, and reset the playback clock to 0.

        Raises:
            DynoDataError: The rig is running already, or the server could not bind its port.
        """
        if self.running:
            raise DynoDataError("SimulatedRig.start: the rig is running already; call stop() first")
        self._stopping.clear()
        self._start_error = None
        self._t0 = time.monotonic()
        ready = threading.Event()
        self._server_thread = threading.Thread(target=self._run_loop, args=(ready,), name="rigsim-modbus", daemon=True)
        self._server_thread.start()
        if not ready.wait(THREAD_TIMEOUT) or self._start_error is not None:
            err = self._start_error
            self.stop()
            where = f"{self._host}:{self._port}"
            raise DynoDataError(
                f"simulated rig: the Modbus server could not listen on {where}: {err or 'timed out'}; "
                "choose another port (0 takes a free one)",
                host=self._host,
                port=self._port,
            ) from err
        if self._serial:
            self._open_pty()
            self._writer = threading.Thread(target=self._write_lines, name="rigsim-serial", daemon=True)
            self._writer.start()

    def stop(self) -> None:
        """Stop the server and the serial writer, close the pty and release the port (idempotent).

        Every thread is joined within ``THREAD_TIMEOUT``.
        """
        self._stopping.set()
        if self._writer is not None:
            self._writer.join(THREAD_TIMEOUT)
            self._writer = None
        loop, thread = self._loop, self._server_thread
        if loop is not None and thread is not None and thread.is_alive():
            try:
                loop.call_soon_threadsafe(loop.stop)
            except RuntimeError:  # the loop has closed already
                pass
        if thread is not None:
            thread.join(THREAD_TIMEOUT)
        self._server_thread = None
        self._loop = None
        with self._pty_lock:
            if self._pty is not None:
                for fd in self._pty:
                    try:
                        os.close(fd)
                    except OSError:
                        pass
                self._pty = None
                self._pty_path = None

    def __enter__(self) -> SimulatedRig:
        self.start()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()

    # ------------------------------------------------------------------ description

    def rig_mapping(self) -> dict[str, Any]:
        """A rig file mapping (schema ``hound-id/rig/1``) that describes exactly this rig.

        Raises:
            DynoDataError: The rig was never started (its port is not known yet).
        """
        host, port = self.address
        devices: dict[str, dict[str, Any]] = {
            name: {"type": "modbus_tcp", "host": host, "port": port, "unit": unit, "timeout": MODBUS_TIMEOUT}
            for name, unit in DEVICES.items()
        }
        if self._serial and self._pty_path is not None:
            devices["console"] = {
                "type": "serial_lines",
                "port": self._pty_path,
                "baud": SERIAL_BAUD,
                "format": {"regex": CONSOLE_REGEX},
            }
        channels: list[dict[str, Any]] = []
        for chan in CHANNELS:
            entry: dict[str, Any] = {
                "column": chan.column,
                "device": chan.device,
                "register": chan.register,
                "kind": "input",
                "dtype": chan.dtype,
            }
            if chan.scale != 1.0:
                entry["scale"] = chan.scale
            entry["unit"] = chan.unit
            channels.append(entry)
        return {"schema": RIG_SCHEMA, "name": "simulated-rig", "devices": devices, "channels": channels}

    # ------------------------------------------------------------------ fault injection

    def pause_modbus(self) -> None:
        """Close the listening socket and every client connection until :meth:`resume_modbus`."""
        self._in_loop(self._close_server(), "pause_modbus")

    def resume_modbus(self) -> None:
        """Listen again on the same port after :meth:`pause_modbus` (no-op when serving).

        Raises:
            DynoDataError: The port was taken meanwhile.
        """
        try:
            self._in_loop(self._listen(self.address[1]), "resume_modbus")
        except OSError as err:
            raise DynoDataError(f"simulated rig: cannot listen again on {self.address}: {err}") from err

    def set_exception(self, unit: int, on: bool, code: int = 0x06) -> None:
        """Answer every request to ``unit`` with a Modbus exception response, or stop doing so.

        Args:
            unit: Modbus unit id (see ``DEVICES``).
            on: True to answer with the exception, False to serve values again.
            code: Modbus exception code: 0x06 SLAVE_DEVICE_BUSY (default), 0x02 ILLEGAL_DATA_ADDRESS,
                0x04 SLAVE_DEVICE_FAILURE, ...

        Raises:
            DynoDataError: ``code`` is not a Modbus exception code.
        """
        from pymodbus.constants import ExcCodes

        try:
            exc = ExcCodes(code)
        except ValueError as err:
            known = ", ".join(f"{c.value:#04x} {c.name}" for c in ExcCodes)
            raise DynoDataError(f"set_exception: code {code!r} is not one of {known}", code=code) from err
        exceptions = dict(self._exceptions)
        if on:
            exceptions[int(unit)] = exc
        else:
            exceptions.pop(int(unit), None)
        self._exceptions = exceptions  # one reference swap: the loop thread sees the old or the new dict

    def send_garbage(self, n: int) -> None:
        """Write ``n`` malformed lines on the serial console, between well-formed ones.

        Raises:
            DynoDataError: The rig has no serial console running.
        """
        if self._pty is None:
            raise DynoDataError("send_garbage: the rig has no serial console; start it with serial=True")
        for k in range(int(n)):
            self._write_pty(_GARBAGE[k % len(_GARBAGE)])

    # ------------------------------------------------------------------ Modbus server (loop thread)

    def _run_loop(self, ready: threading.Event) -> None:
        """Body of the server thread: listen, then run the loop until stop() stops it."""
        loop = asyncio.new_event_loop()
        asyncio.set_event_loop(loop)  # this thread's loop, for pymodbus' get_running_loop and gather
        self._loop = loop
        try:
            try:
                loop.run_until_complete(self._listen(self._port))
            except BaseException as err:  # reported by start()
                self._start_error = err
                return
            finally:
                ready.set()
            if not self._stopping.is_set():
                loop.run_forever()
        finally:
            try:
                loop.run_until_complete(self._close_server())
                pending = [t for t in asyncio.all_tasks(loop) if not t.done()]
                for task in pending:
                    task.cancel()
                loop.run_until_complete(asyncio.gather(*pending, return_exceptions=True))
            finally:
                loop.close()

    async def _listen(self, port: int) -> None:
        """Create the pymodbus server and listen on ``port`` (no-op when listening)."""
        if self._server is not None:
            return
        from pymodbus.server import ModbusTcpServer

        server = ModbusTcpServer(self._devices(), address=(self._host, port))
        try:
            await server.serve_forever(background=True)
        except RuntimeError as err:  # pymodbus: "Could not start listen"
            raise OSError(f"cannot listen on {self._host}:{port}") from err
        sockets = getattr(server.transport, "sockets", None) or ()
        if not sockets:
            await server.shutdown()
            raise OSError(f"no listening socket on {self._host}:{port}")
        name = sockets[0].getsockname()
        self._address = (str(name[0]), int(name[1]))
        self._server = server

    async def _close_server(self) -> None:
        """Close the listener and every connection (no-op when closed)."""
        server, self._server = self._server, None
        if server is not None:
            await server.shutdown()
            await asyncio.sleep(0)  # let the transports run their connection_lost callbacks

    def _devices(self) -> list[Any]:
        """pymodbus SimDevices: one per unit of ``DEVICES`` plus a catch-all for other unit ids."""
        from pymodbus.simulator import DataType, SimData, SimDevice

        devices = [
            SimDevice(
                id=unit,
                simdata=[SimData(0, count=_LAYOUTS[name][2], values=0, datatype=DataType.REGISTERS, readonly=True)],
                action=functools.partial(self._answer, name),
            )
            for name, unit in DEVICES.items()
        ]
        # id 0 takes every other unit id; one block over the whole address space, refused by the action
        devices.append(
            SimDevice(
                id=0,
                simdata=[SimData(0, count=65536, values=0, datatype=DataType.REGISTERS, readonly=True)],
                action=self._answer_missing,
            )
        )
        return devices

    async def _answer(
        self,
        device: str,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> Any:
        """SimDevice action: fill the unit's whole block from one instant, or refuse the request.

        Runs on the loop thread; pymodbus copies the requested registers right after it returns,
        without yielding in between, so a request sees one instant.
        """
        from pymodbus.constants import ExcCodes

        exc = self._exceptions.get(DEVICES[device])
        if exc is not None:
            return exc
        if function_code != 4:
            return ExcCodes.ILLEGAL_FUNCTION
        words = encode_registers(device, self.sample())
        registers[0 : len(words)] = words
        return None

    async def _answer_missing(self, *_: Any) -> Any:
        """SimDevice action of unknown unit ids: the gateway's target does not answer."""
        from pymodbus.constants import ExcCodes

        return ExcCodes.GATEWAY_NO_RESPONSE

    def _in_loop(self, coro: Any, what: str) -> None:
        """Run ``coro`` on the server loop and wait for it (bounded)."""
        loop = self._loop
        if loop is None or not self.running:
            coro.close()
            raise DynoDataError(f"{what}: the rig is not running; call start() first")
        asyncio.run_coroutine_threadsafe(coro, loop).result(THREAD_TIMEOUT)

    # ------------------------------------------------------------------ serial console

    def _open_pty(self) -> None:
        """Open a raw pseudo-terminal; the rig keeps both ends open so writes never fail for lack of a reader."""
        import termios
        import tty

        master, slave = os.openpty()
        tty.setraw(slave)
        attrs = termios.tcgetattr(slave)
        attrs[4] = attrs[5] = termios.B115200  # nominal only: a pty has no line rate
        termios.tcsetattr(slave, termios.TCSANOW, attrs)
        os.set_blocking(master, False)
        with self._pty_lock:
            self._pty = (master, slave)
            self._pty_path = os.ttyname(slave)

    def _write_pty(self, data: bytes) -> None:
        """Write whole lines to the pty; drop them when its buffer is full (nobody reading)."""
        with self._pty_lock:
            if self._pty is None:
                return
            try:
                os.write(self._pty[0], data)
            except OSError:  # BlockingIOError when full; a serial line loses data too
                pass

    def _write_lines(self) -> None:
        """Body of the serial thread: one line per period from the playback clock."""
        period = 1.0 / min(self._rate, SERIAL_MAX_RATE_HZ)
        due = time.monotonic()
        while not self._stopping.is_set():
            wait = due - time.monotonic()
            if wait > 0 and self._stopping.wait(wait):
                break
            v = self.sample()
            self._write_pty(f"I={v['current']:.6g},W={v['velocity']:.6g},T={v['temperature']:.6g}\n".encode("ascii"))
            due += period
            if time.monotonic() - due > 0.1:  # fell behind on a loaded machine: skip, do not burst
                due = time.monotonic()
