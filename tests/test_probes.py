"""Probes: a row of ``<name>_probes.csv`` at every step, whatever ``output_every``.

A probe at a node reads that node's values, and a probe at an element's centroid that
element's cell values: both are compared with the .vtu of every output step. The CSV
writes every double as the shortest text that reads back as itself, so the only
difference left is the round-off of the interpolation weights at a node (the barycentric
coordinates come from a 3 x 3 solve: off by a few ``kappa eps``, ``kappa`` the element's
condition number, below 1e2 for the tets gmsh makes here; ten weights at most: below
``1e3 eps`` times the largest nodal value). A boundary probe is the mean over its faces: a
prescribed displacement to round-off, and the area-weighted mean of its elements' cell
values computed here from the .vtu. Bad probes are located one-line errors (exit 2) before
anything is written; a probe is found again on the mesh a crack makes.
"""

from __future__ import annotations

import csv
import xml.etree.ElementTree as ET
from pathlib import Path
from types import SimpleNamespace

import meshio
import numpy as np
import pytest

from fem_frac.app.cli import main
from fem_frac.app.driver import prepare
from fem_frac.app.probes import ProbeRecorder, columns
from fem_frac.config.schema import Case, Probe
from fem_frac.fem.space import build_space
from fem_frac.fracture import open_crack
from fem_frac.timing import StageTimer
from fem_frac.writers.probes import ProbeFile
from meshes import structured_box
from solve import write_case

EPS = np.finfo(float).eps
WEIGHTS = 1e3 * EPS  # the interpolation weights' round-off at a node (module docstring)
L, B, H = 1.0, 0.2, 0.2
END = -1e-2  # z of xmax at t = 1
STEPS, EVERY = 4, 2


def beam(order: int, probes: list | None = None) -> dict:
    """A beam bent past yield at its root by a prescribed end displacement."""
    case = {
        "mesh": {"geometry": {"type": "box", "lengths": [L, B, H]}, "element_size": 0.1,
                 "order": order},
        "material": {"youngs_modulus": 200e9, "poissons_ratio": 0.3},
        "plasticity": {"yield_stress": 250e6, "hardening": 1e10},
        "boundary_conditions": [
            {"type": "fixed", "boundary": "xmin"},
            {"type": "displacement", "boundary": "xmax", "z": END},
        ],
        "analysis": {"type": "quasi_static", "steps": STEPS, "output_every": EVERY},
    }
    if probes is not None:
        case["probes"] = probes
    return case


def nodes_and_centroids(order: int) -> tuple[np.ndarray, np.ndarray, int]:
    """The mesh's node positions, element centroids and vertex count (the mesh the run
    will make: gmsh is deterministic)."""
    setup = prepare(Case.model_validate(beam(order)), Path("."), StageTimer())
    mesh = setup.disc.mesh
    return setup.disc.space.node_points, mesh.points[mesh.tets].mean(axis=1), mesh.n_points


def run(tmp_path: Path, case: dict) -> Path:
    path = write_case(tmp_path / "beam.yaml", case)
    assert main(["run", str(path), "-o", str(tmp_path / "out"), "-q"]) == 0
    return tmp_path / "out"


