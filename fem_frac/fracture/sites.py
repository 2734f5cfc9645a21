"""Where a batch of cracks opens: elements over strength -> (vertex, normal) split sites.

DESIGN §2: where the smoothed largest principal stress ``sigma1`` of an element exceeds the
tensile strength, a crack opens perpendicular to its direction ``n`` through one of the
element's vertices. The rules, all deterministic:

- candidates are taken in decreasing ``sigma1`` (ties: lower element id first);
- a batch holds at most ``limit`` sites and no two candidates of one smoothing
  neighbourhood: their smoothed stresses are one measurement, which the insertion changes,
  so the next site there waits for the re-solve;
- the vertex: one whose plane (through it, normal ``n``) really separates its tets; among
  those, vertices already on a crack first (cracks grow rather than nucleate anew), then the
  one whose plane passes closest to the element's centroid; vertices of protected parts
  never split, and a vertex is split at most once per batch;
- growth along fronts (cohesive cracks, which carry traction while they open and so keep
  the stress at the strength in their process zone): given the crack front
  (:func:`~fem_frac.fracture.front.crack_front`), an element near a crack
  (:func:`~fem_frac.fracture.front.near_crack`) splits only at a front vertex, or not at
  all, so a crack extends from its own front rather than into a band beside or behind it;
  front vertices come first, then vertices on a crack, then the nearest plane;
- cohesive cracks also try, after the vertices on a crack, the most stressed vertex (the
  mean smoothed ``sigma1`` of its tets) before the nearest plane: a crack starts at the
  stress peak an element samples (a notch root, at the element's vertex on it), not at
  whichever vertex happens to lie nearest the plane through the element's centroid; on a
  mesh whose elements are as large as the process zone the two differ by an element.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .front import near_marked

# Candidates tested per vectorized block (in decreasing stress): a batch is usually full
# long before every element over strength has been looked at.
CHUNK = 256


@dataclass(frozen=True, eq=False)
class Sites:
    """A batch of crack sites: ``elements (k,)`` over strength, the ``vertices (k,)`` to split
    and the crack ``normals (k, 3)`` (unit), with the smoothed ``stress (k,)`` that
    triggered each."""

    elements: np.ndarray
    vertices: np.ndarray
    normals: np.ndarray
    stress: np.ndarray

    def __len__(self) -> int:
        return int(self.vertices.shape[0])

    def subset(self, keep: np.ndarray) -> Sites:
        return Sites(self.elements[keep], self.vertices[keep], self.normals[keep],
                     self.stress[keep])


def vertex_tets(tets: np.ndarray, n_points: int) -> sp.csr_matrix:
    """``(n_points, n_tets)`` 0/1 incidence: row ``v`` lists the tets holding vertex ``v``,
    ascending (canonical CSR: :func:`splits` searches a row)."""
    m = tets.shape[0]
    rows = np.asarray(tets, dtype=np.int64).ravel()
    cols = np.repeat(np.arange(m, dtype=np.int64), 4)
    inc = sp.csr_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(n_points, m))
    inc.sum_duplicates()
    return inc


@dataclass(frozen=True, eq=False)
class Star:
    """Per-topology lookups for :func:`splits`: ``incidence`` (:func:`vertex_tets`), the face
    ``adjacency (m, m)`` and ``held (m, 4)``: whether the face opposite local vertex ``i`` of
    a tet is shared with another tet; ``known``: the answers of :func:`splits` so far, by
    vertex and the sides its tets fall on (all that the answer depends on, on one
    topology)."""

    incidence: sp.csr_matrix
    adjacency: sp.csr_matrix
    held: np.ndarray
    known: dict = field(default_factory=dict, repr=False)


def star(tets: np.ndarray, n_points: int) -> Star:
    from .faces import _face_pairs, face_adjacency

    r1, r2, _, _ = _face_pairs(tets)
    held = np.zeros(4 * tets.shape[0], dtype=bool)
    held[r1] = held[r2] = True  # face row 4 t + i is face i of tet t, opposite vertex i
    return Star(vertex_tets(tets, n_points), face_adjacency(tets), held.reshape(-1, 4))


def splits(points: np.ndarray, tets: np.ndarray, centroids: np.ndarray, s: Star, vertex: int,
           normal: np.ndarray) -> bool:
    """Whether the plane through ``vertex`` with ``normal`` opens a crack there: it leaves
    tets of the vertex on both sides (the rule of
    :func:`~fem_frac.fracture.topology.split_vertex`: zero counts as +), and every group of
    same-side tets joined through faces at the vertex keeps a face away from the vertex
    shared with the rest of the mesh. A group without one would come off as a loose piece
    of a few tets: a crack around a corner, not across the body."""
    inc = s.incidence
    around = inc.indices[inc.indptr[vertex]:inc.indptr[vertex + 1]]  # ascending (canonical)
    side = (centroids[around] - points[vertex]) @ normal < 0.0
    if not side.any() or side.all():
        return False
    key = (vertex, side.tobytes())
    found = s.known.get(key)
    if found is None:
        found = s.known[key] = _anchored(tets, s, vertex, around, side)
    return found


def _anchored(tets: np.ndarray, s: Star, vertex: int, around: np.ndarray,
              side: np.ndarray) -> bool:
    """Whether every group of same-side tets ``around`` the vertex (``side`` of each) joined
    through faces at the vertex keeps a face away from it shared with the rest (the second
    test of :func:`splits`)."""
    adj = s.adjacency
    # the face-sharing pairs among the tets around the vertex (plain numpy: these graphs
    # have a few dozen nodes, far below what sparse slicing pays off for)
    start, degree = adj.indptr[around], adj.indptr[around + 1] - adj.indptr[around]
    row = np.repeat(np.arange(around.size), degree)
    neighbour = adj.indices[np.repeat(start - (np.cumsum(degree) - degree), degree)
                            + np.arange(int(degree.sum()))]
    position = np.minimum(np.searchsorted(around, neighbour), around.size - 1)
    inside = around[position] == neighbour
    i, j = row[inside], position[inside]
    same = side[i] == side[j]
    group = _groups(around.size, i[same].tolist(), j[same].tolist())
    local = np.argmax(tets[around] == vertex, axis=1)
    anchored = {group[k] for k in np.flatnonzero(s.held[around, local]).tolist()}
    return set(group) <= anchored


def _groups(n: int, a: list[int], b: list[int]) -> list[int]:
    """The connected group (its lowest node) of each of ``n`` nodes joined by the edges
    ``a[k] - b[k]``: union-find in Python, for the few dozen tets around a vertex."""
    parent = list(range(n))

    def root(k: int) -> int:
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    for x, y in zip(a, b, strict=True):
        rx, ry = root(x), root(y)
        if rx != ry:
            parent[max(rx, ry)] = min(rx, ry)
    return [root(k) for k in range(n)]


def tilt(normals: np.ndarray, angle: float, rng: np.random.Generator,
         only: np.ndarray | None = None) -> np.ndarray:
    """Unit normals tilted uniformly on the spherical cap of half-angle ``angle`` (radians)
    around each of ``normals (k, 3)``. ``only (k,)`` bool: tilt those rows alone and return
    the others as given; the draws are the same (two per row, for every row), so a row's
    tilt does not depend on which others are tilted."""
    k = normals.shape[0]
    cos = 1.0 - rng.random(k) * (1.0 - np.cos(angle))  # uniform on the cap's area
    phi = 2.0 * np.pi * rng.random(k)
    if only is not None:
        out = np.array(normals, dtype=float)
        out[only] = _tilted(out[only], cos[only], phi[only])
        return out
    return _tilted(normals, cos, phi)


def _tilted(normals: np.ndarray, cos: np.ndarray, phi: np.ndarray) -> np.ndarray:
    n = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    # an orthonormal pair perpendicular to n: cross with the axis least aligned with it
    axis = np.eye(3)[np.argmin(np.abs(n), axis=1)]
    e1 = np.cross(n, axis)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(n, e1)
    sin = np.sqrt(np.maximum(1.0 - cos**2, 0.0))
    return cos[:, None] * n + sin[:, None] * (np.cos(phi)[:, None] * e1
                                              + np.sin(phi)[:, None] * e2)


def two_sided(points: np.ndarray, centroids: np.ndarray, incidence: sp.csr_matrix,
              vertices: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Vectorized first test of :func:`splits` for pairs ``vertices (k,)``, ``normals
    (k, 3)``: whether the plane leaves tets of the vertex on both sides, ``(k,)`` bool."""
    start, stop = incidence.indptr[vertices], incidence.indptr[vertices + 1]
    degree = stop - start
    pair = np.repeat(np.arange(vertices.size), degree)
    offset = np.arange(pair.size) - np.repeat(np.cumsum(degree) - degree, degree)
    tets = incidence.indices[np.repeat(start, degree) + offset]
    minus = np.einsum("ij,ij->i", centroids[tets] - points[vertices[pair]],
                      normals[pair]) < 0.0
    n_minus = np.bincount(pair, weights=minus, minlength=vertices.size)
    return (n_minus > 0) & (n_minus < degree)


