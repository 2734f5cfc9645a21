"""Cohesive crack faces in the solver: a bar cut across by a crack whose faces carry the
traction-separation law, pulled, unloaded, reloaded, separated and pushed back.

The bar (length 1, section 0.5 x 0.5, nu = 0, symmetry on xmin, ymin, zmin, the end xmax
moved along x) is cut at x = 0.5 through every vertex of that plane. Under uniform
uniaxial stress the jump is uniform over the crack and the stress in the bulk equals the
normal traction (P1 reproduces it exactly, and the vertex rule's weights are the bulk's
consistent nodal forces), so the reaction on xmax over the section is the law's traction at
the measured jump, step by step. The section is one element wide so that the initial
stiffness is set by its floor ``2 sigma_t^2 / G_c`` on every face: the whole crack follows
one path. Parameters keep the bar from snapping back: ``L sigma_t / (E (lambda_c -
lambda_0)) < 1``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fem_frac.app.driver import prepare
from fem_frac.config.schema import Case
from fem_frac.fracture.topology import open_crack
from fem_frac.mesh.mesh import TET_FACES, Mesh, exterior_face_rows
from fem_frac.solve.energy import initial_ledger
from fem_frac.solve.state import initial_state
from fem_frac.solve.stepping import advance
from fem_frac.timing import StageTimer
from fem_frac.world.transfer import rediscretize
from meshes import structured_box

E, STRENGTH, ENERGY = 100.0, 1.0, 0.0075
AREA = 0.25
K0 = 2.0 * STRENGTH**2 / ENERGY  # the floor of the initial stiffness
PEAK = STRENGTH / K0
CRITICAL = 2.0 * ENERGY / STRENGTH


def case(opening: list[float], dynamic: bool = False, method: str = "modified_newton"):
    n = len(opening) - 1
    analysis = ({"type": "dynamic", "dt": 1.0 / n, "steps": n, "mass": "consistent"}
                if dynamic else {"type": "quasi_static", "steps": n,
                                 "equilibrium": {"method": method}})
    return {
        "units": "SI",
        "mesh": {"geometry": {"type": "box", "lengths": [1.0, 0.5, 0.5]},
                 "element_size": 0.5},
        "material": {"youngs_modulus": E, "poissons_ratio": 0.0, "density": 1e-3},
        "load_curves": {"path": {"type": "table", "points": [
            [k / n, value] for k, value in enumerate(opening)]}},
        "boundary_conditions": [
            {"type": "symmetry", "boundary": "xmin"},
            {"type": "symmetry", "boundary": "ymin"},
            {"type": "symmetry", "boundary": "zmin"},
            {"type": "displacement", "boundary": "xmax", "x": 1.0, "curve": "path"}],
        "fracture": {"tensile_strength": STRENGTH, "fracture_energy": ENERGY,
                     "smoothing": {"rings": 0}, "cohesive": {"penalty": 1.0}},
        "analysis": analysis,
    }


def cracked_bar() -> Mesh:
    """The bar, its faces named by the box's sides, cut at x = 0.5."""
    mesh = structured_box((2, 1, 1), lengths=(1.0, 0.5, 0.5))
    faces = mesh.tets[:, TET_FACES].reshape(-1, 3)[exterior_face_rows(mesh.tets,
                                                                      mesh.n_points)]
    centre = mesh.points[faces].mean(axis=1)
    size = np.array([1.0, 0.5, 0.5])
    boundaries = {}
    for axis, name in enumerate("xyz"):
        boundaries[f"{name}min"] = faces[np.abs(centre[:, axis]) < 1e-12]
        boundaries[f"{name}max"] = faces[np.abs(centre[:, axis] - size[axis]) < 1e-12]
    mesh = Mesh(mesh.points, mesh.tets, boundaries)
    plane = np.flatnonzero(np.abs(mesh.points[:, 0] - 0.5) < 1e-12)
    cut, _ = open_crack(mesh, plane, np.tile([1.0, 0.0, 0.0], (len(plane), 1)))
    return cut


