"""The contact impulse solver on the problems of one run of a case: saved once, then timed.

    python benchmarks/contact_solves.py capture cases/breaking_beam.yaml FILE
    python benchmarks/contact_solves.py time FILE [--repeats 3]

``capture`` runs ``fem-frac run CASE -q`` in this process (into a temporary folder) with the
impulse solver (``fem_frac.rigid.contact._gauss_seidel``, or ``_sequential_impulses`` in
older checkouts, whose sweeps are then not known) wrapped, and saves every problem
it was given (Delassus matrix, velocities, targets, friction, its options) with the
impulses it returned, as a pickle (a file of this benchmark's own making: load only yours).
``time`` solves every saved problem again with this checkout's solver, in the order of the
run, ``--repeats`` times, and prints the total CPU time (min and spread over the repeats), its
share in the problems that stopped at the cap (``_ITERATIONS`` sweeps) and, against the saved
impulses, the largest change of the contact velocities ``A (lam' - lam)`` over the problem's
scale (``max |b|``). Capture with one checkout and time with two (``git worktree add``;
``PYTHONPATH=<worktree> python <worktree>/benchmarks/contact_solves.py time FILE``): the same
problems, so the same work, before and after a change of the solver.
"""

from __future__ import annotations

import argparse
import os
import pickle
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy, as fem_frac/app/cli.py


def capture(case: Path, file: Path) -> None:
    import fem_frac.rigid.contact as contact
    from fem_frac.app.cli import main as cli

    problems = []
    # checkouts before _gauss_seidel (09d7840 and older) have _sequential_impulses alone,
    # which does not report its sweeps
    name = "_gauss_seidel" if hasattr(contact, "_gauss_seidel") else "_sequential_impulses"
    inner = getattr(contact, name)

    def solver(a, b, target, friction, iterations=contact._ITERATIONS, polish=False,
               scale=None):
        out = inner(a, b, target, friction, iterations, polish, scale)
        lam, sweeps = (out[0], out[1]) if name == "_gauss_seidel" else (out, -1)
        problems.append(dict(a=np.array(a), b=np.array(b), target=np.array(target),
                             friction=np.array(friction), iterations=iterations,
                             polish=polish, scale=scale, lam=lam.copy(), sweeps=sweeps))
        return out

    setattr(contact, name, solver)
    with tempfile.TemporaryDirectory() as tmp:
        try:
            cli(["run", str(case), "-o", str(Path(tmp) / "out"), "-q"])
        except SystemExit as exit_:
            if exit_.code:
                sys.exit(exit_.code)
    with open(file, "wb") as f:
        pickle.dump(problems, f)
    capped = sum(p["sweeps"] >= p["iterations"] for p in problems)
    print(f"{case}: {len(problems)} problems ({capped} at the cap; -1 sweeps: not "
          f"reported) saved to {file}")


def solve_all(problems) -> tuple[list, np.ndarray]:
    """Every problem solved in turn: the impulses and each one's CPU seconds (through
    ``_sequential_impulses``, which checkouts before ``_gauss_seidel`` have too)."""
    from fem_frac.rigid.contact import _sequential_impulses

    out, seconds = [], np.zeros(len(problems))
    for k, p in enumerate(problems):
        start = time.process_time()
        lam = _sequential_impulses(p["a"], p["b"], p["target"], p["friction"],
                                   p["iterations"], p["polish"], p["scale"])
        seconds[k] = time.process_time() - start
        out.append(lam)
    return out, seconds


def time_solves(file: Path, repeats: int) -> None:
    with open(file, "rb") as f:
        problems = pickle.load(f)
    capped = np.array([p["sweeps"] >= p["iterations"] for p in problems])
    totals, lam, seconds = [], None, None
    for _ in range(repeats):
        lam, seconds = solve_all(problems)
        totals.append(seconds.sum())
    change = max((np.abs(p["a"] @ (x - p["lam"])).max(initial=0.0)
                  / (np.abs(p["b"]).max(initial=0.0) + 1e-300)
                  for p, x in zip(problems, lam, strict=True)), default=0.0)
    same = sum(np.array_equal(p["lam"], x) for p, x in zip(problems, lam, strict=True))
    print(f"{file}: {len(problems)} problems, CPU s min {min(totals):.2f} "
          f"(spread {max(totals) - min(totals):.2f}, {repeats} repeats); "
          f"{100 * seconds[capped].sum() / max(seconds.sum(), 1e-300):.0f} % in the "
          f"{int(capped.sum())} capped at capture")
    print(f"against the saved impulses: {same} the same bits; largest change of the "
          f"contact velocities {change:.2g} of max |b|")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    c = sub.add_parser("capture")
    c.add_argument("case", type=Path)
    c.add_argument("file", type=Path)
    t = sub.add_parser("time")
    t.add_argument("file", type=Path)
    t.add_argument("--repeats", type=int, default=3)
    args = p.parse_args()
    if args.command == "capture":
        capture(args.case, args.file)
    else:
        time_solves(args.file, args.repeats)


if __name__ == "__main__":
    main()
