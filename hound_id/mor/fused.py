"""The saturation's elementwise steps fused into one pass (numba), when numba is installed.

The clip of an ordinary command (:meth:`hound_id.mor.saturation.Saturation._saturate_ordinary`) is three small
matrix products and some fifteen elementwise steps: the voltage window, the driver's limit, the current-torque
curve, the clip and the correction. numpy makes one pass over memory per step; for a 4096 x 12 batch each pass
costs about as much as the whole per-joint clip of a trainer makes in all. :func:`clip_correction` does the
elementwise steps in one compiled loop, in the same order and the same dtype as the numpy steps, so its result is
the same bit for bit (NaN propagation included: ``_max``/``_min`` are numpy's maximum and minimum). The products
stay numpy's (BLAS), so the sums are rounded as before.

numba is optional (``pip install 'hound-id[fast]'``): without it, or with ``HOUND_ID_FUSED=0`` in the
environment, the numpy steps run. The loops compile on first use in a process (about half a second for each
dtype and set of motor features).
"""

from __future__ import annotations

import os
from functools import cache
from typing import Any

import numpy as np

from hound_id.mor.drive import SPEED_CAP

#: Environment variable that turns the fused loops off ("0").
ENV = "HOUND_ID_FUSED"


@cache
def _numba() -> Any:
    try:
        import numba
    except ImportError:
        return None
    return numba


@cache
def _helpers() -> tuple[Any, Any, Any]:
    """(jit, numpy's maximum, numpy's minimum) compiled."""
    # numpy's error model: a division by zero gives inf or NaN as numpy's does, with no check and branch to raise
    jit = _numba().njit(nogil=True, boundscheck=False, fastmath=False, error_model="numpy")

    @jit  # type: ignore[untyped-decorator]
    def _max(a: Any, b: Any) -> Any:  # numpy's maximum: NaN if either is (a tie of +-0 may keep the other sign)
        return a if (a >= b) | (a != a) else b  # no short circuit: one select, so the loop vectorises

    @jit  # type: ignore[untyped-decorator]
    def _min(a: Any, b: Any) -> Any:  # numpy's minimum
        return a if (a <= b) | (a != a) else b

    return jit, _max, _min


@cache
def _window_fn(has_fw: bool) -> Any:
    """:func:`hound_id.mor.drive.dq_window` for one element, in the same operations and order (so the same bits),
    without branches (every case is computed and the result selected), so that the loop vectorises; the field
    weakening's part only where some motor has it (``has_fw``)."""
    _, _max, _min = _helpers()
    inline = _numba().njit(nogil=True, boundscheck=False, fastmath=False, error_model="numpy", inline="always")

    @inline  # type: ignore[untyped-decorator]
    def window(
        u: Any, stall: Any, k_rho: Any, limit_x: Any, M: Any, fw: Any, zero: Any, one: Any, speed_cap: Any
    ) -> tuple[Any, Any]:
        w = abs(u)
        cap = speed_cap * (stall if stall > limit_x else limit_x)
        w = cap if w > cap else w
        rho = k_rho * w
        n = one + rho * rho
        cq = -w / n
        # i_d = 0: the chord of the voltage disk on the q axis
        disc = stall * stall * n - (w * rho) * (w * rho)
        h = np.sqrt(_max(disc, zero)) / n
        top = cq + h
        bot = cq - h
        ok = (disc >= zero) & (top >= -limit_x)
        if has_fw:  # the q extent of the disk within the current circle
            sn = np.sqrt(n)
            cd = -w * rho / n
            r = stall / sn
            d = w / sn
            a = (M * M - r * r + d * d) / ((one + one) * (d if d > zero else one))
            hh = np.sqrt(_max(M * M - a * a, zero))
            up = (-a + hh * rho) / sn
            down = (-a - hh * rho) / sn
            top1 = (
                M
                if cd * cd + (M - cq) * (M - cq) <= r * r
                else (cq + r if cd * cd + (cq + r) * (cq + r) <= M * M else up)
            )
            bot1 = (
                -M
                if cd * cd + (M + cq) * (M + cq) <= r * r
                else (cq - r if cd * cd + (cq - r) * (cq - r) <= M * M else down)
            )
            ok1 = (d <= M + r) & (top1 >= -limit_x)
            weak = fw > zero
            top = top1 if weak else top
            bot = bot1 if weak else bot
            ok = ok1 if weak else ok
        reach = limit_x + w
        full = reach * reach + (rho * limit_x) * (rho * limit_x) <= stall * stall
        hi = limit_x if full | (top >= limit_x) else top
        lo = -limit_x if full | (bot <= -limit_x) else bot
        ok = full | ok
        # past control: the diode bridge's current, its q part
        m = _max((-stall + np.sqrt(_max(w * w * n - (stall * rho) * (stall * rho), zero))) / n, zero)
        xq = -(m + stall) * m / np.sqrt((m + stall) * (m + stall) + (rho * m) * (rho * m))
        hi = hi if ok else xq
        lo = lo if ok else xq
        neg = u < zero
        return (-hi if neg else lo), (-lo if neg else hi)

    return window


