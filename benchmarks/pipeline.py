"""Cost of each stage of a static solve at ~10k and ~100k tets, P1 and P2.

Each configuration runs in a fresh subprocess so its peak memory (RSS high-water mark) is
its own. Prints a markdown table; the numbers are recorded in docs/performance.md.

    python benchmarks/pipeline.py                      # 10k and 100k tets, P1 and P2
    python benchmarks/pipeline.py --tets 10000 --orders 1 --solver superlu
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time

# A box of 4 x 1 x 1 clamped at one end and loaded at the other: a beam-like, well-posed
# problem whose mesh size is set to reach the requested number of tets.
LENGTHS = (4.0, 1.0, 1.0)
# gmsh's unstructured tets (HXT): n_tets ~ TETS_PER_H3 * volume / h^3 (measured 4.4-5.6)
TETS_PER_H3 = 4.5


def peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def one(n_tets: int, order: int, solver: str, repeats: int) -> dict:
    import numpy as np
    from skfem import condense

    from fem_frac.config.schema import MeshSection
    from fem_frac.fem.elasticity import stiffness
    from fem_frac.fem.space import build_space
    from fem_frac.fem.tensors import isotropic_tangent
    from fem_frac.mesh.build import build_mesh
    from fem_frac.solve.linalg import factorize

    volume = LENGTHS[0] * LENGTHS[1] * LENGTHS[2]
    h = (TETS_PER_H3 * volume / n_tets) ** (1 / 3)
    row: dict = {"target_tets": n_tets, "order": order}
    t = time.perf_counter()
    section = MeshSection(
        geometry={"type": "box", "lengths": LENGTHS}, element_size=h, order=order
    )
    mesh = build_mesh(section, case_dir=None)
    row["mesh_s"] = time.perf_counter() - t
    row["tets"] = mesh.n_tets
    row["peak_mesh_mib"] = peak_mib()

    t = time.perf_counter()
    space = build_space(mesh, order)
    row["space_s"] = time.perf_counter() - t
    row["dofs"] = space.n_dofs

    t = time.perf_counter()
    k = stiffness(space, isotropic_tangent(210e9, 0.3))
    row["assemble_s"] = time.perf_counter() - t
    row["peak_assemble_mib"] = peak_mib()

    clamped = np.nonzero(space.node_points[:, 0] < 1e-9)[0]
    dofs = (3 * clamped[:, None] + np.arange(3)).ravel()
    f = np.zeros(space.n_dofs)
    f[3 * np.nonzero(space.node_points[:, 0] > LENGTHS[0] - 1e-9)[0] + 2] = -1.0
    a, b, x, interior = condense(k, f, D=dofs)
    a = a.tocsr()
    # load the solver library (MKL: ~0.4 s once per process) outside the timing
    import scipy.sparse as sp

    factorize(sp.identity(3, format="csr"), solver)
    t = time.perf_counter()
    fact = factorize(a, solver)
    row["factorize_s"] = time.perf_counter() - t
    row["solver"] = fact.method
    row["peak_factorize_mib"] = peak_mib()

    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        y = fact.solve(b)
        times.append(time.perf_counter() - t)
    row["solve_s"] = float(np.median(times))
    row["residual"] = float(np.linalg.norm(a @ y - b) / np.linalg.norm(b))
    row["peak_mib"] = peak_mib()
    return row


COLUMNS = [
    ("tets", "{:,}"), ("order", "P{}"), ("dofs", "{:,}"), ("mesh_s", "{:.2f}"),
    ("space_s", "{:.2f}"), ("assemble_s", "{:.2f}"), ("solver", "{}"),
    ("factorize_s", "{:.2f}"), ("solve_s", "{:.3f}"), ("residual", "{:.1e}"),
    ("peak_assemble_mib", "{:,.0f}"), ("peak_mib", "{:,.0f}"),
]


def table(rows: list[dict]) -> str:
    head = "| " + " | ".join(c for c, _ in COLUMNS) + " |"
    rule = "|" + "---|" * len(COLUMNS)
    body = [
        "| " + " | ".join(fmt.format(r[c]) for c, fmt in COLUMNS) + " |" for r in rows
    ]
    return "\n".join([head, rule, *body])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tets", type=int, nargs="+", default=[10_000, 100_000])
    p.add_argument("--orders", type=int, nargs="+", default=[1, 2])
    p.add_argument("--solver", default="auto")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--one", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.one:
        n, order = map(int, args.one.split(","))
        print(json.dumps(one(n, order, args.solver, args.repeats)))
        return
    rows = []
    for n in args.tets:
        for order in args.orders:
            cmd = [sys.executable, __file__, "--one", f"{n},{order}", "--solver", args.solver,
                   "--repeats", str(args.repeats)]
            done = subprocess.run(cmd, capture_output=True, text=True)
            if done.returncode != 0:
                print(f"{n} tets P{order}: failed\n{done.stderr[-2000:]}", file=sys.stderr)
                continue
            rows.append(json.loads(done.stdout.strip().splitlines()[-1]))
            print(table(rows[-1:]).splitlines()[-1], file=sys.stderr, flush=True)
    print(table(rows))


if __name__ == "__main__":
    main()
