"""Element-level verification of the strain operator the solver uses (DESIGN §6).

Everything here goes through ``fem_frac.fem.operators.strain_operator`` (its ``strain``,
``internal_force`` and ``stiffness``, as ``fem_frac.solve.stepping`` calls them) and the
stress of ``fem_frac.plasticity.law.MaterialLaw``, for P1 and P2 and both formulations:
patch tests, rigid motions, the stiffness, and the Mandel scaling against strain energies and
stresses computed by hand from the exact strain tensor.

Tolerances are round-off: ``ROUND`` (a small multiple of machine epsilon) times the sum of
the magnitudes of the terms the result adds up (``|B| |u|`` for a strain, ``|B|^T |D| |B|
|u| dx`` for a force), and for a linear solve times the condition number of its matrix too.
Measured: at most 0.07 of those bounds, about one epsilon times the scale.
"""

import numpy as np
import pytest
import scipy.sparse.linalg as spla
from skfem import condense

from fem_frac.fem.operators import strain_operator
from fem_frac.fem.space import build_space
from fem_frac.fem.tensors import (
    lame_parameters,
    mandel_from_matrix,
    tensor_from_mandel,
)
from fem_frac.mesh import exterior_facets, tet_volumes
from fem_frac.plasticity.law import MaterialLaw
from meshes import structured_box

E, NU = 210e9, 0.3
LAW = MaterialLaw(E, NU)
D = LAW.elastic_tangent
LAM, MU = lame_parameters(E, NU)
LENGTHS = (2.0, 1.0, 1.5)
VOLUME = float(np.prod(LENGTHS))  # the distortion moves only interior vertices
EPS = np.finfo(float).eps
ROUND = 16 * EPS
CASES = [(1, "standard"), (1, "averaged"), (2, "standard")]
IDS = ["P1", "P1-averaged", "P2"]


@pytest.fixture(scope="module")
def distorted():
    mesh = structured_box((4, 3, 3), LENGTHS, distortion=0.3, seed=1)
    assert np.all(tet_volumes(mesh.points, mesh.tets) > 0)
    return mesh


@pytest.fixture(scope="module", params=CASES, ids=IDS)
def op(request, distorted):
    order, formulation = request.param
    return strain_operator(build_space(distorted, order), formulation)


def affine(space, grad, shift):
    return (space.node_points @ grad.T + shift).ravel()


def rigid(space):
    omega, shift = np.array([0.3, -0.2, 0.5]), np.array([1.0, 2.0, -3.0])
    return (shift + np.cross(omega, space.node_points)).ravel()


def stress(op, u):
    """The solver's stress of ``u``: the elastic law applied to the operator's strain."""
    return LAW.update(op.strain(u), None)[0]


def strain_scale(op, u):
    """Largest sum of magnitudes of the terms of a strain component, ``max |B| |u|``."""
    return float((abs(op.matrix) @ np.abs(u)).max())


def force_scale(op, u):
    """Largest sum of magnitudes of the terms of a nodal force, ``max |B|^T |D| |B| |u| dx``."""
    b = abs(op.matrix)
    terms = np.abs(D) @ (b @ np.abs(u)).reshape(6, -1) * op.weights.ravel()
    return float((b.T @ terms.ravel()).max())


def exact_stress(eps):
    """Hand-computed Mandel stress of a (3, 3) strain tensor: lam tr(eps) I + 2 mu eps."""
    sigma = LAM * np.trace(eps) * np.eye(3) + 2.0 * MU * eps
    return mandel_from_matrix(sigma[:, :, None])[:, 0]


def exact_energy(eps):
    """Strain energy of a uniform strain over the box: V (lam / 2 tr(eps)^2 + mu eps:eps)."""
    return VOLUME * (0.5 * LAM * np.trace(eps) ** 2 + MU * np.sum(eps * eps))


# --------------------------------------------------------------------------- patch tests


def test_patch_test_reproduces_affine_field(distorted, op):
    """An affine displacement prescribed on the boundary is reproduced inside to round-off,
    with the exact constant strain and stress, on a distorted mesh (no body force)."""
    space = op.space
    rng = np.random.default_rng(2)
    grad = 1e-3 * rng.normal(size=(3, 3))  # volumetric, shear and rotation parts
    exact = affine(space, grad, 1e-3 * rng.normal(size=3))
    facets = space.facet_indices(exterior_facets(distorted.tets))
    boundary = np.unique(space.basis.get_dofs(facets=facets).flatten())
    assert len(boundary) < space.n_nodes  # there are interior nodes to solve for
    dofs = (3 * boundary[:, None] + np.arange(3)).ravel()
    k = op.stiffness(D)
    u = np.zeros(space.n_dofs)
    u[dofs] = exact[dofs]
    a, b, _, interior = condense(k, np.zeros(space.n_dofs), x=u, D=dofs)
    u[interior] = spla.spsolve(a.tocsc(), b)
    # condition number of the solve (measured 6 for P1-averaged, 11 for P1, 99 for P2)
    largest = spla.eigsh(a, k=1, which="LA", return_eigenvectors=False)[0]
    smallest = spla.eigsh(a.tocsc(), k=1, sigma=0, which="LM", return_eigenvectors=False)[0]
    kappa = largest / smallest
    assert np.max(np.abs(u - exact)) <= ROUND * kappa * np.max(np.abs(exact))

    eps_exact = 0.5 * (grad + grad.T)
    expected = mandel_from_matrix(eps_exact[:, :, None])[:, 0]
    scale = strain_scale(op, exact)
    # B reproduces an affine field's strain exactly; the solved field's to kappa round-off
    assert np.max(np.abs(op.strain(exact) - expected[:, None, None])) <= ROUND * scale
    assert np.max(np.abs(op.strain(u) - expected[:, None, None])) <= ROUND * kappa * scale
    sigma = stress(op, u)
    d_norm = np.abs(D).sum(axis=1).max()
    assert np.max(np.abs(sigma - exact_stress(eps_exact)[:, None, None])) <= (
        ROUND * kappa * d_norm * scale
    )
    # force form: a constant stress is in equilibrium, zero force at the interior dofs
    f = op.internal_force(sigma)
    assert np.max(np.abs(f[interior])) <= ROUND * kappa * force_scale(op, exact)


