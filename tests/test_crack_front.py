"""The crack front and growth along it (fem_frac.fracture.front, select_sites(front=...))."""

from __future__ import annotations

import numpy as np
import pytest

from fem_frac.fracture import CRACK, open_crack
from fem_frac.fracture.front import (
    CONTINUE,
    continue_planes,
    crack_front,
    front_normals,
    near_crack,
)
from fem_frac.fracture.sites import select_sites, splits, star
from fem_frac.fracture.smoothing import smoothing_operator
from fem_frac.mesh.mesh import TET_EDGES
from meshes import structured_box

STRENGTH = 1.0
X = np.array([1.0, 0.0, 0.0])


def _open(mesh, keep):
    """Split the vertices of the plane x = 0.5 where ``keep(points)``, normal x."""
    p = mesh.points
    v = np.flatnonzero((np.abs(p[:, 0] - 0.5) < 1e-12) & keep(p))
    return open_crack(mesh, v, np.tile(X, (len(v), 1)))[0]


def _on_crack(mesh):
    on = np.zeros(mesh.n_points, bool)
    on[mesh.boundaries[CRACK].ravel()] = True
    return on


def test_front_of_a_crack_from_the_surface_is_its_leading_line():
    """Rows y <= 0.5 of the plane x = 0.5 split: the crack covers y <= 0.75 (every in-plane
    triangle of the next strip has a split corner) and meets the faces y = 0, z = 0, z = 1.
    Its front is the line y = 0.75 of the plane, ends on the surface included (the edges
    there run inside the body); the edges on the surface are no front."""
    new = _open(structured_box((4, 4, 4)), lambda p: p[:, 1] < 0.6)
    front = crack_front(new)
    on = _on_crack(new)
    y_max = new.points[on, 1].max()
    assert y_max == pytest.approx(0.75)
    expected = (np.abs(new.points[:, 0] - 0.5) < 1e-12) & (np.abs(new.points[:, 1] - y_max)
                                                          < 1e-12)
    np.testing.assert_array_equal(front, expected)
    assert expected.sum() == 5 and not (front & ~on).any()


def test_front_of_an_embedded_crack_is_the_ring_around_its_vertex():
    """One interior vertex split: the crack is its star in the plane; the front is every
    vertex of the plane joined to it by an edge (the rim), not the split vertex."""
    mesh = structured_box((4, 4, 4))
    p = mesh.points
    v = int(np.flatnonzero(np.all(np.abs(p - 0.5) < 1e-12, axis=1))[0])
    new, _ = open_crack(mesh, [v], X[None])
    edges = mesh.tets[:, TET_EDGES].reshape(-1, 2)
    ring = np.unique(edges[np.any(edges == v, axis=1)])
    ring = ring[(ring != v) & (np.abs(p[ring, 0] - 0.5) < 1e-12)]
    expected = np.zeros(new.n_points, bool)
    expected[ring] = True
    np.testing.assert_array_equal(crack_front(new), expected)
    assert ring.size == 6  # the hexagon of a structured box's plane


def test_front_counts_faces_once_across_batches():
    """The same crack opened in two batches (the crack group appended to) has the same
    front, every copy of a front position included."""
    mesh = structured_box((4, 4, 4))
    once = _open(mesh, lambda p: p[:, 1] < 0.6)
    twice = _open(_open(mesh, lambda p: p[:, 1] < 0.3),
                  lambda p: np.abs(p[:, 1] - 0.5) < 1e-12)
    a, b = crack_front(once), crack_front(twice)
    key = lambda m, f: sorted(map(tuple, np.round(m.points[f], 12).tolist()))  # noqa: E731
    assert key(once, a) == key(twice, b) and a.sum() == b.sum() == 5


def test_no_crack_and_through_crack_have_no_front():
    mesh = structured_box((4, 3, 3))
    assert not crack_front(mesh).any()
    through = _open(mesh, lambda p: np.ones(len(p), bool))
    assert len(through.boundaries[CRACK]) > 0
    assert not crack_front(through).any()


def test_near_crack_is_the_neighbourhood_of_the_crack_tets():
    new = _open(structured_box((4, 4, 4)), lambda p: p[:, 1] < 0.6)
    s = smoothing_operator(new.points, new.tets, rings=1)
    has = _on_crack(new)[new.tets].any(axis=1)
    dense = s.toarray() != 0
    expected = (dense & has[None, :]).any(axis=1) | has
    near = near_crack(new, s)
    np.testing.assert_array_equal(near, expected)
    assert 0 < near.sum() < new.n_tets


@pytest.fixture(scope="module")
def cracked():
    new = _open(structured_box((4, 4, 4)), lambda p: p[:, 1] < 0.6)
    s = smoothing_operator(new.points, new.tets, rings=1)
    return new, s, star(new.tets, new.n_points), crack_front(new), near_crack(new, s)


