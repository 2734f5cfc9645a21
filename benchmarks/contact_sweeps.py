"""How many Gauss-Seidel sweeps the contact solver makes in one run of a case.

    python benchmarks/contact_sweeps.py cases/breaking_beam.yaml

Runs ``fem-frac run CASE -q`` in this process (into a temporary folder) with the impulse
solver (``fem_frac.rigid.contact._sequential_impulses``) wrapped. In a call with friction,
each sweep updates the friction of every point with friction once
(``_friction_impulse``), so their count over the number of such points is the call's
sweeps. Reported for those calls: their number, the sweeps' quartiles, the calls that
stop at the cap (``_ITERATIONS``), their share of the friction updates (the solver's
work) and how far they leave the normal velocities of their pushing points from the
targets, and how often the exact solution on the active set (``_polish``) held.
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

    calls, now = [], {}
    inner, friction_update, polish = (contact._sequential_impulses,
                                      contact._friction_impulse, contact._polish)

    def counted_update(*a, **k):
        now["updates"] += 1
        return friction_update(*a, **k)

    def counted_polish(*a, **k):
        out = polish(*a, **k)
        now["held"] += out is not None
        return out

    def solver(a, b, target, friction, *rest, **kw):
        now.update(updates=0, held=0)
        out = inner(a, b, target, friction, *rest, **kw)
        points = int(np.count_nonzero(np.asarray(friction) > 0.0))
        if points:
            calls.append((now["updates"] / points, now["updates"], now["held"],
                          _normal_error(a, b, target, out)))
        return out

    contact._sequential_impulses, contact._friction_impulse, contact._polish = (
        solver, counted_update, counted_polish)
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
          f"{100 * updates[capped].sum() / updates.sum():.0f} % of the friction updates")
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
