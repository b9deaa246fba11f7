"""Seeded torque-speed logs of a motor driven past its envelope with hidden effects (for tests, demos, benchmarks)."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from hound_id.mor.envelope import Array, EnvelopeInputs, bus_voltage, envelope, motor_current


def simulate_log(
    inputs: EnvelopeInputs,
    params: Mapping[str, float],
    n: int = 20000,
    noise: float = 0.02,
    speed_fraction: float = 0.9,
    seed: int = 0,
    temperature_range: tuple[float, float] = (30.0, 90.0),
) -> dict[str, Array]:
    """A seeded log of a motor driven past its envelope with hidden effects (for tests and demos).

    Speeds are uniform within ``speed_fraction`` of the no-load speed; commands are uniform over
    1.5 x the torque limit; the realised torque is the command clipped to the true envelope plus
    Gaussian sensor noise [N m]. Columns: velocity [rad/s], torque [N m], current [A],
    temperature [degC] (a slow sweep over ``temperature_range``) and bus_voltage [V].
    """
    rng = np.random.default_rng(seed)
    spec = inputs.spec
    omega = rng.uniform(-speed_fraction, speed_fraction, n) * spec.bus_voltage * spec.kv
    command = rng.uniform(-1.5, 1.5, n) * spec.linear_torque_limit
    return _realise(inputs, params, omega, command, noise * rng.standard_normal(n), temperature_range)


def simulate_trajectory(
    inputs: EnvelopeInputs,
    params: Mapping[str, float],
    n: int = 20000,
    rate: float = 1000.0,
    noise: float = 0.03,
    correlation: float = 0.0,
    speed_fraction: float = 0.95,
    amplitude: float = 3.0,
    period: float = 5.0,
    band: float = 3.0,
    seed: int = 0,
    temperature_range: tuple[float, float] = (30.0, 90.0),
) -> dict[str, Array]:
    """A seeded time-ordered log, as a robot or a dyno sweep records it: the speed sweeps a triangle of ``period``
    [s] to ``speed_fraction`` of the no-load speed, the torque command is a smooth random signal (40 sines of 0.05 to
    ``band`` Hz) reaching ``amplitude`` x the torque limit, sampled at ``rate`` [Hz]. The realised torque is the command
    clipped to the true envelope plus AR(1) sensor noise of standard deviation ``noise`` [N m] and lag-1
    ``correlation`` (a filtered torque sensor). Columns as :func:`simulate_log`, plus time [s] and torque_cmd [N m].
    """
    rng = np.random.default_rng(seed)
    spec = inputs.spec
    t = np.arange(n) / rate
    omega = speed_fraction * spec.bus_voltage * spec.kv * (2 / np.pi) * np.arcsin(np.sin(2 * np.pi * t / period))
    command = np.zeros(n)
    for _ in range(40):
        command += np.sin(2 * np.pi * rng.uniform(0.05, band) * t + rng.uniform(0, 2 * np.pi))
    command *= amplitude * spec.linear_torque_limit / np.max(np.abs(command))
    from scipy.signal import lfilter

    white = rng.standard_normal(n) * math.sqrt(1 - correlation**2)
    white[0] = rng.standard_normal()  # the stationary start
    e = lfilter([1.0], [1.0, -correlation], white)  # AR(1): unit variance, lag-1 correlation as given
    out = _realise(inputs, params, omega, command, noise * e, temperature_range)
    return {"time": t, **out, "torque_cmd": command}


def _realise(
    inputs: EnvelopeInputs,
    params: Mapping[str, float],
    omega: Array,
    command: Array,
    sensor_noise: Array,
    temperature_range: tuple[float, float],
) -> dict[str, Array]:
    """The log a motor with the hidden ``params`` records for commands at speeds (see :func:`simulate_log`)."""
    spec = inputs.spec
    n = omega.size
    t_lo, t_hi = temperature_range
    temperature = t_lo + (t_hi - t_lo) * 0.5 * (1 - np.cos(np.linspace(0, 2 * np.pi, n)))
    truth = EnvelopeInputs(spec, temperature=temperature, curve=inputs.curve)
    lo, hi = envelope(omega, params, truth)
    tau = np.clip(command, lo, hi)
    i = motor_current(tau, truth, params.get("kt_saturation", 0.0))
    power = (spec.resistance * i + omega / spec.kv) * i
    r_x = np.where(power > 0, params.get("bus_sag", 0.0), params.get("regen_rise", 0.0))
    return {
        "velocity": omega,
        "torque": tau + sensor_noise,
        "current": i,
        "temperature": temperature,
        "bus_voltage": bus_voltage(spec.bus_voltage, r_x, power),
    }
