"""The parameter bundle (``hound-id/bundle/1``): everything a trainer needs, in one file.

:func:`build_bundle` gathers, for a robot with its (optionally fitted) motors:

* ``joints`` in the order of every joint-space array, and ``motors`` in motor order (motor i
  is the one listed with joint i in the robot file);
* per motor: Kt, Kv, R, V_bus, peak torque, current limit, the torque limit, stall torque,
  no-load speed, rated speed, rotor inertia, the operating region's half-spaces, and when a
  dyno fit is given its current-compensation polynomial and every fitted effect, each
  parameter with its value, standard error and unit; ``friction`` collects the friction
  effects (motor side, zero where not fitted);
* per transmission its velocity map A (qd_joint = A thetad_motor) and the global map;
* per joint the inner box (every point feasible whatever the coupled joints do) and the
  outer box (everything reachable), and the reflected rotor inertia A^-T diag(J) A^-1;
* ``saturation``: the arrays :mod:`hound_id.runtime` rebuilds the clip from, with the measured
  envelopes' polyline edges (``mor --compare --out``) where a motor spec has one;
* ``foot``: the optimised foot's inertial and contact sphere, from ``hound-id foot``'s JSON.

Units are SI throughout (N m, rad/s, A, V, ohm, kg, m, kg m^2), motor side unless a field says
joint. :func:`load_bundle` reads bundles of every schema version so far (there is one).
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from hound_id.errors import SpecError
from hound_id.mor.robot import Robot
from hound_id.mor.spec import MotorSpec

SCHEMA = "hound-id/bundle/1"
#: Schemas :func:`load_bundle` reads, oldest first.
READABLE = ("hound-id/bundle/1",)
#: Friction effects of the fit that the runtime and the simulators use (motor side).
FRICTION = ("coulomb", "viscous", "stribeck")


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
    """Fitted parameters, friction terms and compensation of a spec's fit (empty without a fit)."""
    if spec.fit is None:
        return {}, {k: 0.0 for k in (*FRICTION, "stribeck_speed")}, None
    params = dict(spec.fit.get("parameters", {}))
    friction = {k: float(params[k]["value"]) if k in params else 0.0 for k in FRICTION}
    friction["stribeck_speed"] = float(params["stribeck_speed"]["value"]) if "stribeck_speed" in params else 0.0
    comp = spec.fit.get("compensation")
    return params, friction, (dict(comp) if comp else None)


def build_bundle(
    robot: Robot, foot: dict[str, Any] | None = None, sources: dict[str, Any] | None = None
) -> dict[str, Any]:
    """The bundle of a robot (fits already applied with :func:`apply_fits`); see the module docstring."""
    from hound_id.mor.joint_space import robot_regions
    from hound_id.mor.saturation import Saturation

    regions = robot_regions(robot)
    sat = Saturation.from_robot(robot)
    motors = []
    for i, (motor, region) in enumerate(zip(robot.motors, regions.motors, strict=True)):
        spec = robot.motor_specs[motor]
        params, friction, comp = _effects(spec)
        r = region.to_dict()
        motors.append(
            {
                "name": motor,
                "joint": robot.joints[i],
                "spec": spec.name,
                "kt": spec.kt,
                "kv": spec.kv,
                "resistance": spec.resistance,
                "bus_voltage": spec.bus_voltage,
                "peak_torque": spec.peak_torque,
                "max_current": spec.max_current,
                "torque_limit": float(sat.torque_limit[i]),
                "stall_torque": float(sat.stall_torque[i]),
                "no_load_speed": r["no_load_speed"],
                "max_speed": spec.max_speed,
                "rotor_inertia": spec.rotor_inertia,
                "halfspaces": r["halfspaces"],
                "fitted": spec.fit is not None,
                "effects": params,
                "friction": friction,
                "compensation": comp,
                "envelope": dict(spec.envelope) if spec.envelope else None,
            }
        )
    rotor = [robot.motor_specs[m].rotor_inertia for m in robot.motors]
    reflected = None
    if all(j is not None for j in rotor):
        J = np.diag([float(j) for j in rotor if j is not None])
        reflected = (sat.A_inv.T @ J @ sat.A_inv).tolist()
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
        "reflected_inertia": reflected,
        "saturation": {
            "A": sat.A.tolist(),
            "stall_torque": sat.stall_torque.tolist(),
            "back_emf_damping": sat.back_emf_damping.tolist(),
            "torque_limit": sat.torque_limit.tolist(),
            "max_speed": [v if math.isfinite(v) else None for v in sat.max_speed.tolist()],
            "polylines": [
                {"speeds": p[0].tolist(), "lower": _nan_to_none(p[1]), "upper": _nan_to_none(p[2])}
                if p is not None
                else None
                for p in (sat.polylines or (None,) * len(robot.motors))
            ],
        },
        "foot": foot,
    }
    # plain numbers and lists only (numpy scalars from the regions), so YAML and JSON agree
    plain: dict[str, Any] = json.loads(json.dumps(bundle, default=lambda o: o.tolist()))
    return plain


def _nan_to_none(values: Any) -> list[float | None]:
    return [float(v) if math.isfinite(v) else None for v in values]


def foot_from_json(path: Path) -> dict[str, Any]:
    """The foot part of a bundle from ``hound-id foot --optimise``'s foot.json."""
    try:
        data = json.loads(path.read_text())
    except OSError as err:
        raise SpecError(
            f"--foot {path}: cannot read ({err.strerror or err}); give the foot.json of hound-id foot"
        ) from err
    except json.JSONDecodeError as err:
        raise SpecError(f"--foot {path}: not JSON ({err.msg}, line {err.lineno})") from err
    if not isinstance(data, dict) or data.get("schema") != "hound-id/foot/1":
        raise SpecError(f"--foot {path}: expected the hound-id/foot/1 JSON that hound-id foot --optimise writes")
    g, props = data["geometry"], data["foot"]["closed_form"]
    return {
        "link": "foot",
        "mass": props["mass"],
        "com": props["com"],
        "inertia": props["inertia"],
        "sphere_radius": g["radius"],
        "sphere_centre_z": g["centre_z"],
        "mass_ratio": data["mass_ratio"],
        "inertia_ratio": data["inertia_ratio"],
        "source": str(path.resolve()),
    }


def load_bundle(path: str | Path) -> dict[str, Any]:
    """A bundle (YAML or JSON) of any readable schema version, as the current version's dict."""
    p = Path(path)
    if p.suffix.lower() == ".json":
        try:
            data = json.loads(p.read_text())
        except OSError as err:
            raise SpecError(f"{p}: cannot read the bundle ({err.strerror or err})") from err
        except json.JSONDecodeError as err:
            raise SpecError(f"{p}: not JSON ({err.msg}, line {err.lineno})") from err
    else:
        from hound_id.io import read_yaml

        data = read_yaml(p, "bundle")
    if not isinstance(data, dict):
        raise SpecError(f"{p}: found {type(data).__name__}, expected a hound-id bundle (a YAML or JSON mapping)")
    if data.get("schema") not in READABLE:
        raise SpecError(f"{p}: schema {data.get('schema')!r}; this hound-id reads {', '.join(READABLE)}")
    for key in ("joints", "motors", "saturation"):
        if key not in data:
            raise SpecError(f"{p}: field '{key}' missing; is this a hound-id bundle?")
    return data
