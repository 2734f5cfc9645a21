"""Topology core of crack insertion by face separation (DESIGN.md §2 "Fracture", §3).

Elements are never cut: a crack opens along existing faces by giving tets their own copies
of shared vertices. A mesh is never edited in place; every operation returns a new
:class:`~fem_frac.mesh.Mesh` and a :class:`Transfer` that maps the old state onto it.

- :func:`fragments`: connected components over face adjacency (never over shared nodes);
  the matched faces and the adjacency of a table are :mod:`fem_frac.fracture.faces`'.
- :func:`split_vertex`: separate the tets around one vertex along a plane through it.
- :func:`separate_nonmanifold`: give every face-connected fan of tets around a vertex its
  own copy of the vertex (pieces joined only at a vertex or along an edge come apart).
- :func:`open_crack`: a batch of plane splits followed by one non-manifold separation
  (:func:`cut_tets`, the new tet table, then :func:`rebuilt`, the mesh around it).

New vertices are appended after the old ones (old ids keep their meaning), each a copy of
an old vertex at the same reference position. Faces that were interior and became exterior
are collected in the boundary group ``crack`` (appended to an existing ``crack`` group).

Vectorized over tets and faces; only :func:`open_crack` loops, over the few split vertices.
Deterministic: the same input gives identical arrays (stable sorts, no hash ordering).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..mesh.crack import CRACK
from ..mesh.mesh import (
    TET_EDGES,
    TET_FACES,
    Mesh,
    SortedKeys,
    edge_keys,
    facet_keys,
    match,
)
from .faces import (
    _face_pairs,
    _held,
    _kept_pairs,
    _new_key,
    _remember_key,
    _seed_pairs,
    face_adjacency,
    recalled,
    remember,
)


@dataclass(frozen=True)
class Transfer:
    """How the state of an old mesh maps onto a new one after a topology change.

    Attributes
    ----------
    node_map: ``(n_new,)`` int64, for each new vertex the old vertex it copies (the identity
        on the first ``n_old`` entries: old vertices keep their ids).
    element_map: ``(n_tets,)`` int64, for each new tet the old tet it is (the identity here:
        elements are never cut, so element state such as plastic strain stays put).
    """

    node_map: np.ndarray
    element_map: np.ndarray

    @property
    def n_new_points(self) -> int:
        return self.node_map.shape[0]

    def transfer_nodal(self, values: np.ndarray) -> np.ndarray:
        """Nodal values ``(n_old, ...)`` -> ``(n_new, ...)``: a copy takes its original's value."""
        return np.asarray(values)[self.node_map]

    def transfer_dofs(self, vector: np.ndarray) -> np.ndarray:
        """P1 vector dofs ``(3 n_old, ...)`` (``3 node + component``) -> ``(3 n_new, ...)``."""
        v = np.asarray(vector)
        v = v.reshape((-1, 3) + v.shape[1:])
        return self.transfer_nodal(v).reshape((-1,) + v.shape[2:])

    def transfer_elemental(self, values: np.ndarray, axis: int = 0) -> np.ndarray:
        """Element values with tets along ``axis`` (e.g. ``-2`` for ``(3, 3, nel, nqp)``)."""
        return np.take(np.asarray(values), self.element_map, axis=axis)

    def then(self, later: Transfer) -> Transfer:
        """The composition: first ``self``, then ``later`` (old -> intermediate -> new)."""
        return Transfer(self.node_map[later.node_map], self.element_map[later.element_map])


def identity_transfer(n_points: int, n_tets: int) -> Transfer:
    return Transfer(np.arange(n_points, dtype=np.int64), np.arange(n_tets, dtype=np.int64))


