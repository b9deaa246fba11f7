"""The parametric spherical-cap foot: its shape, closed-form mass properties and its mesh.

Foot frame: origin at the foot mount on the calf axis (the URDF's calf-to-foot fixed joint),
z along the calf pointing *up* to the knee, x forward in the sagittal plane, y lateral. The
foot is the union of

* a **cap**: the spherical shell R - t <= |p - O| <= R about the centre O = (0, 0, z_c), cut
  to the sagittal angles phi in [low, high] (phi measured at O from the calf's -z axis
  towards +x, the contact-angle convention of :mod:`hound_id.foot.angles`) and to the
  lateral band |y| <= W/2;
* a **boss**: the column r_i <= r <= r_b about the calf axis, from the mount plane z = 0 down
  to the cap's inner sphere, which carries the cap on the calf; r_i is the bore of the fastener
  (0 for a solid boss, see :mod:`hound_id.foot.strength`).

Both are described in cylindrical coordinates (the cap about the lateral axis through O, the
boss about the calf axis), where every mass integral has a closed form (polynomials, square
roots and one arcsine). :func:`volume_moments` evaluates them for numpy floats or casadi
symbols alike, so the optimiser differentiates the same formulas the report prints;
:func:`foot_mesh` builds the same solid with manifold3d and the tests check the two against
each other with trimesh.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen
from hound_id.errors import SpecError


@dataclass(frozen=True)
class FootGeometry:
    """A spherical-cap foot with a mounting boss (see the module docstring), SI."""

    radius: float
    """Sphere radius R of the contact surface [m]."""
    thickness: float
    """Shell (wall) thickness t [m]."""
    width: float
    """Lateral width W of the cap [m] (|y| <= W/2)."""
    low: float
    """Lowest sagittal angle of the cap [rad] (liftoff side is positive, touchdown negative)."""
    high: float
    """Highest sagittal angle of the cap [rad]."""
    boss_radius: float
    """Radius r_b of the mounting boss [m]."""
    centre_z: float
    """Height z_c of the sphere centre above the foot mount, along the calf [m] (negative: below)."""
    bore_radius: float = 0.0
    """Radius r_i of the bore through the boss for the fastener [m] (0: a solid boss)."""

    def check(self) -> None:
        """Raise SpecError if the numbers do not describe a solid this module can build."""
        R, t, W, rb = self.radius, self.thickness, self.width, self.boss_radius
        values = (R, t, W, self.low, self.high, rb, self.centre_z)
        if not all(math.isfinite(v) for v in values):
            raise SpecError(f"foot geometry: every dimension must be finite, found {values}")
        if not (R > 0 and 0 < t < R and 0 < W <= 2 * R and rb > 0):
            raise SpecError(
                f"foot geometry: need R > 0, 0 < t < R, 0 < W <= 2R and r_b > 0; found R={R:g} m, t={t:g} m, "
                f"W={W:g} m, r_b={rb:g} m"
            )
        if not (0 < self.high - self.low < math.pi):
            raise SpecError(
                f"foot geometry: the cap's sagittal coverage must be between 0 and 180 deg, found "
                f"{math.degrees(self.low):.1f} to {math.degrees(self.high):.1f} deg"
            )
        if not (math.isfinite(self.bore_radius) and 0 <= self.bore_radius < rb):
            raise SpecError(
                f"foot geometry: the bore (r_i = {self.bore_radius * 1e3:.2f} mm) must be smaller than the boss "
                f"(r_b = {rb * 1e3:.2f} mm)"
            )
        if boss_seat_angle(self) > min(-self.low, self.high) + 1e-9 or rb > W / 2 * (1 + 1e-9):
            raise SpecError(
                f"foot geometry: the boss (r_b = {rb * 1e3:.1f} mm) does not sit inside the cap "
                f"({math.degrees(self.low):.1f} to {math.degrees(self.high):.1f} deg, W = {W * 1e3:.1f} mm); "
                "widen the cap or use a thinner boss"
            )
        if boss_length(self) <= 0:
            raise SpecError(
                f"foot geometry: the cap's inner sphere reaches above the mount at the boss edge "
                f"(boss length {boss_length(self) * 1e3:.2f} mm); lower the sphere centre or use a smaller radius"
            )


def boss_seat_angle(geometry: FootGeometry, ops: Any = math) -> Any:
    """Half-angle at the centre over which the boss meets the cap's inner sphere [rad]."""
    return ops.asin(geometry.boss_radius / (geometry.radius - geometry.thickness))


