"""The motor operating region (MOR) of the paper, motor side.

For x = (tau, omega) the quasi-static DC model gives (paper, eq. 2)

    -V_bus <= (R/Kt) tau + omega/Kv <= V_bus,

intersected with |tau| <= tau_lim, where tau_lim = min(tau_peak, Kt i_max), and
with |omega| <= omega_max when the spec gives a maximum speed. The band between
the voltage lines is a parallelogram; cut by the torque limits it is a hexagon,
wider in the braking quadrants (2 and 4), where back-EMF adds to the bus.

Characteristic values (physics notes): stall torque Kt V/R, no-load speed Kv V,
corner speed Kv (V - R tau_lim/Kt) (the highest speed with full motoring torque;
clipped to [0, max_speed]: 0 when the torque limit exceeds the stall torque),
overspeed Kv (V + R tau_lim/Kt) (past it not even full braking torque keeps the
current inside its limit; see :func:`torque_interval` for what the saturation
returns there).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hound_id.arrays import frozen
from hound_id.mor.spec import MotorSpec

SCHEMA = "hound-id/mor/1"

#: Relative tolerance on the rated maximum speed before the braking-only rule applies,
#: so states computed on the boundary (polygon vertices) count as inside.
SPEED_TOLERANCE = 1e-9


@dataclass(frozen=True)
class OperatingRegion:
    """The convex operating region of one motor in (torque, speed), motor side, SI units."""

    motor: str
    """Name of the motor."""
    A: NDArray[np.float64]
    """Half-space normals, shape (m, 2), rows (a_tau, a_omega); the region is A x <= b."""
    b: NDArray[np.float64]
    """Half-space offsets, shape (m,); units follow each row (V, N m or rad/s)."""
    labels: tuple[str, ...]
    """Name of each half-space row (voltage+, voltage-, torque+, torque-, speed+, speed-)."""
    vertices: NDArray[np.float64]
    """Polygon vertices (tau [N m], omega [rad/s]), counter-clockwise, shape (k, 2)."""
    stall_torque: float
    """Kt V_bus / R [N m]: torque on the voltage line at zero speed."""
    no_load_speed: float
    """Kv V_bus [rad/s]: speed on the voltage line at zero torque."""
    corner_speed: float
    """Highest speed at which the full torque limit can motor [rad/s]: Kv (V_bus - R tau_lim / Kt)
    clipped to [0, max_speed] (0 when the torque limit exceeds the stall torque)."""
    overspeed: float
    """Kv (V_bus + R tau_lim / Kt) [rad/s]: beyond it the full braking torque exceeds the voltage line."""
    torque_limit: float
    """tau_lim = min(peak torque, Kt i_max) [N m]."""
    max_speed: float | None
    """Rated maximum speed [rad/s] if the spec gives one."""
    back_emf_damping: float
    """Slope of the voltage lines, Kt / (R Kv) [N m s/rad]."""
    inner_box: tuple[float, float]
    """Largest-area symmetric box (torque [N m], speed [rad/s]) inside the region."""

    def contains(self, tau: ArrayLike, omega: ArrayLike, rtol: float = 1e-9) -> NDArray[np.bool_]:
        """Whether each (tau [N m], omega [rad/s]) pair lies in the region (with a relative tolerance)."""
        x = np.stack(np.broadcast_arrays(np.asarray(tau, float), np.asarray(omega, float)), axis=-1)
        slack = x @ self.A.T - self.b
        return np.all(slack <= rtol * np.maximum(self.b, 1.0), axis=-1)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready content, schema ``hound-id/mor/1`` (SI, motor side)."""
        return {
            "schema": SCHEMA,
            "motor": self.motor,
            "halfspaces": {"A": self.A.tolist(), "b": self.b.tolist(), "labels": list(self.labels)},
            "vertices": self.vertices.tolist(),
            "stall_torque": self.stall_torque,
            "no_load_speed": self.no_load_speed,
            "corner_speed": self.corner_speed,
            "overspeed": self.overspeed,
            "torque_limit": self.torque_limit,
            "max_speed": self.max_speed,
            "back_emf_damping": self.back_emf_damping,
            "inner_box": {"torque": self.inner_box[0], "speed": self.inner_box[1]},
            "units": {"torque": "N m", "speed": "rad/s", "voltage rows": "V"},
        }


def motor_report(spec: MotorSpec, region: OperatingRegion | None = None) -> dict[str, Any]:
    """The ``hound-id/mor/1`` content for a motor: its region, its spec (SI) and the spec's warnings."""
    from hound_id.mor.spec import spec_warnings

    data = (region or operating_region(spec)).to_dict()
    data.update(spec=spec.to_dict(), warnings=list(spec_warnings(spec)))
    return data


