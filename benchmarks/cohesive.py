"""Cohesive crack faces: one step against a plain step and the floor (docs/performance.md).

Scene: a cube of side L = 0.1 (concrete-like: E = 30 GPa, nu = 0.2, sigma_t = 3 MPa, G_c =
100 N/m, linear law, penalty 20 unless ``--penalty``), structured into n^3 cells of 6 P1 tets
(tests/meshes.py ``structured_box``; n = 12: 10,368 tets, n = 26: 105,456), cut through the
mid plane x = L/2 by ``open_crack`` at every vertex of that plane (2 n^2 crack faces, 3
interface points each). Symmetry on xmin, ymin, zmin; the upper half (z > L/2) of the end
face xmax is moved along x (``--pull whole``: all of it), quasi-static, so the crack opens
from z = L down and its front crosses the section. Displacements are in units of U_REF =
sigma_t L / E + lambda_0 (where a uniform pull brings every face to its peak). The case is
prepared on a coarse gmsh cube and rediscretized on the structured meshes, as
tests/test_cohesive_solver.py does. One subprocess per size.

Timed (``ImplicitStepper.step`` from committed states; process CPU time and wall):

- the floor: one back-solve with the cached factor of K (uncut) plus one pass of the
  material law (strain ``B u``, ``law.update``, internal force), each piece alone, as in
  benchmarks/fracture.py;
- (a) a plain step: the uncut cube, 0.4 -> 0.6 U_REF (elastic, one iteration);
- (b) the same step on the cut cube, every face in its elastic branch;
- (c) three steps 0.8 -> 1.0 -> 1.2 -> 1.4 U_REF, the first taking faces past the peak, the
  front moving through the section: modified Newton (the case's, Anderson acceleration) and
  full Newton (a copy of the stepper), per step: CPU, iterations, factorizations; the
  PARDISO analyses full Newton's refactorizer made;
- the pieces: a back-solve with the cut cube's factor (K + K_coh), ``Interface.respond`` and
  ``force`` on the state (c) reached, ``matrix`` of the secant, ``build_interface`` on the
  cut mesh, a factorization of K and ``iteration_factor`` (what modified Newton does when
  damage changed the secant: the law at the step's start, J^T D J, the sum, factorization).

Every timed call starts from cold caches (a 64 MiB buffer written first) with the garbage
collector off. What takes well under a second (the floor's pieces, (a), (b), the cohesive
pieces) is repeated max(9, 3 x ``--repeats``) times in interleaved rounds, so that a change of
load on the shared cores falls on all alike; factorizations and (c) ``--repeats`` times, (c)'s
methods in turn. Cells: CPU median [min-max over the repeats], wall median, multiple of the
floor and of the plain step (by CPU). The steps are broken down by wrapping what they call
(back-solve, factorization, bulk law pass, cohesive respond / force / matrix, Anderson, ...).

    python benchmarks/cohesive.py                         # 10k and 100k tets, 3 repeats
    python benchmarks/cohesive.py --sizes 10000 --repeats 5
    python benchmarks/cohesive.py --sizes 10000 --penalty 1   # modified Newton vs k0

Measured 2026-12-02 with the defaults (about 11 minutes) on the machine of
docs/performance.md, 2 cores shared with other work (load average 3-4: wall 1.2-1.5x the
CPU time). Per step, CPU in floors, 10,368 / 105,456 tets (288 / 1,352 crack faces):

- (a) plain step 1.15 / 0.87 (the floor's pieces alone, from cold caches, can sum above a
  step at 100k); (b) cohesive step, faces elastic, 1.74 / 0.96: one iteration, no
  factorization; the law is evaluated twice (at the step's start to see whether the secant
  changed, and at the iterate);
- (c) modified Newton 300 / 283 floors a step: 317 / 166 / 103 and 183 / 217 / 196
  iterations (1.4-1.5 floors each), one refactorization a step once faces soften; full
  Newton 119 / 466: 4-7 iterations, a factorization at nearly every one (80 / 93 % of it);
- respond + force 0.40 / 0.05 back-solves; build_interface 1.8 / 1.2 floors;
- the iterations of (c) follow the penalty: with ``--penalty 1`` (k0 20x smaller) modified
  Newton takes 24 / 29 / 20 iterations at 10k (38 floors a step); with ``--pull whole``
  (every face on one path) 1 / 3 / 3.

The table, the breakdown and their reading: docs/performance.md, "Cohesive crack faces".
"""

