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

The elementwise bounds it takes are in :mod:`hound_id.mor.clip_bounds`; the operators of one call (the maps and
limits in the input's array type, its checked inputs) in :mod:`hound_id.mor.clip_operators`; the general paths (fresh
arrays, the exact clip of commands of any size) in :mod:`hound_id.mor.clip_paths`; ``hound-id saturate`` on a log is
:mod:`hound_id.mor.saturate_log`.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen
from hound_id.errors import SaturationError
from hound_id.mor.clip_bounds import (
    capped,
    drive_arrays,
    fusable,
    is_torch,
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
    within_interval,
)
from hound_id.mor.clip_operators import (
    CACHE_SIZE,
    HEADROOM,
    ORDINARY,
    Constants,
    build_constants,
    check_inputs,
    coupled_groups,
    per_element,
    polylines_like,
    rows_like,
)
from hound_id.mor.clip_paths import clip_exact_numpy, clip_exact_torch, clip_fresh, heated_bounds, line_bounds
from hound_id.mor.fused import clip_correction
from hound_id.mor.fused import within as fused_within
from hound_id.mor.region import OperatingRegion, operating_region

if TYPE_CHECKING:  # the runtime imports this module: no robot files (yaml, pint) at run time
    from hound_id.mor.robot import Robot

