"""What one call of the clip (:class:`hound_id.mor.saturation.Saturation`) works with: its inputs checked and
broadcast, and the clip's maps and per-motor limits in the array library, dtype, device and batch shape of the input.

:func:`build_constants` makes the operators of one kind of input (the clip caches them); :func:`caps` the largest
inputs the maps take without overflow; :func:`check_inputs` and :func:`per_element` check the commands and speeds
and broadcast a bus voltage or temperature to them. numpy only at import (torch inside the functions given tensors).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray

from hound_id.errors import SaturationError
from hound_id.mor.clip_bounds import is_torch, largest
from hound_id.mor.region import SPEED_TOLERANCE

#: Cached operator sets (dtype, device, batch shape) kept per Saturation.
CACHE_SIZE = 16
#: Inputs are capped at the dtype's largest finite value / (this x the largest column sum of the map
#: they go through), so no product or partial sum of the maps can overflow (see :func:`caps`).
HEADROOM = 4.0
#: Commands whose joint torques keep every motor torque within this many times the largest stall torque
#: (or torque limit) take the short path: the mapped correction added to the command, whose rounding is
#: then a few tens of roundings of the limits at most (see :meth:`hound_id.mor.saturation.Saturation.__call__`).
ORDINARY = 4.0


def coupled_groups(A: NDArray[np.float64]) -> NDArray[np.float64]:
    """0/1 matrix G (motors x joints): G[m, j] = 1 when motor m and joint j belong to one coupled group.

    The groups are the connected parts of the graph joining joint j and motor m wherever A[j, m] or
    A^-1[m, j] is non-zero: a clip of motor m can change only the joint torques of its group.
    """
    n = A.shape[0]
    parent = list(range(2 * n))  # joints 0..n-1, motors n..2n-1

    def root(k: int) -> int:
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    pattern = (A != 0) | (np.linalg.inv(A).T != 0)
    for j, m in zip(*np.nonzero(pattern), strict=True):
        parent[root(int(j))] = root(n + int(m))
    return np.array([[float(root(n + m) == root(j)) for j in range(n)] for m in range(n)])


class Constants(NamedTuple):
    """What one call needs, in the array library, dtype, device and batch shape of its input."""

    A: Any
    A_inv: Any
    speed_map: Any
    """A^-T scaled by each motor's back-EMF damping: qd @ speed_map = damping * motor speed."""
    groups: Any
    """:func:`coupled_groups` of A."""
    stall: Any
    neg_stall: Any
    torque_limit: Any
    neg_torque_limit: Any
    limit_x: Any
    """Per motor Kt I, the linear-equivalent torque of the current at the torque limit."""
    neg_limit_x: Any
    curve_q: Any
    """Per motor q of the quadratic current-torque curve, x - q x|x| (0: linear)."""
    curve_top: Any
    """Per motor linear-equivalent torque at the curve's top, 1 / (2 q) (inf: linear)."""
    neg_curve_top: Any
    top_torque: Any
    """Per motor torque cap of a table curve past its polyline (inf elsewhere)."""
    neg_top_torque: Any
    has_cap: bool
    has_curve: bool
    wmax: Any
    has_max_speed: bool
    tau_cap: float
    """Largest |joint torque| the maps take without overflow (larger ones are capped to it)."""
    qd_cap: float
    """Largest |joint velocity| likewise."""
    ordinary: float
    """Largest |joint torque| of an ordinary command (:data:`ORDINARY`)."""
    stacked: Any = None
    """numpy: the per-motor limits above and below, stall to fw, as rows of one (16, size) array whose rows they view
    (the fused loop's operand, :func:`hound_id.mor.fused.clip_correction`); None for torch."""
    stall_per_volt: Any = None
    """Per motor S / V_bus [N m/V]: the stall torque at another bus voltage is this times it."""
    k_rho: Any = None
    """Per motor l / (R D) of the drive's reactance [1/(N m)] (0: none; :func:`hound_id.mor.drive.dq_window`)."""
    circle_x: Any = None
    """Per motor Kt I_max [N m], the field-weakening current circle."""
    fw: Any = None
    """Per motor whether the drive weakens the field (booleans; the fused loop reads the stacked row, 1.0 or 0.0)."""
    has_drive: bool = False
    """Whether any motor has a drive model (then every motor's window is the dq one)."""
    has_fw: bool = False
    """Whether any motor's drive weakens the field."""