def read_probes(out: Path) -> dict[str, np.ndarray]:
    with open(out / "beam_probes.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def frames(out: Path) -> list[tuple[float, meshio.Mesh]]:
    """``(time, frame)`` of every output step, from the .pvd."""
    root = ET.parse(out / "beam.pvd").getroot()
    return [(float(d.get("timestep")), meshio.read(out / d.get("file")))
            for d in root.iter("DataSet")]


def at(probes: dict, name: str, field: str, components: tuple) -> np.ndarray:
    """The columns of a probe's field ``(steps + 1, k)``."""
    return np.stack([probes[f"{name}_{field}{c}"] for c in components], axis=1)


VECTOR, TENSOR = ("_x", "_y", "_z"), ("_xx", "_yy", "_zz", "_xy", "_yz", "_xz")
POINT_FIELDS = {"displacement": VECTOR, "equivalent_plastic_strain_nodal": ("",),
                "plastic_strain_nodal": TENSOR}
CELL_FIELDS = {"stress": TENSOR, "von_mises": ("",), "equivalent_plastic_strain": ("",)}


@pytest.fixture(scope="module", params=[1, 2])
def probed(request, tmp_path_factory):
    """A run with a probe at a node near the middle of the top face (P2: a mid-edge
    node), one at the centroid of the element nearest the root's top, and the boundary
    probes of both ends."""
    order = request.param
    nodes, centroids, n_vertices = nodes_and_centroids(order)
    pick = np.arange(len(nodes)) >= (n_vertices if order == 2 else 0)
    near = np.linalg.norm(nodes - [0.5 * L, 0.5 * B, H], axis=1) + np.where(pick, 0.0, 1e9)
    node = nodes[np.argmin(near)]
    cell = centroids[np.argmin(np.linalg.norm(centroids - [0.0, 0.5 * B, H], axis=1))]
    probes = [
        {"name": "node", "point": node.tolist(), "fields": list(POINT_FIELDS)},
        {"name": "cell", "point": cell.tolist(), "fields": list(CELL_FIELDS)},
        {"name": "end", "boundary": "xmax", "fields": ["displacement"]},
        {"name": "root", "boundary": "xmin", "fields": ["von_mises"]},
    ]
    out = run(tmp_path_factory.mktemp(f"probes{order}"), beam(order, probes))
    return order, node, cell, read_probes(out), frames(out)


def test_a_row_every_step_whatever_output_every(probed):
    _, _, _, probes, written = probed
    np.testing.assert_array_equal(probes["step"], np.arange(STEPS + 1))
    assert len(written) == STEPS // EVERY + 1 < STEPS + 1


def test_a_probe_at_a_node_equals_the_vtu_value_at_output_steps(probed):
    _, node, _, probes, written = probed
    for t, m in written:
        row = np.flatnonzero(probes["time"] == t)
        assert len(row) == 1
        a = np.flatnonzero(np.all(m.points == node, axis=1))
        assert len(a) == 1  # the node is a point of the .vtu
        for field, components in POINT_FIELDS.items():
            values = m.point_data[field].reshape(len(m.points), -1)
            got = at(probes, "node", field, components)[row[0]]
            assert np.abs(got - values[a[0]]).max() <= WEIGHTS * np.abs(values).max(), field
    assert np.abs(at(probes, "node", "displacement", VECTOR)).max() > 0  # it moved


def test_a_probe_at_a_centroid_reads_its_element(probed):
    _, _, cell, probes, written = probed
    for t, m in written:
        row = np.flatnonzero(probes["time"] == t)[0]
        (kind, tets), = m.cells_dict.items()
        e = np.argmin(np.linalg.norm(m.points[tets[:, :4]].mean(axis=1) - cell, axis=1))
        for field, components in CELL_FIELDS.items():
            values = m.cell_data_dict[field][kind].reshape(len(tets), -1)
            got = at(probes, "cell", field, components)[row]
            assert np.abs(got - values[e]).max() <= 4 * EPS * np.abs(values[e]).max(), field
    assert probes["cell_equivalent_plastic_strain"][-1] > 0  # the root yields


def test_a_boundary_probe_is_the_mean_over_its_faces(probed):
    """xmax: the prescribed displacement; xmin: the area-weighted mean of the von Mises
    stress of the elements with a face on it, from the .vtu."""
    _, _, _, probes, written = probed
    t = probes["time"]
    end = at(probes, "end", "displacement", VECTOR)
    # weights that sum to one (a sum of a few hundred terms) times a constant
    assert np.abs(end[:, 2] - END * t).max() <= 1e3 * EPS * abs(END)
    for t_out, m in written:
        row = np.flatnonzero(t == t_out)[0]
        (kind, tets), = m.cells_dict.items()
        corners = m.points[tets[:, :4]]
        on = np.abs(corners[:, :, 0]) < 1e-12  # vertices on x = 0
        face = on.sum(axis=1) == 3
        tri = corners[face][on[face]].reshape(-1, 3, 3)
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]),
                                    axis=1)
        assert area.sum() == pytest.approx(B * H, rel=1e-12)
        mean = area @ m.cell_data_dict["von_mises"][kind][face] / area.sum()
        assert probes["root_von_mises"][row] == pytest.approx(mean, rel=1e-12)


