"""Crack insertion by face separation: topology, conservation, transfer (fem_frac.fracture)."""

from __future__ import annotations

import numpy as np
import pytest

from fem_frac.fem.mass import lumped_mass
from fem_frac.fem.space import build_space
from fem_frac.fracture import (
    CRACK,
    face_adjacency,
    fragments,
    open_crack,
    separate_nonmanifold,
    split_vertex,
)
from fem_frac.mesh import Mesh, exterior_facets, tet_volumes
from fem_frac.mesh.mesh import TET_EDGES, TET_FACES, facet_keys
from meshes import structured_box


def _nearest(mesh: Mesh, x) -> int:
    return int(np.argmin(np.linalg.norm(mesh.points - np.asarray(x), axis=1)))


def _with_boundaries(mesh: Mesh) -> Mesh:
    outer = exterior_facets(mesh.tets)
    x0 = np.all(np.abs(mesh.points[outer][:, :, 0]) < 1e-12, axis=1)
    return Mesh(mesh.points, mesh.tets, boundaries={"outer": outer, "left": outer[x0]})


def _face_counts(mesh: Mesh) -> np.ndarray:
    keys = facet_keys(mesh.tets[:, TET_FACES].reshape(-1, 3), mesh.n_points)
    return np.unique(keys, return_counts=True)[1]


def _check_split(old: Mesh, new: Mesh, transfer) -> np.ndarray:
    """Checks shared by every split; returns the crack faces."""
    nm = transfer.node_map
    assert new.n_tets == old.n_tets
    np.testing.assert_array_equal(transfer.element_map, np.arange(old.n_tets))
    np.testing.assert_array_equal(nm[: old.n_points], np.arange(old.n_points))
    np.testing.assert_array_equal(new.points, old.points[nm])
    # the same tets, only with vertex copies
    np.testing.assert_array_equal(nm[new.tets], old.tets)
    vol_old = tet_volumes(old.points, old.tets)
    vol_new = tet_volumes(new.points, new.tets)
    assert np.all(vol_new > 0)
    np.testing.assert_allclose(vol_new, vol_old, rtol=0, atol=1e-15 * vol_old.max())
    # every face in at most two tets (1 = exterior, 2 = interior)
    counts = _face_counts(new)
    assert counts.max() <= 2
    # exterior faces grew by exactly the crack faces
    outer_old = exterior_facets(old.tets)
    outer_new = exterior_facets(new.tets)
    crack = new.boundaries[CRACK]
    assert len(outer_new) == len(outer_old) + len(crack)
    k_new = facet_keys(outer_new, new.n_points)
    k_crack = facet_keys(crack, new.n_points)
    assert np.all(np.isin(k_crack, k_new)) and len(np.unique(k_crack)) == len(crack)
    rest = outer_new[~np.isin(k_new, k_crack)]
    np.testing.assert_array_equal(
        np.sort(facet_keys(nm[rest], old.n_points)), np.sort(facet_keys(outer_old, old.n_points))
    )
    # crack faces were interior faces of the old mesh, each split into exactly two faces
    old_keys = facet_keys(old.tets[:, TET_FACES].reshape(-1, 3), old.n_points)
    img, per_face = np.unique(facet_keys(nm[crack], old.n_points), return_counts=True)
    assert np.all(per_face == 2)
    u, c = np.unique(old_keys, return_counts=True)
    assert np.all(c[np.searchsorted(u, img)] == 2)
    return crack


@pytest.mark.parametrize("distortion", [0.0, 0.1])
def test_split_interior_vertex(distortion):
    old = _with_boundaries(structured_box((4, 3, 3), distortion=distortion))
    v = _nearest(old, [0.5, 1 / 3, 1 / 3])
    new, tr = split_vertex(old, v, [1.0, 0.0, 0.0])
    assert new.n_points >= old.n_points + 1
    assert np.count_nonzero(tr.node_map[old.n_points :] == v) >= 1
    crack = _check_split(old, new, tr)
    assert len(crack) > 0
    # every crack face contains the split vertex or one of its copies
    assert np.all(np.any(tr.node_map[crack] == v, axis=1))
    # boundaries untouched by an interior split, but re-expressed consistently
    for name in ("outer", "left"):
        np.testing.assert_array_equal(tr.node_map[new.boundaries[name]], old.boundaries[name])
    # split tets: those holding the copy lie on the − side of x = x_v
    copy = old.n_points
    holders = np.any(new.tets == copy, axis=1)
    assert holders.any()
    cx = old.points[old.tets[holders]].mean(axis=1)[:, 0]
    assert np.all(cx < old.points[v, 0])