from __future__ import annotations

import argparse
import copy
import gc
import json
import resource
import subprocess
import sys
import time
from collections import defaultdict
from contextlib import contextmanager
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent.parent / "tests"))

L = 0.1  # the cube's side (m)
E, NU, STRENGTH, ENERGY = 30e9, 0.2, 3e6, 100.0  # concrete-like; l_cz = E G_c / sigma^2 = 0.33 m
ELASTIC = (0.4, 0.6)  # steps (a) and (b): end displacement / U_REF, every face below its peak
BEFORE = 0.8  # the committed state (c) starts from: below the first face's peak
SOFTENING = (1.0, 1.2, 1.4)  # the steps of (c): the first takes faces past the peak
FLUSH_BYTES = 64 * 2**20
_FLUSH = np.zeros(0)


def cells_for(n_tets: int) -> int:
    """Cells per side of the structured cube (6 tets a cell), even: a vertex plane at L/2."""
    return max(2, 2 * round((n_tets / 6.0) ** (1 / 3) / 2))


def case_dict(pull: str, penalty: float, law: str) -> dict:
    """The case on a coarse gmsh cube; the discretizations are rebuilt on the structured
    meshes (as tests/test_cohesive_solver.py does). The end displacement is ``t`` metres."""
    if pull == "top":  # the upper half of the end face: the crack opens from z = L down
        where = {"box": {"min": [L * (1 - 1e-6), -L, L * (0.5 - 1e-6)],
                         "max": [L * (1 + 1e-6), 2 * L, 2 * L]}}
    else:
        where = {"boundary": "xmax"}
    return {
        "units": "SI",
        "mesh": {"geometry": {"type": "box", "lengths": [L, L, L]}, "element_size": L},
        "material": {"youngs_modulus": E, "poissons_ratio": NU, "density": 2400.0},
        "load_curves": {"metres": {"type": "table", "points": [[0.0, 0.0], [1.0, 1.0]]}},
        "boundary_conditions": [
            {"type": "symmetry", "boundary": "xmin"},
            {"type": "symmetry", "boundary": "ymin"},
            {"type": "symmetry", "boundary": "zmin"},
            {"type": "displacement", "x": 1.0, "curve": "metres", **where}],
        "fracture": {"tensile_strength": STRENGTH, "fracture_energy": ENERGY,
                     "smoothing": {"rings": 0},
                     "cohesive": {"penalty": penalty, "law": law}},
        "analysis": {"type": "quasi_static", "steps": 1,
                     "equilibrium": {"method": "modified_newton"}},
    }


def meshes(n: int):
    """The structured cube (n cells a side, its sides named) and the same cube cut along
    x = L/2 at every vertex of that plane."""
    from fem_frac.fracture.topology import open_crack
    from fem_frac.mesh.mesh import TET_FACES, Mesh, exterior_face_rows
    from meshes import structured_box

    box = structured_box((n, n, n), lengths=(L, L, L))
    faces = box.tets[:, TET_FACES].reshape(-1, 3)[exterior_face_rows(box.tets, box.n_points)]
    centre = box.points[faces].mean(axis=1)
    named = {}
    for axis, name in enumerate("xyz"):
        named[f"{name}min"] = faces[np.abs(centre[:, axis]) < 1e-9 * L]
        named[f"{name}max"] = faces[np.abs(centre[:, axis] - L) < 1e-9 * L]
    box = Mesh(box.points, box.tets, named)
    plane = np.flatnonzero(np.abs(box.points[:, 0] - 0.5 * L) < 1e-9 * L)
    cut, _ = open_crack(box, plane, np.tile([1.0, 0.0, 0.0], (len(plane), 1)))
    return box, cut


