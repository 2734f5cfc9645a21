"""The queries of points against a mesh's exterior and tets (:mod:`fem_frac.rigid.surface`)
against brute force: every point against every triangle, every point against every tet.
Far points, points on vertices and on a grid (exact ties at shared corners and edges), the
dense search of small sets and the tree search of large ones, and a :class:`Solid`'s kept
geometry against the same queries built afresh."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from fem_frac.mesh.mesh import exterior_facets
from fem_frac.rigid.surface import (
    closest_on_triangles,
    face_normals,
    inside_tets,
    locate_in_solid,
    nearest_faces,
    solid,
)
from tests.meshes import structured_box


def _points(x: np.ndarray, n: int, rng) -> np.ndarray:
    """``n`` points about the mesh ``x``: inside and around it, on its vertices, on a grid
    of its cells' corners (ties between faces), and far away (up to 100 times its size)."""
    lo, hi = x.min(axis=0), x.max(axis=0)
    p = rng.uniform(lo - 0.3, hi + 0.3, (n, 3))
    kind = rng.integers(0, 4, n)
    p[kind == 1] = x[rng.integers(0, len(x), np.count_nonzero(kind == 1))]
    p[kind == 2] = np.round(p[kind == 2] * 4) / 4
    p[kind == 3] *= rng.choice([3.0, 100.0], (np.count_nonzero(kind == 3), 1))
    return p


def _brute_nearest(p: np.ndarray, x: np.ndarray, faces: np.ndarray):
    """Every point against every triangle: the least distance, and of equal ones the face
    first in the centroids' cKDTree order (the tie-break kept from the pairs search)."""
    i, f = np.repeat(np.arange(len(p)), len(faces)), np.tile(np.arange(len(faces)), len(p))
    a, b, c = (x[faces[f, k]] for k in range(3))
    w = closest_on_triangles(p[i], a, b, c)
    d = np.linalg.norm(p[i] - (w[:, :1] * a + w[:, 1:2] * b + w[:, 2:] * c), axis=1)
    tree = cKDTree(x[faces].mean(axis=1))
    rank = np.empty(len(faces), dtype=np.int64)
    rank[tree.indices] = np.arange(len(faces))
    best = np.lexsort((rank[f], d, i))[:: len(faces)]
    return f[best], w[best], d[best]


def _brute_inside(p: np.ndarray, x: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Every point against every tet: barycentric coordinates all >= -1e-12."""
    corners = x[tets]
    edges = np.transpose(corners[:, 1:] - corners[:, :1], (0, 2, 1))
    local = np.einsum("eij,pej->pei", np.linalg.inv(edges), p[:, None] - corners[:, 0])
    bary = np.concatenate([1.0 - local.sum(axis=2, keepdims=True), local], axis=2)
    return np.any(np.all(bary >= -1e-12, axis=2), axis=1)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("n_points", [40, 2000])  # the dense search, then the tree's
def test_nearest_faces_and_inside_tets_are_those_of_brute_force(seed, n_points):
    rng = np.random.default_rng(seed)
    m = structured_box(tuple(rng.integers(2, 5, 3)), tuple(rng.uniform(0.3, 2.0, 3)),
                       distortion=0.3 * (seed % 2), seed=seed)
    x, tets = m.points, m.tets
    faces = exterior_facets(tets)
    p = _points(x, n_points, rng)
    face, weights, distance = nearest_faces(p, x, faces)
    want_face, want_weights, want_distance = _brute_nearest(p, x, faces)
    np.testing.assert_array_equal(distance, want_distance)
    np.testing.assert_array_equal(face, want_face)
    np.testing.assert_array_equal(weights, want_weights)
    inside = inside_tets(p, x, tets)
    np.testing.assert_array_equal(inside, _brute_inside(p, x, tets))
    assert 0 < np.count_nonzero(inside) < n_points


def test_a_far_point_leaves_the_near_points_answers_alone():
    """One point a thousand sizes away: the others find the same faces as without it."""
    m = structured_box((3, 3, 3), (1.0, 1.0, 1.0), distortion=0.2)
    faces = exterior_facets(m.tets)
    p = _points(m.points, 60, np.random.default_rng(7))
    alone = nearest_faces(p, m.points, faces)
    with_far = nearest_faces(np.vstack([p, [1e3, -2e3, 5e2]]), m.points, faces)
    for a, b in zip(alone, with_far, strict=True):
        np.testing.assert_array_equal(a, b[:-1])


def test_a_solid_keeps_its_geometry_and_answers_as_built_afresh():
    m = structured_box((3, 2, 2), (1.0, 0.6, 0.4), distortion=0.3, seed=3)
    shape = solid(m.points, m.tets)
    assert shape.face_cells is shape.face_cells and shape.tet_cells is shape.tet_cells
    np.testing.assert_array_equal(shape.normals, face_normals(shape.vertices, shape.faces))
    for seed in range(3):  # the kept geometry, used again
        p = _points(shape.vertices, 200, np.random.default_rng(seed))
        inside, face, weights, distance = locate_in_solid(p, shape)
        np.testing.assert_array_equal(inside, inside_tets(p, shape.vertices, shape.tets))
        for a, b in zip((face, weights, distance),
                        nearest_faces(p, shape.vertices, shape.faces), strict=True):
            np.testing.assert_array_equal(a, b)
