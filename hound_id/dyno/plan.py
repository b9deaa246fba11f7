"""Dyno test plans: what the rig does so that every effect of the library is identifiable.

A plan (schema ``hound-id/plan/1``) is the :class:`~hound_id.dyno.simulate.TestPlan`
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
from pathlib import Path
from typing import Any

from hound_id.dyno.simulate import SimMotor, TestPlan
from hound_id.errors import SpecError
from hound_id.io import read_yaml

SCHEMA = "hound-id/plan/1"

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


def load_plan(path: str | Path) -> tuple[TestPlan, float]:
    """A plan file -> (TestPlan, max_current [A])."""
    data = read_yaml(path, "plan")
    if not isinstance(data, dict) or data.get("schema") != SCHEMA:
        raise SpecError(f"{path}: expected a test plan with 'schema: {SCHEMA}' (write one with hound-id dyno plan)")
    known = {f.name for f in dataclasses.fields(TestPlan)}
    extra = set(data) - known - {"schema", "max_current", "duration", "why"}
    if extra:
        raise SpecError(f"{path}: unknown key(s) {', '.join(sorted(extra))}; known: {', '.join(sorted(known))}")
    max_current = data.get("max_current")
    if not isinstance(max_current, (int, float)) or isinstance(max_current, bool) or not max_current > 0:
        raise SpecError(f"{path}: field 'max_current': found {max_current!r}, expected a positive current in A")
    args = {k: v for k, v in data.items() if k in known}
    if "speeds" in args and isinstance(args["speeds"], list):
        args["speeds"] = tuple(args["speeds"])
    try:
        return TestPlan(**args), float(max_current)
    except (TypeError, ValueError) as err:
        raise SpecError(f"{path}: {err}") from err


def schedule(plan: TestPlan, max_current: float, rate_hz: float = 1000.0) -> Any:
    """Set-points of the plan: a DataFrame with time [s], current [A] and velocity [rad/s]."""
    from hound_id.dyno.simulate import simulate

    sim = simulate(("linear",), motor=SimMotor(max_current=max_current), plan=plan, rate_hz=rate_hz, noise_std=0.0)
    return sim.frame[["time", "current", "velocity"]]
