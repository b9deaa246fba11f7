"""A polled actuator test rig with the artefacts of real ones, written for the tests.

It shares no code with :mod:`hound_id.dyno.simulate.current` (whose rig streams every channel at one
instant, with white noise) so that a method tuned to one simulator is checked on another. It
follows the public actuator logs described in ``physics-notes.md``:

* a host loop polls the drive at 100-200 Hz with a jittered period; the drive's current reply
  describes the previous loop (``current_late``), so the current lags the torque by one loop;
* the torque transducer is a second-order (Butterworth) low-pass, and its noise is AR(1); options: the
  coupling's torsional mode (a lightly damped resonance the reading rings at after a step) and a
  first-order amplifier filter, each integrated on the physics grid;
* the current reply is quantised, encoded in a fixed range (clamped, or wrapped around);
* the driver limits the current while the command keeps rising; the reply's range may end below
  the driver's limit, and the first reply past it may come back from the other end;
* the torque amplifier may break midway (its gain jumps, sign and all);
* the drive may be switched off midway (its last reply repeats while the torque falls to the
  friction), or the current reading may run away while the torque does not follow;
* an opposing motor imposes the speed, by default through all four quadrants; the regimes that
  cannot identify a parameter (one quadrant, one speed sign, one constant current) are options;
* the CSV may have a title line, a units row, ``, `` separators, a trailing constant field and
  columns in ms, mA or N.mm, with or without a units row saying so;
* options: the inertia of rotor and coupling between motor and sensor (seen while the opposing motor changes speed
  in steps), a torque ADC of coarse counts, a logger that writes every sample several times, and one column
  that updates on a slower clock of its own (a stale channel), and a gear-mesh ripple: a share of the transmitted
  torque at the mesh frequency of the output angle, which the log does not have (noise that grows with the load),
  and a transducer zero that wanders over seconds (creep, heat: a Gauss-Markov process no logged channel follows).

The truth (:class:`Truth`) is the model the fit should recover: measured torque =
kt i - k_sat i|i| - sgn(w) (coulomb + gear |i|) - viscous w - inertia dw/dt, with the transducer's filter and lag.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

FINE_HZ = 4000.0  # physics grid [Hz]


@dataclass(frozen=True)
class Truth:
    kt: float = 1.15  # N m/A, output side (an AK80-9-like actuator)
    k_sat: float = 0.0  # N m/A^2
    coulomb: float = 0.25  # N m
    gear_friction: float = 0.0  # N m/A
    viscous: float = 0.0  # N m s/rad
    inertia: float = 0.0  # kg m^2, output side: rotor (through the gearbox) and coupling before the sensor


@dataclass(frozen=True)
class Rig:
    truth: Truth = Truth()
    seconds: float = 60.0
    rate_hz: float = 150.0
    jitter: float = 0.15  # share of the loop period
    current_amplitude: float = 10.0  # A
    speed_amplitude: float = 3.0  # rad/s
    quadrants: str = "all"  # "all", "motoring" (current and speed both >= 0), "one_speed_sign"
    constant_current: float | None = None  # A: one held current instead of a sweep
    current_loop_tau: float = 0.0015  # s
    torque_filter_hz: float = 80.0  # transducer bandwidth
    resonance_hz: float | None = None  # the coupling's torsional mode between motor and sensor
    resonance_zeta: float = 0.15
    lag_ms: float | None = None  # a first-order filter of the transducer's amplifier
    torque_noise: float = 0.03  # N m
    torque_noise_rho: float = 0.85  # AR(1) correlation per loop
    current_noise: float = 0.02  # A
    current_quantum: float = 0.01  # A
    current_late: bool = True
    current_clamp: float | None = None  # A: the reply's encoding range
    flip_at_clamp: bool = False  # the first reply past the clamp comes back from the other end of the range
    wrap_period: float | None = None  # A: the reply wraps around
    driver_limit: float | None = None  # A
    motor_off_at: float | None = None  # s
    runaway_from: float | None = None  # s
    runaway_rate: float = 1.5  # A/s
    torque_fault_from: float | None = None  # s: the torque amplifier's gain jumps (a broken transducer channel)
    torque_fault_gain: float = -4.0
    speed_steps: bool = False  # the opposing motor steps between speed levels (0.25 s raised-cosine changes)
    torque_quantum: float = 0.0  # N m per count of the torque ADC (0: not rounded)
    repeat: int = 1  # the logger writes every sample this many times
    stale: str | None = None  # a column that updates at a lower rate, on its own jittered clock ("torque_adc", ...)
    stale_every: float = 4.0  # polls per update of that column, on average
    mesh_ripple: float = 0.0  # share of the transmitted torque
    mesh_teeth: int = 36  # ripple periods per output turn
    zero_wander: float = 0.0  # N m RMS: the transducer's zero wanders (creep, heat), a Gauss-Markov process
    zero_wander_s: float = 1.5  # s: its correlation time
    seed: int = 0


def _butter2(x: np.ndarray, cutoff: float, rate: float) -> np.ndarray:
    from scipy.signal import butter, lfilter

    b, a = butter(2, cutoff / (rate / 2))
    return lfilter(b, a, x - x[0]) + x[0]


def _mode(x: np.ndarray, hz: float, zeta: float, rate: float) -> np.ndarray:
    """A spring-mass mode driven by x (unit gain at rest): semi-implicit Euler on the physics grid, its own method."""
    w0, dt = 2 * np.pi * hz, 1.0 / rate
    out = np.empty_like(x)
    pos, vel = float(x[0]), 0.0
    for j, u in enumerate(x.tolist()):
        vel += dt * (w0 * w0 * (u - pos) - 2 * zeta * w0 * vel)
        pos += dt * vel
        out[j] = pos
    return out


def _first_order(x: np.ndarray, tau: float, rate: float) -> np.ndarray:
    out = np.empty_like(x)
    y, a = float(x[0]), 1.0 / (tau * rate)
    for j, u in enumerate(x.tolist()):
        y += a * (u - y)
        out[j] = y
    return out


def run(rig: Rig) -> pd.DataFrame:
    """Columns loop_time [s], iq_meas [A], iq_cmd [A], torque_adc [N m], speed [rad/s]."""
    rng = np.random.default_rng(rig.seed)
    t = np.arange(0.0, rig.seconds, 1.0 / FINE_HZ)
    # the command: a slow sweep with a varying envelope plus square steps (steps make the lags visible)
    sweep = np.sin(2 * np.pi * 0.13 * t) * (0.6 + 0.4 * np.sin(2 * np.pi * 0.021 * t + 1.0))
    steps = 0.25 * np.sign(np.sin(2 * np.pi * 0.7 * t + 0.3))
    command = rig.current_amplitude * np.clip(sweep + steps, -1.0, 1.0)
    speed = rig.speed_amplitude * np.sin(2 * np.pi * 0.17 * t + 0.5)
    accel = rig.speed_amplitude * 2 * np.pi * 0.17 * np.cos(2 * np.pi * 0.17 * t + 0.5)
    if rig.speed_steps:  # levels every 1.5 s, joined by raised cosines of 0.25 s
        levels = rig.speed_amplitude * np.array([1.0, -0.4, 0.7, -1.0, 0.3, -0.7])
        k_lvl = (t // 1.5).astype(int)
        start, end = levels[k_lvl % levels.size], levels[(k_lvl + 1) % levels.size]
        u = np.clip((t - k_lvl * 1.5 - 1.25) / 0.25, 0.0, 1.0)
        speed = start + (end - start) * (1 - np.cos(np.pi * u)) / 2
        accel = (end - start) * np.pi / (2 * 0.25) * np.sin(np.pi * u) * ((u > 0) & (u < 1))
    if rig.quadrants == "motoring":
        command, speed = np.abs(command) + 0.5, np.abs(speed) + 0.3
    elif rig.quadrants == "one_speed_sign":
        speed = np.abs(speed) + 0.3
    if rig.constant_current is not None:
        command = np.full_like(t, rig.constant_current)
    if rig.driver_limit is not None:
        # the command asks for more than the driver gives
        command = command * 1.6
    # the current loop follows the command (first order), within the driver's limit
    alpha = 1.0 - np.exp(-1.0 / (FINE_HZ * rig.current_loop_tau))
    from scipy.signal import lfilter

    current = lfilter([alpha], [1.0, alpha - 1.0], command - command[0]) + command[0]
    if rig.driver_limit is not None:
        current = np.clip(current, -rig.driver_limit, rig.driver_limit)
    off = np.zeros_like(t, dtype=bool) if rig.motor_off_at is None else t >= rig.motor_off_at
    current = np.where(off, 0.0, current)
    tr = rig.truth
    sgn = np.tanh(speed / 0.02)
    torque = (
        tr.kt * current
        - tr.k_sat * current * np.abs(current)
        - sgn * (tr.coulomb + tr.gear_friction * np.abs(current))
        - tr.viscous * speed
        - tr.inertia * accel
    )
    if rig.mesh_ripple > 0:  # the gear mesh: ripple with the output angle, in proportion to the torque carried
        angle = np.cumsum(speed) / FINE_HZ
        torque = torque * (1.0 + rig.mesh_ripple * np.sin(rig.mesh_teeth * angle))
    sensed = _butter2(torque, rig.torque_filter_hz, FINE_HZ)
    if rig.resonance_hz is not None:
        sensed = _mode(sensed, rig.resonance_hz, rig.resonance_zeta, FINE_HZ)
    if rig.lag_ms is not None:
        sensed = _first_order(sensed, rig.lag_ms / 1e3, FINE_HZ)

    # the host loop: jittered polls
    period = 1.0 / rig.rate_hz
    polls = np.cumsum(period * (1.0 + rig.jitter * rng.uniform(-1, 1, int(rig.seconds * rig.rate_hz))))
    polls = polls[polls < t[-1]]
    k = np.searchsorted(t, polls)
    n = k.size
    ar = np.empty(n)
    e = rng.normal(0.0, rig.torque_noise * np.sqrt(1 - rig.torque_noise_rho**2), n)
    ar[0] = rng.normal(0.0, rig.torque_noise)
    for j in range(1, n):
        ar[j] = rig.torque_noise_rho * ar[j - 1] + e[j]
    torque_read = sensed[k] + ar
    if rig.zero_wander > 0:  # its own draws: the same rig without the wander gives the same noise
        walk = np.random.default_rng(rig.seed + 7919).normal(0.0, 1.0, n)
        decay = np.exp(-np.diff(polls, prepend=polls[0]) / rig.zero_wander_s)
        zero = np.empty(n)
        zero[0] = rig.zero_wander * walk[0]
        for j in range(1, n):
            zero[j] = decay[j] * zero[j - 1] + rig.zero_wander * math.sqrt(1.0 - decay[j] ** 2) * walk[j]
        torque_read = torque_read + zero
    if rig.torque_fault_from is not None:
        torque_read = np.where(polls >= rig.torque_fault_from, rig.torque_fault_gain * torque_read, torque_read)
    if rig.torque_quantum > 0:
        torque_read = np.round(torque_read / rig.torque_quantum) * rig.torque_quantum
    measured = current[k] + rng.normal(0.0, rig.current_noise, n)
    if rig.runaway_from is not None:
        measured = measured + rig.runaway_rate * np.clip(polls - rig.runaway_from, 0.0, None)
    if rig.current_late:  # the reply read in this loop was measured in the previous one
        measured = np.concatenate([[measured[0]], measured[:-1]])
    if rig.motor_off_at is not None:  # a disabled drive repeats its last reply
        first = int(np.argmax(polls >= rig.motor_off_at)) if np.any(polls >= rig.motor_off_at) else n
        if first < n:
            measured[first:] = measured[first - 1]
    reply = np.round(measured / rig.current_quantum) * rig.current_quantum
    if rig.current_clamp is not None:
        past = np.abs(reply) > rig.current_clamp
        first_past = past & ~np.concatenate([[False], past[:-1]])
        reply = np.clip(reply, -rig.current_clamp, rig.current_clamp)
        if rig.flip_at_clamp:  # read as it crosses the end of the range: a signed overflow, just inside the other end
            reply[first_past] = -np.sign(reply[first_past]) * (rig.current_clamp - rig.current_quantum)
    if rig.wrap_period is not None:
        p = rig.wrap_period
        reply = np.mod(reply + p / 2, p) - p / 2
    columns = {"iq_meas": reply, "torque_adc": torque_read, "speed": speed[k]}
    if rig.stale is not None:  # its own clock: each poll reads the value of the channel's latest update
        clock = np.cumsum(rig.stale_every * period * (1.0 + 0.3 * rng.uniform(-1, 1, n)))
        latest = np.searchsorted(polls, clock[clock < polls[-1]])
        held = np.searchsorted(latest, np.arange(n), side="right") - 1
        values = columns[rig.stale]
        columns[rig.stale] = np.where(held >= 0, values[latest[np.maximum(held, 0)]], values[0])
    reply, torque_read = columns["iq_meas"], columns["torque_adc"]
    out = pd.DataFrame(
        {
            "loop_time": polls - polls[0],
            "iq_meas": reply,
            "iq_cmd": command[k],
            "torque_adc": torque_read,
            "speed": columns["speed"],
        }
    )
    return out.loc[out.index.repeat(rig.repeat)].reset_index(drop=True) if rig.repeat > 1 else out


COLUMNS = "time=loop_time,current=iq_meas,torque=torque_adc,velocity=speed,current_cmd=iq_cmd"


def write(
    frame: pd.DataFrame,
    path: Path,
    *,
    title: str | None = None,
    units: dict[str, str] | None = None,
    separator: str = ",",
    trailing: str | None = None,
    scale: dict[str, float] | None = None,
    drop: tuple[str, ...] = (),
) -> Path:
    """Write a log as a rig's host would: optional title line, units row, separator, trailing field;
    ``scale`` multiplies columns (1e3 to write ms, mA or N.mm)."""
    out = frame.drop(columns=list(drop)).copy()
    for column, factor in (scale or {}).items():
        out[column] = out[column] * factor
    lines = []
    if title is not None:
        lines.append(title)
    lines.append(separator.join(out.columns))
    if units is not None:
        lines.append(separator.join(units.get(c, "") for c in out.columns))
    cells = out.to_numpy()
    for row in cells:
        text = separator.join(f"{v:.6g}" for v in row)
        lines.append(text + (separator + trailing if trailing is not None else ""))
    path.write_text("\n".join(lines) + "\n")
    return path
