"""Sparse strain operators (fem_frac.fem.operators): build once, then strain ``B u``,
internal force ``B^T sigma dx`` and stiffness, the last against element matrices.

Meshes a unit cube with gmsh (``fem_frac.mesh.geometry.build("box", ...)``) at an element
size giving about the requested number of tets, builds the P1/P2 space, and times (best of
``--repeat``) building the operator, one ``strain``, one ``internal_force`` and one
``stiffness`` with a shared isotropic D, the stiffness next to the element-matrix
``elasticity.stiffness``. P1 also in the ``averaged`` formulation (its strain and force go
through the standard B plus two thin averaging matrices; its ``matrix`` is only needed for
the stiffness).

The element kernels ``elasticity.strain`` / ``internal_force`` that the two ``old`` columns
of the table below timed were test-only and have been removed from fem_frac.fem.elasticity;
the script no longer prints those columns (the figures are kept as measured).

    python benchmarks/operators.py
    python benchmarks/operators.py --cases 1:100000 2:50000 --repeat 5

``--rcm`` adds each mesh renumbered in reverse Cuthill-McKee order (rows ``+rcm``), to
show what node locality does to the sparse products.

Measured with ``--rcm`` on a 2-core x86-64 VM shared with other jobs (numpy 2.4, scipy
1.17), best of 5 (stiffness: of 3), then the lower of two whole runs; times in ms.
``old``: the removed kernels elasticity.strain, internal_force. ``BT csr``: the rejected
alternative to ``internal_force``, a CSR copy of ``matrix.T`` times the weighted stress
(for ``ave`` that is the full averaged matrix, against the factored product in ``force``).
Dofs: 7866 and 56769 (P1), 54879 and 221712 (P2).
``K prod``: ``product_stiffness``; ``K elem``: ``elasticity.stiffness``.

| P | form    | tets  | nnz(B) | build | strain | old  | force | BT csr | old  | K prod | K elem |
|---|---------|-------|--------|-------|--------|------|-------|--------|------|--------|--------|
| 1 | sta     | 11674 | 0.42M  | 8.76  | 0.242  | 3.36 | 0.384 | 0.283  | 1.78 | 31.6   | 51.9   |
| 1 | ave     | 11674 | 3.61M  | 121   | 0.327  | 3.36 | 0.507 | 3.97   | 1.78 | 879    | -      |
| 1 | sta+rcm | 11674 | 0.42M  | 8.31  | 0.225  | 2.12 | 0.331 | 0.237  | 1.57 | 21.3   | 38.1   |
| 1 | ave+rcm | 11674 | 3.61M  | 113   | 0.319  | 2.12 | 0.7   | 3.55   | 1.57 | 653    | -      |
| 1 | sta     | 98897 | 3.56M  | 90.7  | 3.29   | 27.3 | 4.3   | 4.09   | 29.8 | 395    | 432    |
| 1 | ave     | 98897 | 31.9M  | 1060  | 4.47   | 27.3 | 5.78  | 42.2   | 29.8 | 9390   | -      |
| 1 | sta+rcm | 98897 | 3.56M  | 102   | 2.52   | 19.3 | 3.28  | 2.84   | 22.8 | 235    | 431    |
| 1 | ave+rcm | 98897 | 31.9M  | 969   | 3.48   | 19.3 | 4.39  | 29.9   | 22.8 | 7160   | -      |
| 2 | sta     | 11674 | 4.20M  | 98.5  | 2.79   | 15.6 | 3.65  | 3.29   | 25.9 | 440    | 313    |
| 2 | sta+rcm | 11674 | 4.20M  | 101   | 2.37   | 15.7 | 3.21  | 3.08   | 26.7 | 328    | 312    |
| 2 | sta     | 50090 | 18.0M  | 413   | 12.6   | 85.6 | 17.1  | 29.6   | 117  | 2770   | 1370   |
| 2 | sta+rcm | 50090 | 18.0M  | 432   | 10.9   | 71.3 | 14.7  | 15.8   | 127  | 1650   | 1260   |

Reading: the operator's strain and internal force are 4.5-14x faster than the element
kernels (1e5 P1 tets: 3.3 ms against 27 ms and 4.3 ms against 30 ms); building it costs
28-36 of its own strain evaluations, i.e. 3-6 of the old ones, so it pays off within the
first load step. The averaged operator's strain and force cost ~1.35x the standard ones (two
thin averaging products) while its full matrix is 9x larger; its stiffness has ~10x the
nonzeros of the standard one (a tet's strain reaches every vertex of the tets around its
own vertices) and takes 7-9 s at 1e5 tets, and its factorization will be dearer in
proportion. The sparse triple product beats the element matrices for P1, not for P2, which
is how ``StrainOperator.stiffness`` chooses. Timings on this shared VM vary by up to 2x
between runs; ratios within a row are the reliable part. Node locality matters for every
sparse product: RCM renumbering took P1 strain from 3.3 to 2.5 ms and the P1 triple
product from 395 to 235 ms; gmsh's order is not bandwidth-reduced.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from fem_frac.fem import elasticity
from fem_frac.fem.operators import strain_operator
from fem_frac.fem.space import build_space
from fem_frac.fem.tensors import isotropic_tangent
from fem_frac.mesh import Mesh
from fem_frac.mesh.geometry import build

TETS_PER_UNIT_VOLUME = 4.12  # gmsh box, n_tets ~ 4.12 / element_size^3


def best(fn, repeat: int) -> float:
    """Best wall time of ``repeat`` calls, in ms."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e3 * min(times)


