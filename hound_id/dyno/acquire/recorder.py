"""Recording a dyno log: paced sampling, a streaming CSV that survives crashes, a metadata sidecar.

The recorder is transport-agnostic: it calls ``read_sample()`` once per tick of a
monotonic clock at the requested rate, and writes each complete sample as one CSV row
(``time`` in seconds since the start, then the rig's columns, SI units, LF line endings).
A background writer appends the rows to the file and rewrites the sidecar on a timer
(every ``flush_interval``, at least every :data:`SIDECAR_EVERY` seconds), whatever the
reads are doing, so a SIGKILL loses at most a flush interval of rows and leaves a sidecar
that describes the run up to then, an open gap included. Ctrl-C (KeyboardInterrupt) or a
stop request ends the run cleanly with everything recorded so far on disk.

Ticks: tick k is due at t0 + k / rate; its row is stamped with the middle of the read that
produced it (the reads of several devices take a round trip each). Every tick ends as one of:

* a **sample** (a row);
* a **gap tick**: the reads gave no sample. A read that fails (refused connection, timeout,
  exception response, malformed line) is retried by the :class:`RetryPolicy`; if it still
  fails, a gap opens. A gap runs from the last good sample to the next good one
  (:class:`Gap` ``start`` and ``end``), and every tick due in between is booked in it, also
  the ticks skipped because a failing or hung read held the loop up. A read that succeeds
  only after blocking longer than ``RetryPolicy.stall_after`` (a peer that hung and came
  back) makes a gap too, from the previous sample to this one (stamped at the read's end).
  Recording goes on unless the reads have been failing for longer than ``give_up_after``;
* a **missed tick**: the loop was late (scheduling, a rate the link cannot sustain) while the
  reads succeed. A tick whose read would start more than one period late is skipped, never
  bunched to catch up.

The sidecar ``<out>.meta.json`` (schema ``hound-id/record/2``) holds the rig file, start
time, software version, the recorder's PID, requested and achieved rate, samples (rows on
disk), missed ticks, gap ticks, gaps (an open gap has ``"end": null``) and faults, and the
status (``recording``, ``complete``, ``interrupted``, ``failed``).

Output safety: the CSV is locked (``flock``) for the whole run, so a second recorder on
the same file is refused before it writes anything. A log that is already there is refused
unless ``overwrite`` says to replace it, and even then it is replaced (with its sidecar)
only once the first sample is in hand: until then the run writes to a hidden file beside it,
so a rig that answers nothing, or a Ctrl-C before the first sample, leaves it as it was.
A write error (disk full, file size limit) stops the run: the file is cut back to its last whole row, the sidecar says
``failed``, and :class:`~hound_id.errors.OutputError` is raised with the counts.

The log file itself (the lock, the sidecar) is :mod:`hound_id.dyno.acquire.log_file`.
"""

from __future__ import annotations

import dataclasses
import math
import os
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from types import MappingProxyType
from typing import Any

from hound_id import __version__
from hound_id.dyno.acquire.log_file import CsvLog, save_sidecar, sidecar_path
from hound_id.errors import DynoDataError, HoundIdError, OutputError

SCHEMA = "hound-id/record/2"
#: Sampling rates the recorder accepts [Hz]. A polled read is at least one request round trip
#: (0.3-1 ms on loopback for the simulated rig's two devices, more on a bus) plus ~50 us of Python
#: per tick, so a rig delivers at most a few kHz; 10 kHz leaves headroom. 0.01 Hz: one sample in 100 s.
RATE_LIMITS: tuple[float, float] = (0.01, 10_000.0)
#: Flush intervals the recorder accepts [s]: what a SIGKILL may lose, and the CSV write cadence.
FLUSH_LIMITS: tuple[float, float] = (0.05, 60.0)
#: The sidecar is rewritten at least this often, whatever the reads do [s].
SIDECAR_EVERY = 0.5
#: Faults kept in the sidecar (the newest).
MAX_FAULTS = 50


class ReadError(HoundIdError, OSError):
    """One read of the rig failed (timeout, exception response, disconnect, malformed line)."""


@dataclass(frozen=True)
class RetryPolicy:
    """What the recorder does when a read fails or hangs."""

    retries: int = 2
    """Immediate retries of a failed read within the same tick."""
    give_up_after: float = 5.0
    """Stop the run when reads have failed without a break for this long [s]."""
    stall_after: float = 0.5
    """A read that succeeds only after blocking this long is a hung peer, not a late loop: the ticks it held
    up are a gap [s]. Above a device's usual timeout (0.2 s), which ends a hung request as a failure."""


