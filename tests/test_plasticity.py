"""Plasticity through the whole step loop: homogeneous bars against the exact uniaxial path,
Newton against modified Newton, and a clear stop when equilibrium is out of reach."""

from __future__ import annotations

import numpy as np
import pytest

from fem_frac.errors import SolverError
from solve import run

E, NU, SIGMA_Y = 200e9, 0.3, 250e6
L, A = 1.0, 0.2 * 0.2
STRAIN = 3.0 * SIGMA_Y / E  # peak strain: three times the yield strain


def bar(hardening: float, method: str, steps: int = 24, tolerance: float = 1e-10,
        kinematic: float = 0.0) -> dict:
    """Uniaxial stress: symmetry on three faces, the end pulled to 3 yield strains, pushed
    back to -3 and pulled to +3 again (load, reverse, reload)."""
    return {
        "mesh": {"geometry": {"type": "box", "lengths": [L, 0.2, 0.2]}, "element_size": 0.1},
        "material": {"youngs_modulus": E, "poissons_ratio": NU},
        "plasticity": {"yield_stress": SIGMA_Y, "hardening": hardening,
                       "kinematic_hardening": kinematic},
        "boundary_conditions": [
            {"type": "symmetry", "boundary": "xmin"},
            {"type": "symmetry", "boundary": "ymin"},
            {"type": "symmetry", "boundary": "zmin"},
            {"type": "displacement", "boundary": "xmax", "x": STRAIN * L, "curve": "cycle"},
        ],
        "load_curves": {"cycle": {"type": "table",
                                  "points": [[0, 0], [1, 1], [2, -1], [3, 1]]}},
        "analysis": {"type": "quasi_static", "t_end": 3, "steps": steps,
                     "equilibrium": {"method": method, "tolerance": tolerance}},
    }


def exact_uniaxial(strains: np.ndarray, hardening: float, kinematic: float = 0.0) -> np.ndarray:
    """1D return map (the exact stress of a homogeneous bar under uniaxial stress): von Mises
    reduces to |sigma - K eps_p| <= sigma_Y + H alpha, with |d eps_p| = d alpha."""
    stress, plastic, alpha, out = 0.0, 0.0, 0.0, []
    for eps in strains:
        trial = E * (eps - plastic)
        xi = trial - kinematic * plastic
        f = abs(xi) - (SIGMA_Y + hardening * alpha)
        if f > 0:
            dg = f / (E + hardening + kinematic)
            plastic += dg * np.sign(xi)
            alpha += dg
            trial -= E * dg * np.sign(xi)
        stress = trial
        out.append(stress)
    return np.array(out)


@pytest.mark.parametrize("hardening,kinematic", [(0.0, 0.0), (20e9, 0.0), (0.0, 20e9)])
@pytest.mark.parametrize("method", ["modified_newton", "newton"])
def test_homogeneous_bar_follows_the_exact_cyclic_path(hardening, kinematic, method):
    """A homogeneous field is exact in P1, so the bar's end force is sigma A of the 1D law at
    every step, to the equilibrium tolerance (1e-10), whichever iteration reaches it."""
    forces, strains, iterations = [], [], []

    def observe(n, state, ledger, info):
        forces.append(state.reaction)
        iterations.append(info.iterations)

    setup, state, ledger, counters = run(bar(hardening, method, kinematic=kinematic),
                                         observe=observe)
    problem = setup.disc.problem
    dofs = problem.constraints.dofs
    full = np.zeros(problem.space.n_dofs)
    end = problem.reaction_groups["xmax"]
    times = np.array([setup.grid.time(n) for n in range(setup.grid.steps + 1)])
    curve = np.interp(times, [0, 1, 2, 3], [0, 1, -1, 1])
    strains = STRAIN * curve
    measured = []
    for r in forces:
        full[:] = 0.0
        full[dofs] = r
        measured.append(full[end][0::3].sum() / A)
    expected = exact_uniaxial(strains, hardening, kinematic)
    np.testing.assert_allclose(measured, expected, rtol=0, atol=1e-8 * SIGMA_Y)
    # the path really is elastoplastic: saturated (or hardening) and reversed
    assert np.max(expected) >= SIGMA_Y and np.min(expected) <= -SIGMA_Y
    # energy: the plastic work of two and a half yield excursions, balanced exactly; the
    # stored part is H alpha^2 / 2 + K eps_p^2 / 2 per unit volume (1D: axial eps_p)
    assert ledger.plastic_work > 0 and ledger.relative_error < 1e-9
    alpha = state.plastic.equivalent_plastic_strain.mean()
    axial = state.plastic.plastic_strain[0].mean()
    stored = 0.5 * (hardening * alpha**2 + kinematic * axial**2) * L * A
    assert ledger.hardening == pytest.approx(stored, rel=1e-9, abs=1e-12)
    if method == "newton":
        # the consistent tangent makes a plastic step converge in a couple of iterations
        assert max(iterations) <= 3


