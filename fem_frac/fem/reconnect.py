"""The strain operator and stiffness of a mesh a crack has just reconnected, from the old ones.

A crack insertion (:func:`~fem_frac.fracture.topology.open_crack`) keeps every tet, its
geometry and its local vertex order, keeps the old vertex ids and appends the copies; only
the tets around the split vertices change vertices. So for linear tets in the standard
formulation the rows of B of the other tets are unchanged, the rows of the changed tets hold
the same values in new columns, and

    K_new = K_old - sum_changed B_e^T D B_e dx (old columns) + sum_changed (new columns),

which costs a pass over K's nonzeros instead of the triple product over the whole mesh.
Couplings that only changed tets carried cancel to round-off; they are dropped (below
``DROP`` of the largest diagonal entry), so the pattern is that of a fresh assembly. The
values equal a fresh assembly's to round-off (``tests/test_reconnect.py``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .operators import StrainOperator, _weighted_tangent

DROP = 1e-13


def changed_tets(old_tets: np.ndarray, new_tets: np.ndarray,
                 node_map: np.ndarray) -> np.ndarray | None:
    """The tets whose vertices changed, or ``None`` when ``new_tets`` is not ``old_tets``
    reconnected (a different tet count or order, old ids not kept)."""
    old_tets, new_tets = np.asarray(old_tets), np.asarray(new_tets)
    n_old = int(old_tets.max()) + 1 if old_tets.size else 0
    if (old_tets.shape != new_tets.shape or node_map.size < n_old
            or not np.array_equal(node_map[:n_old], np.arange(n_old))
            or not np.array_equal(node_map[new_tets], old_tets)):
        return None
    return np.flatnonzero(np.any(new_tets != old_tets, axis=1))


def _rows(changed: np.ndarray, m: int) -> np.ndarray:
    """B's rows of the ``changed`` tets, component-major (one quadrature point a tet)."""
    return (np.arange(6)[:, None] * m + changed[None, :]).ravel()


def reconnected_matrix(base: sp.csr_matrix, old_tets: np.ndarray, new_tets: np.ndarray,
                       changed: np.ndarray, n_dofs: int) -> sp.csr_matrix:
    """B of the new mesh from ``base``, the old one (P1, standard): the changed tets' rows
    get their new columns (3 vertex + component), sorted within the row with their values."""
    m = old_tets.shape[0]
    indices, data = base.indices.copy(), base.data.copy()
    for c in range(6):  # each component's rows have one length: not a loop over the mesh
        rows = c * m + changed
        start, length = base.indptr[rows], base.indptr[rows + 1] - base.indptr[rows]
        if rows.size == 0:
            continue
        at = start[:, None] + np.arange(int(length[0]))  # (k, L)
        cols = base.indices[at].astype(np.int64)
        vertex, comp = cols // 3, cols % 3
        local = np.argmax(old_tets[changed][:, None, :] == vertex[:, :, None], axis=2)
        new_cols = 3 * np.take_along_axis(new_tets[changed], local, axis=1) + comp
        order = np.argsort(new_cols, axis=1, kind="stable")
        indices[at] = np.take_along_axis(new_cols, order, axis=1)
        data[at] = np.take_along_axis(base.data[at], order, axis=1)
    out = sp.csr_matrix((data, indices, base.indptr.copy()), shape=(base.shape[0], n_dofs))
    out.has_sorted_indices = True
    return out


def _padded(a: sp.csr_matrix, n: int) -> sp.csr_matrix:
    indptr = np.concatenate([a.indptr, np.full(n - a.shape[0], a.indptr[-1],
                                               dtype=a.indptr.dtype)])
    return sp.csr_matrix((a.data, a.indices, indptr), shape=(n, n))


def reconnect(op: StrainOperator, stiffness: sp.csr_matrix, tangent: np.ndarray, space,
              old_tets: np.ndarray, new_tets: np.ndarray,
              changed: np.ndarray) -> tuple[StrainOperator, sp.csr_matrix]:
    """The strain operator on ``space`` (the new mesh's) and its stiffness for the elastic
    ``tangent`` (Mandel ``(6, 6)`` or ``(6, 6, n_tets, 1)``), from ``op`` and ``stiffness``
    of the old mesh (module docstring)."""
    n = space.n_dofs
    m = old_tets.shape[0]
    base = reconnected_matrix(op.matrix, old_tets, new_tets, changed, n)
    weights = np.ascontiguousarray(space.basis.dx, dtype=float)
    rows = _rows(changed, m)
    d = tangent if tangent.ndim == 2 else tangent[:, :, changed]
    w = _weighted_tangent(d, weights[changed])
    before, after = op.matrix[rows], base[rows]
    delta = after.T @ (w @ after) - _padded((before.T @ (w @ before)).tocsr(), n)
    k = (_padded(stiffness.tocsr(), n) + delta).tocsr()
    scale = float(np.abs(k.diagonal()).max()) if n else 0.0
    k.data[np.abs(k.data) <= DROP * scale] = 0.0
    k.eliminate_zeros()
    k.sort_indices()
    return StrainOperator(space, base, weights, "standard", _base=base), k


def reconnect_mass(mass: sp.csr_matrix, element_mass: np.ndarray, old_tets: np.ndarray,
                   new_tets: np.ndarray, changed: np.ndarray, n_nodes: int) -> sp.csr_matrix:
    """The consistent mass (vector, ``3 n_nodes`` square) of a P1 mesh a crack reconnected,
    from ``mass``, the old mesh's: the ``changed`` tets' scalar element masses
    ``element_mass`` (``(n_tets, 4, 4)``, unchanged by the crack) leave their old vertices
    for their new ones, ``M_new = M_old - sum_changed M_e (old) + sum_changed M_e (new)``,
    as :func:`reconnect` does for the stiffness (couplings that cancel dropped below
    ``DROP`` of the largest diagonal entry). Equal to a fresh
    :func:`~fem_frac.fem.mass.consistent_mass` to round-off (``tests/test_reconnect.py``)."""
    from .mass import _times_identity3, element_pairs

    me = element_mass[changed]
    (r1, c1), (r0, c0) = element_pairs(new_tets[changed]), element_pairs(old_tets[changed])
    values = np.concatenate([me.ravel(), -me.ravel()])
    delta = sp.csr_matrix((values, (np.concatenate([r1, r0]), np.concatenate([c1, c0]))),
                          shape=(n_nodes, n_nodes))
    out = (_padded(mass.tocsr(), 3 * n_nodes) + _times_identity3(delta)).tocsr()
    scale = float(np.abs(out.diagonal()).max()) if n_nodes else 0.0
    out.data[np.abs(out.data) <= DROP * scale] = 0.0
    out.eliminate_zeros()
    out.sort_indices()
    return out