class ClipArrays(Protocol):
    """The per-motor arrays the operators are built from: the fields of :class:`hound_id.mor.saturation.Saturation`
    (see their units there)."""

    @property
    def n(self) -> int: ...
    @property
    def A(self) -> NDArray[np.float64]: ...
    @property
    def A_inv(self) -> NDArray[np.float64]: ...
    @property
    def stall_torque(self) -> NDArray[np.float64]: ...
    @property
    def back_emf_damping(self) -> NDArray[np.float64]: ...
    @property
    def torque_limit(self) -> NDArray[np.float64]: ...
    @property
    def max_speed(self) -> NDArray[np.float64]: ...
    @property
    def limit_x(self) -> NDArray[np.float64] | None: ...
    @property
    def curve_q(self) -> NDArray[np.float64] | None: ...
    @property
    def top_torque(self) -> NDArray[np.float64] | None: ...
    @property
    def bus_voltage(self) -> NDArray[np.float64] | None: ...
    @property
    def drive_k_rho(self) -> NDArray[np.float64] | None: ...
    @property
    def drive_circle_x(self) -> NDArray[np.float64] | None: ...
    @property
    def drive_fw(self) -> NDArray[np.bool_] | None: ...


def caps(arrays: ClipArrays, dtype: Any) -> tuple[float, float]:
    """(torque cap, speed cap) for a dtype: |x| <= cap keeps every product and partial sum of
    x @ M below a quarter of the dtype's largest value, for each map M the input goes through.

    Only inputs within a factor 4 x (column sum) of the float range are capped (float64: above
    about 1e307; float32: about 1e37). Such a command is outside every motor's interval and stays
    clipped to an edge; where coupled commands that large nearly cancel, the edge may differ from
    the one exact arithmetic would pick. Such a speed is far past overspeed.
    """
    big = largest(dtype) / HEADROOM

    def cap(*maps: NDArray[np.float64]) -> float:
        return big / max(1.0, *(float(np.abs(m).sum(axis=0).max()) for m in maps))

    speed_map = arrays.A_inv.T * arrays.back_emf_damping[None, :]
    return cap(arrays.A), cap(speed_map, arrays.A_inv.T)


def _motor_rows(arrays: ClipArrays) -> tuple[tuple[NDArray[Any], ...], tuple[NDArray[Any], ...]]:
    """(the four maps, the sixteen per-motor limit vectors in :class:`Constants`' order, stall to fw) in numpy."""
    # u = qd @ speed_map is back_emf_damping * omega_m, folded into one product.
    speed_map = arrays.A_inv.T * arrays.back_emf_damping[None, :]
    wmax = arrays.max_speed * (1.0 + SPEED_TOLERANCE)
    matrices = (arrays.A, arrays.A_inv, speed_map, coupled_groups(arrays.A))
    limit_x = arrays.torque_limit if arrays.limit_x is None else arrays.limit_x
    q = np.zeros(arrays.n) if arrays.curve_q is None else arrays.curve_q
    with np.errstate(divide="ignore"):
        top = np.where(q > 0, 0.5 / np.where(q > 0, q, 1.0), np.inf)
    vectors: tuple[NDArray[Any], ...] = (arrays.stall_torque, -arrays.stall_torque, arrays.torque_limit)
    cap = np.full(arrays.n, np.inf) if arrays.top_torque is None else arrays.top_torque
    vectors = (*vectors, -arrays.torque_limit, limit_x, -limit_x, q, top, -top, cap, -cap, wmax)
    volts = np.full(arrays.n, np.nan) if arrays.bus_voltage is None else arrays.bus_voltage
    k_rho = np.zeros(arrays.n) if arrays.drive_k_rho is None else arrays.drive_k_rho
    circle = limit_x if arrays.drive_circle_x is None else arrays.drive_circle_x
    fw = np.zeros(arrays.n) if arrays.drive_fw is None else arrays.drive_fw.astype(float)
    return matrices, (*vectors, arrays.stall_torque / volts, k_rho, circle, fw)