@cache
def _heated_fn() -> Any:
    """One element's constants at its winding temperature, as the numpy steps make them (inlined into the loop)."""
    _, _max, _min = _helpers()
    inline = _numba().njit(nogil=True, boundscheck=False, fastmath=False, error_model="numpy", inline="always")

    @inline  # type: ignore[untyped-decorator]
    def heated(
        temp: Any, reference: Any, heats: Any, v: Any, uk: Any, lim: Any, kr: Any, ck: Any, zero: Any, one: Any
    ) -> tuple[Any, Any, Any, Any, Any, Any, Any, Any]:
        # heats: (a_R, a_K, derating start, winding limit, Kt x the drive's limit, S / V_bus) of the element at
        # ``temp`` [degC]; returns (S at V / s_R, -S, u s_K / s_R, the derated limit X, -X, k_rho / s_K, the derated
        # circle, s_K) (:mod:`hound_id.mor.thermal`)
        a_r, a_k, start, end, current_x, per_volt = heats
        s_r = one + a_r * (temp - reference)
        s_k = one + a_k * (temp - reference)
        band = end - start
        ramp = (end - temp) / (band if band > zero else one) if band > zero else zero
        d = one if temp < start else _min(_max(ramp, zero), one)
        d = temp if temp != temp else d
        s = _max(v / s_r, zero) * per_volt
        lim = _min(lim, d * current_x)
        return s, -s, uk * (s_k / s_r), lim, -lim, kr / s_k, ck * d, s_k

    return heated


@cache
def _correction(
    has_curve: bool,
    has_cap: bool,
    has_max_speed: bool,
    has_volts: bool,
    has_drive: bool,
    has_fw: bool,
    has_heat: bool = False,
) -> Any:
    """The loop for one set of motors' features: the flags are compile-time constants, so the loop has no branch
    and vectorises (a loop that tests them is 1.7x slower)."""
    jit, _max, _min = _helpers()
    _window = _window_fn(has_fw)
    _heated = _heated_fn()

    @jit  # type: ignore[untyped-decorator]
    def correction(
        tau_m: Any,
        u: Any,
        omega: Any,
        limits: Any,
        zero: Any,
        one: Any,
        speed_cap: Any,
        volts: Any,
        out: Any,
        temps: Any,
        heat: Any,
        reference: Any,
    ) -> None:
        stall, neg_stall, limit_x, neg_limit_x = limits[0], limits[1], limits[4], limits[5]
        q, top, neg_top, cap, neg_cap, wmax = limits[6], limits[7], limits[8], limits[9], limits[10], limits[11]
        per_volt, k_rho, circle, fw = limits[12], limits[13], limits[14], limits[15]
        a_r, a_k, start, end, current_x, nominal = heat[0], heat[1], heat[2], heat[3], heat[4], heat[5]
        for k in range(tau_m.size):
            uk, lim, nlim, kr, ck = u[k], limit_x[k], neg_limit_x[k], k_rho[k], circle[k]
            if has_heat:  # the 20 degC window at s_K omega / s_R and V / s_R, k_rho / s_K, the derated limit
                v = volts[k] if has_volts else nominal[k]
                heats = (a_r[k], a_k[k], start[k], end[k], current_x[k], per_volt[k])
                s, ns, uk, lim, nlim, kr, ck, s_k = _heated(temps[k], reference, heats, v, uk, lim, kr, ck, zero, one)
            elif has_volts:  # the stall torque at this element's bus voltage
                s = _max(volts[k], zero) * per_volt[k]
                ns = -s
            else:
                s = stall[k]
                ns = neg_stall[k]
            if has_drive:
                lo, up = _window(uk, s, kr, lim, ck, fw[k], zero, one, speed_cap)
                if has_curve:
                    lo = _min(_max(lo, neg_top[k]), top[k])
                    up = _min(_max(up, neg_top[k]), top[k])
            else:
                hi = s - uk  # upper voltage line
                lo = ns - uk
                if has_curve:  # the line ends that can pass the curve's top are held there
                    hi = _max(hi, neg_top[k])
                    lo = _min(lo, top[k])
                up = _max(_min(hi, lim), lo)  # the window cut to the driver's limit
                lo = _min(_max(lo, nlim), hi)
            if has_curve:  # x - q x|x|, as numpy's steps round it
                up = up - (abs(up) * q[k]) * up
                lo = lo - (abs(lo) * q[k]) * lo
            if has_cap:
                up = _min(_max(up, neg_cap[k]), cap[k])
                lo = _min(_max(lo, neg_cap[k]), cap[k])
            if has_heat:  # the flux scales the torque at every current
                lo = lo * s_k
                up = up * s_k
            t = tau_m[k]
            x = _min(_max(t, lo), up)
            if has_max_speed:  # past the rated speed only braking torque passes
                w = omega[k]
                x = _min(x, zero) if w > wmax[k] else x
                x = _max(x, zero) if w < -wmax[k] else x
            out[k] = x - t

    return correction


