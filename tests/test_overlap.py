"""The overlap check of an output series (fem_frac.app.overlap, `fem-frac overlap`)."""

import json

import meshio
import numpy as np
import pytest

from fem_frac.app.cli import main
from fem_frac.app.overlap import TOLERANCE, run_overlaps

# the six tets of the unit cube around its diagonal 0-6 (Kuhn), corners in VTK hexahedron order
CORNERS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                    [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=float)
KUHN = np.array([[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6],
                 [0, 5, 1, 6]])


def box(lo, hi):
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return lo + CORNERS * (hi - lo), KUHN.copy()


def write_run(directory, frames, ground=None):
    """A run's output: one .vtu per frame (a list of boxes, fragment_id = their index, the
    last box displaced by ``shift``), the .pvd, and a ground plane file when asked."""
    directory.mkdir()
    entries = []
    for n, (boxes, shift) in enumerate(frames):
        points, cells, ids = [], [], []
        for k, (p, t) in enumerate(boxes):
            cells.append(t + sum(len(q) for q in points))
            points.append(p)
            ids.append(np.full(len(t), k, dtype=np.int32))
        points = np.concatenate(points)
        displacement = np.zeros_like(points)
        displacement[-8:] = shift  # the last box moves
        name = f"r_{n:06d}.vtu"
        meshio.write(directory / name, meshio.Mesh(
            points, [("tetra", np.concatenate(cells))],
            point_data={"displacement": displacement},
            cell_data={"fragment_id": [np.concatenate(ids)]}))
        entries.append(f'<DataSet timestep="{n}" part="0" file="{name}"/>')
    (directory / "r.pvd").write_text(
        '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n<Collection>\n'
        + "\n".join(entries) + "\n</Collection>\n</VTKFile>\n")
    if ground is not None:
        point, normal = ground
        quad = point + np.array([[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]], float)
        meshio.write(directory / "r_ground.vtu", meshio.Mesh(
            quad, [("quad", np.array([[0, 1, 2, 3]]))],
            cell_data={"normal": [np.array([normal], float)]}))


def test_a_corner_inside_another_body_is_measured_to_its_surface(tmp_path):
    """A 1 x 0.5 x 0.5 box whose end reaches 0.1 into a unit cube (its corners 0.1 from
    the cube's face, 0.25 from the others): depth 0.1, over the smaller body's size
    0.25^(1/3). Moved away by its displacement in the next frame: no overlap; touching
    face to face: depth zero."""
    cube = box([0, 0, 0], [1, 1, 1])
    bar = box([0.9, 0.25, 0.25], [1.9, 0.75, 0.75])
    frames = [([cube, bar], 0.0), ([cube, bar], [0.2, 0, 0]), ([cube, bar], [0.1, 0, 0])]
    write_run(tmp_path / "out", frames)
    first, apart, touching = run_overlaps(tmp_path / "out")
    assert first.depth == pytest.approx(0.1, rel=1e-9)
    assert first.fraction == pytest.approx(0.1 / 0.25 ** (1 / 3), rel=1e-9)
    assert set(first.pair) == {"0", "1"}
    assert apart.depth == 0.0 and touching.depth == pytest.approx(0.0, abs=1e-12)


def test_a_body_below_the_ground_plane_and_the_exit_code(tmp_path, capsys):
    """A unit cube 0.05 below a plane z = 0: depth 0.05 = 5 % of its size, beyond the 1 %
    tolerance: exit 1; lifted onto the plane: within it, exit 0."""
    below = box([0, 0, -0.05], [1, 1, 0.95])
    write_run(tmp_path / "a", [([below], 0.0)], ground=(np.zeros(3), [0, 0, 1]))
    (o,) = run_overlaps(tmp_path / "a")
    assert o.depth == pytest.approx(0.05, rel=1e-9) and o.pair == ("0", "ground 0")
    assert main(["overlap", str(tmp_path / "a")]) == 1
    assert "beyond the 1 % tolerance" in capsys.readouterr().out
    write_run(tmp_path / "b", [([below], [0, 0, 0.05])], ground=(np.zeros(3), [0, 0, 1]))
    assert run_overlaps(tmp_path / "b")[0].fraction <= TOLERANCE
    assert main(["overlap", str(tmp_path / "b")]) == 0


