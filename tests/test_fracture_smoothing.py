"""Stress smoothing operators and principal stresses (fem_frac.fracture.smoothing)."""

from __future__ import annotations

from itertools import combinations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from fem_frac.errors import SolverError
from fem_frac.fem.tensors import mandel_from_matrix, principal, principal_values
from fem_frac.fracture import face_adjacency, fragments, open_crack
from fem_frac.fracture.smoothing import (
    centroids,
    mean_edge_length,
    principal_stress,
    smooth,
    smoothing_operator,
)
from fem_frac.mesh import tet_volumes
from fem_frac.mesh.mesh import TET_FACES
from meshes import structured_box

# Row sums and means of a few hundred terms of size <= 1: round-off is a few ulps times the
# number of terms per row (<= m = 216 here), so 1e-13 is a safe bound with room to spare.
ROUND = 1e-13

KINDS = [
    ("neighbours", {"rings": 1}),
    ("neighbours", {"rings": 3}),
    ("neighbours", {"length": 0.3}),
    ("neighbours", {"length": 10.0}),
    ("nodal", {"rings": 1}),
    ("nodal", {"rings": 2}),
    ("nodal", {"length": 0.6}),
]


@pytest.fixture(scope="module")
def box():
    return structured_box((4, 3, 3), distortion=0.2, seed=1)


@pytest.fixture(scope="module")
def cracked():
    """The box cut in two along the full vertex plane x = 0.5: ``(old, new, labels)``."""
    old = structured_box((4, 3, 3))
    plane = np.nonzero(np.abs(old.points[:, 0] - 0.5) < 1e-12)[0]
    assert len(plane) == 16
    new, _ = open_crack(old, plane, np.tile([1.0, 0.0, 0.0], (len(plane), 1)))
    n, labels = fragments(new.tets)
    assert n == 2
    return old, new, labels


def _pairs(s):
    c = s.tocoo()
    return c.row, c.col


@pytest.mark.parametrize(("method", "kw"), KINDS)
def test_rows_sum_to_one_and_uniform_field_kept(box, method, kw):
    s = smoothing_operator(box.points, box.tets, method=method, **kw)
    m = box.n_tets
    assert s.shape == (m, m) and s.format == "csr"
    assert np.all(s.data >= 0.0)
    np.testing.assert_allclose(np.asarray(s.sum(axis=1)).ravel(), 1.0, rtol=0, atol=ROUND)
    assert np.all(s.diagonal() > 0)  # the element itself always contributes
    const = np.array([3.0, -1.0, 2.0, 0.5, -0.25, 1.5])
    field = np.tile(const[:, None], (1, m))
    out = smooth(s, field)
    assert out.shape == (6, m)
    np.testing.assert_allclose(out, field, rtol=0, atol=ROUND * np.abs(const).max())


@pytest.mark.parametrize("method", ["neighbours", "nodal"])
def test_zero_rings_is_identity(box, method):
    s = smoothing_operator(box.points, box.tets, rings=0, method=method)
    assert s.nnz == box.n_tets
    np.testing.assert_array_equal(s.toarray(), np.eye(box.n_tets))


def test_neighbours_volume_weighted_by_hand(box):
    """Row of one element against face neighbours found by brute force (vertex sets)."""
    s = smoothing_operator(box.points, box.tets, rings=1).toarray()
    vol = tet_volumes(box.points, box.tets)
    assert np.ptp(vol) > 0.1 * vol.mean()  # distorted: the weights really differ
    faces = [set(map(frozenset, t[TET_FACES].tolist())) for t in box.tets]
    for i in (0, 57, 131):
        hood = [j for j in range(box.n_tets) if j == i or faces[i] & faces[j]]
        assert 2 <= len(hood) <= 5
        want = np.zeros(box.n_tets)
        want[hood] = vol[hood] / vol[hood].sum()
        np.testing.assert_allclose(s[i], want, rtol=1e-14, atol=0)


def test_nodal_by_hand(box):
    """S[i, j] = 1/4 sum over vertices v of i held by j of V_j / (volume around v)."""
    s = smoothing_operator(box.points, box.tets, rings=1, method="nodal").toarray()
    vol = tet_volumes(box.points, box.tets)
    for i in (3, 100):
        want = np.zeros(box.n_tets)
        for v in box.tets[i]:
            holders = np.nonzero(np.any(box.tets == v, axis=1))[0]
            want[holders] += 0.25 * vol[holders] / vol[holders].sum()
        np.testing.assert_allclose(s[i], want, rtol=1e-14, atol=0)


