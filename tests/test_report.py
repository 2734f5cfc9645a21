"""``fem-frac check``: what it prints of selections, loads, material and the time step; and
the rule of box selections (faces by centroid)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from report_text import check, line, number

from fem_frac.config.loader import load_case
from fem_frac.mesh.build import build_mesh
from fem_frac.mesh.mesh import exterior_facets
from fem_frac.mesh.selection import box_face_area, box_facets
from fem_frac.solve.problem import outer_facets
from meshes import structured_box
from solve import write_case

PLATE = {
    "mesh": {"geometry": {"type": "box", "lengths": [0.1, 0.1, 0.01]}, "element_size": 0.005},
    "material": {"youngs_modulus": 70e9, "poissons_ratio": 0.22, "density": 2500},
    "boundary_conditions": [
        {"type": "fixed", "boundary": "xmin"},
        {"type": "fixed", "box": {"min": [0.1, 0.0, 0.0], "max": [0.1, 0.1, 0.01]}},
        {"type": "pressure", "box": {"min": [0.04, 0.04, 0.01], "max": [0.06, 0.06, 0.01]},
         "pressure": 4e8, "curve": "pulse"},
        {"type": "traction", "boundary": "ymax", "traction": [0.0, 0.0, -1e6]},
    ],
    "body_force": {"gravity": [0.0, 0.0, -9.81]},
    "load_curves": {"pulse": {"type": "table", "points": [[0, 0], [3e-6, 2.0], [1e-5, 0]]}},
    "analysis": {"type": "dynamic", "dt": 2e-6, "steps": 5},
}


def vector(text: str, before: str) -> np.ndarray:
    m = re.search(re.escape(before) + r" \(([^)]*)\)", text)
    return np.array([float(x) for x in m.group(1).split(",")])


def patch(tmp_path: Path, lo, hi) -> tuple[int, float]:
    """Faces whose centroid lies in the box, and their area, counted here by hand."""
    case, source = load_case(write_case(tmp_path / "m.yaml", PLATE))
    mesh = build_mesh(case.mesh, source.path.parent)
    x = mesh.points[exterior_facets(mesh.tets)]
    c = x.mean(axis=1)
    inside = np.all((c >= np.array(lo) - 1e-12) & (c <= np.array(hi) + 1e-12), axis=1)
    area = 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)
    return int(inside.sum()), float(area[inside].sum())


def test_box_selections_print_their_faces_and_area_beside_the_box_face(tmp_path, capsys):
    out = check(tmp_path, capsys, PLATE)
    assert "box selections (faces whose centroid lies in the box)" in out
    loaded = line(out, "boundary_conditions[2] pressure:")
    count, area = patch(tmp_path, [0.04, 0.04, 0.01], [0.06, 0.06, 0.01])
    assert f"{count:,} faces" in loaded
    assert number(loaded, "area") == pytest.approx(area, rel=1e-5)
    assert number(loaded, "the box's face") == pytest.approx(4e-4)
    assert f"({100 * area / 4e-4:.0f} % of it)" in loaded
    # a support's box: the whole xmax side, 0.1 x 0.01
    support = line(out, "boundary_conditions[1] fixed:")
    assert number(support, "area") == pytest.approx(1e-3, rel=1e-9)
    assert "(100 % of it)" in support


def test_loads_are_printed_at_the_peak_of_their_curves(tmp_path, capsys):
    out = check(tmp_path, capsys, PLATE)
    _, area = patch(tmp_path, [0.04, 0.04, 0.01], [0.06, 0.06, 0.01])
    pressure = line(out, "pressure on boundary_conditions[2]: total force")
    # the table's peak (2 at 3 us) lies between steps (2 and 4 us): found all the same
    assert "factor 2 at t = 3e-06" in pressure
    np.testing.assert_allclose(vector(pressure, "total force"), [0, 0, -2 * 4e8 * area],
                               rtol=1e-3)
    traction = line(out, "traction on ymax: total force")
    np.testing.assert_allclose(vector(traction, "total force"), [0, 0, -1e6 * 0.1 * 0.01],
                               rtol=1e-3)
    assert "curve constant (factor 1 at t = 0)" in traction
    gravity = line(out, "gravity (0, 0, -9.81): weight")
    np.testing.assert_allclose(vector(gravity, "weight"), [0, 0, -9.81 * 2500 * 1e-4],
                               rtol=1e-3)  # printed to 4 digits


def test_material_is_printed(tmp_path, capsys):
    case = {**PLATE, "plasticity": {"yield_stress": 2.5e8, "hardening": 1e9}}
    out = check(tmp_path, capsys, case)
    assert line(out, "E 7e+10") == "  E 7e+10, nu 0.22, density 2500"
    assert number(line(out, "mass"), "mass") == pytest.approx(0.25, rel=1e-9)
    assert "yield stress 2.5e+08, hardening 1e+09" in out


def test_implicit_dynamics_has_no_stable_step_line_only_a_labelled_note(tmp_path, capsys):
    out = check(tmp_path, capsys, PLATE)
    step = line(out, "time step")
    assert step.startswith("time step   dt 2e-06: implicit newmark")
    assert "unconditionally stable: no step limit" in step
    lines = out.splitlines()
    note = lines[lines.index(step) + 1]
    assert note.lstrip().startswith("note, for comparison only (it does not limit this "
                                    "implicit run): stable step of central difference")
    assert not any(x.startswith("time step   stable step") for x in lines)


def test_explicit_dynamics_prints_the_stable_step(tmp_path, capsys):
    case = {**PLATE, "analysis": {"type": "dynamic", "integrator": "central_difference",
                                  "dt": 1e-8, "steps": 5}}
    out = check(tmp_path, capsys, case)
    step = line(out, "time step")
    assert step.startswith("time step   stable step of central difference")
    assert "dt 1e-08 is" in step and "note" not in out


def test_static_cases_print_no_time_step(tmp_path, capsys):
    case = {**PLATE, "analysis": {"type": "static"}, "boundary_conditions": [
        {"type": "fixed", "boundary": "xmin"},
        {"type": "traction", "boundary": "xmax", "traction": [0.0, 0.0, -1e6]}]}
    case.pop("load_curves")
    out = check(tmp_path, capsys, case)
    assert "time step" not in out and "box selections" not in out
    assert "curve ramp (factor 1 at t = 1)" in out


# --- the rule ------------------------------------------------------------------------------


def test_a_box_selects_the_exterior_faces_by_their_centroid():
    mesh = structured_box((5, 4, 3), lengths=(1.0, 1.0, 0.6), distortion=0.2, seed=2)
    faces = exterior_facets(mesh.tets)
    lo, hi = np.array([0.1, 0.1, 0.6]), np.array([0.73, 0.9, 0.6])
    chosen = box_facets(mesh, lo, hi)
    c = mesh.points[faces].mean(axis=1)
    want = faces[np.all((c >= lo - 1e-9) & (c <= hi + 1e-9), axis=1)]
    np.testing.assert_array_equal(chosen, want)
    # a face straddling the box's outline counts by its centroid: some corners outside
    corners = mesh.points[chosen]
    assert np.any(corners[..., 0] > hi[0]) and np.any(corners[..., 1] < lo[1])
    # the faces chosen from a given set (the outer faces without cracks) are a subset
    assert len(box_facets(mesh, lo, hi, faces[:10])) <= 10


def test_the_box_face_area_is_that_of_a_flat_box_clipped_to_the_mesh():
    mesh = structured_box((2, 2, 2), lengths=(1.0, 2.0, 3.0))
    assert box_face_area(mesh, [0.0, 0.5, 3.0], [1.0, 1.5, 3.0]) == pytest.approx(1.0)
    # widened beyond the model to catch its edge: clipped to the bounding box
    assert box_face_area(mesh, [-1.0, -1.0, 3.0], [2.0, 5.0, 3.0]) == pytest.approx(2.0)
    assert box_face_area(mesh, [0.0, 0.0, 0.0], [1.0, 1.0, 1.0]) is None  # thick
    assert box_face_area(mesh, [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]) is None  # a line


def test_outer_faces_leave_crack_faces_out_of_box_selections():
    from fem_frac.fracture import open_crack

    mesh = structured_box((4, 2, 2))
    plane = np.flatnonzero(np.abs(mesh.points[:, 0] - 0.5) < 1e-12)
    cracked, _ = open_crack(mesh, plane, np.tile([1.0, 0.0, 0.0], (len(plane), 1)))
    slab = ([0.5, 0.0, 0.0], [0.5, 1.0, 1.0])
    assert len(box_facets(cracked, *slab)) == 16  # both sides of the 8 crack triangles
    assert len(box_facets(cracked, *slab, outer_facets(cracked))) == 0
