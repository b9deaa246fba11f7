"""Motor torque saturation: the clip the method applies every simulation step.

Joint torque commands and joint velocities (arrays shaped (..., n_joints)) go to
motor space through the transmissions (tau_m = A^T tau_j, omega_m = A^-1 qd),
each motor's torque is clipped to its feasible interval at its speed
(:func:`hound_id.mor.region.torque_interval`), and the result goes back to joint
space (tau_j = A^-T tau_m). With numpy arrays the work is numpy; with torch
tensors (any device) it is torch operations only, so it runs on the GPU and keeps
autograd intact.

Past a motor's overspeed the result is its full braking torque; past its rated
``max_speed`` only braking (or zero) torque passes. See the README.

:func:`dc_motor_clip` is the per-joint DC-motor clip of Isaac Lab's ``DCMotor`` and
mjlab's ``DcMotorActuator``, kept as the reference the coupled clip must reduce to
for an uncoupled joint, and as the benchmark's baseline.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen
from hound_id.errors import SaturationError
from hound_id.mor.region import SPEED_TOLERANCE, operating_region
from hound_id.mor.robot import Robot

#: Cached operator sets (dtype, device, batch shape) kept per Saturation.
_CACHE_SIZE = 16


def _is_torch(x: Any) -> bool:
    return type(x).__module__.startswith("torch")


def _np_clip(x: Any, lo: Any, hi: Any, out: Any) -> Any:
    np.maximum(x, lo, out=out)
    return np.minimum(out, hi, out=out)


def _ops(like: Any) -> tuple[Any, Any, Any]:
    """(matmul, subtract, clip) with ``out=`` in the array library of ``like``."""
    if _is_torch(like):
        import torch

        return torch.matmul, torch.sub, torch.clamp
    return np.matmul, np.subtract, _np_clip


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
    """Per motor min(peak torque, Kt i_max) [N m]."""
    max_speed: NDArray[np.float64]
    """Per motor rated maximum speed [rad/s]; inf where the spec gives none."""
    polylines: tuple[tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None, ...] = ()
    """Per motor (speeds, lower, upper) edges of a measured envelope (``mor --compare --out``), or None.
    Where given, the motor's torque interval at speeds inside the polyline is interpolated from it."""
    _cache: dict[Any, tuple[Any, ...]] = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def from_robot(cls, robot: Robot) -> Saturation:
        """Collect the robot's transmissions and motor regions into arrays."""
        regions = [operating_region(robot.motor_specs[m]) for m in robot.motors]
        A = robot.velocity_map()
        polylines = tuple(polyline_of(robot.motor_specs[m].envelope) for m in robot.motors)
        return cls(
            joints=robot.joints,
            A=frozen(A),
            A_inv=frozen(np.linalg.inv(A)),
            stall_torque=frozen([r.stall_torque for r in regions]),
            back_emf_damping=frozen([r.back_emf_damping for r in regions]),
            torque_limit=frozen([r.torque_limit for r in regions]),
            max_speed=frozen([np.inf if r.max_speed is None else r.max_speed for r in regions]),
            polylines=polylines if any(p is not None for p in polylines) else (),
        )

    @property
    def n(self) -> int:
        """Number of joints (= motors)."""
        return len(self.joints)

    def _constants(self, like: Any) -> tuple[Any, ...]:
        """Operators in the array library, dtype, device and batch shape of ``like`` (cached).

        Per-motor limits are stored expanded to the full batch shape: elementwise
        operations on equal shapes run several times faster than broadcasting a
        (n,) vector, in numpy and torch alike (and Isaac Lab stores its limits so).
        """
        torch_like = _is_torch(like)
        shape = tuple(like.shape)
        key: Any = ("torch", like.dtype, like.device, shape) if torch_like else ("numpy", like.dtype, shape)
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        # u = qd @ speed_map is back_emf_damping * omega_m, folded into one product.
        speed_map = self.A_inv.T * self.back_emf_damping[None, :]
        wmax = self.max_speed * (1.0 + SPEED_TOLERANCE)
        matrices = (self.A, self.A_inv, speed_map)
        vectors = (self.stall_torque, -self.stall_torque, self.torque_limit, -self.torque_limit, wmax)
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
            vecs = tuple(np.ascontiguousarray(np.broadcast_to(v.astype(like.dtype), shape)) for v in vectors)
        consts = (*mats, *vecs, bool(np.isfinite(self.max_speed).any()))
        if len(self._cache) >= _CACHE_SIZE:
            self._cache.pop(next(iter(self._cache)))
        self._cache[key] = consts
        return consts

    def motor_state(self, tau: Any, qd: Any) -> tuple[Any, Any]:
        """Motor torques [N m] and speeds [rad/s] for joint torques and velocities."""
        tau, qd = self._check(tau, qd)
        A, A_inv, *_ = self._constants(tau)
        return tau @ A, qd @ A_inv.T

    def _check(self, tau: Any, qd: Any) -> tuple[Any, Any]:
        if _is_torch(tau) != _is_torch(qd):
            raise SaturationError("tau and qd must both be numpy arrays or both torch tensors")
        if not _is_torch(tau):
            tau = np.asarray(tau)
            qd = np.asarray(qd)
            if not np.issubdtype(tau.dtype, np.floating):
                tau = tau.astype(np.float64)
            qd = qd.astype(tau.dtype, copy=False)
        elif qd.dtype != tau.dtype:
            qd = qd.to(tau.dtype)
        if tau.shape[-1:] != (self.n,) or qd.shape[-1:] != (self.n,) or tuple(tau.shape) != tuple(qd.shape):
            raise SaturationError(
                f"saturation: tau has shape {tuple(tau.shape)} and qd {tuple(qd.shape)}; "
                f"expected both (..., {self.n}), the same shape, with joints in the order {', '.join(self.joints)}"
            )
        return tau, qd

    def torque_bounds(self, qd: Any) -> tuple[Any, Any]:
        """Per-motor feasible torque interval [lo, hi] at the motor speeds implied by ``qd``."""
        _, qd = self._check(qd, qd)
        return self._bounds(qd, self._constants(qd))

    def _bounds(self, qd: Any, consts: tuple[Any, ...]) -> tuple[Any, Any]:
        lo, hi = self._line_bounds(qd, consts)
        if self.polylines:
            omega = qd @ consts[1].T
            lo, hi = _polyline_bounds(self._polylines_like(qd), omega, lo, hi)
        return lo, hi

    def _polylines_like(self, like: Any) -> tuple[Any, ...]:
        """The polylines' finite points in the array library, dtype and device of ``like`` (cached: the clip
        runs every simulation step)."""
        key: Any = ("polylines", type(like), like.dtype, getattr(like, "device", None))
        hit = self._cache.get(key)
        if hit is None:
            convert: Any = np.asarray
            if _is_torch(like):
                import torch

                def convert(a: Any) -> Any:
                    return torch.tensor(np.array(a), dtype=like.dtype, device=like.device)

            lines: list[Any] = []
            for line in self.polylines:
                if line is None:
                    lines.append(None)
                    continue
                speeds, lower, upper = line
                ok = np.isfinite(lower) & np.isfinite(upper)
                lines.append((float(speeds[0]), float(speeds[-1]), *(convert(a[ok]) for a in (speeds, lower, upper))))
            hit = tuple(lines)
            if len(self._cache) >= _CACHE_SIZE:
                self._cache.pop(next(iter(self._cache)))
            self._cache[key] = hit
        return hit

    def _line_bounds(self, qd: Any, consts: tuple[Any, ...]) -> tuple[Any, Any]:
        _, A_inv, speed_map, stall, neg_stall, tl, neg_tl, wmax, has_max_speed = consts
        u = qd @ speed_map  # back-EMF damping * motor speed
        if _is_torch(qd):
            import torch

            hi = torch.clamp(stall - u, neg_tl, tl)
            lo = torch.clamp(neg_stall - u, neg_tl, tl)
            if has_max_speed:
                omega = qd @ A_inv.T
                hi = torch.where(omega > wmax, torch.clamp(hi, max=0.0), hi)
                lo = torch.where(omega < -wmax, torch.clamp(lo, min=0.0), lo)
            return lo, hi
        hi = np.subtract(stall, u)
        np.maximum(hi, neg_tl, out=hi)
        np.minimum(hi, tl, out=hi)
        lo = np.subtract(neg_stall, u, out=u)
        np.maximum(lo, neg_tl, out=lo)
        np.minimum(lo, tl, out=lo)
        if has_max_speed:
            omega = qd @ A_inv.T
            hi = np.where(omega > wmax, np.minimum(hi, 0.0), hi)
            lo = np.where(omega < -wmax, np.maximum(lo, 0.0), lo)
        return lo, hi

    def __call__(self, tau: Any, qd: Any) -> Any:
        """Saturate joint torque commands [N m] at joint velocities [rad/s], shapes (..., n).

        Returns joint torques (same type, dtype and device as ``tau``) whose motor
        torques lie in each motor's operating region at its current speed.
        Commands already inside pass bit-for-bit unchanged.
        """
        tau, qd = self._check(tau, qd)
        consts = self._constants(tau)
        A, A_inv = consts[0], consts[1]
        if self.polylines:  # measured envelopes: the general path (interpolated bounds)
            lo, hi = self._bounds(qd, consts)
            tau_m = tau @ A
            if _is_torch(tau):
                import torch

                return tau + (torch.clamp(tau_m, lo, hi) - tau_m) @ A_inv
            return tau + (np.clip(tau_m, lo, hi) - tau_m) @ A_inv
        if _is_torch(tau) and (tau.requires_grad or qd.requires_grad):
            import torch

            lo, hi = self._bounds(qd, consts)
            tau_m = tau @ A
            return tau + (torch.clamp(tau_m, lo, hi) - tau_m) @ A_inv
        return self._saturate_in_place(tau, qd, consts)

    def _saturate_in_place(self, tau: Any, qd: Any, consts: tuple[Any, ...]) -> Any:
        """The same clip with intermediates in reused per-thread buffers.

        Large temporaries cost more in allocation (page faults) than in arithmetic on
        the CPU, so only the returned array is new. Not used under autograd.

        Clipping to the voltage band and then to the torque box equals clipping to
        their intersection whenever it is non-empty (interval projections compose),
        and gives the full braking torque past overspeed, as :func:`torque_interval`.
        """
        A, A_inv, speed_map, stall, neg_stall, tl, neg_tl, wmax, has_max_speed = consts
        matmul, subtract, clip = _ops(tau)
        u, v, tau_m = self._workspace(tau)
        matmul(qd, speed_map, out=u)  # back-EMF damping * motor speed
        matmul(tau, A, out=tau_m)
        subtract(neg_stall, u, out=v)  # lower voltage line
        subtract(stall, u, out=u)  # upper voltage line
        clip(tau_m, v, u, out=v)
        clip(v, neg_tl, tl, out=v)
        if has_max_speed:  # past the rated speed only braking torque passes
            omega = qd @ A_inv.T
            if _is_torch(tau):
                import torch

                torch.where(omega > wmax, torch.clamp(v, max=0.0), v, out=v)
                torch.where(omega < -wmax, torch.clamp(v, min=0.0), v, out=v)
            else:
                np.minimum(v, 0.0, out=v, where=omega > wmax)
                np.maximum(v, 0.0, out=v, where=omega < -wmax)
        subtract(v, tau_m, out=v)  # motor-space correction, exactly 0 where nothing clipped
        out = matmul(v, A_inv)
        out += tau
        return out

    def _workspace(self, like: Any) -> tuple[Any, Any, Any]:
        """Three scratch arrays shaped like ``like``, private to the calling thread."""
        key = ("ws", threading.get_ident(), type(like), like.dtype, getattr(like, "device", None), tuple(like.shape))
        hit = self._cache.get(key)
        if hit is None:
            if _is_torch(like):
                import torch

                hit = tuple(torch.empty_like(like) for _ in range(3))
            else:
                hit = tuple(np.empty_like(like) for _ in range(3))
            if len(self._cache) >= _CACHE_SIZE:
                self._cache.pop(next(iter(self._cache)))
            self._cache[key] = hit
        return hit

    def violation(self, tau: Any, qd: Any) -> Any:
        """How far each motor torque lies outside its interval [N m] (0 inside), shape (..., n)."""
        tau, qd = self._check(tau, qd)
        consts = self._constants(tau)
        lo, hi = self._bounds(qd, consts)
        tau_m = tau @ consts[0]
        if _is_torch(tau):
            import torch

            return torch.clamp(tau_m - hi, min=0.0) + torch.clamp(lo - tau_m, min=0.0)
        return np.maximum(tau_m - hi, 0.0) + np.maximum(lo - tau_m, 0.0)