def boss_length(geometry: FootGeometry, ops: Any = math) -> Any:
    """Shortest length of the boss, at its rim, from the mount to the inner sphere [m]."""
    rho = geometry.radius - geometry.thickness
    return ops.sqrt(rho**2 - geometry.boss_radius**2) - geometry.centre_z


@dataclass(frozen=True)
class MassProperties:
    """Mass properties of a rigid body in a stated frame, SI."""

    mass: float
    """Mass [kg]."""
    com: NDArray[np.float64]
    """Centre of mass in the frame [m], shape (3,)."""
    inertia: NDArray[np.float64]
    """Inertia tensor about the centre of mass, frame axes [kg m^2], shape (3, 3)."""

    def about_axis_y(self, point: tuple[float, float, float]) -> float:
        """Moment of inertia about the line through ``point`` parallel to y [kg m^2]."""
        d = self.com - np.asarray(point, dtype=float)
        return float(self.inertia[1, 1] + self.mass * (d[0] ** 2 + d[2] ** 2))

    def to_dict(self) -> dict[str, Any]:
        return {"mass": self.mass, "com": self.com.tolist(), "inertia": self.inertia.tolist(), "units": "kg, m, kg m^2"}


def _if_else(condition: Any, then: Any, otherwise: Any) -> Any:
    return then if condition else otherwise


#: The few functions :func:`volume_moments` and the foot constraints need, for floats
#: (:func:`hound_id.foot.optimise.casadi_ops` gives casadi's).
FLOAT_OPS = SimpleNamespace(
    sqrt=math.sqrt,
    asin=math.asin,
    sin=math.sin,
    cos=math.cos,
    fmin=min,
    fmax=max,
    if_else=_if_else,
    log=math.log,
    fabs=abs,
)


def _g2(a: Any, r: Any) -> Any:
    """int_0^a (r^2 - y^2) dy."""
    return r**2 * a - a**3 / 3


def _g3(a: Any, r: Any, ops: Any) -> Any:
    """int_0^a (r^2 - y^2)^(3/2) dy, for 0 <= a <= r."""
    return a / 8 * (5 * r**2 - 2 * a**2) * ops.sqrt(r**2 - a**2) + 3 * r**4 / 8 * ops.asin(a / r)


def _g4(a: Any, r: Any) -> Any:
    """int_0^a (r^2 - y^2)^2 dy."""
    return r**4 * a - 2 * r**2 * a**3 / 3 + a**5 / 5


def _column(rb: Any, rho: Any, h: Any, ops: Any) -> dict[str, Any]:
    """Volume moments about O of the solid column r <= rb, from the sphere of radius rho up to zeta = h."""
    q = ops.sqrt(ops.fmax(rho**2 - rb**2, 1e-12))  # real while an optimiser searches; check() refuses rb >= rho
    out = {
        "V": 2 * math.pi * (h * rb**2 / 2 + (rho**3 - q**3) / 3),
        "z": math.pi * (h**2 * rb**2 / 2 - (rho**2 * rb**2 / 2 - rb**4 / 4)),
        "zz": 2 * math.pi / 3 * (h**3 * rb**2 / 2 + (rho**5 - q**5) / 5),
        # int r^3 l(r) dr with l = h + sqrt(rho^2 - r^2); x^2 and y^2 share it
        "xx": math.pi * (h * rb**4 / 4 + (2 / 3 * rho**2 * (rho**3 - q**3) - 2 / 5 * (rho**5 - q**5)) / 2),
        "xz": 0.0,
        "x": 0.0,
    }
    return out