def march(opening, order: int = 1, law: str = "linear", quadrature: str = "vertices", **kw):
    """Step the cut bar along the end displacements ``opening``: per step the uniform jump
    along x, the normal traction from the reaction, and the ledger."""
    c = case(opening, **kw)
    c["mesh"]["order"] = order
    c["fracture"]["cohesive"]["law"] = law
    c["fracture"]["cohesive"]["quadrature"] = quadrature
    setup = prepare(Case.model_validate(c), Path("."), StageTimer())
    disc = rediscretize(setup.disc, cracked_bar(), StageTimer(), "cut")
    stepper, ops = disc.stepper, disc.ops
    state = initial_state(disc.problem, disc.law, ops, None, disc.constrained)
    ledger = initial_ledger(state, disc.law, ops)
    n = len(opening) - 1
    rows = []
    for k in range(1, n + 1):
        state, ledger, _ = advance(stepper, state, k / n, ledger, k)
        jump = ops.interface.openings(state.u)
        reaction = state.reaction.reshape(-1)
        xmax = disc.problem.reaction_groups["xmax"]
        full = np.zeros(disc.space.n_dofs)
        full[disc.constrained.dofs] = reaction
        rows.append((jump, full[xmax].reshape(-1, 3).sum(axis=0)[0] / AREA, ledger, state))
    return disc, rows


def expected_path(jumps: np.ndarray, law) -> np.ndarray:
    """The normal traction of the law along a history of uniform normal jumps (kappa the
    largest jump so far, unloading to the origin), written out independently."""
    out, kappa = [], 0.0
    for d in jumps:
        kappa = max(kappa, d, PEAK)
        envelope = law(kappa)
        out.append(envelope * d / kappa if d < kappa else law(d))
    return np.array(out)


def linear(lam: float) -> float:
    if lam <= PEAK:
        return K0 * lam
    return max(STRENGTH * (CRITICAL - lam) / (CRITICAL - PEAK), 0.0)


# end displacements: pull past the peak (at sigma_t L / E + lambda_0 = 0.01375), unload to
# zero force, reload past the old maximum, pull to full separation (lambda_c = 0.015)
PATH = [0.0, 0.006, 0.012, 0.0142, 0.0145, 0.007, 0.0, 0.008, 0.0146, 0.0148, 0.016, 0.02]


@pytest.mark.parametrize("order, quadrature", [(1, "vertices"), (1, "gauss"), (2, "gauss")])
@pytest.mark.parametrize("method", ["modified_newton", "newton"])
def test_pulled_apart_unloaded_reloaded_follows_the_law(order, quadrature, method):
    """Either rule of P1 faces (their corners or three points inside) gives every corner
    the bulk's consistent nodal force A/3 of a uniform traction, so both follow the law."""
    disc, rows = march(PATH, order=order, method=method, quadrature=quadrature)
    interface = disc.ops.interface
    assert np.all(interface.stiffness == K0)
    if order == 1:  # the points: the corners (shape value 1) or (2/3, 1/6, 1/6) inside
        top = abs(interface.jump).max()
        assert top == pytest.approx(1.0 if quadrature == "vertices" else 2.0 / 3.0, rel=1e-12)
    jumps = np.array([r[0] for r in rows])  # (steps, q, 3)
    # the jump is uniform and along x: one path for the whole crack
    scale = np.abs(jumps).max()
    np.testing.assert_allclose(jumps[:, :, 1:], 0.0, atol=1e-9 * scale)
    np.testing.assert_allclose(jumps[:, :, 0], np.broadcast_to(jumps[:, :1, 0],
                                                              jumps.shape[:2]),
                               rtol=0, atol=1e-9 * scale)
    normal = jumps[:, 0, 0]
    traction = np.array([r[1] for r in rows])  # the support holds the traction
    expected = expected_path(normal, linear)
    # equilibrium is solved to a relative residual 1e-8 of the forces
    np.testing.assert_allclose(traction, expected, rtol=0, atol=1e-7 * STRENGTH)
    assert normal.max() > CRITICAL  # separated at the end
    assert np.any(np.diff(normal) < 0)  # and unloaded on the way
    # at full separation every face has dissipated G_c over its area
    ledger = rows[-1][2]
    np.testing.assert_allclose(ledger.cohesive_dissipated, ENERGY * AREA, rtol=1e-12)
    assert ledger.cohesive_stored == pytest.approx(0.0, abs=1e-15)
    # quasi-static: external work = strain energy + cohesive work, to solver tolerance
    assert ledger.relative_error < 1e-7


def test_exponential_law_dissipates_its_fracture_energy():
    disc, rows = march(PATH + [0.06, 0.1], law="exponential")
    law = disc.ops.interface.law
    assert rows[-1][0][:, 0].min() > law.critical_opening(K0)
    np.testing.assert_allclose(rows[-1][2].cohesive_dissipated, ENERGY * AREA, rtol=1e-12)


