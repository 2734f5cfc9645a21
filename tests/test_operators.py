"""Sparse strain operators (fem_frac.fem.operators), the solver's strain, internal force and
stiffness: the standard B against scikit-fem's own evaluation of the displacement gradient,
of the weak form of the internal force and of the linear elasticity form; the
averaged-nodal-volumetric-strain tetrahedron (patch tests, symmetry, its definition) and the
volumetric locking it cures.

Tolerances are round-off: ``ROUND`` (a small multiple of machine epsilon) times the sum of
the magnitudes of the terms a result adds up, or, for a whole matrix, of the Frobenius norm.
Measured: every check passes with 2 epsilon in place of ``ROUND``.
"""

import numpy as np
import pytest
import scipy.sparse.linalg as spla
from skfem import CellBasis, ElementVector, LinearForm, asm
from skfem.models.elasticity import linear_elasticity

from fem_frac.fem import elasticity
from fem_frac.fem.loads import surface_load
from fem_frac.fem.operators import strain_operator
from fem_frac.fem.space import INTORDER, build_space
from fem_frac.fem.tensors import (
    COMPONENTS,
    isotropic_tangent,
    lame_parameters,
    mandel_from_matrix,
    tensor_from_mandel,
)
from fem_frac.mesh import exterior_facets, tet_volumes
from meshes import structured_box

D = isotropic_tangent(210e9, 0.3)
MANDEL_I = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])
EPS = np.finfo(float).eps
ROUND = 16 * EPS


@pytest.fixture(scope="module")
def mesh():
    m = structured_box((4, 3, 3), (2.0, 1.0, 1.5), distortion=0.2, seed=3)
    assert np.all(tet_volumes(m.points, m.tets) > 0)
    return m


@pytest.fixture(scope="module")
def p1(mesh):
    return build_space(mesh, 1)


def frobenius_rel(a, b):
    return spla.norm(a - b) / spla.norm(b)


def random_spd_tangent(shape, rng):
    a = rng.normal(size=(6, 6) + shape)
    return np.einsum("ikeq,jkeq->ijeq", a, a) + 6.0 * np.eye(6)[:, :, None, None]


def apply(tangent, eps):
    """Mandel stress ``D eps`` ``(6, n_tets, n_qp)``, ``D`` shared or per quadrature point."""
    if tangent.ndim == 2:
        return np.einsum("ab,beq->aeq", tangent, eps)
    return np.einsum("abeq,beq->aeq", tangent, eps)


def strain_scale(op, u):
    """Largest sum of magnitudes of the terms of a strain component, ``max |B| |u|``."""
    return (abs(op.matrix) @ np.abs(u)).max()


def force_scale(op, sigma):
    """Largest sum of magnitudes of the terms of a nodal force, ``max |B|^T |sigma dx|``."""
    return (abs(op.matrix).T @ np.abs(sigma * op.weights).ravel()).max()


def affine(space, grad, shift):
    return (space.node_points @ grad.T + shift).ravel()


def dev(eps):
    return eps - MANDEL_I[:, None, None] * (eps[0] + eps[1] + eps[2]) / 3.0


# --------------------------------------------------------------------------- standard


