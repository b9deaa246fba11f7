"""Collision geometry of the cap for simulators: a row of spheres along its sagittal arc.

The real cap only has material over its angles [low, high]; a full sphere of radius R lets a
simulator's ground touch the foot anywhere on that sphere. URDF has spheres but no capsules,
and MuJoCo and Pinocchio (hpp-fcl/coal) both load URDF spheres, so the cap is exported as N
spheres of radius r_s = :data:`SPHERE_FRACTION` R whose centres lie on the arc of radius
R - r_s about the cap's centre O, at angles evenly spaced from low to high: each sphere touches
the cap's outer sphere at its own angle, and the end spheres touch it at the cap's edges.

How closely it follows the cap (all reported):

* in the sagittal plane, between two neighbours (angular spacing delta) the union's surface dips
  radially below the cap's sphere by at most R - (R - r_s) cos(delta/2) - sqrt(r_s^2 - (R - r_s)^2
  sin^2(delta/2)); N is the smallest count that keeps this within the tolerance. What a flat
  ground meets is the union's support distance, which falls short by less, (R - r_s)(1 - cos(delta/2));
* sideways (roll angle psi) the row's support falls short of the cap's sphere by up to
  (R - r_s)(1 - cos(delta/2) cos psi) (the worst is between two spheres);
* beyond the cap's angles (by Delta) the ground can only meet the end spheres, whose reach
  exceeds the cap's rim by r_s (1 - cos Delta) (a full sphere: R (1 - cos Delta)); there is no
  collision surface past the end spheres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from hound_id.errors import SpecError
from hound_id.foot.geometry import FootGeometry

#: Radius of the collision spheres over the cap's radius (hound-id's choice: halves the reach past the ends
#: of a full sphere while keeping the roll deviation small).
SPHERE_FRACTION = 0.5
#: Angle past the cap's ends at which the reach beyond the rim is reported [rad].
OVERREACH_ANGLE = math.radians(15.0)
#: Most spheres one foot gets.
MAX_SPHERES = 64


@dataclass(frozen=True)
class CollisionSpheres:
    """The spheres of one foot, in the foot frame, and how closely they follow the cap, SI."""

    spheres: tuple[tuple[float, float, float, float], ...]
    """(x, y, z, r) of each sphere [m]."""
    tolerance: float
    """Largest sagittal dip asked for [m]."""
    sagittal_deviation: float
    """Largest radial dip of the union's surface below the cap's sphere over its angles, sagittal plane [m]."""
    ground_deviation: float
    """Largest shortfall of the support distance (where a flat ground touches) over the cap's angles [m]."""
    roll_deviation: float
    """Radial shortfall at the required roll angle [m]."""
    edge_deviation: float
    """Radial shortfall at the cap's lateral edge, asin(W / 2R) [m]."""
    overreach: float
    """Reach beyond the cap's rim at :data:`OVERREACH_ANGLE` past its ends [m]."""
    full_sphere_overreach: float
    """The same for the full sphere exported before [m]."""

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": "spheres",
            "spheres": [list(s) for s in self.spheres],
            "count": len(self.spheres),
            "sphere_radius": self.spheres[0][3],
            "tolerance": self.tolerance,
            "sagittal_deviation": self.sagittal_deviation,
            "ground_deviation": self.ground_deviation,
            "roll_deviation": self.roll_deviation,
            "edge_deviation": self.edge_deviation,
            "overreach_angle": OVERREACH_ANGLE,
            "overreach": self.overreach,
            "full_sphere_overreach": self.full_sphere_overreach,
            "meaning": "spheres (x, y, z, r) in the foot frame along the cap's sagittal arc; deviations are radial "
            "distances below the cap's outer sphere (sagittal: of the surface over the cap's angles; ground: of the "
            "support distance a flat ground meets; roll: at the required roll; "
            "edge: at the cap's lateral edge); outside the cap's angles only the end spheres can touch, reaching "
            "'overreach' past the rim at 'overreach_angle' beyond the end (a full sphere: 'full_sphere_overreach')",
        }


def sagittal_dip(radius: float, sphere_radius: float, spacing: float) -> float:
    """Largest radial dip of two neighbouring spheres below the cap's sphere [m] (module docstring)."""
    c, half = radius - sphere_radius, spacing / 2
    reach = c * math.cos(half) + math.sqrt(max(sphere_radius**2 - (c * math.sin(half)) ** 2, 0.0))
    return radius - reach


def collision_spheres(geometry: FootGeometry, tolerance: float, roll: float) -> CollisionSpheres:
    """The row of spheres along the cap's arc (module docstring).

    Args:
        geometry: The foot.
        tolerance: Largest sagittal dip between neighbours [m].
        roll: The roll angle the cap covers [rad], for the reported roll deviation.
    """
    if not (math.isfinite(tolerance) and 0 < tolerance < geometry.radius):
        raise SpecError(
            f"--collision-tolerance: found {tolerance * 1e3:g} mm, expected more than 0 and less than the cap's "
            f"radius {geometry.radius * 1e3:.1f} mm"
        )
    R, lo, hi = geometry.radius, geometry.low, geometry.high
    rs = SPHERE_FRACTION * R
    n = 2
    while sagittal_dip(R, rs, (hi - lo) / (n - 1)) > tolerance:
        n += 1
        if n > MAX_SPHERES:
            raise SpecError(
                f"--collision-tolerance: {tolerance * 1e3:g} mm needs more than {MAX_SPHERES} spheres on a "
                f"{math.degrees(hi - lo):.0f} deg cap of radius {R * 1e3:.1f} mm; raise the tolerance"
            )
    c = R - rs
    spheres = tuple(
        (c * math.sin(phi), 0.0, geometry.centre_z - c * math.cos(phi), rs)
        for phi in (lo + (hi - lo) * k / (n - 1) for k in range(n))
    )
    edge = math.asin(min(1.0, geometry.width / (2 * R)))
    half = (hi - lo) / (n - 1) / 2  # half the spacing: the farthest any direction is from a sphere
    return CollisionSpheres(
        spheres=spheres,
        tolerance=tolerance,
        sagittal_deviation=sagittal_dip(R, rs, (hi - lo) / (n - 1)),
        ground_deviation=c * (1 - math.cos(half)),
        roll_deviation=c * (1 - math.cos(half) * math.cos(roll)),
        edge_deviation=c * (1 - math.cos(half) * math.cos(edge)),
        overreach=rs * (1 - math.cos(OVERREACH_ANGLE)),
        full_sphere_overreach=R * (1 - math.cos(OVERREACH_ANGLE)),
    )
