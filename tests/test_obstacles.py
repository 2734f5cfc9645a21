"""Obstacles: the case's ``obstacles`` refused where wrong (located, exit 2), their exact
mass properties, their contact geometry, a moving one in free flight, and the output (the
moving ones in the main series, the fixed ones and planes in ``<name>_obstacles.pvd``)."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import meshio
import numpy as np
import pytest

from fem_frac.app.cli import main
from fem_frac.config import load_case
from fem_frac.errors import CaseError
from fem_frac.rigid.body import (
    inverse_inertia_world,
    point_velocities,
    rotation_matrix,
    velocity,
)
from fem_frac.rigid.obstacle_output import drawing, fixed_surface, rigid_bodies, world_surface
from fem_frac.rigid.obstacles import (
    CYLINDER_GAP,
    CYLINDER_SEGMENTS,
    SPHERE_GAP,
    box_surface,
    build_obstacles,
    cylinder_surface,
    icosphere,
    surface_mass_properties,
)
from fem_frac.writers.paraview import script_text

# A brick that is rigid from the start (no finite-element solve: fast), flying under gravity.
BASE = textwrap.dedent("""\
    mesh:
      geometry: {type: box, origin: [0, 0, 0], lengths: [0.3, 0.2, 0.1]}
      element_size: 0.1
    material: {youngs_modulus: 210e9, poissons_ratio: 0.3, density: 7850}
    fragments: {whole_body: true, gravity: [0, 0, -9.81]}
    analysis: {type: dynamic, dt: 0.01, steps: 20, output_every: 5}
    obstacles:
    """)
SPHERE = "  - {type: sphere, center: [5, 0, 0], radius: 0.1, density: 1000}\n"


def _write_stl(path: Path, points, triangles) -> Path:
    meshio.write(path, meshio.Mesh(np.asarray(points, dtype=float),
                                   [("triangle", np.asarray(triangles))]), binary=False)
    return path


def _one_error(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


# --- refusals: one located line, exit 2 ----------------------------------------------------

# (id, the obstacle's line(s), line named, key named, words)
BAD = [
    ("radius <= 0", "  - {type: sphere, center: [0, 0, 1], radius: 0, density: 1}\n", 8,
     "obstacles[0].radius", "must be > 0"),
    ("radius not finite", "  - {type: sphere, center: [0, 0, 1], radius: .inf, density: 1}\n",
     8, "obstacles[0].radius", "finite"),
    ("box size <= 0", "  - {type: box, center: [0, 0, 1], size: [1, -1, 1], mass: 1}\n", 8,
     "obstacles[0].size[1]", "must be > 0"),
    ("zero axis", "  - {type: cylinder, center: [0, 0, 1], axis: [0, 0, 0], radius: 1, "
     "height: 1, fixed: true}\n", 8, "obstacles[0].axis", "must not be zero"),
    ("zero normal", "  - {type: plane, point: [0, 0, -1], normal: [0, 0, 0]}\n", 8,
     "obstacles[0].normal", "must not be zero"),
    ("neither density nor mass", "  - {type: sphere, center: [0, 0, 1], radius: 1}\n", 8,
     "obstacles[0]", "give 'density' or 'mass'"),
    ("density and mass", "  - {type: sphere, center: [0, 0, 1], radius: 1, density: 1,\n"
     "     mass: 2}\n", 9, "obstacles[0].mass", "not both"),
    ("fixed with a velocity", "  - {type: box, center: [0, 0, 1], size: [1, 1, 1], fixed: "
     "true,\n     velocity: [1, 0, 0]}\n", 9, "obstacles[0].velocity", "never moves"),
    ("fixed with a density", "  - {type: box, center: [0, 0, 1], size: [1, 1, 1], fixed: "
     "true,\n     density: 3}\n", 9, "obstacles[0].density", "infinite mass"),
    ("restitution > 1", "  - {type: sphere, center: [0, 0, 1], radius: 1, density: 1,\n"
     "     restitution: 1.5}\n", 9, "obstacles[0].restitution", "must be <= 1"),
    ("friction < 0", "  - {type: plane, friction: -0.1}\n", 8, "obstacles[0].friction",
     "must be >= 0"),
    ("axis without angle", "  - {type: box, center: [0, 0, 1], size: [1, 1, 1], mass: 1,\n"
     "     orientation: {axis: [0, 0, 1]}}\n", 9, "obstacles[0].orientation",
     "'axis' and 'angle'"),
    ("short quaternion", "  - {type: box, center: [0, 0, 1], size: [1, 1, 1], mass: 1,\n"
     "     orientation: {quaternion: [1, 0, 0]}}\n", 9, "obstacles[0].orientation.quaternion",
     "4 numbers"),
    ("zero quaternion", "  - {type: box, center: [0, 0, 1], size: [1, 1, 1], mass: 1,\n"
     "     orientation: {quaternion: [0, 0, 0, 0]}}\n", 9,
     "obstacles[0].orientation.quaternion", "must not be zero"),
    ("unknown type", "  - {type: shpere, center: [0, 0, 1], radius: 1, density: 1}\n", 8,
     "obstacles[0]", "did you mean 'sphere'"),
    ("unknown key", "  - {type: sphere, centre: [0, 0, 1], radius: 1, density: 1}\n", 8,
     "obstacles[0].centre", "did you mean 'center'"),
    ("overflowing mass", "  - {type: sphere, center: [0, 0, 1], radius: 1e150, "
     "density: 1e100}\n", 8, "obstacles[0].radius", "out of range"),
    ("missing mesh file", "  - {type: mesh, file: nowhere.stl, density: 1}\n", 8,
     "obstacles[0].file", "no such obstacle mesh file"),
    ("a .geo file", "  - {type: mesh, file: body.geo, density: 1}\n", 8,
     "obstacles[0].file", "not read for an obstacle"),
]


@pytest.mark.parametrize("text,line,key,words", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_obstacles_are_refused_at_their_key(tmp_path, capsys, text, line, key, words):
    case = tmp_path / "case.yaml"
    case.write_text(BASE + text)
    assert main(["check", str(case)]) == 2
    error = _one_error(capsys)
    assert f"{case}:{line}:" in error and f" {key}: " in error and words in error, error


def test_obstacles_need_the_rigid_stage(tmp_path, capsys):
    case = tmp_path / "case.yaml"
    case.write_text(BASE.replace("fragments: {whole_body: true, gravity: [0, 0, -9.81]}\n",
                                 "") + SPHERE)
    assert main(["check", str(case)]) == 2
    error = _one_error(capsys)
    assert f"{case}:6:" in error and " obstacles: " in error and "'fragments'" in error


def _bad_surfaces(tmp_path: Path) -> list[tuple[str, Path, str]]:
    """(id, file, words): files no obstacle can be made of."""
    v, t = box_surface([1.0, 1.0, 1.0])
    flipped = t.copy()
    flipped[0] = flipped[0, [0, 2, 1]]
    garbage = tmp_path / "garbage.stl"
    garbage.write_bytes(b"\x00\x01 not a mesh at all" * 3)
    flat = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=float)
    tets = tmp_path / "tets.vtu"
    meshio.write(tets, meshio.Mesh(v, [("tetra", np.array([[0, 1, 2, 4]]))]))
    return [
        ("open", _write_stl(tmp_path / "open.stl", v, t[1:]), "an open surface"),
        ("inconsistent", _write_stl(tmp_path / "flip.stl", v, flipped), "not consistently"),
        ("flat", _write_stl(tmp_path / "flat.stl", flat[:3], [[0, 1, 2], [0, 2, 1]]),
         "no volume"),
        ("unreadable", garbage, "cannot read the obstacle mesh"),
        ("no triangles", tets, "no triangles"),
    ]


def test_unusable_surface_files_are_refused_at_the_file_key(tmp_path, capsys):
    for name, path, words in _bad_surfaces(tmp_path):
        case = tmp_path / f"{name}.yaml"
        case.write_text(BASE + f"  - {{type: mesh, file: {path.name}, density: 1}}\n")
        assert main(["check", str(case)]) == 2, name
        error = _one_error(capsys)
        assert f"{case}:8:" in error and " obstacles[0].file: " in error, error
        assert words in error and str(path) in error, (name, error)


# --- mass properties ----------------------------------------------------------------------


def _build(tmp_path: Path, text: str):
    case = tmp_path / "case.yaml"
    case.write_text(BASE + text)
    config, _ = load_case(case)
    return build_obstacles(config.obstacles, tmp_path, True)


def _world_inertia(body) -> np.ndarray:
    r = rotation_matrix(body.orientation)
    return (r * body.inertia) @ r.T


def test_primitives_have_their_closed_form_mass_properties(tmp_path):
    """Sphere 2/5 m r^2; box m (b^2 + c^2) / 12 about its edges (turned 40 degrees about
    an oblique axis: the world tensor R diag R^T); cylinder m r^2 / 2 about its axis and
    m (3 r^2 + h^2) / 12 across; a mass given instead of a density."""
    sphere, box, cylinder, heavy = _build(tmp_path, textwrap.dedent("""\
          - {type: sphere, center: [1, 2, 3], radius: 0.3, density: 2000}
          - {type: box, center: [0, 0, 1], size: [0.2, 0.4, 0.6], density: 500,
             orientation: {axis: [1, 2, 2], angle: 40}}
          - {type: cylinder, center: [0, 1, 0], axis: [0, 3, 4], radius: 0.1, height: 0.5,
             density: 7850}
          - {type: cylinder, center: [0, 1, 0], radius: 0.1, height: 0.5, mass: 12}
        """))
    m = 2000 * 4 / 3 * np.pi * 0.3**3
    assert sphere.body.mass == pytest.approx(m, rel=1e-15)
    np.testing.assert_allclose(sphere.body.inertia, 0.4 * m * 0.09, rtol=1e-15)
    np.testing.assert_array_equal(sphere.body.position, [1, 2, 3])

    a, b, c = 0.2, 0.4, 0.6
    m = 500 * a * b * c
    n = np.array([1, 2, 2]) / 3.0
    angle = np.radians(40)
    k = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
    r = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k  # Rodrigues
    expected = r @ np.diag(m / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])) @ r.T
    assert box.body.mass == pytest.approx(m, rel=1e-15)
    np.testing.assert_allclose(_world_inertia(box.body), expected, rtol=0, atol=1e-15 * m)

    m = 7850 * np.pi * 0.01 * 0.5
    axis = np.array([0, 0.6, 0.8])
    across = m * (3 * 0.01 + 0.25) / 12
    expected = across * np.eye(3) + (0.5 * m * 0.01 - across) * np.outer(axis, axis)
    assert cylinder.body.mass == pytest.approx(m, rel=1e-15)
    np.testing.assert_allclose(_world_inertia(cylinder.body), expected, rtol=0,
                               atol=1e-15 * m)
    assert heavy.body.mass == 12 and heavy.density == pytest.approx(12 / (np.pi * 0.005))
    np.testing.assert_allclose(heavy.body.inertia, [12 * 0.28 / 12] * 2 + [0.06], rtol=1e-15)


def test_a_surface_mesh_of_a_box_has_the_box_primitives_properties(tmp_path):
    """The same box as a primitive (turned, off the origin) and as an STL of its 12
    triangles: mass, centre and world inertia agree to round-off."""
    (box,) = _build(tmp_path, "  - {type: box, center: [3, -2, 7], size: [0.2, 0.4, 0.6], "
                    "density: 500,\n     orientation: {quaternion: [0.9, 0.1, -0.3, 0.2]}}\n")
    x, t = world_surface(box)
    _write_stl(tmp_path / "box.stl", x, t)
    _, mesh = _build(tmp_path, "  - {type: sphere, center: [5, 0, 0], radius: 1, mass: 1}\n"
                     "  - {type: mesh, file: box.stl, density: 500}\n")
    scale = box.body.mass * 0.6**2
    assert mesh.body.mass == pytest.approx(box.body.mass, rel=1e-14)
    np.testing.assert_allclose(mesh.body.position, box.body.position, rtol=0, atol=1e-14 * 7)
    np.testing.assert_allclose(_world_inertia(mesh.body), _world_inertia(box.body), rtol=0,
                               atol=1e-13 * scale)
    assert mesh.volume == pytest.approx(0.2 * 0.4 * 0.6, rel=1e-14)


def test_a_surface_that_is_not_star_shaped_has_the_properties_of_its_parts():
    """An L of two unit cubes (its centroid outside one of them; some tets to the vertices'
    mean are inverted): mass, centre and inertia of the two cubes, parallel axes, exact."""
    cubes = [np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])]
    grid = {tuple(c) for c in cubes}
    faces = []
    for c in cubes:  # the unit cube's faces not shared with another cube of the L
        for axis in range(3):
            for side in (0, 1):
                other = c.copy()
                other[axis] += 1 if side else -1
                if tuple(other) in grid:
                    continue
                u, w = np.eye(3)[(axis + 1) % 3], np.eye(3)[(axis + 2) % 3]
                o = c + side * np.eye(3)[axis]
                quad = [o, o + u, o + u + w, o + w]
                faces.append(quad if side else quad[::-1])
    points, index = np.unique(np.array(faces).reshape(-1, 3), axis=0, return_inverse=True)
    quads = index.reshape(-1, 4)
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    mp = surface_mass_properties(points, triangles, 2.0)
    centers = np.array(cubes) + 0.5
    centre = centers.mean(axis=0)
    inertia = sum(2.0 * (np.eye(3) / 6 + (d @ d) * np.eye(3) - np.outer(d, d))
                  for d in centers - centre)
    assert mp.mass == pytest.approx(6.0, rel=1e-15)
    np.testing.assert_allclose(mp.center, centre, rtol=0, atol=1e-15)
    np.testing.assert_allclose(mp.inertia, inertia, rtol=0, atol=1e-14)


@pytest.mark.parametrize("kind", ["sphere", "cylinder"])
def test_the_tessellations_are_inscribed_within_their_stated_gap(kind):
    """Vertices on the exact surface, faces at most the stated gap inside it, outward; the
    volume of the tessellation is below the exact one by at most the gap's share."""
    if kind == "sphere":
        v, t = icosphere(3)
        gap, exact = SPHERE_GAP, 4 / 3 * np.pi
        np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, rtol=1e-15)
        assert len(v) == 642 and len(t) == 1280
    else:
        v, t = cylinder_surface(1.0, 2.0)
        gap, exact = CYLINDER_GAP, 2 * np.pi
        np.testing.assert_allclose(np.linalg.norm(v[:, :2], axis=1), 1.0, rtol=1e-15)
        assert len(v) == 2 * CYLINDER_SEGMENTS
    x = v[t]
    normal = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    reach = np.einsum("ij,ij->i", normal, x[:, 0])
    assert reach.min() > 0  # outward
    if kind == "sphere":
        assert 1 - reach.min() == pytest.approx(gap, rel=1e-3)
    else:
        side = np.abs(normal[:, 2]) < 0.5
        assert 1 - reach[side].min() == pytest.approx(gap, rel=1e-2)
    volume = surface_mass_properties(v, t).mass
    assert 0 < exact - volume < 3 * gap * exact