@pytest.mark.parametrize("order", [1, 2])
def test_standard_against_scikit_fem(mesh, order):
    """Strain, internal force and stiffness of the standard operator against scikit-fem's
    evaluation of the same quantities; the Mandel layout enters the references only through
    ``fem_frac.fem.tensors`` (``mandel_from_matrix``, ``tensor_from_mandel``)."""
    space = build_space(mesh, order)
    op = strain_operator(space)
    rng = np.random.default_rng(order)
    n_local, n_rows = space.element_dofs.shape[1] // 3, mesh.n_tets * space.n_qp
    # only the nonzeros: n_local per normal row, 2 n_local per shear row
    assert op.matrix.shape == (6 * n_rows, space.n_dofs)
    assert op.matrix.nnz == 9 * n_local * n_rows
    assert np.all(np.diff(op.matrix.indptr)[3 * n_rows :] == 2 * n_local)

    # strain: sym grad u from scikit-fem's interpolation of each displacement component
    u = rng.normal(size=space.n_dofs)
    grad = np.stack([space.basis.interpolate(u[i::3]).grad for i in range(3)])  # du_i/dx_j
    expected = mandel_from_matrix(grad)
    assert np.max(np.abs(op.strain(u) - expected)) <= ROUND * strain_scale(op, u)

    # internal force: the weak form int sigma_ij dv_i/dx_j, assembled by scikit-fem
    sigma = rng.normal(size=op.shape)
    plain = tensor_from_mandel(sigma)
    fields = {f"s{i}{j}": plain[k] for k, (i, j) in enumerate(COMPONENTS)}
    fields.update({f"s{j}{i}": plain[k] for k, (i, j) in enumerate(COMPONENTS)})
    expected = np.empty(space.n_dofs)
    for i in range(3):
        form = LinearForm(lambda v, w, i=i: sum(w[f"s{i}{j}"] * v.grad[j] for j in range(3)))
        expected[i::3] = asm(form, space.basis, **fields)
    assert np.max(np.abs(op.internal_force(sigma) - expected)) <= ROUND * force_scale(op, sigma)

    # stiffness: scikit-fem's linear elasticity form on the vector basis (same dof numbering)
    vector = CellBasis(space.skmesh, ElementVector(space.basis.elem), intorder=INTORDER[order])
    reference = asm(linear_elasticity(*lame_parameters(210e9, 0.3)), vector)
    assert frobenius_rel(op.stiffness(D), reference) <= ROUND
    # the two assemblies (sparse triple product, element matrices) agree, for a tangent per
    # quadrature point too; the operator picks the faster one per order
    per_qp = random_spd_tangent(op.weights.shape, rng)
    for tangent in (D, per_qp):
        product = op.product_stiffness(tangent)
        assert frobenius_rel(product, elasticity.stiffness(space, tangent)) <= ROUND
        assert frobenius_rel(op.stiffness(tangent), product) <= ROUND


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
    expected = averaged.matrix @ u
    assert np.max(np.abs(averaged.strain(u).ravel() - expected)) <= ROUND * strain_scale(
        averaged, u
    )
    sigma = rng.normal(size=averaged.shape)
    expected = averaged.matrix.T @ (sigma * averaged.weights).ravel()
    assert np.max(np.abs(averaged.internal_force(sigma) - expected)) <= ROUND * force_scale(
        averaged, sigma
    )


def test_averaged_volumetric_strain_is_the_nodal_average(mesh, p1, averaged):
    """Against a direct evaluation of theta_bar_e = mean_{a in e} sum V theta / sum V."""
    u = np.random.default_rng(5).normal(size=p1.n_dofs)
    op = strain_operator(p1)
    standard = op.strain(u)
    eps = standard[:, :, 0]
    theta = eps[0] + eps[1] + eps[2]
    volumes = tet_volumes(mesh.points, mesh.tets)
    weighted = np.zeros(mesh.n_points)
    np.add.at(weighted, mesh.tets, (volumes * theta)[:, None])
    total = np.zeros(mesh.n_points)
    np.add.at(total, mesh.tets, volumes[:, None])
    theta_bar = (weighted / total)[mesh.tets].mean(axis=1)
    bar = averaged.strain(u)[:, :, 0]
    scale = strain_scale(op, u)
    assert np.max(np.abs(bar[0] + bar[1] + bar[2] - theta_bar)) <= ROUND * scale
    assert not np.allclose(theta_bar, theta)  # the average does something on this field
    # deviatoric part unchanged, exactly (to round-off)
    assert np.max(np.abs(dev(averaged.strain(u)) - dev(standard))) <= ROUND * scale