# ---------------------------------------------------------------- timing helpers

def flush_caches() -> None:
    """Write a 64 MiB buffer (twice the L3 cache) so the next timed call starts cold, as
    in plastic_step.py and fracture.py."""
    global _FLUSH
    if _FLUSH.size == 0:
        _FLUSH = np.zeros(FLUSH_BYTES // 8)
    _FLUSH += 1.0


def rounds(fns: dict, repeats: int, clock: Clock | None = None):
    """Process CPU and wall seconds of ``repeats`` calls of every ``fns[name]()``,
    interleaved (one call of each per round, so that a change of load on the shared cores
    falls on all of them alike), each from cold caches with the garbage collector off;
    ``(timings by name, last result by name)``. With ``clock``, what each call does is
    booked under its name."""
    times = {name: {"cpu": [], "wall": []} for name in fns}
    out = {}
    for _ in range(repeats):
        for name, fn in fns.items():
            if clock is not None:
                clock.bucket = name
            flush_caches()
            gc.collect()
            gc.disable()
            try:
                c0, w0 = time.process_time(), time.perf_counter()
                out[name] = fn()
                c1, w1 = time.process_time(), time.perf_counter()
            finally:
                gc.enable()
            times[name]["cpu"].append(c1 - c0)
            times[name]["wall"].append(w1 - w0)
    return times, out


class Clock:
    """CPU seconds and calls per label of the functions it wraps, booked under the current
    ``bucket``."""

    def __init__(self):
        self.bucket = ""
        self.seconds: dict = defaultdict(lambda: defaultdict(float))
        self.calls: dict = defaultdict(lambda: defaultdict(int))

    def wrap(self, label: str, fn):
        def wrapped(*args, **kwargs):
            c0 = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                self.seconds[self.bucket][label] += time.process_time() - c0
                self.calls[self.bucket][label] += 1

        return wrapped


@contextmanager
def instrumented(clock: Clock, law_class):
    """What a step calls, timed by ``clock`` (class attributes patched; no label nests in
    another): back-solves, factorizations (restriction to the free dofs, PARDISO, probe),
    the bulk law pass, the bulk tangent assembly, the cohesive law, force and matrix, the
    Jacobian's sum, Anderson's mixing."""
    from fem_frac.cohesive.interface import Interface
    from fem_frac.fem.operators import StrainOperator
    from fem_frac.solve import linalg, stepping
    from fem_frac.solve.constrained import Constrained

    patches = [(linalg.Factorization, "solve", "back-solve"),
               (Constrained, "factorize", "factorization"),
               (StrainOperator, "strain", "bulk law pass"),
               (StrainOperator, "internal_force", "bulk law pass"),
               (law_class, "update", "bulk law pass"),
               (StrainOperator, "stiffness", "bulk tangent B^T D B"),
               (Interface, "respond", "cohesive respond"),
               (Interface, "force", "cohesive force"),
               (Interface, "matrix", "cohesive matrix J^T D J"),
               (stepping.ImplicitStepper, "jacobian", "Jacobian (scaling, sum)"),
               (stepping.Anderson, "__call__", "Anderson")]
    saved = [(cls, name, cls.__dict__[name]) for cls, name, _ in patches]
    try:
        for cls, name, label in patches:
            setattr(cls, name, clock.wrap(label, cls.__dict__[name]))
        yield
    finally:
        for cls, name, fn in saved:
            setattr(cls, name, fn)


def spread(x: list[float]) -> dict:
    return {"median": float(np.median(x)), "min": float(min(x)), "max": float(max(x))}


def summary(t: dict) -> dict:
    return {"cpu": spread(t["cpu"]), "wall": spread(t["wall"]), "n": len(t["cpu"])}


def booked(clock: Clock, bucket: str, cpu: float) -> dict:
    """The clock's seconds and calls under ``bucket``, with the CPU they are part of."""
    return {"seconds": dict(clock.seconds[bucket]), "calls": dict(clock.calls[bucket]),
            "cpu": cpu}


# ---------------------------------------------------------------- one size

def one(n_tets: int, repeats: int, pull: str, penalty: float, law: str) -> dict:
    from fem_frac.app.driver import prepare
    from fem_frac.cohesive.interface import build_interface
    from fem_frac.config.schema import Case
    from fem_frac.solve.state import initial_state
    from fem_frac.solve.stepping import NotConverged
    from fem_frac.timing import StageTimer
    from fem_frac.world.transfer import rediscretize

    cheap = max(9, 3 * repeats)  # repeats of what takes well under a second
    n = cells_for(n_tets)
    box, cut = meshes(n)
    setup = prepare(Case.model_validate(case_dict(pull, penalty, law)), Path("."),
                    StageTimer())
    plain = rediscretize(setup.disc, box, StageTimer(), "uncut")  # no crack face: no interface
    disc = rediscretize(setup.disc, cut, StageTimer(), "cut")
    itf = disc.ops.interface
    assert plain.ops.interface is None and itf is not None
    lam0 = float(np.median(itf.law.peak_opening(itf.stiffness)))
    lamc = float(np.median(itf.law.critical_opening(itf.stiffness)))
    u_ref = STRENGTH * L / E + lam0  # a uniform pull brings every face to its peak here
    r: dict = {"tets": box.n_tets, "cells": n, "dofs": plain.space.n_dofs,
               "cut dofs": disc.space.n_dofs, "free": len(plain.constrained.free),
               "cut free": len(disc.constrained.free), "crack faces": itf.n_faces,
               "interface points": itf.n_points, "k0": float(np.median(itf.stiffness)),
               "lambda_0": lam0, "lambda_c": lamc, "u_ref": u_ref, "pull": pull,
               "penalty": penalty, "law": law, "repeats": repeats, "cheap repeats": cheap}
    clock = Clock()
    law_class = type(disc.law)

    # (a) on the uncut cube and (b) on the cut one: the elastic step 0.4 -> 0.6 U_REF
    pst, st = plain.stepper, disc.stepper
    t_a, t_b = (f * u_ref for f in ELASTIC)
    p0 = initial_state(plain.problem, plain.law, plain.ops, None, plain.constrained)
    c0 = initial_state(disc.problem, disc.law, disc.ops, None, disc.constrained)
    p1, _ = pst.step(p0, t_a, 1)  # factorizes K
    c1, _ = st.step(c0, t_a, 1)  # factorizes K + K_coh (the faces' initial secant)
    with instrumented(clock, law_class):
        t, out = rounds({"plain step": lambda: pst.step(p1, t_b, 2),
                         "elastic step": lambda: st.step(c1, t_b, 2)}, cheap, clock)
    (p2, info_a), (c2, info_b) = out["plain step"], out["elastic step"]
    for name, info in (("plain step", info_a), ("elastic step", info_b)):
        r[name] = summary(t[name])
        r[name]["iterations"], r[name]["factorizations"] = (info.iterations,
                                                            info.factorizations)
        r[name]["booked"] = booked(clock, name, sum(t[name]["cpu"]))
    assert c2.cohesive.kappa.max() < lam0, "step (b) took a face past its peak"
    c3, _ = st.step(c2, BEFORE * u_ref, 3)
    assert c3.cohesive.kappa.max() < lam0, "the state before (c) is past a peak"
    base = (st.factor, st.secant)  # as a run leaves them: the secant at c3 is held

    # (c): softening from c3 through the steps SOFTENING, modified and full Newton in turn
    newton = copy.copy(st)
    newton.equilibrium = st.equilibrium.model_copy(update={"method": "newton"})
    newton.tangents = None
    methods = {"modified Newton": st, "full Newton": newton}
    runs = {name: [] for name in methods}
    reached = {}
    for rep in range(repeats):
        for name, stepper in methods.items():
            if runs[name] and runs[name][-1]["failed"]:
                continue
            stepper.factor, stepper.secant = base
            analyses = stepper.tangents.analyses if stepper.tangents is not None else 0
            clock.bucket = f"{name} {rep}"
            flush_caches()
            gc.collect()
            state, steps, failed = c3, [], None
            with instrumented(clock, law_class):
                c_start, w_start = time.process_time(), time.perf_counter()
                for k, f in enumerate(SOFTENING):
                    c, w = time.process_time(), time.perf_counter()
                    try:
                        state, info = stepper.step(state, f * u_ref, 4 + k)
                    except NotConverged as exc:
                        failed = f"step {k + 1}: {exc}"
                        break
                    steps.append({"cpu": time.process_time() - c,
                                  "wall": time.perf_counter() - w,
                                  "iterations": info.iterations, "solves": info.solves,
                                  "factorizations": info.factorizations})
                total = (time.process_time() - c_start, time.perf_counter() - w_start)
            runs[name].append({"cpu": total[0], "wall": total[1], "steps": steps,
                               "failed": failed,
                               "booked": booked(clock, clock.bucket, total[0]),
                               "analyses": (stepper.tangents.analyses - analyses
                                            if stepper.tangents is not None else 0)})
            if not failed:
                reached[name] = state
    k = len(SOFTENING)
    for name, done in runs.items():
        entry = {"failed": done[-1]["failed"], "analyses": [x["analyses"] for x in done]}
        done = [x for x in done if not x["failed"]]
        if done:
            median = sorted(done, key=lambda x: x["cpu"])[len(done) // 2]
            entry.update({
                "step": {"cpu": spread([x["cpu"] / k for x in done]),
                         "wall": spread([x["wall"] / k for x in done]), "n": len(done)},
                "steps": median["steps"], "booked": median["booked"], "cpu": median["cpu"]})
        r[name] = entry

    # the floor and the cohesive pieces, on the state the softening steps reached (faces
    # in their elastic and softening branches)
    end = reached.get("modified Newton", c3)
    kappa = end.cohesive.kappa
    r["branches"] = {"softening": float(np.mean((kappa > lam0) & (kappa < lamc))),
                     "broken": float(np.mean(kappa >= lamc)),
                     "max opening / lambda_0": float(kappa.max() / lam0)}
    factor, cut_factor = pst.elastic_factor(), base[0]
    rhs = np.random.default_rng(0).standard_normal(len(plain.constrained.free))
    cut_rhs = np.random.default_rng(0).standard_normal(len(disc.constrained.free))
    op = plain.ops.strain_operator
    strain = op.strain(p2.u)
    resp, _ = itf.respond(end.u, kappa)
    recipe, youngs = disc.recipe.cohesive, disc.materials.youngs_modulus
    pieces = {
        "back-solve": lambda: factor.solve(rhs),
        "strain": lambda: op.strain(p2.u),
        "law.update": lambda: plain.law.update(strain, p1.plastic),
        "internal force": lambda: op.internal_force(p2.stress),
        "back-solve K + K_coh": lambda: cut_factor.solve(cut_rhs),
        "respond": lambda: itf.respond(end.u, kappa),
        "force": lambda: itf.force(resp.traction),
        "respond + force": lambda: itf.force(itf.respond(end.u, kappa)[0].traction),
        "matrix": lambda: itf.matrix(resp.secant),
        "build_interface": lambda: build_interface(recipe, cut, disc.space, youngs),
    }
    t, _ = rounds(pieces, cheap)
    floor = ("back-solve", "strain", "law.update", "internal force")
    r["floor pieces"] = {name: summary(t[name]) for name in floor}
    r["floor"] = {w: {"median": sum(r["floor pieces"][name][w]["median"] for name in floor)}
                  for w in ("cpu", "wall")}
    for name in pieces:
        if name not in floor:
            r[name] = summary(t[name])

    # factorizations: K, and what modified Newton does where damage changed the secant
    def refactor():
        st.factor = None
        return st.iteration_factor(c3)

    t, _ = rounds({"factorize K": lambda: plain.constrained.factorize(pst.elastic_jacobian),
                   "iteration_factor": refactor}, repeats)
    r["factorize K"], r["iteration_factor"] = summary(t["factorize K"]), summary(
        t["iteration_factor"])
    r["peak_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return r


# ---------------------------------------------------------------- tables

def _t(x: float) -> str:
    return f"{1e3 * x:.1f} ms" if x < 1 else f"{x:.2f} s"


def _span(s: dict) -> str:
    lo, hi = s["min"], s["max"]
    return f"{1e3 * lo:.1f}-{1e3 * hi:.1f} ms" if hi < 1 else f"{lo:.2f}-{hi:.2f} s"


def _cpu(r: dict, key: str) -> float:
    return r[key]["cpu"]["median"]


def per_iteration(r: dict, name: str) -> str:
    """CPU of the median run of (c) per iteration, in floors."""
    e = r[name]
    if "steps" not in e:
        return "-"
    iterations = sum(s["iterations"] for s in e["steps"])
    return f"{e['cpu'] / iterations / _cpu(r, 'floor'):.1f}"


def table(rows: list[dict]) -> str:
    """One column per size. A time cell: CPU (median of the repeats) [CPU min-max], wall
    median, multiple of the floor, multiple of the plain step (both by CPU)."""
    def line(name: str, f) -> str:
        return f"| {name} | " + " | ".join(f(r) for r in rows) + " |"

    def cell(get, digits: int = 2):
        def f(r):
            s = get(r)
            if s is None:
                return "-"
            c, w = s["cpu"]["median"], s["wall"]["median"]
            floor, plain = r["floor"]["cpu"]["median"], r["plain step"]["cpu"]["median"]
            span = f" [{_span(s['cpu'])}]" if "min" in s["cpu"] else ""
            return (f"{_t(c)}{span}, wall {_t(w)}, {c / floor:.{digits}f}, "
                    f"{c / plain:.{digits}f}")
        return f

    def newton(name: str, key: str):
        return lambda r: ("not converged" if "step" not in r[name] else
                          " / ".join(str(s[key]) for s in r[name]["steps"]))

    out = [line("(CPU [min-max], wall, /floor, /plain step)", lambda r: f"{r['tets']:,} tets"),
           "|" + "---|" * (len(rows) + 1),
           line("cells a side; free dofs uncut / cut", lambda r: (
               f"{r['cells']}; {r['free']:,} / {r['cut free']:,}")),
           line("crack faces; interface points", lambda r: (
               f"{r['crack faces']:,}; {r['interface points']:,}")),
           line("k0 (Pa/m); lambda_0 / lambda_c (m)", lambda r: (
               f"{r['k0']:.2e}; {r['lambda_0']:.2e} / {r['lambda_c']:.2e}")),
           line("peak MiB", lambda r: f"{r['peak_mib']:,.0f}"),
           line("**floor** (sum of medians)", cell(lambda r: r["floor"]))]
    for k in ("back-solve", "strain", "law.update", "internal force"):
        out.append(line(f"- {k}", cell(lambda r, k=k: r["floor pieces"][k])))
    out += [line("**(a) plain step** (uncut, elastic)", cell(lambda r: r["plain step"])),
            line("- iterations", lambda r: str(r["plain step"]["iterations"])),
            line("**(b) cohesive step, faces elastic**", cell(lambda r: r["elastic step"])),
            line("- iterations / factorizations", lambda r: (
                f"{r['elastic step']['iterations']} / {r['elastic step']['factorizations']}"))]
    for name in ("modified Newton", "full Newton"):
        out += [line(f"**(c) {name}, per softening step**",
                     cell(lambda r, n=name: r[n].get("step"), 1)),
                line("- CPU (steps 1 / 2 / 3)", lambda r, n=name: (
                    "-" if "steps" not in r[n] else
                    " / ".join(_t(x["cpu"]) for x in r[n]["steps"]))),
                line("- iterations (steps 1 / 2 / 3)", newton(name, "iterations")),
                line("- factorizations (steps 1 / 2 / 3)", newton(name, "factorizations")),
                line("- CPU per iteration / floor", lambda r, n=name: per_iteration(r, n))]
    out.append(line("- full Newton: PARDISO analyses per run", lambda r: ", ".join(
        str(a) for a in r["full Newton"]["analyses"])))
    out += [line("factorize K (uncut)", cell(lambda r: r["factorize K"], 1)),
            line("refactorize K + K_coh (iteration_factor)", cell(
                lambda r: r["iteration_factor"], 1)),
            line("back-solve with K + K_coh", cell(lambda r: r["back-solve K + K_coh"])),
            line("**respond + force**", cell(lambda r: r["respond + force"])),
            line("- in back-solves (K + K_coh)", lambda r: (
                f"{_cpu(r, 'respond + force') / _cpu(r, 'back-solve K + K_coh'):.2f}")),
            line("- respond", cell(lambda r: r["respond"])),
            line("- force", cell(lambda r: r["force"])),
            line("matrix J^T D J (secant)", cell(lambda r: r["matrix"])),
            line("**build_interface**", cell(lambda r: r["build_interface"], 1)),
            line("state after (c): softening / broken points, max opening / lambda_0",
                 lambda r: (f"{100 * r['branches']['softening']:.0f} % / "
                            f"{100 * r['branches']['broken']:.0f} %, "
                            f"{r['branches']['max opening / lambda_0']:.0f}"))]
    return "\n".join(out)


LABELS = ("back-solve", "bulk law pass", "cohesive respond", "cohesive force",
          "Anderson", "factorization", "cohesive matrix J^T D J", "bulk tangent B^T D B",
          "Jacobian (scaling, sum)")


COLUMNS = {"plain step": "(a)", "elastic step": "(b)", "modified Newton": "(c) modified",
           "full Newton": "(c) full"}


def breakdown(rows: list[dict]) -> str:
    """Where the steps' CPU goes: share, calls (all repeats of (a) and (b); the median run
    of (c), its three steps)."""
    heads = [f"{r['tets']:,} {head}" for r in rows for head in COLUMNS.values()]
    out = ["| share of CPU (calls) | " + " | ".join(heads) + " |",
           "|" + "---|" * (len(heads) + 1)]
    entries = [r[key].get("booked") for r in rows for key in COLUMNS]
    for label in (*LABELS, "other"):
        cells = []
        for e in entries:
            if e is None:
                cells.append("-")
                continue
            if label == "other":
                share = 1 - sum(e["seconds"].values()) / e["cpu"]
                cells.append(f"{100 * share:.0f} %")
                continue
            s, c = e["seconds"].get(label, 0.0), e["calls"].get(label, 0)
            cells.append(f"{100 * s / e['cpu']:.0f} % ({c})" if c else "-")
        out.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--pull", choices=("top", "whole"), default="top",
                   help="displacement on the upper half of the end face, or all of it")
    p.add_argument("--penalty", type=float, default=20.0, help="fracture.cohesive.penalty")
    p.add_argument("--law", choices=("linear", "exponential"), default="linear")
    p.add_argument("--json", help="also write the raw figures here")
    p.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.one:
        print(json.dumps(one(args.one, args.repeats, args.pull, args.penalty, args.law)))
        return
    rows = []
    for n in args.sizes:
        cmd = [sys.executable, __file__, "--one", str(n), "--repeats", str(args.repeats),
               "--pull", args.pull, "--penalty", str(args.penalty), "--law", args.law]
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode != 0:
            print(f"{n} tets: failed\n{done.stderr[-3000:]}", file=sys.stderr)
            continue
        rows.append(json.loads(done.stdout.strip().splitlines()[-1]))
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    if rows:
        print(table(rows))
        print()
        print(breakdown(rows))


if __name__ == "__main__":
    main()
