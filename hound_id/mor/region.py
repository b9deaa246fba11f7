"""The motor operating region (MOR) of the paper, motor side.

For x = (tau, omega) the quasi-static DC model gives (paper, eq. 2)

    -V_bus <= R i(tau) + omega/Kv <= V_bus,    |i(tau)| <= i_max,    |tau| <= tau_peak,

with i(tau) the current the motor's current-torque curve needs for the torque
(:mod:`hound_id.mor.current_curve`: the fit's curve, or the quadratic through the spec
sheet's 20 % point), and |omega| <= omega_max when the spec gives a maximum speed. So at
each speed the current lies in a window, [(-V - omega/Kv)/R, (V - omega/Kv)/R] cut to
+-I (I the current the torque limit needs), and the torque interval is the curve's image
of that window. With a linear curve (i = tau/Kt) the region is the paper's hexagon: the
band between the voltage lines cut by |tau| <= min(tau_peak, Kt i_max). With a
saturating curve the torque limit is the curve's torque at the driver's limit,
tau_lim = min(tau_peak, g(i_max)), and the voltage edges bend: they are polylines here
(refined to :data:`EDGE_TOLERANCE` of the torque limit), concave where the motor drives
and convex in the braking quadrants past the no-load speed; the half-spaces are then a
conservative convex cut and ``convexity_loss`` says by how much.

Characteristic values (physics notes): no-load speed Kv V; corner speed Kv (V - R I)
(the highest speed with full motoring torque; clipped to [0, max_speed]: 0 when I
exceeds the stall current V/R); overspeed Kv (V + R I): past it even the full
opposing voltage cannot hold the current at I, and the back-EMF drives a braking
current of at least (omega/Kv - V)/R through the inverter whatever is commanded
(:func:`torque_interval` returns that torque there).

What ``mor --spec`` reports of a region (bindings, the region at speed, the linear-Kt over-promise, the
straight-line gap) is in :mod:`hound_id.mor.region_report`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hound_id.arrays import frozen
from hound_id.mor.current_curve import CurrentCurve
from hound_id.mor.drive import Drive, dq_window

if TYPE_CHECKING:  # at run time only motor_report needs the spec module: the saturation (and so the runtime)
    from hound_id.mor.spec import MotorSpec  # imports this module without yaml or pint


SCHEMA = "hound-id/mor/3"


#: Relative tolerance on the rated maximum speed before the braking-only rule applies,
#: so states computed on the boundary (polygon vertices) count as inside.
SPEED_TOLERANCE = 1e-9
#: Accuracy of a curved region's polyline edges, as a share of the torque limit: linear interpolation between its
#: points misses the exact edge by at most this (1e-4: 0.8 mN m for the sample motor, far below any torque sensor).
EDGE_TOLERANCE = 1e-4
#: A polyline segment shorter than this share of the speed range is a step in the edge (the braking-only cut at the
#: rated speed), not a slope: it gives no half-space (the speed rows bound it).
STEP_SPAN = 1e-7
#: The curved edges are refined by halving any segment that misses at its midpoint, at most so many times.
EDGE_REFINEMENTS = 20


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
    """Highest speed at which the full torque limit can motor [rad/s]: Kv (V_bus - R I), I the current the torque
    limit needs, clipped to [0, max_speed] (0 when I exceeds the stall current V_bus / R)."""
    overspeed: float
    """Kv (V_bus + R I) [rad/s]: beyond it even the full opposing voltage cannot hold the current at I."""
    torque_limit: float
    """tau_lim = min(peak torque, g(i_max)) [N m], g the current-torque curve (Kt i_max for a linear one)."""
    max_speed: float | None
    """Rated maximum speed [rad/s] if the spec gives one."""
    back_emf_damping: float
    """Slope of the voltage lines, Kt / (R Kv) [N m s/rad]."""
    inner_box: tuple[float, float]
    """Largest-area symmetric box (torque [N m], speed [rad/s]) inside the region."""
    source: str = "spec sheet"
    """What bounds the region: ``spec sheet``, or the measured envelope (:func:`measured_region`)."""
    convexity_loss: float = 0.0
    """For curved or measured edges: the most the convex half-space cut falls inside the edges [N m]."""
    curve: CurrentCurve | None = None
    """The current-torque curve the edges follow (None: linear, tau = Kt i)."""
    linear_limit: float | None = None
    """Kt I [N m]: the linear-equivalent torque of the current the torque limit needs (None: the torque limit)."""
    linear_torque_limit: float | None = None
    """What a linear-Kt model takes for the torque limit, min(peak torque, Kt i_max) [N m] (None: the same)."""
    drive: Drive | None = None
    """The drive's dq model (winding reactance, field weakening) the edges follow; None: the DC law."""

    @property
    def limit_x(self) -> float:
        """Kt I [N m] (:attr:`linear_limit`, or the torque limit for a linear region)."""
        return self.torque_limit if self.linear_limit is None else self.linear_limit

    def contains(self, tau: ArrayLike, omega: ArrayLike, rtol: float = 1e-9) -> NDArray[np.bool_]:
        """Whether each (tau [N m], omega [rad/s]) pair lies in the region (with a relative tolerance)."""
        x = np.stack(np.broadcast_arrays(np.asarray(tau, float), np.asarray(omega, float)), axis=-1)
        slack = x @ self.A.T - self.b
        return np.all(slack <= rtol * np.maximum(self.b, 1.0), axis=-1)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready content, schema ``hound-id/mor/3`` (SI, motor side; /2 added the current-torque curve, the
        limit current and the linear-Kt torque limit, and the curve-limited torque limit replaced Kt i_max; /3 the
        drive's dq model, ``drive``, null for the DC law)."""
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
            "current_curve": None if self.curve is None else self.curve.to_dict(),
            "limit_current": None if self.curve is None else self.limit_x / self.curve.kt,
            "linear_torque_limit": self.torque_limit if self.linear_torque_limit is None else self.linear_torque_limit,
            "drive": None if self.drive is None else self.drive.to_dict(),
            "units": {"torque": "N m", "speed": "rad/s", "voltage rows": "V", "current": "A"},
        }


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
    """The operating region of a motor from its spec and its current-torque curve (module docstring)."""
    curve = spec.current_curve
    if spec.drive is not None:
        return drive_region(spec)
    if curve.form == "linear":
        return replace(linear_region(spec), curve=curve)
    base = _curve_base(spec)
    tl, X, stall, damping = base.torque_limit, base.limit_x, base.stall_torque, base.back_emf_damping
    corner = max((stall - X) / damping, 0.0)
    if spec.max_speed is not None:
        corner = min(corner, spec.max_speed)
    base = replace(base, corner_speed=corner, overspeed=(stall + X) / damping)
    speeds, lower, upper = curved_edges(base)
    # The half-spaces: the edges' segments where they are concave (the upper edge up to the no-load speed, where the
    # current is positive; the lower edge likewise), and past them the voltage lines, tau <= S - D omega, which touch
    # the curved edges at the no-load speeds and lie inside them beyond (a curve bends away from its tangent there).
    nl = stall / damping
    rows: list[tuple[str, tuple[float, float], float]] = [
        ("voltage+", (1.0, damping), stall),
        ("voltage-", (-1.0, -damping), stall),
        ("torque+", (1.0, 0.0), tl),
        ("torque-", (-1.0, 0.0), tl),
    ]
    if spec.max_speed is not None:
        rows += [("speed+", (0.0, 1.0), spec.max_speed), ("speed-", (0.0, -1.0), spec.max_speed)]
    cut_upper = np.where(speeds <= nl * (1 + 1e-12), upper, np.nan)
    cut_lower = np.where(speeds >= -nl * (1 + 1e-12), lower, np.nan)
    region = _cut(base, rows, speeds, cut_lower, cut_upper, "curve", edges=(lower, upper))
    vertices = _ring(speeds, lower, upper)
    return replace(region, vertices=frozen(vertices), inner_box=_traced_box(vertices))


