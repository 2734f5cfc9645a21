"""The balance of the acceleration after a crack insertion with Newmark: one solve with the
consistent mass on the free dofs (``fem_frac.solve.state.balanced_acceleration``), by a fresh
factorization (what it was) against conjugate gradients preconditioned by the mass's
diagonal (``mass_solve``, what it is).

A unit cube of tensor-grid tets held on x = 0, P1 and P2, density 1; a random right-hand
side. Process CPU time, best of ``--repeats``; the CG iterations; the relative difference
of the two solutions.

    python benchmarks/mass_solve.py                 # ~25k and ~200k P1 tets, ~25k P2 tets
    python benchmarks/mass_solve.py --cells 16 --repeats 5

Results in docs/performance.md ("The mass solve after an insertion").
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.sparse.linalg as spla

from fem_frac.fem.mass import consistent_mass
from fem_frac.fem.space import build_space
from fem_frac.mesh import Mesh
from fem_frac.solve.linalg import factorize
from fem_frac.solve.state import mass_solve


class _Held:
    """The free dofs of the cube held on x = 0, and their factorization (as
    ``fem_frac.solve.constrained.Constrained`` offers them)."""

    def __init__(self, free: np.ndarray):
        self.free = free

    def factorize(self, matrix):
        return factorize(matrix[self.free][:, self.free].tocsr())


def cube(cells: int) -> Mesh:
    from skfem import MeshTet

    m = MeshTet.init_tensor(*[np.linspace(0.0, 1.0, cells + 1)] * 3)
    return Mesh(m.p.T.copy(), m.t.T.copy())


def measure(cells: int, order: int, repeats: int) -> dict:
    space = build_space(cube(cells), order)
    mass = consistent_mass(space, 1.0).tocsr()
    held = np.flatnonzero(np.abs(space.node_points[:, 0]) < 1e-12)
    fixed = (3 * held[:, None] + np.arange(3)).ravel()
    constrained = _Held(np.setdiff1d(np.arange(space.n_dofs), fixed))
    rhs = np.random.default_rng(0).standard_normal(constrained.free.size)
    # CG first: after a PARDISO call MKL's threads spin a while, and process CPU time
    # counts them
    cg, direct = [], []
    for _ in range(repeats):
        t = time.process_time()
        x_cg = mass_solve(mass, constrained, rhs)
        cg.append(time.process_time() - t)
    for _ in range(repeats):
        t = time.process_time()
        x_direct = constrained.factorize(mass).solve(rhs)
        direct.append(time.process_time() - t)
    m = mass[constrained.free][:, constrained.free].tocsr()
    count = [0]
    spla.cg(m, rhs, rtol=1e-13, atol=0.0, maxiter=500,
            M=spla.LinearOperator(m.shape, matvec=lambda r: r / m.diagonal()),
            callback=lambda _: count.__setitem__(0, count[0] + 1))
    return {"order": order, "tets": space.mesh.n_tets, "dofs": constrained.free.size,
            "direct": min(direct), "cg": min(cg), "iterations": count[0],
            "difference": float(np.abs(x_cg - x_direct).max() / np.abs(x_direct).max())}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cells", type=int, nargs="*", help="P1 cubes of cells^3 x 6 tets")
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args()
    runs = [(c, 1) for c in args.cells] if args.cells else [(16, 1), (32, 1), (16, 2)]
    print("| order | tets | free dofs | factorization + solve, CPU s | CG, CPU s | CG iterations "
          "| ratio | difference |")
    print("|---|---|---|---|---|---|---|---|")
    for cells, order in runs:
        r = measure(cells, order, args.repeats)
        print(f"| P{r['order']} | {r['tets']:,} | {r['dofs']:,} | {r['direct']:.3f} "
              f"| {r['cg']:.3f} | {r['iterations']} | {r['direct'] / r['cg']:.1f} "
              f"| {r['difference']:.1e} |")


if __name__ == "__main__":
    main()