def test_length_neighbourhoods(box):
    c = centroids(box.points, box.tets)
    lengths = [0.15, 0.25, 0.4, 0.7, 2.0]
    previous = None
    for length in lengths:
        s = smoothing_operator(box.points, box.tets, length=length)
        i, j = _pairs(s)
        # the operator used np.linalg.norm on the same centroids; the 1e-12 relative slack
        # only covers a different summation order of three squares
        assert np.all(np.linalg.norm(c[i] - c[j], axis=1) <= length * (1 + 1e-12))
        pattern = s.toarray() > 0
        if previous is not None:
            assert np.all(pattern[previous])  # a longer length never loses a neighbour
            assert pattern.sum() > previous.sum()  # (and these lengths really add some)
        previous = pattern
    # the whole (connected) box is within 2.0 of every centroid: everyone sees everyone
    assert previous.all()
    # below the smallest centroid distance: nothing but the element itself
    d = np.linalg.norm(c[:, None] - c[None], axis=2)
    d_min = d[~np.eye(len(c), dtype=bool)].min()
    s = smoothing_operator(box.points, box.tets, length=0.99 * d_min)
    np.testing.assert_array_equal(s.toarray(), np.eye(box.n_tets))


def test_length_follows_face_paths():
    """A U-shaped slab: the tops of the two arms are within ``length`` of each other, but
    the face path between them runs down through the bridge, out of the ball, so they do
    not see each other. Checked against a per-element search restricted to the ball."""
    box = structured_box((3, 3, 1), lengths=(3.0, 3.0, 1.0))
    c = centroids(box.points, box.tets)
    keep = ~((c[:, 0] > 1.0) & (c[:, 0] < 2.0) & (c[:, 1] > 1.0))  # cut the notch
    tets = box.tets[keep]
    c = c[keep]
    length = 1.9
    s = smoothing_operator(box.points, tets, length=length)
    want, d = _ball_components(tets, c, length)
    np.testing.assert_array_equal(s.toarray() > 0, want)
    assert np.any(want != (d <= length))  # some in-ball tets are really cut off


def _ball_components(tets, c, length):
    """``(pattern (m, m), distances)``: for each tet, the tets of the face-connected part
    of its ball (centroids within ``length``) that holds it, by a search per element."""
    d = np.linalg.norm(c[:, None] - c[None], axis=2)
    adj = face_adjacency(tets)
    want = np.zeros_like(d, dtype=bool)
    for i in range(len(tets)):
        ball = np.nonzero(d[i] <= length)[0]
        _, comp = connected_components(adj[ball][:, ball], directed=False)
        want[i, ball[comp == comp[ball == i]]] = True
    return want, d


@pytest.mark.parametrize("length", [0.2, 0.35, 0.6])
def test_length_neighbourhoods_on_a_cracked_distorted_box(length):
    """The ring-by-ring search (only the last two rings looked up) against a search per
    element, on a distorted box with a crack through part of it (paths around its front)."""
    box = structured_box((5, 4, 3), distortion=0.2, seed=3)
    c0 = centroids(box.points, box.tets)
    vertices = np.flatnonzero((np.abs(box.points[:, 0] - 0.4) < 0.11)
                              & (box.points[:, 1] < 0.5))
    new, _ = open_crack(box, vertices, np.tile([1.0, 0.0, 0.0], (vertices.size, 1)))
    c = centroids(new.points, new.tets)
    np.testing.assert_array_equal(c, c0)  # a crack moves no tet
    s = smoothing_operator(new.points, new.tets, length=length)
    want, d = _ball_components(new.tets, c, length)
    np.testing.assert_array_equal(s.toarray() > 0, want)
    assert np.any(want != (d <= length))  # the crack cuts some neighbourhoods


@pytest.mark.parametrize(
    ("method", "kw"),
    [
        ("neighbours", {"rings": 4}),
        ("neighbours", {"length": 10.0}),
        ("nodal", {"rings": 3}),
        ("nodal", {"length": 1.0}),
    ],
)
def test_no_smoothing_across_crack(cracked, method, kw):
    old, new, labels = cracked
    s = smoothing_operator(new.points, new.tets, method=method, **kw)
    i, j = _pairs(s)
    assert np.all(labels[i] == labels[j])
    np.testing.assert_allclose(np.asarray(s.sum(axis=1)).ravel(), 1.0, rtol=0, atol=ROUND)
    # not vacuous: on the uncut mesh the same operator couples the two halves
    s_old = smoothing_operator(old.points, old.tets, method=method, **kw)
    i, j = _pairs(s_old)
    assert np.any(labels[i] != labels[j])
    if kw.get("length") == 10.0:
        # within each fragment everyone sees everyone
        same = labels[:, None] == labels[None]
        np.testing.assert_array_equal(s.toarray() > 0, same)


