"""Cohesive traction-separation law: analytic paths, energy balance, consistent tangent."""

import numpy as np
import pytest
from scipy.integrate import quad

from fem_frac.cohesive import CohesiveResponse, TractionSeparation
from fem_frac.cohesive.law import C_M, M

SIGMA, GC = 3.0e6, 100.0  # Pa, J/m^2
K_MIN = SIGMA**2 / (2.0 * GC)  # the smallest admissible initial stiffness
KINDS = ["linear", "exponential"]


def analytic_envelope(kind, lam, k0):
    """The envelope written out from its definition, independently of the module."""
    lam0 = SIGMA / k0
    if kind == "linear":
        lamc = 2.0 * GC / SIGMA
        soft = SIGMA * (lamc - lam) / (lamc - lam0)
    else:
        ell = (GC - 0.5 * SIGMA * lam0) / (SIGMA * C_M)
        lamc = lam0 + M * ell
        soft = SIGMA * (np.exp(-(lam - lam0) / ell) - np.exp(-M)) / (1.0 - np.exp(-M))
    return np.where(lam <= lam0, k0 * lam, np.where(lam >= lamc, 0.0, soft))


def unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@pytest.mark.parametrize("kind", KINDS)
def test_normal_pull_unload_reload_follows_the_analytic_path(kind):
    law, k0 = TractionSeparation(kind, SIGMA, GC), 10.0 * K_MIN
    lamc = float(law.critical_opening(k0))
    n = unit(np.array([0.3, -0.5, 0.8]))
    path = np.concatenate([np.linspace(0, 0.5, 21), np.linspace(0.5, 0, 21)[1:],
                           np.linspace(0, 0.8, 33)[1:], np.linspace(0.8, 1.2, 9)[1:],
                           np.linspace(1.2, 0.3, 10)[1:]]) * lamc
    kappa, reached = np.zeros(1), 0.0
    for d in path:
        r = law.response(d * n, n, kappa, k0)
        if d >= reached:  # loading on the envelope
            expected = analytic_envelope(kind, d, k0)
        else:  # straight towards the origin from the largest opening so far
            hist = max(reached, SIGMA / k0)
            expected = analytic_envelope(kind, hist, k0) * d / hist
        reached = max(reached, d)
        assert np.allclose(r.traction[0], expected * n, rtol=0, atol=1e-12 * SIGMA)
        assert np.isclose(r.kappa[0], reached, rtol=1e-14, atol=0)
        kappa = r.kappa
    assert np.all(r.traction == 0.0) and r.broken[0] and r.dissipated[0] == GC


@pytest.mark.parametrize("kind", KINDS)
def test_full_separation_dissipates_the_fracture_energy(kind):
    law = TractionSeparation(kind, SIGMA, GC, shear_weight=0.6)
    k0 = K_MIN * np.array([1.01, 1.5, 4.0, 20.0, 1e3])
    lam0, lamc = law.peak_opening(k0), law.critical_opening(k0)
    n = unit(np.random.default_rng(1).normal(size=(k0.size, 3)))
    r = law.response(1.2 * lamc[:, None] * n, n, 0.0, k0)
    assert np.all(r.broken)
    assert np.allclose(r.dissipated, GC, rtol=1e-12, atol=0)
    assert np.allclose(law.envelope_work(lamc, k0), GC, rtol=1e-12, atol=0)
    for i, k in enumerate(k0):
        def t(x, k=k):
            return float(law.envelope(x, k)[0])
        area = quad(t, 0.0, lamc[i], points=[lam0[i]], epsabs=0, epsrel=1e-13)[0]
        assert abs(area - GC) <= 1e-11 * GC
        for lam in np.linspace(0.0, 1.1, 12) * lamc[i]:  # the closed form on the way
            part = quad(t, 0.0, lam, points=[lam0[i]] if lam > lam0[i] else None,
                        epsabs=0, epsrel=1e-13)[0]
            assert abs(float(law.envelope_work(lam, k)) - part) <= 1e-11 * GC
            # pulled there once: the area above the unloading line is dissipated
            r = law.response(lam * n[i], n[i], 0.0, k)
            spent = part - 0.5 * lam * t(lam) if lam > lam0[i] else 0.0
            assert abs(r.dissipated[0] - spent) <= 1e-11 * GC


def mixed_path(rng, k, lamc):
    """Waypoints ``(segments + 1, k, 3)`` of jumps: random directions, growing and shrinking
    magnitudes (loading, unloading, reloading), some closing into compression, some points
    breaking on the way."""
    scale = np.array([0.15, 0.45, 0.2, 0.05, 0.6, 0.35, 0.8, 0.3, 0.0])
    scale = scale[:, None] * rng.uniform(0.8, 1.6, size=k) * lamc
    dirs = unit(rng.normal(size=(scale.shape[0], k, 3)))
    return np.concatenate([np.zeros((1, k, 3)), scale[:, :, None] * dirs])


