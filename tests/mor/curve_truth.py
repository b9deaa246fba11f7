"""An independent computation of the curve-limited region, for the region and saturation tests."""

import numpy as np


def brute_interval(spec, omega, currents=200001):
    k = 0.2 * 0.8 * spec.kt**2 / spec.peak_torque
    top = spec.kt / (2 * k)  # the quadratic's top: the curve is held there beyond
    lo_i, hi_i = (
        (-spec.bus_voltage - omega / spec.kv) / spec.resistance,
        (spec.bus_voltage - omega / spec.kv) / spec.resistance,
    )
    # past the top the torque is held at kt^2/(4k) = 1.5625 tau_peak, beyond the peak torque: the scan stops there
    cap = min(spec.max_current if spec.max_current is not None else np.inf, top)
    if max(lo_i, -cap) > min(hi_i, cap):
        return None
    i = np.linspace(max(lo_i, -cap), min(hi_i, cap), currents)
    m = np.minimum(np.abs(i), top)
    tau = np.sign(i) * (spec.kt * m - k * m * m)
    tau = tau[np.abs(tau) <= spec.peak_torque]
    if tau.size == 0:
        return None
    return float(tau.min()), float(tau.max())
