"""``hound-id dyno record``: a rig file in, a recorded log out (the verb the CLI calls).

It sits above :mod:`~hound_id.dyno.acquire.recorder` and :mod:`~hound_id.dyno.acquire.transport` (the transport
imports the recorder's error type), so that neither has to import the other to run a session.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from hound_id.dyno.acquire.recorder import RecordResult, check_free, check_settings, record
from hound_id.io import check_output


def record_rig(
    rig: Path,
    out: Path,
    *,
    rate_hz: float,
    duration: float | None,
    flush_interval: float,
    on_progress: Callable[[Any], None] | None = None,
) -> RecordResult:
    """Check the output and the settings, load the rig file, open its transports and record until ``duration``
    [s] (or Ctrl-C); the sidecar carries the rig file, its name and the transports' error counts."""
    from hound_id.dyno.acquire.rig import load_rig
    from hound_id.dyno.acquire.transport import RigReader

    check_output(out, (".csv",), "log")
    check_settings(rate_hz, duration, flush_interval)
    check_free(out)
    rig_spec = load_rig(rig)
    with RigReader(rig_spec) as reader:
        return record(
            reader.read_sample,
            list(rig_spec.columns),
            out,
            rate_hz=rate_hz,
            duration=duration,
            flush_interval=flush_interval,
            metadata={"rig": str(rig.resolve()), "rig_name": rig_spec.name},
            live=lambda: {"transport_errors": reader.faults()},
            on_progress=on_progress,
        )
