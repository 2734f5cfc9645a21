"""benchmarks/calculix_sphere.py keeps up with the code it measures: the CalculiX deck it
writes is the fem-frac mesh's problem (the same nodes and tets, the pressure on the bore's
element faces), and with CalculiX installed both solvers solve it alike."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent.parent / "benchmarks"))

import calculix_sphere as cs  # noqa: E402

from fem_frac.mesh.reader import read_mesh_file  # noqa: E402

# C3D10 (Abaqus) faces by their corners, 0-based
C3D10_FACES = {1: (0, 1, 2), 2: (0, 3, 1), 3: (1, 3, 2), 4: (2, 3, 0)}


def _deck(path: Path) -> dict[str, list[list[str]]]:
    """The data lines of each keyword block of an .inp file."""
    blocks: dict[str, list[list[str]]] = {}
    key = None
    for line in path.read_text().splitlines():
        if line.startswith("*"):
            key = line.split(",")[0].strip().upper()
            if key == "*NSET":
                key += line.split("=")[1].strip()
            blocks.setdefault(key, [])
        elif line.strip():
            blocks[key].append([x.strip() for x in line.split(",")])
    return blocks


@pytest.fixture(scope="module")
def sphere(tmp_path_factory):
    work = tmp_path_factory.mktemp("calculix")
    mesh, _ = cs.quadratic_mesh(1.0)
    cs.write_msh(mesh, work / "sphere.msh")
    cs.write_inp(mesh, work / "sphere.inp")
    return mesh, work


def test_the_deck_is_the_mesh(sphere):
    mesh, work = sphere
    deck = _deck(work / "sphere.inp")
    nodes = np.array([[float(v) for v in row[1:]] for row in deck["*NODE"]])
    np.testing.assert_allclose(nodes, mesh.points, rtol=0, atol=1e-13)
    tets = np.array([[int(v) - 1 for v in row[1:]] for row in deck["*ELEMENT"]])
    np.testing.assert_array_equal(tets, mesh.tets)
    # every bore triangle carries the pressure once, on the face of its tet
    loads = [(int(e) - 1, int(f[1:]), float(p)) for e, f, p in deck["*DLOAD"]]
    faces = {tuple(sorted(tets[e, list(C3D10_FACES[f])])) for e, f, _ in loads}
    assert faces == {tuple(sorted(t)) for t in mesh.faces["inner"]}
    assert len(loads) == len(mesh.faces["inner"]) and {p for *_, p in loads} == {cs.PRESSURE}
    # the symmetry node sets lie on their planes and hold every node there
    for k in (1, 2, 3):
        ids = np.array([int(v) - 1 for row in deck[f"*NSETSYM{k}"] for v in row if v])
        on = np.flatnonzero(np.abs(mesh.points[:, k - 1]) < 1e-12)
        np.testing.assert_array_equal(np.sort(ids), on)


def test_fem_frac_reads_the_same_mesh(sphere):
    mesh, work = sphere
    read = read_mesh_file(work / "sphere.msh", 2)
    np.testing.assert_array_equal(read.tets, mesh.tets[:, :4])
    assert set(read.boundaries) >= {"inner", "outer", "symmetry_x", "symmetry_y",
                                    "symmetry_z"}
    assert read.curved


@pytest.mark.skipif(shutil.which("ccx") is None, reason="CalculiX (ccx) is not installed")
def test_both_solvers_solve_the_same_problem(tmp_path):
    (row,) = cs.measure([1.0], 1, cs.FEM_FRAC, shutil.which("ccx"), tmp_path)
    # the same discretization but for each solver's quadrature of the curved elements and
    # the pressure: far closer than the discretization error (2e-2 at this size)
    assert row.difference < 0.2 * row.fem_frac_error
    assert abs(row.fem_frac_error - row.ccx_error) < 0.05 * row.ccx_error


def test_the_start_up_references_run(tmp_path):
    """Each reference is one interpreter process whose CPU time is recorded per repeat (the
    table compares CalculiX's runs with the least of numpy's)."""
    cpu: dict = {}
    cs.run_references(tmp_path, cpu)
    cs.run_references(tmp_path, cpu)
    assert list(cpu) == list(cs.REFERENCES)
    assert all(len(v) == 2 and all(t >= 0.0 for t in v) for v in cpu.values())
    row = cs.Row(1.0, 1, 1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, [1.0], [2 * min(cpu["import numpy"])],
                 [1.0], [1.0])
    table = cs.references_table([row], cpu)
    assert "| import numpy |" in table and table.rstrip().endswith("| no |")
