"""Smoothing of element stresses before a fracture criterion, and principal stresses.

P1 tets carry one (piecewise constant) stress per element, noisy from element to element;
a fracture criterion evaluated on it would crack along the mesh's own noise. This module
builds a sparse, row-stochastic ``(m, m)`` operator ``S`` over the ``m`` tets that replaces
each element value by a weighted mean over a neighbourhood of it, and evaluates the largest
principal stress and its direction of the result.

Shapes and units:

- ``points (n, 3)``, ``tets (m, 4)`` int64 (as in :class:`~fem_frac.mesh.Mesh`); ``length``
  in the units of ``points``.
- stresses are Mandel 6-vectors, components first (VTK order XX, YY, ZZ, XY, YZ, XZ, shear
  scaled by sqrt(2), see :mod:`fem_frac.fem.tensors`): ``(6, m)`` element averages, in
  whatever stress unit the caller uses; principal stresses come back in the same unit.
- ``smoothed = stress @ S.T``; for a per-element scalar ``x (m,)``, ``S @ x``.

Two methods:

- ``"neighbours"``: volume-weighted mean over the elements reachable through *face
  adjacency* (:func:`~fem_frac.fracture.topology.face_adjacency`), within a number of
  face-steps (``rings``) or along paths that stay within a distance ``length`` of the
  element's centroid (``length``).
- ``"nodal"``: volume-weighted projection onto the vertices, then back to the elements
  (mean of the four vertex values), applied one or more times.

Why smoothing stops at cracks: a crack is inserted by giving the tets on each side their
own copies of the vertices (:func:`~fem_frac.fracture.topology.open_crack`). Tets on the two
sides of a crack face, and tets of different fragments, then share no face, so face
adjacency never links them; for ``"nodal"`` they share no vertex across an opened face
either. Only around a crack front (where the vertex copies end) can ``"nodal"`` still mix
the two sides, through the vertices on the front, which are genuinely shared.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..fem.tensors import largest_value, principal
from ..mesh.mesh import TET_EDGES, edge_keys, tet_volumes
from .faces import face_adjacency, face_neighbours

METHODS = ("neighbours", "nodal")


def centroids(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Tet centroids ``(m, 3)``."""
    return np.asarray(points, dtype=float)[np.asarray(tets, dtype=np.int64)].mean(axis=1)


def mean_edge_length(points: np.ndarray, tets: np.ndarray) -> float:
    """Mean length of the distinct edges of the mesh (each edge counted once)."""
    points = np.asarray(points, dtype=float)
    pairs = np.asarray(tets, dtype=np.int64)[:, TET_EDGES].reshape(-1, 2)
    keys = np.unique(edge_keys(pairs, points.shape[0]))
    a, b = np.divmod(keys, np.int64(points.shape[0]))
    return float(np.linalg.norm(points[a] - points[b], axis=1).mean())


# ones for the patterns of operators (neighbourhoods): one read-only buffer, grown as
# needed, since a fresh one of a brittle run's size (1.9 million entries) costs more to
# allocate than to use
_ONES = np.ones(0)


def neighbourhoods(operator: sp.csr_matrix) -> sp.csr_matrix:
    """The 0/1 pattern of an ``operator`` (its neighbourhoods), sharing its index arrays;
    read-only."""
    global _ONES
    if _ONES.size < operator.nnz:
        _ONES = np.ones(max(operator.nnz, 2 * _ONES.size))
        _ONES.flags.writeable = False
    return sp.csr_matrix((_ONES[:operator.nnz], operator.indices, operator.indptr),
                         shape=operator.shape)


def _pattern(matrix) -> sp.csr_matrix:
    """The 0/1 float CSR pattern of ``matrix`` (duplicates summed, indices sorted)."""
    out = sp.csr_matrix(matrix, dtype=float, copy=True)
    out.sum_duplicates()
    out.eliminate_zeros()
    out.data[:] = 1.0
    return out


def _volume_weighted(pattern: sp.csr_matrix, volumes: np.ndarray) -> sp.csr_matrix:
    """Rows of ``pattern`` weighted by ``volumes[j]`` and normalized to sum 1."""
    w = sp.csr_matrix(pattern.multiply(volumes[None, :]))
    _divide_rows(w)
    return w


