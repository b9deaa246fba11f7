"""A dynamometer envelope test with the artefacts of real ones, written for the tests of ``mor --compare``.

It shares no code with :mod:`hound_id.mor.envelope` (whose logs are the command clipped to the
model's edges at each sample, exactly) so that a method tuned to one simulator is checked on
another. The protocol is the ordinary one of a dyno envelope test:

* a load motor holds speeds across the range, in random order, through all four quadrants, with
  a PI speed loop that the torque pulses disturb; between holds it ramps at a fixed
  acceleration while the motor under test rests (command 0);
* within a hold the motor under test gets trapezoidal torque pulses of alternating sign to
  1.2-2.2x its torque limit, rising at 10-30 torque limits a second;
* the host sends each command one loop late (the drive applies the previous loop's command);
* the drive's current loop is a first-order lag of ``current_loop_hz``, clamped by the driver's
  current limit and by the voltage the bus can apply. That voltage limit is solved here in the
  dq frame with the exact bus of a pack with internal resistance, V_bus = (V0 + sqrt(V0^2 -
  4 R_pack P))/2, not the linearised one of the envelope model;
* the winding heats with the current (I^2 R), read by a thermistor that lags it by a second;
* the torque transducer between the motors is a second-order low-pass at ``transducer_hz``; it
  also sees the rotor's inertia torque; its noise is AR(1) with a mains hum, quantised;
* the logged current is the drive's reply of the previous loop; bus voltage and speed are
  filtered and noisy.

Every hidden effect is off by default (a motor that matches its spec sheet); :class:`Hidden`
turns one on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

FINE_HZ = 10_000.0  # physics grid [Hz]


@dataclass(frozen=True)
class Hidden:
    r_pack: float = 0.0  # ohm
    inductance: float = 0.0  # H, the q-axis inductance's cross-coupling p w L i
    alpha: float = 0.0  # 1/K, winding resistance temperature coefficient
    current_limit: float | None = None  # A, the driver's clamp below the spec sheet's


@dataclass(frozen=True)
class Dyno:
    hidden: Hidden = field(default_factory=Hidden)
    log_hz: float = 2000.0
    holds: int = 24
    speed_fraction: float = 0.95  # of the no-load speed
    pulses: int = 3  # per hold, alternating sign
    amplitude: tuple[float, float] = (1.2, 2.2)  # pulse peaks, multiples of the torque limit
    acceleration: float = 3000.0  # rad/s^2 between holds
    current_loop_hz: float = 1000.0
    transducer_hz: float = 300.0
    transducer_zeta: float = 0.7
    noise: float = 0.006  # share of the torque limit (AR(1) standard deviation)
    noise_rho: float = 0.8
    hum: float = 0.3  # 50 Hz hum, share of the noise
    temperature: tuple[float, float] = (30.0, 95.0)  # winding, start and end [degC]
    seed: int = 0


def _protocol(spec, dyno: Dyno, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(speed set-point [rad/s], torque command [N m]) on the fine grid."""
    w_nl = spec.bus_voltage * spec.kv
    tau_lim = spec.linear_torque_limit
    speeds = np.linspace(-dyno.speed_fraction, dyno.speed_fraction, dyno.holds) * w_nl
    speeds = rng.permutation(speeds + rng.uniform(-0.3, 0.3, dyno.holds) * (speeds[1] - speeds[0]))
    dt = 1.0 / FINE_HZ
    w_parts, c_parts = [], []
    current = 0.0
    for target in speeds:
        ramp = abs(target - current) / dyno.acceleration
        n = max(int(ramp / dt), 1)
        w_parts.append(np.linspace(current, target, n, endpoint=False))
        c_parts.append(np.zeros(n))
        settle = int(0.05 / dt)  # the speed settles before the first pulse
        w_parts.append(np.full(settle, target))
        c_parts.append(np.zeros(settle))
        sign = rng.choice([-1.0, 1.0])
        for _ in range(dyno.pulses):
            peak = sign * rng.uniform(*dyno.amplitude) * tau_lim
            rate = rng.uniform(15.0, 40.0) * tau_lim
            rise = int(abs(peak) / rate / dt)
            top = int(rng.uniform(0.04, 0.08) / dt)
            gap = int(rng.uniform(0.02, 0.04) / dt)
            pulse = np.concatenate(
                [np.linspace(0, peak, rise), np.full(top, peak), np.linspace(peak, 0, rise), np.zeros(gap)]
            )
            c_parts.append(pulse)
            w_parts.append(np.full(pulse.size, target))
            sign = -sign
        current = target
    return np.concatenate(w_parts), np.concatenate(c_parts)


