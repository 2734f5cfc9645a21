"""The elastic thick sphere, fem-frac (P2) against CalculiX (C3D10) on the same meshes: the
error against the process CPU time of each solver.

The problem: one octant of a thick sphere, radii 1 and 2, E = 210000, nu = 0.3, internal
pressure 100, symmetry on the three planes (Lame's solution,
``fem_frac.verify.exact.lame_sphere_displacement``).

For each element size, the benchmark meshes the octant once with gmsh, through fem-frac's
own geometry (``fem_frac.mesh.geometry.hollow_sphere``, quadratic tets with their mid nodes
on the spheres), and writes that one mesh twice: a gmsh 2.2 ``.msh`` file with the named
faces (read by ``fem-frac run`` with ``mesh: {file, order: 2}``) and a CalculiX deck
(``.inp``: the same nodes, the tets as C3D10, the symmetry planes as node sets, the pressure
as ``*DLOAD`` on the element faces of the bore). Both solvers thus solve the same discrete
problem, and the table gives the difference of their solutions beside their errors.

Each solve is a whole process started as a user starts it, from the mesh file on disk to its
results on disk: ``fem-frac run CASE -o DIR -q`` (its VTK series, history and summary) and
``ccx -i JOB`` (its ``.dat`` with the nodal displacements, ``*NODE PRINT``). The meshing
itself (the same for both) is timed separately. "CPU s" is the child's user + system time
(``getrusage(RUSAGE_CHILDREN)`` deltas: interpreter or program start, reading, assembly,
solve, writing); the solvers run round-robin, ``--repeats`` times each; the table gives the
minimum and the spread (max - min). The error is the same for both, computed by this script
from the nodal displacements each wrote (every node, corner and mid node): the relative
nodal L2 error ``sqrt(sum |u_h - u|^2 / sum |u|^2)`` against Lame's ``u`` at the node, and
the error in ``u(b)`` (the mean radial displacement of the outer nodes, as the Hill benchmark
measures it). Before the timed runs each solver runs once untimed (the file cache; and
fem-frac's compiled modules, which the children may write: ``PYTHONDONTWRITEBYTECODE`` is
dropped from their environment, as a user's installation caches them).

Beside the solvers, the same way and round-robin with them, it times what any Python program
that uses numpy pays before its first line of work (left out with ``--no-references``): this
interpreter with ``-c pass``, ``-c "import numpy"`` and ``-c "import numpy, scipy.sparse"``
(OpenBLAS on one thread, as ``fem-frac`` loads it). Where CalculiX's whole run takes less
CPU time than importing numpy, no program built on numpy can match it at that size; the
last table gives that comparison for each size.

Needs CalculiX's ``ccx`` on the PATH (Debian: ``apt-get install calculix-ccx``, version 2.20).

    python benchmarks/calculix_sphere.py                         # every size, 3 repeats
    python benchmarks/calculix_sphere.py --sizes 0.5 0.2 --repeats 5
    python benchmarks/calculix_sphere.py --json out.json
    python benchmarks/calculix_sphere.py --sizes 1 0.5 0.3 0.2  # the coarse sizes, where
                                                                # CalculiX's whole run costs
                                                                # about numpy's import
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import meshio
import numpy as np
import yaml

from fem_frac.mesh.geometry import hollow_sphere
from fem_frac.mesh.mesh import TET_FACES, edge_keys, facet_keys, match
from fem_frac.mesh.reader import VTK_TET10_EDGES
from fem_frac.verify.exact import lame_sphere_displacement, lame_sphere_radial_displacement

FEM_FRAC = Path(sys.executable).parent / "fem-frac"
INNER, OUTER, E, NU, PRESSURE = 1.0, 2.0, 210000.0, 0.3, 100.0
SIZES = (1.0, 0.5, 0.3, 0.2, 0.14, 0.1, 0.07)
# C3D10 faces (CalculiX = Abaqus numbering) by the one corner they leave out:
# face 1 = 1-2-3, face 2 = 1-4-2, face 3 = 2-4-3, face 4 = 3-4-1
FACE_WITHOUT = {3: 1, 2: 2, 0: 3, 1: 4}


@dataclass
class Mesh10:
    points: np.ndarray  # (n, 3): corners, then one mid node per edge
    tets: np.ndarray  # (m, 10) in VTK's (= CalculiX's C3D10) node order
    faces: dict  # name -> (k, 3) corner triples


def quadratic_mesh(size: float) -> tuple[Mesh10, float]:
    """fem-frac's gmsh octant at ``size``, with a node on every edge (the curved ones where
    gmsh put them); and the CPU seconds meshing took."""
    start = time.process_time()
    mesh = hollow_sphere((0, 0, 0), INNER, OUTER, "octant", element_size=size, order=2)
    cpu = time.process_time() - start
    pairs = np.sort(mesh.tets[:, VTK_TET10_EDGES].reshape(-1, 2), axis=1)
    edges, edge_of = np.unique(pairs, axis=0, return_inverse=True)
    mids = 0.5 * (mesh.points[edges[:, 0]] + mesh.points[edges[:, 1]])
    n = len(mesh.points)
    if mesh.curved:
        mids[match(edge_keys(edges, n), edge_keys(mesh.edges, n))] = mesh.edge_points
    tets = np.hstack([mesh.tets, n + edge_of.reshape(-1, 6)])
    # CalculiX reads a number in at most 20 characters: both files get the coordinates
    # rounded to 14 digits (what "%.13e" writes)
    points = np.array([float(f"{v:.13e}") for v in np.vstack([mesh.points, mids]).ravel()])
    return Mesh10(points.reshape(-1, 3), tets, dict(mesh.boundaries)), cpu


def write_msh(mesh: Mesh10, path: Path) -> None:
    """A gmsh 2.2 file: the tets and the named faces as physical groups."""
    cells, physical, field = [("tetra10", mesh.tets)], [np.ones(len(mesh.tets), int)], {}
    field["solid"] = np.array([1, 3])
    for tag, (name, tris) in enumerate(sorted(mesh.faces.items()), start=2):
        cells.append(("triangle", tris))
        physical.append(np.full(len(tris), tag))
        field[name] = np.array([tag, 2])
    meshio.write(path, meshio.Mesh(mesh.points, cells,
                                   cell_data={"gmsh:physical": physical,
                                              "gmsh:geometrical": physical},
                                   field_data=field), file_format="gmsh22", binary=False)


def write_inp(mesh: Mesh10, path: Path) -> None:
    """The CalculiX deck of the same problem (1-based ids)."""
    lines = ["*NODE, NSET=NALL"]
    lines += [f"{i + 1}, {x:.13e}, {y:.13e}, {z:.13e}" for i, (x, y, z) in enumerate(mesh.points)]
    lines.append("*ELEMENT, TYPE=C3D10, ELSET=EALL")
    lines += [f"{i + 1}, " + ", ".join(map(str, t + 1)) for i, t in enumerate(mesh.tets)]
    for axis in range(3):
        nodes = np.unique(_face_nodes(mesh, f"symmetry_{'xyz'[axis]}")) + 1
        lines.append(f"*NSET, NSET=SYM{axis + 1}")
        lines += [", ".join(map(str, nodes[i:i + 16])) for i in range(0, len(nodes), 16)]
    lines += ["*BOUNDARY"] + [f"SYM{k}, {k}, {k}" for k in (1, 2, 3)]
    lines += ["*MATERIAL, NAME=STEEL", "*ELASTIC", f"{E:.17g}, {NU:.17g}",
              "*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL", "*STEP", "*STATIC", "*DLOAD"]
    element, face = _bore_faces(mesh)
    lines += [f"{e + 1}, P{f}, {PRESSURE:.17g}" for e, f in zip(element, face, strict=True)]
    lines += ["*NODE PRINT, NSET=NALL", "U", "*END STEP", ""]
    path.write_text("\n".join(lines))


def _face_nodes(mesh: Mesh10, name: str) -> np.ndarray:
    """Corner and mid nodes of the faces ``name`` (the mid nodes of their tets' edges)."""
    corners = np.unique(mesh.faces[name])
    on = np.isin(mesh.tets[:, :4], corners)
    both = on[:, VTK_TET10_EDGES[:, 0]] & on[:, VTK_TET10_EDGES[:, 1]]
    mids = mesh.tets[:, 4:][both]
    # an edge with both ends on the plane lies in it (the faces are planar, the tets convex)
    return np.concatenate([corners, mids])


def _bore_faces(mesh: Mesh10) -> tuple[np.ndarray, np.ndarray]:
    """(element, face number) of every bore triangle (face row ``4 t + i`` of the corner
    table is face ``i`` of tet ``t``, opposite its corner ``i``)."""
    corners, n = mesh.tets[:, :4], len(mesh.points)
    faces = corners[:, TET_FACES].reshape(-1, 3)
    row = match(facet_keys(faces, n), facet_keys(mesh.faces["inner"], n))
    if np.any(row < 0):
        raise RuntimeError("bore triangles without a tet")
    return row // 4, np.array([FACE_WITHOUT[i] for i in range(4)])[row % 4]


def nodal_error(points: np.ndarray, u: np.ndarray) -> float:
    exact = lame_sphere_displacement(points.T, (0, 0, 0), INNER, OUTER, PRESSURE, E, NU).T
    return float(np.sqrt(np.sum((u - exact) ** 2) / np.sum(exact ** 2)))


def outer_error(points: np.ndarray, u: np.ndarray) -> float:
    """(mean u . x/|x| over the nodes on the outer sphere - u(b)) / u(b): the Hill
    benchmark's measure (benchmarks/hill_speed.py)."""
    r = np.linalg.norm(points, axis=1)
    on = np.abs(r - OUTER) < 1e-9 * OUTER
    radial = np.einsum("ij,ij->i", u[on], points[on]) / r[on]
    exact = lame_sphere_radial_displacement(OUTER, INNER, OUTER, PRESSURE, E, NU)
    return float((radial.mean() - exact) / exact)


def fem_frac_case(msh: Path) -> dict:
    return {
        "title": "thick sphere, internal pressure (Lame), mesh shared with CalculiX",
        "mesh": {"file": str(msh), "order": 2},
        "material": {"youngs_modulus": E, "poissons_ratio": NU},
        "boundary_conditions": [
            *({"type": "symmetry", "boundary": f"symmetry_{a}"} for a in "xyz"),
            {"type": "pressure", "boundary": "inner", "pressure": PRESSURE}],
    }


def cpu_children() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


# as a user's installation runs: Python may cache the compiled modules (a shell that sets
# PYTHONDONTWRITEBYTECODE makes every run compile fem-frac's ~100 modules, 0.12 CPU s)
CHILD_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def timed(command: list[str], cwd: Path, env: dict | None = None) -> tuple[float, float]:
    before, start = cpu_children(), time.perf_counter()
    subprocess.run(command, cwd=cwd, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, env=CHILD_ENV if env is None else env)
    return cpu_children() - before, time.perf_counter() - start


# what a Python program pays before any work: the interpreter, then numpy, then
# scipy.sparse (fem-frac's least imports), with OpenBLAS on one thread as fem-frac loads it
REFERENCES = {"interpreter (-c pass)": "pass", "import numpy": "import numpy",
              "import numpy, scipy.sparse": "import numpy, scipy.sparse"}
REFERENCE_ENV = {**CHILD_ENV, "OPENBLAS_NUM_THREADS": CHILD_ENV.get("OPENBLAS_NUM_THREADS", "1")}


def run_references(work: Path, cpu: dict) -> None:
    """One run of each of :data:`REFERENCES`, its CPU s appended to ``cpu[name]``."""
    for name, code in REFERENCES.items():
        cpu.setdefault(name, []).append(timed([sys.executable, "-c", code], work,
                                              REFERENCE_ENV)[0])


def run_fem_frac(work: Path, size: float, command: Path) -> tuple[float, float, np.ndarray,
                                                                  np.ndarray]:
    case, out = work / f"sphere_{size:g}.yaml", work / f"sphere_{size:g}.out"
    cpu, wall = timed([str(command), "run", str(case), "-o", str(out), "-q", "--overwrite"], work)
    frame = meshio.read(sorted(out.glob("*.vtu"))[-1])
    return cpu, wall, frame.points, frame.point_data["displacement"]


def run_ccx(work: Path, size: float, ccx: str) -> tuple[float, float, np.ndarray]:
    job = f"sphere_{size:g}"
    cpu, wall = timed([ccx, "-i", job], work)
    return cpu, wall, read_dat(work / f"{job}.dat")


NUMBER = r"[-+]?\d*\.?\d+(?:[eE][-+]?\d+)?"


def read_dat(path: Path) -> np.ndarray:
    """The displacements of ``*NODE PRINT`` (node, ux, uy, uz), ordered by node."""
    row = re.compile(rf"^\s*(\d+)\s+({NUMBER})\s+({NUMBER})\s+({NUMBER})\s*$")
    found = [m.groups() for m in map(row.match, path.read_text().splitlines()) if m]
    data = np.array(found, dtype=float)
    order = np.argsort(data[:, 0])
    return data[order, 1:]


@dataclass
class Row:
    size: float
    tets: int
    nodes: int
    mesh_cpu: float
    fem_frac_error: float
    ccx_error: float
    fem_frac_outer: float  # error in u(b)
    ccx_outer: float
    difference: float  # max |u_fem-frac - u_ccx| over the common nodes / max |u|
    fem_frac_cpu: list
    ccx_cpu: list
    fem_frac_wall: list
    ccx_wall: list


def measure(sizes, repeats: int, command: Path, ccx: str, work: Path,
            references: dict | None = None) -> list[Row]:
    """One :class:`Row` per size; with ``references`` (a dict), each repeat also runs
    :func:`run_references` into it, between the two solvers."""
    rows = []
    for size in sizes:
        mesh, mesh_cpu = quadratic_mesh(size)
        write_msh(mesh, work / f"sphere_{size:g}.msh")
        write_inp(mesh, work / f"sphere_{size:g}.inp")
        (work / f"sphere_{size:g}.yaml").write_text(
            yaml.safe_dump(fem_frac_case(work / f"sphere_{size:g}.msh")))
        ff_cpu, ff_wall, cx_cpu, cx_wall = [], [], [], []
        run_fem_frac(work, size, command)  # untimed: the file cache, compiled modules
        run_ccx(work, size, ccx)
        for _ in range(repeats):
            cpu, wall, points, u_ff = run_fem_frac(work, size, command)
            ff_cpu.append(cpu)
            ff_wall.append(wall)
            if references is not None:
                run_references(work, references)
            cpu, wall, u_cx = run_ccx(work, size, ccx)
            cx_cpu.append(cpu)
            cx_wall.append(wall)
        # fem-frac writes its nodes in its own order: match them to the deck's by position
        from scipy.spatial import cKDTree

        dist, match = cKDTree(mesh.points).query(points)
        if dist.max() > 1e-9 * OUTER or len(u_cx) != len(mesh.points):
            raise RuntimeError("the two solvers' nodes differ")
        scale = np.abs(u_cx).max()
        rows.append(Row(size, len(mesh.tets), len(mesh.points), mesh_cpu,
                        nodal_error(points, u_ff), nodal_error(mesh.points, u_cx),
                        outer_error(points, u_ff), outer_error(mesh.points, u_cx),
                        float(np.abs(u_ff - u_cx[match]).max() / scale),
                        ff_cpu, cx_cpu, ff_wall, cx_wall))
        r = rows[-1]
        print(f"size {size:g}: {r.tets} tets, {r.nodes} nodes, errors {r.fem_frac_error:.3e} "
              f"/ {r.ccx_error:.3e}, CPU s min {min(ff_cpu):.2f} / {min(cx_cpu):.2f}",
              file=sys.stderr, flush=True)
    return rows


def table(rows: list[Row]) -> str:
    lines = ["| element size | tets | nodes (dofs / 3) | meshing CPU s | nodal error fem-frac | "
             "nodal error CalculiX | u(b) error fem-frac | u(b) error CalculiX | "
             "solutions differ by | fem-frac CPU s min (spread) | "
             "CalculiX CPU s min (spread) | CalculiX / fem-frac | fem-frac wall s | "
             "CalculiX wall s |", "|---" * 14 + "|"]
    for r in rows:
        ff, cx = min(r.fem_frac_cpu), min(r.ccx_cpu)
        lines.append(
            f"| {r.size:g} | {r.tets:,} | {r.nodes:,} | {r.mesh_cpu:.2f} | "
            f"{r.fem_frac_error:.2e} | {r.ccx_error:.2e} | {r.fem_frac_outer:+.2e} | "
            f"{r.ccx_outer:+.2e} | {r.difference:.1e} | "
            f"{ff:.2f} ({max(r.fem_frac_cpu) - ff:.2f}) | {cx:.2f} ({max(r.ccx_cpu) - cx:.2f}) | "
            f"{cx / ff:.2f} | {min(r.fem_frac_wall):.2f} | {min(r.ccx_wall):.2f} |")
    return "\n".join(lines)


def references_table(rows: list[Row], references: dict) -> str:
    """The start-up references (min and spread of CPU s) and, for each size, whether
    CalculiX's whole run took less CPU time than importing numpy."""
    lines = ["| before any work | CPU s min (spread) | runs |", "|---|---|---|"]
    for name, cpu in references.items():
        lines.append(f"| {name} | {min(cpu):.3f} ({max(cpu) - min(cpu):.3f}) | {len(cpu)} |")
    numpy_cpu = min(references["import numpy"])
    lines += ["", "| element size | u(b) error CalculiX | CalculiX CPU s min | CalculiX / "
              "import numpy | CalculiX faster than importing numpy |", "|---" * 5 + "|"]
    for r in rows:
        cx = min(r.ccx_cpu)
        lines.append(f"| {r.size:g} | {r.ccx_outer:+.2e} | {cx:.2f} | {cx / numpy_cpu:.2f} | "
                     f"{'yes' if cx < numpy_cpu else 'no'} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", nargs="+", type=float, default=SIZES)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", type=Path, help="write every run here")
    parser.add_argument("--fem-frac", type=Path, default=FEM_FRAC,
                        help=f"the command to run (default {FEM_FRAC})")
    parser.add_argument("--ccx", default="ccx", help="CalculiX's command (default ccx)")
    parser.add_argument("--keep", type=Path, help="keep the meshes, decks and results here")
    parser.add_argument("--no-references", dest="references", action="store_false",
                        help="leave out the start-up references (module docstring)")
    args = parser.parse_args()
    ccx = shutil.which(args.ccx)
    if ccx is None:
        sys.exit(f"error: {args.ccx}: not found (Debian: apt-get install calculix-ccx)")
    print(f"load average before: {os.getloadavg()}", file=sys.stderr)
    with tempfile.TemporaryDirectory() as tmp:
        work = args.keep or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        references = {} if args.references else None
        rows = measure(args.sizes, args.repeats, args.fem_frac, ccx, work, references)
    print(f"load average after: {os.getloadavg()}", file=sys.stderr)
    print(table(rows))
    if references:
        print()
        print(references_table(rows, references))
    if args.json:
        args.json.write_text(json.dumps({"sizes": [asdict(r) for r in rows],
                                         "references": references}, indent=1))


if __name__ == "__main__":
    main()