def volume_moments(geometry: FootGeometry, ops: Any = None) -> dict[str, Any]:
    """Volume integrals of the foot in the foot frame (module docstring), closed form.

    Returns ``V`` [m^3], first moments ``x, z`` [m^4] (y is 0 by symmetry) and second
    moments ``xx, yy, zz, xz`` [m^5] (integrals of x^2, y^2, z^2, x z over the solid; xy and yz
    are 0 by symmetry). ``ops`` supplies sqrt, asin, sin, cos, fmin and if_else: casadi's for
    symbolic use (:func:`hound_id.foot.optimise.casadi_ops`), plain floats by default.
    """
    ops = ops or FLOAT_OPS
    R, t, W = geometry.radius, geometry.thickness, geometry.width
    lo, hi, rb, zc = geometry.low, geometry.high, geometry.boss_radius, geometry.centre_z
    rho, w = R - t, W / 2
    a1 = ops.fmin(w, rho)  # lateral extent where the shell has an inner surface
    dphi = hi - lo
    # Cap, in coordinates about O: x = s sin(phi), zeta = -s cos(phi), y; dV = s ds dphi dy, and
    # int s^(k-1) ds between the spheres integrates over y to M_k.
    m2 = (_g2(w, R) - _g2(a1, rho)) * 2 / 2
    # the inner term at a1 = rho is 3 pi rho^4 / 16; written as a branch because the closed form's
    # derivative there is inf - inf for automatic differentiation
    inner3 = ops.if_else(w < rho, _g3(a1, rho, ops), 3 * math.pi * rho**4 / 16)
    m3 = (_g3(w, R, ops) - inner3) * 2 / 3
    m4 = (_g4(w, R) - _g4(a1, rho)) * 2 / 4
    n2 = (R**2 * w**3 / 3 - w**5 / 5) - (rho**2 * a1**3 / 3 - a1**5 / 5)  # int y^2 (s2^2 - s1^2)/2 dy
    sin_lo, sin_hi, cos_lo, cos_hi = ops.sin(lo), ops.sin(hi), ops.cos(lo), ops.cos(hi)
    sin2 = ops.sin(2 * hi) - ops.sin(2 * lo)
    cap = {
        "V": dphi * m2,
        "x": (cos_lo - cos_hi) * m3,
        "z": -(sin_hi - sin_lo) * m3,
        "xx": (dphi / 2 - sin2 / 4) * m4,
        "zz": (dphi / 2 + sin2 / 4) * m4,
        "xz": -(sin_hi**2 - sin_lo**2) / 2 * m4,
        "yy": dphi * n2,
    }
    # Boss, about the calf axis: the column r_i <= r <= r_b from zeta = -sqrt(rho^2 - r^2) up to zeta = h,
    # the solid column of r_b minus that of the bore r_i.
    outer, bore = _column(rb, rho, -zc, ops), _column(geometry.bore_radius, rho, -zc, ops)
    boss = {k: outer[k] - bore[k] for k in outer}
    boss["yy"] = boss["xx"]
    # Shift both from O to the foot frame (z = zc + zeta).
    out = {"V": cap["V"] + boss["V"], "x": cap["x"] + boss["x"]}
    z1 = cap["z"] + boss["z"]
    out["z"] = z1 + zc * out["V"]
    out["xx"] = cap["xx"] + boss["xx"]
    out["yy"] = cap["yy"] + boss["yy"]
    out["zz"] = cap["zz"] + boss["zz"] + 2 * zc * z1 + zc**2 * out["V"]
    out["xz"] = cap["xz"] + boss["xz"] + zc * out["x"]
    return out


def moments_to_properties(moments: dict[str, Any], density: float) -> MassProperties:
    """Mass, centre of mass and inertia about the centre of mass from volume moments."""
    V = float(moments["V"])
    m = density * V
    com = np.array([float(moments["x"]) / V, 0.0, float(moments["z"]) / V])
    xx, yy, zz, xz = (density * float(moments[k]) for k in ("xx", "yy", "zz", "xz"))
    # about the frame origin: I = [[yy+zz, 0, -xz], [0, xx+zz, 0], [-xz, 0, xx+yy]]
    origin = np.array([[yy + zz, 0.0, -xz], [0.0, xx + zz, 0.0], [-xz, 0.0, xx + yy]])
    shift = m * (float(com @ com) * np.eye(3) - np.outer(com, com))
    return MassProperties(mass=m, com=frozen(com), inertia=frozen(origin - shift))


