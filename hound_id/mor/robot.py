"""Robot descriptions: joints in order, the motors that drive them, and their transmissions.

A robot YAML (schema ``hound-id/robot/1``)::

    name: hound-like
    motor_specs:                 # spec name -> motor spec file (relative to this file)
      ilm85: ../motors/hound_ilm85.yaml
    joints: [FL_HAA, FL_HFE, FL_KFE, ...]        # the order of every joint-space array
    transmissions:
      - type: ratio              # independent gearboxes, one reduction per joint
        joints: [FL_HAA]
        motors: [FL_HAA_motor]
        motor_spec: ilm85        # or motor_specs: [a, b] one per motor
        ratios: [9.0]
      - type: hollow_shaft       # the paper's coaxial hip/knee module
        joints: [FL_HFE, FL_KFE]
        motors: [FL_HFE_motor, FL_KFE_motor]
        motor_spec: ilm85
        hip_ratio: 7.0
        knee_ratio: 7.0
      - type: matrix             # any invertible A with qd_joint = A thetad_motor
        joints: [a, b]
        motors: [ma, mb]
        motor_spec: ilm85
        matrix: [[0.1, 0.0], [0.05, 0.1]]

Every joint belongs to exactly one transmission; motor names are unique. An optional
``urdf: hound_like.urdf`` (relative to this file) names the robot's URDF, whose joints carry
the same names; the MuJoCo and URDF exports need it.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.errors import HoundIdError, RobotError, TransmissionError
from hound_id.io import TEXT_MAX_BYTES, check_input, file_stem, read_yaml
from hound_id.mor.spec import MotorSpec
from hound_id.mor.spec_sheet import load_motor_spec
from hound_id.mor.transmission import Transmission, from_matrix, from_ratios, hollow_shaft
from hound_id.units import as_number

SCHEMA = "hound-id/robot/1"
_TOP_KEYS = ("schema", "name", "source", "notes", "motor_specs", "joints", "transmissions", "urdf")
_TX_KEYS = {
    "ratio": ("ratios",),
    "hollow_shaft": ("hip_ratio", "knee_ratio"),
    "matrix": ("matrix",),
}
_TX_COMMON = ("type", "joints", "motors", "motor_spec", "motor_specs", "notes")


@dataclass(frozen=True)
class Robot:
    """Joints, motors and transmissions of a robot. Joint-space arrays follow ``joints``."""

    name: str
    """Robot name."""
    joints: tuple[str, ...]
    """Joint names in the order of every joint-space array."""
    transmissions: tuple[Transmission, ...]
    """Transmission groups; together they cover every joint once."""
    motor_specs: Mapping[str, MotorSpec]
    """Spec of each motor, by motor name."""
    source: str | None = None
    """Where the numbers came from."""
    urdf: str | None = None
    """The robot's URDF (absolute path), for the exports that need its bodies; None if not given."""

    @property
    def motors(self) -> tuple[str, ...]:
        """Motor names in motor-vector order: motor i is the one listed with joint i."""
        paired = {j: m for tx in self.transmissions for j, m in zip(tx.joints, tx.motors, strict=True)}
        return tuple(paired[j] for j in self.joints)

    def velocity_map(self) -> NDArray[np.float64]:
        """Global A (n x n): qd_joint = A thetad_motor, rows in joint order, columns in motor order."""
        n = len(self.joints)
        index = {j: i for i, j in enumerate(self.joints)}
        A = np.zeros((n, n))
        for tx in self.transmissions:
            idx = [index[j] for j in tx.joints]
            A[np.ix_(idx, idx)] = tx.A
        return A

    def transmission_of(self, joint: str) -> Transmission:
        """The transmission group a joint belongs to."""
        for tx in self.transmissions:
            if joint in tx.joints:
                return tx
        raise RobotError(f"robot {self.name}: no joint named {joint!r}; joints are {', '.join(self.joints)}")

    def reflected_inertia(self, joint: str) -> float | None:
        """Rotor inertia of the joint's transmission group seen at the joint [kg m^2].

        The diagonal entry of A^-T diag(J_rotor) A^-1 (J_rotor G^2 for a single gear); None
        when a motor of the group has no ``rotor_inertia`` in its spec.
        """
        tx = self.transmission_of(joint)
        rotors = [self.motor_specs[m].rotor_inertia for m in tx.motors]
        if any(r is None for r in rotors):
            return None
        k = tx.joints.index(joint)
        return float(tx.reflected_inertia([float(r) for r in rotors if r is not None])[k, k])