BAD = [
    ({"name": "p", "boundary": "xmaxx", "fields": ["displacement"]}, "probes[0].boundary",
     "has no boundary 'xmaxx' (did you mean 'xmax'?"),
    ({"name": "p", "point": [0.5, 0.1, 0.3], "fields": ["displacement"]}, "probes[0].point",
     "lies in no element of the mesh"),
    ({"name": "p", "point": [0.5, 0.1, 0.1], "fields": ["displacement", "velocity"]},
     "probes[0].fields[1]", "a quasi_static analysis has no velocity"),
    ({"name": "p", "point": [0.5, 0.1, 0.1], "fields": ["backstress"]},
     "probes[0].fields[0]", "kinematic_hardening > 0"),
    ({"name": "p", "point": [0.5, 0.1, 0.1], "fields": ["displacment"]},
     "probes[0].fields[0]", "must be one of 'displacement'"),
    ({"name": "p", "point": [0.5, 0.1, 0.1], "boundary": "xmax", "fields": ["stress"]},
     "probes[0]", "give exactly one of 'point' or 'boundary'"),
    ({"name": "1p", "point": [0.5, 0.1, 0.1], "fields": ["stress"]}, "probes[0].name",
     "must start with a letter"),
]


@pytest.mark.parametrize("probe,key,words", BAD)
def test_a_bad_probe_is_a_located_error_before_anything_is_written(tmp_path, capsys, probe,
                                                                    key, words):
    path = write_case(tmp_path / "beam.yaml", beam(1, [probe]))
    assert main(["run", str(path), "-o", str(tmp_path / "out"), "-q"]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("error:")]
    assert len(err) == 1 and "beam.yaml:" in err[0] and f": {key}: " in err[0], err
    assert words in err[0]
    assert not (tmp_path / "out").exists()


def test_names_whose_columns_clash_are_refused(tmp_path, capsys):
    probes = [{"name": "a", "point": [0.5, 0.1, 0.1], "fields": ["stress"]},
              {"name": "a", "boundary": "xmax", "fields": ["von_mises"]}]
    path = write_case(tmp_path / "beam.yaml", beam(1, probes))
    assert main(["run", str(path), "-o", str(tmp_path / "out"), "-q"]) == 2
    assert ": probes[1].name: the columns of probe 'a'" in capsys.readouterr().err


def test_a_point_is_found_again_on_the_mesh_a_crack_makes(tmp_path):
    """A box cut at x = 0.5, the right piece moved by ``d``: a probe at x = 0.6 reads the
    affine field plus ``d`` (P1 interpolates it exactly), not the left side's nodes its
    stencil on the uncut mesh would read; once no finite element is left, NaN."""
    box = structured_box((4, 2, 2))
    plane = np.flatnonzero(np.abs(box.points[:, 0] - 0.5) < 1e-12)
    cut, _ = open_crack(box, plane, np.tile([1.0, 0.0, 0.0], (len(plane), 1)))
    grad, d, x = np.array([[1e-3, 2e-3, 0], [0, 1e-3, 3e-3], [5e-4, 0, 1e-3]]), \
        np.array([0.01, 0.0, 0.0]), np.array([0.6, 0.3, 0.7])

    def world(mesh, t, jump):
        space = build_space(mesh, 1)
        u = space.node_points @ grad
        right = np.unique(mesh.tets[mesh.points[mesh.tets].mean(axis=1)[:, 0] > 0.5])
        u[right] += jump
        state = SimpleNamespace(u=u.ravel(), v=None)
        body = SimpleNamespace(mesh=mesh, disc=SimpleNamespace(mesh=mesh, space=space),
                               state=state, fields={}, labels=np.zeros(len(mesh.tets)))
        return SimpleNamespace(t=t, body=body, rigid=())

    probe = [Probe(name="p", point=tuple(x), fields=["displacement"])]
    recorder = ProbeRecorder(probe, ProbeFile(tmp_path / "p.csv", columns(probe)))
    for n, w in enumerate([world(box, 0.0, 0.0), world(cut, 1.0, d),
                           SimpleNamespace(t=2.0, body=None, rigid=())]):
        recorder(n, w)
    rows = list(csv.reader(open(tmp_path / "p.csv")))
    assert rows[0] == ["step", "time", "p_displacement_x", "p_displacement_y",
                       "p_displacement_z"]
    got = np.array(rows[1:], dtype=float)[:, 2:]
    np.testing.assert_allclose(got[0], x @ grad, rtol=0, atol=1e3 * EPS * 1e-2)
    np.testing.assert_allclose(got[1], x @ grad + d, rtol=0, atol=1e3 * EPS * 1e-2)
    assert np.all(np.isnan(got[2]))