# --------------------------------------------------------------------------- Mandel scaling


SHEAR = np.array([[0.0, 3.0, -1.0], [3.0, 0.0, 2.0], [-1.0, 2.0, 0.0]]) * 1e-4
GENERAL = np.array([[1.0, 3.0, -1.0], [3.0, -2.0, 2.0], [-1.0, 2.0, 4.0]]) * 1e-4
SPIN = np.array([[0.0, -1.0, 2.0], [1.0, 0.0, -3.0], [-2.0, 3.0, 0.0]]) * 1e-4


@pytest.mark.parametrize("eps", [SHEAR, GENERAL], ids=["pure-shear", "general"])
def test_energy_force_and_stress_of_a_uniform_strain(op, eps):
    """An affine field ``u = (eps + W) x + c`` (``W`` skew: a rotation, no strain) against
    quantities computed by hand from the exact tensor ``eps``:

    - the strain energy ``u.K.u / 2 = V (lam / 2 tr(eps)^2 + mu eps:eps)``, exact for an
      affine field (the quadrature integrates a constant); the pure shear case tests only
      the shear rows, where a Voigt/Mandel mix-up (shear scaled by 1 or 2 instead of sqrt 2)
      changes the energy by a factor 2;
    - the internal force of the operator's strain and the law's stress is ``K u``;
    - that stress is the Mandel vector of ``lam tr(eps) I + 2 mu eps``, and in plain
      components (``tensor_from_mandel``) the tensor itself.
    """
    space = op.space
    u = affine(space, eps + SPIN, np.array([1e-4, -2e-4, 3e-4]))
    k = op.stiffness(D)
    energy = 0.5 * u @ (k @ u)
    magnitude = 0.5 * np.abs(u) @ (abs(k) @ np.abs(u))  # sum of the terms' magnitudes
    assert abs(energy - exact_energy(eps)) <= ROUND * magnitude
    assert abs(LAW.elastic_energy(stress(op, u), op.weights) - exact_energy(eps)) <= (
        ROUND * exact_energy(eps)
    )

    sigma = stress(op, u)
    assert np.max(np.abs(op.internal_force(sigma) - k @ u)) <= ROUND * force_scale(op, u)

    expected = exact_stress(eps)
    d_norm = np.abs(D).sum(axis=1).max()
    tol = ROUND * d_norm * strain_scale(op, u)
    assert np.max(np.abs(sigma - expected[:, None, None])) <= tol
    plain = LAM * np.trace(eps) * np.eye(3) + 2.0 * MU * eps
    components = [plain[0, 0], plain[1, 1], plain[2, 2], plain[0, 1], plain[1, 2], plain[0, 2]]
    assert np.max(np.abs(tensor_from_mandel(sigma) - np.array(components)[:, None, None])) <= tol


# --------------------------------------------------------------------------- rigid motions


def test_rigid_motion_gives_zero_strain_and_internal_force(op):
    u = rigid(op.space)
    assert np.max(np.abs(op.strain(u))) <= ROUND * strain_scale(op, u)
    scale = force_scale(op, u)
    assert np.max(np.abs(op.stiffness(D) @ u)) <= ROUND * scale
    assert np.max(np.abs(op.internal_force(stress(op, u)))) <= ROUND * scale


# --------------------------------------------------------------------------- stiffness


def test_stiffness_is_symmetric_semidefinite_with_the_rigid_null_space(op):
    """Symmetric; free, its null space is the six rigid motions and nothing else (no spurious
    zero-energy mode); clamped on one face it is positive definite."""
    space = op.space
    k = op.stiffness(D)
    assert abs(k - k.T).max() <= ROUND * abs(k).max()
    largest = spla.eigsh(k, k=1, which="LA", return_eigenvectors=False)[0]
    # the 7 eigenvalues nearest a small negative shift: 6 zeros, then a clearly positive one
    lowest = np.sort(
        spla.eigsh(k.tocsc(), k=7, sigma=-1e-6 * largest, which="LM", return_eigenvectors=False)
    )
    assert np.all(np.abs(lowest[:6]) <= ROUND * largest)  # measured 0.1 eps of it
    assert lowest[6] > 1e-6 * largest  # measured 3e-4 to 6e-3 of the largest

    clamped = np.nonzero(space.node_points[:, 0] < 1e-12)[0]
    dofs = (3 * clamped[:, None] + np.arange(3)).ravel()
    keep = np.setdiff1d(np.arange(space.n_dofs), dofs)
    a = k[keep][:, keep]
    smallest = spla.eigsh(a.tocsc(), k=1, sigma=0, which="LM", return_eigenvectors=False)
    assert smallest[0] > 1e-6 * largest


def test_mandel_roundtrip_and_vtk_order():
    a = np.array([[1.0, 4.0, 6.0], [4.0, 2.0, 5.0], [6.0, 5.0, 3.0]])
    m = mandel_from_matrix(a[:, :, None])[:, 0]
    # VTK order XX YY ZZ XY YZ XZ, plain components after conversion
    np.testing.assert_allclose(tensor_from_mandel(m), [1, 2, 3, 4, 5, 6], rtol=1e-15)
    # Mandel makes the double contraction a dot product
    assert np.isclose(m @ m, np.sum(a * a), rtol=1e-15)