def trapezoid_gap(law, waypoints, normal, k0, steps):
    """``|trapezoidal work - (stored + dissipated)|`` at the end, per point, with ``steps``
    per segment of the piecewise linear path."""
    kappa = np.zeros(k0.size)
    d_old, r = waypoints[0], law.response(waypoints[0], normal, kappa, k0)
    work = np.zeros(k0.size)
    for a, b in zip(waypoints[:-1], waypoints[1:], strict=True):
        for f in np.arange(1, steps + 1) / steps:
            d_new = a + f * (b - a)
            new = law.response(d_new, normal, r.kappa, k0)
            work += 0.5 * np.einsum("ki,ki->k", r.traction + new.traction, d_new - d_old)
            d_old, r = d_new, new
    return np.abs(work - r.stored - r.dissipated), r


@pytest.mark.parametrize("kind", KINDS)
def test_mixed_mode_work_equals_stored_plus_dissipated(kind):
    rng = np.random.default_rng(7)
    law, k = TractionSeparation(kind, SIGMA, GC, shear_weight=0.7), 200
    k0 = K_MIN * rng.uniform(2.0, 10.0, size=k)
    normal = unit(rng.normal(size=(k, 3)))
    waypoints = mixed_path(rng, k, law.critical_opening(k0))
    coarse, r = trapezoid_gap(law, waypoints, normal, k0, 40)  # 360 steps
    fine, r_fine = trapezoid_gap(law, waypoints, normal, k0, 80)
    assert np.allclose(r.kappa, r_fine.kappa, rtol=1e-3)
    assert np.mean(r.dissipated > 0.0) > 0.9 and 0 < r.broken.sum() < k
    # second order: halving the step divides the error by ~4 (summed over the points, as
    # each point's error comes from a few kinks of the law that fall anywhere in a step) ...
    ratio = coarse.sum() / fine.sum()
    assert 3.0 < ratio < 6.0, ratio
    # ... and the finer error is within its Richardson estimate, (coarse - fine) / 3
    assert fine.sum() <= 1.5 * (coarse.sum() - fine.sum()) / 3.0
    assert fine.sum() < 1e-2 * k * GC


def finite_difference(law, jump, normal, kappa, k0, h):
    """Central differences ``(k, 3, 3)`` of the traction, column j along e_j."""
    cols = []
    for j in range(3):
        e = np.zeros(3)
        e[j] = h
        plus = law.response(jump + e, normal, kappa, k0).traction
        minus = law.response(jump - e, normal, kappa, k0).traction
        cols.append((plus - minus) / (2.0 * h))
    return np.stack(cols, axis=2)


def branch_points(law, rng, k0):
    """Jumps, normals and histories on each branch, away from every kink: elastic, loading
    (softening), unloading and reloading, compression with shear, broken."""
    k = k0.size
    lam0, lamc = law.peak_opening(k0), law.critical_opening(k0)
    normal = unit(rng.normal(size=(k, 3)))
    shear = unit(np.cross(normal, rng.normal(size=(k, 3))))
    case = np.arange(k) % 5
    lam = np.choose(case, [0.5 * lam0, lam0 + rng.uniform(0.2, 0.8, k) * (lamc - lam0),
                           0.5 * lamc, 0.5 * lamc, 2.0 * lamc])
    angle = rng.uniform(0.2, 1.3, k)  # mixed mode, normal opening clearly nonzero
    dn = np.where(case == 3, -0.3 * lamc, lam * np.cos(angle))
    ds = np.where(case == 3, lam, lam * np.sin(angle)) / law.shear_weight
    kappa = np.choose(case, [0.0, 0.5 * lam, 0.75 * lamc, 0.0, 0.0])
    return dn[:, None] * normal + ds[:, None] * shear, normal, kappa, case


@pytest.mark.parametrize("kind", KINDS)
def test_tangent_is_the_derivative_of_the_traction(kind):
    rng = np.random.default_rng(3)
    law = TractionSeparation(kind, SIGMA, GC, shear_weight=1.4)
    k0 = K_MIN * rng.uniform(3.0, 30.0, size=50)
    jump, normal, kappa, case = branch_points(law, rng, k0)
    r = law.response(jump, normal, kappa, k0)
    assert np.all(r.broken == (case == 4))
    h = 1e-7 * float(np.median(law.critical_opening(k0)))
    fd = finite_difference(law, jump, normal, kappa, k0, h)
    scale = np.linalg.norm(r.tangent, axis=(1, 2))[:, None, None]
    assert np.all(np.abs(fd - r.tangent) <= 1e-6 * scale)
    assert np.allclose(r.tangent, r.tangent.transpose(0, 2, 1), rtol=0, atol=1e-14 * scale)
    # the secant is symmetric positive semidefinite, and equals the tangent off the loading
    assert np.all(np.linalg.eigvalsh(r.secant) >= -1e-12 * scale[:, :, 0])
    off = np.isin(case, [0, 2, 4])
    assert np.allclose(r.secant[off], r.tangent[off], rtol=0, atol=1e-14 * scale[off])
    # softening makes the tangent indefinite along P d
    assert np.all(np.linalg.eigvalsh(r.tangent[case == 1])[:, 0] < 0.0)