def test_split_boundary_vertex_reexpresses_boundaries():
    old = _with_boundaries(structured_box((4, 3, 3), distortion=0.1))
    v = _nearest(old, [0.0, 1 / 3, 1 / 3])  # on the face x = 0
    new, tr = split_vertex(old, v, [0.0, 1.0, 0.0])
    assert new.n_points >= old.n_points + 1
    _check_split(old, new, tr)
    outer = exterior_facets(new.tets)
    k_outer = facet_keys(outer, new.n_points)
    for name in ("outer", "left"):
        b = new.boundaries[name]
        # the same triangles in the caller's vertex order, now faces of the new mesh
        np.testing.assert_array_equal(tr.node_map[b], old.boundaries[name])
        assert np.all(np.isin(facet_keys(b, new.n_points), k_outer))

        # orientation kept: same normal as the old triangle
        def normals(p, t):
            return np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])

        np.testing.assert_allclose(
            normals(new.points, b), normals(old.points, old.boundaries[name]), atol=1e-15
        )
    # the vertex copy is used by some of the left boundary triangles
    assert np.any(new.boundaries["left"] >= old.n_points)


def _lumped(mesh: Mesh) -> np.ndarray:
    return lumped_mass(build_space(mesh, 1), 1.0)[0::3]


@pytest.mark.parametrize("distortion", [0.0, 0.1])
def test_mass_and_momentum_conserved(distortion):
    """Exact conservation, up to round-off.

    P1 lumped mass of a vertex is the sum over its tets of rho V_e / 4. A copy of a vertex
    receives exactly the contributions of the tets that now hold the copy, and the tets
    around the original are partitioned between the original and its copies (no tet is
    cut, volumes unchanged). So the masses of an original and its copies sum to its old
    mass; they sit at the same position and carry the same (transferred) velocity, hence
    sum m v and sum m x × v regroup into the old sums term by term. Only the summation
    order changes: equality to round-off.
    """
    old = structured_box((4, 3, 3), distortion=distortion)
    vs = [
        _nearest(old, x) for x in ([0.5, 1 / 3, 1 / 3], [0.5, 2 / 3, 1 / 3], [0.25, 1 / 3, 2 / 3])
    ]
    rng = np.random.default_rng(3)
    normals = rng.normal(size=(3, 3))
    new, tr = open_crack(old, vs, normals)
    assert new.n_points > old.n_points
    m_old, m_new = _lumped(old), _lumped(new)
    assert abs(m_new.sum() - m_old.sum()) <= 1e-12
    # per original vertex: copies' masses sum to the old mass
    regrouped = np.bincount(tr.node_map, weights=m_new, minlength=old.n_points)
    np.testing.assert_allclose(regrouped, m_old, rtol=0, atol=1e-15)
    v_old = rng.normal(size=(old.n_points, 3))
    v_new = tr.transfer_nodal(v_old)
    p_old = (m_old[:, None] * v_old).sum(axis=0)
    p_new = (m_new[:, None] * v_new).sum(axis=0)
    np.testing.assert_allclose(p_new, p_old, rtol=0, atol=1e-14)
    l_old = (m_old[:, None] * np.cross(old.points, v_old)).sum(axis=0)
    l_new = (m_new[:, None] * np.cross(new.points, v_new)).sum(axis=0)
    np.testing.assert_allclose(l_new, l_old, rtol=0, atol=1e-14)
    # the flat dof vector transfers the same way
    np.testing.assert_array_equal(tr.transfer_dofs(v_old.ravel()), v_new.ravel())


