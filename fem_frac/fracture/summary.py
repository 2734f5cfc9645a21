"""Measures of the cracks of a mesh: opened faces and their area, the two sides of every
face and how far they have opened."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mesh.crack import CRACK, CrackFaces, crack_faces
from ..mesh.mesh import Mesh, edge_keys, match

__all__ = ["CrackFaces", "CrackMeasures", "crack_faces", "crack_measures", "crack_openings"]


@dataclass(frozen=True)
class CrackMeasures:
    """``faces``: interior faces opened so far (a face is two triangles of the ``crack``
    group, one per side, or one once the other side has left with a rigid piece);
    ``area``: their area in the reference configuration (each face once)."""

    faces: int
    area: float


def crack_measures(mesh: Mesh) -> CrackMeasures:
    tri = np.asarray(mesh.boundaries.get(CRACK, np.zeros((0, 3), dtype=np.int64)))
    if tri.size == 0:
        return CrackMeasures(0, 0.0)
    x = mesh.points[tri]
    # the two sides of a face sit on copies of the same three reference positions
    _, place = np.unique(x.reshape(-1, 3), axis=0, return_inverse=True)
    _, once = np.unique(np.sort(place.reshape(-1, 3), axis=1), axis=0, return_index=True)
    x = x[once]
    areas = 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)
    return CrackMeasures(len(once), float(areas.sum()))


def crack_openings(space, faces: CrackFaces, u: np.ndarray) -> np.ndarray:
    """The displacement jump ``u(b) - u(a)`` ``(k, 3)`` across every face of ``faces`` at its
    centroid. ``u (n_nodes, 3)``: nodal displacements of ``space`` (vertices first; P2: the
    edge mid-nodes after them)."""
    return _at_centroid(space, faces.b, u) - _at_centroid(space, faces.a, u)


def _at_centroid(space, tri: np.ndarray, u: np.ndarray) -> np.ndarray:
    """A field of ``space`` at the centroid of the mesh's triangles ``tri (k, 3)``: the mean
    of the corners (P1); P2: -1/9 of each corner and 4/9 of each edge mid-node."""
    corners = u[tri].sum(axis=1)
    if space.order == 1:
        return corners / 3.0
    n = space.mesh.n_points
    pairs = tri[:, [[0, 1], [1, 2], [0, 2]]].reshape(-1, 2)
    # scikit-fem numbers the mid-node of its edge e as n + e
    edge = match(edge_keys(np.asarray(space.skmesh.edges).T, n), edge_keys(pairs, n))
    mids = u[n + edge].reshape(-1, 3, 3).sum(axis=1)
    return (4.0 * mids - corners) / 9.0
