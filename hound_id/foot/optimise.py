"""The lightest spherical-cap foot for a leg, by nonlinear programming with casadi (IPOPT).

Design variables (SI): sphere radius R, wall thickness t, lateral width W, cap angles
[low, high], the height z_c of the sphere centre above the mount and the boss radius r_b
(see :mod:`hound_id.foot.geometry`; ``--boss-radius`` fixes it). The boss is bored for the
fastener (``--bolt``, M4 by default; :mod:`hound_id.foot.strength`); z_c sets its length.

Objective: the knee pitch inertia of the foot, I_foot = rho int ((x^2 + (z - L)^2) dV), plus
``mass_weight`` m l^2 with l the knee-to-ground length, so ``mass_weight = 1`` counts the
foot's mass once more as if it sat at the ground. The calf's own inertia is a constant.

Constraints (each reported with its value, limit and margin):

* ``coverage_touchdown`` low <= required low, ``coverage_liftoff`` high >= required high:
  the cap covers the stance's contact angles with the margin;
* ``hertz_pressure``: Hertz peak pressure under the peak ground force <= 1.6 Y / S;
* ``hertz_depth``: t >= 3 x the depth of the largest subsurface shear (0.48 a);
* ``wall_thickness``: t >= the material's process minimum;
* ``leg_length``: the knee-to-ground height at the nominal contact angle theta_n is the
  original foot's, (L - z_c) cos(theta_n) + R = L cos(theta_n) + r0, and
  ``leg_length_stance``: over the whole contact arc it differs from the original's by at most
  ``length_tolerance``, |R - r0 - z_c cos(theta)| <= tol (the gait sees the same leg);
* ``lateral_coverage``: the cap covers roll angles up to ``roll``: asin(W / 2R) >= roll;
* ``boss_seat_front`` / ``boss_seat_back``: the boss, with a rim of one wall thickness, lands
  inside the cap's angles; ``boss_width``: W >= 2 (r_b + t); ``boss_length``: the boss is at
  least ``min_boss_length`` long;
* with a fastener: ``boss_wall``: r_b >= d/2 + wall, ``thread_engagement``: the boss is at least
  the engagement long;
* ``boss_stress``, ``shell_bending``, ``shell_root_touchdown``, ``shell_root_liftoff``: the boss at
  the mount plane, the cap under the load and the cap at the boss seat stay below yield / safety
  at the peak ground force (:mod:`hound_id.foot.strength` states the formulas and their validity);
  ``shell_edge_touchdown`` / ``_liftoff``: the stance's own farthest contacts (the arc without its
  margin) lie at least the shell's characteristic length l from the cap's free edges, where the
  interior bending formula holds;
* ``max_radius`` (when given): R <= the packaging limit.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import numpy as np

from hound_id.errors import SpecError
from hound_id.foot.geometry import FLOAT_OPS, FootGeometry, MassProperties, mass_properties, volume_moments
from hound_id.foot.material import (
    DEPTH_WALLS,
    SHEAR_DEPTH_FACTOR,
    Material,
    allowed_pressure,
    contact_radius,
    effective_modulus,
    min_radius,
    peak_pressure,
)
from hound_id.foot.strength import (
    Fastener,
    band_section,
    boss_moment,
    boss_stress,
    characteristic_length,
    fastener,
    local_bending_stress,
    root_bending_stress,
    seat_angle,
)
from hound_id.foot.urdf import FootMount

#: A constraint counts as satisfied within this relative tolerance of its limit (IPOPT's tol is 1e-10).
TOLERANCE = 1e-7
#: ... of the larger of |limit|, |value| and this floor (in the row's unit), so a limit of zero is not held exactly.
TOLERANCE_FLOOR = 1e-3

#: Unit factors: IPOPT's variables and rows are in millimetres, megapascals and radians, all of order one where
#: the foot lives (its tolerances are absolute), and the messages print the same units.
MM_PER_M = 1e3
M_PER_MM = 1e-3
MPA_PER_PA = 1e-6

#: IPOPT's convergence tolerance (scaled rows); the report's :data:`TOLERANCE` is 1,000 times looser.
IPOPT_TOL = 1e-10
#: IPOPT's iterations per start: the samples converge in well under a hundred; a start still wandering after this
#: many is dropped and the other starts decide.
IPOPT_MAX_ITER = 500
#: Starting radii as multiples of max(the Hertz minimum, the original contact radius / START_SHRINK), each from a
#: narrow and a wide cap: the stress constraints make the problem multimodal (a thick narrow band and a thin wide
#: one both carry the load), and these spread from just above the minimum to four times it.
STARTS = (1.3, 2.0, 1.02, 4.0)
START_SHRINK = 1.3
#: Objectives (relative to the original foot's knee inertia) closer than this are a tie: the earlier start keeps it.
TIE = 1e-9
#: Floor under the square root of the boss length [m^2]: keeps it real where IPOPT steps outside the constraints.
SQRT_FLOOR = 1e-12
#: Bounds of IPOPT's variables (see :func:`optimise_foot`): radius [mm] from 1 mm to 1 m; wall thickness as a
#: share of the radius, 0.1 % to half (a solid sphere has no wall); the lateral half-angle kept off 0 and 90 deg
#: by ANGLE_GUARD [rad], where its arcsine's derivative is infinite; the sphere centre within 1 m of the mount and
#: the boss radius up to 1 m [mm]. Wide enough never to bind on a leg-sized foot (the report would say so).
RADIUS_BOUNDS_MM = (1.0, 1e3)
THICKNESS_SHARE_BOUNDS = (1e-3, 0.5)
ANGLE_GUARD = 1e-3
CENTRE_BOUND_MM = 1e3
BOSS_MAX_MM = 1e3
#: Smallest boss radius without a fastener [m]: a bore-free 1 mm peg.
MIN_BOSS_RADIUS = 1e-3
#: The starting design (:func:`_guess`): a wall of twice the process minimum (at least GUESS_MIN_WALL [m]) and at
#: most GUESS_WALL_SHARE of the radius; a boss of GUESS_BOSS x its smallest radius, or GUESS_BOSS_SHARE of the
#: radius; a width GUESS_WIDTH x what the boss and the roll need, below GUESS_WIDTH_SHARE of the diameter (or, for
#: the wide start, WIDE_START x the radius); cap angles GUESS_ANGLE_MARGIN [rad] past what the stance and the boss
#: need, within +-GUESS_ANGLE_LIMIT [rad]. A start only: IPOPT moves every one of them.
GUESS_MIN_WALL = 1e-3
GUESS_WALL_SHARE = 0.3
GUESS_BOSS = 1.5
GUESS_BOSS_SHARE = 0.25
GUESS_WIDTH = 1.3
GUESS_WIDTH_SHARE = 0.95
WIDE_START = 1.5
GUESS_ANGLE_MARGIN = 0.05
GUESS_ANGLE_LIMIT = 1.5


@dataclass(frozen=True)
class FootRequirements:
    """What the foot must do, SI."""

    low: float
    """Lowest contact angle to cover, margin included [rad]."""
    high: float
    """Highest contact angle to cover, margin included [rad]."""
    material: Material
    ground: Material
    peak_force: float
    """Peak ground reaction force on one foot [N]."""
    safety: float = 1.5
    """Safety factor on the Hertz yield pressure [-]."""
    roll: float = math.radians(10.0)
    """Lateral (roll) angle the cap must also cover [rad]."""
    boss_radius: float | None = None
    """Fix the radius of the mounting boss [m]; None: a design variable."""
    fastener: Fastener | None = field(default_factory=lambda: fastener("M4"))
    """The bolt tapped into the boss (None: a solid boss, no bore)."""
    friction: float = 0.6
    """Tangential over normal ground force at the peak, for the strength checks [-] (assumed)."""
    min_boss_length: float = 0.010
    """Shortest boss, mount to the cap's inner surface [m] (room for the fastening)."""
    nominal_angle: float = 0.0
    """Calf pitch at nominal contact, where the leg length is kept [rad]."""
    max_radius: float | None = None
    """Largest sphere radius that fits [m]; None for no limit."""
    radius: float | None = None
    """Fix the sphere radius [m] instead of optimising it."""
    mass_weight: float = 0.0
    """Weight of the mass term in the objective (module docstring) [-]."""
    length_tolerance: float = 0.005
    """Largest change of the knee-to-ground height over the contact arc [m]."""
    margin: float = 0.0
    """Margin included at each end of [low, high] [rad]: the stance's own contacts reach low + margin and
    high - margin (where the free-edge distance of the shell check is measured)."""

    @property
    def bore_radius(self) -> float:
        """Radius of the fastener's bore [m] (0 without one)."""
        return self.fastener.bore_radius if self.fastener is not None else 0.0

    @property
    def allowed_stress(self) -> float:
        """Yield strength over the safety factor [Pa]."""
        return self.material.yield_strength / self.safety


