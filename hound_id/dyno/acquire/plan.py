"""Dyno test plans: what the rig does so that every effect of the library is identifiable.

A plan (schema ``hound-id/plan/1``) is the :class:`~hound_id.dyno.simulate.schedule.TestPlan`
parameters plus the application's maximum current, with the reason for each part:

* speed plateaus of both signs (four quadrants: motoring and braking);
* near-zero plateaus (+-2 rad/s) for Coulomb and Stribeck friction;
* several speeds for viscous drag;
* at every plateau, current ramps and steps up to ``overdrive`` x the maximum current,
  beyond the application's range, for the saturation curve and the 20 % point;
* fast steps whose edges the torque channel must follow, for the delay;
* at the faster plateaus the rotor turns many times during the excitation, for cogging
  and ripple;
* a hold at the maximum current to warm the winding, for the thermal drift of Kt;
* pauses at zero current that bound the heating and give friction and cogging data.

:func:`schedule` samples the set-points (current and speed against time) for a rig
controller to follow.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hound_id import io
from hound_id.dyno.simulate.current import SimMotor, TestPlan
from hound_id.errors import DynoDataError, OutputError, SpecError
from hound_id.io import read_yaml

#: Maximum currents a plan accepts [A]: a motor spec's max_current span (hound_id.mor.spec_sheet.PLAUSIBLE).
MAX_CURRENT_SPAN = (1e-3, 1e4)
SCHEMA = "hound-id/plan/1"
#: Longest plan [s]. simulate-rig and the set-point schedule sample a plan at 1 kHz: an hour is 3.6 M rows.
MAX_PLAN_SECONDS = 3600.0
#: Command-line option of each TestPlan field (for messages).
OPTIONS: dict[str, str] = {
    "speeds": "--speeds",
    "current_levels": "--levels",
    "overdrive": "--overdrive",
    "plateau_time": "--plateau",
    "pause_time": "--pause",
    "hold_time": "--hold",
    "transition_time": "--transition",
    "current_rise_time": "--rise",
}

RATIONALE = {
    "speeds": "plateaus of both signs cover the four quadrants; +-2 rad/s reveals Coulomb and Stribeck friction, "
    "several speeds separate viscous drag",
    "current_levels": "step levels of both signs at every plateau map the current-torque curve",
    "overdrive": "ramps and the top step go beyond the application's maximum current, so the curve's 20 % point "
    "is measured, not extrapolated",
    "shape": "ramps sweep the curve continuously; steps give the fast edges that reveal the torque channel's delay",
    "plateau_time": "at the faster plateaus the rotor turns many times during the excitation, for cogging and "
    "ripple; the slow ones give friction near rest",
    "pause_time": "zero current between plateaus bounds the winding's heating and records friction and cogging",
    "hold_time": "one hold at the maximum current warms the winding, so the thermal drift of Kt shows",
    "transition_time": "speed changes happen at zero current",
    "current_rise_time": "the edge time a current loop achieves",
    "bus_voltage": "open-circuit supply voltage of the rig",
    "bus_sag": "supply sag per amp (assumed)",
}


def plan_mapping(plan: TestPlan, max_current: float) -> dict[str, Any]:
    """The YAML content of a plan (schema ``hound-id/plan/1``)."""
    fields = {f.name: getattr(plan, f.name) for f in dataclasses.fields(plan)}
    fields["speeds"] = list(plan.speeds)
    return {"schema": SCHEMA, "max_current": max_current, "duration": plan.duration, **fields, "why": dict(RATIONALE)}


def make_plan(
    max_current: float,
    *,
    speeds: Sequence[float] | None = None,
    levels: int | None = None,
    overdrive: float | None = None,
    plateau: float | None = None,
    pause: float | None = None,
    hold: float | None = None,
    transition: float | None = None,
    rise: float | None = None,
) -> TestPlan:
    """The default :class:`TestPlan` with the given parts changed; None keeps a default.

    Args:
        max_current: The application's maximum current [A], positive.
        speeds: Plateau speeds [rad/s], finite.
        levels: Current step levels per sign, >= 1.
        overdrive: Top level / max current, > 1 (the plan measures beyond the application's range).
        plateau: Current excitation per plateau [s], > 0.
        pause: Zero-current pause after each plateau [s], >= 0.
        hold: Hold at max current [s], >= 0.
        transition: Speed change between plateaus [s], > 0.
        rise: Duration of each current edge [s], > 0 and shorter than the shortest step.

    Raises:
        DynoDataError: A value out of range; the message names the option (``--rise``).
    """
    if not (math.isfinite(max_current) and MAX_CURRENT_SPAN[0] <= max_current <= MAX_CURRENT_SPAN[1]):
        raise DynoDataError(
            f"--max-current: found {max_current:g}, expected {MAX_CURRENT_SPAN[0]:g} to {MAX_CURRENT_SPAN[1]:g} A "
            "(the span of real motor drives); check the number and its unit",
            value=max_current,
        )
    changes: dict[str, Any] = {}
    if speeds is not None:
        if not speeds or not all(math.isfinite(w) for w in speeds):
            found = ",".join(f"{w:g}" for w in speeds)
            raise DynoDataError(f"--speeds: found '{found}', expected finite speeds in rad/s such as -40,-2,2,40")
        changes["speeds"] = tuple(float(w) for w in speeds)
    if levels is not None:
        if not levels >= 1:
            raise DynoDataError(f"--levels: found {levels}, expected an integer >= 1", value=levels)
        changes["current_levels"] = int(levels)
    if overdrive is not None:
        if not (math.isfinite(overdrive) and overdrive > 1):
            raise DynoDataError(
                f"--overdrive: found {overdrive:g}, expected a number > 1: the plan drives beyond the maximum "
                "current to measure the saturation curve (1.3 by default)",
                value=overdrive,
            )
        changes["overdrive"] = float(overdrive)
    for name, value, positive in (
        ("plateau_time", plateau, True),
        ("pause_time", pause, False),
        ("hold_time", hold, False),
        ("transition_time", transition, True),
        ("current_rise_time", rise, True),
    ):
        if value is None:
            continue
        if not (math.isfinite(value) and (value > 0 if positive else value >= 0)):
            expected = "a positive number of seconds" if positive else "a number of seconds >= 0"
            raise DynoDataError(f"{OPTIONS[name]}: found {value:g}, expected {expected}", value=value)
        changes[name] = float(value)
    try:
        plan = TestPlan(**changes)
    except DynoDataError as err:
        text = err.message.replace("TestPlan: ", "").replace("TestPlan.", "")
        for name, option in OPTIONS.items():
            text = text.replace(f"{name} = ", f"{option} ").replace(name, option)
        raise DynoDataError(text, **err.details) from err
    if plan.duration > MAX_PLAN_SECONDS:
        raise DynoDataError(
            f"the plan lasts {plan.duration:g} s, expected at most {MAX_PLAN_SECONDS:g} s (it is sampled at 1 kHz); "
            "shorten --plateau, --pause, --hold or --transition, or use fewer --speeds",
            duration=plan.duration,
        )
    return plan


def write_plan(plan: TestPlan, max_current: float, out: Path, schedule_out: Path | None = None) -> dict[str, Any]:
    """Write the plan YAML and, optionally, its set-points table: all files or none.

    Every file is written to a temporary file beside its target first; only when all are written
    are they renamed into place, so a failure (a folder that cannot be written, a full disk)
    leaves no output behind.

    Args:
        plan: The plan.
        max_current: The application's maximum current [A].
        out: Plan YAML path.
        schedule_out: Set-points table (.csv or .parquet), or None.

    Returns:
        The plan mapping written (schema ``hound-id/plan/1``).

    Raises:
        OutputError: A file could not be written; nothing was left behind.
    """
    import yaml

    from hound_id.tables import write_table

    data = plan_mapping(plan, max_current)
    staged: list[tuple[Path, Path]] = []
    try:
        tmp = _stage(out)
        staged.append((tmp, out))
        io.write_text(tmp, yaml.safe_dump(data, sort_keys=False))
        if schedule_out is not None:
            tmp = _stage(schedule_out)
            staged.append((tmp, schedule_out))
            write_table(schedule(plan, max_current), tmp)
        for k, (tmp, target) in enumerate(staged):
            try:
                os.replace(tmp, target)
            except OSError as err:
                for _, done in staged[:k]:  # undo the renames before it: all or nothing
                    done.unlink(missing_ok=True)
                raise OutputError(f"{target}: cannot write ({err.strerror or err})", path=str(target)) from err
    except OutputError as err:
        message = err.message
        for tmp, target in staged:  # name the file the user asked for, not its temporary stand-in
            message = message.replace(str(tmp), str(target))
        raise OutputError(f"{message}; no plan file was written", path=str(staged[-1][1] if staged else out)) from err
    finally:
        for tmp, _ in staged:
            tmp.unlink(missing_ok=True)
    return data


def _stage(target: Path) -> Path:
    """An empty temporary file beside ``target`` with the same suffix (so writers pick the same format)."""
    folder = target.parent if str(target.parent) else Path(".")
    try:
        fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=f".part{target.suffix}", dir=folder)
    except OSError as err:
        raise OutputError(
            f"{target}: cannot write ({err.strerror or err}); choose a folder you can write to", path=str(target)
        ) from err
    os.close(fd)
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(name, 0o666 & ~mask)  # mkstemp makes 0600; outputs get the usual permissions
    return Path(name)


def load_plan(path: str | Path) -> tuple[TestPlan, float]:
    """A plan file -> (TestPlan, max_current [A])."""
    data = read_yaml(path, "plan")
    if not isinstance(data, dict) or data.get("schema") != SCHEMA:
        raise SpecError(f"{path}: expected a test plan with 'schema: {SCHEMA}' (write one with hound-id dyno plan)")
    known = {f.name for f in dataclasses.fields(TestPlan)}
    extra = set(data) - known - {"schema", "max_current", "duration", "why"}
    if extra:
        raise SpecError(
            f"{path}: unknown key(s) {', '.join(sorted(map(str, extra)))}; known: {', '.join(sorted(known))}"
        )
    max_current = data.get("max_current")
    lo, hi = MAX_CURRENT_SPAN
    if not isinstance(max_current, (int, float)) or isinstance(max_current, bool) or not lo <= max_current <= hi:
        raise SpecError(f"{path}: field 'max_current': found {max_current!r}, expected {lo:g} to {hi:g} A")
    args = {k: v for k, v in data.items() if k in known}
    if "speeds" in args and isinstance(args["speeds"], list):
        args["speeds"] = tuple(args["speeds"])
    try:
        return TestPlan(**args), float(max_current)
    except (TypeError, ValueError) as err:
        raise SpecError(f"{path}: {err}") from err


def schedule(plan: TestPlan, max_current: float, rate_hz: float = 1000.0) -> Any:
    """Set-points of the plan: a DataFrame with time [s], current [A] and velocity [rad/s]."""
    from hound_id.dyno.simulate.current import simulate

    sim = simulate(("linear",), motor=SimMotor(max_current=max_current), plan=plan, rate_hz=rate_hz, noise_std=0.0)
    return sim.frame[["time", "current", "velocity"]]