def test_cut_bar_in_two():
    old = structured_box((8, 2, 2), lengths=(2.0, 0.5, 0.5))
    plane = np.nonzero(np.abs(old.points[:, 0] - 1.0) < 1e-12)[0]
    assert len(plane) == 9
    new, tr = open_crack(old, plane, np.tile([1.0, 0.0, 0.0], (len(plane), 1)))
    assert new.n_points == old.n_points + len(plane)  # no non-manifold leftovers
    crack = _check_split(old, new, tr)
    n, labels = fragments(new.tets)
    assert n == 2
    vol = tet_volumes(new.points, new.tets)
    for k in range(2):
        np.testing.assert_allclose(vol[labels == k].sum(), 0.25, rtol=1e-14)
        centroid_x = new.points[new.tets[labels == k]].mean(axis=1)[:, 0]
        assert np.all(centroid_x < 1.0) or np.all(centroid_x > 1.0)
    # fragments share no vertex
    used = [np.unique(new.tets[labels == k]) for k in range(2)]
    assert np.intersect1d(*used).size == 0
    # crack: the 2 x 2 x 2 triangles of the section, both sides, normals ±x, at x = 1
    assert len(crack) == 16
    p = new.points[crack]
    nrm = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    np.testing.assert_allclose(np.abs(nrm[:, 0]), 1.0, atol=1e-14)
    np.testing.assert_allclose(p[:, :, 0], 1.0, atol=1e-14)
    # outward: the left piece's faces point +x, the right piece's -x
    in_0 = np.all(np.isin(crack, used[0]), axis=1)
    left_is_0 = new.points[used[0], 0].mean() < 1.0
    sign = np.where(in_0 == left_is_0, 1.0, -1.0)
    np.testing.assert_allclose(nrm[:, 0], sign, atol=1e-14)
    assert tr.node_map.shape == (new.n_points,)


def _glue(a: Mesh, b: Mesh) -> Mesh:
    """Two meshes merged, coincident points identified."""
    pts = np.concatenate([a.points, b.points])
    tets = np.concatenate([a.tets, b.tets + a.n_points])
    unique, inverse = np.unique(np.round(pts, 9), axis=0, return_inverse=True)
    return Mesh(unique, inverse.ravel()[tets])


def _node_components(mesh: Mesh) -> int:
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    m = mesh.n_tets
    inc = sp.coo_matrix(
        (np.ones(4 * m), (np.repeat(np.arange(m), 4), mesh.tets.ravel())), shape=(m, mesh.n_points)
    ).tocsr()
    return connected_components(inc @ inc.T, directed=False)[0]


@pytest.mark.parametrize("shift,extra", [((1.0, 1.0, 1.0), 1), ((1.0, 1.0, 0.0), 2)])
def test_cubes_sharing_vertex_or_edge(shift, extra):
    a = structured_box((1, 1, 1))
    b = Mesh(a.points + np.asarray(shift), a.tets.copy())
    glued = _glue(a, b)
    assert glued.n_points == 16 - extra
    assert _node_components(glued) == 1  # joined through shared nodes
    assert fragments(glued.tets)[0] == 2  # but not through faces
    new, tr = separate_nonmanifold(glued)
    assert new.n_points == glued.n_points + extra
    n, labels = fragments(new.tets)
    assert n == 2
    used = [np.unique(new.tets[labels == k]) for k in range(2)]
    assert np.intersect1d(*used).size == 0
    assert _node_components(new) == 2
    np.testing.assert_array_equal(tr.node_map[new.tets], glued.tets)
    np.testing.assert_array_equal(new.points, glued.points[tr.node_map])
    assert len(new.boundaries[CRACK]) == 0  # no face was opened
    # a manifold mesh is left alone
    same, tr2 = separate_nonmanifold(a)
    np.testing.assert_array_equal(same.tets, a.tets)
    np.testing.assert_array_equal(tr2.node_map, np.arange(a.n_points))


def test_face_adjacency_counts():
    mesh = structured_box((4, 3, 3), distortion=0.1)
    adj = face_adjacency(mesh.tets)
    assert (adj != adj.T).nnz == 0
    assert adj.diagonal().sum() == 0
    n_interior = np.count_nonzero(_face_counts(mesh) == 2)
    assert adj.nnz == 2 * n_interior
    degree = np.asarray(adj.sum(axis=1)).ravel()
    n_outer = len(exterior_facets(mesh.tets))
    np.testing.assert_array_equal(4 * mesh.n_tets - degree.sum(), n_outer)


