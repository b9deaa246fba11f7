"""What a trainer imports: the motor-space saturation, fitted friction and current compensation
of a hound-id bundle, for numpy arrays or torch tensors on any device.

    import hound_id.runtime
    sat = hound_id.runtime.load("bundle.yaml", joint_names=sim_joint_order)  # from hound-id export
    tau = sat.saturate(tau_cmd, qd)                    # (..., n_joints) joint torques [N m]
    tau_sim = tau + sat.friction_torque(qd, tau)       # in simulation, optionally: the fitted friction
    i_cmd = sat.current(sat.motor_torque(tau))         # on the robot: motor currents [A] for tau

Arrays are shaped (..., n_joints) in the bundle's joint order, or in the order of
``joint_names``; torch stays torch (same dtype and device, autograd intact). Only numpy (and
torch, when given tensors) are imported, besides the standard library: of hound-id, only
:mod:`hound_id.errors`, :mod:`hound_id.arrays` and the clip, :class:`hound_id.mor.saturation.Saturation` (with its
elementwise bounds, :mod:`hound_id.mor.clip_bounds`)
(with :mod:`hound_id.mor.region` for its speed tolerance), the same code ``hound-id saturate`` runs,
:mod:`hound_id.mor.drive`, the drive's dq window the clip takes for a motor with a winding reactance or
field weakening, :mod:`hound_id.mor.current_curve`, the current-torque curves whose exact inverse
:meth:`Runtime.current` gives,
:mod:`hound_id.mor.clip_turn`, the statistics of how far the clip turns coupled joint torques
(:meth:`Runtime.clip_turn`), :mod:`hound_id.mor.friction`, the fitted friction terms,
and :mod:`hound_id.mor.thermal`, the winding temperature's step
(:meth:`Runtime.step_temperature` and a clip at a temperature, imported when first called). With numba
installed (``hound-id[fast]``) the first clip of an ordinary batch imports it for the fused loop of
:mod:`hound_id.mor.fused` (same results; ``HOUND_ID_FUSED=0`` turns it off).
A JSON bundle is read with the standard library; a YAML one with PyYAML (:func:`hound_id.io.read_yaml`),
imported only then. ``tests/test_runtime.py`` and ``tests/test_architecture.py`` check this.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen
from hound_id.errors import SaturationError, SpecError
from hound_id.mor.clip_bounds import interp, polyline_of
from hound_id.mor.clip_turn import ANGLE_FLOOR, ClipTurn, clip_turn
from hound_id.mor.current_curve import CurrentCurve, polynomial
from hound_id.mor.friction import EPS_SPEED, TERMS, parameters
from hound_id.mor.saturation import PER_JOINT_REFERENCE, Saturation, coupled_groups, per_joint_clip

#: Bundle schemas :func:`read_bundle` (and so :func:`load` and :func:`hound_id.export.bundle.load_bundle`)
#: reads, oldest first.
READABLE = tuple(f"hound-id/bundle/{n}" for n in range(1, 6))


def _is_torch(x: Any) -> bool:
    return type(x).__module__.startswith("torch")


@dataclass(frozen=True)
class Runtime:
    """The trainer-side view of a bundle (see the module docstring). Build it with :func:`load`."""

    joints: tuple[str, ...]
    """Joint order of the last axis of every array."""
    motors: tuple[str, ...]
    """Motor order: motor i is the one listed with joint i."""
    clip: Saturation
    """The coupled motor-space clip."""
    friction: Mapping[str, NDArray[np.float64]]
    """Per friction parameter (:func:`hound_id.mor.friction.parameters`: coulomb [N m], viscous [N m s/rad], stribeck
    [N m], stribeck_speed [rad/s], gear_friction [N m/A]), its value per motor (a parameter's value without a fit
    where not fitted: 0, and 1 rad/s for stribeck_speed)."""
    kt: NDArray[np.float64]
    """Per motor torque constant [N m/A] (the fitted one where a fit was given)."""
    compensation: tuple[tuple[tuple[int, ...], tuple[float, ...]] | None, ...]
    """Per motor (powers, coefficients) of the fit's odd compensation polynomial, current [A] = sum c_k tau^k, or
    None; an approximation of the curve's inverse kept for drivers that take a polynomial."""
    resistance: NDArray[np.float64] | None = None
    """Per motor model resistance R [ohm] (for :meth:`voltage`)."""
    kv: NDArray[np.float64] | None = None
    """Per motor speed constant [rad/s/V]."""
    bus_voltage: NDArray[np.float64] | None = None
    """Per motor bus voltage [V]."""
    curves: tuple[CurrentCurve | None, ...] = ()
    """Per motor current-torque curve (bundle/2; empty for a bundle/1), whose exact inverse :meth:`current` uses."""
    bus_voltage_range: NDArray[np.float64] | None = None
    """Per motor (lowest, highest) bus voltage of its battery [V], shape (n, 2), from a bundle/3 whose specs state it
    (None otherwise): draw each environment's ``bus_voltage`` within it."""
    heat: NDArray[np.float64] | None = None
    """Per motor rows (R_th [K/W], time constant [s], ambient [degC], c R20 [W/A^2], a_R [1/K], a_K [1/K]), shape
    (6, n), from a bundle/4 whose specs state a thermal model (None otherwise; a motor without one relaxes to 20 degC
    and is never derated), for :meth:`step_temperature`."""
    own_motor: tuple[int, ...] = ()
    """Per joint, the index of the motor listed with it in the bundle (empty: motor i with joint i); differs when
    ``joint_names`` reorders the joints. Used by :meth:`clip_turn`'s per-joint comparison."""
    _consts: dict[Any, tuple[Any, ...]] = field(default_factory=dict, compare=False, repr=False)

    @property
    def n(self) -> int:
        return len(self.joints)

    def _array(self, x: Any, what: str) -> Any:
        """``x`` as a float array (torch stays torch) shaped (..., n), or SaturationError."""
        if not _is_torch(x):
            x = np.asarray(x)
            if not np.issubdtype(x.dtype, np.floating):
                x = x.astype(np.float64)
        if tuple(x.shape[-1:]) != (self.n,):
            raise SaturationError(
                f"runtime: {what} has shape {tuple(x.shape)}; expected (..., {self.n}) in the bundle's order "
                f"({', '.join(self.joints if what != 'tau_motor' else self.motors)})"
            )
        return x

    def _constants(self, like: Any) -> tuple[Any, ...]:
        """(A^-1, A, then each friction parameter's array in :func:`hound_id.mor.friction.parameters` order) in the
        array type, dtype and device of ``like``, cached."""
        values = (self.clip.A_inv, self.clip.A, *(self.friction[name] for name, _, _ in parameters()))
        return self._like("constants", values, like)

    @cached_property
    def load_friction(self) -> tuple[str, ...]:
        """Motors whose friction grows with their load (a fitted ``gear_friction``): :meth:`friction_torque` needs
        the joint torques for them. Found once (the friction arrays are read-only), not on every step."""
        loaded = [t for t in TERMS.values() if t.needs_load]
        return tuple(
            m
            for i, m in enumerate(self.motors)
            if any(self.friction[p][i] != 0 for t in loaded for p, _, _ in t.parameters)
        )

    def _like(self, name: str, values: Sequence[Any], like: Any) -> tuple[Any, ...]:
        """``values`` (arrays) in the array type, dtype and device of ``like`` (float64 for a non-float numpy
        array), cached under ``name``."""
        key = (name, type(like), str(getattr(like, "dtype", "")), str(getattr(like, "device", "")))
        if key not in self._consts:
            if _is_torch(like):
                import torch

                kw = {"dtype": like.dtype, "device": like.device}
                self._consts[key] = tuple(torch.tensor(np.array(v), **kw) for v in values)
            else:
                dtype = like.dtype if isinstance(like, np.ndarray) and like.dtype.kind == "f" else np.float64
                self._consts[key] = tuple(np.asarray(v, dtype=dtype) for v in values)
        return self._consts[key]

    def saturate(self, tau_cmd: Any, qd: Any, bus_voltage: Any = None, temperature: Any = None) -> Any:
        """Joint torques [N m] after each motor's operating region, for (..., n_joints) commands and speeds.

        Feasible for every finite command, float32 or float64, numpy or torch (however large: the clipped
        motor torques are mapped back); commands inside the region come back unchanged; a NaN command or
        speed comes back NaN, nothing is raised (see :meth:`hound_id.mor.saturation.Saturation.__call__`).

        ``bus_voltage`` [V]: the battery's voltage per environment, (..., 1), or per motor, (..., n), to randomise
        its charge (e.g. drawn at each reset from the bundle's ``bus_voltage_range``); the region follows it (a
        bundle/3 or later). Keep it as a full (..., n) array of the commands' dtype for the cheapest clip.

        ``temperature`` [degC]: each winding's temperature, shaped like ``bus_voltage`` (a bundle/4 whose specs state
        a thermal model): R, Kt and the back-EMF constant follow it and the drive's current limit is derated (the
        fused loop for ordinary commands on the CPU, as without it). Carry it with :meth:`step_temperature`, starting
        from :attr:`ambient`. A NaN temperature gives NaN in its coupled group, like a NaN command.
        """
        return self.clip(tau_cmd, qd, bus_voltage, temperature)

    __call__ = saturate

    def clip_turn(
        self, tau_cmd: Any, tau_sat: Any, qd: Any = None, tau_ref: Any = None, floor: float = ANGLE_FLOOR
    ) -> ClipTurn:
        """How far the coupled clip turned each coupled group's joint-torque vector in a batch, for logging.

        The statistics of ``hound-id saturate`` (:mod:`hound_id.mor.clip_turn`): per coupled group (e.g.
        FL_HFE+FL_KFE) the rows in which a motor of the group clipped, the angle between the commanded and the
        saturated joint-torque vector of the group (median, 95th percentile, max [deg]; vectors shorter than
        ``floor`` [N m] get no angle), the clips in which a joint's |tau| grew and by how much [N m], the same by
        which motors clipped and, given ``qd``, against the per-joint DC-motor clip of the same commands
        (:func:`hound_id.mor.saturation.per_joint_clip`, or your own ``tau_ref``) and how often the motors cannot
        make its torques. ``.scalars()`` gives flat floats for a logger::

            tau = sat.saturate(tau_cmd, qd)
            writer.add_scalars("clip_turn", sat.clip_turn(tau_cmd, tau, qd).scalars())

        Args:
            tau_cmd: Commanded joint torques [N m], (..., n_joints), numpy or torch.
            tau_sat: :meth:`saturate` of them, same shape and type.
            qd: Joint velocities [rad/s]; with it the per-joint comparison is made.
            tau_ref: Your per-joint clip of the same commands [N m] (default with ``qd``: the DC-motor one).
            floor: Shortest vector given an angle, smallest growth counted [N m] (:data:`ANGLE_FLOOR`).

        Torch tensors are worked on their device; per coupled group one (rows x few) float64 array comes back
        to the CPU (a device sync), where the quantiles are taken. Not differentiable (no gradients flow).
        """
        tau_cmd, tau_sat = self._array(tau_cmd, "tau_cmd"), self._array(tau_sat, "tau_sat")
        if _is_torch(tau_cmd) != _is_torch(tau_sat):
            raise SaturationError("runtime: tau_cmd and tau_sat must both be numpy arrays or both torch tensors")
        violation, reference = None, None
        if tau_ref is not None:
            tau_ref, reference = self._array(tau_ref, "tau_ref"), "given (tau_ref)"
        if qd is not None:
            qd = self._array(qd, "qd")
            if tau_ref is None:
                tau_ref = per_joint_clip(self.clip, tau_cmd, qd, self.own_motor or None)
                reference = PER_JOINT_REFERENCE if tau_ref is not None else None
            if tau_ref is not None:
                violation = self.clip.violation(tau_ref, qd)
        key: Any = "groups"
        if key not in self._consts:
            self._consts[key] = (coupled_groups(self.clip.A),)
        return clip_turn(
            tau_cmd, tau_sat, self.clip.A, self._consts[key][0], self.joints, self.motors, floor, tau_ref, violation,
            reference,
        )  # fmt: skip

    @property
    def ambient(self) -> NDArray[np.float64]:
        """Per motor ambient temperature [degC]: the winding temperature to start an episode from (or draw it)."""
        if self.heat is None:
            raise SaturationError("runtime: this bundle has no thermal model (a bundle/4 whose specs state one)")
        return self.heat[2].copy()

    def step_temperature(self, temperature: Any, tau: Any, dt: float) -> Any:
        """The winding temperatures [degC] after ``dt`` [s] with the joint torques ``tau`` [N m] held, (..., n_motors).

        Each motor's current is the inverse of its current-torque curve at its temperature (the curve scaled by
        Kt(T)/Kt20) at the motor torque A^T tau; the copper loss c R(T) i^2 heats the winding, which cools to the
        ambient through R_th; the step is exact for the held current (:func:`hound_id.mor.thermal.step`), so any
        ``dt`` is stable. The drive's derating is read by :meth:`saturate` at the step's start, so keep ``dt`` well
        below the thermal time constant (a control step is). Pass the saturated torques (:meth:`saturate` at the
        same ``temperature``): past the curve's top no current makes the torque, and the temperature becomes NaN.

        ``temperature`` is (..., n_motors), or (..., 1) per environment; the result has ``tau``'s shape, array type
        and device, and the wider of the two dtypes in numpy (the temperature's in torch). Field weakening's d
        current is not counted.
        """
        from hound_id.mor.thermal import step

        if isinstance(dt, bool) or not isinstance(dt, int | float) or not (math.isfinite(dt) and dt > 0):
            raise SaturationError(f"runtime.step_temperature: dt = {dt!r}; expected a positive, finite time step [s]")
        tau_m = self.motor_torque(tau)
        if _is_torch(tau_m):
            import torch

            temperature = torch.as_tensor(temperature, device=tau_m.device)
            if not temperature.is_floating_point():
                temperature = temperature.to(tau_m.dtype)
            tau_m = tau_m.to(temperature.dtype)
            shape_ok = _broadcasts(tuple(temperature.shape), tuple(tau_m.shape))
        else:
            temperature = np.asarray(temperature)
            dtype = np.promote_types(temperature.dtype if temperature.dtype.kind == "f" else np.float64, tau_m.dtype)
            temperature, tau_m = temperature.astype(dtype, copy=False), tau_m.astype(dtype, copy=False)
            shape_ok = _broadcasts(temperature.shape, tau_m.shape)
        if not shape_ok:
            raise SaturationError(
                f"runtime.step_temperature: temperature has shape {tuple(temperature.shape)}; expected tau's "
                f"{tuple(tau_m.shape)} or one per environment, {(*tuple(tau_m.shape)[:-1], 1)} [degC]"
            )
        r_th, tau_th, ambient, loss, a_r, _ = self._heat_rows(tau_m)
        current = self.current(tau_m, temperature=temperature)
        if not _is_torch(current):
            current = current.astype(tau_m.dtype, copy=False)
        return step(temperature, current, dt, r_th, tau_th, ambient, loss, a_r) + 0.0 * tau_m

    def _heat_rows(self, like: Any) -> tuple[Any, ...]:
        """:attr:`heat`'s rows in the array type, dtype and device of ``like`` (cached), or SaturationError without a
        thermal model."""
        if self.heat is None:
            raise SaturationError("runtime: this bundle has no thermal model (a bundle/4 whose specs state one)")
        return self._like("heat", tuple(self.heat), like)

    def _kt_scale(self, temperature: Any, like: Any) -> Any:
        """Kt(T)/Kt20 per motor at ``temperature`` [degC], in the array type of ``like``."""
        from hound_id.mor.thermal import REFERENCE

        a_k = self._heat_rows(like)[5]
        if not _is_torch(temperature):
            temperature = np.asarray(temperature, dtype=a_k.dtype)
        return 1.0 + a_k * (temperature - REFERENCE)

    def motor_velocity(self, qd: Any) -> Any:
        """Motor speeds A^-1 qd [rad/s], (..., n_motors)."""
        qd = self._array(qd, "qd")
        A_inv = self._constants(qd)[0]
        return qd @ A_inv.T

    def motor_torque(self, tau: Any) -> Any:
        """Motor torques A^T tau [N m] (the power-consistent map), (..., n_motors)."""
        tau = self._array(tau, "tau")
        A = self._constants(tau)[1]
        return tau @ A

    def friction_torque(self, qd: Any, tau: Any = None, temperature: Any = None) -> Any:
        """The fitted motor friction seen at the joints, A^-T f [N m]; opposes the motors' motion.

        f is the sum of the fitted terms of :mod:`hound_id.mor.friction`, motor side, at the motor speeds
        omega = A^-1 qd: -(coulomb sgn(omega) + viscous omega + stribeck sgn(omega) exp(-(omega/stribeck_speed)^2)
        + gear_friction |i| sgn(omega)), sgn(omega) = tanh(omega / 0.01 rad/s) as in the fit.

        Load-dependent friction (``gear_friction``, per amp) takes i, the current each motor's curve needs for the
        motor torques A^T ``tau`` (at ``temperature`` [degC], if given): pass ``tau``, the joint torques the motors
        make (what :meth:`saturate` returned). Without ``tau`` a bundle whose motors have it raises SaturationError
        (:attr:`load_friction` names them), rather than leave it out.
        """
        qd = self._array(qd, "qd")
        A_inv, _, *values = self._constants(qd)
        p = {name: v for (name, _, _), v in zip(parameters(), values, strict=True)}
        w = qd @ A_inv.T
        exp: Any = np.exp
        if _is_torch(qd):
            import torch

            sgn, exp = torch.tanh(w / EPS_SPEED), torch.exp
        else:
            sgn = np.tanh(w / EPS_SPEED)
        load = None
        if self.load_friction:
            if tau is None:
                raise SaturationError(
                    f"runtime.friction_torque: motors {', '.join(self.load_friction)} have load-dependent friction "
                    "(gear_friction, per amp of motor current); pass tau, the joint torques the motors make "
                    "(saturate's output): friction_torque(qd, tau)"
                )
            tau = self._array(tau, "tau")
            if tuple(tau.shape) != tuple(qd.shape):
                raise SaturationError(
                    f"runtime.friction_torque: tau has shape {tuple(tau.shape)}, qd {tuple(qd.shape)}; expected the "
                    "same (..., n_joints)"
                )
            load = abs(self.current(self.motor_torque(tau), temperature=temperature))
        # a term that needs the load is zero on every motor when no motor has it (load_friction is empty)
        f_motor = sum(
            term.torque(p, w, sgn, load, exp) for term in TERMS.values() if load is not None or not term.needs_load
        )
        return f_motor @ A_inv  # tau_j = A^-T f, row-vector form f @ A^-1

    def current(self, tau_motor: Any, method: str = "exact", temperature: Any = None) -> Any:
        """Motor currents [A] that make the motor torques [N m], (..., n_motors) in, same shape out.

        ``exact`` (default): the exact inverse of each motor's current-torque curve (the fit's, or the quadratic
        through the spec sheet's 20 % point): closed-form for the quadratic, i = 2 tau / (Kt + sqrt(Kt^2 -
        4 k |tau|)), the table's interpolation otherwise; +-inf past the curve's top. A bundle/1 has no curves:
        there the fit's polynomial, else tau / Kt, as before. ``polynomial``: the fit's odd polynomial (its error
        against the exact inverse is in the bundle's ``compensation_polynomial``) where the motor has one, the
        exact inverse elsewhere.

        ``temperature`` [degC] (a bundle/4 with a thermal model): each winding's temperature, (..., n_motors) or
        (..., 1); the flux scales the curve's torque by Kt(T)/Kt20 at every current, so the current for a torque is
        the 20 degC inverse at tau / (Kt(T)/Kt20).
        """
        if method not in ("exact", "polynomial"):
            raise SaturationError(f"runtime.current: method {method!r}; expected 'exact' or 'polynomial'")
        tau_motor = self._array(tau_motor, "tau_motor")
        if temperature is not None:
            if not _broadcasts(tuple(np.shape(temperature)), tuple(tau_motor.shape)):
                raise SaturationError(
                    f"runtime.current: temperature has shape {tuple(np.shape(temperature))}; expected tau_motor's "
                    f"{tuple(tau_motor.shape)} or one per environment (..., 1) [degC]"
                )
            tau_motor = tau_motor / self._kt_scale(temperature, tau_motor)
        out: Any
        if _is_torch(tau_motor):
            import torch

            out = torch.empty_like(tau_motor)
        else:
            out = np.empty_like(np.asarray(tau_motor, dtype=float))
        for m, comp in enumerate(self.compensation):
            t = tau_motor[..., m]
            curve = self.curves[m] if self.curves else None
            if comp is not None and (method == "polynomial" or curve is None):
                powers, coefficients = comp
                out[..., m] = polynomial(powers, coefficients, t)
            elif curve is not None:
                out[..., m] = _inverse(curve, t)
            else:
                out[..., m] = t / float(self.kt[m])
        return out

    def voltage(self, tau_cmd: Any, qd: Any, bus_voltage: Any = None, temperature: Any = None) -> Any:
        """Motor voltages [V] for MuJoCo's voltage-input dcmotor (``hound-id export``, ``--mujoco-actuator dcmotor``):
        v = R tau_m / Kt + omega_m / Kv of the saturated motor torques, clamped to +-V_bus, (..., n_motors).

        MuJoCo's dcmotor (one motor constant K = 1/Kv, R' = R Ke/Kt) turns v back into tau_m wherever it lies within
        the bus, which it does wherever the region's edges are the straight voltage lines. For a saturating
        current-torque curve past the no-load speed, and past overspeed, the clamp binds and MuJoCo applies its
        straight line instead (by at most the export note's straight-line gap). Numpy or torch, like
        :meth:`saturate`.

        ``temperature`` [degC]: the torques saturated at each winding's temperature (:meth:`saturate`), turned into
        the voltage MuJoCo's 20 degC dcmotor needs for them. A warm winding's weaker flux reaches speeds its 20 degC
        model cannot drive at the bus: there the clamp binds and MuJoCo applies less than the runtime.
        """
        if self.resistance is None or self.kv is None or self.bus_voltage is None:
            raise SaturationError("runtime.voltage: this runtime has no motor resistance, Kv and bus voltage")
        tau_m = self.motor_torque(self.saturate(tau_cmd, qd, bus_voltage, temperature))
        omega = self.motor_velocity(qd)
        r_kt, inv_kv, v_bus = self.resistance / self.kt, 1.0 / self.kv, self.bus_voltage
        if _is_torch(tau_m):
            import torch

            kw = {"dtype": tau_m.dtype, "device": tau_m.device}
            r, w, v = (torch.tensor(np.array(a), **kw) for a in (r_kt, inv_kv, v_bus))
            if bus_voltage is not None:
                v = torch.clamp(torch.as_tensor(bus_voltage, **kw), min=0.0)
            return torch.minimum(torch.maximum(tau_m * r + omega * w, -v), v)
        if bus_voltage is not None:
            v_bus = np.maximum(np.asarray(bus_voltage, dtype=float), 0.0)
        return np.clip(tau_m * r_kt + omega * inv_kv, -v_bus, v_bus)


