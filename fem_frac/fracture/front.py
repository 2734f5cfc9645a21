"""The front of a mesh's cracks, where cohesive cracks grow (DESIGN §2).

A crack face is counted once: its two sides (triangles of the ``crack`` group) sit on the
same reference positions, so vertices are identified by position. A front edge is a pair of
positions used by exactly one crack face that is not an edge of the body's exterior surface
outside the crack (an exterior triangle that is not a crack face); every vertex, every copy,
at a position of a front edge is on the front. A crack that has reached the surface all
round (a through crack) has no front.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..fem.tensors import matrices_from_mandel
from ..mesh.crack import CRACK, crack_faces
from ..mesh.mesh import TET_FACES, Mesh, edge_keys, exterior_face_rows, facet_keys

_TRIANGLE_EDGES = np.array([[0, 1], [1, 2], [0, 2]])


def _crack_triangles(mesh: Mesh) -> np.ndarray:
    return np.asarray(mesh.boundaries.get(CRACK, np.zeros((0, 3), dtype=np.int64)),
                      dtype=np.int64).reshape(-1, 3)


def positions(points: np.ndarray, vertices: np.ndarray) -> tuple[np.ndarray, int]:
    """``(place (n,), count)``: an id per reference position for every point at the position
    of one of ``vertices`` (and possibly a few more points), -1 for the rest."""
    ref = points[vertices]
    maybe = np.flatnonzero(np.isin(points[:, 0], ref[:, 0]) & np.isin(points[:, 1], ref[:, 1])
                           & np.isin(points[:, 2], ref[:, 2]))
    unique, inverse = np.unique(points[maybe], axis=0, return_inverse=True)
    place = np.full(points.shape[0], -1, dtype=np.int64)
    place[maybe] = inverse.ravel()
    return place, int(unique.shape[0])


def crack_front(mesh: Mesh) -> np.ndarray:
    """``(n_points,)`` bool: the vertices on the front of the mesh's cracks (module
    docstring)."""
    n = mesh.n_points
    tri = _crack_triangles(mesh)
    if len(tri) == 0:
        return np.zeros(n, dtype=bool)
    place, k = positions(np.asarray(mesh.points, dtype=float), np.unique(tri))
    faces = np.unique(np.sort(place[tri], axis=1), axis=0)  # each crack face once
    keys, count = np.unique(edge_keys(faces[:, _TRIANGLE_EDGES].reshape(-1, 2), k),
                            return_counts=True)
    single = keys[count == 1]
    tets = np.asarray(mesh.tets, dtype=np.int64)
    outer = tets[:, TET_FACES].reshape(-1, 3)[exterior_face_rows(tets, n)]
    outer = outer[~np.isin(facet_keys(outer, n), facet_keys(tri, n))]  # surface, not crack
    pairs = place[outer][:, _TRIANGLE_EDGES].reshape(-1, 2)
    pairs = pairs[np.all(pairs >= 0, axis=1)]
    single = single[~np.isin(single, edge_keys(pairs, k))]
    ends = np.unique(np.concatenate([single // k, single % k]))
    return np.isin(place, ends)


def near_marked(tets: np.ndarray, neighbourhood: sp.spmatrix, marked: np.ndarray) -> np.ndarray:
    """``(m,)`` bool: the tets that have a ``marked (n,)`` vertex or whose row of the
    ``neighbourhood (m, m)`` pattern lists a tet that has one."""
    has = np.asarray(marked, dtype=bool)[np.asarray(tets, dtype=np.int64)].any(axis=1)
    pattern = neighbourhood.tocsr()
    m = pattern.shape[0]
    row = np.repeat(np.arange(m), np.diff(pattern.indptr))
    return has | (np.bincount(row, weights=has[pattern.indices], minlength=m) > 0)


def near_crack(mesh: Mesh, neighbourhood: sp.spmatrix) -> np.ndarray:
    """``(m,)`` bool: the tets whose smoothing ``neighbourhood`` (the ``(m, m)`` pattern
    given to :func:`~fem_frac.fracture.sites.select_sites`) holds a tet with a vertex on a
    crack face: the cracks' process zones."""
    marked = np.zeros(mesh.n_points, dtype=bool)
    marked[_crack_triangles(mesh).ravel()] = True
    return near_marked(mesh.tets, neighbourhood, marked)


def front_normals(mesh: Mesh, front: np.ndarray) -> np.ndarray:
    """``(m, 3)``: for every tet with a vertex on a crack front, the unit normal of the crack
    there (the area-weighted mean normal of the crack faces at its front vertices, oriented
    as :func:`~fem_frac.mesh.crack.crack_faces` orients them); zero for the other tets."""
    faces = crack_faces(mesh)
    weighted = np.zeros((mesh.n_points, 3))
    if len(faces):
        p = mesh.points[faces.a]
        area_normal = 0.5 * np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        area_normal *= np.sign(np.einsum("ki,ki->k", area_normal, faces.normal))[:, None]
        for side in (faces.a, faces.b):
            for i in range(3):
                np.add.at(weighted, side[:, i], area_normal)
    weighted[~front] = 0.0
    total = weighted[mesh.tets].sum(axis=1)
    size = np.linalg.norm(total, axis=1, keepdims=True)
    return np.divide(total, size, out=np.zeros_like(total), where=size > 0)


# A front goes on in its plane while the normal stress on that plane is at least this
# fraction of the largest principal stress: cos^2(30 deg), the normal stress on a plane 30
# deg off the principal one under uniaxial tension.
CONTINUE = 0.75


def continue_planes(directions: np.ndarray, smoothed: np.ndarray, sigma1: np.ndarray,
                    normals: np.ndarray) -> np.ndarray:
    """The crack normals ``(m, 3)`` sites use: where a tet touches a crack front
    (``normals`` non-zero) and the smoothed stress ``(6, m)`` (Mandel) pulls that crack's
    own plane apart by at least ``CONTINUE`` of the largest principal stress ``sigma1
    (m,)``, the crack goes on in its plane (its normal); elsewhere the principal
    ``directions`` (the crack kinks)."""
    n = normals
    sigma = matrices_from_mandel(smoothed)  # (m, 3, 3)
    traction = np.einsum("mi,mij,mj->m", n, sigma, n)
    keep = (np.linalg.norm(n, axis=1) > 0) & (traction >= CONTINUE * sigma1) & (sigma1 > 0)
    out = directions.copy()
    out[keep] = n[keep]
    return out