@pytest.mark.parametrize(("method", "kw"), KINDS)
def test_linear_field(box, method, kw):
    """Element averages of a linear stress field are its values at the centroids; S keeps
    the affine structure exactly: S f(c) = f(S c), f evaluated at the smoothed centroids.
    For "neighbours" with ``length`` every weight sits within ``length`` of the centroid,
    so |S f(c) - f(c)| <= |grad f| length (a convex combination of points in the ball)."""
    rng = np.random.default_rng(3)
    grad = rng.normal(size=(6, 3))
    f0 = rng.normal(size=(6, 1))
    c = centroids(box.points, box.tets)
    s = smoothing_operator(box.points, box.tets, method=method, **kw)
    exact = f0 + grad @ c.T
    out = smooth(s, exact)
    scale = np.abs(exact).max()
    np.testing.assert_allclose(out, f0 + grad @ (s @ c).T, rtol=0, atol=ROUND * scale)
    if method == "neighbours" and "length" in kw:
        bound = np.linalg.norm(grad, axis=1)[:, None] * kw["length"]
        assert np.all(np.abs(out - exact) <= bound * (1 + 1e-12))


@pytest.mark.parametrize("distortion", [0.0, 0.3])
def test_linear_field_whole_fragment(cracked, distortion):
    """A length taking in a whole fragment gives every element the volume-weighted mean of
    the fragment's tet centroids, which is the fragment's own centroid (first moments add
    up over the tets, on any mesh), so a linear field is smoothed to its value there."""
    _, new, labels = cracked
    points = new.points.copy()
    if distortion:
        rng = np.random.default_rng(5)
        inner = np.all((points > 1e-12) & (points < 1 - 1e-12), axis=1)
        inner &= np.abs(points[:, 0] - 0.5) > 1e-12  # keep the crack plane flat
        points[inner] += distortion * 0.25 * rng.uniform(-1, 1, (inner.sum(), 3))
    s = smoothing_operator(points, new.tets, length=10.0)
    grad = np.arange(18.0).reshape(6, 3) - 8.0
    c = centroids(points, new.tets)
    vol = tet_volumes(points, new.tets)
    assert np.all(vol > 0)
    out = smooth(s, grad @ c.T)
    for k in range(2):
        own = labels == k
        centre = (vol[own] @ c[own]) / vol[own].sum()
        want = np.tile((grad @ centre)[:, None], (1, own.sum()))
        np.testing.assert_allclose(out[:, own], want, rtol=0, atol=ROUND * np.abs(grad).sum())
    # undistorted: the halves [0, 0.5] x [0, 1]^2 and [0.5, 1] x [0, 1]^2
    if not distortion:
        left = labels[np.argmin(c[:, 0])]
        np.testing.assert_allclose(
            out[:, labels == left][:, 0], grad @ [0.25, 0.5, 0.5], rtol=0, atol=1e-13 * 50
        )


def test_nodal_length_to_applications(box):
    h = mean_edge_length(box.points, box.tets)
    one = smoothing_operator(box.points, box.tets, rings=1, method="nodal")
    two = smoothing_operator(box.points, box.tets, rings=2, method="nodal")
    for length, want in [(0.1 * h, one), (0.99 * h, one), (1.5 * h, two)]:
        s = smoothing_operator(box.points, box.tets, length=length, method="nodal")
        np.testing.assert_allclose(s.toarray(), want.toarray(), rtol=0, atol=1e-15)


def test_mean_edge_length(box):
    edges = {
        tuple(sorted((t[i], t[j]))) for t in box.tets.tolist() for i, j in combinations(range(4), 2)
    }
    want = np.mean([np.linalg.norm(box.points[a] - box.points[b]) for a, b in edges])
    assert mean_edge_length(box.points, box.tets) == pytest.approx(want, rel=1e-14)