def rcm_renumbered(mesh: Mesh) -> Mesh:
    """``mesh`` with its vertices in reverse Cuthill-McKee order and its tets sorted by their
    lowest vertex: the locality experiment of the docstring (straight meshes only)."""
    t = mesh.tets
    rows, cols = np.repeat(t, 4, axis=1).ravel(), np.tile(t, (1, 4)).ravel()
    graph = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(mesh.n_points,) * 2)
    perm = reverse_cuthill_mckee(graph, symmetric_mode=True)
    new = np.empty_like(perm)
    new[perm] = np.arange(perm.size)
    tets = new[t]
    return Mesh(mesh.points[perm], tets[np.argsort(tets.min(axis=1), kind="stable")])


def run(order: int, n_tets: int, repeat: int, stiffness: bool, rcm: bool) -> list[dict]:
    size = (TETS_PER_UNIT_VOLUME / n_tets) ** (1 / 3)
    mesh = build("box", {"origin": (0, 0, 0), "lengths": (1, 1, 1)}, size, order)
    if rcm:
        mesh = rcm_renumbered(mesh)
    space = build_space(mesh, order)
    rng = np.random.default_rng(0)
    u = rng.normal(size=space.n_dofs)
    sigma = rng.normal(size=(6, mesh.n_tets, space.n_qp))
    d = isotropic_tangent(1.0, 0.3)
    k_repeat = min(repeat, 3)
    k_elem = best(lambda: elasticity.stiffness(space, d), k_repeat) if stiffness else None
    rows = []
    for form in ("standard", "averaged") if order == 1 else ("standard",):
        op = strain_operator(space, form)
        copy = op.matrix.T.tocsr()  # the rejected alternative to internal_force's CSC view
        weighted = (sigma * op.weights).ravel()
        rows.append(
            {
                "P": order,
                "form": form[:3] + ("+rcm" if rcm else ""),
                "tets": mesh.n_tets,
                "dofs": space.n_dofs,
                "nnz": op.matrix.nnz,
                "build": best(lambda form=form: strain_operator(space, form), repeat),
                "strain": best(lambda op=op: op.strain(u), repeat),
                "force": best(lambda op=op: op.internal_force(sigma), repeat),
                "BT csr": best(lambda c=copy, w=weighted: c @ w, repeat),
                "K prod": best(lambda op=op: op.product_stiffness(d), k_repeat)
                if stiffness
                else None,
                "K elem": k_elem if form == "standard" else None,
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--cases",
        nargs="+",
        default=["1:10000", "1:100000", "2:10000", "2:50000"],
        help="order:tets pairs",
    )
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--no-stiffness", action="store_true", help="skip the stiffness timing")
    parser.add_argument(
        "--rcm", action="store_true", help="also renumber each mesh (reverse Cuthill-McKee)"
    )
    args = parser.parse_args()
    rows = []
    for case in args.cases:
        order, n_tets = (int(x) for x in case.split(":"))
        for rcm in (False, True) if args.rcm else (False,):
            rows += run(order, n_tets, args.repeat, not args.no_stiffness, rcm)
    keys = list(rows[0])
    print("| " + " | ".join(keys) + " |")
    print("|" + "|".join("---" for _ in keys) + "|")
    for row in rows:
        cells = [
            "-" if v is None else f"{v:.3g}" if isinstance(v, float) else str(v)
            for v in row.values()
        ]
        print("| " + " | ".join(cells) + " |")
    print("times in ms, best of", args.repeat, "(stiffness: best of", min(args.repeat, 3), ")")


if __name__ == "__main__":
    main()