def test_fixed_obstacles_have_infinite_mass_and_never_move(tmp_path):
    (box,) = _build(tmp_path, "  - {type: box, center: [0, 0, -1], size: [1, 1, 0.1], "
                    "fixed: true, restitution: 0.2}\n")
    assert box.fixed and box.inverse_mass == 0.0 and not box.inverse_inertia.any()
    assert np.isinf(box.body.mass) and box.rigid_index is None
    assert not inverse_inertia_world(box.body).any() and not velocity(box.body).any()
    assert not point_velocities(box.body, np.ones((4, 3))).any()
    assert len(box.body.points) == 8 and box.shape.exact and box.restitution == 0.2


# --- free flight and output ----------------------------------------------------------------

FLIGHT = BASE + textwrap.dedent("""\
      - {type: sphere, center: [5, 0, 0], radius: 0.1, density: 1000,
         velocity: [1, 2, 3], angular_velocity: [0, 0, 4]}
      - {type: box, center: [-5, 0, 0], size: [1, 1, 1], fixed: true, friction: 0.1,
         orientation: {axis: [0, 0, 1], angle: 30}}
      - {type: plane, point: [0, 0, -100], restitution: 0.25}
      - {type: cylinder, center: [0, 5, 0], radius: 0.05, height: 0.2, mass: 3}
    """)


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    """A run: the brick, a spinning ball and a cylinder in flight, a fixed box and a plane
    far away."""
    out = tmp_path_factory.mktemp("flight")
    case = out / "flight.yaml"
    case.write_text(FLIGHT)
    assert main(["run", str(case), "-o", str(out / "run"), "-q"]) == 0
    return out / "run"


