"""One crack-insertion batch against one plain step and its floor (DESIGN §3, §7).

The floor of a step is one back-solve with the cached elastic factorization plus one pass over
the quadrature points (strain ``B u``, ``law.update``, internal force ``B^T sigma dx``), each
timed alone. On the same state this times a plain elastic step (``ImplicitStepper.step``)
and each piece of one batch of the fracture stage, in the order ``FractureStage._insert``
runs them: selection (``stage.sites``, the smoothed principal stress computed afresh),
``stage.open`` (``cut_tets`` and ``rebuilt``, as ``open_crack``; the debris check, which
also labels the new mesh's pieces), rebuild (``world.transfer.rediscretize``: space, loads,
operators, constrained dofs and stepper), caches (``stage._updated``: ``update_operator``
and the other per-mesh caches of ``_topology``), carry (``world.transfer.carry``), the new
body (``body_of``: crack measures), support check (``stage.loose``), refactorization (the
new stepper's first ``elastic_factor()``: through the old factorization where
fem_frac.solve.bordered keeps it, with a fresh factorization timed beside it), the re-solve
step, and the field the stage publishes for the re-solved state (``stage._published`` on
the new mesh: with one pass no site is chosen on that state, so its largest values
alone). Each piece: best of ``--repeats``, each call from cold caches (a 64 MiB buffer
written first, as in plastic_step.py); selection also right after a batch (as in a run); the
whole batch end to end through ``stage(step, world)``, cold (the first batch of the process,
after steps 0 and 1 of the run) and warm (best of the repeats); and a second batch, warm:
step 3's, on the mesh the first one cracked, whose operators and factorization come through
the first batch's (the reconnection's kept diagonal, the bordered factor's chain), as most
of a run's batches follow another.

Scene: the brittle bar of tests/test_fracture.py (E = 30 GPa, nu = 0.2, strength 3 MPa),
0.1 x 0.02 x 0.02, symmetry on xmin/ymin/zmin, displacement on xmax, quasi-static, 3 steps
to 1.53 x strength (1.02 x at step 2); the stress is uniform, so every element is over
strength (the selection's worst case). gmsh, element size h for ~N tets; smoothing length
1.5 h (tied to the mesh: ~55 tets per neighbourhood at every size); batch_size 8, one pass,
xmin and xmax protected. The batch follows step 2, carrying the committed state of step 1.
One subprocess per size.

    python benchmarks/fracture.py                       # 10k and 100k tets, best of 3
    python benchmarks/fracture.py --sizes 10000 --repeats 5
    python benchmarks/fracture.py --sizes 100000 --profile 40   # and where the second goes

``--profile N``: after the table, for each size, the ``N`` functions of largest cumulative
time of one more warm call of the second batch under ``cProfile`` (which slows Python-level
code, so read its shares, not its seconds).

The measured table and its reading are in docs/performance.md ("One crack-insertion batch
against a plain step"); ``tests/test_benchmark_fracture.py`` runs this script on a small bar
so that it keeps up with the code it times.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

# numpy's OpenBLAS as the fem-frac command runs it (one thread unless the environment says
# otherwise: fem_frac/app/cli.py), set before numpy loads it
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

LENGTHS = (0.1, 0.02, 0.02)
TETS_PER_H3 = 4.5  # gmsh box: n_tets ~ TETS_PER_H3 * volume / h^3
E, NU, STRENGTH = 30e9, 0.2, 3e6
OVER = 1.02  # load at step 2 / strength (the load rises linearly over 3 steps)
FLUSH = np.zeros(0)


def case_dict(n_tets: int) -> dict:
    h = (TETS_PER_H3 * np.prod(LENGTHS) / n_tets) ** (1 / 3)
    return {
        "mesh": {"geometry": {"type": "box", "lengths": list(LENGTHS)}, "element_size": h},
        "material": {"youngs_modulus": E, "poissons_ratio": NU, "density": 2400},
        "boundary_conditions": [
            {"type": "symmetry", "boundary": "xmin"},
            {"type": "symmetry", "boundary": "ymin"},
            {"type": "symmetry", "boundary": "zmin"},
            {"type": "displacement", "boundary": "xmax",
             "x": 1.5 * OVER * STRENGTH * LENGTHS[0] / E},
        ],
        "fracture": {"tensile_strength": STRENGTH, "smoothing": {"length": 1.5 * h},
                     "batch_size": 8, "passes": 1, "max_insertions_per_step": 8,
                     "protect": [{"boundary": "xmin"}, {"boundary": "xmax"}]},
        "analysis": {"type": "quasi_static", "steps": 3},
    }


def best(fn, repeats: int):
    """``(best wall seconds, last result)`` of ``repeats`` calls, each from cold caches."""
    global FLUSH
    if FLUSH.size == 0:
        FLUSH = np.zeros(64 * 2**20 // 8)
    times, out = [], None
    for _ in range(repeats):
        FLUSH += 1.0
        gc.collect()
        gc.disable()
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
        gc.enable()
    return min(times), out


def one(n_tets: int, repeats: int, profile: int = 0) -> dict:
    from dataclasses import replace

    from fem_frac.app.driver import prepare, start, times
    from fem_frac.config.schema import Case
    from fem_frac.fracture.smoothing import principal_stress, smooth, update_operator
    from fem_frac.fracture.stage import FractureStage, smoothing_of
    from fem_frac.fracture.topology import open_crack
    from fem_frac.timing import StageTimer
    from fem_frac.world.equilibrium import EquilibriumStage
    from fem_frac.world.stage import Step
    from fem_frac.world.state import body_of
    from fem_frac.world.transfer import carry, rediscretize
    from fem_frac.writers.fields import cell_average

    timer = StageTimer()
    setup = prepare(Case.model_validate(case_dict(n_tets)), Path("."), timer)
    disc = setup.disc
    law, ops, st = disc.law, disc.ops, disc.stepper
    mesh, free, space = disc.mesh, disc.constrained.free, disc.space
    r: dict = {"tets": mesh.n_tets, "dofs": space.n_dofs}
    world, _ = start(setup, timer)  # factorizes the elastic Jacobian
    factor = st.elastic_factor()
    t = times(setup.grid)
    bt = StageTimer()
    stage = FractureStage(setup.case.fracture, setup.dynamic, bt)
    equilibrium = EquilibriumStage()
    # steps 0 and 1 as in a run (nothing opens at half the strength), then step 2's
    # equilibrium: the batch follows it
    world, _ = stage(Step(0, float(t[0]), world), world)
    step = Step(1, float(t[1]), world)
    world1, info = equilibrium(step, world)
    world1, _ = stage(replace(step, events=(info,)), world1)
    step = Step(2, float(t[2]), world1)
    world2, info = equilibrium(step, world1)
    step2 = replace(step, events=(info,))
    s1, s2, body = world1.body.state, world2.body.state, world2.body
    topo0 = stage._topo  # the caches of the uncracked mesh

    def fresh():
        """The stage's caches as before the batch (nothing refused, no principal stress
        kept), made current."""
        stage._topo = replace(topo0, refused=np.zeros_like(topo0.refused), principal=None,
                              smoothed=None)
        return stage._topo

    def whole():
        fresh()
        return stage(step2, world2)

    r["batch cold"], (_, event) = best(whole, 1)
    assert len(event.batches) == 1, "the batch opened nothing"
    r["smoothing operator"], _ = best(lambda: smoothing_of(stage.config, mesh), repeats)
    r["nnz/row"] = topo0.smoothing.nnz / mesh.n_tets

    # floor and plain step on the uncracked mesh
    rhs = np.random.default_rng(0).standard_normal(len(free))
    op = ops.strain_operator
    r["back-solve"], _ = best(lambda: factor.solve(rhs), repeats)
    r["strain"], strain = best(lambda: op.strain(s2.u), repeats)
    r["law.update"], _ = best(lambda: law.update(strain, s1.plastic), repeats)
    r["internal force"], _ = best(lambda: op.internal_force(s2.stress), repeats)
    r["floor"] = r["back-solve"] + r["strain"] + r["law.update"] + r["internal force"]
    r["step"], (_, step_info) = best(lambda: st.step(s1, float(t[2]), 2), repeats)

    # the batch, piece by piece, in the order of FractureStage._insert
    topo = fresh()

    def select():
        topo.principal = topo.smoothed = None  # computed, as for a new state
        return stage.sites(body, topo, 2, 0, 8)

    p = {}
    p["selection"], sites = best(select, repeats)
    p["  cell average"], mean = best(lambda: cell_average(space, s2.stress), repeats)
    p["  smoothing S @ sigma"], smoothed = best(lambda: smooth(topo.smoothing, mean), repeats)
    p["  eigen-decomposition"], _ = best(lambda: principal_stress(smoothed), repeats)
    p["  site choice"] = p["selection"] - sum(p[k] for k in list(p)[1:])
    p["open (stage.open)"], (sites, new_mesh, transfer, _, pieces) = best(
        lambda: stage.open(topo, body.n_pieces, sites), repeats)
    p["  open_crack"], _ = best(lambda: open_crack(mesh, sites.vertices, sites.normals),
                                repeats)
    p["  debris check"] = p["open (stage.open)"] - p["  open_crack"]
    r["sites"], r["new vertices"] = len(sites), new_mesh.n_points - mesh.n_points
    builds = []

    def rebuild():
        bt.seconds.clear()
        with bt("fracture rebuild"):
            out = rediscretize(disc, new_mesh, bt, "after crack insertion", transfer)
        builds.append(dict(bt.seconds))
        return out

    p["rebuild (rediscretize)"], new_disc = best(rebuild, repeats)
    parts = min(builds, key=lambda b: b["fracture rebuild"])
    for key, label in (("space", "space"), ("loads", "loads"), ("assemble", "operators")):
        p[f"  {label}"] = parts[key]
    p["  constrained, stepper"] = parts["fracture rebuild"] - sum(
        parts[k] for k in ("space", "loads", "assemble"))
    split = mesh.points[sites.vertices]
    sm = stage.config.smoothing
    p["caches (stage._updated)"], new_topo = best(
        lambda: stage._updated(topo, new_mesh, split), repeats)
    p["  update_operator"], _ = best(lambda: update_operator(
        topo.smoothing, new_mesh.points, new_mesh.tets, split, length=sm.length,
        rings=sm.rings, method=sm.method), repeats)
    p["  other caches"] = p["caches (stage._updated)"] - p["  update_operator"]
    p["carry (transfer.carry)"], carried = best(
        lambda: carry(s1, disc, new_disc, transfer, stage.inertia), repeats)
    p["body (body_of)"], new_body = best(
        lambda: body_of(new_disc, carried, pieces=pieces), repeats)
    p["support check"], _ = best(lambda: stage.loose(new_body, 2), repeats)

    seed = new_disc.stepper.seed  # the old factorization, to solve through (bordered)

    def refactor(through_old: bool):
        new_disc.stepper.factor = None
        new_disc.stepper.seed = seed if through_old else None
        return new_disc.stepper.elastic_factor()

    p["refactorization"], made = best(lambda: refactor(True), repeats)
    p["  fresh factorization"], _ = best(lambda: refactor(False), repeats)
    r["factorization"] = made.method
    new_disc.stepper.factor = made
    p["re-solve step"], (resolved, resolve_info) = best(
        lambda: new_disc.stepper.step(carried, float(t[2]), 2), repeats)
    end = new_body.with_state(resolved)

    def field():
        new_topo.principal = new_topo.smoothed = None
        return stage._published(end, new_topo)

    p["field (stage._published)"], _ = best(field, repeats)
    r["iterations"] = f"{step_info.iterations} / {resolve_info.iterations}"
    r["batch (sum of pieces)"] = sum(v for k, v in p.items() if not k.startswith(" "))
    r["batch warm"], _ = best(whole, repeats)

    def sites_after_batch():
        whole()
        topo = fresh()
        t0 = time.perf_counter()
        stage.sites(body, topo, 2, 0, 8)
        return time.perf_counter() - t0

    r["selection, right after a batch"] = min(sites_after_batch() for _ in range(repeats))

    # a batch that follows another (step 3's, on the mesh step 2's batch cracked), as most
    # of a run's batches do: its operators and factorization come through the first
    # batch's (the reconnection's kept diagonal, the bordered factor's chain)
    after, _ = whole()
    step3 = Step(3, float(t[3]), after)
    world3, info3 = equilibrium(step3, after)
    step3 = replace(step3, events=(info3,))
    topo1 = stage._topo
    # the first batch's bordered factor: in a run the one batch made from it appends its
    # columns after its own; each repeat here starts there again (else it copies them)
    prior = world3.body.disc.stepper.factor
    live = prior.columns.live if hasattr(prior, "columns") else None

    def second():
        stage._topo = replace(topo1, refused=np.zeros_like(topo1.refused), principal=None,
                              smoothed=None)
        if live is not None:
            prior.columns.live = live
        return stage(step3, world3)

    r["second batch warm"], (_, event) = best(second, repeats)
    assert len(event.batches) == 1, "the second batch opened nothing"
    if profile:
        r["profile"] = _profiled(second, profile)
    r["pieces"] = p
    r["peak_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return r


def _profiled(fn, top: int) -> str:
    """The ``top`` functions of largest cumulative time of one call of ``fn``."""
    import cProfile
    import io
    import pstats

    profiler = cProfile.Profile()
    profiler.runcall(fn)
    text = io.StringIO()
    pstats.Stats(profiler, stream=text).sort_stats("cumulative").print_stats(top)
    return text.getvalue()


def _t(x: float) -> str:
    return f"{1e3 * x:.1f} ms" if x < 1 else f"{x:.2f} s"


def table(rows: list[dict]) -> str:
    """One column per size; times with their ratios to the floor and to a plain step."""
    def cells(f) -> str:
        return " | ".join(f(r) for r in rows) + " |"

    def times(key: str, digits: int = 1):
        return lambda r: (f"{_t(r[key])}, {r[key] / r['floor']:.{digits}f}, "
                          f"{r[key] / r['step']:.{digits}f}")

    out = ["| (time, /floor, /step) | " + cells(lambda r: f"{r['tets']:,} tets"),
           "|" + "---|" * (len(rows) + 1),
           "| dofs, smoothing nnz/row | " + cells(lambda r: f"{r['dofs']:,}, {r['nnz/row']:.0f}"),
           "| sites / new vertices | " + cells(lambda r: f"{r['sites']} / {r['new vertices']}"),
           "| iterations: step / re-solve | " + cells(lambda r: r["iterations"]),
           "| factorization after the batch | " + cells(lambda r: r["factorization"]),
           "| peak MiB | " + cells(lambda r: f"{r['peak_mib']:,.0f}"),
           "| initial smoothing operator | " + cells(times("smoothing operator", 0))]
    for k in ("floor", "back-solve", "strain", "law.update", "internal force", "step"):
        name = "**floor**" if k == "floor" else ("**plain step**" if k == "step" else
                                                 f"- {k}")
        out.append(f"| {name} | " + cells(times(k, 2)))
    for k in rows[0]["pieces"]:
        name = k.replace("  ", "- ") if k.startswith(" ") else f"**{k}**"
        out.append(f"| {name} | " + cells(lambda r, k=k: times(k)(r["pieces"] | r)))
    for k in ("selection, right after a batch", "batch (sum of pieces)", "batch warm",
              "batch cold", "second batch warm"):
        out.append(f"| **{k}** | " + cells(times(k, 0)))
    return "\n".join(out)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    p.add_argument("--repeats", type=int, default=3, help="best of, for every piece")
    p.add_argument("--profile", type=int, default=0, metavar="N",
                   help="print the N costliest functions of one more second batch")
    p.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.one:
        print(json.dumps(one(args.one, args.repeats, args.profile)))
        return
    rows = []
    for n in args.sizes:
        cmd = [sys.executable, __file__, "--one", str(n), "--repeats", str(args.repeats),
               "--profile", str(args.profile)]
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode != 0:
            print(f"{n} tets: failed\n{done.stderr[-3000:]}", file=sys.stderr)
            continue
        rows.append(json.loads(done.stdout.strip().splitlines()[-1]))
    if rows:
        print(table(rows))
    for r in rows:
        if r.get("profile"):
            print(f"\nThe second batch at {r['tets']:,} tets under cProfile:\n{r['profile']}")


if __name__ == "__main__":
    main()