@dataclass(frozen=True)
class Constraint:
    """One constraint at the design: ``value`` (kind) ``limit``."""

    name: str
    value: float
    limit: float
    kind: str
    """``>=``, ``<=`` or ``==``."""
    unit: str
    satisfied: bool
    meaning: str

    @property
    def margin(self) -> float:
        """How far inside the limit (positive) or outside (negative), in the constraint's unit."""
        if self.kind == ">=":
            return self.value - self.limit
        if self.kind == "<=":
            return self.limit - self.value
        return -abs(self.value - self.limit)

    def to_dict(self) -> dict[str, Any]:
        return {
            "value": self.value,
            "limit": self.limit,
            "kind": self.kind,
            "unit": self.unit,
            "margin": self.margin,
            "satisfied": self.satisfied,
            "meaning": self.meaning,
        }


@dataclass(frozen=True)
class FootDesign:
    """An optimised foot."""

    geometry: FootGeometry
    properties: MassProperties
    """Closed-form mass properties in the foot frame."""
    knee_inertia: float
    """The foot's pitch inertia about the knee axis [kg m^2]."""
    constraints: tuple[Constraint, ...]
    hertz_min_radius: float
    """Smallest radius the contact stress allows [m]."""
    solver: dict[str, Any]
    """IPOPT's status, iterations and objective."""

    @property
    def feasible(self) -> bool:
        return all(c.satisfied for c in self.constraints)