def _frames(pvd: Path) -> list[tuple[float, Path]]:
    import re

    text = pvd.read_text()
    return [(float(t), pvd.parent / f) for t, f in
            re.findall(r'timestep="([^"]+)"[^>]*file="([^"]+)"', text)]


def test_a_moving_obstacle_follows_the_exact_parabola(flight):
    """The ball's centre (the node every one of its cells shares) at every output step:
    x0 + v t + g t^2 / 2 to round-off; its momentum m (v + g t) and angular momentum."""
    frames = _frames(flight / "flight.pvd")
    assert [t for t, _ in frames] == pytest.approx([0, 0.05, 0.1, 0.15, 0.2], abs=1e-15)
    g = np.array([0, 0, -9.81])
    for t, path in frames:
        m = meshio.read(path)
        ids, rigid = m.cell_data["fragment_id"][0], m.cell_data["rigid"][0]
        cells = m.cells[0].data[(ids == 0) & (rigid == 1)]  # the ball: rigid body 0
        assert len(cells) == 1280 and np.all(cells[:, 3] == cells[0, 3])
        c = cells[0, 3]
        x = m.points[c] + m.point_data["displacement"][c]
        np.testing.assert_allclose(x, [5, 0, 0] + np.array([1, 2, 3]) * t + 0.5 * g * t * t,
                                   rtol=0, atol=1e-14 * 5)
        np.testing.assert_allclose(m.point_data["velocity"][c], [1, 2, 3] + g * t, rtol=0,
                                   atol=1e-13)
    summary = json.loads((flight / "summary.json").read_text())
    ball = summary["fragments"]["bodies"][0]
    mass = 1000 * 4 / 3 * np.pi * 0.001
    np.testing.assert_allclose(ball["momentum"], mass * (np.array([1, 2, 3]) + g * 0.2),
                               rtol=1e-14)
    np.testing.assert_allclose(ball["angular_momentum"], [0, 0, 0.4 * mass * 0.01 * 4],
                               rtol=1e-14, atol=1e-20)
    # the ball and the cylinder are the first rigid bodies, the brick after them
    assert summary["fragments"]["rigid_bodies"] == 3
    assert summary["fragments"]["bodies"][1]["mass"] == 3


