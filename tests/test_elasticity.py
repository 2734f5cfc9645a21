"""Element-level verification of the elasticity kernels (DESIGN §6)."""

import numpy as np
import pytest
import scipy.sparse.linalg as spla
from skfem import condense

from fem_frac.fem.elasticity import internal_force, stiffness, strain, stress
from fem_frac.fem.space import build_space
from fem_frac.fem.tensors import isotropic_tangent, mandel_from_matrix, tensor_from_mandel
from fem_frac.mesh import exterior_facets, tet_volumes
from meshes import structured_box

E, NU = 210e9, 0.3
D = isotropic_tangent(E, NU)


@pytest.fixture(scope="module")
def distorted():
    mesh = structured_box((4, 3, 3), (2.0, 1.0, 1.5), distortion=0.3, seed=1)
    assert np.all(tet_volumes(mesh.points, mesh.tets) > 0)
    return mesh


@pytest.mark.parametrize("order", [1, 2])
def test_patch_test_reproduces_affine_field(distorted, order):
    """An affine displacement prescribed on the boundary is reproduced inside to round-off,
    with the exact constant stress, on a distorted mesh (no body force)."""
    space = build_space(distorted, order)
    rng = np.random.default_rng(2)
    grad = 1e-3 * rng.normal(size=(3, 3))
    shift = 1e-3 * rng.normal(size=3)
    exact = (space.node_points @ grad.T + shift).ravel()
    facets = space.facet_indices(exterior_facets(distorted.tets))
    boundary = np.unique(space.basis.get_dofs(facets=facets).flatten())
    assert len(boundary) < space.n_nodes  # there are interior nodes to solve for
    dofs = (3 * boundary[:, None] + np.arange(3)).ravel()
    k = stiffness(space, D)
    u = np.zeros(space.n_dofs)
    u[dofs] = exact[dofs]
    a, b, _, interior = condense(k, np.zeros(space.n_dofs), x=u, D=dofs)
    u[interior] = spla.spsolve(a.tocsc(), b)
    assert np.max(np.abs(u - exact)) <= 1e-10 * np.max(np.abs(exact))
    sigma = stress(D, strain(space, u))
    expected = D @ mandel_from_matrix(grad[:, :, None])[:, 0]
    assert np.max(np.abs(sigma - expected[:, None, None])) <= 1e-10 * np.abs(expected).max()


@pytest.mark.parametrize("order", [1, 2])
def test_rigid_motion_gives_zero_internal_force(distorted, order):
    space = build_space(distorted, order)
    omega, shift = np.array([0.3, -0.2, 0.5]), np.array([1.0, 2.0, -3.0])
    u = (shift + np.cross(omega, space.node_points)).ravel()
    k = stiffness(space, D)
    scale = abs(k).max() * np.abs(u).max()
    assert np.max(np.abs(k @ u)) <= 1e-12 * scale
    assert np.max(np.abs(strain(space, u))) <= 1e-12 * np.abs(omega).max()
    f = internal_force(space, stress(D, strain(space, u)))
    assert np.max(np.abs(f)) <= 1e-12 * scale


@pytest.mark.parametrize("order", [1, 2])
def test_stiffness_is_symmetric_positive_definite_once_supported(distorted, order):
    space = build_space(distorted, order)
    k = stiffness(space, D)
    assert abs(k - k.T).max() <= 1e-14 * abs(k).max()
    clamped = np.nonzero(space.node_points[:, 0] < 1e-12)[0]
    dofs = (3 * clamped[:, None] + np.arange(3)).ravel()
    keep = np.setdiff1d(np.arange(space.n_dofs), dofs)
    a = k[keep][:, keep]
    smallest = spla.eigsh(a.tocsc(), k=1, sigma=0, which="LM", return_eigenvectors=False)
    assert smallest[0] > 0


def test_mandel_roundtrip_and_vtk_order():
    a = np.array([[1.0, 4.0, 6.0], [4.0, 2.0, 5.0], [6.0, 5.0, 3.0]])
    m = mandel_from_matrix(a[:, :, None])[:, 0]
    # VTK order XX YY ZZ XY YZ XZ, plain components after conversion
    np.testing.assert_allclose(tensor_from_mandel(m), [1, 2, 3, 4, 5, 6], rtol=1e-15)
    # Mandel makes the double contraction a dot product
    assert np.isclose(m @ m, np.sum(a * a), rtol=1e-15)
