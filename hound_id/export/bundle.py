"""The parameter bundle (``hound-id/bundle/5``): everything a trainer needs, in one file.

:func:`build_bundle` gathers, for a robot with its (optionally fitted) motors:

* ``joints`` in the order of every joint-space array, and ``motors`` in motor order (motor i
  is the one listed with joint i in the robot file);
* per motor: Kt, Kv, R, V_bus, peak torque, current limit, the torque limit (curve-limited) and
  the linear-Kt one, the current at the torque limit, stall torque, no-load speed, rated speed,
  rotor inertia, the operating region's half-spaces; its current-torque curve
  (``current_curve``: the fit's, or the quadratic through the spec sheet's 20 % point) and the
  current compensation, its exact inverse (``compensation``: method and error); when a dyno fit is
  given, its odd compensation polynomial (``compensation_polynomial``, with its error against the
  exact inverse) and every fitted effect, each parameter with its value, standard error and unit;
  ``friction`` collects every parameter of the friction terms of :mod:`hound_id.mor.friction` (motor side: Coulomb,
  viscous, Stribeck and load-dependent friction; 0 where not fitted), which the runtime applies;
* per transmission its velocity map A (qd_joint = A thetad_motor) and the global map;
* per joint the inner box (every point feasible whatever the coupled joints do) and the
  outer box (everything reachable), and the reflected rotor inertia A^-T diag(J) A^-1;
* ``saturation``: the arrays :mod:`hound_id.runtime` rebuilds the clip from (``limit_x``, Kt times
  the current at the torque limit, ``curve_q``, the quadratic curve's k / Kt^2, and ``top_torque``,
  a table curve's top, null for the others), with polyline
  edges where a motor has a measured envelope (``mor --compare --out``) or a table curve (``held``: the
  polyline's end values hold beyond it), the nominal ``bus_voltage`` per motor (the clip scales its stall torque
  to another bus), and ``drive`` (per motor ``k_rho``, ``circle_x``, ``field_weakening`` of the drive's dq model,
  :mod:`hound_id.mor.drive`; null under the DC law) and ``thermal`` (rows a_R, a_K, derating start, winding
  limit and Kt times the drive's current limit per motor, for the clip at a winding temperature; null without a
  thermal model); each motor carries its ``thermal`` model (:mod:`hound_id.mor.thermal`: R_th, time constant,
  limits, temperature coefficients), which the runtime steps;
* ``foot``: the optimised foot's inertial and contact sphere, from ``hound-id foot``'s JSON.

Units are SI throughout (N m, rad/s, A, V, ohm, kg, m, kg m^2), motor side unless a field says
joint. The bundle is a frozen :class:`Bundle` (one :class:`BundleMotor` per motor, nested blocks
read-only); :meth:`Bundle.to_dict` is the file's content. :func:`load_bundle` reads bundles of every
schema version so far (/1: linear-Kt limits, ``compensation`` the polynomial; /2: the curve; /3: the drive's dq
model, the bus voltage range and the nominal bus per motor in ``saturation``; /4: the thermal model; /5:
``gear_friction`` in ``friction``, read as 0 from the earlier ones).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from hound_id.errors import SpecError
from hound_id.io import TEXT_MAX_BYTES, read_json
from hound_id.mor.current_curve import polynomial
from hound_id.mor.friction import parameters as friction_parameters
from hound_id.mor.joint_space import robot_regions
from hound_id.mor.robot import Robot
from hound_id.mor.saturation import Saturation
from hound_id.mor.spec import MotorSpec, plain, read_only
from hound_id.runtime import READABLE, read_bundle

__all__ = [
    "READABLE", "SCHEMA", "Bundle", "BundleMotor", "apply_fits", "build_bundle", "foot_from_json",
    "load_bundle",
]  # fmt: skip

SCHEMA = "hound-id/bundle/5"


@dataclass(frozen=True)
class BundleMotor:
    """One motor of a bundle, SI, motor side (nested blocks read-only)."""

    name: str
    """Motor name in the robot file."""
    joint: str
    """The joint listed with it (motor i goes with joint i)."""
    spec: str
    """Name of its motor spec."""
    kt: float
    """Torque constant [N m/A] (the fitted one where a fit was applied)."""
    kv: float
    """Speed constant [rad/s/V]."""
    resistance: float
    """Model resistance [ohm]."""
    bus_voltage: float
    """Bus voltage [V]."""
    peak_torque: float
    """Peak torque [N m]."""
    max_current: float | None
    """Driver current limit [A], if any."""
    torque_limit: float
    """min(peak torque, g(i_max)) [N m], g the current-torque curve (bundle/1: Kt i_max)."""
    stall_torque: float
    """Kt V_bus / R [N m]."""
    no_load_speed: float
    """No-load speed of its region [rad/s]."""
    max_speed: float | None
    """Rated maximum speed [rad/s], if any."""
    rotor_inertia: float | None
    """Rotor inertia [kg m^2], if known."""
    halfspaces: Mapping[str, Any]
    """The region's half-spaces: ``A`` (rows (a_tau, a_omega)), ``b`` and ``labels``."""
    fitted: bool
    """Whether a dyno fit was applied."""
    effects: Mapping[str, Mapping[str, Any]]
    """Every fitted parameter: value, stderr, unit, at_bound (empty without a fit)."""
    friction: Mapping[str, float]
    """Every friction parameter (:func:`hound_id.mor.friction.parameters`): coulomb [N m], gear_friction [N m/A],
    stribeck [N m], stribeck_speed [rad/s], viscous [N m s/rad] (0 where not fitted)."""
    compensation: Mapping[str, Any] | None
    """bundle/2: the exact current compensation, the inverse of ``current_curve`` (method, torque_range, max_error);
    bundle/1: the fit's polynomial (powers, coefficients, ...), if any."""
    envelope: Mapping[str, Any] | None = None
    """The measured envelope as its spec carries it (``mor --compare --out``), if any."""
    linear_torque_limit: float | None = None
    """What a linear-Kt model takes for the torque limit, min(peak torque, Kt i_max) [N m] (bundle/2)."""
    limit_current: float | None = None
    """Current the torque limit needs [A] (bundle/2)."""
    current_curve: Mapping[str, Any] | None = None
    """The current-torque curve (:meth:`hound_id.mor.current_curve.CurrentCurve.to_dict`; bundle/2)."""
    compensation_polynomial: Mapping[str, Any] | None = None
    """The fit's odd compensation polynomial with its error against the exact inverse (bundle/2), if fitted."""
    drive: Mapping[str, Any] | None = None
    """The drive's dq model (:meth:`hound_id.mor.drive.Drive.to_dict`; bundle/3), or None for the DC law."""
    bus_voltage_range: tuple[float, float] | None = None
    """(lowest, highest) bus voltage over the battery's discharge [V] (bundle/3), if the spec states it."""
    thermal: Mapping[str, Any] | None = None
    """The winding's thermal model and the drive's derating (:meth:`hound_id.mor.thermal.Thermal.to_dict`;
    bundle/4), if the spec states one."""

    def to_dict(self) -> dict[str, Any]:
        """The motor's entry in the bundle file."""
        return {f.name: plain(getattr(self, f.name)) for f in fields(self)}


