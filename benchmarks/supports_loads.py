"""Cost of the supports and loads (the ``loads`` stage) at ~10k and ~100k tets, P1 and P2,
and in a whole fracture run, where they are rebuilt on every insertion batch.

    python benchmarks/supports_loads.py                           # both parts, 3 repeats (min-max)
    python benchmarks/supports_loads.py --tets 10000 --orders 1 --no-case
    PYTHONPATH=/path/to/other/checkout python benchmarks/supports_loads.py   # another version

Part 1: a 4 x 1 x 1 box meshed by gmsh (as benchmarks/pipeline.py), with a fixed end
(``xmin``), a symmetry plane (``ymin``), a traction on ``xmax`` and a pressure on ``zmax``.
Each repeat (after an untimed one) builds a fresh space (scikit-fem's mesh caches its
facet and edge tables, so a reused one would hide them) and times what the ``loads`` stage
of a run wraps (``element_materials`` and ``build_problem``); ``exterior_s`` is the floor of
finding the boundary faces at all (``exterior_facets``). Part 2: ``fem-frac run`` of the case
(cases/notched_beam.yaml by default), each run in its own process; the ``loads``,
``fracture rebuild`` and ``total`` of summary.json's ``wall_time_s`` and its batches.
Prints markdown tables of min-max over the repeats.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LENGTHS = (4.0, 1.0, 1.0)
TETS_PER_H3 = 4.5  # gmsh's tets per h^3 of volume (benchmarks/pipeline.py)


def _conditions() -> list:
    from fem_frac.config import schema

    return [schema.Fixed(type="fixed", boundary="xmin"),
            schema.Symmetry(type="symmetry", boundary="ymin"),
            schema.Traction(type="traction", boundary="xmax", traction=(0.0, 0.0, -1e6)),
            schema.Pressure(type="pressure", boundary="zmax", pressure=1e5)]


def box_mesh(n_tets: int, order: int):
    from fem_frac.config.schema import MeshSection
    from fem_frac.mesh.build import build_mesh

    h = (TETS_PER_H3 * LENGTHS[0] * LENGTHS[1] * LENGTHS[2] / n_tets) ** (1 / 3)
    section = MeshSection(geometry={"type": "box", "lengths": LENGTHS}, element_size=h,
                          order=order)
    return build_mesh(section, case_dir=None)


def loads_stage(n_tets: int, order: int, repeats: int) -> dict:
    """Seconds of building the space, the loads stage and the exterior faces, per repeat."""
    from fem_frac.config import schema
    from fem_frac.fem.space import build_space
    from fem_frac.mesh.mesh import exterior_facets
    from fem_frac.plasticity.regions import element_materials
    from fem_frac.solve.problem import build_problem

    mesh = box_mesh(n_tets, order)
    material = schema.Material(youngs_modulus=210e9, poissons_ratio=0.3, density=7800)
    row = {"tets": mesh.n_tets, "order": order, "space_s": [], "loads_s": [],
           "exterior_s": []}
    for k in range(repeats + 1):  # the first, untimed, imports what the others use
        t = time.perf_counter()
        space = build_space(mesh, order)
        row["space_s"].append(time.perf_counter() - t)
        t = time.perf_counter()
        materials = element_materials(material, [], mesh)
        problem = build_problem(space, _conditions(), None, materials.density)
        row["loads_s"].append(time.perf_counter() - t)
        t = time.perf_counter()
        exterior_facets(mesh.tets)
        row["exterior_s"].append(time.perf_counter() - t)
        if k == 0:
            row = {key: [] if isinstance(v, list) else v for key, v in row.items()}
    row["dofs"] = space.n_dofs
    row["constrained"] = len(problem.constraints.dofs)
    return row


def case_runs(case: Path, repeats: int) -> dict:
    """``wall_time_s`` figures of ``repeats`` runs of ``case``, each in its own process."""
    row: dict = {"case": case.name, "loads_s": [], "rebuild_s": [], "total_s": []}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(repeats):
            cmd = [sys.executable, "-m", "fem_frac", "run", str(case), "-o", tmp, "-q",
                   "--overwrite"]
            # from the folder above the package this script imported: ``-m`` looks there first
            subprocess.run(cmd, check=True, capture_output=True, cwd=_checkout())
            summary = json.loads((Path(tmp) / "summary.json").read_text())
            wall = summary["wall_time_s"]
            row["loads_s"].append(wall["loads"])
            row["rebuild_s"].append(wall.get("fracture rebuild", 0.0))
            row["total_s"].append(wall["total"])
            row["batches"] = summary.get("fracture", {}).get("batches")
    return row


def _checkout() -> Path:
    import fem_frac

    return Path(fem_frac.__file__).resolve().parents[1]


def span(values: list[float]) -> str:
    return f"{min(values):.3f}-{max(values):.3f}"


def box_table(sizes: list[int], orders: list[int], repeats: int) -> None:
    print("| tets | order | dofs | constrained dofs | space s | loads s | exterior faces s |")
    print("|---|---|---|---|---|---|---|")
    for n in sizes:
        for order in orders:
            r = loads_stage(n, order, repeats)
            print(f"| {r['tets']:,} | P{order} | {r['dofs']:,} | {r['constrained']:,} | "
                  f"{span(r['space_s'])} | {span(r['loads_s'])} | {span(r['exterior_s'])} |",
                  flush=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tets", type=int, nargs="+", default=[10_000, 100_000])
    p.add_argument("--orders", type=int, nargs="+", default=[1, 2])
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--case", type=Path, default=ROOT / "cases" / "notched_beam.yaml")
    p.add_argument("--no-case", action="store_true", help="only the box meshes")
    p.add_argument("--no-box", action="store_true", help="only the case")
    args = p.parse_args()
    import fem_frac

    print(f"fem_frac from {Path(fem_frac.__file__).parent}", file=sys.stderr)
    if not args.no_box:
        box_table(args.tets, args.orders, args.repeats)
    if not args.no_case:
        r = case_runs(args.case, args.repeats)
        print("\n| case | batches | loads s | fracture rebuild s | total s |")
        print("|---|---|---|---|---|")
        print(f"| {r['case']} | {r['batches']} | {span(r['loads_s'])} | "
              f"{span(r['rebuild_s'])} | {span(r['total_s'])} |")


if __name__ == "__main__":
    main()