def _broadcasts(small: tuple[int, ...], full: tuple[int, ...]) -> bool:
    """Whether a per-environment or per-motor array of shape ``small`` broadcasts to ``full`` without growing it."""
    try:
        return tuple(np.broadcast_shapes(small, full)) == full
    except ValueError:
        return False


def _inverse(curve: CurrentCurve, t: Any) -> Any:
    """The curve's exact inverse at torques ``t``, numpy or torch (:meth:`CurrentCurve.current`)."""
    if not _is_torch(t):
        return curve.current(t)
    import torch

    mag = torch.abs(t)
    if curve.currents is not None and curve.torques is not None:
        kw = {"dtype": t.dtype, "device": t.device}
        out = interp(mag, torch.tensor(np.array(curve.torques), **kw), torch.tensor(np.array(curve.currents), **kw))
        out = torch.sign(t) * out
    elif curve.k_sat > 0:  # tau itself in the numerator: autograd gives the slope 1/Kt at zero torque too
        out = 2.0 * t / (curve.kt + torch.sqrt(torch.clamp(curve.kt**2 - 4.0 * curve.k_sat * mag, min=0.0)))
    else:
        out = t / curve.kt
    return torch.where(mag > curve.top_torque, torch.copysign(torch.full_like(t, float("inf")), t), out)


