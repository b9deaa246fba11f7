"""Recording a dyno log: paced sampling, a streaming CSV that survives crashes, a metadata sidecar.

The recorder is transport-agnostic: it calls ``read_sample()`` once per tick of a
monotonic clock at the requested rate, and writes each complete sample as one CSV row
(``time`` in seconds since the start, then the rig's columns, SI units). Rows are
flushed to the operating system at least every ``flush_interval`` seconds, so a SIGKILL
loses at most that much; Ctrl-C (KeyboardInterrupt) or a stop request ends the run
cleanly with everything recorded so far on disk.

Pacing: tick k is due at t0 + k / rate; its row is stamped with the middle of the read
that produced it (the reads of several devices take a round trip each). A tick whose read starts more than one period
late is not taken (the recorder never bunches samples to catch up); it is counted as
missed. A read that fails (timeout, exception response, disconnect, malformed line)
is retried by the :class:`RetryPolicy`; if it still fails, the tick is a gap: no row is
written, the gap is recorded in the sidecar, and recording goes on unless the device has
been failing for longer than ``give_up_after`` seconds.

The sidecar ``<out>.meta.json`` (schema ``hound-id/record/1``) is rewritten atomically at
the start, at every flush and at the end: rig file, start time, software version,
requested and achieved rate, samples, missed ticks, gaps and faults, and the status
(``recording``, ``complete``, ``interrupted``, ``failed``).
"""

from __future__ import annotations

import csv
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, TextIO

from hound_id import __version__, io
from hound_id.errors import DynoDataError, HoundIdError, OutputError

SCHEMA = "hound-id/record/1"


class ReadError(HoundIdError, OSError):
    """One read of the rig failed (timeout, exception response, disconnect, malformed line)."""


@dataclass(frozen=True)
class RetryPolicy:
    """What the recorder does when a read fails."""

    retries: int = 2
    """Immediate retries of a failed read within the same tick."""
    give_up_after: float = 5.0
    """Stop the run when reads have failed without a break for this long [s]."""


@dataclass(frozen=True)
class Gap:
    """A stretch of ticks without a sample."""

    start: float
    """Time of the first missing tick since the start [s]."""
    end: float
    """Time of the last missing tick [s]."""
    ticks: int
    """Ticks lost."""
    reason: str
    """The last failure's message."""

    def to_dict(self) -> dict[str, Any]:
        return {"start": self.start, "end": self.end, "ticks": self.ticks, "reason": self.reason}


@dataclass
class _Progress:
    samples: int = 0
    last_t: float | None = None
    max_interval: float = 0.0
    missed: int = 0
    failed: int = 0
    gaps: list[Gap] = field(default_factory=list)
    faults: list[str] = field(default_factory=list)
    open_gap: tuple[float, float, int, str] | None = None

    def fail(self, t: float, reason: str) -> None:
        self.failed += 1
        if self.open_gap is None:
            self.open_gap = (t, t, 1, reason)
        else:
            start, _, n, _ = self.open_gap
            self.open_gap = (start, t, n + 1, reason)
        if not self.faults or self.faults[-1] != reason:
            self.faults.append(reason)

    def close_gap(self) -> None:
        if self.open_gap is not None:
            self.gaps.append(Gap(*self.open_gap))
            self.open_gap = None


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
    """Rows written."""
    missed: int
    """Ticks skipped because the loop was late."""
    failed: int
    """Ticks lost to read failures."""
    duration: float
    """Wall time from start to stop [s]."""
    achieved_rate: float
    """samples / duration [Hz]."""
    gaps: tuple[Gap, ...]
    """Stretches without samples."""
    message: str = ""
    """Why a failed run stopped."""


class CsvLog:
    """A CSV file written row by row and flushed at a fixed interval (crash-safe up to that interval)."""

    def __init__(self, path: Path, columns: Sequence[str], flush_interval: float) -> None:
        io.check_output(path, (".csv",), "log")
        self.path = path
        self.columns = ["time", *columns]
        self.flush_interval = flush_interval
        try:
            # A buffer larger than a flush interval's rows: rows reach the OS only whole, at our flushes.
            self._file: TextIO = path.open("w", newline="", encoding="utf-8", buffering=1 << 20)
        except OSError as err:
            raise OutputError(f"{path}: cannot write ({err.strerror or err})", path=str(path)) from err
        csv.writer(self._file).writerow(self.columns)
        self._value_columns = self.columns[1:]
        self._file.flush()
        self._last_flush = time.monotonic()

    def write(self, t: float, values: Mapping[str, float]) -> bool:
        """Append one row; returns True when it flushed."""
        # numbers only, so a plain join is valid CSV; repr keeps every digit of the float
        self._file.write(f"{t:.6f}," + ",".join([repr(float(values[c])) for c in self._value_columns]) + "\n")
        now = time.monotonic()
        if now - self._last_flush >= self.flush_interval:
            self.flush()
            return True
        return False

    def flush(self) -> None:
        self._file.flush()
        self._last_flush = time.monotonic()

    def close(self) -> None:
        self._file.flush()
        os.fsync(self._file.fileno())
        self._file.close()


