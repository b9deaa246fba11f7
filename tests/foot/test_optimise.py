"""The casadi optimisation: feasibility, optimality against random feasible designs, clear refusals."""

import math
from dataclasses import replace

import numpy as np
import pytest

from hound_id.errors import SpecError
from hound_id.foot.angles import given_angles
from hound_id.foot.geometry import FootGeometry
from hound_id.foot.material import GROUNDS, MATERIALS
from hound_id.foot.optimise import FootRequirements, evaluate, hertz_min_radius, optimise_foot
from hound_id.foot.urdf import read_foot
from tests.conftest import SAMPLES

LEG = SAMPLES / "legs" / "hound_leg.urdf"


@pytest.fixture(scope="module")
def mount():
    return read_foot(LEG)


def requirements(attack=-50.0, detach=15.0, **kw):
    a = given_angles(attack, detach, 5.0)
    base = dict(low=a.low, high=a.high, material=MATERIALS["aluminium_7075_t6"], ground=GROUNDS["concrete"],
                peak_force=1500.0)  # fmt: skip
    return FootRequirements(**(base | kw))


def test_every_constraint_holds_at_the_optimum(mount):
    req = requirements()
    design = optimise_foot(mount, req)
    assert design.feasible and design.solver["status"] == "Solve_Succeeded"
    c = {k.name: k for k in design.constraints}
    assert all(k.margin >= -1e-7 * max(1.0, abs(k.limit)) for k in design.constraints)
    # the physics that binds: the smallest radius the contact stress allows, the leg length kept
    assert design.geometry.radius == pytest.approx(hertz_min_radius(req), rel=1e-6)
    # the cap ends one shell characteristic length past the arc (the interior bending formula holds there)
    assert c["coverage_touchdown"].value < req.low
    assert c["shell_edge_touchdown"].margin == pytest.approx(0.0, abs=1e-9)
    # the strength checks bind: the wall (bending under the load), the boss (at the mount), the cap at the boss
    for name in ("shell_bending", "boss_stress", "shell_root_touchdown"):
        assert c[name].value == pytest.approx(req.allowed_stress, rel=1e-6)
    assert c["leg_length"].value == pytest.approx(mount.mount_length + mount.contact_radius, abs=1e-9)
    assert design.geometry.thickness >= req.material.min_wall - 1e-9
    # the objective the solver reports is the closed-form knee inertia of the foot
    assert design.solver["objective"] == pytest.approx(design.knee_inertia, rel=1e-9)
    assert design.knee_inertia < 0.2 * mount.foot.about_axis_y((0, 0, mount.mount_length))


def test_no_random_feasible_design_nearby_is_better(mount):
    """A local-optimality check that does not trust IPOPT: perturb, keep the feasible, compare."""
    req = requirements()
    design = optimise_foot(mount, req)
    g0 = design.geometry
    rng = np.random.default_rng(3)
    better = feasible = 0
    for _ in range(6000):
        scale = rng.choice([1e-3, 1e-2, 5e-2])
        R = g0.radius * (1 + scale * rng.normal())
        g = FootGeometry(
            radius=R, thickness=g0.thickness * (1 + scale * rng.normal()), width=g0.width * (1 + scale * rng.normal()),
            low=g0.low + scale * rng.normal(), high=g0.high + scale * rng.normal(),
            boss_radius=g0.boss_radius * (1 + scale * rng.normal()), bore_radius=g0.bore_radius,
            centre_z=R - mount.contact_radius,  # on the leg-length equality
        )  # fmt: skip
        try:
            g.check()
        except SpecError:
            continue
        if not all(c.satisfied for c in evaluate(g, mount, req)):
            continue
        feasible += 1
        from hound_id.foot.geometry import mass_properties

        knee = mass_properties(g, req.material.density).about_axis_y((0, 0, mount.mount_length))
        better += knee < design.knee_inertia * (1 - 1e-6)
    assert feasible > 30
    assert better == 0


