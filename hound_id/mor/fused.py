"""The saturation's elementwise steps fused into one pass (numba), when numba is installed.

The clip of an ordinary command (:meth:`hound_id.mor.saturation.Saturation._saturate_ordinary`) is three small
matrix products and some fifteen elementwise steps: the voltage window, the driver's limit, the current-torque
curve, the clip and the correction. numpy makes one pass over memory per step; for a 4096 x 12 batch each pass
costs about as much as the whole per-joint clip of a trainer makes in all. :func:`clip_correction` does the
elementwise steps in one compiled loop, in the same order and the same dtype as the numpy steps, so its result is
the same bit for bit (NaN propagation included: ``_max``/``_min`` are numpy's maximum and minimum). The products
stay numpy's (BLAS), so the sums are rounded as before.

numba is optional (``pip install 'hound-id[fast]'``): without it, or with ``HOUND_ID_FUSED=0`` in the
environment, the numpy steps run. The loops compile on first use (about a second per dtype, cached on disk
afterwards).
"""

from __future__ import annotations

import os
from functools import cache
from typing import Any

#: Environment variable that turns the fused loops off ("0").
ENV = "HOUND_ID_FUSED"


@cache
def _kernels() -> tuple[Any, Any] | None:
    try:
        import numba
    except ImportError:
        return None

    jit = numba.njit(cache=True, nogil=True, boundscheck=False, fastmath=False)

    @jit  # type: ignore[untyped-decorator]
    def _max(a: Any, b: Any) -> Any:  # numpy's maximum: NaN if either is
        return a if (a >= b or a != a) else b

    @jit  # type: ignore[untyped-decorator]
    def _min(a: Any, b: Any) -> Any:  # numpy's minimum
        return a if (a <= b or a != a) else b

    @jit  # type: ignore[untyped-decorator]
    def correction(  # noqa: PLR0913 - one compiled loop takes every operand
        tau_m: Any,
        u: Any,
        omega: Any,
        stall: Any,
        neg_stall: Any,
        limit_x: Any,
        neg_limit_x: Any,
        q: Any,
        top: Any,
        neg_top: Any,
        cap: Any,
        neg_cap: Any,
        wmax: Any,
        has_curve: bool,
        has_cap: bool,
        has_max_speed: bool,
        zero: Any,
        out: Any,
    ) -> None:
        for k in range(tau_m.size):
            uk = u[k]
            hi = stall[k] - uk  # upper voltage line
            lo = neg_stall[k] - uk
            if has_curve:  # the line ends that can pass the curve's top are held there
                hi = _max(hi, neg_top[k])
                lo = _min(lo, top[k])
            up = _max(_min(hi, limit_x[k]), lo)  # the window cut to the driver's limit
            lo = _min(_max(lo, neg_limit_x[k]), hi)
            if has_curve:  # x - q x|x|, as numpy's steps round it
                up = up - (abs(up) * q[k]) * up
                lo = lo - (abs(lo) * q[k]) * lo
            if has_cap:
                up = _min(_max(up, neg_cap[k]), cap[k])
                lo = _min(_max(lo, neg_cap[k]), cap[k])
            t = tau_m[k]
            x = _min(_max(t, lo), up)
            if has_max_speed:  # past the rated speed only braking torque passes
                w = omega[k]
                if w > wmax[k]:
                    x = _min(x, zero)
                if w < -wmax[k]:
                    x = _max(x, zero)
            out[k] = x - t

    @jit  # type: ignore[untyped-decorator]
    def inside(x: Any, b: Any) -> bool:
        for k in range(x.size):
            if not (x[k] <= b and x[k] >= -b):
                return False
        return True

    return correction, inside


def available() -> bool:
    """Whether the fused loops run (numba importable and not turned off by :data:`ENV`)."""
    return os.environ.get(ENV, "1") != "0" and _kernels() is not None


def clip_correction(tau_m: Any, u: Any, omega: Any, c: Any, out: Any) -> None:
    """``out`` = clip(tau_m, interval(u)) - tau_m for C-contiguous arrays of one shape and dtype, with the
    constants ``c`` (:class:`hound_id.mor.saturation._Constants`, expanded to that shape); ``omega`` (the motor
    speeds) is read only when the constants have a rated speed."""
    kernels = _kernels()
    assert kernels is not None
    flat = [a.reshape(-1) for a in (tau_m, u, omega if omega is not None else tau_m)]
    limits = [c.stall, c.neg_stall, c.limit_x, c.neg_limit_x, c.curve_q, c.curve_top, c.neg_curve_top]
    limits += [c.top_torque, c.neg_top_torque, c.wmax]
    kernels[0](
        *flat,
        *(a.reshape(-1) for a in limits),
        c.has_curve,
        c.has_cap,
        c.has_max_speed,
        out.dtype.type(0.0),
        out.reshape(-1),
    )


def within(x: Any, bound: float) -> bool:
    """Every element of a C-contiguous array in [-bound, bound] (False with a NaN), in one pass."""
    kernels = _kernels()
    assert kernels is not None
    return bool(kernels[1](x.reshape(-1), x.dtype.type(bound)))  # the bound rounded as numpy compares it