def _err(source: str, field: str, msg: str) -> RobotError:
    return RobotError(f"{source}: {field}: {msg}", field=field)


def _str_list(value: Any, source: str, field: str) -> list[str]:
    if not isinstance(value, list) or not value or not all(isinstance(v, str) and v for v in value):
        raise _err(source, field, f"found {value!r}, expected a non-empty list of names")
    return value


def robot_from_mapping(data: Any, source: str, base: Path) -> Robot:
    """Validate a parsed robot mapping; motor spec paths are relative to ``base``."""
    if not isinstance(data, Mapping):
        raise RobotError(f"{source}: found {type(data).__name__}, expected a mapping with joints and transmissions")
    for key in data:
        if key not in _TOP_KEYS:
            close = difflib.get_close_matches(str(key), _TOP_KEYS, n=1)
            hint = f"did you mean '{close[0]}'?" if close else f"known keys: {', '.join(_TOP_KEYS)}"
            raise _err(source, f"field '{key}'", f"unknown key; {hint}")
    if data.get("schema", SCHEMA) != SCHEMA:
        raise _err(source, "field 'schema'", f"found {data.get('schema')!r}, expected {SCHEMA!r}")
    for key in ("name", "motor_specs", "joints", "transmissions"):
        if key not in data:
            raise _err(source, f"field '{key}'", "missing; see docs/robots.md")

    spec_files = data["motor_specs"]
    if not isinstance(spec_files, Mapping) or not spec_files:
        raise _err(source, "field 'motor_specs'", f"found {spec_files!r}, expected a mapping name -> spec file")
    specs: dict[str, MotorSpec] = {}
    for key, rel in spec_files.items():
        if not isinstance(rel, str):
            raise _err(source, f"motor_specs.{key}", f"found {rel!r}, expected a path to a motor spec YAML")
        try:
            specs[str(key)] = load_motor_spec(base / rel)
        except HoundIdError as err:
            raise type(err)(f"{source}: motor_specs.{key}: {err}", **err.details) from err

    joints = _str_list(data["joints"], source, "field 'joints'")
    dupes = sorted({j for j in joints if joints.count(j) > 1})
    if dupes:
        raise _err(source, "field 'joints'", f"joint names repeated: {', '.join(dupes)}")

    txs_data = data["transmissions"]
    if not isinstance(txs_data, list) or not txs_data:
        raise _err(source, "field 'transmissions'", f"found {txs_data!r}, expected a list of transmissions")
    transmissions: list[Transmission] = []
    motor_specs: dict[str, MotorSpec] = {}
    covered: dict[str, int] = {}
    for t, tx in enumerate(txs_data):
        what = f"{source}: transmissions[{t}]"
        transmissions.append(_transmission(tx, what, specs, motor_specs))
        for j in transmissions[-1].joints:
            if j not in joints:
                raise RobotError(
                    f"{what}: joint {j!r} is not in 'joints'; add it there or fix the name", field="joints"
                )
            if j in covered:
                raise RobotError(
                    f"{what}: joint {j!r} is already driven by transmissions[{covered[j]}]", field="joints"
                )
            covered[j] = t
    missing = [j for j in joints if j not in covered]
    if missing:
        raise _err(source, "field 'transmissions'", f"joints without a transmission: {', '.join(missing)}")
    name = file_stem(data["name"], f"{source}: field 'name'")
    src = data.get("source")
    urdf = data.get("urdf")
    if urdf is not None:
        if not isinstance(urdf, str) or not urdf:
            raise _err(source, "field 'urdf'", f"found {urdf!r}, expected the path of the robot's URDF")
        if not (base / urdf).exists():
            raise _err(source, "field 'urdf'", f"{base / urdf} not found; the path is relative to the robot file")
        check_input(base / urdf, "URDF", RobotError, TEXT_MAX_BYTES)
        urdf = str((base / urdf).resolve())
    return Robot(
        name=name,
        joints=tuple(joints),
        transmissions=tuple(transmissions),
        motor_specs=motor_specs,
        source=src if isinstance(src, str) else None,
        urdf=urdf,
    )