@dataclass(frozen=True)
class Gap:
    """A stretch of ticks without a sample, between two good samples."""

    start: float
    """Time of the last sample before the gap (0: the start of the run) [s]."""
    end: float | None
    """Time of the first sample after it (the stop time if none came; None while the gap is open) [s]."""
    ticks: int
    """Ticks due in between that gave no sample."""
    reason: str
    """The last failure's message."""

    def to_dict(self) -> dict[str, Any]:
        return {"start": self.start, "end": self.end, "ticks": self.ticks, "reason": self.reason}


@dataclass(frozen=True)
class RecordResult:
    """What a run recorded."""

    out: Path
    """The CSV file."""
    sidecar: Path
    """The metadata file."""
    status: str
    """complete, interrupted or failed."""
    samples: int
    """Rows written to the file."""
    missed: int
    """Ticks skipped because the loop was late while reads succeeded."""
    failed: int
    """Ticks lost in gaps (reads failing or hung)."""
    duration: float
    """Wall time from start to stop [s]."""
    achieved_rate: float
    """samples / duration [Hz]."""
    gaps: tuple[Gap, ...]
    """Stretches without samples."""
    message: str = ""
    """Why a failed run stopped."""
    metadata: Mapping[str, Any] = field(default_factory=lambda: MappingProxyType({}))
    """What the final sidecar says (schema ``hound-id/record/2``), read-only; empty in the running totals
    given to ``on_progress``."""
    kept_existing: bool = False
    """True when no sample came and the run left the folder as it was: the log already at ``out`` (and its sidecar)
    untouched, or, for a new file, no log and no sidecar left behind."""


def check_settings(rate_hz: float, duration: float | None, flush_interval: float) -> None:
    """Refuse a rate, duration or flush interval the recorder cannot honour (one line, the option named).

    Args:
        rate_hz: Sampling rate [Hz], within :data:`RATE_LIMITS`.
        duration: Seconds to record (None: until stopped); positive and finite.
        flush_interval: Longest time between writes to disk [s], within :data:`FLUSH_LIMITS`.

    Raises:
        DynoDataError: A value out of range; the message names the option and the range.
    """
    lo, hi = RATE_LIMITS
    if not (isinstance(rate_hz, (int, float)) and lo <= rate_hz <= hi):
        raise DynoDataError(
            f"--rate: found {rate_hz:g} Hz, expected {lo:g} to {hi:g} Hz (a polled rig answers at most a few kHz); "
            "choose a rate in that range",
            rate_hz=rate_hz,
        )
    if duration is not None and not (math.isfinite(duration) and duration > 0):
        raise DynoDataError(
            f"--duration: found {duration:g}, expected a positive number of seconds "
            "(leave it out to record until Ctrl-C)",
            duration=duration,
        )
    lo, hi = FLUSH_LIMITS
    if not lo <= flush_interval <= hi:
        raise DynoDataError(
            f"--flush: found {flush_interval:g} s, expected {lo:g} to {hi:g} s between writes to disk",
            flush_interval=flush_interval,
        )


