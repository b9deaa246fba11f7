"""Joint-space operating regions and the rectangular boxes a URDF can hold.

For a transmission group with velocity map A (k joints, k motors) the feasible
joint states are {(tau_j, qd) : (A^T tau_j)_m, (A^-1 qd)_m in MOR_m for every
motor m}: a polytope in 2k dimensions. For each joint hound-id reports

* the **section**: the joint's (tau, qd) region with the other joints of its group
  at zero torque and speed;
* the **projection**: every (tau, qd) the joint can reach for some feasible state
  of the others (exact: the image of the product of the motor polygons);
* the **outer box**: the bounds of the projection, what is reachable at all;
* the **inner box**: the symmetric box |tau_i| <= T_i, |qd_i| <= W_i, for all joints
  of the group at once, every point of which is feasible whatever the coupled
  joints do within their own boxes. Among all such boxes hound-id picks the one of
  largest volume (max sum of log T_i + log W_i, which does not depend on units).
  For an uncoupled motor whose torque limit is below half its stall torque this is
  (torque limit, corner speed) mapped through the gear.

Box containment is exact: for a symmetric box the worst case of each motor
constraint is sum_i |P_mi| T_i + sum_i |Q_mi| W_i (P = A^T, Q = A^-1).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen
from hound_id.errors import RobotError
from hound_id.mor.region import OperatingRegion, halfspace_polygon, largest_box, measured_region, operating_region
from hound_id.mor.region_report import motor_report
from hound_id.mor.robot import Robot
from hound_id.mor.spec import MotorSpec
from hound_id.mor.transmission import Transmission

SCHEMA = "hound-id/mor-robot/1"


@dataclass(frozen=True)
class Box:
    """A symmetric rectangular limit, joint side."""

    effort: float
    """|tau| <= effort [N m]."""
    velocity: float
    """|qd| <= velocity [rad/s]."""

    def to_dict(self) -> dict[str, float]:
        return {"effort": self.effort, "velocity": self.velocity}


@dataclass(frozen=True)
class JointRegion:
    """Operating region of one joint, joint side (N m, rad/s)."""

    joint: str
    """Joint name."""
    motors: tuple[str, ...]
    """Motors of its transmission group."""
    transmission: str
    """Kind of the transmission group."""
    coupled: bool
    """Whether the group couples joints."""
    section: NDArray[np.float64]
    """Vertices (tau, qd), counter-clockwise, with the other joints of the group at rest and unloaded."""
    projection: NDArray[np.float64]
    """Vertices (tau, qd), counter-clockwise, of everything reachable with the others free."""
    inner_box: Box
    """Box whose every point is feasible while the coupled joints stay in their inner boxes, at the battery's lowest
    bus voltage where the motors' specs state a range (``inner_box_bus_voltage``), at 20 degC."""
    outer_box: Box
    """Bounds of the projection (at the nominal bus)."""
    inner_box_bus_voltage: tuple[float, ...] = ()
    """Per motor of the group, the bus voltage [V] the inner box holds at (the lowest of its battery's range, else the
    nominal)."""

    def to_dict(self) -> dict[str, Any]:
        return {
            "joint": self.joint,
            "motors": list(self.motors),
            "transmission": self.transmission,
            "coupled": self.coupled,
            "inner_box": self.inner_box.to_dict(),
            "inner_box_bus_voltage": list(self.inner_box_bus_voltage),
            "outer_box": self.outer_box.to_dict(),
            "section_vertices": self.section.tolist(),
            "projection_vertices": self.projection.tolist(),
        }


