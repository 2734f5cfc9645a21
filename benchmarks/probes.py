"""What probes cost a step (docs/output.md): ten probes against one equilibrium step.

Scene: a plastic beam 1 x 0.2 x 0.2 (E = 200 GPa, nu = 0.3, sigma_Y = 250 MPa, H = 10 GPa),
fixed at xmin, its end xmax moved down by 1e-2 (past yield at the root), P1 on a gmsh mesh of
element size ``--size`` (0.02: about 60,000 tets). Ten probes: eight points along the top
edge and two boundaries (xmin, xmax), each recording displacement, stress, von_mises and
equivalent_plastic_strain; ``--nodal`` adds equivalent_plastic_strain_nodal (a projection
over the whole mesh every step).

Timed, best of ``--repeat`` (wall, process):

- locate: the stencils of all probes on the mesh (once per mesh: at the start and after
  every crack or piece leaving);
- row: the values of one step (``ProbeRecorder.values``) on the state after one load step;
- step: that load step itself (``ImplicitStepper.step``, modified Newton, from t = 0).

    python benchmarks/probes.py [--size 0.02] [--nodal] [--repeat 5]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from fem_frac.app.driver import prepare, start
from fem_frac.app.probes import Places, ProbeRecorder, columns
from fem_frac.config.schema import Case
from fem_frac.timing import StageTimer


def case(size: float, nodal: bool) -> dict:
    fields = ["displacement", "stress", "von_mises", "equivalent_plastic_strain"]
    fields += ["equivalent_plastic_strain_nodal"] if nodal else []
    points = [{"name": f"p{k}", "point": [x, 0.1, 0.2], "fields": fields}
              for k, x in enumerate(np.linspace(0.05, 0.95, 8))]
    ends = [{"name": b, "boundary": b, "fields": fields} for b in ("xmin", "xmax")]
    return {
        "mesh": {"geometry": {"type": "box", "lengths": [1.0, 0.2, 0.2]},
                 "element_size": size, "order": 1},
        "material": {"youngs_modulus": 200e9, "poissons_ratio": 0.3},
        "plasticity": {"yield_stress": 250e6, "hardening": 1e10},
        "boundary_conditions": [{"type": "fixed", "boundary": "xmin"},
                                {"type": "displacement", "boundary": "xmax", "z": -1e-2}],
        "analysis": {"type": "quasi_static", "steps": 1},
        "probes": points + ends,
    }


class NoFile:
    """The recorder's file, without writing (only the values are timed)."""

    def __init__(self, probes):
        self.columns = columns(probes)


def best(f, repeat: int) -> tuple[float, float, object]:
    walls, cpus, out = [], [], None
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        out = f()
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    return min(walls), min(cpus), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=0.02)
    ap.add_argument("--nodal", action="store_true")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    c = Case.model_validate(case(args.size, args.nodal))
    timer = StageTimer()
    setup = prepare(c, Path("."), timer)
    world, _ = start(setup, timer)
    disc = setup.disc
    step = best(lambda: disc.stepper.step(world.body.state, 1.0, 1)[0], args.repeat)
    state = step[2]
    from dataclasses import replace

    stepped = replace(world, t=1.0, body=world.body.with_state(state))
    recorder = ProbeRecorder(c.probes, NoFile(c.probes))
    locate = best(lambda: [places.stencil(p) for places in [Places(disc)]
                           for p in c.probes], args.repeat)
    recorder.values(stepped)  # located once
    row = best(lambda: recorder.values(stepped), args.repeat)
    print(f"mesh {disc.mesh.n_tets:,} tets, {disc.space.n_dofs:,} dofs; 10 probes, "
          f"{len(columns(c.probes)) - 2} columns" + (" (with a nodal field)" if args.nodal
                                                     else ""))
    for what, (wall, cpu, _) in (("locate", locate), ("row", row), ("step", step)):
        print(f"{what:<7} wall {wall * 1e3:9.3f} ms   cpu {cpu * 1e3:9.3f} ms")


if __name__ == "__main__":
    main()