def _curve_base(spec: MotorSpec) -> OperatingRegion:
    """The linear region with the current-torque curve's limits in the linear-equivalent torque x = Kt i: the torque
    limit, X = Kt I (I the current it needs), the stall torque Kt V / R and the back-EMF damping Kt / (R Kv), Kt the
    curve's (the edges and characteristic speeds are the caller's)."""
    curve = spec.current_curve
    return replace(
        linear_region(spec),
        torque_limit=spec.torque_limit,
        stall_torque=curve.kt * spec.bus_voltage / spec.resistance,  # Kt times the stall current V/R
        back_emf_damping=curve.kt / (spec.resistance * spec.kv),
        curve=curve,
        linear_limit=curve.kt * spec.limit_current,
        linear_torque_limit=spec.linear_torque_limit,
    )


#: The drive region's characteristic speeds are searched up to this many DC no-load speeds (past it a drive with field
#: weakening is taken to hold control: the short-circuit current lies within its current circle).
DRIVE_SEARCH_REACH = 8.0
#: Grid points of that search before each crossing is bisected to rounding.
DRIVE_SEARCH_POINTS = 4001


def drive_region(spec: MotorSpec, bus_voltage: float | None = None) -> OperatingRegion:
    """The operating region under the drive's dq model (:mod:`hound_id.mor.drive`): the winding's reactance and,
    where the spec says so, field weakening. The edges are curves (polylines refined to :data:`EDGE_TOLERANCE`); the
    half-spaces are one under each segment within control (a conservative cut where an edge is convex:
    ``convexity_loss``). Corner speed (full torque), no-load speed (the motoring edge reaches zero: Kv V without
    field weakening, beyond with it) and overspeed (the drive loses control: the diode bridge's braking from there)
    are the edges' crossings, found on a grid and bisected. ``bus_voltage`` [V] replaces the spec's."""
    if bus_voltage is not None:
        spec = replace(spec, bus_voltage=bus_voltage)
    if spec.drive is None:
        raise ValueError(f"{spec.name}: the spec has no drive model (inductance with pole pairs, or field weakening)")
    base = _curve_base(spec)
    linear = base.curve is not None and base.curve.form == "linear"
    base = replace(base, curve=None if linear else base.curve, drive=spec.drive)
    tl = base.torque_limit
    corner, no_load, over = _drive_speeds(base)
    if spec.max_speed is not None:
        corner = min(corner, spec.max_speed)
    base = replace(base, corner_speed=corner, no_load_speed=no_load, overspeed=over)
    speeds, lower, upper = curved_edges(base)
    rows: list[tuple[str, tuple[float, float], float]] = [
        ("torque+", (1.0, 0.0), tl),
        ("torque-", (-1.0, 0.0), tl),
        ("speed+", (0.0, 1.0), spec.max_speed if spec.max_speed is not None else over),
        ("speed-", (0.0, -1.0), spec.max_speed if spec.max_speed is not None else over),
    ]
    held = lower < upper  # within control (past it the window is the diode bridge's one torque)
    lower, upper = np.where(held, lower, np.nan), np.where(held, upper, np.nan)
    region = _cut(base, rows, speeds, lower, upper, "drive")
    vertices = _ring(speeds, lower, upper)
    return replace(region, vertices=frozen(vertices), inner_box=_traced_box(vertices))


