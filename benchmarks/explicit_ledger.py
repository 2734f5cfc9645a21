"""The energy ledger of central difference driven by a traction and by a prescribed
displacement, for docs/dynamics.md (Energy):

    python benchmarks/explicit_ledger.py

The bar of tests/test_explicit_ledger.py (1 x 0.1 x 0.1 m steel, nu = 0, P1, element size
0.05, fixed at x = 0): pulled at x = 1 by a traction ramp, and moved along the mean end
displacement that run computed (the equivalent prescribed displacement); then pulled at
constant speed by a plain displacement ramp. About 10 s on 2 cores.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent.parent / "tests"))
from test_explicit_ledger import (  # noqa: E402
    RAMP,
    STABLE,
    STRAIN,
    bar,
    equivalent_runs,
    largest_error,
    steps,
)


def relative(rows: np.ndarray) -> np.ndarray:
    """The ledger's energy_error_relative at every step."""
    return np.abs(rows[:, 1]) / np.where(rows[:, 2] > 0, rows[:, 2], 1.0)


def main() -> None:
    print("| dt / stable step | traction | equivalent displacement | ratio |")
    print("|---|---|---|---|")
    starts = {}
    for factor in (0.9, 0.45, 0.225):
        traction, prescribed = equivalent_runs(factor * STABLE)
        t, u = largest_error(traction), largest_error(prescribed)
        print(f"| {factor} | {t:.2e} | {u:.2e} | {u / t:.3f} |")
        if factor == 0.9:
            starts = {"traction ramp": relative(traction),
                      "equivalent displacement": relative(prescribed)}
    print("\n| dt / stable step | displacement ramp | error ratio to the next |")
    print("|---|---|---|")
    errors = []
    for factor in (0.9, 0.45, 0.225, 0.1125):
        _, rows = steps(bar({"type": "displacement", "x": STRAIN}, factor * STABLE, RAMP))
        errors.append(largest_error(rows))
        if factor == 0.9:
            starts["displacement at constant speed"] = relative(rows)
    for k, (factor, e) in enumerate(zip((0.9, 0.45, 0.225, 0.1125), errors, strict=True)):
        ratio = f"{e / errors[k + 1]:.2f}" if k + 1 < len(errors) else ""
        print(f"| {factor} | {e:.2e} | {ratio} |")
    marks = (1, 2, 5, 10, 50, 100)
    print("\nenergy_error_relative at 0.9 of the stable step, steps " + ", ".join(map(str, marks))
          + ", largest from step 100 on:")
    for name, rel in starts.items():
        print(f"| {name} | " + " | ".join(f"{rel[n]:.1e}" for n in marks)
              + f" | {rel[100:].max():.1e} |")


if __name__ == "__main__":
    main()