def sidecar_path(out: Path) -> Path:
    """``run.csv`` -> ``run.csv.meta.json``."""
    return out.with_name(out.name + ".meta.json")


def record(
    read_sample: Callable[[], Mapping[str, float]],
    columns: Sequence[str],
    out: Path,
    *,
    rate_hz: float,
    duration: float | None = None,
    policy: RetryPolicy = RetryPolicy(),
    flush_interval: float = 0.25,
    metadata: Mapping[str, Any] | None = None,
    on_progress: Callable[[RecordResult], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
) -> RecordResult:
    """Sample ``read_sample`` at ``rate_hz`` into ``out`` until ``duration`` [s], Ctrl-C or ``should_stop``.

    Args:
        read_sample: Returns {column: SI value} for every column, or raises :class:`ReadError`.
        columns: Column order of the CSV (after ``time``).
        out: CSV path (written as the run goes).
        rate_hz: Sampling rate [Hz].
        duration: Stop after this many seconds (None: until interrupted).
        policy: Retries and when to give up.
        flush_interval: Longest time between flushes [s] (what a SIGKILL can lose).
        metadata: Extra fields for the sidecar (rig file, ...).
        on_progress: Called at every flush with the running totals.
        should_stop: Polled every tick; True ends the run as ``complete``.
    """
    if not (rate_hz > 0 and math.isfinite(rate_hz)):
        raise DynoDataError(f"--rate: found {rate_hz}, expected a positive sampling rate in Hz")
    if duration is not None and not duration > 0:
        raise DynoDataError(f"--duration: found {duration}, expected a positive number of seconds")
    if not flush_interval > 0:
        raise DynoDataError(f"--flush: found {flush_interval}, expected a positive number of seconds")
    log = CsvLog(out, columns, flush_interval)
    side = sidecar_path(out)
    started = datetime.now(timezone.utc).isoformat(timespec="milliseconds")
    period = 1.0 / rate_hz
    progress = _Progress()
    status, message = "recording", ""
    t0 = time.monotonic()
    first_failure: float | None = None

    def result(now: float) -> RecordResult:
        elapsed = max(now - t0, 1e-9)
        gaps = (*progress.gaps, *([Gap(*progress.open_gap)] if progress.open_gap else []))
        return RecordResult(
            out,
            side,
            status,
            progress.samples,
            progress.missed,
            progress.failed,
            elapsed,
            progress.samples / elapsed,
            gaps,
            message,
        )

    def write_sidecar(now: float) -> None:
        r = result(now)
        io.write_json(
            side,
            {
                "schema": SCHEMA,
                "status": r.status,
                "message": r.message,
                "software": f"hound-id {__version__}",
                "started": started,
                "rate_requested": rate_hz,
                "rate_achieved": r.achieved_rate,
                "duration": r.duration,
                "samples": r.samples,
                "missed_ticks": r.missed,
                "longest_interval": progress.max_interval,
                "failed_ticks": r.failed,
                "gaps": [g.to_dict() for g in r.gaps],
                "faults": progress.faults[-50:],
                "columns": log.columns,
                "flush_interval": flush_interval,
                **dict(metadata or {}),
            },
        )

    write_sidecar(t0)
    tick = 0
    try:
        while True:
            due = t0 + tick * period
            if duration is not None and due - t0 >= duration:
                status = "complete"
                break
            if should_stop is not None and should_stop():
                status = "complete"
                break
            now = time.monotonic()
            if now < due:
                time.sleep(due - now)
            elif now - due > period:  # late by more than a period: skip to the next tick due in the future
                skip = int((now - due) / period)
                progress.missed += skip
                tick += skip
                continue
            t = due - t0
            sample, error = None, ""
            for _ in range(policy.retries + 1):
                before = time.monotonic()
                try:
                    sample = read_sample()
                    # stamp the row at the middle of the read that produced it, not at the tick it was due
                    t = 0.5 * (before + time.monotonic()) - t0
                    break
                except ReadError as err:
                    error = str(err)
            if sample is None:
                progress.fail(t, error)
                first_failure = first_failure if first_failure is not None else time.monotonic()
                if time.monotonic() - first_failure > policy.give_up_after:
                    status = "failed"
                    message = f"reads failed for more than {policy.give_up_after:g} s; last error: {error}"
                    break
            else:
                progress.close_gap()
                first_failure = None
                if progress.last_t is not None:
                    progress.max_interval = max(progress.max_interval, t - progress.last_t)
                progress.last_t = t
                if log.write(t, sample):
                    write_sidecar(time.monotonic())
                    if on_progress is not None:
                        on_progress(result(time.monotonic()))
                progress.samples += 1
            tick += 1
    except KeyboardInterrupt:
        status = "interrupted"
    finally:
        progress.close_gap()
        log.close()
        if status == "complete" and progress.samples == 0:
            status = "failed"
            message = "no sample was read" + (f"; last error: {progress.faults[-1]}" if progress.faults else "")
        if status == "recording":  # an unexpected exception: say so in the sidecar, then let it propagate
            status, message = "failed", "the recorder stopped on an unexpected error"
        write_sidecar(time.monotonic())
    return result(time.monotonic())
