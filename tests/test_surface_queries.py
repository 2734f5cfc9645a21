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


def _ericson_by_region(p, a, b, c):
    """The closest-point weights as they were first computed (one einsum per dot product,
    each region's weights stacked for all rows and assigned on its own, in the reverse of
    Ericson's order): the bits :func:`closest_on_triangles` must keep."""
    ab, ac, ap, bp, cp = b - a, c - a, p - a, p - b, p - c

    def dot(u, v):
        return np.einsum("ij,ij->i", u, v)

    d1, d2, d3, d4, d5, d6 = dot(ab, ap), dot(ac, ap), dot(ab, bp), dot(ac, bp), \
        dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        total = va + vb + vc
        v, w = vb / total, vc / total
        out = np.stack([1.0 - v - w, v, w], axis=1)
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


def _triangle_queries(m: int, rng):
    """``(p, a, b, c)``, ``m`` rows: general triangles and degenerate ones (a corner
    repeated, collinear, a point), at scales 1e-9 to 1e9, on a coarse grid (exact ties);
    points anywhere, on corners, on edges, on the face, with signed zeros."""
    a, b, c, p = (rng.standard_normal((m, 3)) for _ in range(4))
    kind = rng.integers(0, 5, m)
    b[kind == 1] = a[kind == 1]
    c[kind == 2] = a[kind == 2] + rng.uniform(-2, 2, (np.count_nonzero(kind == 2), 1)) \
        * (b[kind == 2] - a[kind == 2])
    b[kind == 3] = c[kind == 3] = a[kind == 3]
    grid = rng.random(m) < 0.3
    for x in (a, b, c, p):
        x[grid] = np.round(x[grid] * 2) / 2
    s = rng.uniform(0.0, 1.0, (m, 2)) * rng.integers(0, 2, (m, 2))
    where = rng.integers(0, 6, m)
    on = [a, b, c, a + s[:, :1] * (b - a), b + s[:, 1:] * (c - b),
          a + s[:, :1] * (b - a) + s[:, 1:] * (c - a)]
    for k in range(5):
        p[where == k] = on[k][where == k]
    scale = 10.0 ** rng.choice([-9, 0, 0, 0, 9], (m, 1))
    a, b, c, p = (x * scale for x in (a, b, c, p))
    zero = rng.random((4, m, 3)) < 0.15
    for x, z in zip((p, a, b, c), zero, strict=True):
        x[z] = rng.choice([0.0, -0.0], np.count_nonzero(z))
    return p, a, b, c


@pytest.mark.parametrize("m", [0, 1, 2, 7, 64, 500, 5000])
def test_closest_on_triangles_keeps_the_bits_of_the_region_by_region_weights(m):
    """Bit for bit (the sign of zero and NaN of degenerate triangles included) against the
    first implementation, on random and degenerate triangles and points on their
    features."""
    for seed in range(20 if m < 500 else 3):
        p, a, b, c = _triangle_queries(m, np.random.default_rng(1000 * m + seed))
        got = closest_on_triangles(p, a, b, c)
        want = _ericson_by_region(p, a, b, c)
        assert got.shape == want.shape == (m, 3)
        np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))


def test_the_triangle_queries_reach_every_region_and_the_odd_bits():
    """The inputs above are worth the test: every region, negative zeros and NaNs."""
    p, a, b, c = _triangle_queries(5000, np.random.default_rng(0))
    w = _ericson_by_region(p, a, b, c)
    assert np.count_nonzero(np.signbit(w) & (w == 0.0)) > 10
    assert np.count_nonzero(np.isnan(w).any(axis=1)) > 10
    exact = np.isfinite(w).all(axis=1)
    patterns = {tuple(r) for r in (w[exact] == 0.0)}
    assert {(False, True, True), (True, False, True), (True, True, False),
            (False, False, True), (False, True, False), (True, False, False),
            (False, False, False)} <= patterns
