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

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hound_id.arrays import frozen

if TYPE_CHECKING:  # at run time only motor_report needs the spec module: the saturation (and so the runtime)
    from hound_id.mor.spec import MotorSpec  # imports this module without yaml or pint

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
    source: str = "spec sheet"
    """What bounds the region: ``spec sheet``, or the measured envelope (:func:`measured_region`)."""
    convexity_loss: float = 0.0
    """For a measured envelope: the most the convex region falls inside the polyline edges [N m]."""

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
            "source": self.source,
            "convexity_loss": self.convexity_loss,
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


def measured_region(spec: MotorSpec) -> OperatingRegion:
    """The region a measured envelope (``mor --compare --out``) leaves: the spec sheet's region cut by one
    half-space under each segment of the envelope's polyline edges (over each edge's line extended).

    Where the polyline is convex this is exactly the region between its edges; where it is not (a sagging bus
    bends the motoring edge back towards the spec sheet's line near the no-load speed) the cut is conservative: no
    state outside the polyline is inside, and ``convexity_loss`` says by how much the cut falls short of it.
    Characteristic speeds are read off the polygon; the back-EMF damping stays the spec sheet's.
    """
    sheet = operating_region(spec)
    if spec.envelope is None:
        raise ValueError(f"{spec.name}: the spec carries no measured envelope")
    speeds, lower, upper = spec.envelope.polyline
    rows, rhs, labels = [list(r) for r in sheet.A], list(sheet.b), list(sheet.labels)
    for side, edge in ((1, upper), (-1, lower)):
        for k in range(speeds.size - 1):
            w0, w1, t0, t1 = speeds[k], speeds[k + 1], edge[k], edge[k + 1]
            if not (np.isfinite(t0) and np.isfinite(t1)):
                continue
            slope = (t1 - t0) / (w1 - w0)
            offset = side * (t0 - slope * w0)  # side * tau - side * slope * omega <= offset
            if offset <= 1e-9 * spec.torque_limit:  # a segment through the origin: the speed rows bound it
                continue
            rows.append([float(side), float(-side * slope)])
            rhs.append(float(offset))
            labels.append(f"envelope{'+' if side > 0 else '-'}{k}")
    A, b = np.array(rows), np.array(rhs)
    region = replace(
        sheet,
        A=frozen(A),
        b=frozen(b),
        labels=tuple(labels),
        vertices=frozen(_traced(speeds, lower, upper, sheet)),
        no_load_speed=_crossing(speeds, upper, 0.0, sheet.no_load_speed),
        corner_speed=_crossing(speeds, upper, float(np.nanmax(upper[speeds >= 0])) * (1 - 1e-9), 0.0),
        source=f"measured envelope ({spec.envelope.source})",
    )
    grid = np.linspace(speeds[0], speeds[-1], 4001)
    lo_cut, hi_cut = _slice(grid, region)
    loss = max(
        float(np.nanmax(np.interp(grid, speeds, upper) - hi_cut)),
        float(np.nanmax(lo_cut - np.interp(grid, speeds, lower))),
    )
    return replace(region, convexity_loss=max(loss, 0.0), inner_box=_traced_box(region.vertices))


def _traced_box(vertices: NDArray[np.float64], points: int = 20001) -> tuple[float, float]:
    """Largest-area symmetric box (torque [N m], speed [rad/s]) inside a region traced by ``vertices`` (convex or
    not): at half-width W the torque half-width is the least of hi(w) and -lo(w) over |w| <= W.

    The speeds are searched on a grid over the whole region, then twice more between the best point's neighbours,
    so that a region much wider than its box (a peak torque far above the stall torque) is resolved too. The edges
    are linear between vertex speeds, so the least half-width below a speed is at 0 or at a vertex speed."""
    ring = np.vstack([vertices, vertices[:1]])
    top = float(np.abs(vertices[:, 1]).max())
    grid = np.unique(np.concatenate([np.linspace(0.0, top, points), np.abs(vertices[:, 1])]))
    best = (0.0, 0.0)
    for _ in range(3):
        T = _box_torques(ring, grid)
        k = int(np.argmax(T * grid))
        if T[k] * grid[k] >= best[0] * best[1]:
            best = (float(T[k]), float(grid[k]))
        a, b = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
        # the edges are linear between vertex speeds: the least half-width below a is at 0 or a vertex speed
        corners = np.abs(vertices[:, 1])
        grid = np.unique(np.concatenate([[0.0], corners[corners < a], np.linspace(a, b, points)]))
    return best


def _box_torques(ring: NDArray[np.float64], W: NDArray[np.float64]) -> NDArray[np.float64]:
    """Torque half-width of the largest symmetric box of speed half-width ``W`` (sorted, from 0) in ``ring``."""
    both = np.concatenate([-W[::-1], W])
    hi = np.full(both.size, np.inf)
    lo = np.full(both.size, -np.inf)
    for (t0, w0), (t1, w1) in zip(ring[:-1], ring[1:], strict=True):  # each edge bounds the torque at its speeds
        if w0 == w1:
            continue
        on = (both >= min(w0, w1)) & (both <= max(w0, w1))
        t = t0 + (both[on] - w0) * (t1 - t0) / (w1 - w0)
        if w1 > w0:  # counter-clockwise: rising speed is the right (upper torque) side
            hi[on] = np.minimum(hi[on], t)
        else:
            lo[on] = np.maximum(lo[on], t)
    half = np.minimum(hi, -lo)
    T = np.minimum(np.minimum.accumulate(half[W.size :]), np.minimum.accumulate(half[: W.size][::-1]))
    return np.asarray(np.maximum(T, 0.0), float)