def test_face_neighbours_are_the_tets_across_each_face():
    """Face j of tet t (opposite corner j) is held by ``face_neighbours[t, j]`` too, that
    tet is face-adjacent to t, and a face on the boundary or on a crack points back to t."""
    from fem_frac.fracture.faces import face_neighbours

    old = structured_box((4, 3, 3), distortion=0.1)
    mesh, _ = open_crack(old, [_nearest(old, [0.5, 0.5, 0.5])], [[1.0, 0.2, 0.0]])
    nb = face_neighbours(mesh.tets)
    t = np.repeat(np.arange(mesh.n_tets), 4)
    other = nb.ravel()
    faces = mesh.tets[:, TET_FACES].reshape(-1, 3)
    held = np.sort(faces, axis=1)
    across = other != t
    # the other tet holds the same three vertices
    corners = mesh.tets[other[across]]
    assert np.all((corners[:, :, None] == faces[across][:, None, :]).any(axis=1))
    adj = face_adjacency(mesh.tets)
    np.testing.assert_array_equal(np.asarray(adj[t[across], other[across]]).ravel(), 1)
    assert np.count_nonzero(across) == adj.nnz
    # a face no other tet holds is on the boundary (outer or the crack's two sides)
    _, inverse, counts = np.unique(held, axis=0, return_inverse=True, return_counts=True)
    np.testing.assert_array_equal(counts[inverse.ravel()] == 1, ~across)


def test_boundary_rows_kept_through_insertions_equal_a_lookup():
    """The second insertion finds the groups at the face rows the first one recorded; the
    groups are those of a lookup in every face (the rows forgotten), in the same order and
    orientation."""
    from fem_frac.fracture import topology

    old = _with_boundaries(structured_box((4, 3, 3), distortion=0.1))
    one, _ = open_crack(old, [_nearest(old, [0.5, 1 / 3, 1 / 3])], [[1.0, 0.2, 0.0]])
    assert one in topology._BOUNDARY_ROWS
    vs, normals = [_nearest(one, [0.5, 2 / 3, 2 / 3])], [[0.0, 1.0, 1.0]]
    kept, _ = open_crack(one, vs, normals)
    rows = topology._BOUNDARY_ROWS.pop(one)
    looked_up, _ = open_crack(one, vs, normals)
    assert kept.boundaries.keys() == looked_up.boundaries.keys() == {"outer", "left", CRACK}
    for name in kept.boundaries:
        np.testing.assert_array_equal(kept.boundaries[name], looked_up.boundaries[name])
    # rows that do not hold a group's triangles (stale) are not trusted
    topology._BOUNDARY_ROWS[one] = {**rows, "outer": rows["outer"][::-1]}
    checked, _ = open_crack(one, vs, normals)
    np.testing.assert_array_equal(checked.boundaries["outer"], looked_up.boundaries["outer"])
    assert len(kept.boundaries[CRACK]) > len(one.boundaries[CRACK]) > 0


def test_deterministic():
    old = _with_boundaries(structured_box((4, 3, 3), distortion=0.1))
    vs = [_nearest(old, [0.5, 1 / 3, 1 / 3]), _nearest(old, [0.5, 2 / 3, 2 / 3])]
    normals = [[1.0, 0.2, 0.0], [0.0, 1.0, 1.0]]
    one, t1 = open_crack(old, vs, normals)
    two, t2 = open_crack(old, vs, normals)
    np.testing.assert_array_equal(one.points, two.points)
    np.testing.assert_array_equal(one.tets, two.tets)
    np.testing.assert_array_equal(t1.node_map, t2.node_map)
    assert one.boundaries.keys() == two.boundaries.keys()
    for k in one.boundaries:
        np.testing.assert_array_equal(one.boundaries[k], two.boundaries[k])
    np.testing.assert_array_equal(fragments(one.tets)[1], fragments(two.tets)[1])


def test_transfer_linear_field():
    old = structured_box((4, 3, 3), distortion=0.1)
    rng = np.random.default_rng(7)
    vs = rng.choice(old.n_points, 6, replace=False)
    new, tr = open_crack(old, vs, rng.normal(size=(6, 3)))
    assert new.n_points > old.n_points
    a, b = rng.normal(size=(3, 3)), rng.normal(size=3)
    u_old = old.points @ a.T + b
    np.testing.assert_array_equal(tr.transfer_nodal(u_old), new.points @ a.T + b)
    # element state stays with its element
    eps = rng.normal(size=(3, 3, old.n_tets, 1))
    np.testing.assert_array_equal(tr.transfer_elemental(eps, axis=-2), eps)


