"""Sparse strain operators (fem_frac.fem.operators): standard B against the element kernels of
fem_frac.fem.elasticity, the averaged-nodal-volumetric-strain tetrahedron (patch tests,
symmetry, its definition) and the volumetric locking it cures."""

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from fem_frac.fem import elasticity
from fem_frac.fem.loads import surface_load
from fem_frac.fem.operators import strain_operator
from fem_frac.fem.space import build_space
from fem_frac.fem.tensors import isotropic_tangent, mandel_from_matrix
from fem_frac.mesh import exterior_facets, tet_volumes
from meshes import structured_box

D = isotropic_tangent(210e9, 0.3)
MANDEL_I = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def mesh():
    m = structured_box((4, 3, 3), (2.0, 1.0, 1.5), distortion=0.2, seed=3)
    assert np.all(tet_volumes(m.points, m.tets) > 0)
    return m


@pytest.fixture(scope="module")
def p1(mesh):
    return build_space(mesh, 1)


def rel(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


def frobenius_rel(a, b):
    return spla.norm(a - b) / spla.norm(b)


def random_spd_tangent(shape, rng):
    a = rng.normal(size=(6, 6) + shape)
    return np.einsum("ikeq,jkeq->ijeq", a, a) + 6.0 * np.eye(6)[:, :, None, None]


def affine(space, grad, shift):
    return (space.node_points @ grad.T + shift).ravel()


def dev(eps):
    return eps - MANDEL_I[:, None, None] * (eps[0] + eps[1] + eps[2]) / 3.0


# --------------------------------------------------------------------------- standard


@pytest.mark.parametrize("order", [1, 2])
def test_standard_equals_elasticity_kernels(mesh, order):
    space = build_space(mesh, order)
    op = strain_operator(space)
    rng = np.random.default_rng(order)
    n_local, n_rows = space.element_dofs.shape[1] // 3, mesh.n_tets * space.n_qp
    # only the nonzeros: n_local per normal row, 2 n_local per shear row
    assert op.matrix.shape == (6 * n_rows, space.n_dofs)
    assert op.matrix.nnz == 9 * n_local * n_rows
    assert np.all(np.diff(op.matrix.indptr)[3 * n_rows :] == 2 * n_local)

    u = rng.normal(size=space.n_dofs)
    assert rel(op.strain(u), elasticity.strain(space, u)) <= 1e-12
    sigma = rng.normal(size=(6, mesh.n_tets, space.n_qp))
    assert rel(op.internal_force(sigma), elasticity.internal_force(space, sigma)) <= 1e-12

    per_qp = random_spd_tangent(op.weights.shape, rng)
    for tangent in (D, per_qp):
        expected = elasticity.stiffness(space, tangent)
        assert frobenius_rel(op.stiffness(tangent), expected) <= 1e-12
        # the sparse triple product (the averaged element's path) on the standard B
        assert frobenius_rel(op.product_stiffness(tangent), expected) <= 1e-12


def test_bad_arguments(mesh, p1):
    with pytest.raises(ValueError, match="P1 only"):
        strain_operator(build_space(mesh, 2), "averaged")
    with pytest.raises(ValueError, match="formulation"):
        strain_operator(p1, "bbar")
    with pytest.raises(ValueError, match="tangent"):
        strain_operator(p1).stiffness(np.eye(3))


# --------------------------------------------------------------------------- averaged


@pytest.fixture(scope="module")
def averaged(p1):
    return strain_operator(p1, "averaged")


def test_averaged_factored_products_equal_the_matrix(p1, averaged):
    """strain/internal_force go through the thin factors; they must equal the full matrix."""
    rng = np.random.default_rng(4)
    u = rng.normal(size=p1.n_dofs)
    assert rel(averaged.strain(u).ravel(), averaged.matrix @ u) <= 1e-12
    sigma = rng.normal(size=averaged.shape)
    expected = averaged.matrix.T @ (sigma * averaged.weights).ravel()
    assert rel(averaged.internal_force(sigma), expected) <= 1e-12


def test_averaged_volumetric_strain_is_the_nodal_average(mesh, p1, averaged):
    """Against a direct evaluation of theta_bar_e = mean_{a in e} sum V theta / sum V."""
    u = np.random.default_rng(5).normal(size=p1.n_dofs)
    eps = elasticity.strain(p1, u)[:, :, 0]
    theta = eps[0] + eps[1] + eps[2]
    volumes = tet_volumes(mesh.points, mesh.tets)
    weighted = np.zeros(mesh.n_points)
    np.add.at(weighted, mesh.tets, (volumes * theta)[:, None])
    total = np.zeros(mesh.n_points)
    np.add.at(total, mesh.tets, volumes[:, None])
    theta_bar = (weighted / total)[mesh.tets].mean(axis=1)
    bar = averaged.strain(u)[:, :, 0]
    assert rel(bar[0] + bar[1] + bar[2], theta_bar) <= 1e-12
    assert not np.allclose(theta_bar, theta)  # the average does something on this field
    # deviatoric part unchanged, exactly (to round-off)
    assert rel(dev(averaged.strain(u)), dev(elasticity.strain(p1, u))) <= 1e-12


def test_averaged_patch_test_affine_and_rigid(p1, averaged):
    rng = np.random.default_rng(6)
    grad = 1e-3 * rng.normal(size=(3, 3))  # with a volumetric part
    assert abs(np.trace(grad)) > 1e-4
    eps = averaged.strain(affine(p1, grad, 1e-3 * rng.normal(size=3)))
    exact = mandel_from_matrix(grad[:, :, None])[:, 0]
    assert np.max(np.abs(eps - exact[:, None, None])) <= 1e-12 * np.abs(exact).max()

    omega, shift = np.array([0.3, -0.2, 0.5]), np.array([1.0, 2.0, -3.0])
    rigid = (shift + np.cross(omega, p1.node_points)).ravel()
    assert np.max(np.abs(averaged.strain(rigid))) <= 1e-12 * np.abs(omega).max()


def test_averaged_patch_test_force_form(mesh, p1, averaged):
    """The stress of an affine field is in equilibrium: zero internal force at interior
    nodes; and, the stress being constant, the same nodal forces as the standard element."""
    rng = np.random.default_rng(7)
    grad = 1e-3 * rng.normal(size=(3, 3))
    sigma = elasticity.stress(D, averaged.strain(affine(p1, grad, np.zeros(3))))
    f = averaged.internal_force(sigma).reshape(-1, 3)
    boundary = np.unique(exterior_facets(mesh.tets))
    interior = np.setdiff1d(np.arange(p1.n_nodes), boundary)
    assert interior.size > 0
    scale = np.abs(f).max()
    assert scale > 0
    assert np.max(np.abs(f[interior])) <= 1e-10 * scale
    standard = strain_operator(p1).internal_force(sigma).reshape(-1, 3)
    assert np.max(np.abs(f - standard)) <= 1e-10 * scale


def test_averaged_isochoric_field_is_unchanged(p1, averaged):
    rng = np.random.default_rng(8)
    grad = rng.normal(size=(3, 3))
    grad -= np.trace(grad) / 3.0 * np.eye(3)
    u = affine(p1, grad, rng.normal(size=3))
    standard = elasticity.strain(p1, u)
    assert rel(averaged.strain(u), standard) <= 1e-12
    exact = mandel_from_matrix(grad[:, :, None])[:, 0]
    assert rel(averaged.strain(u), np.broadcast_to(exact[:, None, None], standard.shape)) <= 1e-12


def test_averaged_stiffness_symmetric_and_consistent(p1, averaged):
    """K is symmetric, wider than the standard one, annihilates rigid motions and is the
    derivative of the internal force: K u == internal_force(D strain(u))."""
    rng = np.random.default_rng(9)
    for tangent in (D, random_spd_tangent(averaged.weights.shape, rng)):
        k = averaged.stiffness(tangent)
        assert spla.norm(k - k.T) <= 1e-13 * spla.norm(k)
        u = rng.normal(size=p1.n_dofs)
        f = averaged.internal_force(elasticity.stress(tangent, averaged.strain(u)))
        assert rel(k @ u, f) <= 1e-12
    assert k.nnz > strain_operator(p1).stiffness(D).nnz
    omega, shift = np.array([0.3, -0.2, 0.5]), np.array([1.0, 2.0, -3.0])
    rigid = (shift + np.cross(omega, p1.node_points)).ravel()
    assert np.max(np.abs(k @ rigid)) <= 1e-12 * abs(k).max() * np.abs(rigid).max()


# --------------------------------------------------------------------------- locking


def tip_deflection(mesh, order, formulation, nu):
    """Load-weighted mean deflection (f . u / |f|) of a block clamped at x = 0 (all dofs),
    with u_y = 0 on the symmetry plane y = 0, under a uniform traction -z at x = x_max."""
    space = build_space(mesh, order)
    k = strain_operator(space, formulation).stiffness(isotropic_tangent(1.0, nu))
    tri = exterior_facets(mesh.tets)
    tip = tri[np.all(np.isclose(mesh.points[tri, 0], mesh.points[:, 0].max()), axis=1)]
    f = surface_load(space, space.facet_indices(tip), traction=(0.0, 0.0, -1.0))
    clamped = np.nonzero(space.node_points[:, 0] < 1e-12)[0]
    symmetry = np.nonzero(space.node_points[:, 1] < 1e-12)[0]
    fixed = np.union1d((3 * clamped[:, None] + np.arange(3)).ravel(), 3 * symmetry + 1)
    free = np.setdiff1d(np.arange(space.n_dofs), fixed)
    u = np.zeros(space.n_dofs)
    u[free] = spla.spsolve(k[free][:, free].tocsc(), f[free])
    return (f @ u) / np.abs(f).sum()


def test_averaged_element_cures_volumetric_locking():
    """Half (by symmetry) of a 2 x 1 x 1 cantilever block, 12 x 3 x 6 cells (1296 tets),
    distortion 0.2, E = 1, nu = 0.4999, end traction -z. Measured deflection ratios to P2
    (standard) on the same mesh:

        nu        P1/P2   averaged P1/P2
        0.3       0.89    0.95
        0.49      0.53    0.91
        0.4999    0.22    0.885
        0.499999  0.19    0.89

    Standard P1 locks: each tet carries one incompressibility constraint against ~1/5 of a
    free vertex (3 dofs / 5-6 tets), so as nu -> 1/2 its deflection collapses (0.22 of P2
    here, hence the threshold 0.5 with a wide margin). The averaged element has about one
    volumetric constraint per vertex instead; what remains of its gap to P2 (0.885, within
    the 15% asked) is the ordinary coarse-mesh bending stiffness of linear tets, already
    0.95 at nu = 0.3, not locking: it does not grow as nu -> 1/2.
    """
    mesh = structured_box((12, 3, 6), (2.0, 0.5, 1.0), distortion=0.2)
    p2 = tip_deflection(mesh, 2, "standard", 0.4999)
    p1 = tip_deflection(mesh, 1, "standard", 0.4999)
    bar = tip_deflection(mesh, 1, "averaged", 0.4999)
    assert p2 > 0
    assert p1 < 0.5 * p2
    assert abs(bar - p2) <= 0.15 * p2