def _validated(bundle: Mapping[str, Any], source: str) -> tuple[NDArray[np.float64], dict[str, Any], list[Any]]:
    """(A, saturation block, motors) of a bundle, or SpecError naming what is wrong."""
    try:
        joints, motors, s = list(bundle["joints"]), list(bundle["motors"]), dict(bundle["saturation"])
        A = np.asarray(s["A"], dtype=float)
        n = len(joints)
        arrays = {k: np.asarray([np.inf if v is None else v for v in s[k]], dtype=float) for k in _SAT_KEYS}
    except (KeyError, TypeError, ValueError) as err:
        raise SpecError(f"{source}: not a complete hound-id bundle ({type(err).__name__}: {err})") from err
    if A.shape != (n, n) or len(motors) != n or any(a.shape != (n,) for a in arrays.values()):
        raise SpecError(
            f"{source}: {n} joints but A is {A.shape}, {len(motors)} motors and saturation arrays of lengths "
            f"{[a.size for a in arrays.values()]}; expected one motor per joint and an n x n A"
        )
    if not np.all(np.isfinite(A)) or np.linalg.cond(A) > 1e10:
        raise SpecError(f"{source}: saturation.A is singular or not finite; re-export the bundle")
    return A, arrays, motors


_SAT_KEYS = ("stall_torque", "back_emf_damping", "torque_limit", "max_speed")


