"""gmsh primitives and .geo files -> Mesh: volumes, named faces, orientation, sizes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fem_frac.errors import MeshError
from fem_frac.mesh import exterior_facets, tet_volumes
from fem_frac.mesh.geometry import build, from_geo_file
from fem_frac.mesh.mesh import facet_keys, match

MESHES = Path(__file__).resolve().parents[1] / "meshes"
C = np.array([1.0, 2.0, 3.0])  # centre / origin off zero, to catch origin mix-ups


# --- analytic surfaces: signed distance of points and the outward normal of the body ---------


def plane(axis: int, value: float, sign: float):
    """Face on the plane x[axis] = value, outward normal sign * e_axis."""

    def distance(x):
        return x[..., axis] - value

    def normal(x):
        n = np.zeros_like(x)
        n[..., axis] = sign
        return n

    return distance, normal, True


def sphere_face(center, radius: float, sign: float):
    """Spherical face; sign +1: body inside (outer face), -1: body outside (cavity)."""

    def distance(x):
        return np.linalg.norm(x - center, axis=-1) - radius

    def normal(x):
        d = x - center
        return sign * d / np.linalg.norm(d, axis=-1, keepdims=True)

    return distance, normal, False


def cylinder_face(origin, radius: float, sign: float):
    """Face of the cylinder of ``radius`` about the z axis through ``origin``."""

    def distance(x):
        return np.linalg.norm((x - origin)[..., :2], axis=-1) - radius

    def normal(x):
        d = x - origin
        d[..., 2] = 0.0
        return sign * d / np.linalg.norm(d, axis=-1, keepdims=True)

    return distance, normal, False


def check_faces(mesh, faces: dict, size: float) -> None:
    """Every exterior facet is in exactly one named group; vertices lie on the group's surface;
    the outward normal of each exterior facet (``exterior_facets``) points out of the body."""
    assert set(mesh.boundaries) == set(faces)
    ext = exterior_facets(mesh.tets)
    keys = facet_keys(ext, mesh.n_points)
    seen = np.zeros(len(ext), dtype=int)
    for name, (distance, normal, planar) in faces.items():
        tris = mesh.boundaries[name]
        assert tris.shape[1] == 3 and len(tris) > 0
        wanted = facet_keys(tris, mesh.n_points)
        pos = match(keys, wanted)
        assert np.all(pos >= 0), name
        seen[pos] += 1
        # vertices on the analytic surface (gmsh places them on the CAD surface)
        assert np.abs(distance(mesh.points[tris])).max() < 1e-9 * size, name
        # the group's triples carry the same outward orientation as exterior_facets
        np.testing.assert_array_equal(tris, ext[pos])
        x = mesh.points[ext[pos]]
        n = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        cos = np.einsum("ij,ij->i", n, normal(x.mean(axis=1)))
        # planar faces: exact; curved faces: a chord of a coarse facetting tilts the normal
        assert cos.min() > (1 - 1e-12 if planar else 0.5), name
    assert np.all(seen == 1), "exterior facets not named exactly once"


def volume(mesh) -> float:
    v = tet_volumes(mesh.points, mesh.tets)
    assert v.min() > 0
    return float(v.sum())


def circumradii(x: np.ndarray) -> np.ndarray:
    """Circumradius of triangles ``(k, 3, 3)``: abc / (4 area)."""
    a = np.linalg.norm(x[:, 1] - x[:, 2], axis=1)
    b = np.linalg.norm(x[:, 0] - x[:, 2], axis=1)
    c = np.linalg.norm(x[:, 0] - x[:, 1], axis=1)
    area = 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)
    return a * b * c / (4 * area)


def inscribed_deficit_bound(mesh, name: str, radius: float) -> float:
    """Volume between a sphere of ``radius`` and its inscribed facets of group ``name``.

    A facet with circumradius rho cuts a cap of height R - sqrt(R^2 - rho^2) off the sphere;
    the caps together cover at most the sphere's area, so the lost volume is at most
    area * max cap height (relative to the ball: 3 * cap / R, i.e. O(h^2 / R^2)).
    """
    rho = circumradii(mesh.points[mesh.boundaries[name]]).max()
    cap = radius - np.sqrt(radius**2 - rho**2)
    return 4 * np.pi * radius**2 * cap


def curved_volume(mesh) -> float:
    """Volume of the isoparametric P2 geometry (mid-side nodes on the CAD surfaces)."""
    from skfem import CellBasis, ElementTetP2

    from fem_frac.fem.space import skfem_mesh

    basis = CellBasis(skfem_mesh(mesh, 2), ElementTetP2(), intorder=6)
    assert basis.dx.min() > 0
    return float(basis.dx.sum())


def box_faces(lo, hi):
    return {
        f"{axis}{side}": plane(i, (lo if side == "min" else hi)[i], -1 if side == "min" else 1)
        for i, axis in enumerate("xyz")
        for side in ("min", "max")
    }


# --- primitives ------------------------------------------------------------------------------


def test_box_volume_faces_and_size():
    lengths = np.array([2.0, 1.0, 0.5])
    h = 0.2
    mesh = build("box", {"origin": list(C), "lengths": list(lengths)}, h, 1)
    assert volume(mesh) == pytest.approx(np.prod(lengths), rel=1e-12)
    check_faces(mesh, box_faces(C, C + lengths), size=2.0)
    # a well-shaped tet mesh has ~4-9 tets per h^3 of volume; a loose factor
    assert 2 < mesh.n_tets * h**3 / np.prod(lengths) < 15
    assert mesh.points.dtype == np.float64 and mesh.tets.dtype == np.int64
    # every vertex is a tet corner
    assert np.array_equal(np.unique(mesh.tets), np.arange(mesh.n_points))


def test_box_order_2_has_no_curved_edges():
    mesh = build("box", {"origin": [0, 0, 0], "lengths": [1, 1, 1]}, 0.5, 2)
    assert not mesh.curved  # all mid-side nodes are on straight edges: none stored


def test_tet_count_scales_with_volume_over_h_cubed():
    p = {"center": list(C), "radius": 1.0}
    coarse, fine = build("sphere", p, 0.2, 1), build("sphere", p, 0.1, 1)
    ratio = fine.n_tets / coarse.n_tets
    assert 5 < ratio < 12  # 2^3 = 8, up to the surface layer and mesher noise
    assert 2 < fine.n_tets * 0.1**3 / (4 / 3 * np.pi) < 15


def test_cylinder_faces_and_volume():
    r, height, h = 0.5, 1.5, 0.15
    mesh = build("cylinder", {"origin": list(C), "radius": r, "height": height}, h, 1)
    check_faces(
        mesh,
        {
            "bottom": plane(2, C[2], -1),
            "top": plane(2, C[2] + height, 1),
            "outer": cylinder_face(C, r, 1),
        },
        size=height,
    )
    # inscribed polygon of edge <= ~h: relative area loss <= (edge / r)^2 / 6 ~ 3 %
    exact = np.pi * r**2 * height
    assert 0 < (exact - volume(mesh)) / exact < 0.03


def test_sphere_volume_order_1_and_2():
    radius, h = 1.0, 0.25
    p = {"center": list(C), "radius": radius}
    exact = 4 / 3 * np.pi * radius**3
    linear = build("sphere", p, h, 1)
    check_faces(linear, {"outer": sphere_face(C, radius, 1)}, size=radius)
    deficit = exact - volume(linear)
    assert 0 < deficit <= inscribed_deficit_bound(linear, "outer", radius)

    quadratic = build("sphere", p, h, 2)
    np.testing.assert_array_equal(quadratic.tets, linear.tets)  # same corner mesh
    assert quadratic.curved
    dist = np.linalg.norm(quadratic.edge_points - C, axis=1) - radius
    assert np.abs(dist).max() < 1e-12 * radius
    # the curved edges are the boundary edges of the sphere, no others
    assert np.abs(np.linalg.norm(quadratic.points[quadratic.edges] - C, axis=2) - 1).max() < 1e-12
    # quadratic geometry: O((h/R)^4) instead of O((h/R)^2)
    err2 = abs(exact - curved_volume(quadratic))
    assert err2 < 0.02 * deficit and err2 < 1e-3 * exact


@pytest.mark.parametrize("sector", ["full", "octant"])
def test_hollow_sphere(sector):
    a, b, h = 0.5, 1.0, 0.25
    p = {"center": list(C), "inner_radius": a, "outer_radius": b, "sector": sector}
    mesh = build("hollow_sphere", p, h, 1)
    faces = {"inner": sphere_face(C, a, -1), "outer": sphere_face(C, b, 1)}
    if sector == "octant":
        faces |= {f"symmetry_{axis}": plane(i, C[i], -1) for i, axis in enumerate("xyz")}
        assert mesh.points.min(axis=0) == pytest.approx(C, abs=1e-12)
    check_faces(mesh, faces, size=b)
    fraction = 1.0 if sector == "full" else 1 / 8
    exact = fraction * 4 / 3 * np.pi * (b**3 - a**3)
    # outer facets lose volume, inner ones (a cavity) add it; both bounded as for a ball
    loss = fraction * inscribed_deficit_bound(mesh, "outer", b)
    gain = fraction * inscribed_deficit_bound(mesh, "inner", a)
    assert -gain <= exact - volume(mesh) <= loss

    quadratic = build("hollow_sphere", p, h, 2)
    r = np.linalg.norm(quadratic.edge_points - C, axis=1)
    assert np.minimum(abs(r - a), abs(r - b)).max() < 1e-12 * b
    assert abs(curved_volume(quadratic) - exact) < 1e-3 * exact


@pytest.mark.parametrize("sector", ["full", "half", "quarter"])
def test_hollow_cylinder(sector):
    a, b, height, h = 0.5, 1.0, 0.6, 0.2
    p = {
        "origin": tuple(C),
        "inner_radius": a,
        "outer_radius": b,
        "height": height,
        "sector": sector,
    }
    mesh = build("hollow_cylinder", p, h, 1)
    faces = {
        "inner": cylinder_face(C, a, -1),
        "outer": cylinder_face(C, b, 1),
        "bottom": plane(2, C[2], -1),
        "top": plane(2, C[2] + height, 1),
    }
    if sector in ("half", "quarter"):
        faces["symmetry_y"] = plane(1, C[1], -1)
        assert mesh.points[:, 1].min() == pytest.approx(C[1], abs=1e-12)
    if sector == "quarter":
        faces["symmetry_x"] = plane(0, C[0], -1)
        assert mesh.points[:, 0].min() == pytest.approx(C[0], abs=1e-12)
    check_faces(mesh, faces, size=b)
    fraction = {"full": 1.0, "half": 0.5, "quarter": 0.25}[sector]
    exact = fraction * np.pi * (b**2 - a**2) * height
    assert volume(mesh) == pytest.approx(exact, rel=0.03)


def test_deterministic():
    p = {"center": [0, 0, 0], "inner_radius": 0.5, "outer_radius": 1.0, "sector": "octant"}
    m1, m2 = build("hollow_sphere", p, 0.2, 2), build("hollow_sphere", p, 0.2, 2)
    for attr in ("points", "tets", "edges", "edge_points"):
        np.testing.assert_array_equal(getattr(m1, attr), getattr(m2, attr))
    assert m1.boundaries.keys() == m2.boundaries.keys()
    for name in m1.boundaries:
        np.testing.assert_array_equal(m1.boundaries[name], m2.boundaries[name])


@pytest.mark.parametrize(
    ("kind", "params", "message"),
    [
        ("hollow_sphere", {"center": [0, 0, 0], "inner_radius": 1, "outer_radius": 1}, "inner"),
        (
            "hollow_cylinder",
            {
                "origin": [0, 0, 0],
                "inner_radius": 1,
                "outer_radius": 2,
                "height": 1,
                "sector": "third",
            },
            "sector",
        ),
        ("box", {"origin": [0, 0, 0], "lengths": [1, 0, 1]}, "lengths"),
        ("sphere", {"center": [0, 0], "radius": 1}, "3-vector"),
        ("sphere", {"centre": [0, 0, 0], "radius": 1}, "centre"),
        ("torus", {}, "unknown geometry"),
    ],
)
def test_bad_parameters_raise_mesh_error(kind, params, message):
    with pytest.raises(MeshError, match=message) as info:
        build(kind, params, 0.3, 1)
    assert "\n" not in str(info.value)


# --- .geo files ------------------------------------------------------------------------------


def test_example_geo_file():
    mesh = from_geo_file(MESHES / "block_with_hole.geo", 0.2, 1)
    lo, hi = np.zeros(3), np.array([2.0, 1.0, 0.5])
    faces = {
        "left": plane(0, 0.0, -1),
        "right": plane(0, 2.0, 1),
        "front": plane(1, 0.0, -1),
        "back": plane(1, 1.0, 1),
        "bottom": plane(2, 0.0, -1),
        "top": plane(2, 0.5, 1),
        "hole": cylinder_face(np.array([1.0, 0.5, 0.0]), 0.25, -1),
    }
    check_faces(mesh, faces, size=2.0)
    assert np.allclose(mesh.points.min(axis=0), lo) and np.allclose(mesh.points.max(axis=0), hi)
    np.testing.assert_array_equal(mesh.subdomains["solid"], np.arange(mesh.n_tets))
    exact = 1.0 - np.pi * 0.25**2 * 0.5
    assert volume(mesh) == pytest.approx(exact, rel=0.02)


def test_geo_without_physical_surfaces_has_no_boundaries(tmp_path):
    geo = tmp_path / "plain.geo"
    geo.write_text('SetFactory("OpenCASCADE");\nBox(1) = {0, 0, 0, 1, 2, 3};\n')
    mesh = from_geo_file(geo, 0.5, 1)
    assert mesh.boundaries == {} and mesh.subdomains == {}
    assert volume(mesh) == pytest.approx(6.0, rel=1e-12)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("Point(1) = {0, 0, 0};\nFoo bar;\n", "cannot read"),
        ('SetFactory("OpenCASCADE");\nRectangle(1) = {0, 0, 0, 1, 1};\n', "no volume"),
    ],
)
def test_bad_geo_raises_mesh_error(tmp_path, text, message):
    geo = tmp_path / "bad.geo"
    geo.write_text(text)
    with pytest.raises(MeshError, match=message) as info:
        from_geo_file(geo, 0.5, 1)
    assert "\n" not in str(info.value)


# --- .geo commands that run programs or write files (docs/security.md) -----------------------


def _uses(tmp_path, text, name="t.geo"):
    from fem_frac.mesh.gmsh_model import geo_commands

    (tmp_path / name).write_text(text)
    return [(c.path.name, c.line, c.command) for c in geo_commands(tmp_path / name)]


def test_the_shipped_geo_files_use_no_refused_command():
    from fem_frac.mesh.gmsh_model import geo_commands

    for geo in sorted(MESHES.glob("*.geo")):
        assert geo_commands(geo) == [], geo


@pytest.mark.parametrize(("text", "command"), [
    ('SystemCall "rm -rf ~";', "SystemCall"),
    ('System "ls";', "System"),
    ('NonBlockingSystemCall StrCat("x", "y");', "NonBlockingSystemCall"),
    ('OnelabRun("client", "cmd");', "OnelabRun"),
    ('CreateDir "d";', "CreateDir"),
    ('Save "x.msh";', "Save"),
    ('Save View[0] "v.pos";', "Save"),
    ('Print Sprintf("shot%g.png", 1);', "Print"),
    ("Exit;", "Exit"),
    ("Plugin(Bubbles).Run;", "Plugin"),
    ('Printf("%g", 1) > "f.txt";', "Printf > file"),
    ("Printf('(%g)', 1) >> 'f.txt';", "Printf > file"),
    ('General.LogFileName = "x.log";', "General.LogFileName"),
    ('Solver.Executable0 = "sh";', "Solver.Executable0"),
    ('Geometry.DoubleClickedPointCommand = "x";', "Geometry.DoubleClickedPointCommand"),
    ('View[0].FileName = "x";', "View.FileName"),
    ('Include StrCat(CurrentDir, "x.geo");', "Include"),
    ('Merge "x.gz";', "Merge x.gz"),
    ('Merge "solver.py";', "Merge solver.py"),
])
def test_a_command_that_runs_a_program_or_writes_a_file_is_found(tmp_path, text, command):
    assert _uses(tmp_path, f"x = 1;\n\n{text}\n") == [("t.geo", 3, command)]


def test_words_in_comments_strings_and_names_are_no_commands(tmp_path):
    text = """// SystemCall "rm";