def _bus(v0: float, r_pack: float, power: np.ndarray) -> np.ndarray:
    """The pack's terminal voltage when the inverter draws ``power`` [W] (exact: V (V0 - V) = R_pack P)."""
    p = np.maximum(power, 0.0)  # a pack does not rise here (no regen effect hidden)
    return 0.5 * (v0 + np.sqrt(np.maximum(v0 * v0 - 4.0 * r_pack * p, 0.0)))


def _voltage_room(i: np.ndarray, w: np.ndarray, resistance: np.ndarray, spec, hidden: Hidden) -> np.ndarray:
    """Bus voltage left once the dq voltage vector for current ``i`` at speed ``w`` is applied [V]."""
    v_q = resistance * i + w / spec.kv
    v_d = (spec.pole_pairs or 0) * w * hidden.inductance * i  # -p w L i_q, with i_d held at 0
    return _bus(spec.bus_voltage, hidden.r_pack, v_q * i) - np.hypot(v_q, v_d)


def _current_window(w: np.ndarray, resistance: np.ndarray, spec, hidden: Hidden) -> tuple[np.ndarray, np.ndarray]:
    """The lowest and highest current the voltage allows at each speed [A] (bisection on the dq voltage room,
    from the zero-voltage current, where the room is widest)."""
    i0 = -w / (spec.kv * resistance)
    out = []
    big = 10.0 * (spec.max_current or 1e3)
    for side in (-1.0, 1.0):
        inside = np.clip(i0, -big, big)
        outside = np.full_like(w, side * big)
        for _ in range(60):
            mid = 0.5 * (inside + outside)
            ok = _voltage_room(mid, w, resistance, spec, hidden) >= 0
            inside = np.where(ok, mid, inside)
            outside = np.where(ok, outside, mid)
        out.append(inside)
    return out[0], out[1]


def _butter2(x: np.ndarray, hz: float, zeta: float, rate: float) -> np.ndarray:
    from scipy.signal import bilinear, lfilter

    wn = 2 * math.pi * hz
    b, a = bilinear([wn * wn], [1.0, 2 * zeta * wn, wn * wn], fs=rate)
    return lfilter(b, a, x - x[0]) + x[0]


def _lti(num: list[float], den: list[float], x: np.ndarray) -> np.ndarray:
    """A continuous transfer function num/den applied to ``x`` on the fine grid (bilinear), from rest at x[0]."""
    from scipy.signal import bilinear, lfilter, lfilter_zi

    b, a = bilinear(num, den, fs=FINE_HZ)
    return lfilter(b, a, x, zi=lfilter_zi(b, a) * x[0])[0]


def _first_order(x: np.ndarray, tau: float, rate: float) -> np.ndarray:
    from scipy.signal import lfilter

    k = 1.0 - math.exp(-1.0 / (tau * rate))
    return lfilter([k], [1.0, k - 1.0], x - x[0]) + x[0]


def _ar1(rng: np.random.Generator, n: int, rho: float) -> np.ndarray:
    from scipy.signal import lfilter

    e = rng.standard_normal(n) * math.sqrt(1 - rho * rho)
    e[0] = rng.standard_normal()
    return lfilter([1.0], [1.0, -rho], e)