def _drive_speeds(region: OperatingRegion) -> tuple[float, float, float]:
    """(corner, no-load, overspeed) [rad/s] of a drive region: the first speeds >= 0 at which the upper window falls
    below the full current, reaches zero, and at which control is lost (the window collapses onto the diode's
    braking). One window on a grid for all three, then each crossing bisected to rounding."""
    X = region.limit_x
    tests = (
        lambda lo, hi: hi < X * (1.0 - 1e-12),  # below the full current
        lambda lo, hi: hi <= 0.0,  # motoring gone
        lambda lo, hi: lo >= hi,  # control lost
    )
    grid = np.linspace(0.0, DRIVE_SEARCH_REACH * region.stall_torque / region.back_emf_damping, DRIVE_SEARCH_POINTS)
    lo, hi = current_window(grid, region)
    out = []
    for test in tests:
        hit = np.flatnonzero(test(lo, hi))
        if hit.size == 0:
            out.append(float(grid[-1]))
            continue
        k = int(hit[0])
        if k == 0:
            out.append(0.0)
            continue
        a, b = float(grid[k - 1]), float(grid[k])
        for _ in range(60):
            mid = 0.5 * (a + b)
            if mid in (a, b):
                break
            if test(*current_window(np.array([mid]), region))[0]:
                b = mid
            else:
                a = mid
        out.append(b)
    return out[0], out[1], out[2]