#: BundleMotor fields older bundles lack.
_OPTIONAL = (
    "envelope", "linear_torque_limit", "limit_current", "current_curve", "compensation_polynomial", "drive",
    "bus_voltage_range", "thermal",
)  # fmt: skip


@dataclass(frozen=True)
class Bundle:
    """A ``hound-id/bundle/5`` bundle (or a /1 to /4 one read back; see the module docstring); :meth:`to_dict` is
    the file's content."""

    schema: str
    """``hound-id/bundle/5`` (or /1 to /4)."""
    robot: str
    """Robot name."""
    units: str
    """The units sentence."""
    sources: Mapping[str, Any]
    """Files it came from: robot, fits, foot, urdf (read-only)."""
    joints: tuple[str, ...]
    """Joint order of every joint-space array."""
    motors: tuple[BundleMotor, ...]
    """Motors in motor order (motor i goes with joint i)."""
    transmissions: tuple[Mapping[str, Any], ...]
    """Per transmission: kind, joints, motors, A (qd_joint = A thetad_motor)."""
    joint_boxes: Mapping[str, Mapping[str, Any]]
    """Per joint: inner and outer box (effort [N m], velocity [rad/s]) and whether it is coupled."""
    reflected_inertia: tuple[tuple[float, ...], ...] | None
    """A^-T diag(J) A^-1 [kg m^2], joint side, or None where a rotor inertia is unknown."""
    saturation: Mapping[str, Any]
    """The arrays :mod:`hound_id.runtime` rebuilds the clip from (A, stall_torque, ..., polylines)."""
    foot: Mapping[str, Any] | None
    """The optimised foot's inertial and contact sphere, if given."""

    def to_dict(self) -> dict[str, Any]:
        """The bundle file's content (plain dicts, lists and numbers; YAML and JSON agree)."""
        out = {f.name: plain(getattr(self, f.name)) for f in fields(self)}
        out["motors"] = [m.to_dict() for m in self.motors]
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "bundle") -> Bundle:
        """A bundle from a file's content (any readable schema version, as the current version)."""
        try:
            motors = tuple(
                BundleMotor(
                    **{f.name: read_only(m[f.name]) for f in fields(BundleMotor) if f.name not in _OPTIONAL},
                    **{k: read_only(m.get(k)) for k in _OPTIONAL},  # absent from bundles written before them
                )
                for m in data["motors"]
            )
            return cls(
                schema=str(data["schema"]),
                robot=str(data.get("robot", "")),
                units=str(data.get("units", "")),
                sources=read_only(data.get("sources") or {}),
                joints=tuple(str(j) for j in data["joints"]),
                motors=motors,
                transmissions=read_only(data.get("transmissions") or []),
                joint_boxes=read_only(data.get("joint_boxes") or {}),
                reflected_inertia=read_only(data.get("reflected_inertia")),
                saturation=read_only(data["saturation"]),
                foot=read_only(data.get("foot")),
            )
        except (KeyError, TypeError) as err:
            raise SpecError(f"{source}: not a complete hound-id bundle ({type(err).__name__}: {err})") from err


