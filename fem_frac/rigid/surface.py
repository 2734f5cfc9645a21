"""The geometry of contact between rigid bodies and the finite elements: the exterior of the
deformed finite-element body, points located in its tets, closest points on its faces, the
half-spaces of a rigid body's convex hull, and a rigid fragment's own tets and surface
(:class:`Solid`: non-convex pieces touch where they are, not where their hull is). All
vectorized (numpy, scipy's cKDTree).

Used by :mod:`~fem_frac.rigid.deformable`, which finds the contacts and their impulses.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from functools import cache, cached_property
from itertools import chain

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist

from ..mesh.mesh import (
    TET_EDGES,
    TET_FACES,
    edge_keys,
    exterior_face_rows,
    exterior_facets,
    tet_volumes,
)
from .body import RigidBody, rotation_matrix, world_points
from .collide import hull
from .vectors import cross, lengths

# A point counts as inside a tet when its barycentric coordinates are all above this
# (round-off of the coordinates of a point on a face shared by two tets).
_INSIDE = -1e-12

# The relative slack of the candidate bounds (:func:`_near`): their distances' round-off
# never leaves out a triangle or tet that holds the answer.
_SLACK = 1e-9

# Up to this many point-cell pairs, candidates come from the dense distance matrix (cdist
# on tens of thousands of entries is cheaper than a tree's queries and their lists).
_DENSE = 1 << 16


@dataclass(frozen=True, eq=False)
class Exterior:
    """The exterior of a mesh: ``faces (f, 3)`` the vertex triples of the faces held by one
    tet (outward for positively oriented tets; crack faces included), ``nodes (s,)`` the
    scalar nodes on them (their vertices and, for P2, the mid-edge nodes of their edges)."""

    faces: np.ndarray
    nodes: np.ndarray


def exterior(tets: np.ndarray, n_points: int, element_dofs: np.ndarray) -> Exterior:
    """The :class:`Exterior` of the mesh ``tets (e, 4)``; ``element_dofs (n_local, e)`` the
    scalar nodes of every tet (vertices, then P2 mid-edge nodes in ``TET_EDGES`` order)."""
    faces = exterior_facets(tets)
    nodes = np.unique(faces)
    if element_dofs.shape[0] == 10:
        keys = edge_keys(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), n_points)
        element = edge_keys(tets[:, TET_EDGES].reshape(-1, 2), n_points)
        mid = element_dofs[4:].T.reshape(-1)
        nodes = np.union1d(nodes, mid[np.isin(element, keys)])
    return Exterior(faces, nodes)


@dataclass(frozen=True, eq=False)
class Solid:
    """A rigid fragment's own shape in its body frame: ``vertices (n, 3)``, ``tets (e, 4)``,
    ``faces (f, 3)`` its exterior (the faces held by one of its tets, crack faces included),
    oriented outward, ``surface (s,)`` the vertices on them, and ``hull_excess`` the volume
    its convex hull holds beyond its own, as a fraction of its own (0 for a convex piece)."""

    vertices: np.ndarray
    tets: np.ndarray
    faces: np.ndarray
    surface: np.ndarray
    hull_excess: float = 0.0

    # its geometry for the queries, kept with it (a Solid never changes)
    @cached_property
    def face_cells(self) -> Cells:
        """The :class:`Cells` of its exterior faces."""
        return cells(self.vertices, self.faces)

    @cached_property
    def tet_cells(self) -> Cells:
        """The :class:`Cells` of its tets."""
        return cells(self.vertices, self.tets)

    @cached_property
    def normals(self) -> np.ndarray:
        """``(f, 3)`` the outward unit normals of its exterior faces."""
        return face_normals(self.vertices, self.faces)

    @cached_property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``(lower (3,), upper (3,))``: the box of its vertices in its body frame."""
        return self.vertices.min(axis=0), self.vertices.max(axis=0)

    @cached_property
    def radius(self) -> float:
        """The largest distance of its vertices from its body frame's origin (its centre):
        its bounding sphere, for the broad phases."""
        return float(np.linalg.norm(self.vertices, axis=1).max(initial=0.0))


