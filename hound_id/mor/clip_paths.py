"""The clip's general paths (:class:`hound_id.mor.saturation.Saturation`), as functions of one call's operators
(:class:`hound_id.mor.clip_operators.Constants`): the motors' intervals at the joint speeds (at 20 degC or at each
winding's temperature), the clip with fresh arrays (autograd flows through it), and the exact clip for commands of
any size, in numpy and in torch, with its intermediates in reused buffers.

The short path of ordinary commands and the choice among the paths stay with the clip
(:meth:`hound_id.mor.saturation.Saturation.__call__`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hound_id.mor.clip_bounds import capped, is_torch, np_bounds, np_clip, torch_bounds
from hound_id.mor.clip_operators import Constants


def line_bounds(qd: Any, consts: Constants, volts: Any = None) -> tuple[Any, Any]:
    """The motors' intervals (:func:`hound_id.mor.region.torque_interval`) at joint velocities ``qd`` (already
    capped), as fresh arrays."""
    c = consts
    u = qd @ c.speed_map  # back-EMF damping * motor speed
    if is_torch(qd):
        import torch

        lo, hi = torch_bounds(c, u, volts)
        if c.has_max_speed:
            omega = qd @ c.A_inv.T
            hi = torch.where(omega > c.wmax, torch.clamp(hi, max=0.0), hi)
            lo = torch.where(omega < -c.wmax, torch.clamp(lo, min=0.0), lo)
        return lo, hi
    lo, hi = np_bounds(c, u, np.empty_like(u), np.empty_like(u), volts)
    if c.has_max_speed:
        omega = qd @ c.A_inv.T
        hi = np.where(omega > c.wmax, np.minimum(hi, 0.0), hi)
        lo = np.where(omega < -c.wmax, np.maximum(lo, 0.0), lo)
    return lo, hi


def heated_bounds(qd: Any, consts: Constants, volts: Any, temperature: Any, rows: tuple[Any, ...]) -> tuple[Any, Any]:
    """The intervals at each element's winding temperature (:mod:`hound_id.mor.thermal`): s_K times the 20 degC
    window at speed s_K omega / s_R and bus V / s_R, the reactance's k_rho / s_K and the derated current limit.

    ``rows`` are the thermal rows and the nominal bus voltage per motor in ``qd``'s array type
    (:meth:`hound_id.mor.saturation.Saturation._thermal_like`)."""
    from hound_id.mor.thermal import REFERENCE, derating

    torch_like = is_torch(qd)
    a_r, a_k, start, limit, current_x, nominal = rows
    s_r = 1.0 + a_r * (temperature - REFERENCE)
    s_k = 1.0 + a_k * (temperature - REFERENCE)
    if volts is None:
        volts = nominal
    d = derating(temperature, start, limit)
    c = consts
    if torch_like:
        import torch

        lim = torch.minimum(c.limit_x, d * current_x)
    else:
        lim = np.minimum(c.limit_x, d * current_x)
    c = c._replace(limit_x=lim, neg_limit_x=-lim, circle_x=c.circle_x * d, k_rho=c.k_rho / s_k)
    qd = capped(qd, consts.qd_cap)
    u = (qd @ c.speed_map) * (s_k / s_r)
    if torch_like:
        lo, hi = torch_bounds(c, u, volts / s_r)
    else:
        lo, hi = np_bounds(c, u, np.empty_like(u), np.empty_like(u), volts / s_r)
    lo, hi = lo * s_k, hi * s_k
    if c.has_max_speed:
        omega = qd @ c.A_inv.T
        if torch_like:
            hi = torch.where(omega > c.wmax, torch.clamp(hi, max=0.0), hi)
            lo = torch.where(omega < -c.wmax, torch.clamp(lo, min=0.0), lo)
        else:
            hi = np.where(omega > c.wmax, np.minimum(hi, 0.0), hi)
            lo = np.where(omega < -c.wmax, np.maximum(lo, 0.0), lo)
    return lo, hi


def clip_fresh(tau: Any, consts: Constants, lo: Any, hi: Any) -> Any:
    """The clip to the motor intervals [lo, hi] with fresh arrays (autograd flows through it)."""
    tau_m = capped(tau, consts.tau_cap) @ consts.A
    if is_torch(tau):
        import torch

        clipped = torch.clamp(tau_m, lo, hi)
        touched = torch.abs(clipped - tau_m) @ consts.groups
        return torch.where(touched == 0, tau, clipped @ consts.A_inv)
    clipped = np.clip(tau_m, lo, hi)
    touched = np.abs(clipped - tau_m) @ consts.groups
    return np.where(touched == 0, tau, clipped @ consts.A_inv)


def clip_exact_numpy(tau: Any, qd: Any, consts: Constants, volts: Any, workspace: tuple[Any, ...]) -> Any:
    """The exact path in numpy, for commands of any size: the inputs capped, the clipped motor torques
    mapped back (tau_j = A^-T clip(tau_m)), the command kept in the joints of groups none of whose
    motors clipped. The joints are picked without branches; ``workspace`` holds the intermediates
    (:meth:`hound_id.mor.saturation.Saturation._workspace`)."""
    c = consts
    u, v, tau_m, pick, untouched, w = workspace
    qd, tau = capped(qd, c.qd_cap), capped(tau, c.tau_cap)
    np.matmul(qd, c.speed_map, out=u)  # back-EMF damping * motor speed
    np.matmul(tau, c.A, out=tau_m)
    omega = qd @ c.A_inv.T if c.has_max_speed else None
    lo, hi = np_bounds(c, u, v, w, volts)  # lo is v
    np_clip(tau_m, lo, hi, out=v)
    if omega is not None:  # past the rated speed only braking torque passes
        np.minimum(v, 0.0, out=v, where=omega > c.wmax)
        np.maximum(v, 0.0, out=v, where=omega < -c.wmax)
    np.subtract(v, tau_m, out=u)
    np.absolute(u, out=u)
    np.matmul(u, c.groups, out=tau_m)  # 0 exactly in the joints of groups whose motors all passed
    out = np.matmul(v, c.A_inv)  # the clipped motor torques mapped back: tau_j = A^-T tau_m
    # out = tau * k + out * (1 - k), k = 1 where untouched: exact with k in {0, 1}, both finite;
    # branch-free, unlike np.where, whose cost follows the pattern of the mask.
    np.copyto(pick, np.equal(tau_m, 0.0, out=untouched))
    np.multiply(tau, pick, out=v)
    np.subtract(1.0, pick, out=pick)
    np.multiply(out, pick, out=out)
    return np.add(out, v, out=out)


def clip_exact_torch(tau: Any, qd: Any, consts: Constants, volts: Any, workspace: tuple[Any, ...]) -> Any:
    """:func:`clip_exact_numpy` in torch, for every batch on a GPU (deciding would cost a device sync)."""
    import torch

    c = consts
    u, v, tau_m, tau_in, qd_in = workspace
    torch.clamp(qd, -c.qd_cap, c.qd_cap, out=qd_in)
    torch.clamp(tau, -c.tau_cap, c.tau_cap, out=tau_in)
    torch.matmul(qd_in, c.speed_map, out=u)
    torch.matmul(tau_in, c.A, out=tau_m)
    lo, hi = torch_bounds(c, u, volts)
    torch.clamp(tau_m, lo, hi, out=v)
    if c.has_max_speed:
        omega = qd_in @ c.A_inv.T
        torch.where(omega > c.wmax, torch.clamp(v, max=0.0), v, out=v)
        torch.where(omega < -c.wmax, torch.clamp(v, min=0.0), v, out=v)
    torch.sub(v, tau_m, out=u)
    torch.abs(u, out=u)
    torch.matmul(u, c.groups, out=tau_m)
    w = torch.matmul(v, c.A_inv, out=u)
    # lerp(a, b, s) is a + s (b - a) for s < 0.5 and b - (b - a)(1 - s) above: exactly a at s = 0 and
    # b at s = 1 (b - a is finite, a being capped); NaN stays NaN. Cheaper than where on the CPU.
    return torch.lerp(tau_in, w, torch.sign(tau_m, out=tau_m))