def apply_fits(robot: Robot, fitted: list[MotorSpec]) -> Robot:
    """The robot with each fitted motor spec in place of the spec sheet of the same motor name."""
    names = {s.name for s in robot.motor_specs.values()}
    for spec in fitted:
        if spec.fit is None:
            raise SpecError(
                f"--fit: {spec.name} has no 'fit:' block; give the file that hound-id fit-current --out wrote"
            )
        if spec.name not in names:
            raise SpecError(
                f"--fit: the fitted motor is '{spec.name}', but the robot's motors are {', '.join(sorted(names))}; "
                "fit-current --out keeps the spec sheet's name, so check 'base:' in the fitted file"
            )
    dupes = sorted({s.name for s in fitted if [f.name for f in fitted].count(s.name) > 1})
    if dupes:
        raise SpecError(f"--fit: more than one fit for motor {', '.join(dupes)}; give one per motor")
    by_name = {s.name: s for s in fitted}
    return replace(robot, motor_specs={m: by_name.get(s.name, s) for m, s in robot.motor_specs.items()})


def _effects(spec: MotorSpec) -> tuple[dict[str, Any], dict[str, float], dict[str, Any] | None]:
    """Fitted parameters (as the fit record writes them), friction terms and compensation polynomial of a spec's
    fit (empty without a fit), the polynomial with its largest current error against the curve's exact inverse."""
    if spec.fit is None:
        return {}, {k: 0.0 for k, _, _ in friction_parameters()}, None
    written = spec.fit.to_dict()
    friction = {k: spec.fit.value(k) for k, _, _ in friction_parameters()}
    comp = spec.fit.compensation
    polynomial = None
    if comp is not None:  # fit/3 keeps the polynomial's own block apart; fit/2 had it as compensation
        block = dict(written.get("compensation_polynomial") or written.get("compensation") or {})
        polynomial = {
            "powers": list(comp.powers),
            "coefficients": list(comp.coefficients),
            "torque_range": block.get("torque_range"),
            "max_error": block.get("max_error"),
            "slope_error": block.get("slope_error"),
            "error_vs_exact": _polynomial_error(spec, comp.powers, comp.coefficients),
            "units": "current [A] = sum c_k * torque[N m]^k; error_vs_exact [A] up to the torque limit",
        }
    return dict(written.get("parameters") or {}), friction, polynomial


#: Torques at which a compensation polynomial is compared with the exact inverse (0 to the torque limit).
POLYNOMIAL_CHECK_POINTS = 2001


def _polynomial_error(spec: MotorSpec, powers: tuple[int, ...], coefficients: tuple[float, ...]) -> float:
    """Largest |polynomial(tau) - exact inverse(tau)| [A] over 0..the torque limit."""
    tau = np.linspace(0.0, spec.torque_limit, POLYNOMIAL_CHECK_POINTS)
    return float(np.max(np.abs(polynomial(powers, coefficients, tau) - spec.current_curve.current(tau))))


