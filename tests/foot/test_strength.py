"""The strength formulas against independent computations: numeric section integrals, Westergaard's own
numeric form, the rectangular curved beam, statics by cross products, and the ISO thread table."""

import math

import numpy as np
import pytest

from hound_id.errors import SpecError
from hound_id.foot.geometry import FLOAT_OPS
from hound_id.foot.strength import (
    band_section,
    boss_moment,
    boss_stress,
    fastener,
    local_bending_stress,
    root_bending_stress,
)


def numeric_section(R, t, W, n=2001):
    """The band section's integrals on a fine grid of (y, s) strips: nothing shared with the closed form."""
    rho, w = R - t, W / 2
    y = np.linspace(-w, w, n)
    s_in = np.sqrt(np.clip(rho**2 - y**2, 0, None))
    s_out = np.sqrt(R**2 - y**2)
    area = np.trapezoid(s_out - s_in, y)
    s1 = np.trapezoid((s_out**2 - s_in**2) / 2, y)
    s2 = np.trapezoid((s_out**3 - s_in**3) / 3, y)
    recip = np.trapezoid(np.log(s_out / s_in), y)
    return area, s1 / area, s2 - s1**2 / area, area / recip


@pytest.mark.parametrize(("R", "t", "W"), [(0.031, 0.0024, 0.046), (0.03, 0.006, 0.02), (0.05, 0.002, 0.09)])
def test_band_section_matches_numeric_integrals(R, t, W):
    sec = band_section(R, t, W, FLOAT_OPS)
    area, sc, inertia, rn = numeric_section(R, t, W)
    assert sec["A"] == pytest.approx(area, rel=1e-5)
    assert sec["s_c"] == pytest.approx(sc, rel=1e-6)
    assert sec["I"] == pytest.approx(inertia, rel=1e-3)
    assert sec["r_n"] == pytest.approx(rn, rel=1e-5)  # the grid's error near the steep ends of ln(s_out / s_in)
    assert sec["s_min"] == pytest.approx(math.sqrt((R - t) ** 2 - (W / 2) ** 2))


def test_a_narrow_band_is_a_rectangular_curved_beam():
    """W << R: the section is a t x W rectangle between R - t and R; Winkler-Bach's r_n = t / ln(R / (R - t))."""
    R, t, W = 0.03, 0.01, 1e-4
    sec = band_section(R, t, W, FLOAT_OPS)
    assert sec["A"] == pytest.approx(t * W, rel=1e-5)
    assert sec["r_n"] == pytest.approx(t / math.log(R / (R - t)), rel=1e-6)
    # pure moment M on the rectangle: inner-fibre stress M (r_n - a) / (A e a) (Roark Table 9.1's basis)
    M, a = 1.0, R - t
    e = (R - t / 2) - t / math.log(R / a)
    expected_inner = M * (sec["r_n"] - a) / (t * W * e * a)
    # a contact at Delta = 90 deg with no friction loads the cut with F s_c (moment) and F (normal)
    F = M / sec["s_c"]
    stress = root_bending_stress(F, 0.0, R, sec, math.pi / 2, FLOAT_OPS)
    assert stress == pytest.approx(F / sec["A"] + expected_inner, rel=1e-3)


def test_root_resultant_is_statics():
    """Moment of the contact force about the section's centroid by a cross product, at many angles."""
    R, t, W, F, mu = 0.031, 0.0024, 0.046, 1500.0, 0.6
    sec = band_section(R, t, W, FLOAT_OPS)
    sc = sec["s_c"]
    for delta in np.linspace(0.05, 1.2, 7):
        # frame: the cut along +x from O, the contact at angle delta from it; force towards O plus friction
        p = R * np.array([math.cos(delta), math.sin(delta)])
        n = -p / R
        tangent = np.array([-math.sin(delta), math.cos(delta)])
        c = np.array([sc, 0.0])
        moments, normals = [], []
        for sign in (-1.0, 1.0):
            force = F * n + sign * mu * F * tangent
            r = p - c
            moments.append(abs(r[0] * force[1] - r[1] * force[0]))
            normals.append(abs(force[1]))  # the cut's normal is y
        # |a +- b| is at most |a| + |b|, and one friction direction attains it
        assert max(moments) == pytest.approx(F * sc * math.sin(delta) + mu * F * abs(R - sc * math.cos(delta)))
        assert max(normals) == pytest.approx(F * math.sin(delta) + mu * F * math.cos(delta))


def test_local_bending_is_westergaards_interior_formula():
    """Westergaard's numeric form for nu = 0.15: sigma = 0.316 P / h^2 (4 log10(l / b) + 1.069)."""
    F, R, t, c, nu = 1000.0, 0.04, 0.002, 0.005, 0.15  # c > 1.724 t: b = c
    sigma = local_bending_stress(F, R, t, c, nu, FLOAT_OPS)
    rm = R - t / 2
    ell = (rm**2 * t**2 / (12 * (1 - nu**2))) ** 0.25
    assert sigma == pytest.approx(0.316 * F / t**2 * (4 * math.log10(ell / c) + 1.069), rel=2e-3)
    # a load circle below 1.724 t uses the equivalent radius (thicker walls spread the load)
    small = local_bending_stress(F, R, t, 0.001, nu, FLOAT_OPS)
    b = math.sqrt(1.6 * 0.001**2 + t**2) - 0.675 * t
    assert small == pytest.approx(3 * (1 + nu) * F / (2 * math.pi * t**2) * (math.log(ell / b) + 0.6159), rel=1e-4)


def test_boss_stress_of_a_solid_section_by_hand():
    F, mu, r = 1500.0, 0.6, 0.005
    M = boss_moment(F, mu, 0.031, 0.001, -1.0, 0.4, FLOAT_OPS)
    assert M == pytest.approx(F * 0.001 * math.sin(1.0) + mu * F * 0.032)
    sigma = boss_stress(F, mu, r, 0.0, M)
    assert sigma == pytest.approx(F * math.sqrt(1 + mu**2) / (math.pi * r**2) + 4 * M / (math.pi * r**3))
    assert boss_stress(F, mu, r, 0.002, M) > sigma  # a bore weakens it


def test_fasteners_from_the_iso_table():
    m4 = fastener("M4")
    assert m4 is not None and (m4.pitch, m4.bore_radius) == pytest.approx((0.7e-3, 1.65e-3))
    assert (m4.min_boss_radius, m4.engagement) == pytest.approx((4e-3, 8e-3))
    assert fastener("m3", wall=1e-3).min_boss_radius == pytest.approx(2.5e-3)
    assert fastener("none") is None
    with pytest.raises(SpecError, match="--bolt: found 'M7'"):
        fastener("M7")
    with pytest.raises(SpecError, match="--thread-engagement"):
        fastener("M4", engagement=0.5)