def _transmission(tx: Any, what: str, specs: Mapping[str, MotorSpec], out_specs: dict[str, MotorSpec]) -> Transmission:
    if not isinstance(tx, Mapping):
        raise RobotError(f"{what}: found {tx!r}, expected a mapping with type, joints, motors")
    kind = tx.get("type")
    if kind not in _TX_KEYS:
        raise RobotError(f"{what}: field 'type': found {kind!r}, expected one of {', '.join(sorted(_TX_KEYS))}")
    allowed = (*_TX_COMMON, *_TX_KEYS[kind])
    for key in tx:
        if key not in allowed:
            raise RobotError(f"{what}: field '{key}': unknown for type {kind}; allowed: {', '.join(allowed)}")
    for key in ("joints", "motors", *_TX_KEYS[kind]):
        if key not in tx:
            raise RobotError(f"{what}: field '{key}': missing (type {kind} needs {', '.join(_TX_KEYS[kind])})")
    joints = _str_list(tx["joints"], what, "field 'joints'")
    motors = _str_list(tx["motors"], what, "field 'motors'")
    if "motor_spec" in tx and "motor_specs" in tx:
        raise RobotError(f"{what}: give 'motor_spec' (one for all motors) or 'motor_specs' (one per motor), not both")
    keys = tx.get("motor_specs", [tx.get("motor_spec")] * len(motors))
    if not isinstance(keys, list) or len(keys) != len(motors):
        raise RobotError(f"{what}: field 'motor_specs': expected one spec name per motor ({len(motors)})")
    for motor, key in zip(motors, keys, strict=True):
        if key not in specs:
            raise RobotError(
                f"{what}: motor {motor!r} uses spec {key!r}, which is not in motor_specs ({', '.join(specs)})"
            )
        if motor in out_specs:
            raise RobotError(f"{what}: motor name {motor!r} is used twice; every motor drives one transmission")
        out_specs[motor] = specs[key]
    try:
        if kind == "ratio":
            raw = tx["ratios"]
            ratios = [as_number(g) for g in raw] if isinstance(raw, list) else [None]
            if any(g is None for g in ratios):
                raise RobotError(f"{what}: field 'ratios': found {raw!r}, expected a list of numbers")
            if len(ratios) != len(joints):
                raise RobotError(f"{what}: field 'ratios': {len(ratios)} ratios for {len(joints)} joints")
            return from_ratios(joints, motors, [float(g) for g in ratios if g is not None], what=what)
        if kind == "hollow_shaft":
            if len(joints) != 2:
                raise RobotError(f"{what}: hollow_shaft couples exactly 2 joints (hip, knee), found {len(joints)}")
            gh, gk = as_number(tx["hip_ratio"]), as_number(tx["knee_ratio"])
            if gh is None or gk is None:
                raise RobotError(
                    f"{what}: hip_ratio and knee_ratio must be numbers, found {tx['hip_ratio']!r}, {tx['knee_ratio']!r}"
                )
            return hollow_shaft(joints, motors, gh, gk, what=what)
        rows = tx["matrix"]
        matrix: Any = (
            [[as_number(a) for a in row] for row in rows]
            if isinstance(rows, list) and all(isinstance(row, list) for row in rows)
            else rows
        )
        if isinstance(matrix, list) and any(a is None for row in matrix for a in row):
            raise RobotError(f"{what}: field 'matrix': found {rows!r}, expected a list of rows of numbers")
        return from_matrix(joints, motors, matrix, what=what)
    except TransmissionError as err:
        raise RobotError(str(err), **err.details) from err


def load_robot(path: str | Path) -> Robot:
    """Read and validate a robot YAML file (see module docstring)."""
    p = Path(path)
    return robot_from_mapping(read_yaml(p, "robot"), source=str(p), base=p.parent)