# The face rows (4 tet + local face) of each boundary group of a mesh rebuilt() made: a
# tet keeps its row through every later insertion, so the next rebuild finds the groups
# there instead of in a sort of every face. Dropped with the mesh.
_BOUNDARY_ROWS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
# The tet tables cut_tets separated (every vertex one face-connected fan), by identity: a
# later cut of such a table separates only around what it changed (a mesh's table is never
# edited in place). Dropped with the table.
_SEPARATED: dict[int, tuple] = {}


def fragments(tets: np.ndarray, links: np.ndarray | None = None) -> tuple[int, np.ndarray]:
    """Connected components over face adjacency: ``(n_fragments, labels (m,))``.

    Two tets touching only at a vertex or along an edge are in different fragments;
    ``links (j, 2)``: further tet pairs held together (across cohesive crack faces that
    still carry traction).
    """
    adjacency = face_adjacency(tets)
    if links is not None and len(links):
        m = adjacency.shape[0]
        extra = sp.coo_matrix((np.ones(len(links), dtype=np.int8),
                               (links[:, 0], links[:, 1])), shape=(m, m))
        adjacency = adjacency + extra + extra.T
    n, labels = connected_components(adjacency, directed=False)
    return int(n), labels.astype(np.int64)


# --------------------------------------------------------------------------- splitting