def test_the_fixed_obstacles_are_a_series_of_their_own(flight):
    """``flight_obstacles.pvd``: one frame per output step at the main series' times, read
    by meshio and pyvista, with the fixed box's 12 triangles where the box is and the
    plane's square in the plane, their ids and coefficients."""
    pyvista = pytest.importorskip("pyvista")
    summary = json.loads((flight / "summary.json").read_text())
    pvd = flight / "flight_obstacles.pvd"
    assert summary["output"]["obstacles"] == str(pvd)
    frames = _frames(pvd)
    assert [t for t, _ in frames] == [t for t, _ in _frames(flight / "flight.pvd")]
    config, _ = load_case(flight.parent / "flight.yaml")
    box = build_obstacles(config.obstacles, flight.parent, True)[1]
    corners, _ = world_surface(box)
    for _, path in frames:
        m = meshio.read(path)
        ids = m.cell_data["obstacle_id"][0]
        assert [c.type for c in m.cells] == ["triangle"] and ids.tolist() == [1] * 12 + [2] * 2
        np.testing.assert_allclose(m.points[:8], corners, rtol=0, atol=1e-15)
        np.testing.assert_allclose(m.points[8:, 2], -100.0)
        np.testing.assert_array_equal(m.cell_data["friction"][0], [0.1] * 12 + [0.5] * 2)
        np.testing.assert_array_equal(m.cell_data["restitution"][0], [0.5] * 12 + [0.25] * 2)
        np.testing.assert_allclose(m.cell_data["normal"][0][12:], [[0, 0, 1]] * 2)
        assert not m.point_data["displacement"].any()
    reader = pyvista.get_reader(str(pvd))
    assert reader.time_values == pytest.approx([0, 0.05, 0.1, 0.15, 0.2])
    grid = reader.read()[0]
    assert grid.n_cells == 14 and "obstacle_id" in grid.cell_data
    text = (flight / "flight_view.py").read_text()
    compile(text, "flight_view.py", "exec")
    assert "OBSTACLES = True" in text and "_obstacles.pvd" in text