def build_bundle(robot: Robot, foot: dict[str, Any] | None = None, sources: dict[str, Any] | None = None) -> Bundle:
    """The bundle of a robot (fits already applied with :func:`apply_fits`); see the module docstring."""
    regions = robot_regions(robot)
    sat = Saturation.from_robot(robot)
    motors = [
        _motor_fields(robot.motor_specs[motor], motor, robot.joints[i], region.to_dict(), sat, i)
        for i, (motor, region) in enumerate(zip(robot.motors, regions.motors, strict=True))
    ]
    bundle = {
        "schema": SCHEMA,
        "robot": robot.name,
        "units": "SI: N m, rad/s, A, V, ohm, kg, m, kg m^2; motor side unless the field says joint",
        "sources": sources or {},
        "joints": list(robot.joints),
        "motors": motors,
        "transmissions": [
            {"kind": tx.kind, "joints": list(tx.joints), "motors": list(tx.motors), "A": tx.A.tolist()}
            for tx in robot.transmissions
        ],
        "joint_boxes": {
            j.joint: {"inner": j.inner_box.to_dict(), "outer": j.outer_box.to_dict(), "coupled": j.coupled}
            for j in regions.joints
        },
        "reflected_inertia": _reflected_inertia(robot, sat),
        "saturation": _saturation_fields(sat, len(robot.motors)),
        "foot": foot,
    }
    # plain numbers and lists only (numpy scalars from the regions), so YAML and JSON agree
    content: dict[str, Any] = json.loads(json.dumps(bundle, default=lambda o: o.tolist()))
    return Bundle.from_dict(content)


def _motor_fields(
    spec: MotorSpec, motor: str, joint: str, r: Mapping[str, Any], sat: Saturation, i: int
) -> dict[str, Any]:
    """The bundle's entry of motor ``i`` (named ``motor``, driving ``joint``), from its spec, its region's
    dictionary ``r`` and the robot's saturation."""
    params, friction, comp = _effects(spec)
    return {
        "name": motor,
        "joint": joint,
        "spec": spec.name,
        "kt": spec.kt,
        "kv": spec.kv,
        "resistance": spec.resistance,
        "bus_voltage": spec.bus_voltage,
        "peak_torque": spec.peak_torque,
        "max_current": spec.max_current,
        "torque_limit": float(sat.torque_limit[i]),
        "linear_torque_limit": spec.linear_torque_limit,
        "limit_current": spec.limit_current,
        "stall_torque": float(sat.stall_torque[i]),
        "no_load_speed": r["no_load_speed"],
        "max_speed": spec.max_speed,
        "rotor_inertia": spec.rotor_inertia,
        "halfspaces": r["halfspaces"],
        "fitted": spec.fit is not None,
        "effects": params,
        "friction": friction,
        "current_curve": spec.current_curve.to_dict(),
        "compensation": spec.current_curve.compensation(),
        "compensation_polynomial": comp,
        "envelope": spec.envelope.to_dict() if spec.envelope else None,
        "drive": r["drive"],
        "bus_voltage_range": None if spec.bus_voltage_range is None else list(spec.bus_voltage_range),
        "thermal": None if spec.thermal is None else spec.thermal.to_dict(),
    }


def _reflected_inertia(robot: Robot, sat: Saturation) -> list[list[float]] | None:
    """The rotors' inertia reflected to the joints, A^-T diag(J) A^-1 [kg m^2]; None when a motor has none."""
    rotor = [robot.motor_specs[m].rotor_inertia for m in robot.motors]
    if not all(j is not None for j in rotor):
        return None
    J = np.diag([float(j) for j in rotor if j is not None])
    reflected: list[list[float]] = (sat.A_inv.T @ J @ sat.A_inv).tolist()
    return reflected


def _saturation_fields(sat: Saturation, n_motors: int) -> dict[str, Any]:
    """The bundle's ``saturation`` block: the clip's arrays as lists, ``n_motors`` entries each."""
    return {
        "A": sat.A.tolist(),
        "stall_torque": sat.stall_torque.tolist(),
        "back_emf_damping": sat.back_emf_damping.tolist(),
        "torque_limit": sat.torque_limit.tolist(),
        "limit_x": (sat.torque_limit if sat.limit_x is None else sat.limit_x).tolist(),
        "curve_q": (np.zeros(sat.n) if sat.curve_q is None else sat.curve_q).tolist(),
        "top_torque": [None] * sat.n if sat.top_torque is None else _nan_to_none(sat.top_torque),
        "max_speed": [v if math.isfinite(v) else None for v in sat.max_speed.tolist()],
        "polylines": [
            {
                "speeds": p[0].tolist(),
                "lower": _nan_to_none(p[1]),
                "upper": _nan_to_none(p[2]),
                "held": bool(sat.held and sat.held[k]),
            }
            if p is not None
            else None
            for k, p in enumerate(sat.polylines or (None,) * n_motors)
        ],
        "bus_voltage": None if sat.bus_voltage is None else sat.bus_voltage.tolist(),
        "drive": _drive_fields(sat),
        "thermal": _thermal_fields(sat),
    }