def test_curved_edges_follow_their_tets():
    """Mid-side nodes of a curved quadratic mesh are copied with the edges they sit on."""
    box = structured_box((3, 2, 2), distortion=0.1)
    edges = np.unique(np.sort(box.tets[:, TET_EDGES].reshape(-1, 2), axis=1), axis=0)
    rng = np.random.default_rng(5)
    mid = box.points[edges].mean(axis=1) + 0.01 * rng.uniform(-1, 1, (len(edges), 3))
    old = Mesh(box.points, box.tets, edges=edges, edge_points=mid)
    v = _nearest(old, [1 / 3, 0.5, 0.5])
    new, tr = split_vertex(old, v, [1.0, 0.0, 0.0])
    assert new.curved and len(new.edges) > len(edges)
    np.testing.assert_array_equal(new.edges, np.sort(new.edges, axis=1))
    img = np.sort(tr.node_map[new.edges], axis=1)
    pos = np.searchsorted(
        edges[:, 0] * old.n_points + edges[:, 1], img[:, 0] * old.n_points + img[:, 1]
    )
    np.testing.assert_array_equal(edges[pos], img)
    np.testing.assert_array_equal(new.edge_points, mid[pos])
    # every edge of the new tets is listed, and the P2 space builds with the same total mass
    all_new = np.unique(np.sort(new.tets[:, TET_EDGES].reshape(-1, 2), axis=1), axis=0)
    np.testing.assert_array_equal(all_new, new.edges)
    m_old = lumped_mass(build_space(old, 2), 1.0).sum()
    m_new = lumped_mass(build_space(new, 2), 1.0).sum()
    assert abs(m_new - m_old) <= 1e-12 * m_old


def test_second_crack_extends_crack_group():
    old = _with_boundaries(structured_box((4, 3, 3)))
    one, t1 = split_vertex(old, _nearest(old, [0.5, 1 / 3, 1 / 3]), [1.0, 0.0, 0.0])
    two, t2 = split_vertex(one, _nearest(one, [0.5, 2 / 3, 2 / 3]), [1.0, 0.0, 0.0])
    c1, c2 = one.boundaries[CRACK], two.boundaries[CRACK]
    assert len(c2) > len(c1)
    # the old crack faces are re-expressed first, then the new ones follow
    np.testing.assert_array_equal(t2.node_map[c2[: len(c1)]], c1)
    both = t1.then(t2)
    np.testing.assert_array_equal(both.node_map[two.tets], old.tets)
    _check_split(old, two, both)
    # without non-manifold separation only the plane copy is made
    bare, tb = split_vertex(
        old, _nearest(old, [0.5, 1 / 3, 1 / 3]), [1.0, 0.0, 0.0], separate=False
    )
    assert bare.n_points == old.n_points + 1


@pytest.mark.parametrize("count", [1, 5, 9])
def test_matched_faces_after_a_split_are_those_matched_afresh(count, monkeypatch):
    """open_crack keeps the matched faces of its new tables from the old one's (no sort):
    the same pairs and local corners as matching the new table's faces afresh, including
    where the separation gives vertices copies (a bar cut through: count 9)."""
    from fem_frac.fracture import faces
    from fem_frac.fracture.faces import _face_pairs, _match_faces

    old = structured_box((8, 2, 2), lengths=(2.0, 0.5, 0.5))
    plane = np.nonzero(np.abs(old.points[:, 0] - 1.0) < 1e-12)[0][:count]
    _face_pairs(old.tets)  # the old table's pairs, as a run has them
    new, tr = open_crack(old, plane, np.tile([1.0, 0.0, 0.0], (len(plane), 1)))
    assert new.n_points > old.n_points

    def as_set(pairs):
        r1, r2, l1, l2 = pairs
        return {(a, b, *x, *y) for a, b, x, y in zip(r1, r2, map(tuple, l1), map(tuple, l2),
                                                      strict=True)}

    with monkeypatch.context() as m:  # the new table's pairs are kept, not computed
        m.setattr(faces, "_match_faces", None)
        kept = _face_pairs(new.tets)
    fresh = _match_faces(np.asarray(new.tets))
    assert as_set(kept) == as_set(fresh)
    assert len(kept[0]) == len(fresh[0]) < len(_match_faces(np.asarray(old.tets))[0])


def _pair_set(pairs):
    r1, r2, l1, l2 = pairs
    return {(a, b, *x, *y) for a, b, x, y in zip(r1.tolist(), r2.tolist(), l1.tolist(),
                                                  l2.tolist(), strict=True)}


