"""The closed-form solutions of fem_frac.verify.exact checked against their own limits and each
other (Hill's plastic sphere against Lamé's elastic one)."""

import numpy as np
import pytest

from fem_frac.verify.exact import (
    hill_sphere_outer_displacement,
    hill_sphere_plastic_radius,
    hill_sphere_pressure,
    hill_sphere_stress,
    lame_sphere_radial_displacement,
)

A, B, SY, E, NU = 1.0, 2.0, 240.0, 210e3, 0.3


def test_pressure_of_the_plastic_radius_gives_first_yield_and_limit_load():
    p_e = 2 * SY / 3 * (1 - A**3 / B**3)
    p_l = 2 * SY * np.log(B / A)
    assert hill_sphere_pressure(A, A, B, SY) == pytest.approx(p_e, rel=1e-14)
    assert hill_sphere_pressure(B, A, B, SY) == pytest.approx(p_l, rel=1e-14)
    c = np.linspace(A, B, 101)
    assert np.all(np.diff(hill_sphere_pressure(c, A, B, SY)) > 0)  # one root per pressure


@pytest.mark.parametrize("c", [1.0001, 1.2, 1.5, 1.9, 1.9999])
def test_plastic_radius_inverts_the_pressure(c):
    p = float(hill_sphere_pressure(c, A, B, SY))
    assert hill_sphere_plastic_radius(p, A, B, SY) == pytest.approx(c, rel=1e-12)


def test_plastic_radius_outside_the_plastic_range():
    assert hill_sphere_plastic_radius(100.0, A, B, SY) == A  # below p_e = 140: elastic
    with pytest.raises(ValueError, match="limit load"):
        hill_sphere_plastic_radius(2 * SY * np.log(B / A), A, B, SY)


@pytest.mark.parametrize("nu", [0.0, 0.3, 0.49])
def test_outer_displacement_continues_lame_at_first_yield(nu):
    p_e = float(hill_sphere_pressure(A, A, B, SY))
    lame = lame_sphere_radial_displacement(B, A, B, p_e, E, nu)
    assert hill_sphere_outer_displacement(A, B, SY, E, nu) == pytest.approx(lame, rel=1e-13)


def test_outer_displacement_is_lame_of_the_elastic_shell_at_yield():
    """The shell c..b under the radial stress on r = c that puts it at yield."""
    c = 1.5
    q = 2 * SY / 3 * (1 - c**3 / B**3)
    lame = lame_sphere_radial_displacement(B, c, B, q, E, NU)
    assert hill_sphere_outer_displacement(c, B, SY, E, NU) == pytest.approx(lame, rel=1e-13)


def test_stress_satisfies_boundary_conditions_equilibrium_and_yield():
    c = 1.5
    p = float(hill_sphere_pressure(c, A, B, SY))
    sr_a, _ = hill_sphere_stress(A, p, A, B, SY)
    sr_b, _ = hill_sphere_stress(B, p, A, B, SY)
    assert sr_a == pytest.approx(-p, rel=1e-14)
    assert abs(sr_b) < 1e-12 * p
    # continuous across r = c, at yield up to it and below yield beyond it
    r = np.linspace(A, B, 2001)
    sr, st = hill_sphere_stress(r, p, A, B, SY)
    assert np.max(np.abs(np.diff(sr))) < 1e-2 * p
    assert np.max(np.abs(np.diff(st))) < 1e-2 * p
    eq = st - sr
    assert np.allclose(eq[r <= c], SY, rtol=1e-13)
    assert np.all(eq[r > c] < SY)
    # equilibrium d sigma_r / dr = 2 (sigma_theta - sigma_r) / r (central differences)
    h = 1e-5
    rm = np.array([1.1, 1.4, 1.6, 1.9])
    d = (hill_sphere_stress(rm + h, p, A, B, SY)[0] - hill_sphere_stress(rm - h, p, A, B, SY)[0])
    sr_m, st_m = hill_sphere_stress(rm, p, A, B, SY)
    assert np.allclose(d / (2 * h), 2 * (st_m - sr_m) / rm, rtol=1e-7)


def test_stress_below_first_yield_is_lame():
    p = 100.0
    sr, st = hill_sphere_stress(np.array([A, B]), p, A, B, SY)
    assert sr[0] == pytest.approx(-p) and abs(sr[1]) < 1e-12 * p
    assert np.all(st - sr < SY)