def polyline_of(envelope: Any) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None:
    """(speeds, lower, upper) arrays of a motor spec's ``envelope`` block, or None."""
    if not envelope:
        return None
    return (
        frozen(envelope["speeds"]),
        frozen([np.nan if v is None else v for v in envelope["lower"]]),
        frozen([np.nan if v is None else v for v in envelope["upper"]]),
    )


def _interp(x: Any, xp: Any, fp: Any) -> Any:
    """Piecewise-linear interpolation of (xp, fp) at x, numpy or torch (x outside xp: the end values);
    xp and fp are already in x's array type."""
    if not _is_torch(x):
        return np.interp(x, xp, fp)
    import torch

    k = torch.clamp(torch.searchsorted(xp, x.contiguous()), 1, xp.numel() - 1)
    x0, x1, f0, f1 = xp[k - 1], xp[k], fp[k - 1], fp[k]
    t = torch.clamp((x - x0) / (x1 - x0), 0.0, 1.0)
    return f0 + t * (f1 - f0)


def _polyline_bounds(lines: Any, omega: Any, lo: Any, hi: Any) -> tuple[Any, Any]:
    """Replace the straight-line bounds of motors with a polyline, at speeds inside its range.

    ``lines`` per motor: None, or (first speed, last speed, speeds, lower, upper) with the finite
    points only, in omega's array type (see :meth:`Saturation._polylines_like`).
    """
    where: Any
    if _is_torch(omega):
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
        lo[..., m] = where(inside, _interp(w, speeds, lower), lo[..., m])
        hi[..., m] = where(inside, _interp(w, speeds, upper), hi[..., m])
    return lo, hi


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
    if _is_torch(effort):
        import torch

        v = torch.clamp(vel, -vel_at_limit, vel_at_limit)
        top = torch.clamp(saturation_effort * (1.0 - v / velocity_limit), max=effort_limit)
        bottom = torch.clamp(saturation_effort * (-1.0 - v / velocity_limit), min=-effort_limit)
        return torch.clamp(effort, bottom, top)
    v = np.minimum(np.maximum(vel, -vel_at_limit), vel_at_limit)
    top = np.minimum(saturation_effort * (1.0 - v / velocity_limit), effort_limit)
    bottom = np.maximum(saturation_effort * (-1.0 - v / velocity_limit), -effort_limit)
    return np.minimum(np.maximum(effort, bottom), top)