_SOLIDS: dict[int, Solid] = {}


def solid(body_coords: np.ndarray, cells: np.ndarray) -> Solid:
    """The :class:`Solid` of a fragment's nodes ``body_coords (k, 3)`` (body frame) and
    ``cells (e, 4 | 10)`` (VTK order: the four vertices first); kept while ``body_coords``
    lives (a fragment's arrays are shared by all its states, so this runs once per piece).
    The faces are turned outward by the tet that holds them, whatever the tets' sign."""
    key = id(body_coords)
    found = _SOLIDS.get(key)
    if found is not None:
        return found
    tets = np.asarray(cells)[:, :4].astype(np.int64)
    x = np.asarray(body_coords, dtype=float)
    rows = np.flatnonzero(exterior_face_rows(tets, len(x)))
    faces = tets[:, TET_FACES].reshape(-1, 3)[rows]
    corner = x[faces]
    normal = cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0])
    inward = np.einsum("ij,ij->i", normal,
                       corner.mean(axis=1) - x[tets[rows // 4]].mean(axis=1)) < 0.0
    faces[inward] = faces[inward][:, [0, 2, 1]]
    surface = np.unique(faces)
    found = _SOLIDS[key] = Solid(x[: int(tets.max()) + 1], tets, faces, surface,
                                 _hull_excess(x[surface], x, tets))
    weakref.finalize(body_coords, _SOLIDS.pop, key, None)
    return found


def _hull_excess(surface: np.ndarray, x: np.ndarray, tets: np.ndarray) -> float:
    """Hull volume over the tets' volume, minus 1 (0 where either is degenerate)."""
    from scipy.spatial import ConvexHull, QhullError

    volume = float(np.abs(tet_volumes(x, tets)).sum())
    try:
        hull_volume = ConvexHull(surface).volume
    except (QhullError, ValueError):
        return 0.0
    return max(hull_volume / volume - 1.0, 0.0) if volume > 0.0 else 0.0


def locate_in_solid(points: np.ndarray, shape: Solid):
    """Points ``(p, 3)`` (body frame) against a :class:`Solid`: ``(inside (p,), face (p,),
    weights (p, 3), distance (p,))``, inside its tets or not, the nearest exterior face,
    the barycentric weights of its closest point and the distance to it."""
    inside = inside_tets(points, shape.vertices, shape.tets, shape.tet_cells)
    face, weights, distance = nearest_faces(points, shape.vertices, shape.faces,
                                            shape.face_cells)
    return inside, face, weights, distance


def hull_planes(body: RigidBody) -> tuple[np.ndarray, np.ndarray]:
    """``(normals (F, 3), offsets (F,))``: the body's convex hull as the half-spaces
    ``x . n <= offset`` in world coordinates (unit outer normals)."""
    h = hull(body.points)
    r = rotation_matrix(body.orientation)
    offsets = (h.vertices @ h.normals.T).max(axis=0)
    normals = h.normals @ r.T
    return normals, offsets + normals @ body.position


def hull_gaps(x: np.ndarray, body: RigidBody) -> tuple[np.ndarray, np.ndarray]:
    """``(gap (p,), normal (p, 3))`` of world points ``x (p, 3)`` against the body's convex
    hull: the largest signed distance to its face planes (inside: the depth below the least
    penetrated face; outside: a lower bound of the distance) and that face's outer normal."""
    normals, offsets = hull_planes(body)
    distance = x @ normals.T - offsets
    face = np.argmax(distance, axis=1)
    return distance[np.arange(len(x)), face], normals[face]


def solid_gaps(x: np.ndarray, body: RigidBody, shape: Solid) -> tuple[np.ndarray, np.ndarray]:
    """``(gap (p,), normal (p, 3))`` of world points ``x (p, 3)`` against a body's own tets
    ``shape`` (a :class:`Solid` in its body frame): inside, minus the distance to its nearest
    exterior face (normal: that face's, outward); outside, the distance to its surface
    (normal: from the closest point towards the point)."""
    r = rotation_matrix(body.orientation)
    local = (x - body.position) @ r
    inside, face, weights, distance = locate_in_solid(local, shape)
    closest = np.einsum("ij,ijk->ik", weights, shape.vertices[shape.faces[face]])
    apart = (~inside) & (distance > 0.0)
    normal = np.where(apart[:, None],
                      (local - closest) / np.where(apart, distance, 1.0)[:, None],
                      shape.normals[face])
    return np.where(inside, -distance, distance), normal @ r.T


def within_box(x: np.ndarray, body: RigidBody, shape: Solid, margin) -> np.ndarray:
    """``(p,)``: whether world points ``x (p, 3)`` lie within ``margin`` (a number, or one
    per point) of the box of a body's own tets ``shape`` in its body frame, with a relative
    ``_SLACK`` more for round-off. Its distance from the box bounds a point's distance from
    the tets from below: a point outside it by more than ``margin`` is farther than that
    from the body (:func:`solid_gaps`)."""
    local = (x - body.position) @ rotation_matrix(body.orientation)
    lower, upper = shape.bounds
    outside = np.maximum(np.maximum(lower - local, local - upper), 0.0)
    return lengths(outside) <= np.asarray(margin) * (1.0 + _SLACK) + _SLACK * shape.radius


def surface_points(body: RigidBody, shape: Solid | None) -> np.ndarray:
    """World points of a body that can touch another: its own exterior vertices when it
    has a ``shape``, else its hull's."""
    if shape is None:
        return world_points(body)
    return body.position + shape.vertices[shape.surface] @ rotation_matrix(body.orientation).T


def pairs_within(a: np.ndarray, b: np.ndarray, radius) -> tuple[np.ndarray, np.ndarray]:
    """``(i, j)``: every pair of points ``a[i]``, ``b[j]`` at most ``radius`` apart."""
    if len(a) == 0 or len(b) == 0:
        z = np.zeros(0, dtype=np.int64)
        return z, z
    pairs = cKDTree(a).sparse_distance_matrix(cKDTree(b), float(radius),
                                              output_type="ndarray")
    return pairs["i"].astype(np.int64), pairs["j"].astype(np.int64)


@dataclass(frozen=True, eq=False)
class Cells:
    """Triangles ``(f, 3, 3)`` or tets ``(e, 4, 3)`` (their ``corners``) ready for the
    queries of points against them: ``centroid (n, 3)``, ``reach (n,)`` each one's largest
    centroid-to-corner distance (none of its points lies farther from its centroid). Built
    per call for the deformed finite elements, once for a :class:`Solid`."""

    corners: np.ndarray
    centroid: np.ndarray
    reach: np.ndarray

    @cached_property
    def tree(self) -> cKDTree:
        """A cKDTree on the centroids."""
        return cKDTree(self.centroid)

    @cached_property
    def rank(self) -> np.ndarray:
        """``(n,)`` each centroid's place in the tree's order: the order in which a
        traversal of the tree meets them, the tie-break between faces at equal distance
        (kept from a search by ``pairs_within``)."""
        rank = np.empty(len(self.centroid), dtype=np.int64)
        rank[self.tree.indices] = np.arange(len(self.centroid))
        return rank


def cells(x: np.ndarray, vertices: np.ndarray) -> Cells:
    """The :class:`Cells` of the triangles or tets ``vertices (n, 3 | 4)``, corners at
    ``x``."""
    corners = x[vertices]
    centroid = corners.mean(axis=1)
    reach = lengths(corners - centroid[:, None]).max(axis=1, initial=0.0)
    return Cells(corners, centroid, reach)


def _near(points: np.ndarray, shape: Cells, bound=None) -> tuple[np.ndarray, np.ndarray]:
    """``(i, j)``, ascending in ``i``: every point ``points[i]`` within ``r[i] + reach[j]``
    of the centroid of cell ``j`` (a relative ``_SLACK`` more, for round-off); ``r`` 0, or
    ``bound(k)`` of each point's nearest centroid ``k`` when given. One bound per point: a
    far point tests no more cells than its own neighbourhood holds. Small sets by the dense
    distance matrix (cheaper than a tree's queries and their lists), large ones by the
    tree."""
    if len(points) * len(shape.reach) <= _DENSE:
        apart = cdist(points, shape.centroid)
        r = 0.0 if bound is None else bound(apart.argmin(axis=1))[:, None]
        return np.nonzero(apart <= (r + shape.reach) * (1.0 + _SLACK))
    r = np.zeros(len(points)) if bound is None else bound(shape.tree.query(points)[1])
    found = shape.tree.query_ball_point(points, (r + shape.reach.max()) * (1.0 + _SLACK),
                                        return_sorted=False)
    i = np.repeat(np.arange(len(points)), np.fromiter(map(len, found), np.int64, len(found)))
    j = np.fromiter(chain.from_iterable(found), np.int64, len(i))
    keep = lengths(points[i] - shape.centroid[j]) <= (r[i] + shape.reach[j]) * (1.0 + _SLACK)
    return i[keep], j[keep]


def inside_tets(points: np.ndarray, x: np.ndarray, tets: np.ndarray,
                shape: Cells | None = None) -> np.ndarray:
    """``(p,)``: whether each of ``points (p, 3)`` lies in one of the tets ``(e, 4)`` with
    vertices at ``x (n, 3)`` (``shape``: their :class:`Cells`, when kept). Candidates: the
    tets whose centroid is within their own reach of the point, then barycentric
    coordinates."""
    shape = cells(x, tets) if shape is None else shape
    found = np.zeros(len(points), dtype=bool)
    if len(points) == 0 or len(tets) == 0:
        return found
    i, e = _near(points, shape)
    corners = shape.corners
    edges = corners[e, 1:] - corners[e, :1]  # (m, 3 edges, 3)
    solvable = np.abs(np.linalg.det(edges)) > 0.0
    i, e, edges = i[solvable], e[solvable], edges[solvable]
    local = np.linalg.solve(np.transpose(edges, (0, 2, 1)),
                            (points[i] - corners[e, 0])[:, :, None])[:, :, 0]
    bary = np.concatenate([1.0 - local.sum(axis=1, keepdims=True), local], axis=1)
    found[i[np.all(bary >= _INSIDE, axis=1)]] = True
    return found


# Ericson's seven regions of the closest point (5.1.5), in his order: corner A, corner B,
# edge AB, corner C, edge AC, edge BC, the face; each one's weights as rows of the table
# of :func:`_region_weights`.
_REGION_ROWS = np.array([[1, 0, 0], [0, 1, 0], [6, 3, 0], [0, 0, 1], [7, 0, 4], [0, 5, 2],
                         [10, 8, 9]])

# Each region's test (but the face's), as the bits of :func:`_region_codes` that must all
# be set: A d1 <= 0, d2 <= 0; B d3 >= 0, d4 <= d3; AB vc <= 0, d1 >= 0, d3 <= 0; C d6 >= 0,
# d5 <= d6; AC vb <= 0, d2 >= 0, d6 <= 0; BC va <= 0, e >= 0, f >= 0.
_REGION_TESTS = ((4, 5), (11, 14), (2, 9, 6), (12, 15), (1, 10, 7), (0, 8, 13))


@cache
def _first_regions() -> np.ndarray:
    """``(2^16,)`` the region of every code of :func:`_region_codes`: the first whose test
    holds (Ericson's sequence of early returns: on a boundary, the earlier region), else
    the face. Made at the first call (2.8 ms), not at import."""
    bits = (np.arange(1 << 16)[:, None] >> np.arange(16)) & 1 == 1
    holds = [bits[:, list(test)].all(axis=1) for test in _REGION_TESTS]
    return np.stack(holds + [np.ones(1 << 16, dtype=bool)], axis=1).argmax(axis=1)


_POWERS = (1 << np.arange(16)).astype(np.uint16)


def closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray,
                         c: np.ndarray) -> np.ndarray:
    """``(m, 3)`` barycentric weights of the point of each triangle ``a, b, c (m, 3)``
    closest to ``p (m, 3)`` (Ericson, Real-Time Collision Detection, 5.1.5: the Voronoi
    regions of the corners, the edges and the face, vectorized). Every region's weights
    are computed for all rows and each row takes those of its region: a few dozen numpy
    calls, on ``(k, m)`` blocks, whatever the regions (the weights decide contact normals
    and ties downstream: the same bits as a region-by-region assignment)."""
    n = len(p)
    y = _ericson_terms(_corner_dots(p, a, b, c))
    rows = _REGION_ROWS[_first_regions()[_region_codes(y)]]
    rows *= n
    rows += np.arange(n)[:, None]
    return _region_weights(y).reshape(-1).take(rows)


def _corner_dots(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """``(6, m)`` Ericson's ``d1 .. d6``: ``ab.ap, ac.ap, ab.bp, ac.bp, ab.cp, ac.cp``, by one
    einsum over the six pairs stacked (each row's sum as einsum's of the pair alone, which
    is not ``(u * v).sum(1)``'s to the bit)."""
    ab, ac, ap, bp, cp = b - a, c - a, p - a, p - b, p - c
    return np.einsum("ij,ij->i", np.concatenate((ab, ac, ab, ac, ab, ac)),
                     np.concatenate((ap, ap, bp, bp, cp, cp))).reshape(6, len(p))


def _ericson_terms(d: np.ndarray) -> np.ndarray:
    """``(11, m)``: ``va, vb, vc, e, d1, d2, d3, d6, f, d4, d5`` of the dot products ``d``
    (``va = d3 d6 - d5 d4``, ``vb = d5 d2 - d1 d6``, ``vc = d1 d4 - d3 d2``, ``e = d4 - d3``,
    ``f = d5 - d6``), laid out so that the tests and weights take blocks of rows."""
    y = np.empty((11, d.shape[1]))
    x = d.take([2, 4, 0, 5, 1, 3, 4, 0, 2, 3, 5, 1], axis=0)
    np.subtract(x[0:3] * x[3:6], x[6:9] * x[9:12], out=y[0:3])
    y[4:8] = d.take([0, 1, 2, 5], axis=0)
    y[9:11] = d[3:5]
    np.subtract(y[9], y[6], out=y[3])
    np.subtract(y[10], y[7], out=y[8])
    return y


def _region_codes(y: np.ndarray) -> np.ndarray:
    """``(m,)`` the comparisons of the region tests as the bits of one code per row: 0-7
    ``va, vb, vc, e, d1, d2, d3, d6 <= 0``, 8-13 ``e, d1, d2, d3, d6, f >= 0``, 14
    ``d4 <= d3``, 15 ``d5 <= d6`` (``y`` of :func:`_ericson_terms`)."""
    bits = np.empty((16, y.shape[1]), dtype=bool)
    np.less_equal(y[0:8], 0.0, out=bits[0:8])
    np.greater_equal(y[3:9], 0.0, out=bits[8:14])
    np.less_equal(y[9:11], y[6:8], out=bits[14:16])
    return np.dot(_POWERS, bits.view(np.uint8))


def _region_weights(y: np.ndarray) -> np.ndarray:
    """``(11, m)`` the weights of every region, for every row: ``z, z + 1, t, s, r, 1 - t,
    1 - s, 1 - r, v, w, 1 - v - w`` with ``t = e / (e + f)`` the parameter on edge BC,
    ``s = d1 / (d1 - d3)`` on AB, ``r = d2 / (d2 - d6)`` on AC, ``v, w`` the face's and
    ``z = 0 t`` (0 of the sign of ``t``, or NaN where ``t`` is not finite: Ericson's zero
    weights, as they were computed)."""
    table = np.empty((11, y.shape[1]))
    den = np.empty((3, y.shape[1]))
    np.add(y[3], y[8], out=den[0])
    np.subtract(y[4:6], y[6:8], out=den[1:3])
    with np.errstate(divide="ignore", invalid="ignore"):
        np.divide(y[3:6], den, out=table[2:5])
        np.subtract(1.0, table[2:5], out=table[5:8])
        np.multiply(0.0, table[2], out=table[0])
        np.add(table[0], 1.0, out=table[1])
        np.divide(y[1:3], y[0] + y[1] + y[2], out=table[8:10])
        np.subtract(1.0 - table[8], table[9], out=table[10])
    return table


def nearest_faces(points: np.ndarray, x: np.ndarray, faces: np.ndarray,
                  shape: Cells | None = None):
    """The triangle of ``faces (f, 3)`` (vertices at ``x``; ``shape``: their :class:`Cells`,
    when kept) nearest to each of ``points (p, 3)``: ``(face (p,), weights (p, 3),
    distance (p,))``, ``weights`` the barycentric coordinates of its closest point.

    Exact: the distance to the face of the nearest centroid bounds each point's answer from
    above, and no point of a triangle is nearer than its centroid's distance less its
    reach, so every triangle that can be nearest is tried (:func:`_near`, one bound per
    point). Of faces at equal distance, the first in the centroids' tree order wins."""
    shape = cells(x, faces) if shape is None else shape
    out = np.zeros(len(points), dtype=np.int64)
    w = np.zeros((len(points), 3))
    d = np.full(len(points), np.inf)
    if len(points) == 0 or len(faces) == 0:
        return out, w, d
    rows, face = _near(points, shape,
                       lambda k: _distances(points, shape.corners[k])[1])
    weights, distance = _distances(points[rows], shape.corners[face])
    best = _first_nearest(rows, distance, shape.rank[face], len(faces))
    out[rows[best]] = face[best]
    w[rows[best]] = weights[best]
    d[rows[best]] = distance[best]
    return out, w, d


def _first_nearest(rows: np.ndarray, distance: np.ndarray, rank: np.ndarray,
                   n: int) -> np.ndarray:
    """The index of each point's nearest candidate (``rows`` ascending): the least
    ``distance``, of equal ones the least ``rank`` (< ``n``), as a stable sort of the
    candidates in tree order by distance would pick (a NaN, of a degenerate triangle, last)."""
    start = np.flatnonzero(np.concatenate(([True], rows[1:] != rows[:-1])))
    count = np.diff(start, append=len(rows))
    least = np.repeat(np.fmin.reduceat(distance, start), count)
    key = rank + n * (distance != least)
    return np.flatnonzero(key == np.repeat(np.minimum.reduceat(key, start), count))


def _distances(p: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(weights (m, 3), distance (m,))``: the closest point of each triangle ``corners
    (m, 3, 3)`` to ``p (m, 3)`` (barycentric weights) and the distance to it."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    weights = closest_on_triangles(p, a, b, c)
    closest = weights[:, :1] * a + weights[:, 1:2] * b + weights[:, 2:] * c
    return weights, lengths(p - closest)


def face_normals(x: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``(f, 3)`` unit normals of the triangles (right-hand rule: outward for exterior
    faces)."""
    n = cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(norm > 0, norm, 1.0)
