"""PARDISO's back-solve against its forward and backward halves, for 1 to 54 right-hand sides.

    python benchmarks/pardiso_halves.py                  # the ~100k-tet bar, best of 5
    python benchmarks/pardiso_halves.py --tets 10000 --repeats 7

The stiffness (free dofs) of the brittle bar of benchmarks/fracture.py, factorized by
PARDISO as ``fem_frac.solve.linalg`` does. For each number of right-hand sides: the wall
time of phase 33 (the back-solve), 331 (forward substitution) and 333 (backward), best of
``--repeats``; and checks that 331 then 333 is the back-solve to the bit. A bordered factor
(fem_frac/solve/bordered.py) back-solved ``m`` columns for ``G = A^-1 C`` per insertion; it
now forward-substitutes them (``Y = R C``). docs/performance.md, "Insertions, seventh pass".
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as the fem-frac command runs

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tets", type=int, default=100_000)
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--columns", type=int, nargs="+", default=[1, 8, 27, 54])
    args = p.parse_args()

    from fracture import case_dict

    from fem_frac.app.driver import prepare
    from fem_frac.config.schema import Case
    from fem_frac.solve.linalg import factorize
    from fem_frac.timing import StageTimer

    disc = prepare(Case.model_validate(case_dict(args.tets)), Path("."), StageTimer()).disc
    free = disc.constrained.free
    a = sp.csr_matrix(disc.ops.stiffness[free][:, free])
    factor = factorize(a, "pardiso")
    forward, backward = factor.halves
    print(f"{disc.mesh.n_tets:,} tets, {a.shape[0]:,} free dofs, "
          f"{factor.nonzeros:,} entries in the factor")
    print("| right-hand sides | back-solve (33) ms | forward (331) ms | backward (333) ms |")
    print("|---|---|---|---|")
    rng = np.random.default_rng(0)
    for k in args.columns:
        b = np.asfortranarray(rng.standard_normal((a.shape[0], k)))
        assert np.array_equal(backward(forward(b)), factor.solve(b))
        times = []
        for run in (factor.solve, forward, backward):
            best = float("inf")
            for _ in range(args.repeats):
                t0 = time.perf_counter()
                run(b)
                best = min(best, time.perf_counter() - t0)
            times.append(best * 1e3)
        print(f"| {k} | " + " | ".join(f"{t:.1f}" for t in times) + " |")


if __name__ == "__main__":
    main()