def test_check_lists_the_obstacles(tmp_path, capsys):
    case = tmp_path / "flight.yaml"
    case.write_text(FLIGHT)
    assert main(["check", str(case)]) == 0
    out = capsys.readouterr().out
    block = out[out.index("\nobstacles\n"):out.index("\nplan\n")].splitlines()[2:]
    assert block[0].startswith("  [0] sphere, radius 0.1, centre [5, 0, 0]")
    assert "mass 4.18879 (density 1000)" in block[0] and "velocity [1, 2, 3]" in block[0]
    assert "rigid body 0" in block[0]
    assert block[1].startswith("  [1] box, size [1, 1, 1]") and "fixed" in block[1]
    assert block[2].startswith("  [2] plane through [0, 0, -100], normal [0, 0, 1]")
    assert "mass 3 " in block[3] and "rigid body 1" in block[3]


def test_a_mesh_obstacle_runs_and_its_resolved_case_checks_elsewhere(tmp_path, capsys):
    """A relative mesh path becomes absolute in case.resolved.yaml, which checks from the
    output directory."""
    v, t = box_surface([0.5, 0.5, 0.5])
    (tmp_path / "meshes").mkdir()
    _write_stl(tmp_path / "meshes" / "rock.stl", v + [0, 3, 0], t)
    case = tmp_path / "rock.yaml"
    case.write_text(BASE.replace("steps: 20", "steps: 2")
                    + "  - {type: mesh, file: meshes/rock.stl, density: 2000, "
                    "velocity: [0, 0, 1]}\n")
    out = tmp_path / "out"
    assert main(["run", str(case), "-o", str(out), "-q"]) == 0
    resolved = (out / "case.resolved.yaml").read_text()
    assert str((tmp_path / "meshes" / "rock.stl").resolve()) in resolved
    assert main(["check", str(out / "case.resolved.yaml")]) == 0
    assert "[0] mesh, meshes/rock.stl" not in capsys.readouterr().out  # the absolute path