def test_closed_faces_do_not_pass_through_each_other():
    """Pushed back after separating, the faces touch and carry the compression through the
    penalty k0: the overlap is the compressive traction over k0, which the push sets."""
    push = [0.0, 0.01, 0.02, 0.005, -0.002, -0.004]
    _, rows = march(push)
    jump, traction = rows[-1][0][:, 0], rows[-1][1]
    assert traction < 0
    # overlap = |sigma| / k0 exactly
    np.testing.assert_allclose(jump, traction / K0, rtol=1e-7)
    # the stated bound (docs/fracture.md): k0 >= penalty E / h, so the overlap is at most
    # 1 / penalty of an element's own elastic shortening |sigma| h / E (h: the face's mean
    # edge length, here at least the cell size 0.5)
    assert np.abs(jump).max() <= abs(traction) * 0.5 / (1.0 * E)


def test_the_secant_matrices_of_the_steps_share_one_analysis():
    """The faces' secant stiffness changes as they soften, not its pattern: a step whose
    secant changed refactorizes numerically on PARDISO's one analysis, also once the faces
    have separated and their couplings vanish from the sum (part of the pattern analysed:
    tests/test_linalg.py)."""
    from fem_frac.solve.linalg import available_methods

    if "pardiso" not in available_methods():
        pytest.skip("PARDISO is not installed here")
    c = case(PATH)
    c["fracture"]["cohesive"]["law"] = "linear"
    setup = prepare(Case.model_validate(c), Path("."), StageTimer())
    disc = rediscretize(setup.disc, cracked_bar(), StageTimer(), "cut")
    stepper = disc.stepper
    state = initial_state(disc.problem, disc.law, disc.ops, None, disc.constrained)
    ledger = initial_ledger(state, disc.law, disc.ops)
    made = 0
    for k in range(1, len(PATH)):
        state, ledger, info = advance(stepper, state, k / (len(PATH) - 1), ledger, k)
        made += info.factorizations
    # 9 secant factorizations (the secant changed from step to step), one analysis
    assert made >= 8 and stepper.secants.analyses == 1


def test_dynamic_cohesive_run_balances_its_ledger():
    """Newmark average acceleration through softening and separation: the energy balance
    with the cohesive work is exact at converged equilibrium."""
    _, rows = march(PATH, dynamic=True)
    ledger = rows[-1][2]
    assert ledger.cohesive_dissipated > 0.5 * ENERGY * AREA
    assert ledger.relative_error < 1e-8


def test_explicit_stable_step_holds_the_cohesive_stiffness():
    """Central difference on the cut bar: the stable step accounts for the faces' initial
    stiffness (Lanczos on K + K_coh, or the element bound plus Gershgorin's bound on
    M^-1 K_coh), and stepping at it through softening and separation stays stable and keeps
    the energy balance to the scheme's O(dt^2)."""
    from scipy.linalg import eigh

    c = case(PATH)
    c["analysis"] = {"type": "dynamic", "integrator": "central_difference", "dt": 1e-3,
                     "steps": 1000, "mass": "lumped", "substeps": True}
    c["fracture"]["cohesive"]["penalty"] = 200.0  # stiff faces: they set the step
    setup = prepare(Case.model_validate(c), Path("."), StageTimer())
    plain = setup.disc.limit
    disc = rediscretize(setup.disc, cracked_bar(), StageTimer(), "cut")
    ops, free = disc.ops, disc.constrained.free
    response, _ = ops.interface.respond(np.zeros(disc.space.n_dofs),
                                        np.zeros(ops.interface.n_points))
    k = (ops.stiffness + ops.interface.matrix(response.secant)).toarray()[np.ix_(free, free)]
    omega = np.sqrt(eigh(k, np.diag(ops.mass.diagonal()[free]), eigvals_only=True).max())
    assert disc.limit.omega_max >= omega * (1 - 1e-6)
    assert disc.limit.element_bound_dt <= 2.0 / omega  # the bound is never above omega_max
    assert disc.limit.dt < 0.5 * plain.dt  # the faces are stiffer than the cells
    state = initial_state(disc.problem, disc.law, ops, None, disc.constrained)
    ledger = initial_ledger(state, disc.law, ops)
    for n in range(1, 1001):
        state, ledger, _ = advance(disc.stepper, state, n * 1e-3, ledger, n)
    assert ops.interface.openings(state.u)[:, 0].min() > CRITICAL  # separated
    np.testing.assert_allclose(ledger.cohesive_dissipated, ENERGY * AREA, rtol=1e-12)
    # measured 3.2e-5 (the shadow energy of central difference differs by (dt^2 / 8) a^T M a)
    assert ledger.relative_error < 1e-3