def _drive_fields(sat: Saturation) -> dict[str, Any] | None:
    """The saturation's drive block (the dq model at speed); None when the clip has none."""
    if sat.drive_k_rho is None or sat.drive_circle_x is None or sat.drive_fw is None:
        return None
    return {
        "k_rho": sat.drive_k_rho.tolist(),
        "circle_x": sat.drive_circle_x.tolist(),
        "field_weakening": [bool(f) for f in sat.drive_fw],
        "units": {"k_rho": "1/(N m)", "circle_x": "N m"},
    }


def _thermal_fields(sat: Saturation) -> dict[str, Any] | None:
    """The saturation's thermal block (the winding's derating); None when the clip has none."""
    if sat.thermal is None:
        return None
    return {
        "alpha_resistance": sat.thermal[0].tolist(),
        "alpha_kt": sat.thermal[1].tolist(),
        "derate_start": _inf_to_none(sat.thermal[2]),
        "winding_limit": _inf_to_none(sat.thermal[3]),
        "current_x": sat.thermal[4].tolist(),
        "units": {
            "alpha_resistance, alpha_kt": "1/K",
            "derate_start, winding_limit": "degC (null: no thermal model)",
            "current_x": "N m (Kt x the drive's current limit)",
        },
    }


def _inf_to_none(values: Any) -> list[float | None]:
    return [float(v) if math.isfinite(v) else None for v in values]


def _nan_to_none(values: Any) -> list[float | None]:
    return [float(v) if math.isfinite(v) else None for v in values]


def foot_from_json(path: Path) -> dict[str, Any]:
    """The foot part of a bundle from ``hound-id foot --optimise``'s foot.json (its numbers checked finite, its
    mass, radius and inertia positive; one-line SpecError otherwise)."""
    data = read_json(path, "foot.json", TEXT_MAX_BYTES, option="--foot")
    if not isinstance(data, dict) or data.get("schema") not in ("hound-id/foot/1", "hound-id/foot/2"):
        raise SpecError(
            f"--foot {path}: expected the hound-id/foot/2 (or /1) JSON that hound-id foot --optimise writes"
        )

    def field(*keys: str, shape: tuple[int, ...] = (), positive: bool = False) -> Any:
        node: Any = data
        for key in keys:
            node = node.get(key) if isinstance(node, dict) else None
        name = ".".join(keys)
        try:
            values = np.asarray(node, dtype=float)
        except (TypeError, ValueError):
            values = np.asarray(np.nan)
        if (
            node is None
            or values.shape != shape
            or not np.all(np.isfinite(values))
            or (positive and np.any(values <= 0))
        ):
            what = f"an array of shape {shape}" if shape else "a number"
            raise SpecError(
                f"--foot {path}: field '{name}': found {node!r}, expected {what}, finite{', > 0' if positive else ''}; "
                "write the foot.json again with hound-id foot --optimise",
                field=name,
            )
        return node

    spheres = None
    if data["schema"] == "hound-id/foot/2":  # /2 adds the spheres along the cap's arc; a /1 foot keeps its one sphere
        raw = data.get("collision", {}).get("spheres") if isinstance(data.get("collision"), dict) else None
        count = len(raw) if isinstance(raw, list) else 0
        spheres = (
            field("collision", "spheres", shape=(count, 4)) if count else field("collision", "spheres", shape=(1, 4))
        )
        if any(sphere[3] <= 0 for sphere in spheres):
            raise SpecError(f"--foot {path}: field 'collision.spheres': a radius <= 0; write the foot.json again")
    return {
        "link": "foot",
        "mass": field("foot", "closed_form", "mass", positive=True),
        "com": field("foot", "closed_form", "com", shape=(3,)),
        "inertia": field("foot", "closed_form", "inertia", shape=(3, 3)),
        "sphere_radius": field("geometry", "radius", positive=True),
        "sphere_centre_z": field("geometry", "centre_z"),
        **({"collision_spheres": spheres} if spheres is not None else {}),
        "mass_ratio": field("mass_ratio", positive=True),
        "inertia_ratio": field("inertia_ratio", positive=True),
        "source": str(path.resolve()),
    }


def load_bundle(path: str | Path) -> Bundle:
    """A bundle file (YAML or JSON) of any readable schema version (:data:`READABLE`), as the current version."""
    return Bundle.from_dict(read_bundle(path), str(path))