@pytest.mark.parametrize("order", [1, 2])
def test_a_moving_obstacle_is_drawn_by_positive_tets(tmp_path, order):
    """The tets from the centre to the surface triangles: positive volumes summing to the
    tessellation's volume; P2: the mid nodes halfway along the edges (VTK order)."""
    obstacles = _build(tmp_path, SPHERE + "  - {type: cylinder, center: [0, 0, 0], "
                       "radius: 1, height: 2, mass: 1}\n")
    for o, f in zip(obstacles, rigid_bodies(obstacles, order), strict=True):
        nodes, cells = drawing(o, order)
        assert cells.shape[1] == (4 if order == 1 else 10)
        x = nodes[cells[:, :4]]
        d = x[:, 1:] - x[:, :1]
        volume = np.einsum("ei,ei->e", d[:, 0], np.cross(d[:, 1], d[:, 2])) / 6
        assert volume.min() > 0
        assert volume.sum() == pytest.approx(
            surface_mass_properties(o.shape.vertices, o.shape.triangles).mass, rel=1e-12)
        if order == 2:
            edges = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]])
            np.testing.assert_allclose(nodes[cells[:, 4:]],
                                       0.5 * (x[:, edges[:, 0]] + x[:, edges[:, 1]]),
                                       atol=1e-15)
        assert not f.displacement().any() and f.fragment_id == o.rigid_index