@pytest.mark.parametrize(
    "kw",
    [
        {},
        {"length": 1.0, "rings": 1},
        {"length": 0.0},
        {"length": -1.0},
        {"rings": -1},
        {"rings": 1.5},
        {"rings": 1, "method": "gauss"},
    ],
)
def test_bad_arguments(box, kw):
    with pytest.raises(ValueError):
        smoothing_operator(box.points, box.tets, **kw)


# --------------------------------------------------------------------------- principal


def _random_symmetric(rng, m):
    a = rng.normal(size=(3, 3, m))
    return 0.5 * (a + a.transpose(1, 0, 2))


def test_principal_stress_random():
    rng = np.random.default_rng(0)
    a = _random_symmetric(rng, 200)
    s1, d = principal_stress(mandel_from_matrix(a))
    mats = np.moveaxis(a, -1, 0)
    # eigh vs eigvalsh on O(1) matrices: both backward stable, agree to a few ulps
    np.testing.assert_allclose(s1, np.linalg.eigvalsh(mats)[:, -1], rtol=0, atol=1e-13)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=0, atol=1e-14)
    residual = np.einsum("mij,mj->mi", mats, d) - s1[:, None] * d
    assert np.abs(residual).max() < 1e-13


def test_principal_stress_is_the_largest_of_principal():
    """One eigen-decomposition (fem.tensors.principal) behind the fracture criterion and the
    output field (principal_values, eigvalsh of the same matrices: a few ulps apart)."""
    rng = np.random.default_rng(3)
    m = mandel_from_matrix(_random_symmetric(rng, 50).reshape(3, 3, 10, 5))
    values, vectors = principal(m)
    assert values.shape == (10, 5, 3) and vectors.shape == (10, 5, 3, 3)
    s1, d = principal_stress(m)
    np.testing.assert_array_equal(s1, values[..., -1])
    np.testing.assert_array_equal(np.abs(d), np.abs(vectors[..., -1]))
    np.testing.assert_allclose(principal_values(m), np.moveaxis(values, -1, 0), rtol=0,
                               atol=1e-13)


def test_the_bound_of_the_largest_value_holds_and_is_sharp():
    """fem.tensors.largest_value_bound is at least the eigen-decomposition's largest value
    of every tensor, including the uniaxial ones where p + sqrt(2/3)|dev| equals it (in
    random frames, with offsets and scales over decades), and it is that value there to
    its slack (1e-12 of the tensor's size)."""
    from fem_frac.fem.tensors import largest_value_bound

    rng = np.random.default_rng(12)
    a = _random_symmetric(rng, 400) * 10.0 ** rng.uniform(-6, 9, 400)
    q = np.linalg.qr(rng.normal(size=(400, 3, 3)))[0]
    n = q[:, :, 0]
    size = 10.0 ** rng.uniform(-6, 9, 400)
    uniaxial = np.moveaxis(size[:, None, None] * np.einsum("ki,kj->kij", n, n), 0, -1)
    for mats in (a, uniaxial, uniaxial - 0.3 * size * np.eye(3)[:, :, None]):
        m = mandel_from_matrix(mats)
        value = principal(m)[0][..., -1]
        bound = largest_value_bound(m)
        assert np.all(bound >= value)
    # the uniaxial ones: the bound is the value to its slack and round-off
    m = mandel_from_matrix(uniaxial)
    gap = largest_value_bound(m) - principal(m)[0][..., -1]
    assert np.all(gap <= 2e-12 * size)


def test_principal_stress_rotated_uniaxial():
    """sigma = 5 n n^T - 1 (I - n n^T) in a random frame: sigma1 = 5 along n. The gap 6
    between the eigenvalues makes the direction well conditioned (error ~ eps |A| / gap)."""
    rng = np.random.default_rng(7)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    n = q[:, 0]
    a = 5.0 * np.outer(n, n) - (np.eye(3) - np.outer(n, n))
    s1, d = principal_stress(mandel_from_matrix(a[:, :, None]))
    np.testing.assert_allclose(s1, [5.0], rtol=0, atol=1e-12)
    k = np.argmax(np.abs(n))
    n_oriented = n * np.sign(n[k])
    np.testing.assert_allclose(d[0], n_oriented, rtol=0, atol=1e-12)


