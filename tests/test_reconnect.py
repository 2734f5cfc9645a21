"""Operators of a cracked mesh updated from the old ones (fem_frac.fem.reconnect) against a
fresh assembly: B the same bits, K the same values to round-off and the same pattern."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from fem_frac.fem.operators import strain_operator
from fem_frac.fem.reconnect import changed_tets, reconnect
from fem_frac.fem.space import build_space
from fem_frac.fem.tensors import isotropic_tangent
from fem_frac.fracture import open_crack
from meshes import structured_box

D = isotropic_tangent(210e9, 0.3)


def _cracked(distortion):
    """A distorted box and the same box cracked at the plane x = 0.5 over y < 0.6
    (normal x), twice over: the second insertion acts on the first one's mesh."""
    mesh = structured_box((4, 4, 4), distortion=distortion, seed=3)
    p = mesh.points
    first = np.flatnonzero((np.abs(p[:, 0] - 0.5) < 0.13) & (p[:, 1] < 0.3))
    once, t1 = open_crack(mesh, first[:3], np.tile([1.0, 0.0, 0.0], (3, 1)))
    q = once.points
    second = np.flatnonzero((np.abs(q[:, 0] - 0.5) < 0.13) & (q[:, 1] > 0.3) & (q[:, 1] < 0.6))
    twice, t2 = open_crack(once, second[:2], np.tile([1.0, 0.1, 0.0], (2, 1)))
    return [(mesh, once, t1), (once, twice, t2)]


@pytest.mark.parametrize("per_element", [False, True])
@pytest.mark.parametrize("distortion", [0.0, 0.15])
def test_reconnected_operators_equal_a_fresh_assembly(distortion, per_element):
    for old, new, transfer in _cracked(distortion):
        assert new.n_points > old.n_points
        changed = changed_tets(old.tets, new.tets, transfer.node_map)
        assert changed is not None and 0 < changed.size < new.n_tets
        old_space, new_space = build_space(old, 1), build_space(new, 1)
        tangent = D
        if per_element:  # a second material on half the tets
            scale = np.where(np.arange(old.n_tets) % 2 == 0, 1.0, 0.25)
            tangent = np.ascontiguousarray(D[:, :, None, None] * scale[None, None, :, None])
        op = strain_operator(old_space)
        op_new, k_new, diagonal = reconnect(op, op.stiffness(tangent), tangent, new_space,
                                            np.asarray(old.tets), np.asarray(new.tets),
                                            changed)
        np.testing.assert_array_equal(diagonal, k_new.diagonal())
        fresh = strain_operator(new_space)
        for a, b in ((op_new.matrix, fresh.matrix),):
            np.testing.assert_array_equal(a.indptr, b.indptr)
            np.testing.assert_array_equal(a.indices, b.indices)
            np.testing.assert_array_equal(a.data, b.data)
        k_fresh = fresh.stiffness(tangent).tocsr()
        k_fresh.eliminate_zeros()
        scale = np.abs(k_fresh.diagonal()).max()
        assert abs(k_new - k_fresh).max() <= 1e-14 * scale * 10
        # the same couplings: none kept that only the changed tets carried
        kept = k_fresh.copy()
        kept.data[np.abs(kept.data) <= 1e-13 * scale] = 0.0
        kept.eliminate_zeros()
        assert (k_new != 0).nnz == (kept != 0).nnz
        assert ((k_new != 0) != (kept != 0)).nnz == 0


def test_not_a_reconnection_is_refused():
    mesh = structured_box((2, 2, 2))
    tets = np.asarray(mesh.tets)
    ids = np.arange(mesh.n_points)
    assert changed_tets(tets, tets, ids).size == 0
    assert changed_tets(tets, tets[::-1], ids) is None  # tets reordered
    assert changed_tets(tets, tets[1:], ids) is None  # a tet gone
    assert changed_tets(tets, tets, ids[::-1]) is None  # old ids not kept


@pytest.mark.parametrize("order", [1, 2])
def test_element_masses_survive_a_crack(order):
    """A crack moves no tet: the scalar element masses of the cracked mesh are the old
    ones to the bit, so a reconnected discretization carries them over
    (solve.discretization) and its consistent mass is the fresh one."""
    from fem_frac.fem.mass import consistent_mass, element_scalar_mass

    for old, new, _ in _cracked(0.15):
        old_space, new_space = build_space(old, order), build_space(new, order)
        kept = element_scalar_mass(old_space, 7800.0)
        np.testing.assert_array_equal(kept, element_scalar_mass(new_space, 7800.0))
        np.testing.assert_array_equal(consistent_mass(new_space, 7800.0, kept).data,
                                      consistent_mass(new_space, 7800.0).data)


def test_lumped_element_masses_survive_a_crack():
    """The same for a lumped mass (explicit dynamics): the old mesh's lumped scalar element
    masses give the cracked mesh's lumped mass to the bit."""
    from fem_frac.fem.mass import element_scalar_lumped, lumped_mass

    density = np.linspace(1000.0, 8000.0, 64 * 6)
    for old, new, _ in _cracked(0.15):
        kept = element_scalar_lumped(build_space(old, 1), density)
        new_space = build_space(new, 1)
        np.testing.assert_array_equal(kept, element_scalar_lumped(new_space, density))
        np.testing.assert_array_equal(lumped_mass(new_space, density, kept),
                                      lumped_mass(new_space, density))