def _preference(points: np.ndarray, centroid: np.ndarray, normal: np.ndarray,
                corners: np.ndarray, on_crack: np.ndarray,
                front: np.ndarray | None, peak: np.ndarray | None = None) -> np.ndarray:
    """The order in which an element's ``corners (4,)`` are tried: front vertices first
    (when ``front`` is given), then vertices on a crack, then (when ``peak (n,)`` is
    given) the most stressed vertex, then the plane closest to the ``centroid``, then the
    lower id."""
    distance = np.abs((points[corners] - centroid) @ normal)
    keys = (corners, distance)
    if peak is not None:
        keys = (*keys, -peak[corners])
    keys = (*keys, ~on_crack[corners])
    return np.lexsort(keys if front is None else (*keys, ~front[corners]))


def vertex_stress(incidence: sp.csr_matrix, sigma1: np.ndarray) -> np.ndarray:
    """``(n,)``: the mean smoothed largest principal stress ``sigma1 (m,)`` of the tets
    around each vertex (``incidence`` from :func:`vertex_tets`)."""
    count = np.asarray(incidence.sum(axis=1)).ravel()
    total = incidence @ np.asarray(sigma1, dtype=float)
    return np.divide(total, count, out=np.zeros_like(total), where=count > 0)


def _allowed(points: np.ndarray, centroids: np.ndarray, lookups: Star, corners: np.ndarray,
             normals: np.ndarray, protected: np.ndarray, front: np.ndarray | None,
             near: np.ndarray | None) -> np.ndarray:
    """``(k, 4)`` bool: the (candidate, corner) pairs of ``corners (k, 4)`` whose plane
    (``normals (k, 3)``) cuts the vertex's tets in two, at an unprotected vertex and, for a
    candidate ``near`` a crack when a ``front`` is given, at a front vertex. Vectorized over
    the block; the rest of the rules are :func:`splits` and the batch's bookkeeping."""
    cut = two_sided(points, centroids, lookups.incidence, corners.ravel(),
                    np.repeat(normals, 4, axis=0)).reshape(-1, 4)
    cut &= ~protected[corners]
    if front is not None:
        cut &= ~near[:, None] | front[corners]
    return cut


