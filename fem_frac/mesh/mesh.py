"""The tetrahedral mesh every stage shares: reference geometry, topology and named groups.

A :class:`Mesh` is immutable. A stage that changes topology (crack insertion) returns a new
mesh, because derived topology (faces, edges, adjacency) is cached by whoever computed it.

Conventions
-----------
- ``points``: ``(n_points, 3)`` float64 reference coordinates of the corner vertices.
- ``tets``: ``(n_tets, 4)`` int64 corner vertex ids, positively oriented (volume > 0).
- ``boundaries``: name -> ``(n_facets, 3)`` int64 corner vertex triples of boundary triangles.
- ``subdomains``: name -> ``(k,)`` int64 tet ids (volume physical groups).
- ``edges``/``edge_points``: optional curved geometry of quadratic meshes: ``(n_edges, 2)``
  vertex pairs (sorted within the pair) and the ``(n_edges, 3)`` position of each edge's
  mid-side node. Edges not listed are straight.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# Local vertex pairs of the six edges of a tetrahedron, in the order VTK's quadratic tet
# (and scikit-fem's ``t2e``) uses.
TET_EDGES = np.array([[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]])
# Local vertex triples of the four faces; face i is opposite vertex i and its right-hand
# normal points out of a positively oriented tet.
TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])


@dataclass(frozen=True, eq=False)
class Mesh:
    points: np.ndarray
    tets: np.ndarray
    boundaries: dict[str, np.ndarray] = field(default_factory=dict)
    subdomains: dict[str, np.ndarray] = field(default_factory=dict)
    edges: np.ndarray | None = None
    edge_points: np.ndarray | None = None

    @property
    def n_points(self) -> int:
        return self.points.shape[0]

    @property
    def n_tets(self) -> int:
        return self.tets.shape[0]

    @property
    def curved(self) -> bool:
        """True when mid-side nodes of a quadratic geometry are stored."""
        return self.edges is not None and len(self.edges) > 0


def tet_volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volumes ``(n_tets,)`` of straight-sided tets; negative means inverted."""
    x = points[tets]
    d = x[:, 1:] - x[:, :1]
    return np.einsum("ei,ei->e", d[:, 0], np.cross(d[:, 1], d[:, 2])) / 6.0


def min_dihedral_angles(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Smallest interior dihedral angle of each tet, in degrees, ``(n_tets,)``.

    The dihedral angle along an edge is pi minus the angle between the outward normals of
    the two faces meeting there.
    """
    x = points[tets]
    normals = []
    for opposite, (a, b, c) in enumerate(TET_FACES):
        n = np.cross(x[:, b] - x[:, a], x[:, c] - x[:, a])
        # orient outward: away from the opposite vertex
        s = np.sign(np.einsum("ei,ei->e", n, x[:, a] - x[:, opposite]))
        n = n * s[:, None]
        norm = np.linalg.norm(n, axis=1, keepdims=True)
        normals.append(n / np.where(norm > 0, norm, 1.0))
    angles = []
    for i in range(4):
        for j in range(i + 1, 4):
            cos = np.clip(-np.einsum("ei,ei->e", normals[i], normals[j]), -1.0, 1.0)
            angles.append(np.arccos(cos))
    return np.degrees(np.min(angles, axis=0))


def exterior_facets(tets: np.ndarray) -> np.ndarray:
    """Corner triples ``(n, 3)`` of faces that belong to exactly one tet, outward oriented.

    Orientation assumes positively oriented tets (see :func:`tet_volumes`).
    """
    tets = np.asarray(tets)
    faces = tets[:, TET_FACES].reshape(-1, 3)
    n = int(tets.max()) + 1 if tets.size else 0
    return faces[exterior_face_rows(tets, n)]


def exterior_face_rows(tets: np.ndarray, n_points: int) -> np.ndarray:
    """Mask ``(4 m,)`` over the face rows ``tets[:, TET_FACES].reshape(-1, 3)`` of the faces
    held by one tet only (``n_points``: any bound above the vertex ids)."""
    faces = np.asarray(tets)[:, TET_FACES].reshape(-1, 3)
    # integer keys sort far faster than np.unique(axis=0) on rows
    _, inverse, counts = np.unique(facet_keys(faces, n_points), return_inverse=True,
                                   return_counts=True)
    return counts[inverse.ravel()] == 1


def facet_keys(triples: np.ndarray, n_points: int) -> np.ndarray:
    """Order-independent integer key per vertex triple, for matching facets between tables."""
    s = np.sort(np.asarray(triples, dtype=np.int64), axis=1)
    n = np.int64(n_points)
    if n_points < 2_000_000:
        return (s[:, 0] * n + s[:, 1]) * n + s[:, 2]
    return np.ascontiguousarray(s).view([("", np.int64)] * 3).ravel()


def edge_keys(pairs: np.ndarray, n_points: int) -> np.ndarray:
    """Order-independent integer key per vertex pair ``(k, 2)``, as :func:`facet_keys`."""
    s = np.sort(np.asarray(pairs, dtype=np.int64), axis=1)
    return s[:, 0] * np.int64(n_points) + s[:, 1]


class SortedKeys:
    """A table of keys ``(n,)`` (e.g. :func:`facet_keys`) sorted once for look-ups.

    The sort is stable, so among equal keys the lowest row is found first.
    """

    def __init__(self, keys: np.ndarray):
        self.keys = np.asarray(keys)
        self.order = np.argsort(self.keys, kind="stable")
        self._sorted = self.keys[self.order]

    @property
    def sorted(self) -> np.ndarray:
        """The keys in ascending order (``keys[order]``)."""
        return self._sorted

    def rows(self, wanted: np.ndarray) -> np.ndarray:
        """For each of ``wanted (k,)`` the lowest row of the table holding it; -1 where
        none does (callers decide whether a missing key is an error)."""
        wanted = np.asarray(wanted)
        if self._sorted.size == 0:
            return np.full(wanted.shape[0], -1, dtype=np.intp)
        pos = np.minimum(np.searchsorted(self._sorted, wanted), self._sorted.size - 1)
        return np.where(self._sorted[pos] == wanted, self.order[pos], -1)

    def counts(self, wanted: np.ndarray) -> np.ndarray:
        """How many rows of the table hold each of ``wanted (k,)``."""
        left = np.searchsorted(self._sorted, wanted, side="left")
        return np.searchsorted(self._sorted, wanted, side="right") - left


def match(keys: np.ndarray, wanted: np.ndarray) -> np.ndarray:
    """Rows of ``keys (n,)`` holding ``wanted (k,)``: the lowest such row, -1 where none
    (:meth:`SortedKeys.rows`; build a :class:`SortedKeys` to look up many times)."""
    return SortedKeys(keys).rows(wanted)
