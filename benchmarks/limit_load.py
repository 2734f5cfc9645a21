"""The limit-load rule of the equilibrium iteration (docs/solvers.md, "Near a limit load"),
with and without it.

    python benchmarks/limit_load.py            # Hill's sphere near and past its limit (~15 s)
    python benchmarks/limit_load.py --cases    # and the shipped cases where it fires (~2 min)

For each run: whether it completed, the equilibrium iterations it tried (every attempt,
cut-backs included, counted at each convergence test), those of the steps it completed, the
factorizations, the wall time, and how often the rule switched to full Newton. "off" runs the
same case with the rule's window set past any cap (it never fires). The Hill cases are those
of tests/test_cutback.py: the octant of a = 1, b = 2, P2 at element size 0.5 (1,833 dofs),
the pressure ramped over 5 steps to a fraction of the exact limit 2 sigma_Y ln(b/a); this
mesh carries 1.006 p_L and not 1.008 p_L.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from test_cutback import sphere  # noqa: E402

import fem_frac.solve.convergence as convergence  # noqa: E402
from fem_frac.app.driver import prepare, simulate  # noqa: E402
from fem_frac.config import load_case  # noqa: E402
from fem_frac.errors import SolverError  # noqa: E402
from fem_frac.solve.stepping import ImplicitStepper  # noqa: E402
from fem_frac.timing import StageTimer  # noqa: E402
from solve import simulate_dict  # noqa: E402

WINDOW = convergence.RATE_WINDOW
CASES = ("ductile_plate.yaml", "dcb.yaml")


class Counts:
    """Every convergence test (one per iteration, of every attempt) and every switch."""

    def __init__(self):
        self.iterations = self.switches = 0
        converged, near = ImplicitStepper._converged, ImplicitStepper._near_limit

        def count(stepper, *args):
            self.iterations += 1
            return converged(stepper, *args)

        def switch(stepper, *args):
            out = near(stepper, *args)
            self.switches += int(out)
            return out

        ImplicitStepper._converged, ImplicitStepper._near_limit = count, switch

    def reset(self) -> None:
        self.iterations = self.switches = 0


def measure(counts: Counts, label: str, run) -> str:
    counts.reset()
    t0 = time.perf_counter()
    try:
        tally, extra = run()
        done = (f"yes | {tally.iterations} | {tally.factorizations}", extra)
    except SolverError as exc:
        done = (" no |  |  ", str(exc).split(": ", 1)[-1][:90])
    wall = time.perf_counter() - t0
    return (f"| {label} | {done[0]} | {counts.iterations} | {counts.switches} | {wall:.1f} | "
            f"{done[1]} |")


def hill(fraction: float):
    def run():
        _, world, tally = simulate_dict(sphere(fraction))
        return tally, f"max residual {tally.max_residual:.1e}"
    return run


def shipped(name: str):
    def run():
        path = ROOT / "cases" / name
        case, _ = load_case(path)
        setup = prepare(case, path.parent, StageTimer())
        world, tally = simulate(setup, StageTimer())
        return tally, (f"{tally.body.crack.faces} crack faces, strain energy "
                       f"{world.ledger.elastic:.6g}")
    return run


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cases", action="store_true", help="also the shipped cases (~2 min)")
    args = p.parse_args()
    counts = Counts()
    runs = [(f"Hill sphere, {f} p_L", hill(f)) for f in (0.998, 1.006, 1.02)]
    if args.cases:
        runs += [(f"cases/{name}", shipped(name)) for name in CASES]
    print("| run | rule | completed | iterations (steps completed) | factorizations | "
          "iterations tried | switches | wall s | note |")
    print("|---|---|---|---|---|---|---|---|---|")
    for label, run in runs:
        for rule, window in (("on", WINDOW), ("off", 10**9)):
            convergence.RATE_WINDOW = window
            row = measure(counts, label, run)
            print(row.replace(f"| {label} |", f"| {label} | {rule} |", 1), flush=True)
    convergence.RATE_WINDOW = WINDOW


if __name__ == "__main__":
    main()