def _divide_rows(w: sp.csr_matrix) -> None:
    """Divide each row of ``w`` by its sum, in place (rows without entries stay empty;
    dividing rather than multiplying by the reciprocal keeps a lone entry exactly 1)."""
    row = np.repeat(np.arange(w.shape[0]), np.diff(w.indptr))
    w.data /= np.bincount(row, weights=w.data, minlength=w.shape[0])[row]


def _face_steps(tets: np.ndarray) -> sp.csr_matrix:
    """Pattern ``(m, m)`` of one step through a shared face, or none (the diagonal)."""
    return _pattern(face_adjacency(tets) + sp.identity(tets.shape[0], format="csr"))


def _length_neighbourhoods(step: sp.csr_matrix, c: np.ndarray, length: float
                           ) -> sp.csr_matrix:
    """Pattern ``(m, m)`` of pairs ``(i, j)`` joined by a path of ``step`` (0/1, holding the
    diagonal) whose every element has its centroid within ``length`` of ``c[i]``.

    A breadth-first search from every tet at once, ring by ring: a ring is the pairs at
    that many steps in the row's graph (the tets within ``length``), and a neighbour of ring
    ``k`` lies in ring ``k - 1``, ``k`` or ``k + 1``, so only the last two rings are looked
    up to find the new pairs, not all held so far. Cost grows with the number of pairs
    (about the number of tets in a ball of radius ``length`` per row).
    """
    m = c.shape[0]
    cx, cy, cz = (np.ascontiguousarray(c[:, i]) for i in range(3))
    own = np.arange(m, dtype=np.int64)
    front = sp.csr_matrix((np.ones(m), own, np.arange(m + 1)), shape=(m, m))
    before = sp.csr_matrix((m, m))
    # an entry of front @ step counts the paths into it, at most a column of step's entries:
    # the last two rings' entries, weighted by more, come out negative
    mark = float(np.diff(step.indptr).max()) + 1.0
    rows, cols = [own], [own]
    while front.nnz:
        cand = front @ step - mark * (front + before)
        r = np.repeat(own, np.diff(cand.indptr))
        new = cand.data > 0.0
        r, t = r[new], cand.indices[new]
        # |c[i] - c[j]| as numpy.linalg.norm sums it, to the bit
        dx, dy, dz = cx[r] - cx[t], cy[r] - cy[t], cz[r] - cz[t]
        near = np.sqrt((dx * dx + dy * dy) + dz * dz) <= length
        r, t = r[near], t[near]
        indptr = np.zeros(m + 1, dtype=np.int64)
        np.cumsum(np.bincount(r, minlength=m), out=indptr[1:])  # r ascends
        before, front = front, sp.csr_matrix((np.ones(r.size), t, indptr), shape=(m, m))
        rows.append(r)
        cols.append(t)
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    reach = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(m, m))
    reach.sort_indices()
    return reach


def _ring_neighbourhoods(step: sp.csr_matrix, rings: int, rows: np.ndarray) -> sp.csr_matrix:
    """Pattern ``(len(rows), m)`` of the tets within ``rings`` steps of each of ``rows``."""
    m = step.shape[0]
    k = rows.size
    reach = sp.csr_matrix((np.ones(k), (np.arange(k), rows)), shape=(k, m))
    for _ in range(int(rings)):
        reach = _pattern(reach @ step)
    return reach