@dataclass(frozen=True)
class RobotRegions:
    """Joint-space regions of every joint of a robot, in joint order."""

    robot: str
    joints: tuple[JointRegion, ...]
    motors: tuple[OperatingRegion, ...]
    """Motor regions in motor-vector order."""
    transmissions: tuple[Transmission, ...]
    """Transmission groups."""
    specs: tuple[MotorSpec, ...] = ()
    """Motor specs in motor-vector order."""
    motor_names: tuple[str, ...] = ()
    """Motor instance names in motor-vector order."""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready content, schema ``hound-id/mor-robot/1`` (SI, joint side unless stated)."""
        return {
            "schema": SCHEMA,
            "robot": self.robot,
            "units": {"effort": "N m", "velocity": "rad/s", "motors": "motor side"},
            "joints": [j.to_dict() for j in self.joints],
            "transmissions": [
                {"type": t.kind, "joints": list(t.joints), "motors": list(t.motors), "A": t.A.tolist()}
                for t in self.transmissions
            ],
            "motors": [
                dict(motor_report(spec, region), motor=name)
                for name, spec, region in zip(self.motor_names, self.specs, self.motors, strict=True)
            ],
        }


def _group_constraints(tx: Transmission, regions: list[OperatingRegion]) -> tuple[np.ndarray, np.ndarray]:
    """Rows G, h with G [tau_j; qd] <= h describing the group's feasible joint states."""
    k = len(tx.joints)
    P, Q = tx.A.T, tx.A_inv  # tau_m = P tau_j, omega_m = Q qd
    rows, rhs = [], []
    for m, region in enumerate(regions):
        for a, b in zip(region.A, region.b, strict=True):
            rows.append(np.concatenate([a[0] * P[m], a[1] * Q[m]]))
            rhs.append(b)
    G, h = np.array(rows), np.array(rhs)
    assert G.shape[1] == 2 * k
    return G, h


def _section(tx: Transmission, G: np.ndarray, h: np.ndarray, i: int) -> np.ndarray:
    k = len(tx.joints)
    return halfspace_polygon(G[:, [i, k + i]], h)


def _scaled(tx: Transmission, region: OperatingRegion) -> np.ndarray:
    """An uncoupled joint's region: its motor's vertices (traced, for a measured envelope) through the gear."""
    verts = region.vertices / np.array([tx.A.T[0, 0], tx.A_inv[0, 0]])[None, :]  # tau_j = tau_m / P, qd = w_m / Q
    start = int(np.lexsort((-verts[:, 1], -verts[:, 0]))[0])
    return np.roll(verts, -start, axis=0)


def _projection(tx: Transmission, regions: list[OperatingRegion], i: int) -> np.ndarray:
    """Image of the product of the motor polygons, projected on joint i's (tau, qd)."""
    from scipy.spatial import ConvexHull

    P_inv_row = tx.A_inv.T[i]  # tau_j = A^-T tau_m
    A_row = tx.A[i]  # qd = A omega_m
    points = [
        (float(P_inv_row @ np.array([v[0] for v in combo])), float(A_row @ np.array([v[1] for v in combo])))
        for combo in itertools.product(*(r.vertices for r in regions))
    ]
    pts = np.array(points)
    scale = np.max(np.abs(pts), axis=0)  # hull in units of the extent: torques and speeds differ by 1e12
    unit = np.unique(np.round(pts / scale, 12), axis=0)
    verts = unit[ConvexHull(unit).vertices] * scale
    start = int(np.lexsort((-verts[:, 1], -verts[:, 0]))[0])
    return np.roll(verts, -start, axis=0)


def _inner_boxes(tx: Transmission, regions: list[OperatingRegion]) -> list[Box]:
    """Largest-volume symmetric box per joint contained in the group's feasible set: every row a of every motor's
    region holds at the box's worst corner, |a_tau| sum_i |P_mi| T_i + |a_omega| sum_i |Q_mi| W_i <= b (for a
    measured envelope the rows are a convex cut inside it). An uncoupled joint takes its motor's box."""
    k = len(tx.joints)
    P, Q = np.abs(tx.A.T), np.abs(tx.A_inv)
    if not tx.coupled:  # each joint its own motor's box through its gear (exact for a measured envelope too)
        return [
            Box(effort=float(r.inner_box[0] / P[i, i]), velocity=float(r.inner_box[1] / Q[i, i]))
            for i, r in enumerate(regions)
        ]
    rows, rhs = [], []
    for m, r in enumerate(regions):
        for a_tau, a_omega in _box_rows(r):
            rows.append(np.concatenate([a_tau * P[m], a_omega * Q[m]]))
            rhs.append(1.0)
    try:
        x = largest_box(np.array(rows), np.array(rhs))
    except RobotError as err:
        raise RobotError(f"inner box of {', '.join(tx.joints)}: {err}") from err
    return [Box(effort=float(x[i]), velocity=float(x[k + i])) for i in range(k)]