_X = ("radius", "thickness", "width", "low", "high", "centre_z", "boss_radius")


def _geometry(x: Any, req: FootRequirements) -> FootGeometry:
    return FootGeometry(**{name: x[i] for i, name in enumerate(_X)}, bore_radius=req.bore_radius)


def _knee_ground(mount: FootMount, req: FootRequirements) -> float:
    """Knee-to-ground height of the original foot at the nominal angle [m]."""
    return mount.mount_length * math.cos(req.nominal_angle) + mount.contact_radius


def _objective(m: dict[str, Any], mount: FootMount, req: FootRequirements) -> tuple[Any, Any]:
    rho, L = req.material.density, mount.mount_length
    inertia = rho * (m["xx"] + m["zz"] - 2 * L * m["z"] + L**2 * m["V"])
    return inertia, inertia + req.mass_weight * rho * m["V"] * _knee_ground(mount, req) ** 2


def _stance_angles(req: FootRequirements) -> list[float]:
    """Contact angles where the knee-to-ground height deviates most: the arc's ends, and 0 inside it."""
    return [req.low, req.high] + ([0.0] if req.low < 0.0 < req.high else [])


def _constraints(
    x: Any, mount: FootMount, req: FootRequirements, ops: Any, symbolic: bool = False
) -> list[tuple[str, Any, Any, str, str, str]]:
    """(name, value, limit, kind, unit, meaning) for a design x, numeric or symbolic.

    ``symbolic`` rows are the smooth forms IPOPT gets: the boss seats as sines instead of
    arcsines (whose derivative is infinite at 1) and the stance leg length as one two-sided
    (``within``) row per angle instead of a maximum; the numeric rows are what the report shows.
    """
    parts = tuple(x[i] for i in range(len(_X)))
    R, t, W, lo, hi, zc, rb = parts
    e_star = effective_modulus(req.material, req.ground)
    F, allowed = req.peak_force, req.allowed_stress
    a = contact_radius(F, R, e_star)
    rim = (rb + t) / (R - t)  # sine of the half-angle of the boss plus a rim of one wall
    cos_n, L = math.cos(req.nominal_angle), mount.mount_length
    # knee-to-ground height, new minus original, with the calf at contact angle theta
    dh = [R - mount.contact_radius - zc * math.cos(theta) for theta in _stance_angles(req)]
    boss_len = ops.sqrt(ops.fmax((R - t) ** 2 - rb**2, SQRT_FLOOR)) - zc
    seats, stance = _seats_and_stance(lo, hi, rim, dh, req, ops, symbolic)
    out = [
        ("coverage_touchdown", lo, req.low, "<=", "rad", "the cap reaches the lowest contact angle"),
        ("coverage_liftoff", hi, req.high, ">=", "rad", "the cap reaches the highest contact angle"),
        ("hertz_pressure", peak_pressure(F, R, e_star), allowed_pressure(req.material, req.safety), "<=", "Pa",
         "Hertz peak pressure under the peak force <= 1.6 yield / safety"),
        ("hertz_depth", t, DEPTH_WALLS * SHEAR_DEPTH_FACTOR * a, ">=", "m",
         f"wall >= {DEPTH_WALLS:g} x depth of the largest subsurface shear"),
        ("wall_thickness", t, req.material.min_wall, ">=", "m", "wall >= the process minimum"),
        ("leg_length", (L - zc) * cos_n + R, _knee_ground(mount, req), "==", "m",
         "knee-to-ground height at nominal contact unchanged"),
        *stance,
        ("lateral_coverage", ops.asin(W / (2 * R)), req.roll, ">=", "rad", "the cap covers the roll angle"),
        *seats,
        ("boss_width", W, 2 * (rb + t), ">=", "m", "cap as wide as the boss and a rim"),
        # the floor under the square root keeps its derivative finite while IPOPT searches
        ("boss_length", boss_len, req.min_boss_length, ">=", "m",
         "room for the fastening between the mount and the cap"),
    ]  # fmt: skip
    out += _strength_rows(parts, req, ops, a, boss_len, allowed)
    if req.max_radius is not None:
        out.append(("max_radius", R, req.max_radius, "<=", "m", "the sphere fits the packaging limit"))
    return out