def halfspace_polygon(A: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Vertices (counter-clockwise) of the bounded 2-D polygon {x : A x <= b}.

    Rows whose normal is zero are dropped (they must then have b >= 0). The
    polygon must contain the origin strictly (b > 0), which holds for every
    region hound-id builds since all limits are positive.
    """
    from scipy.spatial import ConvexHull, HalfspaceIntersection

    normals = np.asarray(A, float)
    offsets = np.asarray(b, float)
    keep = np.linalg.norm(normals, axis=1) > 1e-14 * max(1.0, float(np.abs(normals).max(initial=0.0)))
    normals, offsets = normals[keep], offsets[keep]
    if np.any(offsets <= 0):
        raise ValueError("halfspace_polygon needs the origin strictly inside (all b > 0)")
    # Work in axes scaled to the polygon's extent (torques of 1e-3..1e3 N m against speeds of
    # 1e-3..1e4 rad/s) and with unit normals, so qhull sees a well-shaped problem.
    with np.errstate(divide="ignore"):
        reach = np.where(np.abs(normals) > 0, offsets[:, None] / np.abs(normals), np.inf)
    axis_scale = reach.min(axis=0)
    if not np.all(np.isfinite(axis_scale)):
        raise ValueError("halfspace_polygon needs a bounded polygon")
    scaled = normals * axis_scale[None, :]
    norm = np.linalg.norm(scaled, axis=1)
    hs = np.column_stack([scaled / norm[:, None], -offsets / norm])
    points = HalfspaceIntersection(hs, np.zeros(2)).intersections
    hull = ConvexHull(points)
    verts = points[hull.vertices] * axis_scale[None, :]  # counter-clockwise for 2-D hulls (scaling keeps it)
    start = int(np.lexsort((-verts[:, 1], -verts[:, 0]))[0])  # max torque, then max speed
    return np.roll(verts, -start, axis=0)


def operating_region(spec: MotorSpec) -> OperatingRegion:
    """Build the operating region of a motor from its spec."""
    r_over_kt = spec.resistance / spec.kt
    inv_kv = 1.0 / spec.kv
    tau_lim = spec.torque_limit
    rows = [
        ("voltage+", (r_over_kt, inv_kv), spec.bus_voltage),
        ("voltage-", (-r_over_kt, -inv_kv), spec.bus_voltage),
        ("torque+", (1.0, 0.0), tau_lim),
        ("torque-", (-1.0, 0.0), tau_lim),
    ]
    if spec.max_speed is not None:
        rows += [("speed+", (0.0, 1.0), spec.max_speed), ("speed-", (0.0, -1.0), spec.max_speed)]
    A = np.array([r[1] for r in rows])
    b = np.array([r[2] for r in rows])
    corner = max(spec.kv * (spec.bus_voltage - r_over_kt * tau_lim), 0.0)
    if spec.max_speed is not None:
        corner = min(corner, spec.max_speed)
    return OperatingRegion(
        motor=spec.name,
        A=frozen(A),
        b=frozen(b),
        labels=tuple(r[0] for r in rows),
        vertices=frozen(halfspace_polygon(A, b)),
        stall_torque=spec.stall_torque,
        no_load_speed=spec.no_load_speed,
        corner_speed=corner,
        overspeed=spec.kv * (spec.bus_voltage + r_over_kt * tau_lim),
        torque_limit=tau_lim,
        max_speed=spec.max_speed,
        back_emf_damping=spec.back_emf_damping,
        inner_box=_inner_box(spec.stall_torque, spec.no_load_speed, tau_lim, spec.max_speed),
    )


def _inner_box(stall: float, no_load: float, tau_lim: float, max_speed: float | None) -> tuple[float, float]:
    """Max T*W with T <= tau_lim, W <= max_speed and T/stall + W/no_load <= 1 (the voltage line).

    On the voltage line T W is largest at T = stall/2; the torque and speed limits
    clip that point along the line. If the corner (tau_lim, max_speed) lies inside
    the voltage band, the box is the full rectangle.
    """
    w_max = np.inf if max_speed is None else max_speed
    if tau_lim / stall + w_max / no_load <= 1.0:
        return tau_lim, float(w_max)
    t_low = max(stall * (1.0 - w_max / no_load), 0.0)  # below this torque the speed limit binds
    torque = float(np.clip(stall / 2.0, t_low, tau_lim))
    speed = float(min(no_load * (1.0 - torque / stall), w_max))
    return torque, speed


def torque_interval(omega: ArrayLike, region: OperatingRegion) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Feasible motor torque interval [lo, hi] at speed ``omega`` [rad/s].

    Inside |omega| <= overspeed this is exactly the region's slice at that speed.
    Past overspeed the slice is empty; the interval collapses to the full braking
    torque, -sign(omega) tau_lim, which is what a current-limited drive applies
    when the back-EMF outruns the bus (and what Isaac Lab's ``DCMotor`` returns).
    Past ``max_speed`` (if given) only braking torque (sign opposite to omega, or
    zero) passes, as a drive's speed limiter does.
    """
    omega = np.asarray(omega, float)
    tl = region.torque_limit
    lo = np.clip(-region.stall_torque - region.back_emf_damping * omega, -tl, tl)
    hi = np.clip(region.stall_torque - region.back_emf_damping * omega, -tl, tl)
    if region.max_speed is not None:
        limit = region.max_speed * (1.0 + SPEED_TOLERANCE)
        hi = np.where(omega > limit, np.minimum(hi, 0.0), hi)
        lo = np.where(omega < -limit, np.maximum(lo, 0.0), lo)
    return lo, hi
