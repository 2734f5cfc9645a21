"""Where a batch of cracks opens (fem_frac.fracture.sites)."""

from __future__ import annotations

import numpy as np
import pytest

from fem_frac.fracture import fragments, open_crack
from fem_frac.fracture.sites import select_sites, splits, star, tilt, two_sided
from fem_frac.fracture.smoothing import smoothing_operator
from meshes import structured_box

STRENGTH = 1.0


def _uniform(mesh, value=2.0, direction=(1.0, 0.0, 0.0)):
    m = mesh.n_tets
    return np.full(m, value), np.tile(np.asarray(direction, float), (m, 1))


def _select(mesh, sigma1, direction, limit, on_crack=None, protected=None, rings=1):
    n = mesh.n_points
    s = smoothing_operator(mesh.points, mesh.tets, rings=rings)
    return select_sites(mesh.points, mesh.tets, sigma1, direction, STRENGTH, s,
                        np.zeros(n, bool) if on_crack is None else on_crack,
                        np.zeros(n, bool) if protected is None else protected, limit)


def test_nothing_below_the_strength():
    mesh = structured_box((4, 3, 3))
    sigma1, direction = _uniform(mesh, value=STRENGTH)  # equal is not above
    assert len(_select(mesh, sigma1, direction, 8)) == 0


def test_highest_stress_first_and_one_site_per_neighbourhood():
    mesh = structured_box((6, 3, 3), lengths=(2.0, 1.0, 1.0))
    rng = np.random.default_rng(1)
    sigma1 = 1.5 + rng.random(mesh.n_tets)
    _, direction = _uniform(mesh)
    s = smoothing_operator(mesh.points, mesh.tets, rings=1)
    sites = _select(mesh, sigma1, direction, 50)
    assert len(sites) > 1
    assert sites.elements[0] == np.argmax(sigma1)
    assert np.all(np.diff(sites.stress) <= 0)  # taken in decreasing stress
    # no chosen element lies in the neighbourhood of an earlier one
    for k, e in enumerate(sites.elements):
        earlier = sites.elements[:k]
        assert not np.any(s[earlier][:, [e]].toarray())
    assert len(set(sites.vertices.tolist())) == len(sites)  # a vertex at most once
    assert len(_select(mesh, sigma1, direction, 3)) == 3


def test_every_site_really_splits_and_protected_vertices_never_do():
    mesh = structured_box((6, 3, 3), lengths=(2.0, 1.0, 1.0), distortion=0.1)
    sigma1, direction = _uniform(mesh, direction=(1.0, 0.4, 0.2))
    direction /= np.linalg.norm(direction[0])
    protected = mesh.points[:, 0] < 1.0
    sites = _select(mesh, sigma1, direction, 100, protected=protected)
    assert len(sites) > 0 and not protected[sites.vertices].any()
    lookups = star(mesh.tets, mesh.n_points)
    c = mesh.points[mesh.tets].mean(axis=1)
    for v, n in zip(sites.vertices, sites.normals, strict=True):
        assert splits(mesh.points, mesh.tets, c, lookups, v, n)
    new, transfer = open_crack(mesh, sites.vertices, sites.normals)
    assert new.n_points > mesh.n_points


def _two_ways():
    """A distorted box, one crack direction for every tet, the first tet that at least two
    of its corners can split along it, those corners, and the one whose plane passes
    nearest the tet's centroid."""
    mesh = structured_box((4, 3, 3), distortion=0.1, seed=5)
    direction = np.tile(np.array([1.0, 0.5, 0.3]) / np.linalg.norm([1.0, 0.5, 0.3]),
                        (mesh.n_tets, 1))
    lookups = star(mesh.tets, mesh.n_points)
    c = mesh.points[mesh.tets].mean(axis=1)
    good = np.array([sum(splits(mesh.points, mesh.tets, c, lookups, v, direction[e])
                         for v in mesh.tets[e]) for e in range(mesh.n_tets)])
    e = int(np.flatnonzero(good >= 2)[0])
    candidates = [v for v in mesh.tets[e]
                  if splits(mesh.points, mesh.tets, c, lookups, v, direction[e])]
    distance = np.abs((mesh.points[candidates] - c[e]) @ direction[e])
    return mesh, direction, e, candidates, candidates[int(np.argmin(distance))]