@pytest.mark.parametrize("distortion", [0.0, 0.15])
def test_reconnected_mass_equals_a_fresh_assembly(distortion):
    """The consistent mass updated through the changed tets: the values of a fresh assembly
    to round-off (each entry a sum of a few element terms, summed in another order: a few
    ulps of the largest entry) and its pattern (couplings only changed tets carried, between
    a vertex and its copy, dropped), through two insertions in a row."""
    from fem_frac.fem.mass import consistent_mass, element_scalar_mass
    from fem_frac.fem.reconnect import reconnect_mass

    density = np.linspace(1000.0, 8000.0, 64 * 6)  # per element: the tets' own masses
    steps = _cracked(distortion)
    mass = consistent_mass(build_space(steps[0][0], 1), density)
    diagonal = None  # a fresh assembly's: every entry searched, then the touched rows
    for old, new, transfer in steps:
        changed = changed_tets(old.tets, new.tets, transfer.node_map)
        space = build_space(new, 1)
        me = element_scalar_mass(space, density)
        mass, diagonal = reconnect_mass(mass, me, np.asarray(old.tets), np.asarray(new.tets),
                                        changed, new.n_points, diagonal)
        np.testing.assert_array_equal(diagonal, mass.diagonal())
        fresh = consistent_mass(space, density).tocsr()
        scale = np.abs(fresh.diagonal()).max()
        assert abs(mass - fresh).max() <= 10 * np.finfo(float).eps * scale
        np.testing.assert_array_equal(mass.indptr, fresh.indptr)
        np.testing.assert_array_equal(mass.indices, fresh.indices)


@pytest.mark.parametrize("order", [1, 2])
def test_a_reconnected_space_reuses_the_old_geometry_to_the_bit(order):
    """``build_space(new, like=old)``: the old tets' mapping, and every array of the space
    the same bits as built afresh on the cracked mesh."""
    for old, new, _ in _cracked(0.15):
        old_space = build_space(old, order)
        reused, fresh = build_space(new, order, like=old_space), build_space(new, order)
        assert reused.basis.mapping is old_space.basis.mapping
        assert fresh.basis.mapping is not old_space.basis.mapping
        np.testing.assert_array_equal(reused.basis.dx, fresh.basis.dx)
        np.testing.assert_array_equal(reused.gradients(), fresh.gradients())
        np.testing.assert_array_equal(reused.element_dofs, fresh.element_dofs)
        np.testing.assert_array_equal(reused.node_points, fresh.node_points)


@pytest.mark.parametrize("distortion", [0.0, 0.15])
def test_the_touched_rows_drop_what_a_search_of_every_entry_drops(distortion):
    """Through two insertions, the stiffness and the consistent mass with the diagonal
    carried from one reconnection to the next (only the rows an insertion touches searched
    for cancelled couplings) are the same matrices, to the bit, as with every entry
    searched each time."""
    from fem_frac.fem.mass import consistent_mass, element_scalar_mass
    from fem_frac.fem.reconnect import reconnect_mass

    density = np.linspace(1000.0, 8000.0, 64 * 6)
    steps = _cracked(distortion)
    space = build_space(steps[0][0], 1)
    op0 = strain_operator(space)
    k0, m0 = op0.stiffness(D).tocsr(), consistent_mass(space, density)
    carried = [(op0, k0, None, m0, None)]
    searched = [(op0, k0, None, m0, None)]
    for old, new, transfer in steps:
        changed = changed_tets(old.tets, new.tets, transfer.node_map)
        new_space = build_space(new, 1)
        me = element_scalar_mass(new_space, density)
        for chain, keep in ((carried, True), (searched, False)):
            op, k, dk, m, dm = chain[-1]
            args = (np.asarray(old.tets), np.asarray(new.tets), changed)
            op, k, dk = reconnect(op, k, D, new_space, *args, dk if keep else None)
            m, dm = reconnect_mass(m, me, *args, new.n_points, dm if keep else None)
            chain.append((op, k, dk, m, dm))
    assert carried[-1][2] is not None
    for a, b in zip(carried[1:], searched[1:], strict=True):
        for x, y in ((a[1], b[1]), (a[3], b[3])):
            np.testing.assert_array_equal(x.indptr, y.indptr)
            np.testing.assert_array_equal(x.indices, y.indices)
            np.testing.assert_array_equal(x.data, y.data)
        np.testing.assert_array_equal(a[2], b[2])
        np.testing.assert_array_equal(a[4], b[4])


def test_a_larger_diagonal_searches_every_entry():
    """Where the new largest diagonal entry exceeds the old one, an entry outside the
    touched rows may fall under the threshold: every entry is searched then."""
    from fem_frac.fem.reconnect import DROP, _without_cancelled

    old = sp.csr_matrix(np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 2e-13], [0.0, 2e-13, 1.0]]))
    delta = sp.csr_matrix(np.array([[3.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]))
    assert 2e-13 > DROP * 1.0 and 2e-13 <= DROP * 4.0
    out, diagonal = _without_cancelled((old + delta).tocsr(), delta, old.diagonal())
    assert out.nnz == 3  # the couplings of rows 1 and 2, untouched, dropped
    np.testing.assert_array_equal(diagonal, [4.0, 1.0, 1.0])