def test_planes_size_with_the_scene_and_no_fixed_obstacle_no_series(tmp_path):
    obstacles = _build(tmp_path, SPHERE)
    assert fixed_surface(obstacles, np.zeros((1, 3))) is None
    (plane,) = _build(tmp_path, "  - {type: plane, point: [0, 0, -1]}\n")
    points, triangles, data = fixed_surface((plane,), np.array([[0, 0, 0], [1, 1, 1.0]]))
    assert triangles.tolist() == [[0, 1, 2], [0, 2, 3]] and data["obstacle_id"].tolist() == [0, 0]
    np.testing.assert_allclose(points[:, 2], -1.0)
    assert "OBSTACLES = False" in script_text("x", 1.0, False, tmp_path)


def test_build_refuses_obstacles_without_the_rigid_stage(tmp_path):
    case = tmp_path / "case.yaml"
    case.write_text(BASE + SPHERE)
    config, _ = load_case(case)
    with pytest.raises(CaseError) as err:
        build_obstacles(config.obstacles, tmp_path, False)
    assert err.value.path == ("obstacles",)


def test_balls_dropped_on_a_fixed_box_and_a_plane_obstacle_stay_on_them(tmp_path):
    """The rigid stage's contact takes the fixed box as a body of infinite mass and the
    plane obstacle as a ground plane: the balls bounce on them and never sink into them by
    more than the contact's slop (1 mm)."""
    case = tmp_path / "drop.yaml"
    case.write_text(BASE.replace("origin: [0, 0, 0]", "origin: [10, 0, 0]")
                    .replace("dt: 0.01, steps: 20, output_every: 5",
                             "dt: 0.002, steps: 350, output_every: 5") + textwrap.dedent("""\
          - {type: sphere, center: [0, 0, 1], radius: 0.1, density: 1000}
          - {type: box, center: [0, 0, 0], size: [1, 1, 0.2], fixed: true}
          - {type: sphere, center: [3, 0, 1], radius: 0.1, density: 1000}
          - {type: plane, point: [0, 0, -1]}
        """))
    out = tmp_path / "out"
    assert main(["run", str(case), "-o", str(out), "-q"]) == 0
    lowest = np.full(2, np.inf)
    for _, path in _frames(out / "drop.pvd"):
        m = meshio.read(path)
        ids, x = m.cell_data["fragment_id"][0], m.points + m.point_data["displacement"]
        for k in (0, 1):
            lowest[k] = min(lowest[k], x[np.unique(m.cells[0].data[ids == k])][:, 2].min())
    assert lowest[0] > 0.1 - 1e-3 and lowest[1] > -1.0 - 1e-3
    assert lowest[0] < 0.1 + 0.05 and lowest[1] < -1.0 + 0.05  # they reached them
    summary = json.loads((out / "summary.json").read_text())
    assert summary["fragments"]["bodies"][0]["position"][2] < 0.9  # no longer at the start