def test_newton_and_modified_newton_agree_and_newton_needs_fewer_iterations():
    """On a nonhomogeneous problem (a beam bent past yield) both methods reach the same
    equilibrium: their displacements differ by no more than the residual tolerance allows
    (relative 1e-9 residual -> ~1e-7 relative displacement through the condition number,
    ~1e2 to 1e3, of this small P1 system)."""
    case = {
        "mesh": {"geometry": {"type": "box", "lengths": [1.0, 0.1, 0.1]},
                 "element_size": 0.05},
        "material": {"youngs_modulus": E, "poissons_ratio": NU},
        "plasticity": {"yield_stress": SIGMA_Y},
        "boundary_conditions": [
            {"type": "fixed", "boundary": "xmin"},
            {"type": "displacement", "boundary": "xmax", "z": -0.015},
        ],
        "analysis": {"type": "quasi_static", "steps": 5,
                     "equilibrium": {"tolerance": 1e-9}},
    }
    results = {}
    for method in ("modified_newton", "newton"):
        case["analysis"]["equilibrium"]["method"] = method
        setup, state, ledger, counters = run(case)
        results[method] = (state.u, counters.iterations, ledger.plastic_work)
    u_mod, it_mod, w_mod = results["modified_newton"]
    u_new, it_new, w_new = results["newton"]
    assert w_mod > 0
    assert np.linalg.norm(u_mod - u_new) <= 1e-6 * np.linalg.norm(u_new)
    assert it_new < it_mod


def test_single_pass_reports_the_residual_it_leaves():
    """The single pass of the course notes takes one solve per step; the residual it leaves
    in plastic steps is reported, not hidden."""
    seen = []
    run(bar(0.0, "single_pass", steps=6),
        observe=lambda n, s, led, info: seen.append((info.iterations, info.residual)))
    iterations = [i for i, _ in seen[1:]]
    residuals = [r for _, r in seen[1:]]
    assert iterations == [1] * 6
    assert max(residuals) > 1e-3  # plastic steps leave an unbalanced force


def test_equilibrium_out_of_reach_stops_with_a_diagnostic():
    case = bar(0.0, "modified_newton", steps=3)
    case["analysis"]["equilibrium"]["max_iterations"] = 2
    with pytest.raises(SolverError) as err:
        run(case)
    message = str(err.value)
    assert "step 1" in message and "equilibrium not reached in 2 iterations" in message
    assert "newton" in message


