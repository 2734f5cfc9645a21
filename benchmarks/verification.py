"""Error against theory, and wall time, for the elastic verification cases.

    python benchmarks/verification.py            # tables recorded in docs/verification.md

Cantilever: tip deflection against Timoshenko beam theory. Hollow sphere: relative L2 error
of the displacement against Lamé's solution, with the slope fitted over the meshes.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent.parent / "tests"))

from test_verification import (  # noqa: E402
    NU,
    B,
    E,
    H,
    L,
    P,
    lame_error,
    tip_deflection,
)

from fem_frac.verify.exact import cantilever_tip_deflection  # noqa: E402


def timed(fn, *args):
    t = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - t


def main() -> None:
    exact = cantilever_tip_deflection(P, L, B, H, E, NU)
    print(f"Cantilever tip deflection, Timoshenko: {exact * 1e3:.5f} mm\n")
    print("| order | element size | deflection (mm) | error vs beam theory | wall s |")
    print("|---|---|---|---|---|")
    for order in (1, 2):
        for size in (H / 2, H / 4, H / 8):
            d, t = timed(tip_deflection, order, size)
            print(f"| P{order} | {size:g} | {d * 1e3:.5f} | {(d - exact) / exact:+.2%} | {t:.2f} |")
    print("\nHollow sphere (octant), relative L2 displacement error against Lamé\n")
    print("| order | element size | mean h | L2 error | wall s |")
    print("|---|---|---|---|---|")
    for order in (1, 2):
        rows = []
        for size in (0.025, 0.018, 0.0125, 0.009):
            (err, h), t = timed(lame_error, order, size)
            rows.append((err, h))
            print(f"| P{order} | {size:g} | {h:.4f} | {err:.3e} | {t:.2f} |")
        errs, hs = np.array(rows).T
        slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
        print(f"| P{order} | fitted slope | | {slope:.2f} | |")


if __name__ == "__main__":
    main()
