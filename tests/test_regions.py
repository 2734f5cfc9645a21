"""Material regions: properties per element, from a mesh file's volume groups or boxes."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from fem_frac.errors import CaseError
from solve import run

E1, E2, NU, SIGMA = 200e9, 20e9, 0.3, 1e6
GEO = textwrap.dedent("""\
    SetFactory("OpenCASCADE");
    Box(1) = {0, 0, 0, 0.5, 0.2, 0.2};
    Box(2) = {0.5, 0, 0, 0.5, 0.2, 0.2};
    BooleanFragments{ Volume{1}; Delete; }{ Volume{2}; Delete; }
    Physical Volume("stiff") = {1};
    Physical Volume("soft") = {2};
""")


def plane(axis: int, value: float) -> dict:
    lo, hi = [-1.0] * 3, [2.0] * 3
    lo[axis], hi[axis] = value - 1e-9, value + 1e-9
    return {"min": lo, "max": hi}


def bar(tmp_path, nu: float = NU, **extra) -> dict:
    """Two halves of a 1 x 0.2 x 0.2 bar (a .geo with two volume groups) in uniaxial
    stress: symmetry on x = 0, y = 0, z = 0, a traction on x = 1."""
    (tmp_path / "bar.geo").write_text(GEO)
    case = {
        "mesh": {"file": "bar.geo", "element_size": 0.1},
        "material": {"youngs_modulus": E1, "poissons_ratio": nu, "density": 7800.0},
        "regions": [{"subdomain": "soft", "youngs_modulus": E2}],
        "boundary_conditions": [
            {"type": "symmetry", "box": plane(0, 0.0)},
            {"type": "symmetry", "box": plane(1, 0.0)},
            {"type": "symmetry", "box": plane(2, 0.0)},
            {"type": "traction", "box": plane(0, 1.0), "traction": [SIGMA, 0, 0]},
        ],
    }
    case.update(extra)
    return case


def test_bar_of_two_materials_in_series_is_exact(tmp_path):
    """Uniaxial stress sigma in both halves: the end moves sigma (L1 / E1 + L2 / E2), a
    piecewise-linear field that linear tets conforming to the interface reproduce exactly.
    nu = 0, so the halves contract no differently (with nu > 0 the lateral strains -nu
    sigma / E_i differ and the interface constrains them: no longer uniaxial)."""
    setup, state, _, _ = run(bar(tmp_path, nu=0.0), tmp_path)
    x = setup.disc.space.node_points
    end = np.isclose(x[:, 0], 1.0)
    ux = state.u.reshape(-1, 3)[end, 0]
    exact = SIGMA * (0.5 / E1 + 0.5 / E2)
    np.testing.assert_allclose(ux, exact, rtol=1e-9)
    # with one material (the soft region removed) it would be 5.5x smaller
    assert exact > 5 * SIGMA / E1


def test_density_regions_enter_gravity_and_mass_exactly(tmp_path):
    """Total gravity load and total lumped mass are sum(rho_i V_i) (times g), with a 1e4
    density contrast."""
    case = bar(tmp_path, regions=[{"subdomain": "soft", "density": 0.78}],
               body_force={"gravity": [0, 0, -9.81]})
    setup, _, _, _ = run(case, tmp_path)
    problem = setup.disc.problem
    total = problem.external_force(1.0).reshape(-1, 3).sum(axis=0)
    expected_mass = (7800.0 + 0.78) * 0.5 * 0.2 * 0.2
    traction = SIGMA * 0.2 * 0.2
    np.testing.assert_allclose(total, [traction, 0, -9.81 * expected_mass], rtol=1e-12)
    from fem_frac.fem.mass import lumped_mass

    m = lumped_mass(setup.disc.space, setup.disc.materials.density)
    assert m[0::3].sum() == pytest.approx(expected_mass, rel=1e-12)


def test_unknown_subdomain_and_empty_box_are_located_errors(tmp_path):
    with pytest.raises(CaseError) as err:
        run(bar(tmp_path, regions=[{"subdomain": "rubber", "density": 1.0}]), tmp_path)
    assert err.value.path == ("regions", 0, "subdomain") and "stiff" in err.value.message
    with pytest.raises(CaseError) as err:
        run(bar(tmp_path, regions=[{"box": {"min": [5, 5, 5], "max": [6, 6, 6]},
                                    "density": 1.0}]), tmp_path)
    assert err.value.path == ("regions", 0, "box")


def test_plastic_bar_of_two_materials_with_full_newton(tmp_path):
    """The consistent tangent with moduli per element: full Newton on a two-material bar
    pulled past yield reaches the same state as modified Newton and converges in a few
    iterations (a wrong per-element tangent would cost it its quadratic rate)."""
    results = {}
    for method in ("modified_newton", "newton"):
        case = bar(tmp_path, nu=0.0, plasticity={"yield_stress": 5e5})
        case["boundary_conditions"][3] = {"type": "displacement", "box": plane(0, 1.0),
                                          "x": 1e-4}
        case["analysis"] = {"type": "quasi_static", "steps": 4,
                            "equilibrium": {"method": method, "tolerance": 1e-10}}
        _, state, ledger, counters = run(case, tmp_path)
        results[method] = (state.u, counters.iterations, ledger)
    u_mod, it_mod, _ = results["modified_newton"]
    u_new, it_new, led = results["newton"]
    assert led.plastic_work > 0 and led.relative_error < 1e-8
    assert np.linalg.norm(u_mod - u_new) <= 1e-7 * np.linalg.norm(u_new)
    assert it_new <= 4 * 3