def test_anderson_acceleration_reaches_the_same_equilibrium_in_fewer_iterations():
    """Acceleration changes the path of the iteration, not its fixed point: both runs stop at
    relative residual 1e-10, so their displacements agree to ~1e-8 (residual times the
    condition number of this small system), and the accelerated one needs far fewer
    iterations (plain modified Newton converges linearly near a limit load)."""
    case = {
        "mesh": {"geometry": {"type": "hollow_sphere", "inner_radius": 1.0,
                              "outer_radius": 2.0, "sector": "octant"},
                 "element_size": 0.3},
        "material": {"youngs_modulus": E, "poissons_ratio": NU},
        "plasticity": {"yield_stress": SIGMA_Y},
        "boundary_conditions": [
            {"type": "symmetry", "boundary": f"symmetry_{a}"} for a in "xyz"
        ] + [{"type": "pressure", "boundary": "inner", "pressure": 1.25 * SIGMA_Y}],
        "analysis": {"type": "quasi_static", "steps": 5,
                     "equilibrium": {"tolerance": 1e-10}},
    }
    results = {}
    for acceleration in ("none", "anderson"):
        case["analysis"]["equilibrium"]["acceleration"] = acceleration
        _, state, ledger, counters = run(case)
        results[acceleration] = (state.u, counters.iterations, ledger.relative_error)
    plain, fast = results["none"], results["anderson"]
    assert np.linalg.norm(plain[0] - fast[0]) <= 1e-7 * np.linalg.norm(plain[0])
    assert fast[1] < 0.6 * plain[1]
    assert fast[2] < 1e-8


def sphere_in_one_step(pressure: float, cutbacks: int, max_iterations: int,
                       method: str = "newton") -> dict:
    """A perfectly plastic thick sphere (a = 1, b = 2: limit load 2 ln 2 sigma_Y = 1.386
    sigma_Y) loaded in a single quasi-static step; linear tets with the averaged volumetric
    strain (standard linear tets lock: on this coarse mesh they carry 1.6 sigma_Y)."""
    return {
        "mesh": {"geometry": {"type": "hollow_sphere", "inner_radius": 1.0,
                              "outer_radius": 2.0, "sector": "octant"},
                 "element_size": 0.35, "formulation": "averaged"},
        "material": {"youngs_modulus": E, "poissons_ratio": NU},
        "plasticity": {"yield_stress": SIGMA_Y},
        "boundary_conditions": [
            {"type": "symmetry", "boundary": f"symmetry_{a}"} for a in "xyz"
        ] + [{"type": "pressure", "boundary": "inner", "pressure": pressure}],
        "analysis": {"type": "quasi_static", "steps": 1,
                     "equilibrium": {"method": method, "max_iterations": max_iterations,
                                     "cutbacks": cutbacks}},
    }


def test_cutbacks_split_a_step_that_does_not_converge():
    """1.25 sigma_Y (90 % of the limit load) at once is beyond what full Newton reaches in 6
    iterations (it needs 7); halves of the step are within its convergence radius, and the
    energy still balances (every sub-step enters the ledger). (Modified Newton gains little
    from cutbacks: its rate depends on the yielded fraction more than on the increment.)"""
    with pytest.raises(SolverError, match="equilibrium not reached"):
        run(sphere_in_one_step(1.25 * SIGMA_Y, cutbacks=0, max_iterations=6))
    seen = []
    _, state, ledger, counters = run(
        sphere_in_one_step(1.25 * SIGMA_Y, cutbacks=4, max_iterations=6),
        observe=lambda n, s, led, info: seen.append(info))
    assert counters.cutbacks >= 1 and seen[-1].cutbacks == counters.cutbacks
    assert state.t == 1.0 and ledger.plastic_work > 0
    assert ledger.relative_error < 1e-7


def test_a_load_beyond_the_limit_load_stops_with_a_diagnostic():
    """Above 2 ln 2 sigma_Y no equilibrium exists: cutbacks cannot help, the run stops and
    says so, naming the step and the cutbacks tried."""
    with pytest.raises(SolverError) as err:
        run(sphere_in_one_step(1.6 * SIGMA_Y, cutbacks=3, max_iterations=60,
                               method="modified_newton"))
    message = str(err.value)
    assert "step 1" in message and "after 3 levels of cut-back" in message
    assert "exceed" in message
