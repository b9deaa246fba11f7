"""Motor torque saturation: the clip the method applies every simulation step.

Joint torque commands and joint velocities (arrays shaped (..., n_joints)) go to
motor space through the transmissions (tau_m = A^T tau_j, omega_m = A^-1 qd),
each motor's torque is clipped to its feasible interval at its speed
(:func:`hound_id.mor.region.torque_interval`), and the result goes back to joint
space (tau_j = A^-T tau_m). With numpy arrays the work is numpy; with torch
tensors on a GPU, or under autograd, it is torch operations only, so it runs on the
GPU and keeps autograd intact. Float CPU tensors without autograd are worked on by
numpy through views of their memory (fewer microseconds per call for these small
products), and the result comes back as a tensor.

The result is feasible for every finite input, in float32 and float64: commands far
past the limits have their clipped motor torques mapped back (not the command plus a
mapped correction, whose rounding grows with the command), and inputs are capped
where a product could overflow. See :meth:`Saturation.__call__`.

Past a motor's overspeed the result is its full braking torque; past its rated
``max_speed`` only braking (or zero) torque passes. See docs/saturate.md.

:func:`dc_motor_clip` is the per-joint DC-motor clip of Isaac Lab's ``DCMotor`` and
mjlab's ``DcMotorActuator``, kept as the reference the coupled clip must reduce to
for an uncoupled joint, and as the benchmark's baseline.

The elementwise bounds it takes are in :mod:`hound_id.mor.clip_bounds`; ``hound-id saturate`` on a log is
:mod:`hound_id.mor.saturate_log`.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen
from hound_id.errors import SaturationError
from hound_id.mor.clip_bounds import (
    capped,
    drive_arrays,
    fusable,
    is_torch,
    largest,
    np_bounds,
    np_clip,
    numpy_views,
    polyline_bounds,
    polyline_of,
    quadratic_q,
    scaled_matmul,
    table_polyline,
    table_top,
    thermal_rows,
    torch_bounds,
    within_interval,
)
from hound_id.mor.fused import clip_correction
from hound_id.mor.fused import within as fused_within
from hound_id.mor.region import SPEED_TOLERANCE, OperatingRegion, operating_region

if TYPE_CHECKING:  # the runtime imports this module: no robot files (yaml, pint) at run time
    from hound_id.mor.robot import Robot


#: Cached operator sets (dtype, device, batch shape) kept per Saturation.
_CACHE_SIZE = 16
#: Inputs are capped at the dtype's largest finite value / (this x the largest column sum of the map
#: they go through), so no product or partial sum of the maps can overflow (see :meth:`Saturation._caps`).
HEADROOM = 4.0
#: Commands whose joint torques keep every motor torque within this many times the largest stall torque
#: (or torque limit) take the short path: the mapped correction added to the command, whose rounding is
#: then a few tens of roundings of the limits at most (see :meth:`Saturation.__call__`).
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


class _Constants(NamedTuple):
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


@dataclass(frozen=True)
class Saturation:
    """Coupled motor-space torque saturation for a whole robot.

    Build it with :func:`saturation_for` (or :meth:`from_robot`), then call it:
    ``tau_sat = sat(tau_cmd, qd)``.
    """

    joints: tuple[str, ...]
    """Joint order of the last axis of every array."""
    A: NDArray[np.float64]
    """Global velocity map qd = A thetad_m (n x n, block diagonal up to ordering)."""
    A_inv: NDArray[np.float64]
    """Its inverse, thetad_m = A^-1 qd."""
    stall_torque: NDArray[np.float64]
    """Per motor Kt V_bus / R [N m]."""
    back_emf_damping: NDArray[np.float64]
    """Per motor Kt / (R Kv) [N m s/rad]."""
    torque_limit: NDArray[np.float64]
    """Per motor torque limit, min(peak torque, g(i_max)) [N m] (g the current-torque curve)."""
    max_speed: NDArray[np.float64]
    """Per motor rated maximum speed [rad/s]; inf where the spec gives none."""
    limit_x: NDArray[np.float64] | None = None
    """Per motor Kt I [N m], I the current the torque limit needs (None: the torque limit, a linear curve)."""
    curve_q: NDArray[np.float64] | None = None
    """Per motor q [1/(N m)] of the quadratic current-torque curve: torque = x - q x|x| in the linear-equivalent
    torque x = Kt i (None or 0: linear). A table curve is carried as a polyline."""
    top_torque: NDArray[np.float64] | None = None
    """Per motor the most torque a table curve makes [N m] (inf elsewhere; None: inf for all): past its polyline,
    which reaches the speed where the braking current meets the curve's top, a table motor's interval is held
    there."""
    polylines: tuple[tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None, ...] = ()
    held: tuple[bool, ...] = ()
    """Per motor whether its polyline holds its end values beyond its speeds (a table curve under a drive model,
    whose diode braking never reaches the curve's top; empty: none does); else the line bounds apply there."""
    """Per motor (speeds, lower, upper) edges of a measured envelope (``mor --compare --out``), or None.
    Where given, the motor's torque interval at speeds inside the polyline is interpolated from it."""
    bus_voltage: NDArray[np.float64] | None = None
    """Per motor nominal bus voltage [V] (None: unknown; then no other bus voltage can be given)."""
    drive_k_rho: NDArray[np.float64] | None = None
    """Per motor l / (R D) [1/(N m)] of the drive's reactance (:mod:`hound_id.mor.drive`; 0 for a motor without);
    None: no motor has a drive model (the DC law)."""
    drive_circle_x: NDArray[np.float64] | None = None
    """Per motor Kt I_max [N m], the phase-current circle of field weakening (None with ``drive_k_rho``)."""
    drive_fw: NDArray[np.bool_] | None = None
    """Per motor whether the drive weakens the field (None with ``drive_k_rho``)."""
    thermal: NDArray[np.float64] | None = None
    """Rows (a_R [1/K], a_K [1/K], derating start [degC], winding limit [degC], Kt x the drive's current limit [N m])
    per motor, shape (5, n), for ``temperature`` (:mod:`hound_id.mor.thermal`; a motor without a thermal model: 0, 0,
    inf, inf, its limit); None: no motor has one."""
    _cache: dict[Any, Any] = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def from_robot(cls, robot: Robot) -> Saturation:
        """Collect the robot's transmissions and motor regions into arrays."""
        by_spec: dict[int, OperatingRegion] = {}  # motors sharing a spec share its region (each costs ~0.1 s)
        for m in robot.motors:
            spec = robot.motor_specs[m]
            if id(spec) not in by_spec:
                by_spec[id(spec)] = operating_region(spec)
        regions = [by_spec[id(robot.motor_specs[m])] for m in robot.motors]
        A = robot.velocity_map()
        polylines = tuple(
            polyline_of(robot.motor_specs[m].envelope) or table_polyline(r)
            for m, r in zip(robot.motors, regions, strict=True)
        )
        held = tuple(  # a table curve's polyline under a drive model (a measured envelope's keeps its line bounds)
            p is not None and r.drive is not None and robot.motor_specs[m].envelope is None
            for m, r, p in zip(robot.motors, regions, polylines, strict=True)
        )
        return cls(
            joints=robot.joints,
            A=frozen(A),
            A_inv=frozen(np.linalg.inv(A)),
            stall_torque=frozen([r.stall_torque for r in regions]),
            back_emf_damping=frozen([r.back_emf_damping for r in regions]),
            torque_limit=frozen([r.torque_limit for r in regions]),
            max_speed=frozen([np.inf if r.max_speed is None else r.max_speed for r in regions]),
            limit_x=frozen([r.limit_x for r in regions]),
            curve_q=frozen([quadratic_q(r) for r in regions]),
            top_torque=frozen([table_top(r) for r in regions]),
            polylines=polylines if any(p is not None for p in polylines) else (),
            held=held if any(held) else (),
            bus_voltage=frozen([robot.motor_specs[m].bus_voltage for m in robot.motors]),
            thermal=thermal_rows([robot.motor_specs[m] for m in robot.motors], regions),
            **drive_arrays(regions),
        )

    @property
    def n(self) -> int:
        """Number of joints (= motors)."""
        return len(self.joints)

    def _caps(self, dtype: Any) -> tuple[float, float]:
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

        speed_map = self.A_inv.T * self.back_emf_damping[None, :]
        return cap(self.A), cap(speed_map, self.A_inv.T)

    def _constants(self, like: Any) -> _Constants:
        """Operators in the array library, dtype, device and batch shape of ``like`` (cached).

        Per-motor limits are stored expanded to the full batch shape: elementwise
        operations on equal shapes run several times faster than broadcasting a
        (n,) vector, in numpy and torch alike (and Isaac Lab stores its limits so).
        """
        torch_like = is_torch(like)
        shape = tuple(like.shape)
        key: Any = ("torch", like.dtype, like.device, shape) if torch_like else ("numpy", like.dtype, shape)
        hit = self._cache.get(key)
        if hit is not None:
            return hit  # type: ignore[no-any-return]
        # u = qd @ speed_map is back_emf_damping * omega_m, folded into one product.
        speed_map = self.A_inv.T * self.back_emf_damping[None, :]
        wmax = self.max_speed * (1.0 + SPEED_TOLERANCE)
        matrices = (self.A, self.A_inv, speed_map, coupled_groups(self.A))
        limit_x = self.torque_limit if self.limit_x is None else self.limit_x
        q = np.zeros(self.n) if self.curve_q is None else self.curve_q
        with np.errstate(divide="ignore"):
            top = np.where(q > 0, 0.5 / np.where(q > 0, q, 1.0), np.inf)
        vectors: tuple[NDArray[Any], ...] = (self.stall_torque, -self.stall_torque, self.torque_limit)
        cap = np.full(self.n, np.inf) if self.top_torque is None else self.top_torque
        vectors = (*vectors, -self.torque_limit, limit_x, -limit_x, q, top, -top, cap, -cap, wmax)
        volts = np.full(self.n, np.nan) if self.bus_voltage is None else self.bus_voltage
        k_rho = np.zeros(self.n) if self.drive_k_rho is None else self.drive_k_rho
        circle = limit_x if self.drive_circle_x is None else self.drive_circle_x
        fw = np.zeros(self.n) if self.drive_fw is None else self.drive_fw.astype(float)
        vectors = (*vectors, self.stall_torque / volts, k_rho, circle, fw)
        if torch_like:
            import torch

            mats: tuple[Any, ...] = tuple(
                torch.tensor(np.array(a), dtype=like.dtype, device=like.device) for a in matrices
            )
            vecs: tuple[Any, ...] = tuple(
                torch.tensor(np.array(v), dtype=like.dtype, device=like.device).expand(shape).contiguous()
                for v in vectors
            )
        else:
            mats = tuple(np.ascontiguousarray(a, dtype=like.dtype) for a in matrices)
            stacked = np.empty((len(vectors), *shape), dtype=like.dtype)  # one block: the fused loop takes it whole
            for row, v in zip(stacked, vectors, strict=True):
                row[...] = v.astype(like.dtype)
            vecs = tuple(stacked)
        tau_cap, qd_cap = self._caps(like.dtype)
        colsum = max(1e-300, float(np.abs(self.A).sum(axis=0).max()))
        consts = _Constants(
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
            has_max_speed=bool(np.isfinite(self.max_speed).any()),
            tau_cap=tau_cap,
            qd_cap=qd_cap,
            stacked=None if torch_like else stacked.reshape(len(vectors), -1),
            stall_per_volt=vecs[12],
            k_rho=vecs[13],
            circle_x=vecs[14],
            fw=vecs[15] > 0,
            has_drive=self.drive_k_rho is not None,
            has_fw=self.drive_fw is not None and bool(np.any(self.drive_fw)),
            ordinary=min(tau_cap, ORDINARY * float(max(self.stall_torque.max(), limit_x.max())) / colsum),
        )
        self._remember(key, consts)
        return consts

    def _remember(self, key: Any, value: Any) -> None:
        if len(self._cache) >= _CACHE_SIZE:
            self._cache.pop(next(iter(self._cache)))
        self._cache[key] = value

    def motor_state(self, tau: Any, qd: Any) -> tuple[Any, Any]:
        """Motor torques [N m] and speeds [rad/s] for joint torques and velocities.

        Exact to rounding for every finite input: where a product could overflow, the inputs are
        scaled by a power of two first, so a motor torque beyond the dtype's range is ±inf, not NaN.
        """
        tau, qd = self._check(tau, qd)
        consts = self._constants(tau)
        return scaled_matmul(tau, consts.A, consts.tau_cap), scaled_matmul(qd, consts.A_inv.T, consts.qd_cap)

    def _check(self, tau: Any, qd: Any) -> tuple[Any, Any]:
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
        if tau.shape[-1:] != (self.n,) or qd.shape[-1:] != (self.n,) or tuple(tau.shape) != tuple(qd.shape):
            raise SaturationError(
                f"saturation: tau has shape {tuple(tau.shape)} and qd {tuple(qd.shape)}; "
                f"expected both (..., {self.n}), the same shape, with joints in the order {', '.join(self.joints)}"
            )
        return tau, qd

    def torque_bounds(self, qd: Any, bus_voltage: Any = None, temperature: Any = None) -> tuple[Any, Any]:
        """Per-motor feasible torque interval [lo, hi] at the motor speeds implied by ``qd`` (and, if given, the bus
        voltage [V] and winding temperature [degC] of each element, broadcast against ``qd``: see
        :meth:`__call__`)."""
        _, qd = self._check(qd, qd)
        consts = self._constants(qd)
        volts = self._volts(bus_voltage, qd)
        if temperature is not None:
            return self._heated_bounds(qd, consts, volts, self._temperatures(temperature, qd))
        return self._bounds(qd, consts, volts)

    def _volts(self, bus_voltage: Any, like: Any, name: str = "bus_voltage", unit: str = "V") -> Any:
        """The bus voltage [V] per element of ``like``'s shape, in its array type, dtype and device, C-contiguous (the
        bounds take max(V, 0)); None stays None. One voltage per environment, (..., 1), is repeated along the motors
        (numpy's broadcasting of a length-1 axis is several times slower than a repeat)."""
        if bus_voltage is None:
            return None
        if self.bus_voltage is None:
            raise SaturationError("saturation: this clip has no nominal bus voltage, so it cannot take another one")
        shape = tuple(like.shape)
        if is_torch(like):
            import torch

            v = torch.as_tensor(bus_voltage, dtype=like.dtype, device=like.device)
            if tuple(v.shape) == shape and v.is_contiguous():
                return v  # kept by the trainer at full shape (torch's broadcast_shapes alone costs ~10 us)
            try:
                fits = tuple(torch.broadcast_shapes(v.shape, shape)) == shape
            except RuntimeError:
                fits = False
            if not fits:
                raise SaturationError(self._volts_shape(tuple(v.shape), shape, name, unit))
            return torch.broadcast_to(v, shape).contiguous()
        volts = np.asarray(bus_voltage, dtype=like.dtype)
        if volts.shape == shape and volts.flags.c_contiguous:
            return volts  # kept by the trainer at full shape: read as it is (the clip takes max(V, 0) itself)
        try:
            fits = np.broadcast_shapes(volts.shape, shape) == shape
        except ValueError:
            fits = False
        if not fits:
            raise SaturationError(self._volts_shape(volts.shape, shape, name, unit))
        if volts.ndim == len(shape) and volts.shape[:-1] == shape[:-1] and volts.shape[-1] == 1 and shape[-1] > 1:
            return np.repeat(volts, shape[-1], axis=-1)
        return np.ascontiguousarray(np.broadcast_to(volts, shape))

    def _temperatures(self, temperature: Any, like: Any) -> Any:
        """The winding temperature [degC] per element of ``like``'s shape (as :meth:`_volts`), or SaturationError."""
        if self.thermal is None:
            raise SaturationError(
                "saturation: no motor has a thermal model, so the clip cannot take a temperature; add "
                "thermal_time_constant, winding_limit and thermal_resistance (or continuous_current) to the specs"
            )
        if self.polylines:
            raise SaturationError(
                "saturation: a motor with a measured envelope or a table current-torque curve cannot be clipped at "
                "another temperature (its edges are held as a polyline at 20 degC); drop the temperature, or use a "
                "linear or quadratic curve"
            )
        if self.bus_voltage is None:
            raise SaturationError("saturation: this clip has no nominal bus voltage, so it cannot take a temperature")
        return self._volts(temperature, like, "temperature", "degC")

    def _heated_bounds(self, qd: Any, consts: _Constants, volts: Any, temperature: Any) -> tuple[Any, Any]:
        """The intervals at each element's winding temperature (:mod:`hound_id.mor.thermal`): s_K times the 20 degC
        window at speed s_K omega / s_R and bus V / s_R, the reactance's k_rho / s_K and the derated current limit."""
        from hound_id.mor.thermal import REFERENCE, derating

        torch_like = is_torch(qd)
        rows = self._thermal_like(qd)
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

    def _thermal_like(self, like: Any) -> tuple[Any, ...]:
        """The thermal rows and the nominal bus voltage, per motor, in the array type, dtype and device of ``like``."""
        key: Any = ("thermal", type(like), like.dtype, getattr(like, "device", None))
        hit = self._cache.get(key)
        if hit is None:
            assert self.thermal is not None and self.bus_voltage is not None
            rows = [*self.thermal, self.bus_voltage]
            if is_torch(like):
                import torch

                hit = tuple(torch.tensor(np.array(r), dtype=like.dtype, device=like.device) for r in rows)
            else:
                hit = tuple(np.asarray(r, dtype=like.dtype) for r in rows)
            self._remember(key, hit)
        return hit  # type: ignore[no-any-return]

    def _volts_shape(self, got: tuple[int, ...], want: tuple[int, ...], name: str, unit: str) -> str:
        what = "voltage" if name == "bus_voltage" else name
        return (
            f"saturation: {name} has shape {got}, which does not broadcast to the commands' {want}; give one "
            f"{what} per environment as (..., 1) or one per motor as (..., {self.n}) [{unit}] (a 1-D array is per "
            "motor)"
        )

    def _bounds(self, qd: Any, consts: _Constants, volts: Any = None) -> tuple[Any, Any]:
        qd = capped(qd, consts.qd_cap)
        lo, hi = self._line_bounds(qd, consts, volts)
        if self.polylines:
            omega = qd @ consts.A_inv.T
            lo, hi = polyline_bounds(self._polylines_like(qd), omega, lo, hi)
        return lo, hi

    def _polylines_like(self, like: Any) -> tuple[Any, ...]:
        """The polylines' finite points in the array library, dtype and device of ``like`` (cached: the clip
        runs every simulation step)."""
        key: Any = ("polylines", type(like), like.dtype, getattr(like, "device", None))
        hit = self._cache.get(key)
        if hit is None:
            convert: Any = np.asarray
            if is_torch(like):
                import torch

                def convert(a: Any) -> Any:
                    return torch.tensor(np.array(a), dtype=like.dtype, device=like.device)

            lines: list[Any] = []
            for m, line in enumerate(self.polylines):
                if line is None:
                    lines.append(None)
                    continue
                speeds, lower, upper = line
                ok = np.isfinite(lower) & np.isfinite(upper)
                ends = (-math.inf, math.inf) if self.held and self.held[m] else (float(speeds[0]), float(speeds[-1]))
                lines.append((*ends, *(convert(a[ok]) for a in (speeds, lower, upper))))
            hit = tuple(lines)
            self._remember(key, hit)
        return hit  # type: ignore[no-any-return]

    def _line_bounds(self, qd: Any, consts: _Constants, volts: Any = None) -> tuple[Any, Any]:
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

    def __call__(self, tau: Any, qd: Any, bus_voltage: Any = None, temperature: Any = None) -> Any:
        """Saturate joint torque commands [N m] at joint velocities [rad/s], shapes (..., n).

        Returns joint torques (same type, dtype and device as ``tau``) whose motor torques lie in
        each motor's operating region at its current speed, for every finite input, to within a
        few roundings of the limits (not of the command). Two paths give that:

        * ordinary commands (motor torques within :data:`ORDINARY` times the largest stall torque,
          checked on the CPU): the command plus the clip's correction mapped back, whose rounding
          is then a few tens of roundings of the limits at most; as before, so results are unchanged;
        * larger ones, and every batch on a GPU (where the check would cost a device sync): the
          clipped motor torques themselves mapped back, tau_j = A^-T clip(tau_m), with the inputs
          capped (:meth:`_caps`) so that no product overflows.

        Either way the joints of a coupled group none of whose motors was clipped pass unchanged.
        Speeds are taken as the dtype holds them: past |qd| ~ overspeed / eps the motor speed of a
        coupled joint is not resolved, and the clip uses the computed one.

        NaN propagates, in numpy and torch alike: a NaN command or speed gives NaN in every joint
        of its coupled group (and, through the matrix products of numpy's and torch's BLAS, of its
        row); nothing is raised, since a check would cost a device sync every step. ±inf commands
        are clipped like any command beyond the limits; ±inf speeds are past overspeed.

        ``bus_voltage`` [V] (optional) is the bus each element sees, broadcast against ``tau``: one per environment
        as (..., 1), or one per motor as (..., n), to randomise the battery's charge. The stall torque scales with it
        (the voltage lines shift; a drive's dq window follows it); the nominal bus is the spec's ``bus_voltage``.
        Negative voltages are taken as 0. Not given: the nominal bus, as before.

        ``temperature`` [degC] (optional) is each winding's temperature, shaped like ``bus_voltage``, for motors whose
        specs carry a thermal model (:mod:`hound_id.mor.thermal`): the resistance, Kt and the back-EMF constant
        follow it and the drive's current limit is derated. Ordinary commands on the CPU take the fused loop (numba;
        numpy and CPU tensors), the others the general path (fresh arrays), with the same result. It needs linear
        or quadratic current-torque curves. Not given: the 20 degC region, as before.
        """
        tau, qd = self._check(tau, qd)
        consts = self._constants(tau)
        volts = self._volts(bus_voltage, tau)
        if temperature is not None:
            temps = self._temperatures(temperature, tau)
            if not (is_torch(tau) and (tau.requires_grad or qd.requires_grad)):
                fast = self._saturate_heated_fused(tau, qd, volts, temps)
                if fast is not None:
                    return fast
            return self._saturate(tau, qd, consts, volts, temps)
        if self.polylines or (is_torch(tau) and (tau.requires_grad or qd.requires_grad)):
            return self._saturate(tau, qd, consts, volts)  # measured envelopes or autograd: the general path
        return self._saturate_in_place(tau, qd, consts, volts)

    def _saturate_heated_fused(self, tau: Any, qd: Any, volts: Any, temps: Any) -> Any:
        """The clip at winding temperatures ``temps`` through the fused loop
        (:func:`hound_id.mor.fused.clip_correction`) for ordinary commands in C-contiguous numpy arrays or CPU
        tensors; None where it does not apply (then the general path runs). Same result as :meth:`_saturate` with
        the temperatures, to the correction's rounding."""
        if is_torch(tau):
            views = numpy_views(tau, qd)
            if views is None or not (temps.is_contiguous() and (volts is None or volts.is_contiguous())):
                return None
            import torch

            out = self._saturate_heated_fused(*views, None if volts is None else volts.numpy(), temps.detach().numpy())
            return None if out is None else torch.from_numpy(out)
        if not fusable(tau, qd):
            return None
        c = self._constants(tau)
        if not fused_within(tau, c.ordinary, qd, c.qd_cap):
            return None
        key: Any = ("heat-rows", tau.dtype, tuple(tau.shape))
        rows = self._cache.get(key)
        if rows is None:
            per_motor = self._thermal_like(tau)
            rows = np.empty((len(per_motor), tau.size), dtype=tau.dtype)
            for row, values in zip(rows, per_motor, strict=True):
                row.reshape(tau.shape)[...] = values
            self._remember(key, rows)
        u, v, tau_m, _, _, _ = self._workspace(tau)
        np.matmul(qd, c.speed_map, out=u)
        np.matmul(tau, c.A, out=tau_m)
        from hound_id.mor.thermal import REFERENCE

        omega = qd @ c.A_inv.T if c.has_max_speed else None
        clip_correction(tau_m, u, omega, c, v, volts, temps, rows, REFERENCE)
        out = np.matmul(v, c.A_inv)
        out += tau
        return out

    def _saturate(self, tau: Any, qd: Any, consts: _Constants, volts: Any = None, temperature: Any = None) -> Any:
        """The clip with fresh arrays (autograd flows through it)."""
        if temperature is not None:
            lo, hi = self._heated_bounds(qd, consts, volts, temperature)
        else:
            lo, hi = self._bounds(qd, consts, volts)
        tau_m = capped(tau, consts.tau_cap) @ consts.A
        if is_torch(tau):
            import torch

            clipped = torch.clamp(tau_m, lo, hi)
            touched = torch.abs(clipped - tau_m) @ consts.groups
            return torch.where(touched == 0, tau, clipped @ consts.A_inv)
        clipped = np.clip(tau_m, lo, hi)
        touched = np.abs(clipped - tau_m) @ consts.groups
        return np.where(touched == 0, tau, clipped @ consts.A_inv)

    def _saturate_in_place(self, tau: Any, qd: Any, consts: _Constants, volts: Any = None) -> Any:
        """The clip with intermediates in reused per-thread buffers (not under autograd).

        Large temporaries cost more in allocation (page faults) than in arithmetic on
        the CPU, so only the returned array is new.

        Ordinary commands (motor torques within :data:`ORDINARY` stall torques, speeds below
        the cap: checked on the CPU, where a check costs no device sync) take the short path of
        :meth:`_saturate_ordinary`; the others, and every batch on a GPU, the exact one. CPU
        tensors go through numpy views (:func:`numpy_views`).
        """
        c = consts
        if is_torch(tau):
            views = numpy_views(tau, qd)
            if views is None:
                return self._saturate_torch(tau, qd, consts, volts)
            import torch

            v = None if volts is None else volts.numpy()
            return torch.from_numpy(self._saturate_in_place(*views, self._constants(views[0]), v))
        fused = fusable(tau, qd)
        ordinary = fused_within(tau, c.ordinary, qd, c.qd_cap) if fused else within_interval(tau, c.ordinary)
        if not (ordinary and (fused or within_interval(qd, c.qd_cap))):
            return self._saturate_numpy(tau, qd, consts, volts)
        return self._saturate_ordinary(tau, qd, consts, fused, volts)

    def _saturate_ordinary(self, tau: Any, qd: Any, consts: _Constants, fused: bool = False, volts: Any = None) -> Any:
        """Clip, then add the clip's correction mapped back: tau + A^-T (clip(tau_m) - tau_m).

        The correction is exactly 0 in the joints of groups whose motors all passed, so those pass bit
        for bit. Its rounding is eps times the command's size, which :data:`ORDINARY` keeps within a few
        stall torques (beyond, :meth:`_saturate_numpy` maps the clipped torques themselves back).

        The interval is :func:`hound_id.mor.region.torque_interval`'s: the current window the bus allows cut to the
        driver's limit (past overspeed, the braking torque the back-EMF forces), through the current-torque curve.
        With ``fused`` its elementwise steps run as one loop (:mod:`hound_id.mor.fused`), with the same result.
        """
        c = consts
        u, v, tau_m, _, _, w = self._workspace(tau)
        np.matmul(qd, c.speed_map, out=u)  # back-EMF damping * motor speed
        np.matmul(tau, c.A, out=tau_m)
        if fused:
            clip_correction(tau_m, u, qd @ c.A_inv.T if c.has_max_speed else None, c, v, volts)
            out = np.matmul(v, c.A_inv)
            out += tau
            return out
        lo, hi = np_bounds(c, u, v, w, volts)  # lo is v
        np_clip(tau_m, lo, hi, out=v)
        if c.has_max_speed:  # past the rated speed only braking torque passes
            omega = qd @ c.A_inv.T
            np.minimum(v, 0.0, out=v, where=omega > c.wmax)
            np.maximum(v, 0.0, out=v, where=omega < -c.wmax)
        np.subtract(v, tau_m, out=v)  # motor-space correction, exactly 0 where nothing clipped
        out = np.matmul(v, c.A_inv)
        out += tau
        return out

    def _saturate_numpy(self, tau: Any, qd: Any, consts: _Constants, volts: Any = None) -> Any:
        """The exact path in numpy, for commands of any size: the inputs capped, the clipped motor torques
        mapped back (tau_j = A^-T clip(tau_m)), the command kept in the joints of groups none of whose
        motors clipped. The joints are picked without branches."""
        c = consts
        u, v, tau_m, pick, untouched, w = self._workspace(tau)
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

    def _saturate_torch(self, tau: Any, qd: Any, consts: _Constants, volts: Any = None) -> Any:
        """:meth:`_saturate_numpy` in torch, for every batch on a GPU (deciding would cost a device sync)."""
        import torch

        c = consts
        u, v, tau_m, tau_in, qd_in = self._workspace(tau)
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

    def _workspace(self, like: Any) -> tuple[Any, ...]:
        """Scratch arrays shaped like ``like``, private to the calling thread: five in torch; in numpy four, a boolean
        one and a fifth float one."""
        key = ("ws", threading.get_ident(), type(like), like.dtype, getattr(like, "device", None), tuple(like.shape))
        hit = self._cache.get(key)
        if hit is None:
            if is_torch(like):
                import torch

                hit = tuple(torch.empty_like(like) for _ in range(5))
            else:
                hit = (*(np.empty_like(like) for _ in range(4)), np.empty(like.shape, dtype=bool), np.empty_like(like))
            self._remember(key, hit)
        return hit  # type: ignore[no-any-return]

    def violation(self, tau: Any, qd: Any, bus_voltage: Any = None, temperature: Any = None) -> Any:
        """How far each motor torque lies outside its interval [N m] (0 inside), shape (..., n), at the nominal bus or
        the given ``bus_voltage`` [V], and at 20 degC or the given winding ``temperature`` [degC] (as in
        :meth:`__call__`)."""
        tau, qd = self._check(tau, qd)
        consts = self._constants(tau)
        volts = self._volts(bus_voltage, tau)
        if temperature is not None:
            lo, hi = self._heated_bounds(qd, consts, volts, self._temperatures(temperature, tau))
        else:
            lo, hi = self._bounds(qd, consts, volts)
        tau_m = scaled_matmul(tau, consts.A, consts.tau_cap)
        if is_torch(tau):
            import torch

            return torch.clamp(tau_m - hi, min=0.0) + torch.clamp(lo - tau_m, min=0.0)
        return np.maximum(tau_m - hi, 0.0) + np.maximum(lo - tau_m, 0.0)


def saturation_for(robot: Robot) -> Saturation:
    """The coupled motor-space saturation of a robot."""
    return Saturation.from_robot(robot)


def dc_motor_clip(
    effort: Any, vel: Any, saturation_effort: Any, velocity_limit: Any, effort_limit: Any, vel_at_limit: Any = None
) -> Any:
    """Per-joint DC-motor clip as in Isaac Lab ``DCMotor._clip_effort`` and mjlab ``DcMotorActuator``.

    All quantities joint side: saturation_effort = stall torque [N m], velocity_limit =
    no-load speed [rad/s], effort_limit = peak torque [N m]. The velocity is first
    clamped to the speed where the torque-speed line meets -effort_limit
    (``vel_at_limit``; computed here unless given, as Isaac Lab caches it at start-up).
    Works on numpy arrays and torch tensors.
    """
    if vel_at_limit is None:
        vel_at_limit = velocity_limit * (1.0 + effort_limit / saturation_effort)
    if is_torch(effort):
        import torch

        v = torch.clamp(vel, -vel_at_limit, vel_at_limit)
        top = torch.clamp(saturation_effort * (1.0 - v / velocity_limit), max=effort_limit)
        bottom = torch.clamp(saturation_effort * (-1.0 - v / velocity_limit), min=-effort_limit)
        return torch.clamp(effort, bottom, top)
    v = np.minimum(np.maximum(vel, -vel_at_limit), vel_at_limit)
    top = np.minimum(saturation_effort * (1.0 - v / velocity_limit), effort_limit)
    bottom = np.maximum(saturation_effort * (-1.0 - v / velocity_limit), -effort_limit)
    return np.minimum(np.maximum(effort, bottom), top)


#: What :func:`per_joint_clip` is, for the reports.
PER_JOINT_REFERENCE = (
    "per-joint DC-motor clip (Isaac Lab DCMotor, mjlab DcMotorActuator) of each joint alone, with its own motor "
    "through the gear ratio 1/|A[j, j]| at the joint speed: stall torque x G, no-load speed / G, torque limit x G"
)


def per_joint_clip(sat: Saturation, tau: Any, qd: Any, own_motor: Any = None) -> Any:
    """The same commands clipped joint by joint, as a per-joint simulator model would (the reference the
    coupled clip is compared with): :func:`dc_motor_clip` of each joint j with its own motor m (the one listed
    with it: ``own_motor[j]``, by default m = j), through the gear ratio G = 1/|A[j, m]| (motor turns per joint
    turn with the group's other motors held), at the joint's own speed. For an uncoupled joint this is the
    coupled clip itself (below a rated ``max_speed``); for the hollow-shaft hip/knee it ignores that the knee
    motor also turns with the hip and carries part of the hip torque. Measured-envelope polylines and
    ``max_speed`` are not applied (a DC-motor clip has neither). numpy arrays or torch tensors (..., n).

    Returns None when a joint has no motor of its own (A[j, m] = 0), so no per-joint model exists.
    """
    own = np.arange(sat.n) if own_motor is None else np.asarray(own_motor, dtype=int)
    diagonal = np.abs(sat.A[np.arange(sat.n), own])
    if not np.all(diagonal > 0):
        return None
    gear = 1.0 / diagonal
    stall, limit = sat.stall_torque[own], sat.torque_limit[own]
    no_load = stall / sat.back_emf_damping[own]
    params: tuple[Any, ...] = (stall * gear, no_load / gear, limit * gear)
    if is_torch(tau):
        import torch

        params = tuple(torch.tensor(p, dtype=tau.dtype, device=tau.device) for p in params)
    return dc_motor_clip(tau, qd, *params)
