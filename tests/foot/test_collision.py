"""The collision spheres follow the cap: sampled support distances against the stated deviations,
and both simulators load them (Pinocchio from the patched URDF, MuJoCo compiling it)."""

import math

import numpy as np
import pytest

from hound_id.errors import SpecError
from hound_id.foot.collision import OVERREACH_ANGLE, collision_spheres
from hound_id.foot.geometry import FootGeometry, MassProperties

G = FootGeometry(radius=0.031, thickness=0.0024, width=0.046, low=-0.986, high=0.349, boss_radius=0.005,
                 centre_z=0.0009, bore_radius=0.00165)  # fmt: skip


def reach(spheres, zc, phi, psi=0.0):
    """How far from the cap's centre the union of spheres reaches along the direction (phi sagittal, psi roll)."""
    u = np.array([math.sin(phi) * math.cos(psi), math.sin(psi), -math.cos(phi) * math.cos(psi)])
    return max(float(np.dot(np.array([x, y, z - zc]), u)) + r for x, y, z, r in spheres)


def surface(spheres, zc, phi):
    """Distance from the cap's centre to the union's surface along the ray at phi (sagittal plane)."""
    u = np.array([math.sin(phi), 0.0, -math.cos(phi)])
    out = 0.0
    for x, y, z, r in spheres:
        p = np.array([x, y, z - zc])
        disc = r**2 - float(p @ p) + float(p @ u) ** 2
        if disc >= 0:
            out = max(out, float(p @ u) + math.sqrt(disc))
    return out


def test_sagittal_dip_roll_and_ends_are_what_the_report_says():
    col = collision_spheres(G, 1e-4, math.radians(10))
    s = col.spheres
    phis = np.linspace(G.low, G.high, 4001)
    dips = [G.radius - reach(s, G.centre_z, phi) for phi in phis]
    assert max(dips) == pytest.approx(col.ground_deviation, rel=1e-4)
    assert min(dips) == pytest.approx(0.0, abs=1e-12)  # each sphere touches the cap's sphere
    assert max(G.radius - surface(s, G.centre_z, phi) for phi in phis) == pytest.approx(
        col.sagittal_deviation, rel=1e-4
    )
    assert col.ground_deviation < col.sagittal_deviation <= 1e-4
    rolled = max(G.radius - reach(s, G.centre_z, phi, math.radians(10)) for phi in phis)
    assert rolled == pytest.approx(col.roll_deviation, rel=1e-4)
    # past the ends only the end sphere reaches, r_s (1 - cos) beyond the rim's reach R cos
    for end, sign in ((G.low, -1.0), (G.high, 1.0)):
        phi = end + sign * OVERREACH_ANGLE
        assert reach(s, G.centre_z, phi) - G.radius * math.cos(OVERREACH_ANGLE) == pytest.approx(col.overreach)
    assert col.overreach == pytest.approx(col.full_sphere_overreach / 2)  # r_s = R / 2
    # a finer tolerance needs more spheres
    assert len(collision_spheres(G, 2e-5, 0.0).spheres) > len(s)
    with pytest.raises(SpecError, match="--collision-tolerance"):
        collision_spheres(G, 1e-9, 0.0)


def test_both_simulators_load_the_spheres(tmp_path):
    import mujoco
    import pinocchio as pin

    from hound_id.foot.urdf import patched_urdf, read_foot
    from tests.conftest import SAMPLES

    mount = read_foot(SAMPLES / "legs" / "hound_leg.urdf")
    col = collision_spheres(G, 1e-4, 0.0)
    props = MassProperties(mass=0.02, com=np.array([0.0, 0.0, -0.02]), inertia=np.eye(3) * 1e-6)
    text = patched_urdf(mount, props, mesh_filename="foot.stl", spheres=col.spheres, comment="test")
    model = pin.buildModelFromXML(text)
    geom = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.COLLISION)
    assert geom.ngeoms == len(col.spheres)
    no_visual = text.replace('<mesh filename="foot.stl" />', '<sphere radius="0.001" />')
    mj = mujoco.MjModel.from_xml_string(no_visual)
    spheres = [
        g for g in range(mj.ngeom) if mj.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE and mj.geom_size[g, 0] > 0.002
    ]
    assert len(spheres) == len(col.spheres)
    assert sorted(mj.geom_size[spheres, 0]) == pytest.approx([s[3] for s in col.spheres])
