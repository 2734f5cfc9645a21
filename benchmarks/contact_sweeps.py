"""How many Gauss-Seidel sweeps the contact solver makes in one run of a case.

    python benchmarks/contact_sweeps.py cases/breaking_beam.yaml

Runs ``fem-frac run CASE -q`` in this process (into a temporary folder) with the impulse
solver (``fem_frac.rigid.contact._gauss_seidel``, which returns its sweeps) wrapped.
Reported for the calls with friction: their number, the sweeps' quartiles, the calls that
stop at the cap (``_ITERATIONS``), their share of the point updates (sweeps x points: the
solver's work) and how far they leave the normal velocities of their pushing points from
the targets, and how often the exact solution on the active set (``_polish``) held.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy, as fem_frac/app/cli.py


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("case", type=Path)
    args = p.parse_args()

    import fem_frac.rigid.contact as contact
    from fem_frac.app.cli import main as cli

    calls = []
    inner = contact._gauss_seidel

    def solver(a, b, target, friction, *rest, **kw):
        lam, sweeps, exact = inner(a, b, target, friction, *rest, **kw)
        points = int(np.count_nonzero(np.asarray(friction) > 0.0))
        if points:
            calls.append((sweeps, sweeps * len(target), exact,
                          _normal_error(a, b, target, lam)))
        return lam, sweeps, exact

    contact._gauss_seidel = solver
    with tempfile.TemporaryDirectory() as tmp:
        try:
            cli(["run", str(args.case), "-o", str(Path(tmp) / "out"), "-q"])
        except SystemExit as exit_:
            if exit_.code:
                sys.exit(exit_.code)
    if not calls:
        print(f"{args.case}: no contact solve with friction")
        return
    sweeps, updates, held, error = (np.array(c, dtype=float)
                                    for c in zip(*calls, strict=True))
    capped = sweeps >= contact._ITERATIONS
    q = np.percentile(sweeps, [25, 50, 75])
    print(f"{args.case}: {len(calls)} solves with friction; sweeps a solve: quartiles "
          f"{q[0]:.0f} / {q[1]:.0f} / {q[2]:.0f}, max {sweeps.max():.0f}")
    print(f"at the cap ({contact._ITERATIONS} sweeps): {int(capped.sum())} solves, "
          f"{100 * updates[capped].sum() / updates.sum():.0f} % of the point updates")
    if capped.any():
        e = np.percentile(error[capped], [50, 100])
        print(f"  their normal velocity off its target at a pushing point: median {e[0]:.2g},"
              f" max {e[1]:.2g} (velocity units of the case)")
    print(f"exact solution on the active set held in {int(held.sum())} solves")


def _normal_error(a, b, target, impulses) -> float:
    """The largest ``|v_n - target|`` at the points with a normal impulse (where the
    solved velocities should reach their targets), after the solve."""
    normal = np.asarray(impulses).reshape(-1, 3)[:, 0]
    v = (b + a @ impulses).reshape(-1, 3)[:, 0]
    pushing = normal > 0.0
    return float(np.abs(v - target)[pushing].max(initial=0.0))


if __name__ == "__main__":
    main()