def test_principal_direction_orientation():
    rng = np.random.default_rng(11)
    a = _random_symmetric(rng, 100)
    m = mandel_from_matrix(a)
    s1, d = principal_stress(m)
    big = np.take_along_axis(d, np.argmax(np.abs(d), axis=1)[:, None], axis=1)
    assert np.all(big > 0)
    s1b, db = principal_stress(m.copy())
    np.testing.assert_array_equal(s1, s1b)
    np.testing.assert_array_equal(d, db)
    # scaling by a positive factor keeps the oriented direction (eigenvector round-off
    # ~ eps |A| / gap; the random gaps here are >> 1e-5, so 1e-10 is generous)
    _, dc = principal_stress(3.0 * m)
    np.testing.assert_allclose(dc, d, rtol=0, atol=1e-10)
    # a single (6,) tensor is accepted too; same LAPACK routine, agreement to round-off
    s0, d0 = principal_stress(m[:, 0])
    assert np.shape(s0) == () and d0.shape == (3,)
    np.testing.assert_allclose(d0, d[0], rtol=0, atol=1e-14)


def test_largest_principal_closed_form():
    """The closed form against eigh: the value to a few ulps of the tensor's size where
    the largest value stands apart or is repeated exactly, to sqrt(eps) of it where the top
    two nearly coincide (the cubic's phase where arccos is ill-conditioned); the vector an
    eigenvector; repeated and all-equal values included."""
    from fem_frac.fem.tensors import largest_principal

    rng = np.random.default_rng(5)
    a = _random_symmetric(rng, 2000) * 10.0 ** rng.uniform(-3, 9, size=2000)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    a[:, :, 0] = 0.0  # zero
    a[:, :, 1] = 7.0 * np.eye(3)  # all three equal
    a[:, :, 2] = q @ np.diag([2.0, 2.0, -1.0]) @ q.T  # the largest repeated
    a[:, :, 3] = q @ np.diag([3.0, 1.0, 1.0]) @ q.T  # the smallest repeated
    a[:, :, 4] = q @ np.diag([1e8, 1.0 + 1e8, 1e8]) @ q.T  # tiny gaps on a large shift
    m = mandel_from_matrix(a)
    value, vector = largest_principal(m)
    mats = np.moveaxis(a, -1, 0)
    exact = np.linalg.eigvalsh(mats)[:, -1]
    size = np.linalg.norm(mats, axis=(1, 2))
    assert np.all(np.abs(value - exact) <= 1e-14 * size + 1e-300)
    np.testing.assert_allclose(np.linalg.norm(vector, axis=1), 1.0, rtol=0, atol=1e-14)
    residual = np.linalg.norm(np.einsum("mij,mj->mi", mats, vector) - value[:, None] * vector,
                              axis=1)
    assert np.all(residual[5:] <= 1e-13 * size[5:])
    np.testing.assert_array_equal(vector[1], [0.0, 0.0, 1.0])
    # a repeated largest value: a vector of its eigenspace (orthogonal to the third)
    assert abs(vector[2] @ q[:, 2]) < 1e-12
    # the top two nearly coincide: within sqrt(eps) of the size, not a few ulps
    gaps = np.repeat(10.0 ** np.arange(-10.0, -5.0, 0.5), 200)
    qs, _ = np.linalg.qr(rng.normal(size=(gaps.size, 3, 3)))
    near = np.einsum("nij,nj,nkj->nik", qs, np.stack(
        [np.ones_like(gaps), 1.0 - gaps, -np.ones_like(gaps)], axis=1), qs)
    value, _ = largest_principal(mandel_from_matrix(np.moveaxis(near, 0, -1)))
    error = np.abs(value - np.linalg.eigvalsh(near)[:, -1])
    size = np.linalg.norm(near, axis=(1, 2))
    assert np.all(error <= np.sqrt(np.finfo(float).eps) * size)
    assert error.max() > 1e3 * np.finfo(float).eps  # not a few ulps there


