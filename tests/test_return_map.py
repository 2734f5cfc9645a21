"""Von Mises radial return (DESIGN §2): consistency, consistent tangent, uniaxial path."""

import numpy as np
import pytest

from fem_frac.fem.tensors import von_mises
from fem_frac.plasticity import PlasticState, radial_return

E, NU, SY = 200e9, 0.3, 250e6
EPS_Y = SY / E


MODELS = [(0.0, 0.0), (E / 10, 0.0), (0.0, E / 10), (E / 20, E / 20)]  # (H, K)


@pytest.mark.parametrize("hardening,kinematic", MODELS)
def test_stress_returns_to_the_yield_surface(hardening, kinematic):
    rng = np.random.default_rng(0)
    # magnitudes from well inside the elastic range to 5x the yield strain
    strain = EPS_Y * rng.normal(size=(6, 1000)) * rng.uniform(0.05, 5.0, size=1000)
    plastic = 0.1 * EPS_Y * rng.normal(size=(6, 1000))
    plastic[:3] -= plastic[:3].mean(axis=0)  # plastic strain is deviatoric
    back = None
    if kinematic:
        back = (2.0 / 3.0) * kinematic * plastic  # Prager's backstress of that plastic strain
    state = PlasticState(plastic, np.abs(0.1 * EPS_Y * rng.normal(size=1000)), back)
    stress, new, _ = radial_return(strain, state, E, NU, SY, hardening,
                                   kinematic_hardening=kinematic)
    flow = SY + hardening * new.equivalent_plastic_strain
    shifted = stress - (new.backstress if kinematic else 0.0)
    f = von_mises(shifted) - flow
    yielded = new.equivalent_plastic_strain > state.equivalent_plastic_strain
    assert yielded.sum() > 100 and (~yielded).sum() > 0
    assert np.all(f <= 1e-10 * SY)
    assert np.all(np.abs(f[yielded]) <= 1e-10 * SY)
    # plastic flow is isochoric
    assert np.allclose(new.plastic_strain[:3].sum(axis=0), state.plastic_strain[:3].sum(axis=0),
                       rtol=0, atol=1e-15)


@pytest.mark.parametrize("hardening,kinematic", MODELS)
def test_consistent_tangent_matches_finite_differences(hardening, kinematic):
    """Central differences, step 1e-6 of the strain: truncation O(step^2) and round-off
    ~1e-16 * |stress| / step are both far below the 1e-6 tolerance."""
    rng = np.random.default_rng(1)
    strain = 3 * EPS_Y * rng.normal(size=(6, 20))
    state = PlasticState.zeros((20,), kinematic=kinematic > 0)
    if kinematic:  # a backstress already in place, so the tangent is tested off-centre
        back = EPS_Y * kinematic * rng.normal(size=(6, 20))
        back[:3] -= back[:3].mean(axis=0)
        state = PlasticState(state.plastic_strain, state.equivalent_plastic_strain, back)
    model = dict(kinematic_hardening=kinematic)
    _, _, tangent = radial_return(strain, state, E, NU, SY, hardening, **model)
    step = 1e-6 * EPS_Y
    fd = np.empty_like(tangent)
    for j in range(6):
        d = np.zeros((6, 1))
        d[j] = step
        plus = radial_return(strain + d, state, E, NU, SY, hardening, False, **model)[0]
        minus = radial_return(strain - d, state, E, NU, SY, hardening, False, **model)[0]
        fd[:, j] = (plus - minus) / (2 * step)
    assert np.max(np.abs(tangent - fd)) <= 1e-6 * E
    assert np.allclose(tangent, np.swapaxes(tangent, 0, 1), rtol=0, atol=1e-6 * E)