def build_constants(arrays: ClipArrays, like: Any) -> Constants:
    """Operators in the array library, dtype, device and batch shape of ``like``.

    Per-motor limits are stored expanded to the full batch shape: elementwise
    operations on equal shapes run several times faster than broadcasting a
    (n,) vector, in numpy and torch alike (and Isaac Lab stores its limits so).
    """
    torch_like = is_torch(like)
    shape = tuple(like.shape)
    matrices, vectors = _motor_rows(arrays)
    if torch_like:
        import torch

        mats: tuple[Any, ...] = tuple(torch.tensor(np.array(a), dtype=like.dtype, device=like.device) for a in matrices)
        vecs: tuple[Any, ...] = tuple(
            torch.tensor(np.array(v), dtype=like.dtype, device=like.device).expand(shape).contiguous() for v in vectors
        )
    else:
        mats = tuple(np.ascontiguousarray(a, dtype=like.dtype) for a in matrices)
        stacked = np.empty((len(vectors), *shape), dtype=like.dtype)  # one block: the fused loop takes it whole
        for row, v in zip(stacked, vectors, strict=True):
            row[...] = v.astype(like.dtype)
        vecs = tuple(stacked)
    tau_cap, qd_cap = caps(arrays, like.dtype)
    colsum = max(1e-300, float(np.abs(arrays.A).sum(axis=0).max()))
    limit_x, q, cap = vectors[4], vectors[6], vectors[9]
    return Constants(
        A=mats[0],
        A_inv=mats[1],
        speed_map=mats[2],
        groups=mats[3],
        stall=vecs[0],
        neg_stall=vecs[1],
        torque_limit=vecs[2],
        neg_torque_limit=vecs[3],
        limit_x=vecs[4],
        neg_limit_x=vecs[5],
        curve_q=vecs[6],
        curve_top=vecs[7],
        neg_curve_top=vecs[8],
        top_torque=vecs[9],
        neg_top_torque=vecs[10],
        has_cap=bool(np.isfinite(cap).any()),
        has_curve=bool(np.any(q > 0)),
        wmax=vecs[11],
        has_max_speed=bool(np.isfinite(arrays.max_speed).any()),
        tau_cap=tau_cap,
        qd_cap=qd_cap,
        stacked=None if torch_like else stacked.reshape(len(vectors), -1),
        stall_per_volt=vecs[12],
        k_rho=vecs[13],
        circle_x=vecs[14],
        fw=vecs[15] > 0,
        has_drive=arrays.drive_k_rho is not None,
        has_fw=arrays.drive_fw is not None and bool(np.any(arrays.drive_fw)),
        ordinary=min(tau_cap, ORDINARY * float(max(arrays.stall_torque.max(), limit_x.max())) / colsum),
    )


def check_inputs(tau: Any, qd: Any, joints: tuple[str, ...]) -> tuple[Any, Any]:
    """Joint torques and velocities of one array type and float dtype, shaped (..., n), or SaturationError."""
    n = len(joints)
    if is_torch(tau) != is_torch(qd):
        raise SaturationError("tau and qd must both be numpy arrays or both torch tensors")
    if not is_torch(tau):
        tau = np.asarray(tau)
        qd = np.asarray(qd)
        if tau.dtype.kind != "f":
            tau = tau.astype(np.float64)
        if qd.dtype != tau.dtype:
            qd = qd.astype(tau.dtype)
    elif qd.dtype != tau.dtype:
        qd = qd.to(tau.dtype)
    if tau.shape[-1:] != (n,) or qd.shape[-1:] != (n,) or tuple(tau.shape) != tuple(qd.shape):
        raise SaturationError(
            f"saturation: tau has shape {tuple(tau.shape)} and qd {tuple(qd.shape)}; "
            f"expected both (..., {n}), the same shape, with joints in the order {', '.join(joints)}"
        )
    return tau, qd