@dataclass(frozen=True)
class BoxStudy:
    """What a rectangular joint limit lets through that the motors cannot make."""

    samples: int
    """Number of random (tau, qd) commands drawn per box."""
    outer_infeasible: float
    """Fraction of commands inside the outer (URDF-style) box that the MOR clips."""
    outer_mean_clip: float
    """Mean |tau_cmd - tau_sat| over joints and those commands [N m]."""
    inner_infeasible: float
    """Fraction of commands inside the inner box that the MOR clips (0 by construction)."""
    max_violation_after: float
    """Largest motor-torque violation left after saturation [N m] (0 up to round-off)."""

    def to_dict(self) -> dict[str, float | int]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def box_study(
    sat: Saturation, inner: NDArray[np.float64], outer: NDArray[np.float64], samples: int = 100_000, seed: int = 0
) -> BoxStudy:
    """Draw commands uniformly in the inner and outer boxes and saturate them.

    Args:
        sat: The robot's saturation.
        inner: Inner box per joint, shape (n, 2): (effort [N m], velocity [rad/s]).
        outer: Outer box per joint, same shape.
        samples: Number of commands per box.
        seed: Random seed.
    """
    rng = np.random.default_rng(seed)
    results = []
    for box in (outer, inner):
        u = rng.uniform(-1.0, 1.0, size=(2, samples, sat.n))
        tau, qd = u[0] * box[:, 0], u[1] * box[:, 1]
        clipped = sat(tau, qd)
        changed = np.any(np.abs(clipped - tau) > 1e-9 * np.maximum(1.0, np.abs(tau)), axis=-1)
        results.append(
            (float(changed.mean()), float(np.abs(clipped - tau).mean()), float(sat.violation(clipped, qd).max()))
        )
    return BoxStudy(
        samples=samples,
        outer_infeasible=results[0][0],
        outer_mean_clip=results[0][1],
        inner_infeasible=results[1][0],
        max_violation_after=max(results[0][2], results[1][2]),
    )