def uniaxial_path(axial_strains, hardening, kinematic=0.0):
    """Axial stress under uniaxial stress: axial strain prescribed, the other five stress
    components held at zero by Newton's method on the lateral strains."""
    state = PlasticState.zeros((1,), kinematic=kinematic > 0)
    strain = np.zeros((6, 1))
    out = []
    for eps in axial_strains:
        strain[0] = eps
        for _ in range(20):
            stress, new, tangent = radial_return(strain, state, E, NU, SY, hardening,
                                                 kinematic_hardening=kinematic)
            residual = stress[1:, 0]
            if np.max(np.abs(residual)) <= 1e-12 * SY:
                break
            strain[1:, 0] -= np.linalg.solve(tangent[1:, 1:, 0], residual)
        else:
            raise AssertionError("lateral equilibrium did not converge")
        state = new
        out.append(stress[0, 0])
    return np.array(out)


def exact_uniaxial(axial_strains, hardening):
    """Piecewise-linear exact response: slope E, then E_t = E H / (E + H) beyond yield,
    elastic unloading from the largest stress reached, reloading elastic up to it."""
    tangent_modulus = E * hardening / (E + hardening)
    sigma, eps_prev, sigma_max = 0.0, 0.0, SY
    out = []
    for eps in axial_strains:
        trial = sigma + E * (eps - eps_prev)
        sigma = trial if trial <= sigma_max else sigma_max + tangent_modulus * (
            eps - (eps_prev + (sigma_max - sigma) / E))
        sigma_max = max(sigma_max, sigma)
        eps_prev = eps
        out.append(sigma)
    return np.array(out)


@pytest.mark.parametrize("hardening", [0.0, E / 10])
def test_uniaxial_load_unload_reload_follows_the_exact_path(hardening):
    load = np.linspace(0, 4 * EPS_Y, 17)[1:]
    unload = np.linspace(4 * EPS_Y, 3 * EPS_Y, 5)[1:]
    reload = np.linspace(3 * EPS_Y, 6 * EPS_Y, 13)[1:]
    path = np.concatenate([load, unload, reload])
    computed = uniaxial_path(path, hardening)
    expected = exact_uniaxial(path, hardening)
    np.testing.assert_allclose(computed, expected, rtol=1e-10, atol=1e-10 * SY)
    if hardening == 0.0:
        assert np.allclose(computed[path >= EPS_Y][:12], SY, rtol=1e-10)


def exact_kinematic(axial_strains, kinematic):
    """1D Prager hardening: |sigma - b| <= sigma_Y with b = K eps_p. (In uniaxial stress the
    3D backstress (2/3) K eps_p has the axial-minus-lateral difference K eps_p_axial, which
    is what shifts the axial yield stress.)"""
    sigma, eps_p, out = 0.0, 0.0, []
    for eps in axial_strains:
        trial = E * (eps - eps_p)
        xi = trial - kinematic * eps_p
        f = abs(xi) - SY
        if f > 0:
            d = f / (E + kinematic) * np.sign(xi)
            eps_p += d
            trial -= E * d
        sigma = trial
        out.append(sigma)
    return np.array(out)


def test_kinematic_hardening_shows_the_bauschinger_effect():
    """Loaded to sigma_max > sigma_Y and reversed, a kinematically hardening material yields
    again at sigma_max - 2 sigma_Y (the elastic range keeps its width and moves), where an
    isotropically hardening one stays elastic down to -sigma_max."""
    k = E / 10
    load = np.linspace(0, 4 * EPS_Y, 17)[1:]
    reverse = np.linspace(4 * EPS_Y, -4 * EPS_Y, 33)[1:]
    path = np.concatenate([load, reverse])
    computed = uniaxial_path(path, 0.0, kinematic=k)
    np.testing.assert_allclose(computed, exact_kinematic(path, k), rtol=1e-10,
                               atol=1e-10 * SY)
    peak = computed[len(load) - 1]
    assert peak > SY
    # reverse steps of sigma_Y / 4: exactly 8 elastic ones (a drop of 2 sigma_Y), then
    # plastic ones with the slope E K / (E + K); isotropic hardening would allow 2 peak / SY * 4
    slopes = np.diff(computed[len(load) - 1:])
    elastic = np.isclose(slopes, -SY / 4, rtol=1e-9)
    assert np.all(elastic[:8]) and not np.any(elastic[8:])
    assert np.allclose(slopes[8:], -SY / 4 * k / (E + k), rtol=1e-9)