def _one(new, s, lookups, e, normal, **kw):
    """The site of element ``e`` alone over strength, crack normal ``normal``."""
    sigma1 = np.zeros(new.n_tets)
    sigma1[e] = 2.0
    direction = np.tile(normal, (new.n_tets, 1))
    return select_sites(new.points, new.tets, sigma1, direction, STRENGTH, s, _on_crack(new),
                        np.zeros(new.n_points, bool), 1, lookups, **kw)


@pytest.mark.parametrize("normal", [X, np.array([0.0, 1.0, 0.0])])
def test_process_zone_grows_only_from_the_front(cracked, normal):
    """Each element over strength alone: far from the crack it splits as before; near it,
    at a front vertex when one of its vertices on the front splits, else not at all, even
    where the plain rule opens an off-crack vertex beside the crack (normal x: a band) or a
    crack-interior one (normal y: a branch behind the front); with normal y a front vertex
    wins over a crack-interior one."""
    new, s, lookups, front, near = cracked
    c = new.points[new.tets].mean(axis=1)
    on = _on_crack(new)
    refused = {True: 0, False: 0}  # by whether the plain rule's vertex is on the crack
    redirected = 0
    for e in range(new.n_tets):
        plain = _one(new, s, lookups, e, normal)
        grown = _one(new, s, lookups, e, normal, front=front, near=near)
        if not near[e]:
            np.testing.assert_array_equal(grown.vertices, plain.vertices)
            continue
        ok = [v for v in new.tets[e] if front[v] and splits(new.points, new.tets, c,
                                                            lookups, v, normal)]
        if ok:
            assert len(grown) == 1 and grown.vertices[0] in ok
            redirected += len(plain) == 1 and not front[plain.vertices[0]]
        else:
            assert len(grown) == 0
            if len(plain):
                assert not front[plain.vertices[0]]
                refused[bool(on[plain.vertices[0]])] += 1
    assert refused[False] > 0
    if normal[1]:
        assert refused[True] > 0 and redirected > 0


def test_front_none_is_the_plain_rule(cracked):
    """``near`` alone changes nothing, nor does an empty front with nothing near."""
    new, s, lookups, front, near = cracked
    rng = np.random.default_rng(3)
    sigma1 = 1.5 + rng.random(new.n_tets)
    direction = rng.normal(size=(new.n_tets, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    args = (new.points, new.tets, sigma1, direction, STRENGTH, s, _on_crack(new),
            np.zeros(new.n_points, bool), 20, lookups)
    plain = select_sites(*args)
    assert len(plain) > 1
    for other in (select_sites(*args, near=near),
                  select_sites(*args, front=np.zeros(new.n_points, bool),
                               near=np.zeros(new.n_tets, bool))):
        np.testing.assert_array_equal(other.elements, plain.elements)
        np.testing.assert_array_equal(other.vertices, plain.vertices)
    grown = select_sites(*args, front=front)  # near from on_crack
    assert np.all(front[grown.vertices] | ~near[grown.elements])
    np.testing.assert_array_equal(grown.vertices,
                                  select_sites(*args, front=front, near=near).vertices)


def test_front_normals_are_the_cracks_own():
    """On a planar crack x = 0.5 every tet touching the front gets the normal x; the rest
    none."""
    new = _open(structured_box((4, 4, 4)), lambda p: p[:, 1] < 0.6)
    front = crack_front(new)
    normals = front_normals(new, front)
    touching = front[new.tets].any(axis=1)
    np.testing.assert_allclose(normals[touching], np.tile(X, (touching.sum(), 1)), atol=1e-12)
    assert not normals[~touching].any()


@pytest.mark.parametrize("share", [CONTINUE + 0.01, CONTINUE - 0.01])
def test_a_front_goes_on_in_its_plane_while_the_stress_pulls_it_apart(share):
    """A stress whose principal direction is tilted 40 deg from the crack normal: the crack
    goes on in its plane when the normal stress on that plane is at least CONTINUE of the
    largest principal stress, and kinks (the principal direction) when it is not."""
    angle = np.radians(40.0)
    d = np.array([np.cos(angle), 0.0, np.sin(angle)])  # principal direction, in x-z
    e = np.array([-np.sin(angle), 0.0, np.cos(angle)])
    # sigma = s1 d d^T + s2 e e^T with n.sigma.n = share s1 on n = x
    s1 = 1.0
    s2 = (share * s1 - s1 * d[0] ** 2) / e[0] ** 2
    sigma = s1 * np.outer(d, d) + s2 * np.outer(e, e)
    r2 = np.sqrt(2.0)
    mandel = np.array([sigma[0, 0], sigma[1, 1], sigma[2, 2], r2 * sigma[0, 1],
                       r2 * sigma[1, 2], r2 * sigma[0, 2]])[:, None]
    assert s1 >= s2
    out = continue_planes(d[None, :], mandel, np.array([s1]), X[None, :])
    expected = X if share >= CONTINUE else d
    np.testing.assert_allclose(out[0], expected, atol=1e-12)
    # a tet off every front keeps the principal direction
    out = continue_planes(d[None, :], mandel, np.array([s1]), np.zeros((1, 3)))
    np.testing.assert_allclose(out[0], d)