def _seats_and_stance(
    lo: Any, hi: Any, rim: Any, dh: list[Any], req: FootRequirements, ops: Any, symbolic: bool
) -> tuple[list[tuple[str, Any, Any, str, str, str]], list[tuple[str, Any, Any, str, str, str]]]:
    """(boss-seat rows, stance rows): smooth forms for IPOPT if ``symbolic``, else what the report shows."""
    if symbolic:
        seats = [
            ("boss_seat_front", ops.sin(-lo), rim, ">=", "-", ""),
            ("boss_seat_back", ops.sin(hi), rim, ">=", "-", ""),
        ]
        stance = [(f"leg_length_stance_{i}", d, req.length_tolerance, "within", "m", "") for i, d in enumerate(dh)]
        return seats, stance
    seat = ops.asin(ops.fmin(rim, 1.0))
    seats = [
        (
            "boss_seat_front",
            -lo,
            seat,
            ">=",
            "rad",
            "the boss and a rim of one wall land inside the cap (touchdown side)",
        ),
        (
            "boss_seat_back",
            hi,
            seat,
            ">=",
            "rad",
            "the boss and a rim of one wall land inside the cap (liftoff side)",
        ),
    ]
    worst = max(abs(d) for d in dh)
    stance = [
        (
            "leg_length_stance",
            worst,
            req.length_tolerance,
            "<=",
            "m",
            "knee-to-ground height within the tolerance of the original's over the whole contact arc",
        )
    ]
    return seats, stance


