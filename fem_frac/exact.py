"""Closed-form solutions used to verify the solver."""

from __future__ import annotations

import numpy as np


def shear_coefficient_rectangle(poissons_ratio: float) -> float:
    """Timoshenko shear coefficient of a rectangular section (Cowper 1966)."""
    nu = poissons_ratio
    return 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu)


def cantilever_tip_deflection(
    force: float, length: float, width: float, height: float, youngs_modulus: float,
    poissons_ratio: float,
) -> float:
    """Tip deflection of an end-loaded cantilever of rectangular section (Timoshenko beam):
    bending ``P L^3 / (3 E I)`` plus shear ``P L / (k G A)``. ``height`` is the depth in the
    direction of the load."""
    e, nu = youngs_modulus, poissons_ratio
    inertia = width * height**3 / 12.0
    area = width * height
    shear_modulus = e / (2.0 * (1.0 + nu))
    k = shear_coefficient_rectangle(nu)
    return force * length**3 / (3 * e * inertia) + force * length / (k * shear_modulus * area)


def lame_sphere_radial_displacement(
    r: np.ndarray, inner_radius: float, outer_radius: float, pressure: float,
    youngs_modulus: float, poissons_ratio: float,
) -> np.ndarray:
    """Radial displacement of a thick-walled sphere under internal pressure (Lamé)."""
    a, b, p, e, nu = inner_radius, outer_radius, pressure, youngs_modulus, poissons_ratio
    c = p * a**3 / (e * (b**3 - a**3))
    return c * ((1.0 - 2.0 * nu) * r + (1.0 + nu) * b**3 / (2.0 * r**2))


def lame_sphere_displacement(
    x: np.ndarray, center, inner_radius: float, outer_radius: float, pressure: float,
    youngs_modulus: float, poissons_ratio: float,
) -> np.ndarray:
    """Displacement vectors ``(3, ...)`` at points ``x`` ``(3, ...)`` (Lamé sphere)."""
    d = x - np.asarray(center, dtype=float).reshape((3,) + (1,) * (x.ndim - 1))
    r = np.linalg.norm(d, axis=0)
    ur = lame_sphere_radial_displacement(
        r, inner_radius, outer_radius, pressure, youngs_modulus, poissons_ratio
    )
    return d * (ur / r)