def no_sites() -> Sites:
    return Sites(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0))


def select_sites(points: np.ndarray, tets: np.ndarray, sigma1: np.ndarray,
                 direction: np.ndarray, strength: float, neighbourhood: sp.csr_matrix,
                 on_crack: np.ndarray, protected: np.ndarray, limit: int,
                 lookups: Star | None = None, front: np.ndarray | None = None,
                 near: np.ndarray | None = None, peak_first: bool = False,
                 centroids: np.ndarray | None = None) -> Sites:
    """The batch of at most ``limit`` sites (module docstring).

    ``points (n, 3)``, ``tets (m, 4)`` reference mesh; ``sigma1 (m,)``, ``direction (m, 3)``
    the smoothed largest principal stress and its unit direction; ``neighbourhood (m, m)``
    the smoothing operator's pattern; ``on_crack``/``protected`` ``(n,)`` bool per vertex;
    ``lookups`` the :func:`star` of the mesh (made here when not given). ``front (n,)``
    bool per vertex turns on growth along fronts, with ``near (m,)`` bool per tet (the
    tets near a crack; when not given, those whose neighbourhood holds an ``on_crack``
    vertex); without ``front``, ``near`` is ignored. ``peak_first``: the most stressed vertex
    (:func:`vertex_stress`) before the nearest plane (cohesive). ``centroids (m, 3)``: the tets'."""
    tets = np.asarray(tets, dtype=np.int64)
    candidates = np.flatnonzero(sigma1 > strength)
    if candidates.size == 0 or limit <= 0:
        return no_sites()
    lookups = lookups if lookups is not None else star(tets, points.shape[0])
    if front is not None and near is None:
        near = near_marked(tets, neighbourhood, on_crack)
    centroids = points[tets].mean(axis=1) if centroids is None else centroids
    peak = vertex_stress(lookups.incidence, sigma1) if peak_first else None
    candidates = candidates[np.argsort(-sigma1[candidates], kind="stable")]  # ties by id
    pattern = neighbourhood.tocsr()
    claimed, used = np.zeros(tets.shape[0], dtype=bool), np.zeros(points.shape[0], dtype=bool)
    chosen: list[tuple[int, int]] = []
    chunk = max(CHUNK, 8 * limit)
    for begin in range(0, candidates.size, chunk):
        block = candidates[begin:begin + chunk]
        block = block[~claimed[block]]
        corners = tets[block]  # (k, 4)
        cut = _allowed(points, centroids, lookups, corners, direction[block], protected,
                       front, None if near is None else near[block])
        for i in np.flatnonzero(cut.any(axis=1)).tolist():
            e = int(block[i])
            if claimed[e]:
                continue
            n = direction[e]
            for j in _preference(points, centroids[e], n, corners[i], on_crack, front,
                                 peak).tolist():
                v = int(corners[i, j])
                if (not cut[i, j] or used[v]
                        or not splits(points, tets, centroids, lookups, v, n)):
                    continue
                chosen.append((e, v))
                used[v] = True
                claimed[pattern.indices[pattern.indptr[e]:pattern.indptr[e + 1]]] = True
                claimed[e] = True
                break
            if len(chosen) == limit:
                break
        if len(chosen) == limit:
            break
    if not chosen:
        return no_sites()
    elements, vertices = (np.array(c, dtype=np.int64) for c in zip(*chosen, strict=True))
    return Sites(elements, vertices, direction[elements].copy(), sigma1[elements].copy())
