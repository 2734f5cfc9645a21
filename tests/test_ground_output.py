"""The ground planes of rigid fragments in the output: ``<name>_ground.vtu``, one square per
plane, in the plane, facing along its normal, covering the scene; readable by meshio and
pyvista; shown by the ParaView script; nothing written without planes."""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest

from fem_frac.config import load_case
from fem_frac.rigid.contact import Plane
from fem_frac.rigid.stage import planes as case_planes
from fem_frac.writers.directory import Manifest, listed
from fem_frac.writers.ground import ground_quads, half_side, in_plane_axes, write_ground
from fem_frac.writers.paraview import script_text, write_paraview_script

CASES = Path(__file__).parent.parent / "cases"


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


# a horizontal ground, a tilted wall far from the origin, an upside-down ceiling, and a plane
# whose normal is a world axis other than z
PLANES = (
    Plane(np.array([0.0, 0.0, -0.5]), np.array([0.0, 0.0, 1.0]), 0.3, 0.6),
    Plane(np.array([40.0, -3.0, 7.0]), _unit([1.0, 2.0, -0.5]), 0.8, 0.1),
    Plane(np.array([0.0, 0.0, 2.0]), np.array([0.0, 0.0, -1.0]), 0.0, 0.0),
    Plane(np.array([-1.0, 0.2, 0.0]), np.array([1.0, 0.0, 0.0]), 1.0, 2.5),
)


@pytest.fixture
def scene():
    """A beam-like cloud of points: 1 x 0.1 x 0.1, not at the origin."""
    rng = np.random.default_rng(7)
    return rng.random((200, 3)) * [1.0, 0.1, 0.1] + [0.3, -0.2, 0.1]


def _diagonal(points):
    return float(np.linalg.norm(np.ptp(points, axis=0)))


def test_squares_lie_in_their_planes_and_face_along_the_normal(scene):
    quads = ground_quads(PLANES, scene)
    assert quads.shape == (len(PLANES), 4, 3)
    for plane, q in zip(PLANES, quads, strict=True):
        scale = np.linalg.norm(plane.point) + np.abs(q).max()
        np.testing.assert_allclose((q - plane.point) @ plane.normal, 0.0,
                                   atol=1e-14 * scale)
        # a square: equal sides, right angles, counter-clockwise about the normal
        edges = np.roll(q, -1, axis=0) - q
        lengths = np.linalg.norm(edges, axis=1)
        np.testing.assert_allclose(lengths, 2 * half_side(plane, scene), rtol=1e-13)
        np.testing.assert_allclose(np.einsum("ij,ij->i", edges, np.roll(edges, -1, axis=0)),
                                   0.0, atol=1e-13 * lengths[0] ** 2)
        np.testing.assert_allclose(_unit(np.cross(edges[0], edges[1])), plane.normal,
                                   atol=1e-14)


def test_squares_cover_the_projection_of_the_scene_and_the_reach_of_a_fall(scene):
    """Centred at the projection of the bounding box's centre; every point of the scene
    projects at least a diagonal inside the square; the half side exceeds the range
    2 sqrt(2) h of a fragment thrown from the highest point h above the plane at the speed
    it gains falling h."""
    d = _diagonal(scene)
    centre = 0.5 * (scene.min(axis=0) + scene.max(axis=0))
    for plane, q in zip(PLANES, ground_quads(PLANES, scene), strict=True):
        s = half_side(plane, scene)
        foot = centre - ((centre - plane.point) @ plane.normal) * plane.normal
        np.testing.assert_allclose(q.mean(axis=0), foot, atol=1e-13 * (1 + np.abs(foot).max()))
        t1, t2 = in_plane_axes(plane.normal)
        local = (scene - foot) @ np.column_stack([t1, t2])
        assert np.abs(local).max() <= s - d + 1e-12
        h = max(((scene - plane.point) @ plane.normal).max(), 0.0)
        assert s >= 2 * np.sqrt(2) * h and s >= 1.5 * d
    # the breaking beam: 1 m long, its top 0.6 m above the ground: s = 1.5 D + 3 * 0.6
    ground = PLANES[0]
    box = np.array([[0, 0, 0], [1, 0.1, 0.1]], dtype=float)
    assert half_side(ground, box) == pytest.approx(1.5 * np.sqrt(1.02) + 1.8)
    # the ceiling, 2 m above the beam's underside, faces down at it: its height counts
    assert half_side(PLANES[2], box) == pytest.approx(1.5 * np.sqrt(1.02) + 3 * 2.0)
    # a plane with the whole scene behind it: sized by the scene alone
    behind = Plane(np.array([0.0, 0.0, -0.5]), np.array([0.0, 0.0, -1.0]))
    assert half_side(behind, box) == pytest.approx(1.5 * np.sqrt(1.02))