@pytest.mark.parametrize("seed", range(6))
def test_separation_around_the_changes_equals_the_whole(seed):
    """A table cut_tets separated is cut again with the separation made around the tets the
    splits changed; the same tets and node map as the separation of the whole table
    (the same mesh with a copy of its table, which cut_tets does not know separated)."""
    from fem_frac.fracture import faces
    from fem_frac.fracture.topology import _is_separated, cut_tets, rebuilt

    rng = np.random.default_rng(seed)
    mesh = structured_box((5, 4, 4), distortion=0.15, seed=seed)
    separated = 0  # copies the separations made (beyond the plane splits)
    for _ in range(6):
        vertices = rng.choice(mesh.n_points, size=12, replace=False)
        normals = rng.normal(size=(12, 3))
        tets, node_map = cut_tets(mesh, vertices, normals)
        copy = Mesh(mesh.points, np.array(mesh.tets), dict(mesh.boundaries))
        assert not _is_separated(copy.tets)
        whole, whole_map = cut_tets(copy, vertices, normals)
        np.testing.assert_array_equal(tets, whole)
        np.testing.assert_array_equal(node_map, whole_map)
        assert _is_separated(tets)
        # the table's key is kept (no hash of it), and the matched faces kept under it
        # are those of its faces matched afresh
        assert id(tets) in faces._KEYS
        assert _pair_set(faces._face_pairs(tets)) == _pair_set(faces._match_faces(tets))
        separated += node_map.size - cut_tets(copy, vertices, normals, separate=False)[1].size
        mesh, _ = rebuilt(mesh, tets, node_map)
    assert separated > 0


def test_check_separated_records_a_conforming_mesh_and_not_a_pinched_one():
    """A conforming mesh (every vertex one fan) is found separated and kept so: its first
    cut then separates around the splits, with the whole separation's tets and node map.
    Two tets that share only a vertex are not (that vertex has two fans), and stay
    unknown."""
    from fem_frac.fracture.topology import _is_separated, check_separated, cut_tets

    mesh = structured_box((4, 3, 3), distortion=0.1, seed=3)
    copy = Mesh(mesh.points, np.array(mesh.tets), dict(mesh.boundaries))
    assert not _is_separated(mesh.tets)
    assert check_separated(mesh) and _is_separated(mesh.tets)
    assert not _is_separated(copy.tets)
    rng = np.random.default_rng(3)
    vertices = rng.choice(mesh.n_points, size=10, replace=False)
    normals = rng.normal(size=(10, 3))
    tets, node_map = cut_tets(mesh, vertices, normals)
    whole, whole_map = cut_tets(copy, vertices, normals)
    np.testing.assert_array_equal(tets, whole)
    np.testing.assert_array_equal(node_map, whole_map)

    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1],
                       [-1, 0, 0], [0, -1, 0], [0, 0, -1]], dtype=float)
    pinched = Mesh(points, np.array([[0, 1, 2, 3], [0, 4, 6, 5]]), {})
    assert not check_separated(pinched) and not _is_separated(pinched.tets)


def test_debris_retries_keep_the_meshs_matched_faces(monkeypatch):
    """A batch that sheds debris cuts its mesh again and again (fracture/stage.py, ``open``),
    each cut keeping two new tables' matched faces; the mesh's own, which every cut and the
    new mesh's boundary groups ask for, stays kept (least recently asked goes first): its
    faces are matched once, not again after the retries."""
    from collections import OrderedDict

    from fem_frac.fracture import faces
    from fem_frac.fracture.topology import cut_tets, rebuilt

    monkeypatch.setattr(faces, "_PAIRS", OrderedDict())  # nothing kept from other tests
    monkeypatch.setattr(faces, "_ADJACENCY", {})
    mesh = structured_box((5, 4, 4), distortion=0.1, seed=2)
    matched = []
    inner = faces._match_faces

    def counted(tets):
        matched.append(tets.shape)
        return inner(tets)

    monkeypatch.setattr(faces, "_match_faces", counted)
    faces._face_pairs(mesh.tets)
    assert len(matched) == 1
    inside = np.flatnonzero(np.all((mesh.points > 0.1) & (mesh.points < 0.9), axis=1))
    for k in range(4):  # a first try and three retries, each with other sites
        tets, node_map = cut_tets(mesh, inside[k: k + 3], np.tile([1.0, 0.2, 0.1], (3, 1)))
    new, _ = rebuilt(mesh, tets, node_map)
    assert new.n_points > mesh.n_points
    assert len(matched) == 1