def _strength_rows(
    parts: tuple[Any, ...], req: FootRequirements, ops: Any, a: Any, boss_len: Any, allowed: float
) -> list[tuple[str, Any, Any, str, str, str]]:
    """The fastener's rows (with a bolt) and the stress rows of the design's variables (in _X's order)."""
    R, t, W, lo, hi, zc, rb = parts
    F, mu, nu = req.peak_force, req.friction, req.material.poisson
    out: list[tuple[str, Any, Any, str, str, str]] = []
    if req.fastener is not None:
        f = req.fastener
        out += [
            ("boss_wall", rb, f.min_boss_radius, ">=", "m",
             f"boss radius >= {f.name} major radius + {f.wall * MM_PER_M:.2f} mm wall"),
            ("thread_engagement", boss_len, f.engagement, ">=", "m",
             f"boss (at its rim) at least the {f.name} thread engagement long"),
        ]  # fmt: skip
    section = band_section(R, t, W, ops)
    l_char = characteristic_length(R, t, nu)
    seat = seat_angle(rb, R, t, ops)
    moment = boss_moment(F, mu, R, zc, req.low, req.high, ops)
    out += [
        ("boss_stress", boss_stress(F, mu, rb, req.bore_radius, moment), allowed, "<=", "Pa",
         "boss section at the mount plane: N/A + M r_b/I <= yield / safety"),
        ("shell_bending", local_bending_stress(F, R, t, a, nu, ops), allowed, "<=", "Pa",
         "cap bending under the load (Reissner shallow shell = Westergaard interior formula) <= yield / safety"),
        ("shell_root_touchdown", root_bending_stress(F, mu, R, section, -req.low - seat, ops), allowed, "<=", "Pa",
         "cap at the boss seat, contact at the touchdown end: N/A + M c/I <= yield / safety"),
        ("shell_root_liftoff", root_bending_stress(F, mu, R, section, req.high - seat, ops), allowed, "<=", "Pa",
         "cap at the boss seat, contact at the liftoff end: N/A + M c/I <= yield / safety"),
        ("shell_edge_touchdown", R * (req.low + req.margin - lo), l_char, ">=", "m",
         "the stance's farthest touchdown contact lies >= l from the cap's edge (the interior bending formula holds)"),
        ("shell_edge_liftoff", R * (hi - req.high + req.margin), l_char, ">=", "m",
         "the stance's farthest liftoff contact lies >= l from the cap's edge (the interior bending formula holds)"),
    ]  # fmt: skip
    return out


def hertz_min_radius(req: FootRequirements) -> float:
    """Smallest sphere radius the Hertz contact stress allows for the requirements [m]."""
    return min_radius(
        req.peak_force, effective_modulus(req.material, req.ground), allowed_pressure(req.material, req.safety)
    )


