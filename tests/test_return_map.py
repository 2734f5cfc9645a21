"""Von Mises radial return (DESIGN §2): consistency, consistent tangent, uniaxial path."""

import numpy as np
import pytest

from fem_frac.fem.tensors import von_mises
from fem_frac.plasticity import PlasticState, radial_return

E, NU, SY = 200e9, 0.3, 250e6
EPS_Y = SY / E


@pytest.mark.parametrize("hardening", [0.0, E / 10])
def test_stress_returns_to_the_yield_surface(hardening):
    rng = np.random.default_rng(0)
    # magnitudes from well inside the elastic range to 5x the yield strain
    strain = EPS_Y * rng.normal(size=(6, 1000)) * rng.uniform(0.05, 5.0, size=1000)
    plastic = 0.1 * EPS_Y * rng.normal(size=(6, 1000))
    plastic[:3] -= plastic[:3].mean(axis=0)  # plastic strain is deviatoric
    state = PlasticState(plastic, np.abs(0.1 * EPS_Y * rng.normal(size=1000)))
    stress, new, _ = radial_return(strain, state, E, NU, SY, hardening)
    flow = SY + hardening * new.equivalent_plastic_strain
    f = von_mises(stress) - flow
    yielded = new.equivalent_plastic_strain > state.equivalent_plastic_strain
    assert yielded.sum() > 100 and (~yielded).sum() > 0
    assert np.all(f <= 1e-10 * SY)
    assert np.all(np.abs(f[yielded]) <= 1e-10 * SY)
    # plastic flow is isochoric
    assert np.allclose(new.plastic_strain[:3].sum(axis=0), state.plastic_strain[:3].sum(axis=0),
                       rtol=0, atol=1e-15)


@pytest.mark.parametrize("hardening", [0.0, E / 10])
def test_consistent_tangent_matches_finite_differences(hardening):
    """Central differences, step 1e-6 of the strain: truncation O(step^2) and round-off
    ~1e-16 * |stress| / step are both far below the 1e-6 tolerance."""
    rng = np.random.default_rng(1)
    strain = 3 * EPS_Y * rng.normal(size=(6, 20))
    state = PlasticState.zeros((20,))
    _, _, tangent = radial_return(strain, state, E, NU, SY, hardening)
    step = 1e-6 * EPS_Y
    fd = np.empty_like(tangent)
    for j in range(6):
        d = np.zeros((6, 1))
        d[j] = step
        plus = radial_return(strain + d, state, E, NU, SY, hardening, tangent=False)[0]
        minus = radial_return(strain - d, state, E, NU, SY, hardening, tangent=False)[0]
        fd[:, j] = (plus - minus) / (2 * step)
    assert np.max(np.abs(tangent - fd)) <= 1e-6 * E
    assert np.allclose(tangent, np.swapaxes(tangent, 0, 1), rtol=0, atol=1e-6 * E)


def uniaxial_path(axial_strains, hardening):
    """Axial stress under uniaxial stress: axial strain prescribed, the other five stress
    components held at zero by Newton's method on the lateral strains."""
    state = PlasticState.zeros((1,))
    strain = np.zeros((6, 1))
    out = []
    for eps in axial_strains:
        strain[0] = eps
        for _ in range(20):
            stress, new, tangent = radial_return(strain, state, E, NU, SY, hardening)
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