def mass_properties(geometry: FootGeometry, density: float) -> MassProperties:
    """Closed-form mass properties of the foot for a material density [kg/m^3]."""
    geometry.check()
    return moments_to_properties(volume_moments(geometry), density)


def _ccw(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    area = sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(points, points[1:] + points[:1], strict=True))
    return points if area > 0 else points[::-1]


def _arc(radius: float, start: float, stop: float, step: float) -> list[tuple[float, float]]:
    n = max(2, math.ceil(abs(stop - start) / step) + 1)
    return [(radius * math.cos(a), radius * math.sin(a)) for a in np.linspace(start, stop, n)]


def foot_mesh(geometry: FootGeometry, resolution_deg: float = 1.0) -> Any:
    """The foot as a watertight trimesh.Trimesh built by CSG with manifold3d, in metres.

    The cap is the shell's (s, y) section revolved about the lateral axis over [low, high];
    the boss is its (r, z) section revolved about the calf axis, reaching half-way into the
    shell so that the union is one solid (the bore, if any, stops at the cap's inner sphere).
    ``resolution_deg`` is the angular step of arcs and
    revolutions.
    """
    import manifold3d
    import trimesh

    geometry.check()
    R, t, w, rb, zc = geometry.radius, geometry.thickness, geometry.width / 2, geometry.boss_radius, geometry.centre_z
    rho = R - t
    step = math.radians(resolution_deg)
    segments = max(8, math.ceil(360.0 / resolution_deg))
    # cap section in (s, y): outer arc, then the inner arc back (or the axis when W/2 >= R - t)
    alpha = math.asin(min(1.0, w / R))
    section = _arc(R, -alpha, alpha, step)
    if w < rho:
        beta = math.asin(w / rho)
        section += _arc(rho, beta, -beta, step)
    else:
        section += [(0.0, w), *_arc(rho, math.pi / 2, -math.pi / 2, step), (0.0, -w)]
    cap = manifold3d.Manifold.revolve(
        manifold3d.CrossSection([_ccw(section)]), segments, math.degrees(geometry.high - geometry.low)
    )
    # revolved point (s cos psi, s sin psi, y) -> phi = high - psi: x = s sin phi, z = zc - s cos phi, y = y
    sh, ch = math.sin(geometry.high), math.cos(geometry.high)
    cap = cap.transform(np.array([[sh, -ch, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [-ch, -sh, 0.0, zc]]))
    # boss section in (r, z): down from the mount to the sphere of radius R - t/2 (inside the shell)
    rm, ri = R - t / 2, geometry.bore_radius
    boss_section = [(ri, 0.0), (rb, 0.0)] + [
        (r, zc - math.sqrt(rm**2 - r**2)) for r in np.linspace(rb, ri, max(2, math.ceil((rb - ri) / (rm * step)) + 1))
    ]
    if ri > 0:  # the bore ends at the cap's inner sphere: the shell closes it
        boss_section[-1] = (ri, zc - math.sqrt((R - t) ** 2 - ri**2))
    boss = manifold3d.Manifold.revolve(manifold3d.CrossSection([_ccw(boss_section)]), segments)
    solid = cap + boss
    mesh = solid.to_mesh()
    return trimesh.Trimesh(
        vertices=np.asarray(mesh.vert_properties, dtype=float)[:, :3],
        faces=np.asarray(mesh.tri_verts, dtype=np.int64),
        process=False,  # manifold3d's vertices are already shared; merging by distance could pinch them
    )


def mesh_properties(mesh: Any, density: float) -> MassProperties:
    """Mass properties of a trimesh solid for a density [kg/m^3], in the mesh frame."""
    mesh = mesh.copy()
    mesh.density = density
    return MassProperties(
        mass=float(mesh.mass), com=frozen(mesh.center_mass), inertia=frozen(np.asarray(mesh.moment_inertia))
    )