def _precheck(mount: FootMount, req: FootRequirements) -> float:
    """The Hertz minimum radius; clear errors for requests no design can meet."""
    if not 0 < req.high - req.low < math.pi:
        raise SpecError(
            f"foot: the coverage {math.degrees(req.low):.1f} to {math.degrees(req.high):.1f} deg must span "
            "between 0 and 180 deg"
        )
    rb = req.boss_radius
    if not (req.peak_force > 0 and req.safety > 0 and 0 <= req.roll < math.pi / 2 and (rb is None or rb > 0)):
        raise SpecError(
            f"foot: need --grf > 0, --safety > 0, 0 <= --roll < 90 deg and --boss-radius > 0; found "
            f"{req.peak_force:g} N, {req.safety:g}, {math.degrees(req.roll):g} deg, "
            + (f"{rb * MM_PER_M:g} mm" if rb is not None else "boss radius optimised")
        )
    if not (math.isfinite(req.friction) and 0 <= req.friction <= 2):
        raise SpecError(f"--friction: found {req.friction:g}, expected a friction coefficient from 0 to 2")
    if rb is not None and req.fastener is not None and rb < req.fastener.min_boss_radius * (1 - TOLERANCE):
        f = req.fastener
        raise SpecError(
            f"--boss-radius: {rb * MM_PER_M:.2f} mm is too thin for the {f.name} bolt: it needs at least "
            f"{f.min_boss_radius * MM_PER_M:.2f} mm (major radius {f.diameter / 2 * MM_PER_M:.2f} mm + "
            f"{f.wall * MM_PER_M:.2f} mm "
            "wall); give a larger --boss-radius, a smaller --bolt or --boss-wall, or --bolt none",
            found=rb,
            expected=f.min_boss_radius,
        )
    e_star = effective_modulus(req.material, req.ground)
    p_allow = allowed_pressure(req.material, req.safety)
    r_min = hertz_min_radius(req)
    for option, limit in (("--radius", req.radius), ("--max-radius", req.max_radius)):
        if limit is not None and limit < r_min * (1 - TOLERANCE):
            p0 = peak_pressure(req.peak_force, limit, e_star)
            raise SpecError(
                f"foot: {option} {limit * MM_PER_M:.1f} mm is too small for the load: a {req.peak_force:g} N peak "
                f"ground force on {req.material.name} against {req.ground.name} gives a Hertz pressure of "
                f"{p0 * MPA_PER_PA:.0f} MPa (allowed {p_allow * MPA_PER_PA:.0f} MPa = 1.6 x yield / safety "
                f"{req.safety:g}); the radius must be at least {r_min * MM_PER_M:.1f} mm: raise it, lower --grf, or "
                "choose a stronger --material",
                found=limit,
                expected=r_min,
            )
    # a sphere larger than the original changes the knee height over the arc by (R - r0)(1 - cos/cos_n)
    radius = req.radius if req.radius is not None else max(r_min, mount.contact_radius)
    spread = max(abs(1 - math.cos(theta) / math.cos(req.nominal_angle)) for theta in _stance_angles(req))
    change = abs(radius - mount.contact_radius) * spread
    if change > req.length_tolerance * (1 + TOLERANCE):
        which = "--radius" if req.radius is not None else "the Hertz minimum radius"
        raise SpecError(
            f"foot: {which} {radius * MM_PER_M:.1f} mm differs from the original contact radius "
            f"{mount.contact_radius * MM_PER_M:.1f} mm, so over the contact arc the knee-to-ground height would change "
            f"by {change * MM_PER_M:.1f} mm, more than --length-tolerance {req.length_tolerance * MM_PER_M:.1f} mm: "
            "raise the "
            "tolerance, narrow the arc (--margin), or lower --grf / choose a stronger --material",
            found=change,
            expected=req.length_tolerance,
        )
    return r_min


def evaluate(geometry: FootGeometry, mount: FootMount, req: FootRequirements) -> tuple[Constraint, ...]:
    """Every constraint of a design, numerically."""
    x = [getattr(geometry, k) for k in _X]
    out = []
    for name, value, limit, kind, unit, meaning in _constraints(x, mount, req, FLOAT_OPS):
        value, limit = float(value), float(limit)
        tol = TOLERANCE * max(abs(limit), abs(value), TOLERANCE_FLOOR)
        ok = {">=": value >= limit - tol, "<=": value <= limit + tol, "==": abs(value - limit) <= tol}[kind]
        out.append(Constraint(name, value, limit, kind, unit, ok, meaning))
    return tuple(out)


def _guess(R0: float, mount: FootMount, req: FootRequirements, wide: bool = False) -> list[float]:
    """A starting point in IPOPT's variables (see :func:`optimise_foot`) for a radius R0 [m]; ``wide``
    starts from a cap 1.5 x as wide as the radius (the stress constraints make the problem multimodal:
    a thick narrow band and a thin wide one both carry the load)."""
    if req.radius is not None:
        R0 = req.radius
    if req.max_radius is not None:
        R0 = min(R0, req.max_radius)
    t0 = min(max(req.material.min_wall, GUESS_MIN_WALL) * 2, GUESS_WALL_SHARE * R0)
    rb0 = req.boss_radius if req.boss_radius is not None else max(_min_boss(req) * GUESS_BOSS, GUESS_BOSS_SHARE * R0)
    seat = math.asin(min(1.0, (rb0 + t0) / (R0 - t0)))
    W0 = min(2 * R0 * GUESS_WIDTH_SHARE, max(2 * (rb0 + t0), 2 * R0 * math.sin(req.roll)) * GUESS_WIDTH)
    if wide:
        W0 = max(W0, min(WIDE_START * R0, 2 * (R0 - t0) * GUESS_WIDTH_SHARE))
    lo0 = max(min(req.low, -seat) - GUESS_ANGLE_MARGIN, -GUESS_ANGLE_LIMIT)
    hi0 = min(max(req.high, seat) + GUESS_ANGLE_MARGIN, GUESS_ANGLE_LIMIT)
    zc0 = (R0 - mount.contact_radius) / math.cos(req.nominal_angle)
    return [R0 * MM_PER_M, t0 / R0, math.asin(W0 / (2 * R0)), lo0, hi0, zc0 * MM_PER_M, rb0 * MM_PER_M]