def test_averaged_patch_test_affine_and_rigid(p1, averaged):
    rng = np.random.default_rng(6)
    grad = 1e-3 * rng.normal(size=(3, 3))  # with a volumetric part
    assert abs(np.trace(grad)) > 1e-4
    u = affine(p1, grad, 1e-3 * rng.normal(size=3))
    exact = mandel_from_matrix(grad[:, :, None])[:, 0]
    eps = averaged.strain(u)
    assert np.max(np.abs(eps - exact[:, None, None])) <= ROUND * strain_scale(averaged, u)

    omega, shift = np.array([0.3, -0.2, 0.5]), np.array([1.0, 2.0, -3.0])
    rigid = (shift + np.cross(omega, p1.node_points)).ravel()
    assert np.max(np.abs(averaged.strain(rigid))) <= ROUND * strain_scale(averaged, rigid)


def test_averaged_patch_test_force_form(mesh, p1, averaged):
    """The stress of an affine field is in equilibrium: zero internal force at interior
    nodes; and, the stress being constant, the same nodal forces as the standard element."""
    rng = np.random.default_rng(7)
    grad = 1e-3 * rng.normal(size=(3, 3))
    u = affine(p1, grad, np.zeros(3))
    sigma = apply(D, averaged.strain(u))
    f = averaged.internal_force(sigma).reshape(-1, 3)
    boundary = np.unique(exterior_facets(mesh.tets))
    interior = np.setdiff1d(np.arange(p1.n_nodes), boundary)
    assert interior.size > 0
    assert np.abs(f).max() > 0
    # sigma is exact to round-off of |D| |B| |u|, the force adds |B|^T |sigma dx|
    magnitude = apply(np.abs(D), (abs(averaged.matrix) @ np.abs(u)).reshape(averaged.shape))
    scale = force_scale(averaged, magnitude)
    assert np.max(np.abs(f[interior])) <= ROUND * scale
    standard = strain_operator(p1).internal_force(sigma).reshape(-1, 3)
    assert np.max(np.abs(f - standard)) <= ROUND * scale


def test_averaged_isochoric_field_is_unchanged(p1, averaged):
    rng = np.random.default_rng(8)
    grad = rng.normal(size=(3, 3))
    grad -= np.trace(grad) / 3.0 * np.eye(3)
    u = affine(p1, grad, rng.normal(size=3))
    standard = strain_operator(p1).strain(u)
    scale = strain_scale(averaged, u)
    assert np.max(np.abs(averaged.strain(u) - standard)) <= ROUND * scale
    exact = mandel_from_matrix(grad[:, :, None])[:, 0]
    assert np.max(np.abs(averaged.strain(u) - exact[:, None, None])) <= ROUND * scale


@pytest.mark.parametrize("order, formulation", [(1, "standard"), (1, "averaged"), (2, "standard")])
def test_stiffness_is_the_derivative_of_the_internal_force(mesh, order, formulation):
    """``stiffness(D) u == internal_force(D strain(u))`` for any u, D shared or per
    quadrature point: the Newton matrix of the step loop is the derivative of its residual
    (for P2 the stiffness comes from element matrices, the force from the sparse B)."""
    op = strain_operator(build_space(mesh, order), formulation)
    rng = np.random.default_rng(9)
    b = abs(op.matrix)
    for tangent in (D, random_spd_tangent(op.weights.shape, rng)):
        k = op.stiffness(tangent)
        assert spla.norm(k - k.T) <= ROUND * spla.norm(k)
        u = rng.normal(size=op.space.n_dofs)
        f = op.internal_force(apply(tangent, op.strain(u)))
        terms = apply(np.abs(tangent), (b @ np.abs(u)).reshape(op.shape)) * op.weights
        assert np.max(np.abs(k @ u - f)) <= ROUND * (b.T @ terms.ravel()).max()


def test_averaged_stiffness_is_wider_and_annihilates_rigid_motions(p1, averaged):
    k = averaged.stiffness(D)
    assert k.nnz > strain_operator(p1).stiffness(D).nnz
    omega, shift = np.array([0.3, -0.2, 0.5]), np.array([1.0, 2.0, -3.0])
    rigid = (shift + np.cross(omega, p1.node_points)).ravel()
    assert np.max(np.abs(k @ rigid)) <= ROUND * (abs(k) @ np.abs(rigid)).max()


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