def _traced(
    speeds: NDArray[np.float64], lower: NDArray[np.float64], upper: NDArray[np.float64], sheet: OperatingRegion
) -> NDArray[np.float64]:
    """Vertices (tau, omega), counter-clockwise from the largest torque, of the region between the polyline's edges
    within its speeds and the spec sheet's region beyond them."""
    beyond = sheet.vertices[(sheet.vertices[:, 1] < speeds[0]) | (sheet.vertices[:, 1] > speeds[-1]), 1]
    w = np.unique(np.concatenate([speeds, beyond, [min(speeds[0], sheet.vertices[:, 1].min())]]))
    lo, hi = torque_interval(w, sheet)
    inside = (w >= speeds[0]) & (w <= speeds[-1])
    lo = np.where(inside, np.interp(w, speeds, lower), lo)
    hi = np.where(inside, np.interp(w, speeds, upper), hi)
    ok = np.isfinite(lo) & np.isfinite(hi) & (lo <= hi + 1e-12)
    w, lo, hi = w[ok], lo[ok], hi[ok]
    ring = np.vstack([np.column_stack([hi, w]), np.column_stack([lo, w])[::-1]])
    scale = np.abs(ring).max(axis=0)
    unit = ring / scale
    # drop repeated points and points on the straight line through their neighbours (flat torque limits)
    keep = np.any(np.abs(unit - np.roll(unit, 1, axis=0)) > 1e-9, axis=1)
    unit = unit[keep]
    before, after = np.roll(unit, 1, axis=0), np.roll(unit, -1, axis=0)
    cross = (unit[:, 0] - before[:, 0]) * (after[:, 1] - before[:, 1]) - (unit[:, 1] - before[:, 1]) * (
        after[:, 0] - before[:, 0]
    )
    ring = unit[np.abs(cross) > 1e-9] * scale
    start = int(np.lexsort((-ring[:, 1], -ring[:, 0]))[0])  # max torque, then max speed
    return np.roll(ring, -start, axis=0)


def _crossing(speeds: NDArray[np.float64], edge: NDArray[np.float64], level: float, default: float) -> float:
    """The first speed >= 0 [rad/s] at which ``edge`` falls to ``level`` (linear between points), or ``default``."""
    ok = np.isfinite(edge) & (speeds >= 0)
    w, t = speeds[ok], edge[ok]
    below = np.flatnonzero(t <= level)
    if below.size == 0 or w.size < 2:
        return default
    k = int(below[0])
    if k == 0:
        return float(w[0])
    return float(w[k - 1] + (level - t[k - 1]) * (w[k] - w[k - 1]) / (t[k] - t[k - 1]))


def _slice(omega: NDArray[np.float64], region: OperatingRegion) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Torque interval [N m] of a region's half-spaces at each speed [rad/s] (NaN where empty)."""
    a_tau, a_w = region.A[:, 0], region.A[:, 1]
    room = region.b[None, :] - a_w[None, :] * omega[:, None]  # a_tau tau <= room
    with np.errstate(divide="ignore", invalid="ignore"):
        hi = np.min(np.where(a_tau > 0, room / a_tau, np.inf), axis=1)
        lo = np.max(np.where(a_tau < 0, room / a_tau, -np.inf), axis=1)
        free = np.all(np.where(a_tau == 0, room >= 0, True), axis=1)
    empty = (lo > hi) | ~free
    return np.where(empty, np.nan, lo), np.where(empty, np.nan, hi)


def box_in(A: ArrayLike, b: ArrayLike) -> tuple[float, float]:
    """Largest-area symmetric box (torque [N m], speed [rad/s]) inside {x : A x <= b}: every row must hold at the
    box's worst corner, |a_tau| T + |a_omega| W <= b."""
    T, W = largest_box(np.abs(np.asarray(A, float)), np.asarray(b, float))
    return float(T), float(W)


def largest_box(M: ArrayLike, c: ArrayLike) -> NDArray[np.float64]:
    """The positive x of largest product (max sum of log x, which no choice of units changes) with M x <= c,
    M >= 0 elementwise, c > 0: the half-widths of the largest box whose every corner meets the rows."""
    from scipy.optimize import minimize

    from hound_id.errors import RobotError

    Mn = np.asarray(M, float) / np.asarray(c, float)[:, None]  # every row reads Mn exp(y) <= 1
    start = np.log(0.1 / (2 * Mn.shape[1]) / Mn.max(axis=0))  # inside: a small share of what each row allows
    res = minimize(
        lambda y: -float(np.sum(y)),
        start,
        jac=lambda y: -np.ones_like(y),
        constraints=[
            {"type": "ineq", "fun": lambda y: 1.0 - Mn @ np.exp(y), "jac": lambda y: -Mn * np.exp(y)[None, :]}
        ],
        method="SLSQP",
        options={"maxiter": 500, "ftol": 1e-12},
    )
    worst = float(np.max(Mn @ np.exp(res.x)))
    if not res.success or not np.isfinite(worst):
        raise RobotError(f"largest box: optimiser failed ({res.message})")
    return np.exp(res.x) / max(worst, 1.0)  # a hair of infeasibility from the solver: shrink onto the boundary


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
