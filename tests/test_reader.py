"""Mesh files -> Mesh with meshio: named groups, tetra10, orientation checks, errors."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import meshio
import numpy as np
import pytest

from fem_frac.errors import MeshError
from fem_frac.mesh import exterior_facets, tet_volumes
from fem_frac.mesh.mesh import SortedKeys, facet_keys, match
from fem_frac.mesh.reader import read_mesh_file
from meshes import structured_box

MESHES = Path(__file__).resolve().parents[1] / "meshes"


def gmsh_box_file(path: Path, version: float, binary: bool, order: int = 1) -> None:
    """A unit box with physical surfaces ``left`` (x=0), ``right`` (x=1), ``rest`` (the other
    four faces) and physical volume ``solid``, written by gmsh."""
    import gmsh

    from fem_frac.mesh.gmsh_model import gmsh_session

    with gmsh_session():
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        e = 1e-6
        left = gmsh.model.getEntitiesInBoundingBox(-e, -e, -e, e, 1 + e, 1 + e, dim=2)
        right = gmsh.model.getEntitiesInBoundingBox(1 - e, -e, -e, 1 + e, 1 + e, 1 + e, 2)
        ends = {t for _, t in left + right}
        rest = [t for _, t in gmsh.model.getEntities(2) if t not in ends]
        gmsh.model.addPhysicalGroup(2, [t for _, t in left], name="left")
        gmsh.model.addPhysicalGroup(2, [t for _, t in right], name="right")
        gmsh.model.addPhysicalGroup(2, rest, name="rest")
        gmsh.model.addPhysicalGroup(3, [1], name="solid")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.3)
        gmsh.model.mesh.generate(3)
        if order == 2:
            gmsh.model.mesh.setOrder(2)
        gmsh.option.setNumber("Mesh.MshFileVersion", version)
        gmsh.option.setNumber("Mesh.Binary", int(binary))
        gmsh.write(str(path))


def assert_valid(mesh) -> None:
    assert tet_volumes(mesh.points, mesh.tets).min() > 0
    assert np.array_equal(np.unique(mesh.tets), np.arange(mesh.n_points))  # compact


def test_key_lookup_contract():
    """match: the lowest row holding each key, -1 for a missing one; counts: how many."""
    keys = np.array([7, 3, 9, 3, 1])
    np.testing.assert_array_equal(match(keys, [3, 1, 4, 9, 10, 0]), [1, 4, -1, 2, -1, -1])
    np.testing.assert_array_equal(SortedKeys(keys).counts([3, 9, 4]), [2, 1, 0])
    np.testing.assert_array_equal(match(np.zeros(0, dtype=np.int64), [1, 2]), [-1, -1])
    assert match(keys, np.zeros(0, dtype=np.int64)).shape == (0,)
    # the structured keys facet_keys makes for meshes of 2M points and more
    tri = np.array([[0, 1, 2], [5, 4, 3], [2, 1, 0], [6, 7, 8]])
    table = facet_keys(tri, 3_000_000)
    wanted = facet_keys(np.array([[3, 4, 5], [1, 2, 0], [0, 1, 3]]), 3_000_000)
    np.testing.assert_array_equal(match(table, wanted), [1, 0, -1])


@pytest.mark.parametrize(("version", "binary"), [(4.1, False), (4.1, True), (2.2, False)])
def test_gmsh_round_trip_keeps_physical_groups(tmp_path, version, binary):
    path = tmp_path / "box.msh"
    gmsh_box_file(path, version, binary)
    mesh = read_mesh_file(path)
    assert_valid(mesh)
    assert set(mesh.boundaries) == {"left", "right", "rest"}
    assert set(mesh.subdomains) == {"solid"}
    np.testing.assert_array_equal(mesh.subdomains["solid"], np.arange(mesh.n_tets))
    assert tet_volumes(mesh.points, mesh.tets).sum() == pytest.approx(1.0, rel=1e-12)
    assert np.abs(mesh.points[mesh.boundaries["left"]][..., 0]).max() == 0.0
    assert np.abs(mesh.points[mesh.boundaries["right"]][..., 0] - 1).max() < 1e-15
    # the named facets are exactly the exterior, each once, oriented as exterior_facets
    ext = exterior_facets(mesh.tets)
    named = np.concatenate(list(mesh.boundaries.values()))
    assert len(named) == len(ext)
    order = np.argsort(facet_keys(ext, mesh.n_points))
    np.testing.assert_array_equal(ext[order], named[np.argsort(facet_keys(named, mesh.n_points))])


def test_tetra10_gmsh_file_matches_direct_meshing(tmp_path):
    import gmsh

    from fem_frac.mesh.gmsh_model import gmsh_session, mesh_current_model

    path = tmp_path / "ball.msh"
    with gmsh_session():
        gmsh.model.occ.addSphere(0, 0, 0, 2.0)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(2, [1], name="outer")
        gmsh.model.addPhysicalGroup(3, [1], name="ball")  # else gmsh writes no tets
        direct = mesh_current_model(0.8, 2)
        gmsh.write(str(path))
    mesh = read_mesh_file(path, order_hint=2)
    assert_valid(mesh)
    assert mesh.curved
    # mid-side nodes of curved edges on the sphere: tetra10 node order read correctly
    assert np.abs(np.linalg.norm(mesh.edge_points, axis=1) - 2.0).max() < 1e-12
    np.testing.assert_array_equal(mesh.tets, direct.tets)
    np.testing.assert_array_equal(mesh.edges, direct.edges)
    np.testing.assert_allclose(mesh.edge_points, direct.edge_points, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(mesh.boundaries["outer"], direct.boundaries["outer"])
    # order 1 wanted: the mid-side nodes are dropped
    assert not read_mesh_file(path, order_hint=1).curved


def test_tetra10_vtu_uses_vtk_edge_order(tmp_path):
    base = structured_box((2, 2, 2))
    # VTK tetra10: corners, then mid nodes of (0,1),(1,2),(2,0),(0,3),(1,3),(2,3)
    pairs = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]])
    mids = base.points[base.tets[:, pairs]].mean(axis=2)  # (n_tets, 6, 3)
    bump = np.array([0.0, 0.0, 0.01])
    mids = mids + bump  # every edge "curved" by the same offset
    n = base.n_points
    mid_ids = n + np.arange(6 * base.n_tets).reshape(-1, 6)
    points = np.vstack([base.points, mids.reshape(-1, 3)])
    cells = [("tetra10", np.hstack([base.tets, mid_ids]))]
    meshio.write(tmp_path / "q.vtu", meshio.Mesh(points, cells))
    mesh = read_mesh_file(tmp_path / "q.vtu")
    assert mesh.n_points == n
    a, b = mesh.points[mesh.edges[:, 0]], mesh.points[mesh.edges[:, 1]]
    np.testing.assert_allclose(mesh.edge_points - 0.5 * (a + b), np.tile(bump, (len(a), 1)))
    assert np.all(mesh.edges[:, 0] < mesh.edges[:, 1])


def test_all_negative_tets_are_flipped_and_unused_nodes_dropped(tmp_path):
    base = structured_box((2, 2, 1))
    extra = np.array([[9.0, 9.0, 9.0], [8.0, 8.0, 8.0]])
    points = np.vstack([extra, base.points])  # unused nodes first: ids shift by 2
    tets = base.tets[:, [1, 0, 2, 3]] + 2  # all inverted
    meshio.write(tmp_path / "neg.vtu", meshio.Mesh(points, [("tetra", tets)]))
    mesh = read_mesh_file(tmp_path / "neg.vtu")
    assert_valid(mesh)
    np.testing.assert_array_equal(mesh.points, base.points)
    np.testing.assert_allclose(
        tet_volumes(mesh.points, mesh.tets), tet_volumes(base.points, base.tets)
    )


def test_mixed_orientation_raises(tmp_path):
    base = structured_box((2, 2, 2))
    tets = base.tets.copy()
    tets[[3, 7]] = tets[[3, 7]][:, [1, 0, 2, 3]]
    meshio.write(tmp_path / "mixed.vtu", meshio.Mesh(base.points, [("tetra", tets)]))
    with pytest.raises(MeshError, match=r"2 of \d+ tets .*3, 7.*inverted") as info:
        read_mesh_file(tmp_path / "mixed.vtu")
    assert "\n" not in str(info.value)


def test_zero_volume_tet_raises(tmp_path):
    base = structured_box((2, 2, 2))
    tets = base.tets.copy()
    a, b, c, _ = tets[5]
    # a flat sliver: its fourth vertex is in the plane of the other three
    points = np.vstack([base.points, base.points[[a, b, c]].mean(axis=0)])
    tets = np.vstack([tets, [a, b, c, len(points) - 1]])
    meshio.write(tmp_path / "flat.vtu", meshio.Mesh(points, [("tetra", tets)]))
    with pytest.raises(MeshError, match=rf"1 of {len(tets)} tets .*{len(tets) - 1}.*zero-volume"):
        read_mesh_file(tmp_path / "flat.vtu")


def test_gmsh_file_without_physical_volume_explains(tmp_path):
    import gmsh

    from fem_frac.mesh.gmsh_model import gmsh_session

    with gmsh_session():
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(2, [1], name="side")
        gmsh.model.mesh.generate(3)
        gmsh.write(str(tmp_path / "surf.msh"))
    with pytest.raises(MeshError, match="no tetrahedra.*Physical Volume"):
        read_mesh_file(tmp_path / "surf.msh")


def test_triangles_only_raises(tmp_path):
    points = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    meshio.write(tmp_path / "tri.vtu", meshio.Mesh(points, [("triangle", np.array([[0, 1, 2]]))]))
    with pytest.raises(MeshError, match=r"no tetrahedra \(cell types: triangle\)"):
        read_mesh_file(tmp_path / "tri.vtu")


def test_integer_cell_data_names_groups(tmp_path):
    base = structured_box((2, 2, 2))
    ext = exterior_facets(base.tets)
    normal_x = np.abs(
        np.cross(*(base.points[ext[:, 1:]] - base.points[ext[:, :1]]).transpose(1, 0, 2))[:, 0]
    )
    ids = np.where(normal_x > 0, 1, 2)  # faces normal to x: 1, others: 2
    flipped = ext[:, [0, 2, 1]]  # stored inward: the reader turns them outward
    cells = [("tetra", base.tets), ("triangle", flipped)]
    data = {"boundary_id": [np.full(base.n_tets, 7), ids]}
    meshio.write(tmp_path / "ids.vtu", meshio.Mesh(base.points, cells, cell_data=data))
    mesh = read_mesh_file(tmp_path / "ids.vtu")
    assert set(mesh.boundaries) == {"boundary_id_1", "boundary_id_2"}
    assert set(mesh.subdomains) == {"boundary_id_7"}
    np.testing.assert_array_equal(mesh.boundaries["boundary_id_1"], ext[ids == 1])
    np.testing.assert_array_equal(mesh.boundaries["boundary_id_2"], ext[ids == 2])
    x = mesh.points[mesh.boundaries["boundary_id_1"]][..., 0]
    assert np.all(np.ptp(x, axis=1) == 0) and set(np.unique(x)) == {0.0, 1.0}


def test_facet_that_is_no_tet_face_raises(tmp_path):
    base = structured_box((2, 1, 1))
    # two vertices at x = 0 and one at x = 1 (two cells apart) share no tet
    x0 = np.flatnonzero(base.points[:, 0] == 0)[:2]
    x2 = np.flatnonzero(base.points[:, 0] == 1)[:1]
    cells = [("tetra", base.tets), ("triangle", np.concatenate([x0, x2])[None])]
    data = {"ref": [np.zeros(base.n_tets, int), np.array([3])]}
    meshio.write(tmp_path / "bad.vtu", meshio.Mesh(base.points, cells, cell_data=data))
    with pytest.raises(MeshError, match="ref_3.*not tet faces"):
        read_mesh_file(tmp_path / "bad.vtu")


@pytest.mark.parametrize(
    ("name", "text", "message"),
    [
        ("junk.msh", "hello\n", "cannot read mesh file"),
        ("junk.vtu", "<xml>\n", "cannot read mesh file"),
        ("junk.unknownext", "1 2 3\n", "cannot read mesh file"),
        ("missing.vtk", None, "not found"),
    ],
)
def test_unreadable_files_raise_one_line(tmp_path, capfd, name, text, message):
    path = tmp_path / name
    if text is not None:
        path.write_text(text)
    with pytest.raises(MeshError, match=message) as info:
        read_mesh_file(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)
    out, err = capfd.readouterr()
    assert out == "" and err == ""  # meshio's chatter is captured


def test_example_mesh_file():
    mesh = read_mesh_file(MESHES / "block_with_hole.msh")
    assert_valid(mesh)
    assert set(mesh.boundaries) == {"left", "right", "front", "back", "bottom", "top", "hole"}
    np.testing.assert_array_equal(mesh.subdomains["solid"], np.arange(mesh.n_tets))
    assert mesh.n_tets < 10_000
    hole = mesh.points[mesh.boundaries["hole"]]
    r = np.linalg.norm(hole[..., :2] - [1.0, 0.5], axis=-1)
    assert np.abs(r - 0.25).max() < 1e-9


def test_reading_a_file_does_not_import_gmsh():
    code = (
        "import sys; from fem_frac.mesh.reader import read_mesh_file; "
        f"m = read_mesh_file({str(MESHES / 'block_with_hole.msh')!r}); "
        "assert m.n_tets > 0; assert 'gmsh' not in sys.modules, 'gmsh imported'"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.mark.parametrize(
    "change,words",
    [
        (lambda p, t: p.__setitem__((4, 1), np.nan), r"1 points have non-finite coordinates"),
        (lambda p, t: p.__setitem__((4, 2), np.inf), r"non-finite coordinates \(first: point 4\)"),
        (lambda p, t: p.__setitem__((4, 0), 1e200), r"coordinates up to 1e\+200"),
        (lambda p, t: t.__setitem__((2, 1), 10**6), r"1 tetra cells name nodes outside 0\.\.\d+"),
        (lambda p, t: t.__setitem__((0, 3), -1), r"outside 0\.\.\d+ \(first: cell 0"),
    ],
    ids=["nan", "inf", "huge", "index-high", "index-negative"],
)
def test_non_finite_points_and_indices_out_of_range_raise(tmp_path, change, words):
    base = structured_box((2, 2, 2))
    points, tets = base.points.copy(), base.tets.copy()
    change(points, tets)
    meshio.write(tmp_path / "bad.vtu", meshio.Mesh(points, [("tetra", tets)]))
    with pytest.raises(MeshError, match=words) as info:
        read_mesh_file(tmp_path / "bad.vtu")
    assert "\n" not in str(info.value)


def test_triangle_indices_out_of_range_raise(tmp_path):
    base = structured_box((2, 2, 2))
    tris = exterior_facets(base.tets)[:4].copy()
    tris[1, 0] = len(base.points) + 3
    cells = [("tetra", base.tets), ("triangle", tris)]
    meshio.write(tmp_path / "bad.vtu", meshio.Mesh(base.points, cells))
    with pytest.raises(MeshError, match="1 triangle cells name nodes outside"):
        read_mesh_file(tmp_path / "bad.vtu")


def test_truncated_gmsh_file_raises_one_line(tmp_path):
    whole = (MESHES / "block_with_hole.msh").read_bytes()
    for fraction in (0.1, 0.5, 0.9):
        path = tmp_path / f"cut{fraction}.msh"
        path.write_bytes(whole[: int(len(whole) * fraction)])
        with pytest.raises(MeshError) as info:
            read_mesh_file(path)
        assert str(path) in str(info.value) and "\n" not in str(info.value)