def _curve_of(motor: Mapping[str, Any], source: str) -> CurrentCurve:
    """A bundle/2 motor's current-torque curve; SpecError when missing or malformed."""
    block = motor.get("current_curve")
    if not isinstance(block, Mapping):
        raise SpecError(f"{source}: motor {motor.get('name')!r} has no current_curve; re-export the bundle")
    return CurrentCurve.from_dict(block, f"{source}: motor {motor.get('name')}")


#: Relative agreement the clip's curve arrays must have with the motors' current_curve and torque_limit in a bundle.
CURVE_AGREEMENT = 1e-6


def _curve_arrays(
    block: Mapping[str, Any], curves: list[Any], torque_limit: NDArray[np.float64], source: str
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(limit_x, curve_q, top_torque) of a bundle/2's saturation block, checked against each motor's current_curve
    and torque limit (the clip must hold the curve the file describes); SpecError names the first disagreement."""
    n = len(curves)
    out = []
    for key in ("limit_x", "curve_q", "top_torque"):
        values = block.get(key)
        try:
            arr = np.asarray([np.inf if v is None else v for v in values], dtype=float) if values is not None else None
        except (TypeError, ValueError) as err:
            raise SpecError(
                f"{source}: saturation.{key} is not a list of numbers ({err}); re-export the bundle"
            ) from err
        if arr is None or arr.shape != (n,) or np.any(np.isnan(arr)) or np.any(arr < 0):
            raise SpecError(f"{source}: saturation.{key} needs {n} numbers >= 0 (a bundle/2 has it); re-export it")
        out.append(arr)
    limit_x, q, top = out
    for m, curve in enumerate(curves):
        want_q = curve.q
        want_top = curve.top_torque if curve.form == "table" else np.inf
        made = float(curve.torque(limit_x[m] / curve.kt))  # the torque the clip's current limit makes on the curve
        checks = (
            ("curve_q", q[m], want_q, f"is {q[m]:.6g}, but k_sat / Kt^2 of its current_curve is {want_q:.6g}"),
            ("top_torque", top[m], want_top, f"is {top[m]:.6g}, but its current_curve's is {want_top:.6g} (inf: none)"),
            (
                "limit_x",
                made,
                float(torque_limit[m]),
                f"makes {made:.6g} N m through its current_curve, but its torque limit is {torque_limit[m]:.6g} N m",
            ),
        )
        for key, got, want, what in checks:
            same = got == want or (math.isfinite(want) and abs(got - want) <= CURVE_AGREEMENT * max(1.0, abs(want)))
            if not same:
                raise SpecError(
                    f"{source}: saturation.{key} of motor {m} {what}; the file is damaged or was edited by hand: "
                    "re-export the bundle"
                )
    return frozen(limit_x), frozen(q), frozen(top)


def _ranges(motors: list[Any]) -> NDArray[np.float64] | None:
    """Per motor (lowest, highest) bus voltage [V] when every motor of a bundle/3 states its battery's range."""
    ranges = [m.get("bus_voltage_range") for m in motors]
    if not ranges or any(r is None for r in ranges):
        return None
    return frozen(np.array([[float(r[0]), float(r[1])] for r in ranges]))


def _heat_rows(motors: list[Any], source: str) -> NDArray[np.float64] | None:
    """:attr:`Runtime.heat` from a bundle/4's motors (None when none has a thermal model)."""
    blocks = [m.get("thermal") for m in motors]
    if all(b is None for b in blocks):
        return None
    rows = np.empty((6, len(blocks)))
    for k, b in enumerate(blocks):
        if b is None:
            rows[:, k] = (0.0, 1.0, 20.0, 0.0, 0.0, 0.0)
            continue
        try:
            rows[:, k] = [
                float(b[key])
                for key in (
                    "thermal_resistance", "thermal_time_constant", "ambient", "copper_loss_per_current_squared",
                    "alpha_resistance", "alpha_kt",
                )
            ]  # fmt: skip
        except (KeyError, TypeError, ValueError) as err:
            raise SpecError(f"{source}: motor {k}'s thermal block is damaged ({err}); re-export the bundle") from err
    if not (np.all(np.isfinite(rows)) and np.all(rows[1] > 0) and np.all(rows[0] >= 0) and np.all(rows[3] >= 0)):
        raise SpecError(f"{source}: a motor's thermal block has a non-positive time constant or a negative value")
    return frozen(rows)


def _drive_fields(block: Mapping[str, Any], n: int, source: str) -> dict[str, Any]:
    """The Saturation fields of a bundle/3's nominal bus voltages and drive arrays (empty for older bundles and for
    the DC law); SpecError names a malformed one."""
    out: dict[str, Any] = {}
    try:
        if block.get("bus_voltage") is not None:
            volts = np.asarray(block["bus_voltage"], dtype=float)
            if volts.shape != (n,) or not np.all(volts > 0) or not np.all(np.isfinite(volts)):
                raise ValueError(f"bus_voltage needs {n} positive numbers")
            out["bus_voltage"] = frozen(volts)
        drive = block.get("drive")
        if drive is not None:
            k_rho = np.asarray(drive["k_rho"], dtype=float)
            circle = np.asarray(drive["circle_x"], dtype=float)
            fw = np.asarray([bool(f) for f in drive["field_weakening"]])
            if any(a.shape != (n,) for a in (k_rho, circle, fw)) or not (
                np.all(np.isfinite(k_rho)) and np.all(k_rho >= 0) and np.all(circle > 0) and np.all(np.isfinite(circle))
            ):
                raise ValueError(f"drive needs {n} finite k_rho >= 0, circle_x > 0 and field_weakening flags")
            out.update(drive_k_rho=frozen(k_rho), drive_circle_x=frozen(circle), drive_fw=frozen(fw))
        heat = block.get("thermal")
        if heat is not None:
            rows = np.array(
                [
                    [np.inf if v is None else float(v) for v in heat[key]]
                    for key in ("alpha_resistance", "alpha_kt", "derate_start", "winding_limit", "current_x")
                ]
            )
            if rows.shape != (5, n) or np.any(np.isnan(rows)) or not np.all(np.isfinite(rows[[0, 1, 4]])):
                raise ValueError(f"thermal needs {n} numbers in each of its five rows")
            out["thermal"] = frozen(rows)
    except (KeyError, TypeError, ValueError) as err:
        raise SpecError(f"{source}: saturation block is damaged ({err}); re-export the bundle") from err
    return out


def from_bundle(bundle: Any, joint_names: Sequence[str] | None = None, source: str = "bundle") -> Runtime:
    """A runtime from a bundle: its dict (the file's content) or a :class:`hound_id.export.bundle.Bundle`
    (see :func:`load`).

    ``joint_names`` is the order your simulator uses (Isaac Lab's ``asset.joint_names``, for
    instance, which is breadth-first): every joint-space array you pass and get back is then in
    that order. By default it is the bundle's order.
    """
    if not isinstance(bundle, Mapping) and hasattr(bundle, "to_dict"):  # a typed Bundle: its file content
        bundle = bundle.to_dict()
    A, arrays, motors = _validated(bundle, source)
    joints = list(bundle["joints"])
    own: tuple[int, ...] = ()
    if joint_names is not None:
        names = list(joint_names)
        if sorted(names) != sorted(joints):
            missing, extra = sorted(set(joints) - set(names)), sorted(set(names) - set(joints))
            raise SpecError(
                f"{source}: joint_names must be the bundle's joints in your order; missing {missing or 'none'}, "
                f"not in the bundle {extra or 'none'}"
            )
        own = tuple(joints.index(j) for j in names)  # motor k is the one listed with the bundle's joint k
        A = A[list(own), :]  # rows follow your joints; motors keep their order
        joints = names
    blocks = list(bundle["saturation"].get("polylines") or [])
    lines = tuple(polyline_of(p) for p in blocks)
    held = tuple(bool(isinstance(p, Mapping) and p.get("held")) for p in blocks)
    second = bundle.get("schema") != "hound-id/bundle/1"
    curves = [_curve_of(m, source) for m in motors] if second else [None] * len(motors)
    curve_arrays = (
        _curve_arrays(bundle["saturation"], curves, arrays["torque_limit"], source) if second else (None,) * 3
    )
    clip = Saturation(
        joints=tuple(joints),
        A=frozen(A),
        A_inv=frozen(np.linalg.inv(A)),
        stall_torque=frozen(arrays["stall_torque"]),
        back_emf_damping=frozen(arrays["back_emf_damping"]),
        torque_limit=frozen(arrays["torque_limit"]),
        max_speed=frozen(arrays["max_speed"]),
        limit_x=curve_arrays[0],
        curve_q=curve_arrays[1],
        top_torque=curve_arrays[2],
        polylines=lines if any(p is not None for p in lines) else (),
        held=held if any(held) else (),
        **_drive_fields(bundle["saturation"], len(motors), source),
    )

    def per_motor(key: str, default: float) -> NDArray[np.float64]:
        return frozen(np.array([float(m["friction"].get(key) or default) for m in motors]))  # or: a null is unfitted

    comps = []
    for m in motors:
        c = m.get("compensation_polynomial") if second else m.get("compensation")  # bundle/1: the polynomial
        comps.append((tuple(int(p) for p in c["powers"]), tuple(float(v) for v in c["coefficients"])) if c else None)
    return Runtime(
        joints=tuple(joints),
        motors=tuple(m["name"] for m in motors),
        clip=clip,
        friction={name: per_motor(name, default) for name, _, default in parameters()},
        kt=frozen(np.array([float(m["kt"]) for m in motors])),
        resistance=frozen(np.array([float(m["resistance"]) for m in motors])),
        kv=frozen(np.array([float(m["kv"]) for m in motors])),
        bus_voltage=frozen(np.array([float(m["bus_voltage"]) for m in motors])),
        bus_voltage_range=_ranges(motors),
        heat=_heat_rows(motors, source),
        compensation=tuple(comps),
        curves=tuple(curves) if any(c is not None for c in curves) else (),
        own_motor=own,
    )


def load(path: str | Path, joint_names: Sequence[str] | None = None) -> Runtime:
    """The runtime of a bundle file (YAML or JSON) written by ``hound-id export --format bundle``.

    Pass ``joint_names`` when your simulator orders joints differently from the bundle (see
    :func:`from_bundle`); arrays are matched by position, so a wrong order gives wrong torques.
    """
    return from_bundle(read_bundle(path), joint_names, source=str(path))


def read_bundle(path: str | Path) -> dict[str, Any]:
    """The content of a bundle file (YAML or JSON) of any readable schema version (:data:`READABLE`), checked
    for its schema and its top-level fields; SpecError names what is wrong.

    JSON is read with the standard library; YAML needs PyYAML, imported only for it.
    """
    p = Path(path)
    if p.suffix.lower() == ".json":
        try:
            data = json.loads(p.read_text())
        except OSError as err:
            raise SpecError(f"{p}: cannot read the bundle ({err.strerror or err})") from err
        except json.JSONDecodeError as err:
            raise SpecError(f"{p}: not JSON ({err.msg}, line {err.lineno})") from err
        except (ValueError, RecursionError) as err:  # not UTF-8, nesting too deep, an integer of 5,000 digits
            first = str(err).splitlines()[0] if str(err) else type(err).__name__
            raise SpecError(f"{p}: not a bundle hound-id reads ({first})") from err
    else:
        from hound_id.io import read_yaml  # PyYAML: only for a YAML bundle

        data = read_yaml(p, "bundle")
    if not isinstance(data, dict):
        raise SpecError(f"{p}: found {type(data).__name__}, expected a hound-id bundle (a YAML or JSON mapping)")
    if data.get("schema") not in READABLE:
        raise SpecError(f"{p}: schema {data.get('schema')!r}; this hound-id reads {', '.join(READABLE)}")
    for key in ("joints", "motors", "saturation"):
        if key not in data:
            raise SpecError(f"{p}: field '{key}' missing; is this a hound-id bundle?")
    return data