def test_no_series_is_an_error(tmp_path, capsys):
    assert main(["overlap", str(tmp_path)]) == 2
    assert "no .pvd series" in capsys.readouterr().err


def test_the_series_named_in_the_summary_is_read(tmp_path):
    cube = box([0, 0, 0], [1, 1, 1])
    write_run(tmp_path / "out", [([cube], 0.0)])
    (tmp_path / "out" / "other.pvd").write_text("<VTKFile/>")  # not the run's series
    (tmp_path / "out" / "summary.json").write_text(json.dumps(
        {"output": {"pvd": str(tmp_path / "out" / "r.pvd")}}))
    assert len(run_overlaps(tmp_path / "out")) == 1


def write_fixed(directory, solid_bounds, plane_z=None):
    """``r_obstacles.pvd``: one frame holding a fixed box obstacle (a closed triangle
    surface, obstacle 0) and, when asked, a plane z = ``plane_z`` drawn as an open square
    (obstacle 1), as the run writes them."""
    import pyvista as pv

    box_surface = pv.Box(bounds=solid_bounds).triangulate()
    # its corners exactly the bounds (pyvista's points are single precision)
    lo, hi = np.array(solid_bounds[0::2], float), np.array(solid_bounds[1::2], float)
    corners = np.asarray(box_surface.points, dtype=float)
    points = [np.where(np.abs(corners - lo) < np.abs(corners - hi), lo, hi)]
    triangles = [np.asarray(box_surface.faces).reshape(-1, 4)[:, 1:]]
    ids = [np.zeros(len(triangles[0]), dtype=np.int32)]
    if plane_z is not None:
        square = np.array([[-5, -5, plane_z], [5, -5, plane_z], [5, 5, plane_z],
                           [-5, 5, plane_z]], float)
        triangles.append(np.array([[0, 1, 2], [0, 2, 3]]) + len(points[0]))
        points.append(square)
        ids.append(np.ones(2, dtype=np.int32))
    ids = np.concatenate(ids)
    normals = np.tile([0.0, 0.0, 1.0], (len(ids), 1))
    meshio.write(directory / "r_obstacles_000000.vtu", meshio.Mesh(
        np.concatenate(points), [("triangle", np.concatenate(triangles))],
        cell_data={"obstacle_id": [ids], "normal": [normals]}))
    (directory / "r_obstacles.pvd").write_text(
        '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n<Collection>\n'
        '<DataSet timestep="0" part="0" file="r_obstacles_000000.vtu"/>\n'
        "</Collection>\n</VTKFile>\n")


def test_fixed_obstacles_count_as_solids_and_planes(tmp_path):
    """A fixed 1 x 0.4 x 0.4 box obstacle whose end reaches 0.05 into a unit cube: depth
    0.05 over the smaller size (the obstacle's 0.16^(1/3)); an obstacle plane z = 0.02
    drawn as an open square: the cube's bottom 0.02 below it."""
    write_run(tmp_path / "out", [([box([0, 0, 0], [1, 1, 1])], 0.0)])
    write_fixed(tmp_path / "out", (0.95, 1.95, 0.3, 0.7, 0.3, 0.7))
    (o,) = run_overlaps(tmp_path / "out")
    assert o.depth == pytest.approx(0.05, rel=1e-9) and o.pair == ("0", "obstacle 0")
    assert o.fraction == pytest.approx(0.05 / 0.16 ** (1 / 3), rel=1e-9)
    write_run(tmp_path / "b", [([box([0, 0, 0], [1, 1, 1])], 0.0)])
    write_fixed(tmp_path / "b", (3, 4, 3, 4, 3, 4), plane_z=0.02)
    (o,) = run_overlaps(tmp_path / "b")
    assert o.depth == pytest.approx(0.02, rel=1e-9) and o.pair == ("0", "ground 0")
