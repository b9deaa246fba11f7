"""The simulated rig's test plan (:class:`TestPlan`): its steps of current at speed, their shapes and bounds, and the
schedule of set-points a simulation plays (:func:`schedule`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from hound_id.errors import DynoDataError

if TYPE_CHECKING:  # pragma: no cover
    pass


SHAPES = ("ramps", "ramps_and_steps", "steps")


def check_finite(value: object, what: str, *, positive: bool = False, nonnegative: bool = False) -> float:
    """``value`` as a float, or DynoDataError naming ``what``."""
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as err:
        raise DynoDataError(f"{what}: found {value!r}, expected a number", value=value) from err
    if not math.isfinite(x):
        raise DynoDataError(f"{what}: found {x}, expected a finite number", value=x)
    if positive and x <= 0:
        raise DynoDataError(f"{what}: found {x}, expected a positive number", value=x)
    if nonnegative and x < 0:
        raise DynoDataError(f"{what}: found {x}, expected a number >= 0", value=x)
    return x


#: The longest test plan [s]: an hour on the rig (a dyno's plan runs minutes; a thermal soak fits); its simulated log
#: at 1 kHz is 3.6 million rows, held in memory.
MAX_PLAN_DURATION = 3600.0
#: The largest overdrive of a plan [-]: its top level beyond the application's max current, which is at most a
#: drive's peak (2-3x its continuous current).
MAX_OVERDRIVE = 3.0


@dataclass(frozen=True)
class TestPlan:
    """What the rig does over time (relative to the motor's max_current, so one plan fits every motor).

    Time line: a lead-in of ``pause_time`` at zero current at the first speed; then for every
    speed, in the given order, a raised-cosine speed transition of ``transition_time`` (zero
    current; not before the first), the current excitation of ``plateau_time``, after the middle
    plateau (index ``len(speeds) // 2``) a hold at +max_current for ``hold_time``, and a pause of
    ``pause_time`` at zero current. The excitation is, by ``shape``:

    * ``ramps``: one triangle 0 -> +I -> -I -> 0 over the whole plateau, I = overdrive max_current;
    * ``steps``: for each level I k/n (k = 1..n, n = current_levels), a pulse to +level, zero,
      a pulse to -level, zero, each slot ``step_time`` long;
    * ``ramps_and_steps``: the triangle in the first half, the pulses in the second.

    Current edges take ``current_rise_time`` (a current loop is not instantaneous).
    """

    __test__ = False  # not a pytest test class despite the name

    speeds: tuple[float, ...] = (-40.0, -10.0, -2.0, 2.0, 10.0, 40.0)
    """Plateau speeds in time order [rad/s]; both signs for the four quadrants."""
    current_levels: int = 5
    """Number of step levels per sign and plateau."""
    overdrive: float = 1.3
    """Ramps and the top step level reach overdrive * max_current [-]."""
    shape: str = "ramps_and_steps"
    """Excitation within a plateau: "ramps", "steps" or "ramps_and_steps"."""
    plateau_time: float = 2.0
    """Current excitation per plateau [s]."""
    pause_time: float = 6.0
    """Zero current after each plateau and before the first [s]: friction and cogging data, bounded heating."""
    hold_time: float = 1.0
    """Hold at +max_current once, after the middle plateau, to heat the winding [s] (0: none)."""
    transition_time: float = 1.0
    """Raised-cosine speed change between plateaus, at zero current [s]."""
    current_rise_time: float = 0.001
    """Duration of every current step edge [s]."""
    bus_voltage: float = 48.0
    """Open-circuit bus voltage of the rig supply [V]."""
    bus_sag: float = 0.02
    """Bus sag per amp of |current| [V/A] (assumed)."""

    def __post_init__(self) -> None:
        if isinstance(self.speeds, (str, bytes)) or not isinstance(self.speeds, Sequence):
            raise DynoDataError(f"TestPlan.speeds: found {self.speeds!r}, expected a sequence of speeds in rad/s")
        speeds = tuple(check_finite(w, "TestPlan.speeds") for w in self.speeds)
        if not speeds:
            raise DynoDataError("TestPlan.speeds: found no speeds, expected at least one plateau")
        object.__setattr__(self, "speeds", speeds)
        levels = self.current_levels
        if isinstance(levels, bool) or not isinstance(levels, (int, np.integer)) or levels < 1:
            raise DynoDataError(f"TestPlan.current_levels: found {levels!r}, expected an integer >= 1", value=levels)
        object.__setattr__(self, "current_levels", int(levels))
        if self.shape not in SHAPES:
            raise DynoDataError(f"TestPlan.shape: found {self.shape!r}, expected one of {', '.join(SHAPES)}")
        for name in ("overdrive", "plateau_time", "transition_time", "current_rise_time", "bus_voltage"):
            object.__setattr__(self, name, check_finite(getattr(self, name), f"TestPlan.{name}", positive=True))
        for name in ("pause_time", "hold_time", "bus_sag"):
            object.__setattr__(self, name, check_finite(getattr(self, name), f"TestPlan.{name}", nonnegative=True))
        if not self.overdrive <= MAX_OVERDRIVE:
            raise DynoDataError(
                f"TestPlan.overdrive: found {self.overdrive:g}, expected at most {MAX_OVERDRIVE:g} (the top level is "
                "overdrive x the max current: a drive's peak current is 2-3x its continuous one)",
                value=self.overdrive,
            )
        if self.duration > MAX_PLAN_DURATION:
            raise DynoDataError(
                f"TestPlan: the plan lasts {self.duration:.4g} s, expected at most {MAX_PLAN_DURATION:g} s (an hour on "
                "the rig; a simulated log holds every sample in memory); shorten plateau_time, pause_time, hold_time "
                "or transition_time, or use fewer speeds"
            )
        shortest = min(t for t in (self.step_time, self.ramp_time / 4.0, self.hold_time or math.inf) if t > 0)
        if shortest <= self.current_rise_time:
            raise DynoDataError(
                f"TestPlan: the shortest step or ramp leg lasts {shortest:g} s, expected more than "
                f"current_rise_time = {self.current_rise_time:g} s; lengthen plateau_time or use fewer levels"
            )

    @property
    def ramp_time(self) -> float:
        """Duration of the triangular ramp cycle of each plateau [s] (0 for "steps")."""
        return {"ramps": self.plateau_time, "ramps_and_steps": self.plateau_time / 2.0}.get(self.shape, 0.0)

    @property
    def step_time(self) -> float:
        """Duration of each step slot (a pulse or the zero gap after it) [s] (0 for "ramps")."""
        return (self.plateau_time - self.ramp_time) / (4 * self.current_levels) if self.shape != "ramps" else 0.0

    @property
    def hold_index(self) -> int:
        """Index of the plateau after whose excitation the hold comes."""
        return len(self.speeds) // 2

    @property
    def duration(self) -> float:
        """Length of the log [s]."""
        n = len(self.speeds)
        return (
            self.pause_time
            + n * (self.plateau_time + self.pause_time)
            + (n - 1) * self.transition_time
            + (self.hold_time)
        )


@dataclass(frozen=True)
class _Schedule:
    """The plan as continuous-time signals: current knots and speed segments."""

    knot_time: NDArray[np.float64]
    knot_current: NDArray[np.float64]
    seg_start: NDArray[np.float64]
    seg_duration: NDArray[np.float64]
    seg_from: NDArray[np.float64]
    seg_to: NDArray[np.float64]
    seg_position: NDArray[np.float64]
    duration: float

    def current(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Piecewise-linear current at times ``t`` [A] (0 outside the plan)."""
        return np.interp(t, self.knot_time, self.knot_current, left=0.0, right=0.0)

    def acceleration(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """d speed / dt at times ``t`` [rad/s^2]: (b - a) pi / (2 T) sin(pi u) inside a transition, else 0."""
        k = np.clip(np.searchsorted(self.seg_start, t, side="right") - 1, 0, self.seg_start.size - 1)
        dur, a, b = self.seg_duration[k], self.seg_from[k], self.seg_to[k]
        u = (t - self.seg_start[k]) / dur
        inside = (u > 0.0) & (u < 1.0)
        return np.where(inside, (b - a) * np.pi / (2.0 * dur) * np.sin(np.pi * np.clip(u, 0.0, 1.0)), 0.0)

    def speed_and_position(self, t: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Speed [rad/s] and its exact integral from 0 [rad] at times ``t``, constant speed outside the plan."""
        k = np.clip(np.searchsorted(self.seg_start, t, side="right") - 1, 0, self.seg_start.size - 1)
        start, dur, a, b = self.seg_start[k], self.seg_duration[k], self.seg_from[k], self.seg_to[k]
        rel = t - start
        u = np.clip(rel / dur, 0.0, 1.0)
        # raised-cosine shape s(u) = (1 - cos(pi u))/2 and its integral; trig only inside transitions
        shape = u.copy()
        area = u / 2.0
        moving = np.flatnonzero((u > 0.0) & (u < 1.0) & (a != b))
        um = u[moving]
        shape[moving] = 0.5 * (1.0 - np.cos(np.pi * um))
        area[moving] = um / 2.0 - np.sin(np.pi * um) / (2.0 * np.pi)
        speed = a + (b - a) * shape
        position = self.seg_position[k] + dur * (a * u + (b - a) * area)
        position += b * np.maximum(rel - dur, 0.0) + a * np.minimum(rel, 0.0)
        return speed, position


def schedule(plan: TestPlan, max_current: float) -> _Schedule:
    """Lay the plan out in time (a few dozen segments; the signals are evaluated vectorised)."""
    rise = plan.current_rise_time
    top = plan.overdrive * max_current
    knots: list[tuple[float, float]] = [(0.0, 0.0)]

    def pulse(t0: float, t1: float, level: float) -> None:
        # 0 -> level over the rise time, hold, level -> 0 from t1
        knots.extend(((t0, 0.0), (t0 + rise, level), (t1, level), (t1 + rise, 0.0)))

    segments: list[tuple[float, float, float, float]] = []  # start, duration, from, to
    t = 0.0
    seg_t0 = 0.0
    previous = plan.speeds[0]
    t += plan.pause_time
    for k, w in enumerate(plan.speeds):
        if k > 0:
            segments.append((seg_t0, t - seg_t0, previous, previous))
            segments.append((t, plan.transition_time, previous, w))
            t += plan.transition_time
            seg_t0 = t
        if plan.ramp_time > 0:
            q = plan.ramp_time / 4.0
            knots.extend(((t, 0.0), (t + q, top), (t + 3 * q, -top), (t + 4 * q, 0.0)))
            t += plan.ramp_time
        if plan.step_time > 0:
            slot = plan.step_time
            for level in range(1, plan.current_levels + 1):
                amp = top * level / plan.current_levels
                for sign in (1.0, -1.0):
                    pulse(t, t + slot, sign * amp)
                    t += 2 * slot
        if k == plan.hold_index and plan.hold_time > 0:
            pulse(t, t + plan.hold_time, max_current)
            t += plan.hold_time
        t += plan.pause_time
        previous = w
    segments.append((seg_t0, max(t - seg_t0, 1e-9), previous, previous))

    # drop repeated knots (a pulse starting where a ramp ended); times must increase strictly for interp
    times: list[float] = []
    values: list[float] = []
    for time, value in knots:
        if times and time <= times[-1]:
            continue  # only ever a repeated zero knot
        times.append(time)
        values.append(value)
    seg = np.array(segments, dtype=np.float64)
    dur, a, b = seg[:, 1], seg[:, 2], seg[:, 3]
    seg_position = np.concatenate(([0.0], np.cumsum(dur * (a + b) / 2.0)[:-1]))
    return _Schedule(
        knot_time=np.array(times),
        knot_current=np.array(values),
        seg_start=seg[:, 0].copy(),
        seg_duration=dur.copy(),
        seg_from=a.copy(),
        seg_to=b.copy(),
        seg_position=seg_position,
        duration=t,
    )
