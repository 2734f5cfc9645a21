"""Dynamics figures for docs/dynamics.md: energy behaviour of each integrator, the stable
step of central difference (Lanczos against the element bound) and the cost per step.

    python benchmarks/dynamics.py

A clamped steel beam 1 x 0.1 x 0.1 m (P1, element size 0.05) is set swinging by a uniform
initial velocity of 1 m/s; the plastic run uses 20 m/s and sigma_Y = 300 MPa.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent.parent / "tests"))
from fem_frac.app.driver import prepare  # noqa: E402
from fem_frac.config.schema import Case  # noqa: E402
from fem_frac.timing import StageTimer  # noqa: E402
from solve import run  # noqa: E402


def beam(analysis: dict, plastic: bool = False, element_size: float = 0.05) -> dict:
    case = {
        "mesh": {"geometry": {"type": "box", "lengths": [1.0, 0.1, 0.1]},
                 "element_size": element_size},
        "material": {"youngs_modulus": 200e9, "poissons_ratio": 0.3, "density": 7800.0},
        "boundary_conditions": [{"type": "fixed", "boundary": "xmin"}],
        "analysis": {"type": "dynamic",
                     "initial_velocity": {"uniform": [0, 0, 20.0 if plastic else 1.0]},
                     **analysis},
    }
    if plastic:
        case["plasticity"] = {"yield_stress": 300e6, "hardening": 2e9}
    return case


def history(case: dict):
    rows = []
    t0 = time.perf_counter()
    setup, state, ledger, counters = run(
        case, observe=lambda n, s, led, i: rows.append(
            (led.kinetic + led.elastic, led.relative_error)))
    wall = time.perf_counter() - t0
    return np.array(rows), counters, wall, setup


def limit_of(element_size: float):
    case = Case.model_validate(beam({"integrator": "central_difference", "dt": 1e-12,
                                     "steps": 1}, element_size=element_size))
    return prepare(case, Path("."), StageTimer()).disc.limit


def main() -> None:
    print("integrator                         steps   dt        max |dE|/E0   energy_error_rel  "
          "iterations  wall s")
    lim = limit_of(0.05)
    runs = [
        ("newmark (average acceleration)", {"integrator": "newmark", "dt": 1e-5,
                                             "steps": 1000}, False),
        ("hht alpha = -0.05", {"integrator": "hht", "alpha": -0.05, "dt": 1e-5,
                               "steps": 1000}, False),
        ("hht alpha = -0.3", {"integrator": "hht", "alpha": -0.3, "dt": 1e-5,
                              "steps": 1000}, False),
        ("central difference, 0.9 dt_crit", {"integrator": "central_difference",
                                             "dt": 0.9 * lim.dt, "steps": 10_000}, False),
        ("newmark, plastic (20 m/s)", {"integrator": "newmark", "dt": 1e-5, "steps": 200},
         True),
        ("central difference, plastic", {"integrator": "central_difference",
                                         "dt": 0.9 * lim.dt, "steps": 2000}, True),
    ]
    for name, analysis, plastic in runs:
        rows, counters, wall, setup = history(beam(analysis, plastic))
        total = rows[:, 0]
        drift = np.max(np.abs(total - total[0])) / total[0]
        print(f"{name:<34} {analysis['steps']:>6}  {analysis['dt']:.2e}  {drift:11.2e}   "
              f"{rows[:, 1].max():14.2e}  {counters.iterations:>10}  {wall:6.2f}")
    print()
    print("element size  dofs    stable step (Lanczos)  element bound   bound / Lanczos")
    for h in (0.05, 0.025):
        lim = limit_of(h)
        case = Case.model_validate(beam({"integrator": "central_difference", "dt": 1e-12,
                                         "steps": 1}, element_size=h))
        n = prepare(case, Path("."), StageTimer()).disc.space.n_dofs
        print(f"{h:<12}  {n:<6}  {lim.dt:.4e} s          {lim.element_bound_dt:.4e} s    "
              f"{lim.element_bound_dt / lim.dt:.2f}")


if __name__ == "__main__":
    main()