@pytest.mark.parametrize("kind", KINDS)
def test_compression_is_a_penalty_without_damage(kind):
    rng = np.random.default_rng(5)
    law, k = TractionSeparation(kind, SIGMA, GC, shear_weight=0.8), 6
    k0 = K_MIN * np.array([2.0, 5.0, 10.0, 100.0, 5.0, 5.0])
    lamc = law.critical_opening(k0)
    normal = unit(rng.normal(size=(k, 3)))
    dn = -np.array([0.1, 1.0, 3.0, 0.5, 0.2, 0.2]) * lamc
    kappa = np.array([0.0, 0.0, 0.3, 0.0, 0.5, 2.0]) * lamc  # last one broken
    r = law.response(dn[:, None] * normal, normal, kappa, k0)
    assert np.allclose(r.traction, (k0 * dn)[:, None] * normal, rtol=1e-14, atol=0)
    assert np.allclose(r.kappa, kappa, rtol=0, atol=1e-14 * lamc)  # round-off shear only
    assert np.allclose(r.stored, 0.5 * k0 * dn**2, rtol=1e-14, atol=0)
    fresh = kappa == 0.0
    assert np.all(r.dissipated[fresh] == 0.0) and np.all(~r.broken[fresh])
    # with shear: the shear part follows the law as if the faces were just touching
    shear = unit(np.cross(normal, rng.normal(size=(k, 3)))) * (0.4 * lamc)[:, None]
    r = law.response(dn[:, None] * normal + shear, normal, kappa, k0)
    alone = law.response(shear, normal, kappa, k0)
    assert np.allclose(r.traction, alone.traction + (k0 * dn)[:, None] * normal,
                       rtol=0, atol=1e-12 * SIGMA)
    assert np.allclose(r.kappa, alone.kappa, rtol=1e-15, atol=0)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("beta", [0.5, 1.0, 2.0])
def test_pure_shear_uses_the_weighted_opening(kind, beta):
    rng = np.random.default_rng(11)
    law, k = TractionSeparation(kind, SIGMA, GC, shear_weight=beta), 30
    k0 = K_MIN * rng.uniform(2.0, 40.0, size=k)
    normal = unit(rng.normal(size=(k, 3)))
    size = rng.uniform(0.0, 1.2, size=k) * law.critical_opening(k0) / beta
    ds = unit(np.cross(normal, rng.normal(size=(k, 3)))) * size[:, None]
    r = law.response(ds, normal, 0.0, k0)
    lam = beta * np.linalg.norm(ds, axis=1)
    assert np.allclose(r.kappa, lam, rtol=1e-14, atol=0)
    s = analytic_envelope(kind, lam, k0) / lam
    assert np.allclose(r.traction, beta**2 * s[:, None] * ds, rtol=0, atol=1e-12 * SIGMA)
    assert np.allclose(r.stored, 0.5 * s * lam**2, rtol=1e-12, atol=1e-15 * GC)


@pytest.mark.parametrize("kind", KINDS)
def test_peak_beyond_the_critical_opening_is_refused(kind):
    law = TractionSeparation(kind, SIGMA, GC)
    k0 = np.array([10.0, 1.0, 0.5]) * K_MIN
    for call in (law.peak_opening, law.critical_opening):
        with pytest.raises(ValueError, match="lambda_0.*lambda_c.*2 point"):
            call(k0)
    with pytest.raises(ValueError, match="lambda_0"):
        law.response(np.zeros((3, 3)), [0.0, 0.0, 1.0], 0.0, k0)
    assert float(law.peak_opening(1.001 * K_MIN)) < float(law.critical_opening(1.001 * K_MIN))


def test_zero_jump_and_bad_input():
    law = TractionSeparation("linear", SIGMA, GC)
    r = law.response(np.zeros(3), [0.0, 0.0, 1.0], 0.0, 5.0 * K_MIN)
    assert isinstance(r, CohesiveResponse) and r.traction.shape == (1, 3)
    assert np.all(r.traction == 0.0) and np.all(np.isfinite(r.tangent))
    assert np.allclose(r.tangent[0], 5.0 * K_MIN * np.eye(3))
    with pytest.raises(ValueError, match="kind"):
        TractionSeparation("bilinear", SIGMA, GC)
    with pytest.raises(ValueError, match="energy"):
        TractionSeparation("linear", SIGMA, 0.0)
    with pytest.raises(ValueError, match="unit"):
        law.response(np.zeros(3), [0.0, 0.0, 2.0], 0.0, 5.0 * K_MIN)