def test_in_plane_axes_follow_the_world_axes_for_a_level_ground():
    t1, t2 = in_plane_axes([0.0, 0.0, 1.0])
    np.testing.assert_array_equal(t1, [1.0, 0.0, 0.0])
    np.testing.assert_array_equal(t2, [0.0, 1.0, 0.0])
    for n in (p.normal for p in PLANES):
        t1, t2 = in_plane_axes(n)
        np.testing.assert_allclose(np.column_stack([t1, t2, n]).T
                                   @ np.column_stack([t1, t2, n]), np.eye(3), atol=1e-15)
        np.testing.assert_allclose(np.cross(t1, t2), n, atol=1e-15)


def test_the_file_is_read_by_meshio_and_pyvista_with_its_fields(tmp_path, scene):
    pyvista = pytest.importorskip("pyvista")
    manifest = Manifest(tmp_path)
    path = write_ground(manifest, "beam", PLANES, scene)
    assert path == tmp_path / "beam_ground.vtu" and path.is_file()
    assert "beam_ground.vtu" in listed(tmp_path)  # recorded before it was written
    assert not (tmp_path / "beam_ground.vtu.tmp").exists()

    m = meshio.read(path)
    assert [c.type for c in m.cells] == ["quad"] and len(m.cells[0].data) == len(PLANES)
    corners = m.points[m.cells[0].data]
    np.testing.assert_allclose(corners, ground_quads(PLANES, scene), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(m.cell_data["obstacle_id"][0], np.arange(len(PLANES)))
    np.testing.assert_array_equal(m.cell_data["restitution"][0],
                                  [p.restitution for p in PLANES])
    np.testing.assert_array_equal(m.cell_data["friction"][0], [p.friction for p in PLANES])
    np.testing.assert_allclose(m.cell_data["normal"][0], [p.normal for p in PLANES])

    grid = pyvista.read(path)
    assert grid.n_cells == len(PLANES) and grid.n_points == 4 * len(PLANES)
    assert set(grid.celltypes) == {pyvista.CellType.QUAD}
    for name in ("obstacle_id", "restitution", "friction", "normal"):
        assert name in grid.cell_data
    np.testing.assert_array_equal(grid.cell_data["friction"], [p.friction for p in PLANES])
    # as pyvista reads them, the quads turn counter-clockwise about the planes' normals
    q = grid.points[grid.cells_dict[pyvista.CellType.QUAD]]
    turn = np.cross(q[:, 1] - q[:, 0], q[:, 3] - q[:, 0])
    np.testing.assert_allclose(turn / np.linalg.norm(turn, axis=1)[:, None],
                               [p.normal for p in PLANES], atol=1e-14)


def test_a_directory_takes_its_own_manifest(tmp_path, scene):
    path = write_ground(tmp_path, "run", PLANES[:1], scene)
    assert path == tmp_path / "run_ground.vtu"
    assert listed(tmp_path) == ["run_ground.vtu.tmp", "run_ground.vtu"]
    assert meshio.read(path).cell_data["obstacle_id"][0].tolist() == [0]


def test_no_planes_no_file(tmp_path, scene):
    assert write_ground(Manifest(tmp_path), "beam", (), scene) is None
    assert list(tmp_path.iterdir()) == []


def test_the_planes_of_the_breaking_beam(tmp_path):
    """From the case, as the driver gets them: the ground under the beam, 0.5 m down."""
    case, _ = load_case(CASES / "breaking_beam.yaml")
    box = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 0.1) for z in (0.0, 0.1)])
    path = write_ground(tmp_path, "breaking_beam", case_planes(case.fragments), box)
    m = meshio.read(path)
    np.testing.assert_allclose(m.points[:, 2], -0.5)
    np.testing.assert_allclose(m.points.mean(axis=0), [0.5, 0.05, -0.5], atol=1e-15)
    assert m.cell_data["restitution"][0].tolist() == [0.3]
    assert m.cell_data["friction"][0].tolist() == [0.6]


@pytest.mark.parametrize("ground", [True, False])
def test_the_view_script_shows_the_ground(tmp_path, ground):
    path = write_paraview_script(tmp_path, "beam", 1.0, False, ground=ground)
    text = path.read_text()
    compile(text, str(path), "exec")
    assert f"GROUND = {ground}" in text
    for name in ("XMLUnstructuredGridReader", '"_ground.vtu"', "Opacity", "DiffuseColor"):
        assert name in text
    assert script_text("beam", 1.0, False, tmp_path, ground) == text
    # the script as it was without the argument
    assert script_text("beam", 1.0, False, tmp_path) == script_text("beam", 1.0, False,
                                                                     tmp_path, False)