def update_operator(operator: sp.csr_matrix, points: np.ndarray, tets: np.ndarray,
                    split: np.ndarray, *, length: float | None = None,
                    rings: int | None = None, method: str = "neighbours",
                    volumes: np.ndarray | None = None) -> sp.csr_matrix:
    """The operator of a mesh just cracked, from the ``operator`` of the mesh before.

    ``operator``: :func:`smoothing_operator` of the mesh before with the same size;
    ``points``, ``tets``: the new mesh (same tets, element ids unchanged); ``split``: the
    positions ``(k, 3)`` of the vertices split, as the mesh holds them (compared to the
    bit with ``points``, whose copies of them a crack made exactly). Cracks open only
    along faces at those vertices, so for ``neighbours`` only some rows change. With
    ``length``: the rows whose neighbourhood held a tet at a split vertex, each now the
    part of its old neighbourhood still connected to its tet (:func:`_reachable_within`).
    With ``rings``: the elements within ``rings + 1`` face-steps of a tet at a split
    vertex, rebuilt. The other rows are kept; the result equals :func:`smoothing_operator`
    on the new mesh, to the bit. ``nodal`` is rebuilt whole. ``volumes``: the tets' signed
    volumes where known (a crack leaves them as they were).
    """
    if method != "neighbours":
        return smoothing_operator(points, tets, length=length, rings=rings, method=method)
    points = np.asarray(points, dtype=float)
    tets = np.asarray(tets, dtype=np.int64)
    m = tets.shape[0]
    split = np.asarray(split, dtype=float).reshape(-1, 3)
    at = _at_split(points, tets, split)
    volumes = np.abs(tet_volumes(points, tets) if volumes is None else volumes)
    if length is not None:
        # a neighbourhood changes only where it held a tet at a split vertex (both tets of
        # an opened face hold one), and only loses tets: the new one of such a row is the
        # part of its old one still reachable from the row's tet; the rows that lost none
        # are kept as they are
        rows = np.flatnonzero(smooth(operator, (at >= 0).any(axis=1)[None].astype(float)))
        fresh = _reachable_within(operator, face_neighbours(tets), rows)
        lost = np.diff(fresh.indptr) < np.diff(operator.indptr)[rows]
        rows, fresh = rows[lost], fresh[lost]
    else:
        step = _face_steps(tets)
        c = centroids(points, tets)
        near = np.zeros(m)
        near[_within(c, split, _split_diameters(points, tets, at, split.shape[0]))] = 1.0
        for _ in range(int(rings) + 1):
            near = step @ near
        rows = np.flatnonzero(near)
        fresh = _ring_neighbourhoods(step, int(rings), rows)
    return _replace_rows(operator, rows, _volume_weighted(fresh, volumes))


def _at_split(points: np.ndarray, tets: np.ndarray, split: np.ndarray) -> np.ndarray:
    """``(m, 4)``: the split position ``(k, 3)`` each tet corner is at (the vertex split or
    a copy of it, whose coordinates a crack copies to the bit), -1 for the others. Two
    split positions can coincide (a vertex and its copy, both split): their corners name
    one of them. Positions are compared as the bytes of their three coordinates, sorted
    once (no spatial tree: it is exact, and spares a fracture run scipy.spatial's import,
    0.13 s under ``python -X importtime``)."""
    row = np.dtype((np.void, 3 * np.dtype(np.float64).itemsize))
    keys = np.ascontiguousarray(points, dtype=np.float64).view(row).ravel()
    wanted = np.ascontiguousarray(split, dtype=np.float64).reshape(-1, 3).view(row).ravel()
    if wanted.size == 0:
        return np.full(tets.shape, -1, dtype=np.int64)
    order = np.argsort(wanted, kind="stable")
    ranked = wanted[order]
    pos = np.minimum(np.searchsorted(ranked, keys), ranked.size - 1)
    at = np.where(ranked[pos] == keys, order[pos], -1).astype(np.int64)
    return at[tets]


def _split_diameters(points: np.ndarray, tets: np.ndarray, at: np.ndarray, k: int
                     ) -> np.ndarray:
    """For each of the ``k`` split positions, the largest diameter of the tets with a corner
    there (``at``: :func:`_at_split`; 0 for a position that shares its corners with another).
    A face opened at a split vertex lies between such tets, whose centroids are within their
    diameter of it: this bounds how far from the position a neighbourhood can meet the new
    faces."""
    t, corner = np.nonzero(at >= 0)
    x = points[tets[t]]
    d = np.max(np.linalg.norm(x[:, TET_EDGES[:, 0]] - x[:, TET_EDGES[:, 1]], axis=2), axis=1)
    out = np.zeros(k)
    np.maximum.at(out, at[t, corner], d)
    return out