@dataclass
class _State:
    """Running totals, shared by the sampling loop and the writer thread (under ``lock``)."""

    period: float
    stall_after: float
    lock: threading.Lock = field(default_factory=threading.Lock)
    pending_rows: list[str] = field(default_factory=list)
    taken: int = 0
    last_t: float | None = None
    max_interval: float = 0.0
    missed: int = 0
    lost: int = 0
    gaps: list[Gap] = field(default_factory=list)
    faults: list[str] = field(default_factory=list)
    open_start: float | None = None  # an open gap: reads failing since the sample at this time
    open_ticks: int = 0
    open_reason: str = ""
    closing: Gap | None = None  # a gap closed by a sample; the ticks its reads held up are skipped next
    reading_since: float | None = None  # monotonic time a read in progress started
    reading_due: float | None = None  # monotonic time its tick was due

    def _settle(self) -> None:
        if self.closing is not None and self.closing.ticks > 0:  # a read held up that cost no tick is no gap
            self.gaps.append(self.closing)
        self.closing = None

    def fail(self, reason: str) -> None:
        """A tick whose reads all failed."""
        self._settle()
        if self.open_start is None:
            self.open_start, self.open_ticks = (self.last_t if self.last_t is not None else 0.0), 0
        self.open_ticks += 1
        self.lost += 1
        self.open_reason = reason
        if not self.faults or self.faults[-1] != reason:
            self.faults.append(reason)
            del self.faults[:-MAX_FAULTS]

    def skip(self, n: int) -> None:
        """``n`` ticks skipped because the loop is late: a gap's if a read failed or hung, else missed."""
        if self.open_start is not None:
            self.open_ticks += n
            self.lost += n
        elif self.closing is not None:
            self.closing = dataclasses.replace(self.closing, ticks=self.closing.ticks + n)
            self.lost += n
            self._settle()
        else:
            self.missed += n

    def take(self, t: float, row: str, held: str) -> None:
        """A sample at ``t`` [s]; ``held`` says why its read held the loop up (failed attempts before it, or a
        peer that hung and then answered), "" for a plain read."""
        self._settle()
        if self.open_start is not None or held:
            start = self.open_start if self.open_start is not None else (self.last_t or 0.0)
            # the gap ends here, but the ticks its reads held up are skipped next: they belong to it
            self.closing = Gap(start, t, self.open_ticks, self.open_reason or held)
            self.open_start, self.open_ticks, self.open_reason = None, 0, ""
        if self.last_t is not None:
            self.max_interval = max(self.max_interval, t - self.last_t)
        self.last_t = t
        self.pending_rows.append(row)
        self.taken += 1

    def all_gaps(self, now: float | None, stop_t: float) -> tuple[list[Gap], int]:
        """(gaps, ticks lost in them): closed gaps, then the open one, whose ``end`` is None while recording
        (``now`` given) and ``stop_t`` after. A read blocked for longer than ``stall_after`` shows as open."""
        gaps = list(self.gaps)
        if self.closing is not None and self.closing.ticks > 0:
            gaps.append(self.closing)
        reading = self.reading_since
        blocked = (now - reading) if (now is not None and reading is not None) else 0.0
        hung = blocked > self.stall_after
        lost = self.lost
        if self.open_start is not None or hung:
            # the ticks due since the tick being read are not booked yet: the loop books them when the read ends
            due = self.reading_due if self.reading_due is not None else 0.0
            extra = int((now - due) / self.period) if (now is not None and reading is not None) else 0
            lost += extra
            start = self.open_start if self.open_start is not None else (self.last_t or 0.0)
            reason = self.open_reason or f"a read has been blocked for {blocked:.1f} s"
            gaps.append(Gap(start, None if now is not None else stop_t, self.open_ticks + extra, reason))
        return gaps, lost