def _min_boss(req: FootRequirements) -> float:
    """Smallest boss radius the bounds allow [m]: the fastener's, or a bore-free 1 mm."""
    return req.fastener.min_boss_radius if req.fastener is not None else MIN_BOSS_RADIUS


def optimise_foot(mount: FootMount, req: FootRequirements) -> FootDesign:
    """The foot of least knee inertia (plus the mass term) that meets every constraint."""
    import casadi as ca

    r_min = _precheck(mount, req)
    # IPOPT's variables y: R [mm], t / R, the lateral half-angle beta (W = 2 R sin beta), low, high
    # [rad], z_c [mm], r_b [mm]. Their bounds keep every square root and arcsine of the formulas real, since
    # IPOPT may step outside the constraints (never outside the bounds) while it searches.
    y = ca.SX.sym("y", len(_X))
    r_mm, share, beta, lo, hi, zc_mm, rb_mm = (y[i] for i in range(len(_X)))
    R = r_mm * M_PER_MM
    x = ca.vertcat(R, share * R, 2 * R * ca.sin(beta), lo, hi, zc_mm * M_PER_MM, rb_mm * M_PER_MM)  # in _X's order
    ops = casadi_ops()
    m = volume_moments(_geometry(x, req), ops=ops)
    inertia, objective = _objective(m, mount, req)
    g, lbg, ubg = _scaled_rows(_constraints(x, mount, req, ops, symbolic=True))
    i_ref = mount.foot.about_axis_y((0.0, 0.0, mount.mount_length))  # objective scale
    nlp = {"x": y, "f": objective / i_ref, "g": ca.vertcat(*g)}
    opts: dict[str, Any] = {"ipopt.print_level": 0, "print_time": False, "ipopt.tol": IPOPT_TOL,
            "ipopt.max_iter": IPOPT_MAX_ITER, "ipopt.sb": "yes", "ipopt.bound_relax_factor": 0.0,
            "show_eval_warnings": False}  # fmt: skip
    solver = ca.nlpsol("foot", "ipopt", nlp, opts)
    to_x = ca.Function("x", [y], [x])
    lbx, ubx = _variable_bounds(req)
    f_best, x_opt, stats, y_best = _best_start(solver, to_x, (lbx, ubx, lbg, ubg), r_min, mount, req)
    geometry = _geometry(x_opt, req)
    constraints = evaluate(geometry, mount, req)
    violated = [c for c in constraints if not c.satisfied]
    if violated or not stats.get("success", False):
        detail = "; ".join(f"{c.name} {c.value:.4g} {c.kind} {c.limit:.4g} {c.unit}" for c in violated) or "none"
        raise SpecError(
            f"foot: no design meets every constraint (IPOPT: {stats.get('return_status')}; violated: {detail}); "
            "relax the request (smaller margin or roll, larger --max-radius, lower --grf or --friction, "
            "another --boss-radius)"
        )
    props = mass_properties(geometry, req.material.density)
    knee = props.about_axis_y((0.0, 0.0, mount.mount_length))
    return FootDesign(
        geometry=geometry,
        properties=props,
        knee_inertia=knee,
        constraints=constraints,
        hertz_min_radius=r_min,
        solver={
            "status": str(stats.get("return_status")),
            "iterations": int(stats.get("iter_count", -1)),
            "objective": f_best * i_ref,
            "objective_unit": "kg m^2",
            "inertia_check": float(ca.Function("i", [y], [inertia])(y_best)) - knee,
        },
    )