def per_element(value: Any, like: Any, name: str, unit: str) -> Any:
    """``value`` (a bus voltage [V] or a temperature [degC]) per element of ``like``'s shape, in its array type, dtype
    and device, C-contiguous, or SaturationError. One value per environment, (..., 1), is repeated along the motors
    (numpy's broadcasting of a length-1 axis is several times slower than a repeat)."""
    shape = tuple(like.shape)
    if is_torch(like):
        import torch

        v = torch.as_tensor(value, dtype=like.dtype, device=like.device)
        if tuple(v.shape) == shape and v.is_contiguous():
            return v  # kept by the trainer at full shape (torch's broadcast_shapes alone costs ~10 us)
        try:
            fits = tuple(torch.broadcast_shapes(v.shape, shape)) == shape
        except RuntimeError:
            fits = False
        if not fits:
            raise SaturationError(_shape_message(tuple(v.shape), shape, name, unit))
        return torch.broadcast_to(v, shape).contiguous()
    values = np.asarray(value, dtype=like.dtype)
    if values.shape == shape and values.flags.c_contiguous:
        return values  # kept by the trainer at full shape: read as it is (the clip takes max(V, 0) itself)
    try:
        fits = np.broadcast_shapes(values.shape, shape) == shape
    except ValueError:
        fits = False
    if not fits:
        raise SaturationError(_shape_message(values.shape, shape, name, unit))
    if values.ndim == len(shape) and values.shape[:-1] == shape[:-1] and values.shape[-1] == 1 and shape[-1] > 1:
        return np.repeat(values, shape[-1], axis=-1)
    return np.ascontiguousarray(np.broadcast_to(values, shape))


def _shape_message(got: tuple[int, ...], want: tuple[int, ...], name: str, unit: str) -> str:
    """The error of a bus voltage or temperature whose shape does not broadcast to the commands'."""
    what = "voltage" if name == "bus_voltage" else name
    return (
        f"saturation: {name} has shape {got}, which does not broadcast to the commands' {want}; give one "
        f"{what} per environment as (..., 1) or one per motor as (..., {want[-1]}) [{unit}] (a 1-D array is per "
        "motor)"
    )


def rows_like(rows: list[NDArray[np.float64]], like: Any) -> tuple[Any, ...]:
    """Per-motor rows in the array type, dtype and device of ``like``."""
    if is_torch(like):
        import torch

        return tuple(torch.tensor(np.array(r), dtype=like.dtype, device=like.device) for r in rows)
    return tuple(np.asarray(r, dtype=like.dtype) for r in rows)


def polylines_like(
    polylines: tuple[tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None, ...],
    held: tuple[bool, ...],
    like: Any,
) -> tuple[Any, ...]:
    """The polylines' finite points (and the speeds they reach, infinite where ``held``) in the array library, dtype
    and device of ``like``."""
    convert: Any = np.asarray
    if is_torch(like):
        import torch

        def convert(a: Any) -> Any:
            return torch.tensor(np.array(a), dtype=like.dtype, device=like.device)

    lines: list[Any] = []
    for m, line in enumerate(polylines):
        if line is None:
            lines.append(None)
            continue
        speeds, lower, upper = line
        ok = np.isfinite(lower) & np.isfinite(upper)
        ends = (-math.inf, math.inf) if held and held[m] else (float(speeds[0]), float(speeds[-1]))
        lines.append((*ends, *(convert(a[ok]) for a in (speeds, lower, upper))))
    return tuple(lines)