@dataclass(frozen=True)
class LogSaturation:
    """A log of joint torque commands saturated by the MOR, with what was clipped."""

    joints: tuple[str, ...]
    """Joint order of the arrays."""
    motors: tuple[str, ...]
    """Motor order of the motor-space arrays."""
    tau_cmd: NDArray[np.float64]
    """Commanded joint torques [N m], shape (rows, n)."""
    qd: NDArray[np.float64]
    """Joint velocities [rad/s], shape (rows, n)."""
    tau_sat: NDArray[np.float64]
    """Saturated joint torques [N m], shape (rows, n)."""
    motor_torque_cmd: NDArray[np.float64]
    """Commanded motor torques [N m], shape (rows, n)."""
    motor_torque_sat: NDArray[np.float64]
    """Saturated motor torques [N m], shape (rows, n)."""
    motor_speed: NDArray[np.float64]
    """Motor speeds [rad/s], shape (rows, n)."""

    @property
    def motor_clipped(self) -> NDArray[np.bool_]:
        """Whether each motor torque command was outside the region, shape (rows, n)."""
        tol = 1e-9 * np.maximum(1.0, np.abs(self.motor_torque_cmd))
        return np.abs(self.motor_torque_sat - self.motor_torque_cmd) > tol

    def to_dict(self) -> dict[str, Any]:
        """Summary, schema ``hound-id/saturate/1``."""
        clipped = self.motor_clipped
        clip = np.abs(self.tau_sat - self.tau_cmd)
        return {
            "schema": "hound-id/saturate/1",
            "rows": int(self.tau_cmd.shape[0]),
            "violating_fraction": float(np.any(clipped, axis=1).mean()),
            "joints": [
                {"joint": j, "max_clip": float(clip[:, i].max()), "mean_clip": float(clip[:, i].mean())}
                for i, j in enumerate(self.joints)
            ],
            "motors": [
                {"motor": m, "clipped_fraction": float(clipped[:, i].mean())} for i, m in enumerate(self.motors)
            ],
            "units": {"clip": "N m (joint side)"},
        }