def linear_region(spec: MotorSpec) -> OperatingRegion:
    """The paper's hexagon with linear Kt: what the region would be if torque followed current, tau = Kt i, up to
    min(peak torque, Kt i_max). :func:`operating_region` is this region for a linear curve; for a saturating one
    it shows how much the linear model over-promises."""
    r_over_kt = spec.resistance / spec.kt
    tau_lim = spec.linear_torque_limit
    rows = [
        ("voltage+", (r_over_kt, 1.0 / spec.kv), spec.bus_voltage),
        ("voltage-", (-r_over_kt, -1.0 / spec.kv), spec.bus_voltage),
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


def curved_edges(
    region: OperatingRegion, reach: float | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(speeds [rad/s], lower [N m], upper [N m]) of a region's edges from -``reach`` to +``reach`` (default the
    overspeed; past it both edges are the forced braking torque), refined until
    linear interpolation misses :func:`torque_interval` by at most :data:`EDGE_TOLERANCE` x the torque limit at
    every segment's midpoint. The breakpoints of the edges (the corner speeds, where the current limit stops
    binding; the no-load speeds; the rated speeds) are points of the polyline."""
    d, stall, X = region.back_emf_damping, region.stall_torque, region.limit_x
    top = region.overspeed if reach is None else reach
    marks = [(stall - X) / d, stall / d, (stall + X) / d]  # mirrored below
    if region.drive is not None:  # the last point within control, and where it is lost (the window collapses)
        marks = [region.corner_speed, region.no_load_speed, region.overspeed * (1 - 1e-9), region.overspeed]
    if region.max_speed is not None:
        marks += [region.max_speed, region.max_speed * (1 + 2 * SPEED_TOLERANCE)]
    marks = [m for m in marks if abs(m) < top]
    speeds = np.unique(np.concatenate([np.linspace(-top, top, 17), marks, np.negative(marks)]))
    tol = EDGE_TOLERANCE * region.torque_limit
    for _ in range(EDGE_REFINEMENTS):
        lo, hi = torque_interval(speeds, region)
        mid = 0.5 * (speeds[:-1] + speeds[1:])
        mlo, mhi = torque_interval(mid, region)
        miss = np.maximum(np.abs(0.5 * (hi[:-1] + hi[1:]) - mhi), np.abs(0.5 * (lo[:-1] + lo[1:]) - mlo))
        bad = miss > tol
        if not bad.any():
            break
        speeds = np.sort(np.concatenate([speeds, mid[bad]]))
    lo, hi = torque_interval(speeds, region)
    return frozen(speeds), frozen(lo), frozen(hi)


def _cut(
    base: OperatingRegion,
    rows: list[tuple[str, tuple[float, float], float]],
    speeds: NDArray[np.float64],
    lower: NDArray[np.float64],
    upper: NDArray[np.float64],
    name: str,
    edges: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
) -> OperatingRegion:
    """``base`` with half-spaces ``rows`` plus one under each segment of the polyline edges (over each edge's line
    extended; segments with a NaN end give none), labelled ``name+k`` / ``name-k``, and the most the cut falls inside
    the region's ``edges`` (lower, upper; default the polyline's) as ``convexity_loss``."""
    A_rows = [list(r[1]) for r in rows]
    rhs = [float(r[2]) for r in rows]
    labels = [r[0] for r in rows]
    for side, edge in ((1, upper), (-1, lower)):
        for k in range(speeds.size - 1):
            w0, w1, t0, t1 = speeds[k], speeds[k + 1], edge[k], edge[k + 1]
            if not (np.isfinite(t0) and np.isfinite(t1)) or w1 - w0 <= STEP_SPAN * (speeds[-1] - speeds[0]):
                continue  # no edge there, or a step (the rated speed's braking-only cut): the other rows bound it
            slope = (t1 - t0) / (w1 - w0)
            offset = side * (t0 - slope * w0)  # side * tau - side * slope * omega <= offset
            if offset <= 1e-9 * base.torque_limit:  # a segment through the origin: the other rows bound it
                continue
            A_rows.append([float(side), float(-side * slope)])
            rhs.append(float(offset))
            labels.append(f"{name}{'+' if side > 0 else '-'}{k}")
    region = replace(base, A=frozen(np.array(A_rows)), b=frozen(np.array(rhs)), labels=tuple(labels))
    grid = np.linspace(speeds[0], speeds[-1], 4001)
    lo_cut, hi_cut = _slice(grid, region)
    true_lo, true_hi = edges if edges is not None else (lower, upper)
    with np.errstate(invalid="ignore"):
        loss = max(
            float(np.nanmax(np.interp(grid, speeds, true_hi) - hi_cut, initial=0.0)),
            float(np.nanmax(lo_cut - np.interp(grid, speeds, true_lo), initial=0.0)),
        )
    return replace(region, convexity_loss=max(loss, 0.0))


#: Points of a traced ring closer than this (relative to the ring's extent in torque and speed) are one vertex.
RING_MERGE = 1e-9
#: A point whose cross product with its neighbours (relative coordinates) is below this lies on their straight line.
RING_STRAIGHT = 1e-9


def _ring(speeds: NDArray[np.float64], lower: NDArray[np.float64], upper: NDArray[np.float64]) -> NDArray[np.float64]:
    """Vertices (tau, omega), counter-clockwise from the largest torque, of the region between two edges."""
    ok = np.isfinite(lower) & np.isfinite(upper) & (lower <= upper + 1e-12)
    w, lo, hi = speeds[ok], lower[ok], upper[ok]
    ring = np.vstack([np.column_stack([hi, w]), np.column_stack([lo, w])[::-1]])
    scale = np.abs(ring).max(axis=0)
    unit = ring / scale
    # drop repeated points, then walk the ring dropping each point on the straight line from the last point kept to
    # the next (flat torque limits); measured from the last point kept, a cluster of nearly coincident points (where an
    # edge's slope grows without bound, as at the drive's loss of control) cannot hide the corner it ends in
    keep = np.any(np.abs(unit - np.roll(unit, 1, axis=0)) > RING_MERGE, axis=1)
    unit = unit[keep]
    kept = [0]
    for k in range(1, len(unit)):
        a, p, b = unit[kept[-1]], unit[k], unit[(k + 1) % len(unit)]
        if abs((p[0] - a[0]) * (b[1] - a[1]) - (p[1] - a[1]) * (b[0] - a[0])) > RING_STRAIGHT:
            kept.append(k)
    ring = unit[kept] * scale
    start = int(np.lexsort((-ring[:, 1], -ring[:, 0]))[0])  # max torque, then max speed
    return np.roll(ring, -start, axis=0)


def measured_region(spec: MotorSpec) -> OperatingRegion:
    """The region a measured envelope (``mor --compare --out``) leaves: the spec sheet's region cut by one
    half-space under each segment of the envelope's polyline edges (over each edge's line extended).

    Where the polyline is convex this is exactly the region between its edges; where it is not (a sagging bus
    bends the motoring edge back towards the spec sheet's line near the no-load speed) the cut is conservative: no
    state outside the polyline is inside, and ``convexity_loss`` says by how much the cut falls short of it.
    Characteristic speeds are read off the polygon; the back-EMF damping stays the spec sheet's.

    The envelope's model (:mod:`hound_id.mor.envelope`) starts from the linear-Kt region (a measured curve enters
    it as the ``kt_saturation`` effect), so the sheet here is :func:`linear_region`.
    """
    sheet = linear_region(spec)
    if spec.envelope is None:
        raise ValueError(f"{spec.name}: the spec carries no measured envelope")
    speeds, lower, upper = spec.envelope.polyline
    rows = [
        (label, (float(a[0]), float(a[1])), float(b))
        for label, a, b in zip(sheet.labels, sheet.A, sheet.b, strict=True)
    ]
    region = _cut(sheet, rows, speeds, lower, upper, "envelope")
    region = replace(
        region,
        vertices=frozen(_traced(speeds, lower, upper, sheet)),
        no_load_speed=_crossing(speeds, upper, 0.0, sheet.no_load_speed),
        corner_speed=_crossing(speeds, upper, float(np.nanmax(upper[speeds >= 0])) * (1 - 1e-9), 0.0),
        source=f"measured envelope ({spec.envelope.source})",
    )
    return replace(region, inner_box=_traced_box(region.vertices))


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
    return _ring(w, lo, hi)


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


def current_window(
    omega: NDArray[np.float64], region: OperatingRegion
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The linear-equivalent torque window x = Kt i [N m] at motor speeds ``omega`` [rad/s], before the current-torque
    curve: the DC law's [-S - D omega, S - D omega] cut to [-X, X] (past overspeed collapsed onto the end nearest it),
    or the drive's dq window (:func:`hound_id.mor.drive.dq_window`)."""
    X = region.limit_x
    u = region.back_emf_damping * omega
    if region.drive is not None:
        d = region.drive
        lo, hi = dq_window(u, region.stall_torque, d.k_rho, X, d.circle_x, d.field_weakening)
        return np.asarray(lo, float), np.asarray(hi, float)
    x_hi = region.stall_torque - u
    x_lo = -region.stall_torque - u
    hi = np.maximum(np.minimum(x_hi, X), x_lo)  # past overspeed both collapse onto the end nearest the window
    lo = np.minimum(np.maximum(x_lo, -X), x_hi)
    return lo, hi