def _separate_tets(tets: np.ndarray, n_points: int, candidates: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Core of :func:`separate_nonmanifold` on the tet table: ``(new_tets, node_map)``.

    Graph over the ``4 m`` corner incidences (tet, local corner): two incidences of the same
    vertex are joined when their tets share a face containing it. Each component is one
    face-connected fan of tets around a vertex. The fan holding the lowest incidence keeps
    the vertex id; the others get copies appended in order of (vertex, lowest incidence).
    ``candidates``: the only vertices whose fans may be split (every other vertex known to
    have one fan): the graph is then made over their incidences alone, with the same result.
    """
    tets = np.asarray(tets, dtype=np.int64)
    m = tets.shape[0]
    flat = tets.reshape(-1)
    r1, r2, l1, l2 = _face_pairs(tets)
    i1 = ((r1 // 4)[:, None] * 4 + l1).ravel()
    i2 = ((r2 // 4)[:, None] * 4 + l2).ravel()
    if candidates is None:
        incidence = np.arange(4 * m, dtype=np.int64)
    else:
        wanted = np.zeros(n_points, dtype=bool)
        wanted[candidates] = True
        incidence = np.flatnonzero(wanted[flat])
        joined = wanted[flat[i1]]  # both ends hold the same vertex
        local = np.full(4 * m, -1, dtype=np.int64)
        local[incidence] = np.arange(incidence.size)
        i1, i2 = local[i1[joined]], local[i2[joined]]
    k = incidence.size
    graph = sp.coo_matrix((np.ones(i1.size, dtype=np.int8), (i1, i2)), shape=(k, k))
    n_comp, comp = connected_components(graph, directed=False)
    first = np.full(n_comp, 4 * m, dtype=np.int64)
    np.minimum.at(first, comp, incidence)
    vert = flat[first]  # the vertex of each fan
    order = np.lexsort((first, vert))
    primary = np.ones(n_comp, dtype=bool)
    primary[order[1:]] = vert[order[1:]] != vert[order[:-1]]
    new_id = vert.copy()
    extra = order[~primary[order]]
    new_id[extra] = n_points + np.arange(extra.size, dtype=np.int64)
    node_map = np.concatenate([np.arange(n_points, dtype=np.int64), vert[extra]])
    out = flat.copy()
    out[incidence] = new_id[comp]
    return out.reshape(m, 4), node_map


def _split_plane(tets, points, vertex, normal, incidences) -> bool:
    """Give the tets around ``vertex`` whose centroid lies on the negative side of the plane
    through it (normal ``normal``) the id ``len(points)``, in place; True if it split.

    ``incidences``: flat indices into ``tets`` that held ``vertex`` originally (a split only
    ever replaces ids, so the current holders are among them).
    """
    flat = tets.reshape(-1)
    inc = incidences[flat[incidences] == vertex]
    if inc.size == 0:
        return False
    rows = inc // 4
    centroids = points[tets[rows]].mean(axis=1)
    minus = (centroids - points[vertex]) @ normal < 0.0
    if not minus.any() or minus.all():
        return False
    flat[inc[minus]] = len(points)
    return True


def rebuilt(old: Mesh, tets: np.ndarray, node_map: np.ndarray) -> tuple[Mesh, Transfer]:
    """The new mesh on ``tets`` (ids into ``old.points[node_map]``; :func:`cut_tets`):
    boundaries re-expressed, the ``crack`` group extended by the newly exposed faces,
    curved edges remapped."""
    n_old = old.n_points
    points = old.points[node_map]

    # every face of the new mesh (rows 4 tet + local face: a tet keeps its row, and the
    # image of row r in old ids is the old face at row r)
    faces = tets[:, TET_FACES].reshape(-1, 3)
    # the old mesh's rows, kept for it too where a sort found them (its next cut: a debris
    # retry, a benchmark's repeat)
    known = _BOUNDARY_ROWS.setdefault(old, {})
    image = None
    boundaries, rows = {}, {}
    for name, tri in old.boundaries.items():
        tri = np.asarray(tri, dtype=np.int64).reshape(-1, 3)
        row = known.get(name)
        if row is not None and row.size == tri.shape[0]:
            same = _corners(node_map[faces[row]], tri)
        if row is None or row.size != tri.shape[0] or not same.any(axis=2).all():
            if image is None:  # ties: lowest tet first
                image = SortedKeys(facet_keys(node_map[faces], n_old))
            row = image.rows(facet_keys(tri, n_old))
            if np.any(row < 0):
                raise ValueError(f"boundary {name!r}: facets that are not faces of the mesh")
            same = _corners(node_map[faces[row]], tri)
            known[name] = row
        # keep the caller's vertex order (and so the orientation) of every triangle
        boundaries[name] = np.take_along_axis(faces[row], np.argmax(same, axis=2), axis=1)
        rows[name] = row

    # a face is newly exposed where its row was held by two tets and is held by one now
    exposed = np.flatnonzero(_held(old.tets) & ~_held(tets))
    rows[CRACK] = np.concatenate([rows.get(CRACK, np.empty(0, dtype=np.int64)), exposed])
    boundaries[CRACK] = np.concatenate(
        [boundaries.get(CRACK, np.empty((0, 3), dtype=np.int64)), faces[exposed]]
    ).astype(np.int64)

    edges, edge_points = old.edges, old.edge_points
    if old.curved:
        pairs = np.unique(np.sort(tets[:, TET_EDGES].reshape(-1, 2), axis=1), axis=0)
        pos = match(edge_keys(old.edges, n_old), edge_keys(node_map[pairs], n_old))
        ok = pos >= 0
        edges, edge_points = pairs[ok], old.edge_points[pos[ok]]

    mesh = Mesh(
        points=points,
        tets=tets,
        boundaries=boundaries,
        subdomains={k: np.asarray(v).copy() for k, v in old.subdomains.items()},
        edges=edges,
        edge_points=edge_points,
    )
    _BOUNDARY_ROWS[mesh] = rows
    return mesh, Transfer(node_map, np.arange(old.n_tets, dtype=np.int64))


def _corners(faces: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """``(k, 3, 3)``: corner ``j`` of ``faces[i]`` is corner ``c`` of ``tri[i]``, at
    ``[i, c, j]``."""
    return faces[:, None, :] == tri[:, :, None]


def separate_nonmanifold(mesh: Mesh) -> tuple[Mesh, Transfer]:
    """Split every vertex whose incident tets are not face-connected among themselves.

    Each extra face-connected fan around a vertex gets its own copy of the vertex, so pieces
    joined only at a vertex come apart, and pieces joined only along an edge come apart too
    (both end vertices split). No face changes hands: a face shared by two tets keeps one
    fan on both sides, so the exterior faces and the ``crack`` group stay as they are.
    """
    tets, node_map = _separate_tets(mesh.tets, mesh.n_points)
    return rebuilt(mesh, tets, node_map)


def split_vertex(mesh: Mesh, vertex: int, normal, separate: bool = True) -> tuple[Mesh, Transfer]:
    """Open the mesh at ``vertex`` along the plane through it with normal ``normal``.

    The tets around the vertex go to the + or − side by the sign of
    ``(centroid − vertex) · normal`` in reference coordinates (zero counts as +). If both
    sides are non-empty, the − side gets a new copy of the vertex (appended last); the faces
    between the two sides become exterior and are added to the ``crack`` boundary. Then
    (``separate``) :func:`separate_nonmanifold` splits whatever is left joined only at a
    vertex or an edge. Returns the new mesh and the :class:`Transfer` from ``mesh``.
    """
    return open_crack(mesh, [vertex], np.reshape(normal, (1, 3)), separate=separate)


def open_crack(mesh: Mesh, vertices, normals, separate: bool = True) -> tuple[Mesh, Transfer]:
    """A batch of :func:`split_vertex`: plane splits in the given order, then one
    :func:`separate_nonmanifold`. ``vertices (k,)`` are ids of ``mesh`` (old ids keep their
    meaning through the batch: a later split of a vertex acts on the tets still holding the
    original id, i.e. its + side). ``normals (k, 3)``; only their direction matters.
    """
    return rebuilt(mesh, *cut_tets(mesh, vertices, normals, separate))


def cut_tets(mesh: Mesh, vertices, normals, separate: bool = True
             ) -> tuple[np.ndarray, np.ndarray]:
    """The tet table and node map of :func:`open_crack` (``(new tets (m, 4), node_map)``),
    without the mesh around them (its boundary groups): enough to count the pieces a batch
    would make before :func:`rebuilt` makes the mesh."""
    vertices = np.atleast_1d(np.asarray(vertices, dtype=np.int64))
    normals = np.asarray(normals, dtype=float).reshape(-1, 3)
    if vertices.shape[0] != normals.shape[0]:
        raise ValueError(f"{vertices.shape[0]} vertices but {normals.shape[0]} normals")
    if vertices.size and (vertices.min() < 0 or vertices.max() >= mesh.n_points):
        raise ValueError("vertex id out of range")
    tets = np.array(mesh.tets, dtype=np.int64)  # a private copy, edited in place below
    n = mesh.n_points
    # the flat positions in ``tets`` of the vertices to split (each vertex's ascending)
    flat = tets.reshape(-1)
    wanted = np.zeros(n, dtype=bool)
    wanted[vertices] = True
    held = np.flatnonzero(wanted[flat])
    holder = flat[held]  # the vertex each held before the splits
    # reference points of the originals and of the copies made so far
    ref = np.concatenate([np.asarray(mesh.points, dtype=float), np.empty((len(vertices), 3))])
    copied = []
    for v, normal in zip(vertices.tolist(), normals, strict=True):
        inc = held[holder == v]
        if _split_plane(tets, ref[: n + len(copied)], v, normal, inc):
            ref[n + len(copied)] = ref[v]
            copied.append(v)
    node_map = np.concatenate([np.arange(n, dtype=np.int64), np.asarray(copied, dtype=np.int64)])
    # the splits only gave corners new ids: the faces matched before, still matched, are
    # the new table's (a sort of every face saved for each of the tables below)
    # the tets a split changed: only corners it held can have new ids
    changed = np.zeros(tets.shape[0], dtype=bool)
    changed[held[flat[held] != holder] // 4] = True
    pairs = _kept_pairs(_face_pairs(mesh.tets), mesh.tets, tets, changed)
    if pairs is not None:
        _seed_pairs(tets, pairs, _new_key(tets))
    if separate:
        # on a table already separated, only the corners (old and new ids) of the tets a
        # split changed can have lost a face between their fans
        candidates = None
        if pairs is not None and _is_separated(mesh.tets):
            candidates = np.unique(np.concatenate([tets[changed].ravel(),
                                                   mesh.tets[changed].ravel()]))
        separated, later = _separate_tets(tets, node_map.size, candidates)
        if later.size > node_map.size:  # fans came apart: copies, the pairs kept again
            if pairs is not None:  # a separation gives no face to another tet
                _seed_pairs(separated, _kept_pairs(pairs, tets, separated),
                            _new_key(separated))
            tets, node_map = separated, node_map[later]
        # (else the same table: no fan came apart, every corner kept its id)
        remember(_SEPARATED, tets, True)
    return tets, node_map


def _is_separated(tets: np.ndarray) -> bool:
    """Whether ``tets`` is a table :func:`cut_tets` separated or :func:`check_separated`
    found so (every vertex one fan)."""
    return recalled(_SEPARATED, tets) is not None


def check_separated(mesh: Mesh) -> bool:
    """Whether every vertex of ``mesh`` is one face-connected fan of tets (as a conforming
    mesh's are, and every table :func:`cut_tets` makes), found once by a whole separation
    (:func:`separate_nonmanifold`) and then kept for its table, so that the first cut of
    a mesh that did not come from a cut also separates around its splits only. The
    table's key for its matched faces is kept with it, as for the tables cut_tets makes
    (a batch asks for them several times, each a hash of the whole table otherwise)."""
    tets = mesh.tets
    if _is_separated(tets):
        return True
    _remember_key(tets)
    _, node_map = _separate_tets(tets, mesh.n_points)
    if node_map.size != mesh.n_points:
        return False
    remember(_SEPARATED, tets, True)
    return True


def extract(mesh: Mesh, keep) -> tuple[Mesh, Transfer]:
    """The mesh of the tets ``keep`` (bool ``(n_tets,)`` or ids) alone, vertices renumbered in
    their old order: ``(mesh, Transfer)`` with ``node_map`` the old id of every kept vertex and
    ``element_map`` the old id of every kept tet. Boundary groups keep the faces of kept tets
    (every group face is exterior, so it has one tet); subdomains and curved edges follow."""
    keep = np.asarray(keep)
    ids = np.flatnonzero(keep) if keep.dtype == bool else np.sort(keep.astype(np.int64))
    tets = np.asarray(mesh.tets, dtype=np.int64)[ids]
    node_map = np.unique(tets)
    new_id = np.full(mesh.n_points, -1, dtype=np.int64)
    new_id[node_map] = np.arange(node_map.size)
    kept_faces = facet_keys(tets[:, TET_FACES].reshape(-1, 3), mesh.n_points)
    boundaries = {}
    for name, tri in mesh.boundaries.items():
        tri = np.asarray(tri, dtype=np.int64).reshape(-1, 3)
        mine = np.isin(facet_keys(tri, mesh.n_points), kept_faces)
        boundaries[name] = new_id[tri[mine]]
    tet_new = np.full(mesh.n_tets, -1, dtype=np.int64)
    tet_new[ids] = np.arange(ids.size)
    subdomains = {k: tet_new[np.asarray(v, dtype=np.int64)][tet_new[np.asarray(v)] >= 0]
                  for k, v in mesh.subdomains.items()}
    edges, edge_points = mesh.edges, mesh.edge_points
    if mesh.curved:
        ok = np.all(new_id[mesh.edges] >= 0, axis=1)
        edges, edge_points = new_id[mesh.edges[ok]], mesh.edge_points[ok]
    new = Mesh(points=np.asarray(mesh.points)[node_map], tets=new_id[tets],
               boundaries=boundaries, subdomains=subdomains, edges=edges,
               edge_points=edge_points)
    return new, Transfer(node_map, ids)

