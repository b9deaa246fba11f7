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

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.errors import SaturationError
from hound_id.mor.region import SPEED_TOLERANCE, operating_region
from hound_id.mor.robot import Robot


def _frozen(a: Any) -> NDArray[np.float64]:
    out = np.array(a, dtype=np.float64)
    out.setflags(write=False)
    return out


def _is_torch(x: Any) -> bool:
    return type(x).__module__.startswith("torch")


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
    _cache: dict[Any, tuple[Any, ...]] = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def from_robot(cls, robot: Robot) -> Saturation:
        """Collect the robot's transmissions and motor regions into arrays."""
        regions = [operating_region(robot.motor_specs[m]) for m in robot.motors]
        A = robot.velocity_map()
        return cls(
            joints=robot.joints,
            A=_frozen(A),
            A_inv=_frozen(np.linalg.inv(A)),
            stall_torque=_frozen([r.stall_torque for r in regions]),
            back_emf_damping=_frozen([r.back_emf_damping for r in regions]),
            torque_limit=_frozen([r.torque_limit for r in regions]),
            max_speed=_frozen([np.inf if r.max_speed is None else r.max_speed for r in regions]),
        )

    @property
    def n(self) -> int:
        """Number of joints (= motors)."""
        return len(self.joints)

    def _constants(self, like: Any) -> tuple[Any, ...]:
        """Operators in the array library, dtype and device of ``like`` (cached)."""
        if _is_torch(like):
            key: Any = ("torch", like.dtype, like.device)
        else:
            key = ("numpy", like.dtype)
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        # u = qd @ speed_map is back_emf_damping * omega_m, folded into one product.
        speed_map = self.A_inv.T * self.back_emf_damping[None, :]
        arrays = (self.A, self.A_inv, speed_map, self.stall_torque, self.torque_limit,
                  self.max_speed * (1.0 + SPEED_TOLERANCE))
        if key[0] == "torch":
            import torch

            tensors = tuple(torch.tensor(np.array(a), dtype=like.dtype, device=like.device) for a in arrays)
        else:
            tensors = tuple(np.ascontiguousarray(a, dtype=like.dtype) for a in arrays)
        consts = (*tensors, bool(np.isfinite(self.max_speed).any()))
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
        if tau.shape[-1:] != (self.n,) or qd.shape[-1:] != (self.n,):
            raise SaturationError(
                f"saturation: tau has shape {tuple(tau.shape)} and qd {tuple(qd.shape)}; "
                f"expected (..., {self.n}) with joints in the order {', '.join(self.joints)}"
            )
        return tau, qd

    def torque_bounds(self, qd: Any) -> tuple[Any, Any]:
        """Per-motor feasible torque interval [lo, hi] at the motor speeds implied by ``qd``."""
        _, qd = self._check(qd, qd)
        return self._bounds(qd, self._constants(qd))

    def _bounds(self, qd: Any, consts: tuple[Any, ...]) -> tuple[Any, Any]:
        _, A_inv, speed_map, stall, tl, wmax, has_max_speed = consts
        u = qd @ speed_map  # back-EMF damping * motor speed
        if _is_torch(qd):
            import torch

            hi = torch.clamp(stall - u, -tl, tl)
            lo = torch.clamp(u.neg_().sub_(stall), -tl, tl)
            if has_max_speed:
                omega = qd @ A_inv.T
                hi = torch.where(omega > wmax, torch.clamp(hi, max=0.0), hi)
                lo = torch.where(omega < -wmax, torch.clamp(lo, min=0.0), lo)
            return lo, hi
        hi = stall - u
        np.maximum(hi, -tl, out=hi)
        np.minimum(hi, tl, out=hi)
        lo = np.subtract(-stall, u, out=u)
        np.maximum(lo, -tl, out=lo)
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
        """
        tau, qd = self._check(tau, qd)
        consts = self._constants(tau)
        A, A_inv = consts[0], consts[1]
        lo, hi = self._bounds(qd, consts)
        tau_m = tau @ A
        if _is_torch(tau):
            import torch

            return torch.clamp(tau_m, lo, hi) @ A_inv
        np.maximum(tau_m, lo, out=tau_m)
        np.minimum(tau_m, hi, out=tau_m)
        return tau_m @ A_inv

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


def saturation_for(robot: Robot) -> Saturation:
    """The coupled motor-space saturation of a robot."""
    return Saturation.from_robot(robot)


def dc_motor_clip(effort: Any, vel: Any, saturation_effort: Any, velocity_limit: Any, effort_limit: Any) -> Any:
    """Per-joint DC-motor clip as in Isaac Lab ``DCMotor._clip_effort`` and mjlab ``DcMotorActuator``.

    All quantities joint side: saturation_effort = stall torque [N m], velocity_limit =
    no-load speed [rad/s], effort_limit = peak torque [N m]. The velocity is first
    clamped to the speed where the torque-speed line meets -effort_limit.
    Works on numpy arrays and torch tensors.
    """
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


def box_study(sat: Saturation, inner: NDArray[np.float64], outer: NDArray[np.float64],
              samples: int = 100_000, seed: int = 0) -> BoxStudy:
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
        results.append((float(changed.mean()), float(np.abs(clipped - tau).mean()),
                        float(sat.violation(clipped, qd).max())))
    return BoxStudy(
        samples=samples,
        outer_infeasible=results[0][0],
        outer_mean_clip=results[0][1],
        inner_infeasible=results[1][0],
        max_violation_after=max(results[0][2], results[1][2]),
    )