def torque_interval(omega: ArrayLike, region: OperatingRegion) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Feasible motor torque interval [lo, hi] at speed ``omega`` [rad/s].

    In the linear-equivalent torque x = Kt i the drive can make any current whose voltage fits the bus,
    x in [-S - D omega, S - D omega] (S = Kt V/R, D = Kt/(R Kv)), and the driver holds |x| <= X (X = Kt I, I the
    current the torque limit needs). The interval is the curve's image of that window (x -> g(x/Kt), exactly x for
    a linear curve): inside |omega| <= overspeed the region's slice at that speed.

    Past overspeed the window misses [-X, X]: even the full opposing voltage cannot hold the current at I, and the
    back-EMF drives a braking current (|omega|/Kv - V)/R through the inverter (its diodes, when the switches are
    off) whatever is commanded. The interval collapses to the torque of that current, g((V - omega/Kv)/R) for
    omega > 0, beyond the torque limit and growing with the speed (held at the curve's top past it, where neither
    the fit nor the spec sheet says more). Isaac Lab's ``DCMotor`` returns the torque limit there instead.

    Past ``max_speed`` (if given) only braking torque (sign opposite to omega, or zero) passes, as a drive's speed
    limiter does.
    """
    omega = np.asarray(omega, float)
    lo, hi = current_window(omega, region)
    if region.curve is not None and region.curve.form != "linear":
        hi = region.curve.torque(hi / region.curve.kt)
        lo = region.curve.torque(lo / region.curve.kt)
    if region.max_speed is not None:
        limit = region.max_speed * (1.0 + SPEED_TOLERANCE)
        hi = np.where(omega > limit, np.minimum(hi, 0.0), hi)
        lo = np.where(omega < -limit, np.maximum(lo, 0.0), lo)
    return lo, hi