@cache
def _inside() -> Any:
    jit, _, _ = _helpers()

    @jit  # type: ignore[untyped-decorator]
    def inside(a: Any, a_bound: Any, b: Any, b_bound: Any) -> bool:
        ok = True
        for k in range(a.size):  # no early exit: a branch-free reduction vectorises
            ok &= (a[k] <= a_bound) & (a[k] >= -a_bound) & (b[k] <= b_bound) & (b[k] >= -b_bound)
        return ok

    return inside


def available() -> bool:
    """Whether the fused loops run (numba importable and not turned off by :data:`ENV`)."""
    return os.environ.get(ENV, "1") != "0" and _numba() is not None


def clip_correction(
    tau_m: Any,
    u: Any,
    omega: Any,
    c: Any,
    out: Any,
    volts: Any = None,
    temps: Any = None,
    heat: Any = None,
    reference: float = 0.0,
) -> None:
    """``out`` = clip(tau_m, interval(u)) - tau_m for C-contiguous arrays of one shape and dtype, with the
    constants ``c`` (:class:`hound_id.mor.clip_operators.Constants`, their ``stacked`` limits expanded to that shape);
    ``omega`` (the motor speeds) is read only when the constants have a rated speed, ``volts`` (the bus voltage
    per element, same shape) only when given, ``temps`` (the winding temperature per element [degC]) with ``heat``
    (the six thermal rows of :func:`hound_id.mor.clip_paths.heated_bounds`, expanded to that shape) and
    ``reference`` (the temperature [degC] the 20 degC constants hold at) only when given."""
    has_heat = temps is not None
    loop = _correction(c.has_curve, c.has_cap, c.has_max_speed, volts is not None, c.has_drive, c.has_fw, has_heat)
    flat = tau_m.reshape(-1)
    loop(
        flat,
        u.reshape(-1),
        flat if omega is None else omega.reshape(-1),
        c.stacked,
        out.dtype.type(0.0),
        out.dtype.type(1.0),
        out.dtype.type(SPEED_CAP),
        flat if volts is None else np.ascontiguousarray(volts).reshape(-1),
        out.reshape(-1),
        flat if temps is None else np.ascontiguousarray(temps).reshape(-1),
        c.stacked if heat is None else heat,
        out.dtype.type(reference),
    )


def within(a: Any, a_bound: float, b: Any, b_bound: float) -> bool:
    """Every element of ``a`` in [-a_bound, a_bound] and of ``b`` (same size) in [-b_bound, b_bound], False with a
    NaN, in one pass; C-contiguous arrays of one dtype. The bounds are rounded to it, as numpy compares them."""
    t = a.dtype.type
    return bool(_inside()(a.reshape(-1), t(a_bound), b.reshape(-1), t(b_bound)))
