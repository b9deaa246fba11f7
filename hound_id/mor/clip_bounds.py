"""The elementwise work of the clip (:mod:`hound_id.mor.saturation`): each motor's torque interval at its speed in numpy
and torch (the linear-equivalent curve, the drive's dq window, measured and table polylines), the numpy views of
CPU tensors, and the caps that keep products finite."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen
from hound_id.mor.drive import dq_window
from hound_id.mor.fused import available as fused_available
from hound_id.mor.region import OperatingRegion

if TYPE_CHECKING:  # the runtime imports this module: no robot files (yaml, pint) at run time
    from hound_id.mor.spec import MeasuredEnvelope, MotorSpec


def is_torch(x: Any) -> bool:
    return type(x).__module__.startswith("torch")


def np_clip(x: Any, lo: Any, hi: Any, out: Any) -> Any:
    np.maximum(x, lo, out=out)
    return np.minimum(out, hi, out=out)


def np_bounds(c: Any, u: Any, lo: Any, hi: Any, volts: Any = None) -> tuple[Any, Any]:
    """The motors' torque intervals from u = back-EMF damping x motor speed
    (:func:`hound_id.mor.region.torque_interval`): the linear-equivalent window [-S - u, S - u] cut to [-X, X]
    (past overspeed, collapsed onto the end nearest it), then the current-torque curve. Returns (lower, upper) in
    two of the buffers ``u``, ``lo`` and ``hi`` (all three are overwritten).

    With a curve, the line ends that can pass the curve's top are held there first (the upper line only falls past
    -top, the lower only rises past +top; their other ends are cut to +-X <= top by the window), so the curve needs
    no clip of its own.

    ``volts`` (the bus voltage per element, shaped like ``u``: :meth:`Saturation._volts`) scales the stall torque,
    S = (S / V_bus) V; a drive's
    motors (:mod:`hound_id.mor.drive`) take its dq window instead of the voltage lines."""
    if c.has_drive:
        return _np_drive_bounds(c, u, lo, hi, volts)
    if volts is None:
        np.subtract(c.stall, u, out=hi)  # x_hi, upper voltage line
        np.subtract(c.neg_stall, u, out=lo)  # x_lo
    else:  # the stall torque at each element's bus voltage
        np.maximum(volts, 0.0, out=lo)
        np.multiply(lo, c.stall_per_volt, out=lo)
        np.subtract(lo, u, out=hi)
        np.negative(lo, out=lo)
        np.subtract(lo, u, out=lo)
    if c.has_curve:
        np.maximum(hi, c.neg_curve_top, out=hi)
        np.minimum(lo, c.curve_top, out=lo)
    np.minimum(hi, c.limit_x, out=u)
    np.maximum(u, lo, out=u)  # upper end of the window
    np.maximum(lo, c.neg_limit_x, out=lo)
    np.minimum(lo, hi, out=lo)  # lower end
    if c.has_curve:
        _np_curve(u, c, hi)
        _np_curve(lo, c, hi)
    if c.has_cap:  # table curves past their polylines: held at the curve's top
        np_clip(u, c.neg_top_torque, c.top_torque, out=u)
        np_clip(lo, c.neg_top_torque, c.top_torque, out=lo)
    return lo, u


def _np_drive_bounds(c: Any, u: Any, lo: Any, hi: Any, volts: Any = None) -> tuple[Any, Any]:
    """:func:`np_bounds` for robots with a drive model: the dq window (:func:`hound_id.mor.drive.dq_window`; a motor
    without reactance or field weakening gets the DC law's window from it, to rounding), then the curve. Returns
    (lower, upper) in ``lo`` and ``u``."""
    stall = c.stall if volts is None else np.maximum(volts, 0.0) * c.stall_per_volt
    x_lo, x_hi = dq_window(u, stall, c.k_rho, c.limit_x, c.circle_x, c.fw)
    if c.has_curve:  # the diode bridge's current may pass the curve's top: held there
        np.clip(x_lo, c.neg_curve_top, c.curve_top, out=lo)
        np.clip(x_hi, c.neg_curve_top, c.curve_top, out=u)
        _np_curve(u, c, hi)
        _np_curve(lo, c, hi)
    else:
        np.copyto(lo, x_lo)
        np.copyto(u, x_hi)
    if c.has_cap:
        np_clip(u, c.neg_top_torque, c.top_torque, out=u)
        np_clip(lo, c.neg_top_torque, c.top_torque, out=lo)
    return lo, u


def _np_curve(x: Any, c: Any, tmp: Any) -> None:
    """x -> x - q x|x| in place, for |x| within the curve's top (``tmp`` is scratch)."""
    np.absolute(x, out=tmp)
    tmp *= c.curve_q
    tmp *= x
    x -= tmp


def torch_bounds(c: Any, u: Any, volts: Any = None) -> tuple[Any, Any]:
    """:func:`np_bounds` in torch, as fresh tensors (autograd may flow through ``u``): (lower, upper)."""
    import torch

    stall = c.stall if volts is None else torch.clamp(volts, min=0.0) * c.stall_per_volt
    if c.has_drive:
        lo, hi = dq_window(u, stall, c.k_rho, c.limit_x, c.circle_x, c.fw)
        if c.has_curve:
            hi = torch.minimum(torch.maximum(hi, c.neg_curve_top), c.curve_top)
            lo = torch.minimum(torch.maximum(lo, c.neg_curve_top), c.curve_top)
    else:
        hi_x, lo_x = stall - u, -stall - u
        if c.has_curve:
            hi_x, lo_x = torch.maximum(hi_x, c.neg_curve_top), torch.minimum(lo_x, c.curve_top)
        hi = torch.maximum(torch.minimum(hi_x, c.limit_x), lo_x)  # past overspeed both collapse onto one end
        lo = torch.minimum(torch.maximum(lo_x, c.neg_limit_x), hi_x)
    if c.has_curve:
        hi, lo = hi - c.curve_q * hi * torch.abs(hi), lo - c.curve_q * lo * torch.abs(lo)
    if c.has_cap:
        hi = torch.minimum(torch.maximum(hi, c.neg_top_torque), c.top_torque)
        lo = torch.minimum(torch.maximum(lo, c.neg_top_torque), c.top_torque)
    return lo, hi


def numpy_views(tau: Any, qd: Any) -> tuple[Any, Any] | None:
    """numpy views of CPU float tensors (no copy), or None (GPU, other dtypes, tensors numpy cannot view).

    On the CPU numpy does the same arithmetic as torch in fewer microseconds per call for these small
    matrices, and the result is handed back as a tensor sharing its memory.
    """
    import torch

    if tau.device.type != "cpu" or tau.dtype not in (torch.float32, torch.float64):
        return None
    try:
        return tau.numpy(), qd.numpy()
    except (RuntimeError, TypeError):  # e.g. a tensor with its negative or conjugate bit set
        return None


def fusable(tau: NDArray[Any], qd: NDArray[Any]) -> bool:
    """Whether the fused loops take this call: numba present and both inputs C-contiguous float arrays of one
    dtype (the workspace and constants are then too)."""
    return (
        tau.dtype == qd.dtype
        and tau.dtype in (np.float32, np.float64)
        and tau.flags.c_contiguous
        and qd.flags.c_contiguous
        and fused_available()
    )


def within_interval(x: NDArray[Any], bound: float) -> bool:
    """Every element in [-bound, bound] (False with a NaN)."""
    return x.size == 0 or bool(x.max() <= bound and x.min() >= -bound)


def largest(dtype: Any) -> float:
    """The largest finite value of a numpy or torch floating dtype."""
    if type(dtype).__module__.startswith("torch"):
        import torch

        return float(torch.finfo(dtype).max)
    return float(np.finfo(dtype).max)


def capped(x: Any, cap: float, out: Any = None) -> Any:
    """``x`` clamped to [-cap, cap] (NaN stays NaN); numpy skips the copy when nothing is that large.

    Torch always clamps: a check would cost a device sync.
    """
    if is_torch(x):
        import torch

        return torch.clamp(x, -cap, cap, out=out)
    if x.size == 0 or (x.max() <= cap and x.min() >= -cap):
        return x
    return np.clip(x, -cap, cap, out=out)


def scaled_matmul(x: Any, M: Any, cap: float) -> Any:
    """x @ M without intermediate overflow for finite x: scaled by a power of two when |x| > cap."""
    if x.numel() == 0 if is_torch(x) else x.size == 0:
        return x @ M
    if x.max() <= cap and x.min() >= -cap:  # the usual case (False with a NaN)
        return x @ M
    if is_torch(x):
        import torch

        finite = x[torch.isfinite(x)]
        big = float(finite.abs().max()) if finite.numel() else 0.0
    else:
        finite = x[np.isfinite(x)]
        big = float(np.abs(finite).max()) if finite.size else 0.0
    if big <= cap:
        return x @ M
    scale = 2.0 ** math.ceil(math.log2(big / cap))
    with np.errstate(over="ignore"):
        return ((x / scale) @ M) * scale


def polyline_of(
    envelope: MeasuredEnvelope | Mapping[str, Any] | None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None:
    """(speeds, lower, upper) read-only arrays of a spec's measured envelope, or of a bundle's polyline
    (``{speeds, lower, upper}`` with None where no torque is feasible), or None."""
    if envelope is None:
        return None
    if not isinstance(envelope, Mapping):
        return envelope.polyline
    if not envelope:
        return None
    return (
        frozen(envelope["speeds"]),
        frozen([np.nan if v is None else v for v in envelope["lower"]]),
        frozen([np.nan if v is None else v for v in envelope["upper"]]),
    )


def interp(x: Any, xp: Any, fp: Any) -> Any:
    """Piecewise-linear interpolation of (xp, fp) at x, numpy or torch (x outside xp: the end values);
    xp and fp are already in x's array type."""
    if not is_torch(x):
        return np.interp(x, xp, fp)
    import torch

    k = torch.clamp(torch.searchsorted(xp, x.contiguous()), 1, xp.numel() - 1)
    x0, x1, f0, f1 = xp[k - 1], xp[k], fp[k - 1], fp[k]
    t = torch.clamp((x - x0) / (x1 - x0), 0.0, 1.0)
    return f0 + t * (f1 - f0)


def polyline_bounds(lines: Any, omega: Any, lo: Any, hi: Any) -> tuple[Any, Any]:
    """Replace the straight-line bounds of motors with a polyline, at speeds inside its range.

    ``lines`` per motor: None, or (first speed, last speed, speeds, lower, upper) with the finite
    points only, in omega's array type (see :meth:`Saturation._polylines_like`).
    """
    where: Any
    if is_torch(omega):
        import torch

        lo, hi = lo.clone(), hi.clone()
        where = torch.where
    else:
        lo, hi = lo.copy(), hi.copy()
        where = np.where
    for m, line in enumerate(lines):
        if line is None:
            continue
        first, last, speeds, lower, upper = line
        w = omega[..., m]
        inside = (w >= first) & (w <= last)
        lo[..., m] = where(inside, interp(w, speeds, lower), lo[..., m])
        hi[..., m] = where(inside, interp(w, speeds, upper), hi[..., m])
    return lo, hi


def quadratic_q(region: OperatingRegion) -> float:
    """q of a region's quadratic current-torque curve (0 for a linear or a table one)."""
    return 0.0 if region.curve is None else region.curve.q


def table_polyline(
    region: OperatingRegion,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None:
    """A table curve's region as a polyline (the clip interpolates it; its points are within the region's
    :data:`hound_id.mor.region.EDGE_TOLERANCE`), or None for a linear or quadratic curve."""
    from hound_id.mor.region import curved_edges

    if region.curve is None or region.curve.form != "table":
        return None
    if region.drive is not None:  # the diode braking fades before the curve's top: out to where the window is held
        from hound_id.mor.drive import SPEED_CAP

        return curved_edges(region, reach=SPEED_CAP * region.stall_torque / region.back_emf_damping)
    # out to where the forced braking current reaches the curve's top (beyond, the interval is the top: top_torque)
    reach = (region.stall_torque + region.curve.kt * region.curve.top_current) / region.back_emf_damping
    return curved_edges(region, reach=max(reach, region.overspeed) * (1 + 1e-6))


def table_top(region: OperatingRegion) -> float:
    """The most a table curve makes [N m]; inf for a linear or quadratic one."""
    return region.curve.top_torque if region.curve is not None and region.curve.form == "table" else math.inf


def drive_arrays(regions: list[OperatingRegion]) -> dict[str, Any]:
    """The Saturation fields of the motors' drive models (empty when none has one: the DC law throughout)."""
    if all(r.drive is None for r in regions):
        return {}
    return {
        "drive_k_rho": frozen([0.0 if r.drive is None else r.drive.k_rho for r in regions]),
        "drive_circle_x": frozen([r.limit_x if r.drive is None else r.drive.circle_x for r in regions]),
        "drive_fw": frozen(np.array([r.drive is not None and r.drive.field_weakening for r in regions])),
    }


def thermal_rows(specs: list[MotorSpec], regions: list[OperatingRegion]) -> NDArray[np.float64] | None:
    """:attr:`Saturation.thermal` of the motors (None when none has a thermal model)."""
    if all(s.thermal is None for s in specs):
        return None
    rows = np.empty((5, len(specs)))
    for m, (spec, region) in enumerate(zip(specs, regions, strict=True)):
        th = spec.thermal
        if th is None:
            rows[:, m] = (0.0, 0.0, math.inf, math.inf, region.limit_x)
        else:
            current_x = spec.current_curve.kt * spec.drive_current
            rows[:, m] = (th.alpha_resistance, th.alpha_kt, th.derate_start, th.winding_limit, current_x)
    return frozen(rows)