def _scaled_rows(rows: list[tuple[str, Any, Any, str, str, str]]) -> tuple[list[Any], list[float], list[float]]:
    """(g, lower, upper bounds) of IPOPT's constraints from the symbolic rows, in MPa, mm and rad."""
    import casadi as ca

    g, lbg, ubg = [], [], []
    for _, value, limit, kind, unit, _ in rows:
        scale = MPA_PER_PA if unit == "Pa" else (MM_PER_M if unit == "m" else 1.0)  # MPa, mm, rad
        if kind == "within":  # -limit <= value <= limit
            g.append(value * scale)
            lbg.append(-limit * scale)
            ubg.append(limit * scale)
            continue
        g.append((value - limit) * scale)
        lbg.append(0.0 if kind in (">=", "==") else -ca.inf)
        ubg.append(0.0 if kind in ("<=", "==") else ca.inf)
    return g, lbg, ubg


def _variable_bounds(req: FootRequirements) -> tuple[list[float], list[float]]:
    """(lower, upper) bounds of IPOPT's variables (see :func:`optimise_foot`), a fixed radius or boss radius held."""
    lbx = [RADIUS_BOUNDS_MM[0], THICKNESS_SHARE_BOUNDS[0], ANGLE_GUARD, -math.pi / 2, 0.0, -CENTRE_BOUND_MM]
    ubx = [RADIUS_BOUNDS_MM[1], THICKNESS_SHARE_BOUNDS[1], math.pi / 2 - ANGLE_GUARD, 0.0, math.pi / 2, CENTRE_BOUND_MM]
    lbx, ubx = [*lbx, _min_boss(req) * MM_PER_M], [*ubx, BOSS_MAX_MM]
    if req.radius is not None:
        lbx[0] = ubx[0] = req.radius * MM_PER_M
    boss = _X.index("boss_radius")
    if req.boss_radius is not None:
        lbx[boss] = ubx[boss] = req.boss_radius * MM_PER_M
    return lbx, ubx


def _best_start(
    solver: Any,
    to_x: Any,
    bounds: tuple[list[float], list[float], list[float], list[float]],
    r_min: float,
    mount: FootMount,
    req: FootRequirements,
) -> tuple[float, list[float], dict[str, Any], list[float]]:
    """(objective, x, IPOPT's stats, y) of the best feasible solution of a few starts, or SpecError."""
    lbx, ubx, lbg, ubg = bounds
    best: tuple[float, list[float], dict[str, Any], list[float]] | None = None
    last: tuple[list[float], dict[str, Any]] | None = None
    for start, wide in itertools.product(STARTS, (False, True)):  # the best of a few starts
        guess = _guess(start * max(r_min, mount.contact_radius / START_SHRINK), mount, req, wide)
        sol = solver(x0=guess, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
        stats = solver.stats()
        y_opt = [float(v) for v in sol["x"].full().ravel()]
        x_try = [float(v) for v in np.asarray(to_x(y_opt)).ravel()]
        last = (x_try, stats)
        if stats.get("success", False) and all(c.satisfied for c in evaluate(_geometry(x_try, req), mount, req)):
            f = float(sol["f"])
            if best is None or f < best[0] - TIE:
                best = (f, x_try, stats, y_opt)
    if best is None:
        assert last is not None
        x_bad, stats = last
        violated = [c for c in evaluate(_geometry(x_bad, req), mount, req) if not c.satisfied]
        detail = "; ".join(f"{c.name} {c.value:.4g} {c.kind} {c.limit:.4g} {c.unit}" for c in violated)
        raise SpecError(
            f"foot: no design found that meets every constraint (IPOPT: {stats.get('return_status')}"
            + (f"; violated at its last point: {detail}" if detail else "")
            + "); relax the request: a smaller --margin or --roll, a larger --max-radius or --length-tolerance, "
            "a shorter --min-boss-length, a smaller --bolt, a lower --grf or --friction, or a stronger --material"
        )
    return best


def casadi_ops() -> Any:
    """casadi's versions of the functions :func:`volume_moments` and the constraints use."""
    import casadi as ca

    return SimpleNamespace(
        sqrt=ca.sqrt,
        asin=ca.asin,
        sin=ca.sin,
        cos=ca.cos,
        fmin=ca.fmin,
        fmax=ca.fmax,
        if_else=ca.if_else,
        log=ca.log,
        fabs=ca.fabs,
    )