def _electrical(
    spec, dyno: Dyno, w: np.ndarray, command: np.ndarray, temperature: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The motor current [A] on the fine grid, the drive's loop following the command, clamped; and the lowest and
    highest current the drive can make at each instant [A]."""
    hidden = dyno.hidden
    resistance = spec.resistance * (1.0 + hidden.alpha * (temperature - 25.0))
    coarse = np.arange(0, w.size + 9, 10).clip(max=w.size - 1)  # the window moves slowly: solved at 1 kHz
    window = _current_window(w[coarse], resistance[coarse], spec, hidden)
    lo, hi = (np.interp(np.arange(w.size), coarse, x) for x in window)
    limit = min(spec.max_current or math.inf, hidden.current_limit or math.inf)
    log_step = int(FINE_HZ / dyno.log_hz)
    late = np.concatenate([np.zeros(log_step), command[:-log_step]])  # the host's command, one loop late
    reference = np.clip(late / spec.kt, -limit, limit)
    k = 1.0 - math.exp(-2 * math.pi * dyno.current_loop_hz / FINE_HZ)
    i = np.empty_like(w)
    state = 0.0
    for n, (ref, a, b) in enumerate(zip(reference.tolist(), lo.tolist(), hi.tolist(), strict=True)):
        state += k * (ref - state)
        state = a if state < a else (b if state > b else state)  # the voltage limit: the integrator clamps
        i[n] = state
    return i, np.maximum(lo, -limit), np.minimum(hi, limit)


def run(spec, dyno: Dyno = Dyno()) -> dict[str, np.ndarray]:
    """The log, at ``dyno.log_hz``: time [s], torque [N m] (transducer), velocity [rad/s], torque_cmd [N m],
    current [A], bus_voltage [V], temperature [degC]. Motor side, SI. Also the truth, which a log does not have:
    true_lower and true_upper, the torque the motor could make at each row [N m]."""
    rng = np.random.default_rng(dyno.seed)
    set_w, command = _protocol(spec, dyno, rng)
    n = set_w.size
    dt = 1.0 / FINE_HZ
    # the load motor's speed loop: a PI of ~15 Hz on the combined inertia, disturbed by the motor's torque (linear:
    # J s w = tau + (kp + ki/s)(w_set - w), discretised by the bilinear transform)
    j_total, bw = 0.02, 2 * math.pi * 15.0
    kp, ki = j_total * 2 * bw, j_total * bw * bw
    tau_guess = np.clip(command, -spec.linear_torque_limit, spec.linear_torque_limit)
    den = [j_total, kp, ki]
    w = _lti([kp, ki], den, set_w) + _lti([1.0, 0.0], den, tau_guess)
    # the winding heats with the current: I^2 heat (of the clamped command), scaled to the test's rise
    heat = np.cumsum(tau_guess**2)
    t_lo, t_hi = dyno.temperature
    temperature = t_lo + (t_hi - t_lo) * heat / heat[-1]
    i, i_lo, i_hi = _electrical(spec, dyno, w, command, temperature)
    tau = spec.kt * i
    j_rotor = spec.rotor_inertia or 0.0
    shaft = tau - j_rotor * np.gradient(w, dt)
    measured = _butter2(shaft, dyno.transducer_hz, dyno.transducer_zeta, FINE_HZ)
    step = int(FINE_HZ / dyno.log_hz)
    rows = np.arange(0, n, step)
    m = rows.size
    t = rows * dt
    sigma = dyno.noise * spec.linear_torque_limit
    noise = sigma * (_ar1(rng, m, dyno.noise_rho) + dyno.hum * math.sqrt(2) * np.sin(2 * math.pi * 50.0 * t))
    torque = np.round((measured[rows] + noise) / 1e-3) * 1e-3  # a 1 mN m ADC step
    velocity = _first_order(w, 0.5e-3, FINE_HZ)[rows] + 0.3 * rng.standard_normal(m)
    hidden = dyno.hidden
    resistance = spec.resistance * (1.0 + hidden.alpha * (temperature - 25.0))
    power = (resistance * i + w / spec.kv) * i
    bus = _first_order(_bus(spec.bus_voltage, hidden.r_pack, power), 2e-3, FINE_HZ)[rows]
    current = np.concatenate([[0.0], i[rows][:-1]]) + 0.2 * rng.standard_normal(m)  # the reply of the loop before
    thermistor = np.round(_first_order(temperature, 1.0, FINE_HZ)[rows] + 0.1 * rng.standard_normal(m), 1)
    return {
        "time": t,
        "torque": torque,
        "velocity": velocity,
        "torque_cmd": command[rows],
        "current": current,
        "bus_voltage": bus + 0.05 * rng.standard_normal(m),
        "temperature": thermistor,
        # the truth, not logged: the motor's torque edges at each row [N m]
        "true_lower": spec.kt * i_lo[rows],
        "true_upper": spec.kt * i_hi[rows],
    }
