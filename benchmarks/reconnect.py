"""A crack insertion's reconnected stiffness, and the smoothing update's graph, in isolation.

    python benchmarks/reconnect.py                  # ~100k tets, best of 5
    python benchmarks/reconnect.py --tets 10000 --repeats 3

Meshes a 1 x 0.5 x 0.25 box with gmsh (``fem_frac.mesh.geometry.build``) at about
``--tets`` tets, assembles the P1 stiffness, opens two cracks in turn (nine vertices each,
``open_crack`` with normal x, at x = 0.5 and x = 0.3 for y < 0.3) and times the second
reconnection (:func:`fem_frac.fem.reconnect.reconnect`), best of ``--repeats`` calls each
from cold caches (a 64 MiB buffer written first):

- **every entry searched**: without the first reconnection's diagonal, as after a fresh
  assembly (and as every reconnection did before the eleventh pass of
  docs/performance.md);
- **touched rows**: with it, as a run's later insertions do. The two stiffnesses are
  checked to be the same bits.

And ``scipy.sparse.csgraph.connected_components`` (strong components, as
``fracture.smoothing._reachable_within`` calls it) on a graph of the smoothing update's
shape: about ``--tets`` x 8 nodes on a square grid, 4 edges each to the neighbours (itself
at the edge: local and symmetric, as the update's (row, tet) pairs), with int8 weights
(converted to float64 by scipy, a copy of the graph) and float64 weights; the labels are
checked to give the same components.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as the fem-frac command

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
from fracture import best  # noqa: E402  (best of the repeats, each from cold caches)


def crack(mesh, x: float):
    from fem_frac.fracture import open_crack

    p = mesh.points
    near = np.flatnonzero((p[:, 1] < 0.3) & (p[:, 1] > 0.0) & (p[:, 2] > 0.0)
                          & (p[:, 2] < 0.25))
    vertices = near[np.argsort(np.abs(p[near, 0] - x), kind="stable")[:9]]
    return open_crack(mesh, vertices, np.tile([1.0, 0.0, 0.0], (vertices.size, 1)))


def reconnection(n_tets: int, repeats: int) -> dict:
    from fem_frac.fem.operators import strain_operator
    from fem_frac.fem.reconnect import changed_tets, reconnect
    from fem_frac.fem.space import build_space
    from fem_frac.fem.tensors import isotropic_tangent
    from fem_frac.mesh.geometry import build

    d = isotropic_tangent(30e9, 0.2)
    h = (4.5 * 0.125 / n_tets) ** (1 / 3)  # gmsh box: n_tets ~ 4.5 volume / h^3
    mesh = build("box", {"origin": (0, 0, 0), "lengths": (1.0, 0.5, 0.25)}, h)
    once, t1 = crack(mesh, 0.5)
    twice, t2 = crack(once, 0.3)
    spaces = [build_space(m, 1) for m in (mesh, once, twice)]
    op0 = strain_operator(spaces[0])
    c1 = changed_tets(mesh.tets, once.tets, np.asarray(t1.node_map))
    c2 = changed_tets(once.tets, twice.tets, np.asarray(t2.node_map))
    op1, k1, d1 = reconnect(op0, op0.stiffness(d), d, spaces[1], np.asarray(mesh.tets),
                            np.asarray(once.tets), c1)
    args = (op1, k1, d, spaces[2], np.asarray(once.tets), np.asarray(twice.tets), c2)
    every, (_, a, _) = best(lambda: reconnect(*args), repeats)
    touched, (_, b, _) = best(lambda: reconnect(*args, d1), repeats)
    assert all(np.array_equal(getattr(a, k), getattr(b, k))
               for k in ("indptr", "indices", "data")), "not the same stiffness"
    return {"tets": mesh.n_tets, "dofs": spaces[2].n_dofs, "nnz": a.nnz,
            "every entry searched": every, "touched rows": touched}


def graph(n_tets: int, repeats: int) -> dict:
    from scipy.sparse.csgraph import connected_components

    # a square grid, each node's 4 neighbours (itself at the edge), as the update's pairs
    # point to their tets' face neighbours within the row (themselves where none): local and
    # symmetric
    side = int(np.sqrt(8 * n_tets))
    n, width = side * side, 4
    i, j = np.divmod(np.arange(n), side)
    target = np.stack([np.where(i > 0, -side, 0), np.where(i < side - 1, side, 0),
                       np.where(j > 0, -1, 0), np.where(j < side - 1, 1, 0)], axis=1)
    target = (np.arange(n)[:, None] + target).ravel()
    indptr = np.arange(0, n * width + 1, width, dtype=np.int64)
    out, labels = {"nodes": n, "edges": n * width}, []
    for name, dtype in (("int8 weights", np.int8), ("float64 weights", np.float64)):
        g = sp.csr_matrix((np.ones(target.size, dtype=dtype), target, indptr), shape=(n, n))
        out[name], (_, label) = best(
            lambda g=g: connected_components(g, directed=True, connection="strong"), repeats)
        labels.append(label)
    # the same components: the labels of the two runs correspond one to one
    pairs = np.unique(np.c_[labels[0], labels[1]], axis=0)
    assert len(pairs) == len(np.unique(labels[0])) == len(np.unique(labels[1])), \
        "not the same components"
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tets", type=int, default=100_000)
    p.add_argument("--repeats", type=int, default=5)
    a = p.parse_args()
    r = reconnection(a.tets, a.repeats)
    print(f"reconnection, {r['tets']:,} tets, {r['dofs']:,} dofs, nnz(K) {r['nnz']:,}: "
          f"every entry searched {1e3 * r['every entry searched']:.1f} ms, touched rows "
          f"{1e3 * r['touched rows']:.1f} ms (the same bits)")
    g = graph(a.tets, a.repeats)
    print(f"strong components, {g['nodes']:,} nodes, {g['edges']:,} edges: int8 weights "
          f"{1e3 * g['int8 weights']:.1f} ms, float64 weights "
          f"{1e3 * g['float64 weights']:.1f} ms (the same components)")


if __name__ == "__main__":
    main()