def test_options_move_the_optimum_the_right_way(mount):
    base = optimise_foot(mount, requirements())
    heavier_load = optimise_foot(mount, requirements(peak_force=2000.0))
    assert heavier_load.geometry.radius > base.geometry.radius
    wider_roll = optimise_foot(mount, requirements(roll=math.radians(60)))
    assert wider_roll.geometry.width > base.geometry.width
    fixed = optimise_foot(mount, requirements(radius=0.05, length_tolerance=0.01))
    assert fixed.geometry.radius == pytest.approx(0.05) and fixed.feasible
    # with the leg length kept, a larger sphere's centre sits higher above the mount
    assert fixed.geometry.centre_z == pytest.approx(0.05 - mount.contact_radius, abs=1e-9)
    tilted = optimise_foot(mount, requirements(nominal_angle=math.radians(20), length_tolerance=0.01))
    c = {k.name: k for k in tilted.constraints}["leg_length"]
    assert c.value == pytest.approx(mount.mount_length * math.cos(math.radians(20)) + mount.contact_radius, abs=1e-9)
    weighted = optimise_foot(mount, requirements(mass_weight=1.0))
    assert weighted.feasible and weighted.properties.mass <= base.properties.mass * (1 + 1e-6)


@pytest.mark.parametrize(
    ("material", "force"),
    [("steel_17_4ph_h900", 100.0), ("steel_17_4ph_h900", 200.0), ("aluminium_7075_t6", 50.0),
     ("aluminium_7075_t6", 300.0), ("titanium_ti6al4v", 50.0), ("pa12_sls", 40.0)],
)  # fmt: skip
def test_light_loads_give_small_feet_held_by_the_leg_length_over_the_stance(mount, material, force):
    """Low forces let the Hertz radius fall below the original's; then keeping the leg length over the
    whole contact arc binds, not the contact stress (these cases once hit a NaN derivative)."""
    req = requirements(material=MATERIALS[material], peak_force=force)
    design = optimise_foot(mount, req)
    c = {k.name: k for k in design.constraints}
    assert design.feasible and design.geometry.radius >= hertz_min_radius(req) * (1 - 1e-9)
    assert c["leg_length_stance"].value <= req.length_tolerance * (1 + 1e-7)
    if hertz_min_radius(req) < 0.025:
        # |R - r0| (1 - cos(theta_end)) = tolerance at the worst end of the arc
        worst = max(1 - math.cos(req.low), 1 - math.cos(req.high))
        assert design.geometry.radius == pytest.approx(mount.contact_radius - req.length_tolerance / worst, rel=1e-6)


def test_a_radius_too_small_for_the_load_is_refused(mount):
    with pytest.raises(SpecError, match=r"--radius 20.0 mm is too small for the load.*at least 30.9 mm"):
        optimise_foot(mount, requirements(radius=0.02))
    with pytest.raises(SpecError, match=r"--max-radius 25.0 mm is too small for the load"):
        optimise_foot(mount, requirements(max_radius=0.025))
    with pytest.raises(SpecError, match="--max-radius"):
        optimise_foot(mount, requirements(max_radius=0.05, peak_force=20000.0))


def test_a_sphere_too_large_for_the_leg_length_is_refused_up_front(mount):
    # 3 kN needs R >= 43.6 mm: 13.6 mm over the original, (1 - cos 55 deg) of that over the arc
    with pytest.raises(
        SpecError, match=r"Hertz minimum radius 43.6 mm .* change by 5.8 mm, more than --length-tolerance"
    ):
        optimise_foot(mount, requirements(peak_force=3000.0))
    assert optimise_foot(mount, requirements(peak_force=3000.0, length_tolerance=0.006)).feasible


def test_requests_no_design_can_meet_are_refused(mount):
    with pytest.raises(SpecError, match="must span between 0 and 180 deg"):
        optimise_foot(mount, replace(requirements(), low=-1.7, high=1.6))
    with pytest.raises(SpecError, match="--grf > 0"):
        optimise_foot(mount, requirements(peak_force=-5.0))
    # a boss too fat for any cap that keeps the leg length: IPOPT fails, the violated constraints are named
    with pytest.raises(
        SpecError, match="no design found that meets every constraint.*violated at its last point: .*boss_width"
    ):
        optimise_foot(mount, requirements(boss_radius=0.2, max_radius=0.12))