def _reachable_within(old: sp.csr_matrix, neighbours: np.ndarray, rows: np.ndarray
                      ) -> sp.csr_matrix:
    """Pattern ``(len(rows), m)``: for each of ``rows``, the tets of its row of ``old`` (a
    neighbourhood) that face-sharing paths (``neighbours (m, w)``: the tets across each
    tet's faces, itself where none: :func:`~fem_frac.fracture.topology.face_neighbours`)
    still connect to the row's own tet within that row. One connected-components pass over
    the graph of (row, tet) pairs, instead of growing the neighbourhoods ring by ring: each
    pair's edges go to the pairs of the same row at its tet's face neighbours (a pair whose
    neighbour is not in the row points to itself), found in a table of the pairs by row
    and tet (:func:`_pair_table`)."""
    m = old.shape[1]
    sub = old[rows]
    sub.sort_indices()
    n = sub.indices.size
    owner = np.repeat(np.arange(rows.size, dtype=np.int64), np.diff(sub.indptr))
    width = neighbours.shape[1]
    found = _pair_table(owner, sub.indices, m, neighbours[sub.indices])
    itself = np.repeat(np.arange(n, dtype=np.int64), width)
    target = np.where(found >= 0, found, itself.reshape(n, width)).ravel()
    graph = sp.csr_matrix((np.ones(target.size), target,  # float64: scipy copies any other
                           np.arange(0, target.size + 1, width, dtype=np.int64)),
                          shape=(n, n))
    # the graph is symmetric (a pair's neighbour in its row has it as a neighbour), so its
    # strong components are its connected ones, found without a transpose
    _, label = connected_components(graph, directed=True, connection="strong")
    # each row's own pair: the pairs' keys (row, tet) ascend, the indices being sorted
    keys = owner * m + sub.indices
    home = np.searchsorted(keys, np.arange(rows.size, dtype=np.int64) * m + rows)
    kept = label == label[home][owner]
    indptr = np.zeros(rows.size + 1, dtype=np.int64)
    np.cumsum(np.bincount(owner[kept], minlength=rows.size), out=indptr[1:])
    return sp.csr_matrix((np.ones(np.count_nonzero(kept)), sub.indices[kept], indptr),
                         shape=(rows.size, m))


# entries of one block of the dense (row, tet) table of _pair_table: 4 bytes each
PAIR_BLOCK = 2**22