/* Save "x.msh";
   Exit; */
Printf("SystemCall and Exit > here");
Printf("%g", 1);
Print.Width = 800; Mesh.SaveAll = 0; General.Terminal = 0;
System = 3; x = System + 1; y[] = {System};
Mesh.CharacteristicLengthMax = 0.1;
s = 'Save "x"';
"""
    assert _uses(tmp_path, text) == []


def test_included_and_merged_scripts_are_read_relative_to_the_including_file(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "b").mkdir()
    (tmp_path / "a" / "inc.geo").write_text('Include "b/deep.geo";\nMerge "b/script.txt";\n'
                                           'Merge "b/mesh.msh";\nMerge "b/part.step";\n')
    (tmp_path / "a" / "b" / "deep.geo").write_text('\nSave "x";\nInclude "../inc.geo";\n')
    (tmp_path / "a" / "b" / "script.txt").write_text('Exit;\n')
    (tmp_path / "a" / "b" / "mesh.msh").write_text('$MeshFormat\nSystemCall "x";\n')
    (tmp_path / "a" / "b" / "part.step").write_text('SystemCall "x";\n')
    assert _uses(tmp_path, 'Include "a/inc.geo";\n') == [
        ("deep.geo", 2, "Save"), ("script.txt", 1, "Exit")]


def test_a_device_a_missing_file_and_a_cycle_are_not_read_as_scripts(tmp_path):
    text = 'Include "/dev/zero";\nMerge "/dev/zero";\nInclude "nowhere.geo";\nInclude "t.geo";\n'
    assert _uses(tmp_path, text + 'Save "x";\n') == [("t.geo", 5, "Save")]


def test_a_refused_geo_file_is_not_read_by_gmsh_unless_allowed(tmp_path):
    made = tmp_path / "made.txt"
    geo = tmp_path / "w.geo"
    geo.write_text('SetFactory("OpenCASCADE");\nBox(1) = {0, 0, 0, 1, 1, 1};\n'
                   f'Printf("hi") > "{made}";\n')
    with pytest.raises(MeshError, match=r"w\.geo:3: Printf > file writes a file") as info:
        from_geo_file(geo, 0.5, 1)
    assert "\n" not in str(info.value) and not made.exists()
    assert from_geo_file(geo, 0.5, 1, allow_commands=True).n_tets > 0
    assert made.read_text() == "hi\n"


def test_a_part_one_element_thick_gets_no_flat_tets():
    """HXT leaves a flat tet (four coplanar corners, quality ~1e-14) in a 1 x 0.05 x 0.05 box
    meshed at 0.05; the mesher falls back on Delaunay there, whose tets are all sound."""
    from fem_frac.mesh.geometry import build
    from fem_frac.mesh.mesh import min_dihedral_angles

    m = build("box", {"lengths": (1.0, 0.05, 0.05), "origin": (0, 0, 0)}, 0.05, 1)
    assert min_dihedral_angles(m.points, m.tets).min() > 1.0
