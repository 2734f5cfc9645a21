"""Figures of docs/dynamics.md, *Initial displacement*: a steel cantilever 1 x 0.1 x 0.05 m
(P2, element size 0.05) released from rest, deflected by a static tip load (preload), by
the Euler-Bernoulli first mode shape (field) and, as a control, from the static deflection
with the initial acceleration left at zero.

    python benchmarks/initial_displacement.py

The cases and the modal projection are those of tests/test_initial_displacement.py.
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent.parent / "tests"))
import test_initial_displacement as t  # noqa: E402

from fem_frac.app.initial import first_state  # noqa: E402

BETA = 1.8751040687  # beta L of the first mode
SIGMA = (np.cosh(BETA) + np.cos(BETA)) / (np.sinh(BETA) + np.sin(BETA))
FIELD = {"field": {"constants": {"b": BETA, "s": SIGMA, "a": 5e-4},
                   "z": "a * (cosh(b * x) - cos(b * x) - s * (sinh(b * x) - sin(b * x)))"}}


def report(name: str, start: dict) -> None:
    began = time.perf_counter()
    setup, u, v = t.history(t.cantilever(start))
    wall = time.perf_counter() - began
    modes = t.Modes(setup.disc)
    a = modes.amplitudes(u, v)
    content = a[:, 1] * abs(modes.tip[1]) / (a[:, 0] * abs(modes.tip[0]))
    drift = np.abs(a - a[0]).max(axis=0) / a[0, 0]
    print(f"| {name} | {setup.disc.space.n_dofs:,} | {content[0]:.4f} | {content.max():.4f} "
          f"| {drift[0]:.1e} | {drift[1]:.1e} | {wall:.1f} |")
    if name == "preload":
        print(f"omega_1 {modes.omega[0]:.2f}, omega_2 {modes.omega[1]:.2f} rad/s, ratio "
              f"{modes.omega[1] / modes.omega[0]:.3f} (Euler-Bernoulli 6.267); "
              f"(omega_1 / omega_2)^2 = {(modes.omega[0] / modes.omega[1]) ** 2:.4f}, "
              f"Euler-Bernoulli content {t.EULER_BERNOULLI_CONTENT:.4f}")
        state = first_state(setup.case, setup.disc, setup.case_dir)
        first, _ = setup.disc.stepper.step(replace(state, a=np.zeros_like(state.a)), t.DT, 1)
        b = modes.amplitudes(first.u, first.v)
        moved = abs(b[1] - a[0, 1]) / a[0, 0]
        print(f"control, a0 = 0: second-mode amplitude moved by {moved:.1e} of the first "
              "mode's in the first step")


if __name__ == "__main__":
    print(f"{t.STEPS} Newmark steps of {t.DT:g} s (about one first-mode period)")
    print("| start | dofs | 2nd-mode content at the tip, t = 0 | max over the run "
          "| drift of A_1 / A_1 | drift of A_2 / A_1 | wall s |")
    print("|---|---|---|---|---|---|---|")
    report("preload", {"preload": {"boundary_conditions": [t.TIP_FORCE]}})
    report("field", FIELD)
