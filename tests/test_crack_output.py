"""The crack-face series and the ParaView view script.

Every step of the crack series is read back by meshio and by VTK (pyvista), before the
first crack, with cracks, and once no finite element is left. On a bar pulled apart the
faces between the two pieces open by the gap between them (the end displacement: one piece
rests, the other moves with the loaded end), along x, and carry the step they opened in.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import meshio
import numpy as np
import pytest

from fem_frac.app.driver import prepare, simulate
from fem_frac.app.results import CrackWriter, write_crack_surface
from fem_frac.config.schema import Case
from fem_frac.fem.space import build_space
from fem_frac.fracture import open_crack
from fem_frac.fracture.summary import crack_faces
from fem_frac.timing import StageTimer
from fem_frac.writers.paraview import script_text, view_scale, write_paraview_script
from fem_frac.writers.series import SeriesWriter
from meshes import structured_box

pyvista = pytest.importorskip("pyvista")

END = 2.1e-5  # the bar's end displacement at t = 1 (cases/bar_tension_break.yaml)
STEPS = 20


def bar_case() -> dict:
    """The bar of cases/bar_tension_break.yaml: it breaks in step 10, in two."""
    return {
        "mesh": {"geometry": {"type": "box", "lengths": [0.1, 0.02, 0.02]},
                 "element_size": 0.005},
        "material": {"youngs_modulus": 30e9, "poissons_ratio": 0.2, "density": 2400},
        "boundary_conditions": [
            {"type": "symmetry", "boundary": "xmin"},
            {"type": "symmetry", "boundary": "ymin"},
            {"type": "symmetry", "boundary": "zmin"},
            {"type": "displacement", "boundary": "xmax", "x": END},
        ],
        "fracture": {"tensile_strength": 3e6, "smoothing": {"length": 0.006},
                     "batch_size": 1, "passes": 200, "max_insertions_per_step": 200,
                     "protect": [{"boundary": "xmin"}, {"boundary": "xmax"}]},
        "analysis": {"type": "quasi_static", "steps": STEPS},
    }


class CrackOutput:
    """What the output stage does with a CrackWriter: record every step, write it."""

    name = "cracks"

    def __init__(self, writer: CrackWriter):
        self.writer, self.last_mesh, self.meshes = writer, None, []

    def __call__(self, step, world):
        if world.body is not None:
            self.last_mesh = world.body.mesh
        self.meshes.append(self.last_mesh)
        self.writer.record(step.n, world)
        self.writer.write(world, self.last_mesh)
        return world, None


@pytest.fixture(scope="module")
def bar(tmp_path_factory):
    out = tmp_path_factory.mktemp("bar")
    timer = StageTimer()
    setup = prepare(Case.model_validate(bar_case()), Path("."), timer)
    output = CrackOutput(CrackWriter(SeriesWriter(out, "bar_crack")))
    world, _ = simulate(setup, timer, observers=(output,))
    return out, output, world


def read_both(path: Path):
    """The step as meshio and as VTK read it (both must)."""
    return meshio.read(path), pyvista.read(path)


def triangles(m) -> np.ndarray:
    return m.cells_dict.get("triangle", np.zeros((0, 3), dtype=int))


def test_every_step_is_readable_by_meshio_and_vtk(bar):
    out, output, _ = bar
    files = sorted(out.glob("bar_crack_*.vtu"))
    assert len(files) == STEPS + 1
    reader = pyvista.get_reader(str(out / "bar_crack.pvd"))
    assert len(reader.time_values) == STEPS + 1
    for n, path in enumerate(files):
        m, grid = read_both(path)
        faces = len(crack_faces(output.meshes[n]))
        assert len(triangles(m)) == faces == (grid.n_cells if faces else 0)
        for name in ("opening", "opening_norm", "normal_opening", "normal", "opened_step",
                     "opened_time"):
            assert name in m.cell_data and name in grid.cell_data
        assert m.point_data["displacement"].shape == (len(m.points), 3)
        if faces == 0:  # the stand-in: one vertex cell, no face
            assert [c.type for c in m.cells] == ["vertex"]
            assert m.cell_data["opened_step"][0].tolist() == [-1]
            assert grid.n_cells == 1
    reader.set_active_time_point(STEPS)
    assert reader.read()[0].n_cells > 0


def test_faces_appear_in_the_step_the_bar_breaks(bar):
    out, _, _ = bar
    counts = [len(triangles(meshio.read(p))) for p in sorted(out.glob("bar_crack_*.vtu"))]
    first = next(n for n, c in enumerate(counts) if c)
    assert first == 10  # 3 MPa reached during step 10 (tests/test_fracture.py)
    for path in sorted(out.glob("bar_crack_*.vtu"))[first:]:
        m = meshio.read(path)
        np.testing.assert_array_equal(m.cell_data["opened_step"][0], first)
        np.testing.assert_array_equal(m.cell_data["opened_time"][0], first / STEPS)


def test_the_faces_between_the_pieces_open_by_the_gap_along_x(bar):
    """After the break one piece rests (symmetry on xmin) and the other moves with the end
    (u_x = END t): the faces between them open by (END t, 0, 0) up to the sign of their
    side a, the faces of crack branches inside one piece not at all; the faces' point
    displacement is the mean of the sides, half the gap."""
    out, _, _ = bar
    for n in range(10, STEPS + 1):
        m = meshio.read(out / f"bar_crack_{n:06d}.vtu")
        gap = END * n / STEPS
        opening = m.cell_data["opening"][0]
        size = m.cell_data["opening_norm"][0]
        np.testing.assert_allclose(size, np.linalg.norm(opening, axis=1), rtol=1e-12)
        apart = size > 0.5 * gap
        assert apart.any()
        np.testing.assert_allclose(size[apart], gap, rtol=1e-9)
        np.testing.assert_allclose(np.abs(opening[apart, 0]), gap, rtol=1e-9)
        assert np.abs(opening[apart, 1:]).max() < 1e-9 * gap
        assert size[~apart].max(initial=0.0) < 1e-9 * gap
        normal = m.cell_data["normal"][0]
        np.testing.assert_allclose(m.cell_data["normal_opening"][0],
                                   np.einsum("ki,ki->k", opening, normal), atol=1e-12 * gap)
        corners = m.cells_dict["triangle"][apart].ravel()
        np.testing.assert_allclose(m.point_data["displacement"][corners, 0], gap / 2,
                                   rtol=1e-9)


# --- a box cut by hand: openings exact, P1 and P2, steps remembered across cracks -------


def cut(mesh, x):
    plane = np.flatnonzero(np.abs(mesh.points[:, 0] - x) < 1e-12)
    new, _ = open_crack(mesh, plane, np.tile([1.0, 0.0, 0.0], (len(plane), 1)))
    return new


def world_on(mesh, order, t, jump, shape=None):
    """A world whose body moves every piece right of x by ``jump[x]`` (times ``shape`` of
    the reference position, when given), plus one affine field for all (the same on both
    sides of a face)."""
    from fem_frac.fracture import fragments

    space = build_space(mesh, order)
    _, labels = fragments(mesh.tets)
    nodes = space.element_dofs[:, ::3] // 3
    x = space.node_points
    u = x @ np.array([[1e-3, 2e-3, 0.0], [0.0, 1e-3, 3e-3], [5e-4, 0.0, 1e-3]])
    centroid_x = mesh.points[mesh.tets].mean(axis=1)[:, 0]
    for where, d in jump.items():
        right = np.unique(nodes[centroid_x > where])
        u[right] += d if shape is None else np.outer(shape(x[right]), d)
    disc = SimpleNamespace(space=space, ops=SimpleNamespace(interface=None))
    body = SimpleNamespace(mesh=mesh, disc=disc, labels=labels,
                           state=SimpleNamespace(u=u.ravel(), cohesive=None))
    return SimpleNamespace(t=t, body=body)


@pytest.mark.parametrize("order", [1, 2])
def test_openings_and_steps_on_a_box_cut_twice(tmp_path, order):
    box = structured_box((4, 2, 2))
    once = cut(box, 0.25)
    twice = cut(once, 0.75)
    d1, d2 = np.array([0.01, 0.0, 0.0]), np.array([0.0, 0.02, 0.0])
    writer = CrackWriter(SeriesWriter(tmp_path, "box_crack"))
    worlds = [(0, world_on(box, order, 0.0, {})), (3, world_on(once, order, 0.3, {0.25: d1})),
              (4, world_on(once, order, 0.4, {0.25: d1})),
              (5, world_on(twice, order, 0.5, {0.25: d1, 0.75: d2}))]
    for n, world in worlds:
        writer.record(n, world)
        writer.write(world, world.body.mesh)
    assert [c.type for c in meshio.read(tmp_path / "box_crack_000000.vtu").cells] == ["vertex"]
    m = meshio.read(tmp_path / "box_crack_000001.vtu")
    assert len(triangles(m)) == 2 * 2 * 2  # the plane x = 0.25: 2 x 2 squares
    np.testing.assert_allclose(m.cell_data["opening"][0], np.tile(d1, (8, 1)), atol=1e-15)
    np.testing.assert_allclose(m.cell_data["normal"][0], np.tile([1.0, 0, 0], (8, 1)))
    np.testing.assert_allclose(m.cell_data["normal_opening"][0], 0.01)
    assert set(m.cell_data["opened_step"][0]) == {3}
    last = meshio.read(sorted(tmp_path.glob("box_crack_*.vtu"))[-1])
    x = last.points[last.cells_dict["triangle"]].mean(axis=1)[:, 0]
    first, second = np.abs(x - 0.25) < 1e-12, np.abs(x - 0.75) < 1e-12
    assert first.sum() == second.sum() == 8
    np.testing.assert_array_equal(last.cell_data["opened_step"][0][first], 3)
    np.testing.assert_array_equal(last.cell_data["opened_step"][0][second], 5)
    np.testing.assert_allclose(last.cell_data["opened_time"][0][second], 0.5)
    # the right piece of the second cut moved by d1 + d2, the middle one by d1
    np.testing.assert_allclose(last.cell_data["opening"][0][first], np.tile(d1, (8, 1)),
                               atol=1e-15)
    np.testing.assert_allclose(last.cell_data["opening"][0][second], np.tile(d2, (8, 1)),
                               atol=1e-15)
    np.testing.assert_allclose(last.cell_data["normal_opening"][0][second], 0.0, atol=1e-15)


@pytest.mark.parametrize("order", [1, 2])
def test_the_opening_is_the_jump_at_the_centroid(tmp_path, order):
    """A jump varying as y^2 + z across the cut: at the centroid of every face, as the
    element interpolates it (P1: the corners' mean; P2: exact for a quadratic)."""
    mesh = cut(structured_box((4, 3, 3)), 0.5)
    d = np.array([0.01, 0.0, 0.0])
    world = world_on(mesh, order, 1.0, {0.5: d}, shape=lambda x: x[:, 1] ** 2 + x[:, 2])
    writer = CrackWriter(SeriesWriter(tmp_path, "c"))
    writer.record(1, world)
    m = meshio.read(writer.write(world, mesh))
    corners = m.points[m.cells_dict["triangle"]]  # (k, 3, 3)
    f = corners[..., 1] ** 2 + corners[..., 2]
    c = corners.mean(axis=1)
    expected = f.mean(axis=1) if order == 1 else c[:, 1] ** 2 + c[:, 2]
    np.testing.assert_allclose(m.cell_data["opening"][0][:, 0], 0.01 * expected, rtol=1e-12)
    if order == 2:  # the corners' mean would differ
        assert np.abs(f.mean(axis=1) - expected).max() > 1e-3


def test_sides_are_paired_corner_by_corner_and_named_by_position():
    mesh = cut(structured_box((4, 3, 3)), 0.5)
    faces = crack_faces(mesh)
    assert len(faces) == len(mesh.boundaries["crack"]) // 2 and len(faces.unpaired) == 0
    np.testing.assert_array_equal(mesh.points[faces.a], mesh.points[faces.b])
    assert np.all(faces.a != faces.b)  # every corner of the plane was split
    # the normal is side a's own (right-hand) normal, pointing to +x here
    p = mesh.points[faces.a]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    np.testing.assert_allclose(n / np.linalg.norm(n, axis=1, keepdims=True), faces.normal)
    assert np.all(faces.normal[:, 0] > 0.9)
    assert len(set(faces.keys)) == len(faces)


def test_no_finite_element_left_still_writes_a_readable_step(tmp_path, bar):
    """Once every piece is rigid (no body) the step is the stand-in at the last mesh."""
    _, output, world = bar
    writer = CrackWriter(SeriesWriter(tmp_path, "gone_crack"))
    writer.record(0, world)
    writer.write(world, world.body.mesh)
    writer.record(1, SimpleNamespace(t=2.0, body=None))
    path = writer.write(SimpleNamespace(t=2.0, body=None), output.last_mesh)
    m, grid = read_both(path)
    assert [c.type for c in m.cells] == ["vertex"] and grid.n_cells == 1
    lo, hi = output.last_mesh.points.min(axis=0), output.last_mesh.points.max(axis=0)
    np.testing.assert_allclose(m.points[0], (lo + hi) / 2)


def test_a_plain_series_writer_still_gets_the_crack_faces(tmp_path, bar):
    """write_crack_surface with a SeriesWriter (no steps recorded): the faces with the time
    they were first written, the step unknown (-1)."""
    _, _, world = bar
    series = SeriesWriter(tmp_path, "plain_crack")
    write_crack_surface(series, world, world.body.mesh)
    write_crack_surface(series, SimpleNamespace(t=9.0, body=world.body), world.body.mesh)
    m = meshio.read(tmp_path / "plain_crack_000001.vtu")
    assert len(triangles(m)) == len(crack_faces(world.body.mesh)) > 0
    assert set(m.cell_data["opened_step"][0]) == {-1}
    np.testing.assert_array_equal(m.cell_data["opened_time"][0], world.t)


def test_a_run_whose_body_turns_rigid_writes_readable_crack_steps(tmp_path):
    """Through the command line: a body free of supports is handed off after step 1, and
    every step of its crack series reads back."""
    from fem_frac.app.cli import main
    from solve import write_case

    case = {
        "mesh": {"geometry": {"type": "box", "lengths": [0.2, 0.1, 0.1]}, "element_size": 0.05},
        "material": {"youngs_modulus": 1e9, "poissons_ratio": 0.3, "density": 1000.0},
        "fracture": {"tensile_strength": 1e12, "smoothing": {"rings": 1}},
        "fragments": {},
        "analysis": {"type": "dynamic", "dt": 0.01, "steps": 4,
                     "initial_velocity": {"uniform": [1.0, 0.0, 2.0]}},
        "output": {"crack_surface": True},
    }
    path = write_case(tmp_path / "free.yaml", case)
    out = tmp_path / "out"
    assert main(["run", str(path), "-o", str(out), "-q"]) == 0
    files = sorted(out.glob("free_crack_*.vtu"))
    assert len(files) == 5
    for f in files:
        m, grid = read_both(f)
        assert [c.type for c in m.cells] == ["vertex"] and grid.n_cells == 1


# --- the ParaView script ------------------------------------------------------------------


def test_view_scale_shows_the_largest_displacement_at_4_to_10_percent():
    points = np.array([[0.0, 0.0, 0.0], [0.1, 0.02, 0.02]])
    diagonal = np.linalg.norm([0.1, 0.02, 0.02])
    for u in (2.1e-5, 3e-6, 1e-4, 7.7e-4):
        scale = view_scale(u, points)
        assert 0.04 * diagonal < scale * u <= 0.1 * diagonal * (1 + 1e-12)
        mantissa = scale / 10.0 ** np.floor(np.log10(scale))
        assert round(mantissa, 9) in (1.0, 2.0, 5.0)
    assert view_scale(0.05, points) == 1.0  # already visible: true scale
    assert view_scale(0.0, points) == 1.0


@pytest.mark.parametrize("cracks", [True, False])
def test_view_script_compiles_and_names_the_series(tmp_path, cracks):
    path = write_paraview_script(tmp_path, "plate", 50.0, cracks)
    assert path == tmp_path / "plate_view.py"
    text = path.read_text()
    compile(text, str(path), "exec")
    assert "NAME = 'plate'" in text and "WARP = 50.0" in text
    assert f"CRACKS = {cracks}" in text
    for name in ("PVDReader", "WarpByVector", "ColorBy", "Show", "Render", "von_mises",
                 "displacement", "opening_norm"):
        assert name in text
    assert script_text("plate", 50.0, cracks, tmp_path) == text


def test_crack_measures_count_a_face_once_whatever_left():
    """Cut a unit-section bar across: one crack face per face of the section, area 1; once
    the piece on one side leaves the mesh the faces and the area stay (one side each)."""
    from fem_frac.fracture.summary import crack_measures
    from fem_frac.fracture.topology import extract, fragments

    mesh = cut(structured_box((4, 3, 3)), 0.5)
    whole = crack_measures(mesh)
    assert whole.faces == len(mesh.boundaries["crack"]) // 2
    _, labels = fragments(mesh.tets)
    right = labels == labels[np.argmax(mesh.points[mesh.tets].mean(axis=1)[:, 0])]
    left, _ = extract(mesh, ~right)
    half = crack_measures(left)
    assert half.faces == whole.faces and len(left.boundaries["crack"]) == whole.faces
    area = 1.0 * 1.0  # the section of structured_box's unit cube
    assert whole.area == pytest.approx(area, rel=1e-12)
    assert half.area == pytest.approx(area, rel=1e-12)
