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


# --- thick-walled sphere, elastic-perfectly plastic (Hill 1950, ch. V) --------------------
#
# Small strain, internal pressure p on r = a, outer surface r = b free. The stress is
# spherically symmetric with sigma_theta = sigma_phi > sigma_r, so von Mises and Tresca
# coincide (equivalent stress sigma_theta - sigma_r) and the plastic zone a <= r <= c is
# statically determined: equilibrium d sigma_r / dr = 2 (sigma_theta - sigma_r) / r with
# sigma_theta - sigma_r = sigma_Y. The shell c <= r <= b is elastic (Lamé) and at yield on
# r = c. Loading is monotonic, so no point unloads and the solution is path independent.


def hill_sphere_pressure(
    plastic_radius, inner_radius: float, outer_radius: float, yield_stress: float
):
    """Internal pressure at which the plastic zone of a thick sphere reaches
    ``plastic_radius`` c (Hill 1950, ch. V):

        p(c) = 2 sigma_Y [ln(c / a) + (1 - c^3 / b^3) / 3].

    ``c = a`` gives first yield ``p_e = (2 sigma_Y / 3)(1 - a^3 / b^3)``; ``c = b`` the limit
    load ``p_L = 2 sigma_Y ln(b / a)``. Increasing in c on [a, b]. Accepts arrays.
    """
    c = np.asarray(plastic_radius, dtype=float)
    a, b, s = inner_radius, outer_radius, yield_stress
    return 2.0 * s * (np.log(c / a) + (1.0 - c**3 / b**3) / 3.0)


def hill_sphere_plastic_radius(
    pressure: float, inner_radius: float, outer_radius: float, yield_stress: float
) -> float:
    """Radius c of the plastic zone under internal ``pressure`` p: the root of
    ``hill_sphere_pressure(c) = p`` on [a, b] (Newton safeguarded by bisection, to round-off;
    scipy.optimize would cost a run 0.1 s of imports for this one root).

    Returns ``a`` (no plastic zone) for ``p <= p_e``; raises ``ValueError`` for
    ``p >= p_L`` (no equilibrium: the whole wall flows).
    """
    a, b, s = inner_radius, outer_radius, yield_stress
    p_e = hill_sphere_pressure(a, a, b, s)
    p_l = hill_sphere_pressure(b, a, b, s)
    if pressure <= p_e:
        return float(a)
    if pressure >= p_l:
        raise ValueError(
            f"pressure {pressure:g} is at or above the limit load {p_l:g} = 2 sigma_Y ln(b/a)"
        )
    lo, hi, c = float(a), float(b), 0.5 * (a + b)
    for _ in range(200):
        residual = float(hill_sphere_pressure(c, a, b, s)) - pressure
        if residual == 0.0:
            break
        if residual > 0.0:
            hi = c
        else:
            lo = c
        slope = 2.0 * s * (1.0 / c - c**2 / b**3)  # dp/dc > 0 inside (a, b)
        new = c - residual / slope
        if not lo < new < hi:
            new = 0.5 * (lo + hi)
        tiny = 4.0 * np.finfo(float).eps * b
        c, step = new, abs(new - c)
        if step <= tiny or hi - lo <= tiny:
            break
    return float(c)


def hill_sphere_outer_displacement(
    plastic_radius: float, outer_radius: float, yield_stress: float, youngs_modulus: float,
    poissons_ratio: float,
) -> float:
    """Radial displacement of the outer surface r = b once the plastic zone reaches
    ``plastic_radius`` c:

        u_b = sigma_Y (1 - nu) c^3 / (E b^2).

    The shell c <= r <= b is elastic, free at r = b and loaded on r = c by the radial stress
    that puts it at yield there, ``(2 sigma_Y / 3)(1 - c^3 / b^3)``; this is Lamé's outer
    displacement of that shell. It does not depend on the plastic flow inside r < c. At
    ``c = a`` it equals Lamé's solution of the whole wall under the first-yield pressure.
    """
    c, b = plastic_radius, outer_radius
    return yield_stress * (1.0 - poissons_ratio) * c**3 / (youngs_modulus * b**2)


def hill_sphere_stress(
    r, pressure: float, inner_radius: float, outer_radius: float, yield_stress: float
) -> tuple[np.ndarray, np.ndarray]:
    """Radial and hoop stresses ``(sigma_r, sigma_theta)`` at radii ``r`` (arrays) under
    internal ``pressure`` (tension positive). Plastic zone ``a <= r <= c``:

        sigma_r = -p + 2 sigma_Y ln(r / a),   sigma_theta = sigma_r + sigma_Y;

    elastic shell ``c <= r <= b`` (Lamé, at yield on r = c):

        sigma_r = -(2 sigma_Y / 3)(c^3 / r^3 - c^3 / b^3),
        sigma_theta = (2 sigma_Y / 3)(c^3 / (2 r^3) + c^3 / b^3),

    with c from :func:`hill_sphere_plastic_radius`. For ``p <= p_e`` (no plastic zone) they
    are Lamé's elastic stresses under p.
    """
    r = np.asarray(r, dtype=float)
    a, b, s, p = inner_radius, outer_radius, yield_stress, pressure
    c = hill_sphere_plastic_radius(p, a, b, s)
    if c == a:  # elastic: Lamé, proportional to p
        k = p * a**3 / (b**3 - a**3)
        return -k * (b**3 / r**3 - 1.0), k * (b**3 / (2.0 * r**3) + 1.0)
    plastic = r <= c
    sr_p = -p + 2.0 * s * np.log(r / a)
    sr_e = -(2.0 * s / 3.0) * (c**3 / r**3 - c**3 / b**3)
    st_e = (2.0 * s / 3.0) * (c**3 / (2.0 * r**3) + c**3 / b**3)
    return np.where(plastic, sr_p, sr_e), np.where(plastic, sr_p + s, st_e)


def uniaxial_stress(strains, youngs_modulus: float, plasticity=None) -> float:
    """Exact axial stress of a homogeneous bar in uniaxial stress after the axial strain
    history ``strains``: the 1D return map |sigma - K eps_p| <= sigma_Y + H alpha
    (``plasticity``: an object with ``yield_stress``, ``hardening`` H and
    ``kinematic_hardening`` K; elastic when ``None``)."""
    e, p = youngs_modulus, plasticity
    sigma, plastic, alpha = 0.0, 0.0, 0.0
    for eps in strains:
        sigma = e * (eps - plastic)
        if p is None:
            continue
        xi = sigma - p.kinematic_hardening * plastic
        f = abs(xi) - (p.yield_stress + p.hardening * alpha)
        if f > 0:
            dg = f / (e + p.hardening + p.kinematic_hardening)
            plastic += dg * np.sign(xi)
            alpha += dg
            sigma -= e * dg * np.sign(xi)
    return float(sigma)


def fundamental_period(times, signal) -> float:
    """Twice the mean spacing of the zero crossings of ``signal`` (linear interpolation
    between samples; the first sample, at rest, is skipped); ``nan`` below three
    crossings."""
    t, s = np.asarray(times[1:], dtype=float), np.asarray(signal[1:], dtype=float)
    k = np.flatnonzero(np.sign(s[:-1]) * np.sign(s[1:]) < 0)
    if len(k) < 3:
        return float("nan")
    crossings = t[k] - s[k] * (t[k + 1] - t[k]) / (s[k + 1] - s[k])
    return float(2.0 * np.mean(np.diff(crossings)))