__all__ = [
    "HEADROOM",
    "ORDINARY",
    "PER_JOINT_REFERENCE",
    "Saturation",
    "coupled_groups",
    "dc_motor_clip",
    "per_joint_clip",
    "saturation_for",
]


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

    def _constants(self, like: Any) -> Constants:
        """Operators in the array library, dtype, device and batch shape of ``like`` (cached:
        :func:`hound_id.mor.clip_operators.build_constants`)."""
        torch_like = is_torch(like)
        shape = tuple(like.shape)
        key: Any = ("torch", like.dtype, like.device, shape) if torch_like else ("numpy", like.dtype, shape)
        hit = self._cache.get(key)
        if hit is not None:
            return hit  # type: ignore[no-any-return]
        consts = build_constants(self, like)
        self._remember(key, consts)
        return consts

    def _remember(self, key: Any, value: Any) -> None:
        if len(self._cache) >= CACHE_SIZE:
            self._cache.pop(next(iter(self._cache)))
        self._cache[key] = value

    def motor_state(self, tau: Any, qd: Any) -> tuple[Any, Any]:
        """Motor torques [N m] and speeds [rad/s] for joint torques and velocities.

        Exact to rounding for every finite input: where a product could overflow, the inputs are
        scaled by a power of two first, so a motor torque beyond the dtype's range is ±inf, not NaN.
        """
        tau, qd = check_inputs(tau, qd, self.joints)
        consts = self._constants(tau)
        return scaled_matmul(tau, consts.A, consts.tau_cap), scaled_matmul(qd, consts.A_inv.T, consts.qd_cap)

    def torque_bounds(self, qd: Any, bus_voltage: Any = None, temperature: Any = None) -> tuple[Any, Any]:
        """Per-motor feasible torque interval [lo, hi] at the motor speeds implied by ``qd`` (and, if given, the bus
        voltage [V] and winding temperature [degC] of each element, broadcast against ``qd``: see
        :meth:`__call__`)."""
        _, qd = check_inputs(qd, qd, self.joints)
        consts = self._constants(qd)
        volts = self._volts(bus_voltage, qd)
        if temperature is not None:
            return heated_bounds(qd, consts, volts, self._temperatures(temperature, qd), self._thermal_like(qd))
        return self._bounds(qd, consts, volts)

    def _volts(self, bus_voltage: Any, like: Any) -> Any:
        """The bus voltage [V] per element of ``like``'s shape, in its array type, dtype and device, C-contiguous (the
        bounds take max(V, 0); :func:`hound_id.mor.clip_operators.per_element`); None stays None."""
        if bus_voltage is None:
            return None
        if self.bus_voltage is None:
            raise SaturationError("saturation: this clip has no nominal bus voltage, so it cannot take another one")
        return per_element(bus_voltage, like, "bus_voltage", "V")

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
        return per_element(temperature, like, "temperature", "degC")

    def _thermal_like(self, like: Any) -> tuple[Any, ...]:
        """The thermal rows and the nominal bus voltage, per motor, in the array type, dtype and device of ``like``."""
        key: Any = ("thermal", type(like), like.dtype, getattr(like, "device", None))
        hit = self._cache.get(key)
        if hit is None:
            assert self.thermal is not None and self.bus_voltage is not None
            hit = rows_like([*self.thermal, self.bus_voltage], like)
            self._remember(key, hit)
        return hit  # type: ignore[no-any-return]

    def _bounds(self, qd: Any, consts: Constants, volts: Any = None) -> tuple[Any, Any]:
        qd = capped(qd, consts.qd_cap)
        lo, hi = line_bounds(qd, consts, volts)
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
            hit = polylines_like(self.polylines, self.held, like)
            self._remember(key, hit)
        return hit  # type: ignore[no-any-return]

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
          capped (:func:`hound_id.mor.clip_operators.caps`) so that no product overflows.

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
        tau, qd = check_inputs(tau, qd, self.joints)
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

    def _saturate(self, tau: Any, qd: Any, consts: Constants, volts: Any = None, temperature: Any = None) -> Any:
        """The clip with fresh arrays (autograd flows through it: :func:`hound_id.mor.clip_paths.clip_fresh`)."""
        if temperature is not None:
            lo, hi = heated_bounds(qd, consts, volts, temperature, self._thermal_like(qd))
        else:
            lo, hi = self._bounds(qd, consts, volts)
        return clip_fresh(tau, consts, lo, hi)

    def _saturate_in_place(self, tau: Any, qd: Any, consts: Constants, volts: Any = None) -> Any:
        """The clip with intermediates in reused per-thread buffers (not under autograd).

        Large temporaries cost more in allocation (page faults) than in arithmetic on
        the CPU, so only the returned array is new.

        Ordinary commands (motor torques within :data:`ORDINARY` stall torques, speeds below
        the cap: checked on the CPU, where a check costs no device sync) take the short path of
        :meth:`_saturate_ordinary`; the others, and every batch on a GPU, the exact one
        (:func:`hound_id.mor.clip_paths.clip_exact_numpy`, :func:`hound_id.mor.clip_paths.clip_exact_torch`). CPU
        tensors go through numpy views (:func:`numpy_views`).
        """
        c = consts
        if is_torch(tau):
            views = numpy_views(tau, qd)
            if views is None:
                return clip_exact_torch(tau, qd, consts, volts, self._workspace(tau))
            import torch

            v = None if volts is None else volts.numpy()
            return torch.from_numpy(self._saturate_in_place(*views, self._constants(views[0]), v))
        fused = fusable(tau, qd)
        ordinary = fused_within(tau, c.ordinary, qd, c.qd_cap) if fused else within_interval(tau, c.ordinary)
        if not (ordinary and (fused or within_interval(qd, c.qd_cap))):
            return clip_exact_numpy(tau, qd, consts, volts, self._workspace(tau))
        return self._saturate_ordinary(tau, qd, consts, fused, volts)

    def _saturate_ordinary(self, tau: Any, qd: Any, consts: Constants, fused: bool = False, volts: Any = None) -> Any:
        """Clip, then add the clip's correction mapped back: tau + A^-T (clip(tau_m) - tau_m).

        The correction is exactly 0 in the joints of groups whose motors all passed, so those pass bit
        for bit. Its rounding is eps times the command's size, which :data:`ORDINARY` keeps within a few
        stall torques (beyond, :func:`hound_id.mor.clip_paths.clip_exact_numpy` maps the clipped torques themselves
        back).

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
        tau, qd = check_inputs(tau, qd, self.joints)
        consts = self._constants(tau)
        volts = self._volts(bus_voltage, tau)
        if temperature is not None:
            temps = self._temperatures(temperature, tau)
            lo, hi = heated_bounds(qd, consts, volts, temps, self._thermal_like(qd))
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