def _pair_table(owner: np.ndarray, tet: np.ndarray, m: int, wanted: np.ndarray
                ) -> np.ndarray:
    """The pairs ``(owner[k], tet[k])`` (``k < n``, distinct, ``owner`` ascending) of rows
    over ``m`` tets, looked up: for each ``(owner[i], wanted[i, j])`` the number ``k`` of
    that pair, -1 where it is none. In a dense table over the rows and the tets the pairs
    hold, a block of rows at a time (at most about :data:`PAIR_BLOCK` entries), where a
    search would be a binary search per look-up."""
    held = np.zeros(m, dtype=bool)
    held[tet] = True
    local = np.full(m + 1, -1, dtype=np.int64)  # -1 (the last entry) for tets no pair has
    columns = np.flatnonzero(held)
    local[columns] = np.arange(columns.size)
    column = local[wanted]
    out = np.zeros(wanted.shape, dtype=np.int64)
    rows = int(owner[-1]) + 1 if owner.size else 0
    per_block = max(PAIR_BLOCK // max(columns.size, 1), 1)
    first = np.searchsorted(owner, np.arange(0, rows + per_block, per_block))
    for b in range(first.size - 1):
        lo = b * per_block
        # numbered from 1 in a zeroed block (calloc'd, no pass to fill it)
        block = np.zeros((min(per_block, rows - lo), columns.size + 1),
                         dtype=np.int32 if owner.size < 2**31 - 1 else np.int64)
        pairs = slice(first[b], first[b + 1])
        block[owner[pairs] - lo, local[tet[pairs]]] = np.arange(first[b] + 1, first[b + 1] + 1)
        out[pairs] = block[(owner[pairs] - lo)[:, None], column[pairs]]
    out -= 1
    return out


def _within(c: np.ndarray, split: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Sorted ids of the centroids ``c`` within ``radius[j]`` of some ``split[j]``."""
    from scipy.spatial import cKDTree

    hit = cKDTree(c).query_ball_point(split, radius)
    return np.unique(np.concatenate([np.asarray(h, dtype=np.int64) for h in hit]
                                    + [np.zeros(0, np.int64)]))


def _replace_rows(operator: sp.csr_matrix, rows: np.ndarray, fresh: sp.csr_matrix
                  ) -> sp.csr_matrix:
    """``operator`` with its rows ``rows`` (sorted, unique) replaced by the rows of ``fresh``
    (``(len(rows), m)``), sorted indices kept; ``operator`` itself where no row is
    replaced. One copy of each array: the stretches of the old arrays between the
    replaced rows and the fresh rows, joined in order."""
    if rows.size == 0:
        return operator
    fresh = sp.csr_matrix(fresh)
    fresh.sort_indices()
    operator.sort_indices()
    old_ptr, new_ptr = operator.indptr, fresh.indptr
    length = np.diff(old_ptr)
    length[rows] = np.diff(new_ptr)
    total = int(length.sum())
    indptr = np.zeros(operator.shape[0] + 1,
                      dtype=old_ptr.dtype if total <= np.iinfo(old_ptr.dtype).max else np.int64)
    np.cumsum(length, out=indptr[1:])
    # the kept stretches of the old arrays, with the fresh rows between them
    kept = list(zip(np.r_[0, old_ptr[rows + 1]].tolist(),
                    np.r_[old_ptr[rows], old_ptr[-1]].tolist(), strict=True))
    replaced = list(zip(new_ptr[:-1].tolist(), new_ptr[1:].tolist(), strict=True))

    def joined(old: np.ndarray, new: np.ndarray) -> np.ndarray:
        parts = [None] * (len(kept) + len(replaced))
        parts[0::2] = [old[a:b] for a, b in kept]
        parts[1::2] = [new[a:b] for a, b in replaced]
        return np.concatenate(parts)

    out = sp.csr_matrix((joined(operator.data, fresh.data),
                         joined(operator.indices, fresh.indices), indptr),
                        shape=operator.shape)
    out.has_sorted_indices = True
    return out


def _vertex_projection(points, tets, volumes) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """``(A (n, m), B (m, n))``: A = volume-weighted mean over the tets holding a vertex
    (zero rows for vertices no tet uses), B = mean of a tet's four vertices."""
    n, m = np.asarray(points).shape[0], tets.shape[0]
    elem = np.repeat(np.arange(m, dtype=np.int64), 4)
    vert = tets.reshape(-1)
    a = sp.csr_matrix((volumes[elem], (vert, elem)), shape=(n, m))
    _divide_rows(a)
    b = sp.csr_matrix((np.full(4 * m, 0.25), (elem, vert)), shape=(m, n))
    return a, b


def smoothing_operator(
    points: np.ndarray,
    tets: np.ndarray,
    *,
    length: float | None = None,
    rings: int | None = None,
    method: str = "neighbours",
) -> sp.csr_matrix:
    """The ``(m, m)`` row-stochastic CSR smoothing operator ``S`` (``smoothed = x @ S.T``).

    Exactly one of ``length`` (> 0, units of ``points``) and ``rings`` (integer >= 0).

    ``method="neighbours"``: ``S[i, j] = V_j / sum_k V_k`` over the neighbourhood of ``i``
    (``V``: tet volumes): with ``rings=r`` the tets within ``r`` face-steps of ``i``; with
    ``length`` the tets reachable from ``i`` through face-sharing paths whose every tet has
    its centroid within ``length`` of the centroid of ``i``. ``i`` itself always belongs.

    ``method="nodal"``: ``S = (B A)^r``, A the volume-weighted mean over the tets holding a
    vertex, B the mean over a tet's four vertices. ``rings=r`` gives ``r`` applications
    (``r = 0`` the identity); ``length`` gives the smallest ``r >= 1`` with
    ``r * mean_edge_length(points, tets) >= length`` (one application spreads a value over
    roughly one edge length).
    """
    if (length is None) == (rings is None):
        raise ValueError("give exactly one of length and rings")
    if length is not None and not length > 0:
        raise ValueError(f"length must be > 0, got {length!r}")
    if rings is not None and (isinstance(rings, bool) or int(rings) != rings or rings < 0):
        raise ValueError(f"rings must be an integer >= 0, got {rings!r}")
    if method not in METHODS:
        raise ValueError(f"unknown smoothing method {method!r}; expected one of {METHODS}")
    points = np.asarray(points, dtype=float)
    tets = np.asarray(tets, dtype=np.int64)
    m = tets.shape[0]
    volumes = np.abs(tet_volumes(points, tets))

    if method == "neighbours":
        step = _face_steps(tets)
        if rings is not None:
            reach = _ring_neighbourhoods(step, int(rings), np.arange(m))
        else:
            reach = _length_neighbourhoods(step, centroids(points, tets), float(length))
        return _volume_weighted(reach, volumes)

    if rings is not None:
        r = int(rings)
    else:
        r = max(1, int(np.ceil(float(length) / mean_edge_length(points, tets))))
    a, b = _vertex_projection(points, tets, volumes)
    once = sp.csr_matrix(b @ a)
    out = sp.identity(m, dtype=float, format="csr")
    for _ in range(r):
        out = sp.csr_matrix(out @ once)
    out.sort_indices()
    return out


def smooth(operator, element_stress: np.ndarray) -> np.ndarray:
    """Apply ``operator (m, m)`` to element values ``(k, m)`` (e.g. ``(6, m)`` stresses):
    ``element_stress @ operator.T``, same shape. A large CSR operator's rows go over the
    cores (:mod:`fem_frac.threads`; each row's sum the same bits)."""
    from ..threads import map_ranges

    x = np.asarray(element_stress, dtype=float).T
    if not (sp.issparse(operator) and operator.format == "csr"):
        return np.asarray((operator @ x).T)
    parts = map_ranges(lambda a, b: _rows(operator, a, b) @ x, operator.shape[0])
    return np.asarray((parts[0] if len(parts) == 1 else np.vstack(parts)).T)


def _rows(a: sp.csr_matrix, start: int, stop: int) -> sp.csr_matrix:
    """Rows ``start:stop`` of ``a``, its data and indices shared (no copy: given to the
    constructor, views of less than half of ``a``'s arrays would be copied)."""
    if start == 0 and stop == a.shape[0]:
        return a
    lo, hi = a.indptr[start], a.indptr[stop]
    block = sp.csr_matrix((stop - start, a.shape[1]), dtype=a.dtype)
    block.indptr = a.indptr[start:stop + 1] - lo
    block.indices, block.data = a.indices[lo:hi], a.data[lo:hi]
    return block


def principal_stress(element_stress: np.ndarray, exact_above: float | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Largest principal stress and its unit direction of Mandel stresses ``(6, m)``.

    Returns ``(sigma1 (m,), direction (m, 3))`` from :func:`~fem_frac.fem.tensors.principal`
    (batched :func:`numpy.linalg.eigh`). Each direction is oriented so that its
    largest-magnitude component is positive (the first such one on a tie), so the result is
    reproducible; where the largest eigenvalue is repeated the direction is one unit vector
    of its eigenspace, whichever LAPACK returns.

    ``exact_above``: the values are first found in closed form
    (:func:`~fem_frac.fem.tensors.largest_value`), and only the tensors whose value may
    exceed ``exact_above`` (a crack criterion's strength; a margin of :data:`EXACT_MARGIN`
    of the tensor's size covers the closed form's error) go through ``eigh``: those
    values and directions are the same bits as without it, the other values within
    round-off, and the other directions, which a crack criterion never reads, NaN (where
    most tensors may exceed the level, ``eigh`` runs throughout and gives them all).
    """
    stress = np.asarray(element_stress, dtype=float)
    if exact_above is not None and _mostly_below(stress, exact_above):
        value = largest_value(stress)
        size = np.abs(np.sum(stress[:3], axis=0)) + np.sqrt(np.sum(stress * stress, axis=0))
        near = value >= exact_above - EXACT_MARGIN * size
        if np.all(np.isfinite(value)) and np.count_nonzero(near) <= 0.5 * value.size:
            vector = np.full(value.shape + (3,), np.nan)
            if near.any():
                value[near], vector[near] = _oriented_eigh(stress[:, near])
            return value, vector
    return _oriented_eigh(stress)


# the closed form's error is a few ulps of a tensor's size where its largest value stands
# apart, and up to ~sqrt(eps) of it (1.6e-8 measured) where the top two nearly coincide
# (fem_frac.fem.tensors.largest_principal): far inside this margin
EXACT_MARGIN = 1e-6


def _mostly_below(stress: np.ndarray, level: float) -> bool:
    """Whether most tensors ``(6, m)`` have their largest value below ``level`` by the bound
    ``sigma1 <= p + sqrt(2/3) |dev|`` (p the mean stress): where most may exceed it, eigh
    is needed for most anyway and the closed form would be spent in vain."""
    p = np.sum(stress[:3], axis=0) / 3.0
    dev2 = np.sum((stress[:3] - p) ** 2, axis=0) + np.sum(stress[3:] ** 2, axis=0)
    return np.count_nonzero(p + np.sqrt(2.0 / 3.0 * dev2) >= level) <= 0.5 * p.size


def _oriented_eigh(stress: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    values, vectors = principal(stress)
    return values[..., -1], _oriented(vectors[..., :, -1])


def _oriented(d: np.ndarray) -> np.ndarray:
    """Unit vectors ``(..., 3)`` turned so that the largest-magnitude component is positive."""
    k = np.argmax(np.abs(d), axis=-1)[..., None]
    sign = np.where(np.take_along_axis(d, k, axis=-1) < 0.0, -1.0, 1.0)
    return d * sign