def _box_rows(region: OperatingRegion) -> np.ndarray:
    """The rows (|a_tau| / b, |a_omega| / b) of a region that can bound a symmetric box, T |a_tau| / b + W |a_omega| / b
    <= 1: a row is implied by the others when its point lies inside the hull of theirs and of the axes' feet (a
    curved edge gives hundreds of rows of which a few bind; the box optimiser works on those)."""
    from scipy.spatial import ConvexHull, QhullError

    points = np.abs(region.A) / region.b[:, None]
    points = points[np.any(points > 0, axis=1)]
    if len(points) <= 3:
        return points
    feet = np.array([[0.0, 0.0], [points[:, 0].max(), 0.0], [0.0, points[:, 1].max()]])
    allp = np.vstack([points, feet])
    scale = allp.max(axis=0)
    scale[scale == 0] = 1.0
    try:
        hull = ConvexHull(allp / scale)
    except QhullError:  # degenerate (all rows on one line): every row
        return points
    keep = [k for k in hull.vertices if k < len(points)]
    return points[np.array(sorted(keep))]


def motor_region(spec: MotorSpec) -> OperatingRegion:
    """The region a motor's limits come from: its measured envelope if the spec carries one, else the spec sheet."""
    return measured_region(spec) if spec.envelope else operating_region(spec)


def robot_regions(robot: Robot) -> RobotRegions:
    """Joint-space regions and URDF boxes for every joint of ``robot``."""
    by_spec: dict[int, OperatingRegion] = {}  # motors sharing a spec share its region
    motor_regions = {}
    for m in robot.motors:
        spec = robot.motor_specs[m]
        if id(spec) not in by_spec:
            by_spec[id(spec)] = motor_region(spec)
        motor_regions[m] = by_spec[id(spec)]
    low: dict[int, OperatingRegion] = {}  # the inner boxes hold at every charge: at the battery's lowest voltage
    low_volts = {}
    for m in robot.motors:
        spec = robot.motor_specs[m]
        volts = spec.bus_voltage_range[0] if spec.bus_voltage_range and spec.envelope is None else spec.bus_voltage
        if id(spec) not in low:
            same = volts == spec.bus_voltage
            low[id(spec)] = by_spec[id(spec)] if same else motor_region(replace(spec, bus_voltage=volts))
        low_volts[m] = volts
    per_joint: dict[str, JointRegion] = {}
    for tx in robot.transmissions:
        regions = [motor_regions[m] for m in tx.motors]
        G, h = _group_constraints(tx, regions)
        boxes = _inner_boxes(tx, [low[id(robot.motor_specs[m])] for m in tx.motors])
        for i, joint in enumerate(tx.joints):
            proj = _projection(tx, regions, i)
            per_joint[joint] = JointRegion(
                joint=joint,
                motors=tx.motors,
                transmission=tx.kind,
                coupled=tx.coupled,
                section=frozen(_section(tx, G, h, i) if tx.coupled else _scaled(tx, regions[0])),
                projection=frozen(proj),
                inner_box=boxes[i],
                outer_box=Box(effort=float(np.max(np.abs(proj[:, 0]))), velocity=float(np.max(np.abs(proj[:, 1])))),
                inner_box_bus_voltage=tuple(low_volts[m] for m in tx.motors),
            )
    return RobotRegions(
        robot=robot.name,
        joints=tuple(per_joint[j] for j in robot.joints),
        motors=tuple(motor_regions[m] for m in robot.motors),
        transmissions=robot.transmissions,
        specs=tuple(robot.motor_specs[m] for m in robot.motors),
        motor_names=robot.motors,
    )