def test_vertices_on_a_crack_are_preferred():
    """Of the vertices of the most stressed element whose planes split, the one closest to
    the element's plane is taken; marked as lying on a crack, another one wins."""
    mesh, direction, e, candidates, nearest = _two_ways()
    sigma1 = np.full(mesh.n_tets, 0.0)
    sigma1[e] = 2.0
    first = _select(mesh, sigma1, direction, 1)
    assert first.elements[0] == e
    assert first.vertices[0] == nearest
    other = next(v for v in candidates if v != first.vertices[0])
    on_crack = np.zeros(mesh.n_points, bool)
    on_crack[other] = True
    again = _select(mesh, sigma1, direction, 1, on_crack=on_crack)
    assert again.elements[0] == e and again.vertices[0] == other


def test_a_cohesive_crack_starts_at_the_most_stressed_vertex():
    """With ``peak_first`` (cohesive cracks), a new crack splits the vertex of the element
    whose tets are the most stressed on average, not the one nearest the plane through the
    centroid; without it (brittle) the nearest plane still decides."""
    mesh, direction, e, candidates, nearest = _two_ways()
    peak = next(v for v in candidates if v != nearest)
    # the tets around `peak` carry a stress just under the strength, the rest nothing
    sigma1 = np.zeros(mesh.n_tets)
    sigma1[np.any(mesh.tets == peak, axis=1)] = 0.9 * STRENGTH
    sigma1[e] = 2.0
    assert _select(mesh, sigma1, direction, 1).vertices[0] == nearest
    s = smoothing_operator(mesh.points, mesh.tets, rings=1)
    none = np.zeros(mesh.n_points, bool)
    cohesive = select_sites(mesh.points, mesh.tets, sigma1, direction, STRENGTH, s, none,
                            none, 1, front=none, peak_first=True)
    assert cohesive.elements[0] == e and cohesive.vertices[0] == peak


def test_a_split_that_would_shed_loose_tets_is_refused():
    """At a vertex on the surface a plane can cut off tets whose faces away from the vertex
    are all exterior: such a split would shed loose debris, not open a crack across the
    body. Exactly those two-sided splits are refused."""
    mesh = structured_box((3, 3, 3))
    lookups = star(mesh.tets, mesh.n_points)
    c = mesh.points[mesh.tets].mean(axis=1)
    rng = np.random.default_rng(0)
    refused = accepted = 0
    for v in range(mesh.n_points):
        for n in rng.normal(size=(6, 3)):
            n /= np.linalg.norm(n)
            if not two_sided(mesh.points, c, lookups.incidence, np.array([v]), n[None])[0]:
                continue
            ok = splits(mesh.points, mesh.tets, c, lookups, v, n)
            new, _ = open_crack(mesh, [v], n[None], separate=False)
            assert (fragments(new.tets)[0] == 1) == ok
            refused += not ok
            accepted += ok
    assert refused > 0 and accepted > 0


def test_known_answers_are_those_of_a_fresh_lookup():
    """splits keeps its answers on the topology's Star, by vertex and the sides its tets
    fall on: on a cracked mesh, with many normals per vertex (repeated side patterns), the
    kept answers equal those of a fresh Star each time, and answers are reused."""
    mesh = structured_box((4, 3, 3), distortion=0.1, seed=5)
    p = mesh.points
    mesh, _ = open_crack(mesh, np.flatnonzero(np.abs(p[:, 0] - 0.5) < 0.13)[:4],
                         np.tile([1.0, 0.0, 0.0], (4, 1)))
    shared = star(mesh.tets, mesh.n_points)
    c = mesh.points[mesh.tets].mean(axis=1)
    rng = np.random.default_rng(8)
    calls = 0
    for v in range(mesh.n_points):
        for n in rng.normal(size=(12, 3)):
            kept = splits(mesh.points, mesh.tets, c, shared, v, n)
            fresh = splits(mesh.points, mesh.tets, c, star(mesh.tets, mesh.n_points), v, n)
            assert kept == fresh
            calls += 1
    assert 0 < len(shared.known) < calls


