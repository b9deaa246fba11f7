"""The verbs of ``hound-id dyno record`` (a rig file in, a recorded log out) and ``dyno simulate-rig``.

It sits above :mod:`~hound_id.dyno.acquire.recorder` and :mod:`~hound_id.dyno.acquire.transport` (the transport
imports the recorder's error type), so that neither has to import the other to run a session.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hound_id.dyno.acquire.log_file import check_existing, check_free
from hound_id.dyno.acquire.recorder import RecordResult, check_settings, record
from hound_id.errors import DynoDataError
from hound_id.io import check_output

if TYPE_CHECKING:
    from hound_id.dyno.acquire.simulated_rig import SimulatedRig


def record_rig(
    rig: Path,
    out: Path,
    *,
    rate_hz: float,
    duration: float | None,
    flush_interval: float,
    overwrite: bool = False,
    on_progress: Callable[[Any], None] | None = None,
) -> RecordResult:
    """Check the output and the settings, load the rig file, open its transports and record until ``duration``
    [s] (or Ctrl-C); the sidecar carries the rig file, its name and the transports' error counts. A log already
    at ``out`` is refused unless ``overwrite``, and then replaced only once the first sample is in."""
    from hound_id.dyno.acquire.rig_file import load_rig
    from hound_id.dyno.acquire.transport import RigReader

    check_output(out, (".csv",), "log", inputs=(rig,))
    check_settings(rate_hz, duration, flush_interval)
    check_free(out)
    check_existing(out, overwrite, (rig,))
    rig_spec = load_rig(rig)
    with RigReader(rig_spec) as reader:
        return record(
            reader.read_sample,
            list(rig_spec.columns),
            out,
            rate_hz=rate_hz,
            duration=duration,
            flush_interval=flush_interval,
            overwrite=overwrite,
            metadata={"rig": str(rig.resolve()), "rig_name": rig_spec.name},
            live=lambda: {"transport_errors": reader.faults()},
            on_progress=on_progress,
        )


#: Current rise time of the simulated rig's default test plan [s]: a polled rig samples at most about 1 kHz, so the
#: plan's current edges take 10 ms and are resolved (a real drive's are sharper; the plan, not the rig, sets them).
RIG_CURRENT_RISE = 0.01


def serve_simulated_rig(
    effects: Sequence[str],
    rig_out: Path,
    *,
    seed: int = 0,
    plan: Path | None = None,
    port: int = 5020,
    speedup: float = 1.0,
    serial: bool = True,
    duration: float | None = None,
) -> SimulatedRig:
    """``hound-id dyno simulate-rig``: check the options, start a simulated motor and torque transducer over Modbus
    TCP (and a serial pty) on 127.0.0.1 playing ``plan`` (default: the standard plan with :data:`RIG_CURRENT_RISE`),
    and write its rig file to ``rig_out``. Returns the running rig; the caller serves for ``duration`` (checked here)
    and stops it."""
    import yaml

    from hound_id import io
    from hound_id.dyno.acquire.simulated_rig import SimulatedRig, check_speedup
    from hound_id.dyno.simulate.current import SimMotor, TestPlan

    check_output(rig_out, (".yaml", ".yml"), "rig", inputs=(plan,))
    if not effects:
        raise DynoDataError("--effects: found none, expected effects joined by ',' (e.g. linear,saturation)")
    if duration is not None and not (math.isfinite(duration) and duration > 0):
        raise DynoDataError(
            f"--duration: found {duration:g}, expected a positive number of seconds (leave it out to serve until "
            "Ctrl-C)",
            duration=duration,
        )
    if not 0 <= port <= 65535:
        raise DynoDataError(f"--port: found {port}, expected 0 to 65535 (0: any free port)", port=port)
    if seed < 0:
        raise DynoDataError(f"--seed: found {seed}, expected an integer >= 0", seed=seed)
    check_speedup(speedup, "--speedup")
    test_plan, motor = TestPlan(current_rise_time=RIG_CURRENT_RISE), SimMotor()
    if plan is not None:
        from hound_id.dyno.acquire.plan import load_plan

        test_plan, max_current = load_plan(plan)
        motor = SimMotor(max_current=max_current)
    sim = SimulatedRig(
        tuple(effects), seed=seed, motor=motor, plan=test_plan, port=port, serial=serial, speedup=speedup
    )
    sim.start()
    try:
        io.write_text(rig_out, yaml.safe_dump(sim.rig_mapping(), sort_keys=False))
    except BaseException:
        sim.stop()
        raise
    return sim