class _Writer:
    """Appends the pending rows to the CSV and rewrites the sidecar on a timer, in a background thread."""

    def __init__(
        self,
        log: CsvLog,
        state: _State,
        sidecar: Callable[[], None],
        flush_interval: float,
        on_progress: Callable[[], None] | None,
    ) -> None:
        self.log, self.state, self.sidecar = log, state, sidecar
        self.flush_interval = flush_interval
        self.on_progress = on_progress
        self.error: OSError | None = None
        """The CSV write that failed (disk full): the run stops."""
        self.crash: BaseException | None = None
        """An unexpected error in the thread (a callback's): the run stops and it is raised."""
        self.stop = threading.Event()
        self._last_flush = time.monotonic()
        self._thread = threading.Thread(target=self._run, name="record-writer", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def join(self) -> None:
        self.stop.set()
        self._thread.join()

    def flush(self) -> None:
        """Write the pending rows; a write error is kept in :attr:`error` and stops further writes."""
        with self.state.lock:
            rows, self.state.pending_rows = self.state.pending_rows, []
        if rows and self.error is None:
            try:
                self.log.append(rows)
            except OSError as err:
                self.error = err
        self._last_flush = time.monotonic()

    def _run(self) -> None:
        every = min(self.flush_interval, SIDECAR_EVERY)
        try:
            while not self.stop.wait(every):
                if time.monotonic() - self._last_flush >= self.flush_interval - 1e-3:
                    self.flush()
                try:
                    self.sidecar()
                except OSError:
                    pass  # the CSV is what matters; the next rewrite or the end tries again
                if self.on_progress is not None:
                    self.on_progress()
        except BaseException as err:  # noqa: BLE001 - handed to the sampling loop, which raises it
            self.crash = err


def record(
    read_sample: Callable[[], Mapping[str, float]],
    columns: Sequence[str],
    out: Path,
    *,
    rate_hz: float,
    duration: float | None = None,
    policy: RetryPolicy = RetryPolicy(),
    flush_interval: float = 0.25,
    overwrite: bool = False,
    metadata: Mapping[str, Any] | None = None,
    live: Callable[[], Mapping[str, Any]] | None = None,
    on_progress: Callable[[RecordResult], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
) -> RecordResult:
    """Sample ``read_sample`` at ``rate_hz`` into ``out`` until ``duration`` [s], Ctrl-C or ``should_stop``.

    Args:
        read_sample: Returns {column: SI value} for every column, or raises :class:`ReadError`.
        columns: Column order of the CSV (after ``time``).
        out: CSV path (written as the run goes; locked while recording).
        rate_hz: Sampling rate [Hz], within :data:`RATE_LIMITS`.
        duration: Stop after this many seconds (None: until interrupted).
        policy: Retries, when to give up, when a blocked read is a hung peer.
        flush_interval: Longest time between writes of rows to disk [s] (what a SIGKILL can lose).
        overwrite: Replace a log already at ``out`` once the first sample is in (:class:`CsvLog`).
        metadata: Extra fields for the sidecar (rig file, ...).
        live: Extra fields read at every sidecar rewrite (transport error counters); called from the
            writer thread.
        on_progress: Called with the running totals at every sidecar rewrite (from the writer thread).
        should_stop: Polled every tick; True ends the run as ``complete``.

    Returns:
        The run's totals; ``status`` is failed when reads failed for longer than ``give_up_after`` or
        no sample was read.

    Raises:
        DynoDataError: A setting out of range (:func:`check_settings`).
        OutputError: The CSV cannot be created, another recorder holds it, or a write failed during the
            run (disk full): then the file holds whole rows only, the sidecar says ``failed``, and the
            error carries ``rows`` and ``result``.
    """
    check_settings(rate_hz, duration, flush_interval)
    log = CsvLog(out, columns, overwrite)
    started = datetime.now(timezone.utc).isoformat(timespec="milliseconds")
    state = _State(1.0 / rate_hz, policy.stall_after)
    run = _Run(log, out, sidecar_path(out), started, rate_hz, flush_interval, metadata, live, state, time.monotonic())
    run.first_sidecar()
    writer = _Writer(log, state, run.write_sidecar, flush_interval, _progress(run, on_progress))
    writer.start()
    try:
        _sample(run, writer, read_sample, columns, duration, policy, should_stop)
    except KeyboardInterrupt:
        run.status = "interrupted"
    finally:
        final, write_error = _finish(run, writer)
    _raise_failure(run, writer, final, write_error)
    return final


@dataclass
class _Run:
    """One run's files, settings and outcome so far (``status``, ``message``, ``stop_t``), read by the writer thread
    through :meth:`snapshot`."""

    log: CsvLog
    out: Path
    side: Path
    started: str
    rate_hz: float
    flush_interval: float
    metadata: Mapping[str, Any] | None
    live: Callable[[], Mapping[str, Any]] | None
    state: _State
    t0: float
    status: str = "recording"
    message: str = ""
    stop_t: float | None = None

    def result(self, now: float, gaps: Sequence[Gap], lost: int) -> RecordResult:
        """The run's totals at monotonic time ``now``, with its ``gaps`` and the ticks ``lost`` in them."""
        elapsed = max(now - self.t0, 1e-9)
        rows = self.log.rows
        return RecordResult(
            self.out,
            self.side,
            self.status,
            rows,
            self.state.missed,
            lost,
            elapsed,
            rows / elapsed,
            tuple(gaps),
            self.message,
        )

    def snapshot(self) -> tuple[RecordResult, dict[str, Any]]:
        """The running totals and what the sidecar says now."""
        now, state, stop_t = time.monotonic(), self.state, self.stop_t
        with state.lock:
            gaps, lost = state.all_gaps(
                None if stop_t is not None else now, now - self.t0 if stop_t is None else stop_t
            )
            r = self.result(now, gaps, lost)
            longest = state.max_interval
            faults = list(state.faults)
        data = {
            "schema": SCHEMA,
            "status": r.status,
            "message": r.message,
            "software": f"hound-id {__version__}",
            "pid": os.getpid(),
            "started": self.started,
            "updated": datetime.now(timezone.utc).isoformat(timespec="milliseconds"),
            "rate_requested": self.rate_hz,
            "rate_achieved": r.achieved_rate,
            "duration": r.duration,
            "samples": r.samples,
            "missed_ticks": r.missed,
            "longest_interval": longest,
            "failed_ticks": r.failed,
            "gaps": [g.to_dict() for g in r.gaps],
            "faults": faults,
            "columns": self.log.columns,
            "flush_interval": self.flush_interval,
            **dict(self.metadata or {}),
            **dict(self.live() if self.live is not None else {}),
        }
        return r, data

    def write_sidecar(self) -> None:
        """Rewrite the sidecar (beside the hidden file until it replaces an old log)."""
        save_sidecar(sidecar_path(self.log.writing), self.snapshot()[1])

    def first_sidecar(self) -> None:
        """Write the first sidecar; if it cannot be written, release the log and raise :class:`OutputError`."""
        try:
            self.write_sidecar()
        except OSError as err:
            self.log.close()
            raise OutputError(
                f"{sidecar_path(self.log.writing)}: cannot write ({err.strerror or err}); choose another --out",
                path=str(self.side),
            ) from err


def _progress(run: _Run, on_progress: Callable[[RecordResult], None] | None) -> Callable[[], None] | None:
    """What the writer calls at every sidecar rewrite: ``on_progress`` with the running totals (None: nothing)."""
    if on_progress is None:
        return None
    callback = on_progress

    def progress() -> None:
        callback(run.snapshot()[0])

    return progress


def _sample(
    run: _Run,
    writer: _Writer,
    read_sample: Callable[[], Mapping[str, float]],
    columns: Sequence[str],
    duration: float | None,
    policy: RetryPolicy,
    should_stop: Callable[[], bool] | None,
) -> None:
    """The sampling loop: one tick per period until the duration, ``should_stop``, a write error, a crash of the
    writer, or reads failing for longer than ``policy.give_up_after``; it books every tick in ``run.state`` and sets
    ``run.status`` and ``run.message`` when it ends the run itself."""
    state, t0, period = run.state, run.t0, run.state.period
    first_failure: float | None = None
    tick = 0
    while writer.error is None and writer.crash is None:
        due = t0 + tick * period
        if (duration is not None and due - t0 >= duration) or (should_stop is not None and should_stop()):
            run.status = "complete"
            return
        now = time.monotonic()
        if now < due:
            time.sleep(due - now)
        elif now - due > period:  # late by more than a period: skip to the next tick due in the future
            skip = _skipped(now, due, period, duration, tick)
            if skip == 0:
                run.status = "complete"
                return
            with state.lock:
                state.skip(skip)
            tick += skip
            continue
        state.reading_due = due
        since = state.reading_since = time.monotonic()
        sample, error, before, after = _read(read_sample, policy.retries, since)
        state.reading_since = None
        if sample is None:
            with state.lock:
                state.fail(error)
            now = time.monotonic()
            first_failure = first_failure if first_failure is not None else now
            if now - first_failure > policy.give_up_after:
                run.status = "failed"
                run.message = f"reads failed for more than {policy.give_up_after:g} s; last error: {error}"
                return
        else:
            first_failure = None
            t, held = _stamp(before, after, error, policy.stall_after)
            t -= t0
            with state.lock:
                state.take(t, _row(t, sample, columns), held)
        tick += 1


def _skipped(now: float, due: float, period: float, duration: float | None, tick: int) -> int:
    """Ticks to skip when tick ``tick`` (due at monotonic ``due``) is late by more than a ``period`` at ``now`` [s];
    0 when every tick left is past the end of a run of ``duration`` [s]."""
    skip = int((now - due) / period)
    if duration is not None:  # ticks past the end of the run are not missed: they were never due
        skip = min(skip, max(math.ceil(duration / period - 1e-9) - tick, 0))
    return skip


def _read(
    read_sample: Callable[[], Mapping[str, float]], retries: int, since: float
) -> tuple[Mapping[str, float] | None, str, float, float]:
    """One tick's read, retried ``retries`` times: (the sample or None, the last failure's message, the monotonic
    times the successful attempt began and ended; both ``since`` if no attempt ran)."""
    sample, error = None, ""
    before = after = since
    for _ in range(retries + 1):
        before = time.monotonic()
        try:
            sample = read_sample()
            after = time.monotonic()
            break
        except ReadError as err:
            error = str(err)
    return sample, error, before, after


def _stamp(before: float, after: float, error: str, stall_after: float) -> tuple[float, str]:
    """A sample's monotonic time stamp [s] and why its read held the loop up ("" for a plain read), from its read's
    begin and end [s], the failed attempts' last message, and how long a read blocks before it is a hung peer [s]."""
    stalled = after - before > stall_after
    # the loop was held up by a hung read, or by attempts that failed before this one
    held = f"a read blocked for {after - before:.2f} s" if stalled else error
    # a row is stamped at the middle of its read; a hung peer answered at the end of it
    return (after if stalled else 0.5 * (before + after)), held


def _row(t: float, sample: Mapping[str, float], columns: Sequence[str]) -> str:
    """The CSV row of a sample at ``t`` [s since the start]."""
    # numbers only, so a plain join is valid CSV; repr keeps every digit of the float
    return f"{t:.6f}," + ",".join([repr(float(sample[c])) for c in columns]) + "\n"


def _finish(run: _Run, writer: _Writer) -> tuple[RecordResult, OSError | None]:
    """End a run, however it ended: stop the writer, write the last rows, sync, settle the status and message,
    write the final sidecar and close the log (removing a new file that got no sample). Returns the final result
    and the write error of the sync or the final sidecar, if any."""
    log, out, side = run.log, run.out, run.side
    writer.join()
    writer.flush()
    run.stop_t = stop_t = time.monotonic() - run.t0
    if writer.error is None:
        try:
            log.sync()
        except OSError as err:
            writer.error = err
    write_error = writer.error
    run.status, run.message = _outcome(run.status, run.message, write_error, log.rows, stop_t, run.state.faults)
    kept = not log.replaced
    if kept and log.rows == 0 and run.status != "failed":  # Ctrl-C before the first sample
        run.message = "stopped before the first sample"
    if kept:
        run.message = f"{run.message}; {out} was left as it was" if run.message else f"{out} was left as it was"
    final, data = run.snapshot()
    final = dataclasses.replace(final, metadata=MappingProxyType(data), kept_existing=kept)
    try:
        save_sidecar(sidecar_path(log.writing), data)
    except OSError as err:
        if write_error is None:
            write_error = err
    log.close()
    if log.rows == 0 and log.created and log.replaced and write_error is None:  # a new file with no sample
        for made in (out, side):
            made.unlink(missing_ok=True)
        said = final.message or "stopped before the first sample"
        final = dataclasses.replace(final, message=f"{said}; nothing was written", kept_existing=True)
    return final, write_error


def _outcome(
    status: str, message: str, write_error: OSError | None, rows: int, stop_t: float, faults: Sequence[str]
) -> tuple[str, str]:
    """The run's final status and message from the loop's, a write error, the rows on disk, the stop time [s since
    the start] and the faults."""
    if write_error is not None:
        status = "failed"
        message = (
            f"cannot write the log ({write_error.strerror or write_error}) after {rows} rows "
            f"({stop_t:.1f} s); the file holds whole rows only"
        )
    elif status == "complete" and rows == 0:
        status = "failed"
        message = "no sample was read" + (f"; last error: {faults[-1]}" if faults else "")
    if status == "recording":  # an unexpected exception: say so in the sidecar, then let it propagate
        status, message = "failed", "the recorder stopped on an unexpected error"
    return status, message


def _raise_failure(run: _Run, writer: _Writer, final: RecordResult, write_error: OSError | None) -> None:
    """Raise what stopped the writer (its crash, or the log's write error), or the final sidecar's write error."""
    if writer.crash is not None:
        raise writer.crash
    if writer.error is not None:
        raise OutputError(
            f"{run.out}: {run.message}; free space on the disk (or choose another --out) and record again",
            path=str(run.out),
            rows=final.samples,
            result=final,
        ) from writer.error
    if write_error is not None:
        raise OutputError(
            f"{run.side}: cannot write the sidecar ({getattr(write_error, 'strerror', None) or write_error}); "
            f"the log {run.out} holds {final.samples} rows",
            path=str(run.side),
            result=final,
        ) from write_error