def test_two_sided_matches_the_scalar_rule():
    mesh = structured_box((3, 3, 3), distortion=0.15, seed=4)
    lookups = star(mesh.tets, mesh.n_points)
    c = mesh.points[mesh.tets].mean(axis=1)
    rng = np.random.default_rng(2)
    v = rng.integers(0, mesh.n_points, 300)
    n = rng.normal(size=(300, 3))
    fast = two_sided(mesh.points, c, lookups.incidence, v, n)
    inc = lookups.incidence
    slow = []
    for vi, ni in zip(v, n, strict=True):
        t = inc.indices[inc.indptr[vi]:inc.indptr[vi + 1]]
        side = (c[t] - mesh.points[vi]) @ ni < 0
        slow.append(side.any() and not side.all())
    np.testing.assert_array_equal(fast, slow)


@pytest.mark.parametrize("angle", [5.0, 30.0])
def test_tilt_is_uniform_on_the_cap(angle):
    """The tilt angle theta of a uniform distribution on a cap of half-angle a has
    P(cos theta <= x) = (1 - x) / (1 - cos a); the sample's mean of cos theta is
    (1 + cos a) / 2 with standard error (1 - cos a) / sqrt(12 N): within 5 of them."""
    rng = np.random.default_rng(3)
    n = np.tile(rng.normal(size=3), (20000, 1))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    out = tilt(n, np.radians(angle), rng)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-14)
    cos = np.einsum("ij,ij->i", out, n)
    a = np.cos(np.radians(angle))
    assert cos.min() >= a - 1e-12
    assert abs(cos.mean() - (1 + a) / 2) < 5 * (1 - a) / np.sqrt(12 * len(cos))
    # and the same seed gives the same tilt
    again = tilt(n[:5], np.radians(angle), np.random.default_rng(9))
    np.testing.assert_array_equal(again, tilt(n[:5], np.radians(angle),
                                              np.random.default_rng(9)))


def test_tilting_some_rows_tilts_them_as_tilting_all_does():
    """``only``: the rows asked for get the bits a tilt of every row gives them (the draws
    are made for every row), the others come back as given, NaN included."""
    rng = np.random.default_rng(4)
    n = rng.normal(size=(50, 3))
    n[::7] = np.nan  # directions nobody reads (fem_frac.fracture.smoothing)
    only = rng.random(50) < 0.4
    only[::7] = False
    every = tilt(n, np.radians(10.0), np.random.default_rng(5))
    some = tilt(n, np.radians(10.0), np.random.default_rng(5), only=only)
    np.testing.assert_array_equal(some[only], every[only])
    np.testing.assert_array_equal(some[~only], n[~only])
    assert not np.allclose(some[only], n[only] / np.linalg.norm(n[only], axis=1)[:, None])


def test_groups_are_the_connected_components():
    """The union-find of ``splits`` (the tets around one vertex, a few dozen) groups nodes
    as scipy's connected components do, each group named by its lowest node."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    from fem_frac.fracture.sites import _groups

    rng = np.random.default_rng(3)
    for n in (1, 2, 7, 30, 60):
        for edges in (0, n // 2, n, 3 * n):
            a, b = rng.integers(0, n, edges), rng.integers(0, n, edges)
            group = np.array(_groups(n, a.tolist(), b.tolist()))
            graph = sp.coo_matrix((np.ones(edges), (a, b)), shape=(n, n))
            _, label = connected_components(graph, directed=False)
            # the same partition, each group named by its lowest node
            first = {lab: np.flatnonzero(label == lab).min() for lab in np.unique(label)}
            np.testing.assert_array_equal(group, [first[lab] for lab in label])
