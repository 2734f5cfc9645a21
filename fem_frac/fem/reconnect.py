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
values equal a fresh assembly's to round-off (``tests/test_reconnect.py``). A matrix this
module made keeps no entry within ``DROP`` of its own largest diagonal entry, and an
insertion only lowers the diagonal (a vertex's tets are shared with its copies), so the
next insertion looks for such entries only in the rows it changes
(:func:`_without_cancelled`).
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
              old_tets: np.ndarray, new_tets: np.ndarray, changed: np.ndarray,
              diagonal: np.ndarray | None = None
              ) -> tuple[StrainOperator, sp.csr_matrix, np.ndarray]:
    """The strain operator on ``space`` (the new mesh's), its stiffness for the elastic
    ``tangent`` (Mandel ``(6, 6)`` or ``(6, 6, n_tets, 1)``) and that stiffness's diagonal,
    from ``op`` and ``stiffness`` of the old mesh (module docstring). ``diagonal``: the one
    this function returned with ``stiffness``, ``None`` for a stiffness assembled afresh."""
    n = space.n_dofs
    m = old_tets.shape[0]
    base = reconnected_matrix(op.matrix, old_tets, new_tets, changed, n)
    weights = np.ascontiguousarray(space.basis.dx, dtype=float)
    rows = _rows(changed, m)
    d = tangent if tangent.ndim == 2 else tangent[:, :, changed]
    w = _weighted_tangent(d, weights[changed])
    before, after = op.matrix[rows], base[rows]
    delta = (after.T @ (w @ after) - _padded((before.T @ (w @ before)).tocsr(), n)).tocsr()
    k, diagonal = _without_cancelled((_padded(stiffness.tocsr(), n) + delta).tocsr(), delta,
                                     diagonal)
    return StrainOperator(space, base, weights, "standard", _base=base), k, diagonal


def reconnect_mass(mass: sp.csr_matrix, element_mass: np.ndarray, old_tets: np.ndarray,
                   new_tets: np.ndarray, changed: np.ndarray, n_nodes: int,
                   diagonal: np.ndarray | None = None) -> tuple[sp.csr_matrix, np.ndarray]:
    """The consistent mass (vector, ``3 n_nodes`` square) of a P1 mesh a crack reconnected
    and its diagonal, from ``mass``, the old mesh's: the ``changed`` tets' scalar element
    masses ``element_mass`` (``(n_tets, 4, 4)``, unchanged by the crack) leave their old
    vertices for their new ones, ``M_new = M_old - sum_changed M_e (old) + sum_changed M_e
    (new)``, as :func:`reconnect` does for the stiffness (couplings that cancel dropped below
    ``DROP`` of the largest diagonal entry; ``diagonal`` as there). Equal to a fresh
    :func:`~fem_frac.fem.mass.consistent_mass` to round-off (``tests/test_reconnect.py``)."""
    from .mass import _times_identity3, element_pairs

    me = element_mass[changed]
    (r1, c1), (r0, c0) = element_pairs(new_tets[changed]), element_pairs(old_tets[changed])
    values = np.concatenate([me.ravel(), -me.ravel()])
    delta = sp.csr_matrix((values, (np.concatenate([r1, r0]), np.concatenate([c1, c0]))),
                          shape=(n_nodes, n_nodes))
    delta = _times_identity3(delta).tocsr()
    return _without_cancelled((_padded(mass.tocsr(), 3 * n_nodes) + delta).tocsr(), delta,
                              diagonal)


def _without_cancelled(a: sp.csr_matrix, delta: sp.csr_matrix, diagonal: np.ndarray | None
                       ) -> tuple[sp.csr_matrix, np.ndarray]:
    """``a`` (``old + delta``, as the sum made it) without its entries of at most ``DROP``
    times its largest diagonal entry, sorted, and its diagonal.

    ``diagonal``: ``old``'s, where ``old`` came from here, else ``None``. Then every entry of
    ``old`` exceeds ``DROP`` times its own largest diagonal entry, and the entries outside
    the rows ``delta`` touches are ``old``'s: where ``a``'s largest diagonal entry is no
    larger (an insertion shares a vertex's tets with its copies, so it only lowers the
    diagonal), none of those is dropped, and only the touched rows are searched, with the
    diagonal read there. The same entries are dropped as by a search of every entry: the
    same matrix, to the bit (``tests/test_reconnect.py``)."""
    n = a.shape[0]
    rows = np.flatnonzero(np.diff(delta.indptr))
    start = a.indptr[rows].astype(np.int64)
    count = a.indptr[rows + 1] - start
    entries = np.repeat(start - np.cumsum(count) + count, count) + np.arange(count.sum())
    owner = np.repeat(rows, count)
    if diagonal is not None:
        new = np.zeros(n)
        new[:diagonal.size] = diagonal
        new[rows] = 0.0
        on = a.indices[entries] == owner
        new[owner[on]] = a.data[entries[on]]
        scale = float(np.abs(new).max()) if n else 0.0
        before = float(np.abs(diagonal).max()) if diagonal.size else 0.0
    if diagonal is None or not 0.0 < scale <= before:  # every entry searched
        new = a.diagonal()
        scale = float(np.abs(new).max()) if n else 0.0
        a.data[np.abs(a.data) <= DROP * scale] = 0.0
        a.eliminate_zeros()
    else:
        small = entries[np.abs(a.data[entries]) <= DROP * scale]
        if small.size:
            a.data[small] = 0.0
            a.eliminate_zeros()
    new[np.abs(new) <= DROP * scale] = 0.0  # as the entries themselves
    a.sort_indices()
    return a, new