def test_largest_values_within_ulps_of_lapack_at_any_gap():
    """The output's largest principal stress (fem.tensors.largest_values) against eigvalsh,
    with the top two values apart by 1e-16 to 1 of the size: LAPACK's bits where they
    nearly coincide (1 + r < NEAR_DOUBLE), elsewhere the closed form, whose error is
    ``2 p sin(phi) dphi`` with ``dphi = dr / (3 sqrt(1 - r^2))``, ``dr`` a few tens of
    ulps: at most ~100 ulps of the size there. Without the fallback the error reaches
    ~sqrt(eps) of the size."""
    from fem_frac.fem.tensors import largest_value, largest_values

    rng = np.random.default_rng(12)
    n = 20000
    qs, _ = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    top = rng.uniform(0.2, 1.0, n)
    second = top - 10.0 ** rng.uniform(-16, 0, n)
    third = np.minimum(rng.uniform(-1.0, 1.0, n), second)
    mats = np.einsum("nij,nj,nkj->nik", qs, np.stack([third, second, top], axis=1), qs)
    mats = 0.5 * (mats + np.swapaxes(mats, 1, 2)) * 10.0 ** rng.uniform(-3, 9, (n, 1, 1))
    mats[0], mats[1] = 0.0, 7.0 * np.eye(3)  # zero, all three equal
    m = mandel_from_matrix(np.moveaxis(mats, 0, -1)).reshape(6, 100, 200)
    exact = np.linalg.eigvalsh(mats)[:, -1].reshape(100, 200)
    size = np.linalg.norm(mats, axis=(1, 2)).reshape(100, 200)
    eps = np.finfo(float).eps
    value = largest_values(m)
    assert value.shape == (100, 200)
    assert np.all(np.abs(value - exact) <= 100 * eps * size)
    # not vacuous: the closed form alone is far off where the top two nearly coincide
    off = np.abs(largest_value(m) - exact)[size > 0] / size[size > 0]
    assert off.max() > 1e4 * eps


def test_principal_stress_exact_above_a_strength():
    """With ``exact_above`` the tensors that may exceed it are eigh's to the bit (a crack
    criterion decides on them as before), the other values within round-off and their
    directions not computed (NaN); non-finite stresses still fail in eigh."""
    from fem_frac.fracture.smoothing import _mostly_below

    rng = np.random.default_rng(9)
    m = mandel_from_matrix(_random_symmetric(rng, 5000)) * 1e6
    s1, d = principal_stress(m)
    strength = np.quantile(s1, 0.97)
    assert _mostly_below(m, strength)  # the closed form's path
    t1, e = principal_stress(m, exact_above=strength)
    over = s1 >= strength * (1 - 1e-12)
    np.testing.assert_array_equal(t1[over], s1[over])
    np.testing.assert_array_equal(e[over], d[over])
    assert np.all(t1[~over] < strength)
    np.testing.assert_allclose(t1, s1, rtol=0, atol=1e-14 * np.abs(m).max())
    computed = np.all(np.isfinite(e), axis=1)
    assert np.all(computed[over]) and 0 < np.count_nonzero(computed) < 0.1 * computed.size
    np.testing.assert_array_equal(e[computed], d[computed])
    assert np.all(np.isnan(e[~computed]))
    # where most tensors may exceed the level, eigh throughout
    assert not _mostly_below(m, np.quantile(s1, 0.3))
    m[0, 3] = np.nan
    with pytest.raises(SolverError):
        principal_stress(m, exact_above=strength)


def test_principal_stress_exact_above_with_the_largest_value_nearly_repeated():
    """sigma1 ~ sigma2 > sigma3 (equibiaxial tension): the closed form's phase sits where
    acos is ill-conditioned, and its value is off by up to ~sqrt(eps) of the tensor's size.
    The tensors whose eigh value reaches the strength still go through eigh: the margin
    covers that error."""
    rng = np.random.default_rng(11)
    n, strength = 4000, 3e6
    q, _ = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    # the top pair 1e-8 to 5e-8 of the size apart, where the closed form is lowest (by
    # up to ~1.6e-8 of the size), straddling the strength by up to 3e-8 of the size
    size = 1e8
    top = strength + size * rng.uniform(-3e-8, 3e-8, size=n)
    values = np.stack([top, top - size * rng.uniform(1e-8, 5e-8, size=n),
                       np.full(n, -size)], axis=1)
    mats = np.einsum("nij,nj,nkj->nik", q, values, q)
    m = mandel_from_matrix(np.moveaxis(mats, 0, -1))
    m = np.concatenate([m, np.zeros((6, 4 * n))], axis=1)  # mostly below: the closed form
    s1, _ = principal_stress(m)
    t1, _ = principal_stress(m, exact_above=strength)
    over = s1 >= strength
    assert 0.3 * n < np.count_nonzero(over) < 0.7 * n
    np.testing.assert_array_equal(t1[over], s1[over])


@pytest.mark.parametrize("size,block", [({"length": 0.45}, None), ({"length": 0.45}, 7),
                                        ({"rings": 2}, None)])
