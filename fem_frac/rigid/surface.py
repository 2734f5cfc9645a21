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

import numpy as np
from scipy.spatial import cKDTree

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

# A point counts as inside a tet when its barycentric coordinates are all above this
# (round-off of the coordinates of a point on a face shared by two tets).
_INSIDE = -1e-12


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
    normal = np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0])
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
    inside = inside_tets(points, shape.vertices, shape.tets)
    face, weights, distance = nearest_faces(points, shape.vertices, shape.faces)
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
                      face_normals(shape.vertices, shape.faces)[face])
    return np.where(inside, -distance, distance), normal @ r.T


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


def inside_tets(points: np.ndarray, x: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """``(p,)``: whether each of ``points (p, 3)`` lies in one of the tets ``(e, 4)`` with
    vertices at ``x (n, 3)``. Candidates by a cKDTree on the centroids (every tet whose
    centroid is within its largest centroid-to-vertex distance), then barycentric
    coordinates."""
    corners = x[tets]
    centroid = corners.mean(axis=1)
    reach = float(np.linalg.norm(corners - centroid[:, None], axis=2).max(initial=0.0))
    i, e = pairs_within(points, centroid, reach)
    found = np.zeros(len(points), dtype=bool)
    if i.size == 0:
        return found
    edges = corners[e, 1:] - corners[e, :1]  # (m, 3 edges, 3)
    solvable = np.abs(np.linalg.det(edges)) > 0.0
    i, e, edges = i[solvable], e[solvable], edges[solvable]
    local = np.linalg.solve(np.transpose(edges, (0, 2, 1)),
                            (points[i] - corners[e, 0])[:, :, None])[:, :, 0]
    bary = np.concatenate([1.0 - local.sum(axis=1, keepdims=True), local], axis=1)
    found[i[np.all(bary >= _INSIDE, axis=1)]] = True
    return found


def closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray,
                         c: np.ndarray) -> np.ndarray:
    """``(m, 3)`` barycentric weights of the point of each triangle ``a, b, c (m, 3)``
    closest to ``p (m, 3)`` (Ericson, Real-Time Collision Detection, 5.1.5: the Voronoi
    regions of the corners, the edges and the face, vectorized)."""
    ab, ac, ap, bp, cp = b - a, c - a, p - a, p - b, p - c

    def dot(u, v):
        return np.einsum("ij,ij->i", u, v)

    d1, d2, d3, d4, d5, d6 = dot(ab, ap), dot(ac, ap), dot(ab, bp), dot(ac, bp), \
        dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        total = va + vb + vc
        v, w = vb / total, vc / total
        out = np.stack([1.0 - v - w, v, w], axis=1)
        # the regions in the reverse of Ericson's order, so that the first of his wins
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        regions = [
            ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), [0 * t, 1 - t, t]),
            ((vb <= 0) & (d2 >= 0) & (d6 <= 0), [1 - d2 / (d2 - d6), 0 * t, d2 / (d2 - d6)]),
            ((d6 >= 0) & (d5 <= d6), [0 * t, 0 * t, 0 * t + 1]),
            ((vc <= 0) & (d1 >= 0) & (d3 <= 0), [1 - d1 / (d1 - d3), d1 / (d1 - d3), 0 * t]),
            ((d3 >= 0) & (d4 <= d3), [0 * t, 0 * t + 1, 0 * t]),
            ((d1 <= 0) & (d2 <= 0), [0 * t + 1, 0 * t, 0 * t]),
        ]
        for mask, weights in regions:
            out[mask] = np.stack(weights, axis=1)[mask]
    return out


def nearest_faces(points: np.ndarray, x: np.ndarray, faces: np.ndarray):
    """The triangle of ``faces (f, 3)`` (vertices at ``x``) nearest to each of
    ``points (p, 3)``: ``(face (p,), weights (p, 3), distance (p,))``, ``weights`` the
    barycentric coordinates of its closest point. Exact: every triangle whose centroid lies
    within (the distance to the nearest centroid + the largest centroid-to-corner distance)
    is tried."""
    corners = x[faces]
    centroid = corners.mean(axis=1)
    spread = float(np.linalg.norm(corners - centroid[:, None], axis=2).max(initial=0.0))
    nearest = cKDTree(centroid).query(points)[0]
    rows, face = pairs_within(points, centroid, float(nearest.max(initial=0.0)) + spread)
    keep = (np.linalg.norm(points[rows] - centroid[face], axis=1)
            <= nearest[rows] + spread * (1 + 1e-12))
    rows, face = rows[keep], face[keep]
    a, b, c = (corners[face, k] for k in range(3))
    weights = closest_on_triangles(points[rows], a, b, c)
    closest = weights[:, :1] * a + weights[:, 1:2] * b + weights[:, 2:] * c
    distance = np.linalg.norm(points[rows] - closest, axis=1)
    # the nearest face of each point: sort by point, then distance
    order = np.lexsort((distance, rows))
    first = order[np.flatnonzero(np.r_[True, rows[order][1:] != rows[order][:-1]])]
    out = np.empty(len(points), dtype=np.int64)
    out[rows[first]] = face[first]
    w = np.zeros((len(points), 3))
    w[rows[first]] = weights[first]
    d = np.full(len(points), np.inf)
    d[rows[first]] = distance[first]
    return out, w, d


def face_normals(x: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``(f, 3)`` unit normals of the triangles (right-hand rule: outward for exterior
    faces)."""
    n = np.cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(norm > 0, norm, 1.0)
