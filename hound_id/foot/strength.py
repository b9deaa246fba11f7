"""The foot's strength: the fastener in the boss, the boss at the mount, and the cap in bending.

Every formula here takes floats or casadi symbols (``ops``, see :data:`hound_id.foot.geometry.FLOAT_OPS`),
so the optimiser constrains exactly what the report prints. Loads (SI): the peak ground force F
(``--grf``) acts along the ground normal at any contact angle of the required arc, with a tangential
(friction) force mu F on top (``--friction``); the gait log has no forces, so the peak is applied
everywhere on the arc. Stresses are compared with the yield strength over the safety factor.

**Fastener.** The boss is bored and tapped for an ISO metric coarse bolt (ISO 261/262 pitches):
the bore is the tap drill, d - P (the ISO 2306 rule), the boss keeps a wall of
:data:`WALL_PER_D` d around the thread's major diameter (boss outside diameter >= 2 d, a common rule
for tapped bosses; assumed) and a thread engagement of :data:`ENGAGEMENT_PER_D` d (a common rule
for steel bolts tapped into aluminium alloys; assumed). Both are options of ``hound-id foot``.

**Boss at the mount plane.** The boss is a hollow circular section (r_i..r_b) at z = 0 carrying the
axial force and the bending moment of the contact force about the mount. A normal force on a
sphere passes through its centre O, so it only has the lever |z_c| sin(phi); the friction force
acts on the lever R - z_c cos(phi). sigma = N / A + M r_b / I (elementary beam flexure). The
bolted joint (preload, bolt stress, joint opening) is not checked.

**Cap, local bending under the load** (``shell_bending``): a thin shallow spherical shell under a
load on a small circle behaves near the load as a plate on an elastic foundation of modulus
E t / R^2 (Reissner 1946, *J. Math. Phys.* 25), with the characteristic length
l = (R^2 t^2 / (12 (1 - nu^2)))^(1/4). The largest bending stress, under the load, is then
Westergaard's interior formula for a plate on an elastic foundation (Timoshenko and
Woinowsky-Krieger, *Theory of Plates and Shells*, 1959, sec. 57):

    sigma = 3 (1 + nu) F / (2 pi t^2) (ln(l / b) + ln 2 + 1/2 - gamma),

with b Westergaard's equivalent radius of the load circle c (here the Hertz contact radius):
b = sqrt(1.6 c^2 + t^2) - 0.675 t for c < 1.724 t, else c (the same correction as Roark's r'_0).
Valid for a thin shell (t / R <= 0.1, reported) and a load at least about l from the free edges
and from the boss (the distance to the cap's edges is reported in units of l: nearer an edge
Westergaard's edge case gives up to about twice the stress).

**Cap, bending at the boss** (``shell_root_touchdown`` / ``_liftoff``): off the boss the cap is a
curved cantilever from the boss seat (the half-angle phi_b = asin(r_b / (R - t)) at O). The
resultant on the cut through O at phi_b follows from statics exactly (moment F s_c sin(Delta) +
mu F |R - s_c cos(Delta)|, normal force F sin(Delta) + mu F cos(Delta), Delta the angle from
the seat to the farthest contact of the arc on that side, s_c the section's centroid distance
from O). The stress on the true section (the band |y| <= W/2 of the annulus R - t..R) is the
Winkler-Bach curved-beam formula (Roark, *Formulas for Stress and Strain*, 7th ed., sec. 9.1):
sigma = N / A + M (r_n - s) / (A e s) at the inner (s = s_min) and outer (s = R) fibres, with
r_n = A / int(dA / s) the neutral axis and e = s_c - r_n, all in closed form for this section.
It assumes plane sections and the whole band effective (shear lag beside a boss narrower than
the band is neglected) and needs W/2 < R - t. Use FEA for the final part.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

from hound_id.errors import SpecError

#: ISO 261/262 coarse thread pitch [m] by nominal diameter [mm].
COARSE_PITCH = {2.0: 0.4e-3, 2.5: 0.45e-3, 3.0: 0.5e-3, 4.0: 0.7e-3, 5.0: 0.8e-3, 6.0: 1.0e-3, 8.0: 1.25e-3,
                10.0: 1.5e-3, 12.0: 1.75e-3}  # fmt: skip
#: Wall around the thread's major diameter over d: boss outside diameter >= 2 d (common rule; assumed).
WALL_PER_D = 0.5
#: Thread engagement over d for a steel bolt tapped into an aluminium alloy (common rule; assumed).
ENGAGEMENT_PER_D = 2.0
#: ln 2 + 1/2 - Euler's gamma: the constant of Westergaard's interior formula.
WESTERGAARD_CONSTANT = math.log(2.0) + 0.5 - 0.5772156649015329
#: Westergaard's equivalent radius applies below this load radius over the thickness.
WESTERGAARD_THICK = 1.724
#: Largest wall over radius for which the thin-shell formulas are used (reported, not enforced).
THIN_SHELL = 0.1


@dataclass(frozen=True)
class Fastener:
    """A tapped bolt hole in the boss, SI."""

    name: str
    """E.g. ``M4``."""
    diameter: float
    """Nominal (major) diameter d [m]."""
    pitch: float
    """Thread pitch P [m] (ISO 261/262 coarse)."""
    wall: float
    """Wall the boss keeps around the major diameter [m]."""
    engagement: float
    """Thread engagement length the boss must give [m]."""

    @property
    def bore_radius(self) -> float:
        """Radius of the tap-drill bore, (d - P) / 2 [m] (ISO 2306 rule)."""
        return (self.diameter - self.pitch) / 2

    @property
    def min_boss_radius(self) -> float:
        """Smallest boss radius that keeps the wall, d / 2 + wall [m]."""
        return self.diameter / 2 + self.wall

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "diameter": self.diameter,
            "pitch": self.pitch,
            "bore_radius": self.bore_radius,
            "wall": self.wall,
            "engagement": self.engagement,
            "min_boss_radius": self.min_boss_radius,
            "source": "ISO 261/262 coarse pitch; bore = tap drill d - P (ISO 2306); wall default "
            f"{WALL_PER_D:g} d (boss OD >= 2 d) and engagement default {ENGAGEMENT_PER_D:g} d: common design rules "
            "for steel bolts tapped into aluminium (assumed)",
        }


def fastener(name: str, wall: float | None = None, engagement: float | None = None) -> Fastener | None:
    """The fastener of ``--bolt`` (``M4``, ``M3``...; ``none`` for a solid boss without a bore).

    Args:
        name: ``M<d>`` with d in mm from :data:`COARSE_PITCH`, or ``none``.
        wall: Wall around the major diameter [m] (None: :data:`WALL_PER_D` d).
        engagement: Thread engagement [m] (None: :data:`ENGAGEMENT_PER_D` d).
    """
    if name.strip().lower() == "none":
        return None
    match = re.fullmatch(r"[mM](\d+(?:\.\d+)?)", name.strip())
    sizes = ", ".join(f"M{d:g}" for d in COARSE_PITCH)
    if match is None or float(match.group(1)) not in COARSE_PITCH:
        raise SpecError(f"--bolt: found {name!r}, expected an ISO metric coarse size ({sizes}) or none")
    d_mm = float(match.group(1))
    d = d_mm * 1e-3
    for option, value in (("--boss-wall", wall), ("--thread-engagement", engagement)):
        if value is not None and not (0 < value < 0.1):
            raise SpecError(f"{option}: found {value:g} m, expected more than 0 and less than 100 mm")
    return Fastener(
        name=f"M{d_mm:g}",
        diameter=d,
        pitch=COARSE_PITCH[d_mm],
        wall=wall if wall is not None else WALL_PER_D * d,
        engagement=engagement if engagement is not None else ENGAGEMENT_PER_D * d,
    )


def characteristic_length(radius: Any, thickness: Any, poisson: float) -> Any:
    """l = (R_m^2 t^2 / (12 (1 - nu^2)))^(1/4) of a shallow spherical shell, R_m = R - t/2 [m]."""
    rm = radius - thickness / 2
    return (rm**2 * thickness**2 / (12 * (1 - poisson**2))) ** 0.25


def local_bending_stress(force: float, radius: Any, thickness: Any, load_radius: Any, poisson: float, ops: Any) -> Any:
    """Westergaard/Reissner bending stress under a load on a circle of ``load_radius`` [Pa] (module docstring)."""
    t, c = thickness, load_radius
    b = ops.if_else(c < WESTERGAARD_THICK * t, ops.sqrt(1.6 * c**2 + t**2) - 0.675 * t, c)
    l_char = characteristic_length(radius, t, poisson)
    return 3 * (1 + poisson) * force / (2 * math.pi * t**2) * (ops.log(l_char / b) + WESTERGAARD_CONSTANT)


def _g1(a: Any, r: Any, ops: Any) -> Any:
    """int_0^a sqrt(r^2 - y^2) dy, for 0 <= a <= r."""
    return (a * ops.sqrt(ops.fmax(r**2 - a**2, 1e-14)) + r**2 * ops.asin(a / r)) / 2


def band_section(radius: Any, thickness: Any, width: Any, ops: Any) -> dict[str, Any]:
    """The cap's cross-section on a plane through O containing the lateral axis, SI.

    The region R - t <= sqrt(s^2 + y^2) <= R, |y| <= W/2, s >= 0 (s: distance from O in the plane).
    Returns its area ``A`` [m^2], centroid distance ``s_c`` from O [m], second moment ``I`` about the
    lateral axis through the centroid [m^4], the extreme fibre distances ``c_out`` and ``c_in`` [m]
    and its radial ``depth`` [m].
    """
    R, rho, w = radius, radius - thickness, width / 2
    a1 = ops.fmin(w, rho)
    inner1 = ops.if_else(w < rho, _g1(a1, rho, ops), math.pi * rho**2 / 4)
    area = 2 * (_g1(w, R, ops) - inner1)
    s1 = (R**2 * w - w**3 / 3) - (rho**2 * a1 - a1**3 / 3)  # int s dA
    g3 = _g3_ops(w, R, ops)
    inner3 = ops.if_else(w < rho, _g3_ops(a1, rho, ops), 3 * math.pi * rho**4 / 16)
    s2 = (g3 - inner3) * 2 / 3  # int s^2 dA
    sc = s1 / area
    inertia = s2 - s1**2 / area
    s_min = ops.sqrt(ops.fmax(rho**2 - w**2, 1e-14))  # the floor keeps its derivative finite
    # int dA / s = int (ln sqrt(R^2 - y^2) - ln sqrt(rho^2 - y^2)) dy over |y| <= W/2, finite while W/2 < R - t
    recip = _log_integral(w, R, ops) - _log_integral(w, rho, ops)
    r_n = area / recip  # Winkler-Bach neutral axis of the curved beam
    return {"A": area, "s_c": sc, "I": inertia, "r_n": r_n, "s_min": s_min, "s_max": R, "depth": R - s_min}


def _log_integral(a: Any, r: Any, ops: Any) -> Any:
    """int_{-a}^{a} ln sqrt(r^2 - y^2) dy = (r + a) ln(r + a) - (r - a) ln(r - a) - 2a, for 0 <= a <= r."""
    gap = ops.fmax(r - a, 1e-12)
    return (r + a) * ops.log(r + a) - gap * ops.log(gap) - 2 * a


def _g3_ops(a: Any, r: Any, ops: Any) -> Any:
    """int_0^a (r^2 - y^2)^(3/2) dy, for 0 <= a <= r."""
    return a / 8 * (5 * r**2 - 2 * a**2) * ops.sqrt(ops.fmax(r**2 - a**2, 1e-14)) + 3 * r**4 / 8 * ops.asin(a / r)


def root_bending_stress(
    force: float, friction: float, radius: Any, section: dict[str, Any], delta: Any, ops: Any
) -> Any:
    """Largest stress on the cap's cut at the boss seat for a contact ``delta`` [rad] beyond it [Pa]."""
    d = ops.fmax(delta, 0.0)
    sc, rn, area = section["s_c"], section["r_n"], section["A"]
    moment = force * sc * ops.sin(d) + friction * force * ops.fabs(radius - sc * ops.cos(d))
    normal = force * ops.sin(d) + friction * force * ops.cos(d)
    e = sc - rn  # offset of the neutral axis towards the centre of curvature
    inner = moment * (rn - section["s_min"]) / (area * e * section["s_min"])
    outer = moment * (section["s_max"] - rn) / (area * e * section["s_max"])
    return normal / area + ops.fmax(inner, outer)


def boss_moment(force: float, friction: float, radius: Any, centre_z: Any, low: float, high: float, ops: Any) -> Any:
    """Largest bending moment of the contact force about the mount, over the arc [low, high] [N m]."""
    sin_max = max(abs(math.sin(low)), abs(math.sin(high)))  # |angles| <= 90 deg
    return force * ops.fabs(centre_z) * sin_max + friction * force * (radius + ops.fabs(centre_z))


def boss_stress(force: float, friction: float, boss_radius: Any, bore_radius: float, moment: Any) -> Any:
    """N / A + M r_b / I of the hollow boss section at the mount plane [Pa] (N = F sqrt(1 + mu^2))."""
    area = math.pi * (boss_radius**2 - bore_radius**2)
    inertia = math.pi * (boss_radius**4 - bore_radius**4) / 4
    return force * math.sqrt(1 + friction**2) / area + moment * boss_radius / inertia


def seat_angle(boss_radius: Any, radius: Any, thickness: Any, ops: Any) -> Any:
    """Half-angle at O of the boss seat on the cap's inner sphere [rad]."""
    return ops.asin(ops.fmin(boss_radius / (radius - thickness), 1.0))