def test_update_after_a_crack_equals_a_rebuild(size, block, monkeypatch):
    """The operator updated near the split vertices is the one built afresh on the cracked
    mesh, entry for entry (rows far from the crack cannot see it); also with the table of
    (row, tet) pairs looked up a few rows at a time (``block``: entries per block)."""
    import fem_frac.fracture.smoothing as smoothing
    from fem_frac.fracture.smoothing import update_operator

    if block is not None:
        monkeypatch.setattr(smoothing, "PAIR_BLOCK", block)

    mesh = structured_box((6, 3, 3), lengths=(2.0, 1.0, 1.0), distortion=0.1, seed=2)
    before = smoothing_operator(mesh.points, mesh.tets, **size)
    pick = np.flatnonzero(np.abs(mesh.points[:, 0] - 1.0) < 0.2)[:3]
    new, _ = open_crack(mesh, pick, np.tile([1.0, 0.2, 0.0], (len(pick), 1)))
    assert new.n_points > mesh.n_points
    fresh = smoothing_operator(new.points, new.tets, **size)
    updated = update_operator(before, new.points, new.tets, mesh.points[pick], **size)
    assert (fresh != before).nnz > 0  # the crack did change some neighbourhoods
    # to the bit: the same pattern, sorted, and the same sums of the same volumes
    for a in ("indptr", "indices", "data"):
        np.testing.assert_array_equal(getattr(updated, a), getattr(fresh, a))
    # a second batch on the updated operator, along x = 1
    plane = np.flatnonzero(np.abs(new.points[:, 0] - 1.0) < 1e-9)
    cut, _ = open_crack(new, plane, np.tile([1.0, 0.0, 0.0], (len(plane), 1)))
    again = update_operator(updated, cut.points, cut.tets, new.points[plane], **size)
    fresh = smoothing_operator(cut.points, cut.tets, **size)
    for a in ("indptr", "indices", "data"):
        np.testing.assert_array_equal(getattr(again, a), getattr(fresh, a))


@pytest.mark.parametrize("rows", [[0], [9], [0, 1, 2], [3, 4, 8, 9], list(range(10))])
def test_replace_rows_against_dense(rows):
    """Rows replaced where they start, end, touch each other or are all of them, by random
    fresh rows (every third one empty): the dense result, rows sorted, the other rows as
    they were (their arrays' entries, to the bit)."""
    from fem_frac.fracture.smoothing import _replace_rows

    rng = np.random.default_rng(len(rows))
    old = sp.random(10, 12, density=0.4, format="csr", random_state=rng)
    old.sort_indices()
    rows = np.asarray(rows)
    fresh = sp.random(rows.size, 12, density=0.5, format="csr", random_state=rng)
    fresh = sp.csr_matrix(fresh.toarray() * (np.arange(rows.size) % 3 != 1)[:, None])
    expected = old.toarray()
    expected[rows] = fresh.toarray()
    out = _replace_rows(old, rows, fresh)
    np.testing.assert_array_equal(out.toarray(), expected)
    assert out.has_sorted_indices
    assert all(np.all(np.diff(out.indices[out.indptr[r]:out.indptr[r + 1]]) > 0)
               for r in range(10))
    for r in sorted(set(range(10)) - set(rows.tolist())):
        a, b = old.indptr[r:r + 2]
        c, d = out.indptr[r:r + 2]
        np.testing.assert_array_equal(out.indices[c:d], old.indices[a:b])
        np.testing.assert_array_equal(out.data[c:d], old.data[a:b])
    assert _replace_rows(old, np.zeros(0, dtype=np.int64), fresh[:0]) is old


def test_a_brittle_fracture_run_does_not_import_scipy_spatial(tmp_path):
    """The operator's update finds the split corners by their coordinates' bytes (a copy
    has its vertex's to the bit), so a run that opens cracks but has no rigid pieces does
    not pay for scipy.spatial's import (0.13 s under ``python -X importtime``, mostly
    scipy.special)."""
    import subprocess
    import sys
    from pathlib import Path

    case = Path(__file__).parent.parent / "cases" / "bar_tension_break.yaml"
    code = ("import sys; from fem_frac.app.cli import main; "
            f"assert main(['run', {str(case)!r}, '-o', {str(tmp_path / 'out')!r}, '-q']) "
            "== 0; assert 'scipy.spatial' not in sys.modules, 'scipy.spatial imported'")
    subprocess.run([sys.executable, "-c", code], check=True)