def saturate_log(robot: Robot, columns: Any, source: str = "commands") -> LogSaturation:
    """Saturate a log with columns ``tau_<joint>`` [N m] and ``qd_<joint>`` [rad/s] for every joint.

    Args:
        robot: The robot whose motors and transmissions apply.
        columns: A mapping (or DataFrame) of column name -> 1-D numeric array.
        source: File name, for messages.

    Raises:
        TableError: A column is missing or holds a non-finite value.
    """
    import pandas as pd

    from hound_id.errors import TableError

    arrays = {}
    for prefix in ("tau", "qd"):
        stacked = []
        for joint in robot.joints:
            name = f"{prefix}_{joint}"
            if name not in columns:
                raise TableError(
                    f"{source}: column '{name}' missing; expected tau_<joint> [N m] and qd_<joint> [rad/s] "
                    f"for every joint ({', '.join(robot.joints)})",
                    column=name,
                )
            raw = pd.Series(np.asarray(columns[name]))
            numeric = pd.to_numeric(raw, errors="coerce")
            text = np.flatnonzero(numeric.isna().to_numpy() & raw.notna().to_numpy())
            if text.size:
                raise TableError(
                    f"{source}: column '{name}' data row {int(text[0]) + 1} holds {raw.iloc[text[0]]!r}; "
                    "expected a number",
                    column=name,
                    row=int(text[0]) + 1,
                )
            values = numeric.to_numpy(dtype=float)
            bad = np.flatnonzero(~np.isfinite(values))
            if bad.size:
                raise TableError(
                    f"{source}: column '{name}' data row {int(bad[0]) + 1} holds {values[bad[0]]}; "
                    "expected a finite number (drop or fill such rows first)",
                    column=name,
                    row=int(bad[0]) + 1,
                )
            stacked.append(values)
        arrays[prefix] = np.column_stack(stacked)
    sat = saturation_for(robot)
    tau, qd = arrays["tau"], arrays["qd"]
    tau_sat = sat(tau, qd)
    tau_m, omega = sat.motor_state(tau, qd)
    tau_m_sat, _ = sat.motor_state(tau_sat, qd)
    return LogSaturation(
        joints=robot.joints,
        motors=robot.motors,
        tau_cmd=frozen(tau),
        qd=frozen(qd),
        tau_sat=frozen(tau_sat),
        motor_torque_cmd=frozen(tau_m),
        motor_torque_sat=frozen(tau_m_sat),
        motor_speed=frozen(omega),
    )
