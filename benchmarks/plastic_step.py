"""One implicit plastic step against its floor (DESIGN §7).

The floor of a step is one back-solve with the cached factorization plus one pass of the
return map over all quadrature points, each timed alone (best of ``--repeats``). Against
it, from the same committed, partly plastic state (so the steps are comparable), this
times ``ImplicitStepper.step`` for

- (a) a step the first iterate solves: elastic unloading from the plastic state;
- (b) a plastic loading step with modified Newton (iterations, cost per iteration);
- (c) the same step with full Newton (iterations, tangent assembly and factorization share),

and breaks every step down by wrapping what the stepper calls (back-solve, strain, return
map, internal force, external force, residual norms; for Newton the tangent assembly and
the factorization) with timers: what is left is the stepper's own residual and bookkeeping
arithmetic.

The case: a thick hollow sphere octant (radii 1 and 2, symmetry planes) under internal
pressure ramped to the yield stress, von Mises with linear hardening, quasi-static; loaded
in 9 steps to 0.9 sigma_Y, when the inner part of the wall has yielded. Each configuration
runs in a fresh subprocess. Prints markdown tables; the numbers are in docs/performance.md.

    python benchmarks/plastic_step.py --repeats 9            # P1 10k, 100k; P2 10k, 50k
    python benchmarks/plastic_step.py --configs 10000,1 --repeats 5
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
from contextlib import ExitStack, contextmanager
from pathlib import Path

import numpy as np

INNER, OUTER = 1.0, 2.0
VOLUME = np.pi / 6.0 * (OUTER**3 - INNER**3)  # the octant
# gmsh tets of the hollow sphere octant: n_tets ~ TETS_PER_H3 * volume / h^3 (measured 4.2-4.7)
TETS_PER_H3 = 4.5
YIELD = 250e6
STEPS = 10  # of the load ramp 0 -> YIELD over t in [0, 1]
PRELOAD = 9  # committed steps before the timed ones: t = 0.9
FLUSH_BYTES = 64 * 2**20
DEFAULT_CONFIGS = ("10000,1", "100000,1", "10000,2", "50000,2")


def case_dict(n_tets: int, order: int, formulation: str) -> dict:
    h = (TETS_PER_H3 * VOLUME / n_tets) ** (1 / 3)
    dt = 1.0 / STEPS
    return {
        "mesh": {
            "geometry": {"type": "hollow_sphere", "inner_radius": INNER,
                         "outer_radius": OUTER, "sector": "octant"},
            "element_size": h, "order": order, "formulation": formulation,
        },
        "material": {"youngs_modulus": 210e9, "poissons_ratio": 0.3},
        "plasticity": {"yield_stress": YIELD, "hardening": 10e9},
        "boundary_conditions": [
            {"type": "symmetry", "boundary": "symmetry_x"},
            {"type": "symmetry", "boundary": "symmetry_y"},
            {"type": "symmetry", "boundary": "symmetry_z"},
            {"type": "pressure", "boundary": "inner", "pressure": YIELD, "curve": "load"},
        ],
        "load_curves": {"load": {"type": "ramp", "t_end": 1.0}},
        "analysis": {"type": "quasi_static", "t_end": PRELOAD * dt, "steps": PRELOAD,
                     "linear_solver": "auto"},
    }


def peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


# ---------------------------------------------------------------- timing helpers

class Clock:
    """Inclusive seconds and calls per label of the functions it wraps."""

    def __init__(self):
        self.seconds: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)

    def wrap(self, label: str, fn):
        def timed(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.seconds[label] += time.perf_counter() - t0
                self.calls[label] += 1

        return timed

    def reset(self) -> None:
        self.seconds.clear()
        self.calls.clear()


class Proxy:
    """``target`` with some methods replaced by ``clock``-wrapped ones; the rest passes."""

    def __init__(self, target, clock: Clock, methods: dict[str, str], wrap_result=None):
        self._target = target
        for name, label in methods.items():
            fn = clock.wrap(label, getattr(target, name))
            if wrap_result is not None and name in wrap_result:
                fn = _then(fn, wrap_result[name])
            setattr(self, name, fn)

    def __getattr__(self, name):
        return getattr(self._target, name)


def _then(fn, post):
    return lambda *a, **k: post(fn(*a, **k))


class TimedMatrix:
    """A sparse matrix whose ``@`` is timed (the stepper's linearized predictor)."""

    def __init__(self, matrix, clock: Clock, label: str):
        self._matmul = clock.wrap(label, matrix.__matmul__)

    def __matmul__(self, other):
        return self._matmul(other)


@contextmanager
def no_gc():
    """The garbage collector off, as timeit does."""
    gc.collect()
    gc.disable()
    try:
        yield
    finally:
        gc.enable()


_FLUSH = np.zeros(0)


def flush_caches() -> None:
    """Write a buffer twice the size of the L3 cache (32 MiB here), so that the next timed
    call starts cold, as a step does after the ledger, output and other work of a run:
    back-to-back repeats would otherwise find a small factor (10k P1: a few MiB) and the
    quadrature-point arrays in cache and run 2-3x faster than inside a step."""
    global _FLUSH
    if _FLUSH.size == 0:
        _FLUSH = np.zeros(FLUSH_BYTES // 8)
    _FLUSH += 1.0


def best(fn, repeats: int) -> tuple[float, object]:
    """Best wall time of ``repeats`` calls of ``fn()``, each from cold caches, and the last
    result."""
    times, out = [], None
    with no_gc():
        for _ in range(repeats):
            flush_caches()
            t0 = time.perf_counter()
            out = fn()
            times.append(time.perf_counter() - t0)
    return min(times), out


@contextmanager
def patched(module, name: str, value):
    old = getattr(module, name)
    setattr(module, name, value)
    try:
        yield
    finally:
        setattr(module, name, old)


def instrumented(disc, clock: Clock, method: str | None = None):
    """A copy of the discretization's stepper whose collaborators report to ``clock``; with
    ``method``, that equilibrium method instead of the case's."""
    import fem_frac.solve.constrained as constrained
    import fem_frac.solve.linalg as linalg
    from fem_frac.solve import stepping
    from fem_frac.solve.state import Operators

    base = disc.stepper
    st = copy.copy(base)
    if method is not None:
        st.equilibrium = base.equilibrium.model_copy(update={"method": method})
    solve_proxy = lambda f: Proxy(f, clock, {"solve": "back-solve"})  # noqa: E731
    st.factor = solve_proxy(base.elastic_factor())
    st.problem = Proxy(base.problem, clock, {"external_force": "external force",
                                             "prescribed": "external force"})
    st.law = Proxy(base.law, clock, {"update": "return map"})
    op = Proxy(base.ops.strain_operator, clock, {"strain": "strain",
                                                 "internal_force": "internal force",
                                                 "stiffness": "tangent assembly"})
    st.ops = Operators(op, base.ops.stiffness, base.ops.mass, base.ops.damping)
    # the first iterate's K du: the stiffness columns of the moved prescribed dofs
    st.fixed_columns = TimedMatrix(base.fixed_columns, clock, "K du predictor")
    st.constrained = Proxy(base.constrained, clock, {"factorize": "factorize (all)"},
                           wrap_result={"factorize": solve_proxy})
    st.jacobian = clock.wrap("tangent assembly", st.jacobian)
    patches = [
        (stepping, "check_finite", clock.wrap("finite checks", stepping.check_finite)),
        (constrained, "factorize", clock.wrap("factorize (linalg)", constrained.factorize)),
        # full Newton's tangents go through the refactorizer, not linalg.factorize
        (linalg.Refactorizer, "factorize",
         clock.wrap("factorize (linalg)", linalg.Refactorizer.factorize)),
        (linalg, "_probe", clock.wrap("factorize probe", linalg._probe)),
    ]
    if hasattr(stepping, "_norm"):
        patches.append((stepping, "_norm", clock.wrap("residual norms", stepping._norm)))
    return st, patches


def run_instrumented(disc, state, t: float, repeats: int, method: str | None = None):
    """Best (by total) of ``repeats`` instrumented steps: ``(total, seconds, calls, info)``."""
    clock = Clock()
    st, patches = instrumented(disc, clock, method)
    best_run = None
    for _ in range(repeats):
        clock.reset()
        with ExitStack() as stack:
            stack.enter_context(no_gc())
            for patch in patches:
                stack.enter_context(patched(*patch))
            flush_caches()
            t0 = time.perf_counter()
            _, info = st.step(state, t, PRELOAD + 1)
            total = time.perf_counter() - t0
        if best_run is None or total < best_run[0]:
            best_run = (total, dict(clock.seconds), dict(clock.calls), info)
    return best_run


FACTOR_LABELS = ("restrict to free dofs", "factorize (PARDISO + checks)", "factorize probe")


def pardiso_phases(disc) -> dict:
    """Seconds of PARDISO's analysis (phase 11: METIS ordering, symbolic factorization) and
    numerical factorization (phase 22) of the elastic Jacobian on the free dofs: what a
    refactorization with an unchanged sparsity pattern could skip, and what it cannot."""
    from fem_frac.solve import linalg

    if disc.stepper.elastic_factor().method != "pardiso":
        return {}
    free = disc.constrained.free
    sub = disc.stepper.elastic_jacobian[free][:, free].tocsr()
    handle = linalg._PardisoHandle(sub)
    dummy = np.zeros(handle.n)
    t0 = time.perf_counter()
    handle.call(11, dummy, dummy)
    t1 = time.perf_counter()
    handle.call(22, dummy, dummy)
    t2 = time.perf_counter()
    return {"pardiso_analysis_s": t1 - t0, "pardiso_numeric_s": t2 - t1}


def exclusive(seconds: dict[str, float], total: float) -> dict[str, float]:
    """Nested labels made exclusive; ``other`` is what the wrappers did not see."""
    s = dict(seconds)
    all_f = s.pop("factorize (all)", 0.0)
    lin = s.pop("factorize (linalg)", 0.0)
    probe = s.pop("factorize probe", 0.0)
    if all_f:
        s["restrict to free dofs"] = all_f - lin
        s["factorize (PARDISO + checks)"] = lin - probe
        s["factorize probe"] = probe
    s["other (residual, copies, state)"] = total - sum(s.values())
    return s


# ---------------------------------------------------------------- one configuration

def one(n_tets: int, order: int, formulation: str, repeats: int, newton_repeats: int) -> dict:
    from fem_frac.app.driver import prepare, simulate
    from fem_frac.config.schema import Case
    from fem_frac.timing import StageTimer

    row: dict = {"target_tets": n_tets, "order": order, "formulation": formulation}
    timer = StageTimer()
    setup = prepare(Case.model_validate(case_dict(n_tets, order, formulation)), Path("."),
                    timer)
    t0 = time.perf_counter()
    world, tally = simulate(setup, timer)
    row["preload_s"] = time.perf_counter() - t0
    row["factorize_s"] = timer.seconds["factorize"]
    row["preload_iterations"] = tally.iterations
    state, disc = world.body.state, world.body.disc
    law, ops, st = disc.law, disc.ops, disc.stepper
    factor = st.elastic_factor()
    row["solver"] = factor.method
    row["tets"] = disc.mesh.n_tets
    row["dofs"] = disc.space.n_dofs
    row["free_dofs"] = len(disc.constrained.free)
    row["qp"] = int(ops.weights.size)
    row["yielded"] = float(np.mean(state.plastic.equivalent_plastic_strain > 0))
    dt = 1.0 / STEPS
    t_a, t_b = state.t - dt, state.t + dt  # unloading, loading

    # floor: one back-solve, one return map (and, for reference, strain and internal force)
    free = disc.constrained.free
    rhs = (disc.problem.external_force(t_a) - state.internal_force)[free]
    row["solve_s"], _ = best(lambda: factor.solve(rhs), repeats)
    new_a, info_a = st.step(state, t_a, PRELOAD + 1)
    strain = ops.strain_operator.strain(new_a.u)
    row["return_map_s"], _ = best(lambda: law.update(strain, state.plastic), repeats)
    row["strain_s"], _ = best(lambda: ops.strain_operator.strain(new_a.u), repeats)
    row["internal_force_s"], _ = best(
        lambda: ops.strain_operator.internal_force(new_a.stress), repeats)
    floor = row["floor_s"] = row["solve_s"] + row["return_map_s"]

    # (a) a step the first iterate solves
    row["a_s"], (_, info) = best(lambda: st.step(state, t_a, PRELOAD + 1), repeats)
    row["a_iterations"] = info.iterations
    total, seconds, calls, _ = run_instrumented(disc, state, t_a, repeats)
    row["a_instrumented_s"] = total
    row["a_parts"] = exclusive(seconds, total)
    row["a_calls"] = calls
    row["a_ratio"] = row["a_s"] / floor
    # against DESIGN §7's wider floor: the whole pass over the quadrature points
    row["a_pass_ratio"] = row["a_s"] / (floor + row["strain_s"] + row["internal_force_s"])

    # (b) plastic loading step, modified Newton
    b_repeats = max(1, min(3, repeats // 2))
    row["b_s"], (new_b, info) = best(lambda: st.step(state, t_b, PRELOAD + 1), b_repeats)
    row["b_iterations"] = info.iterations
    row["b_ratio"] = row["b_s"] / floor
    row["b_per_iteration_ratio"] = row["b_s"] / info.iterations / floor
    total, seconds, calls, _ = run_instrumented(disc, state, t_b, 1)
    row["b_parts"] = exclusive(seconds, total)
    row["b_calls"] = calls
    row["b_yielded"] = float(np.mean(new_b.plastic.equivalent_plastic_strain > 0))

    # (c) the same step, full Newton (the elastic factorization reused for its first iterate)
    total, seconds, calls, info = run_instrumented(disc, state, t_b, newton_repeats,
                                                   method="newton")
    row["c_s"] = total
    row["c_iterations"] = info.iterations
    row["c_factorizations"] = info.factorizations
    row["c_ratio"] = total / floor
    row["c_parts"] = c = exclusive(seconds, total)
    row["c_calls"] = calls
    row["c_tangent_s"] = c.get("return map", 0.0) - info.iterations * row["return_map_s"]
    row.update(pardiso_phases(disc))
    row["peak_mib"] = peak_mib()
    return row


# ---------------------------------------------------------------- tables

def _ms(x: float) -> str:
    return f"{1e3 * x:.1f}" if x < 10 else f"{x:.1f} s"


def summary_table(rows: list[dict]) -> str:
    """Floor and step (a)."""
    head = ("| tets | P | free dofs | qp | yielded | solver | back-solve ms | return map ms "
            "| floor ms | strain ms | internal force ms | (a) iterations | (a) ms | (a)/floor "
            "| (a)/(floor + strain + internal force) |")
    rule = "|" + "---|" * 15
    body = [
        f"| {r['tets']:,} | P{r['order']} | {r['free_dofs']:,} | {r['qp']:,} "
        f"| {100 * r['yielded']:.0f} % | {r['solver']} | {_ms(r['solve_s'])} "
        f"| {_ms(r['return_map_s'])} | {_ms(r['floor_s'])} | {_ms(r['strain_s'])} "
        f"| {_ms(r['internal_force_s'])} | {r['a_iterations']} | {_ms(r['a_s'])} "
        f"| **{r['a_ratio']:.2f}** | {r['a_pass_ratio']:.2f} |"
        for r in rows
    ]
    return "\n".join([head, rule, *body])


def newton_table(rows: list[dict]) -> str:
    """Steps (b) and (c)."""
    head = ("| tets | P | (b) iterations | (b) s | (b)/floor | (b)/iteration/floor "
            "| (c) iterations | (c) factorizations | (c) s | (c)/floor | (c)/(b) "
            "| (c) tangent + assembly | (c) factorization | PARDISO analysis / numeric s |")
    rule = "|" + "---|" * 14
    body = []
    for r in rows:
        c, total = r["c_parts"], r["c_s"]
        assembly = c.get("tangent assembly", 0.0)
        if "return map" in c:  # with the consistent tangent, in (c)
            assembly += c["return map"]
        factor = sum(c.get(k, 0.0) for k in FACTOR_LABELS)
        phases = (f"{r['pardiso_analysis_s']:.2f} / {r['pardiso_numeric_s']:.2f}"
                  if "pardiso_analysis_s" in r else "-")
        body.append(
            f"| {r['tets']:,} | P{r['order']} | {r['b_iterations']} | {r['b_s']:.2f} "
            f"| {r['b_ratio']:.0f} | {r['b_per_iteration_ratio']:.2f} "
            f"| {r['c_iterations']} "
            f"| {r['c_factorizations']} | {total:.2f} | {r['c_ratio']:.0f} "
            f"| {total / r['b_s']:.1f} "
            f"| {100 * assembly / total:.0f} % | {100 * factor / total:.0f} % | {phases} |"
        )
    return "\n".join([head, rule, *body])


def parts_table(rows: list[dict], key: str, title: str) -> str:
    labels: list[str] = []
    for r in rows:
        for label in r[f"{key}_parts"]:
            if label not in labels:
                labels.append(label)
    head = f"| {title} | " + " | ".join(f"{r['tets']:,} P{r['order']}" for r in rows) + " |"
    rule = "|" + "---|" * (len(rows) + 1)
    body = []
    for label in labels:
        cells = []
        for r in rows:
            s = r[f"{key}_parts"].get(label)
            total = sum(r[f"{key}_parts"].values())
            n = r[f"{key}_calls"].get(label, 0) if label in r[f"{key}_calls"] else ""
            calls = f" ({n}x)" if n and n > 1 else ""
            cells.append("-" if s is None else
                         f"{_ms(s)}{calls}, {100 * s / total:.0f} %, {s / r['floor_s']:.2f} fl")
        body.append(f"| {label} | " + " | ".join(cells) + " |")
    totals = " | ".join(f"{_ms(sum(r[f'{key}_parts'].values()))}" for r in rows)
    body.append(f"| **total** | {totals} |")
    return "\n".join([head, rule, *body])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--configs", nargs="+", default=list(DEFAULT_CONFIGS),
                   help="n_tets,order pairs")
    p.add_argument("--formulation", default="standard", choices=["standard", "averaged"])
    p.add_argument("--repeats", type=int, default=7, help="best of, for the floor and (a)")
    p.add_argument("--newton-repeats", type=int, default=2)
    p.add_argument("--one", help=argparse.SUPPRESS)
    p.add_argument("--json", help="also write the rows to this file")
    args = p.parse_args()
    if args.one:
        n, order = map(int, args.one.split(","))
        newton_repeats = args.newton_repeats if n * order**3 <= 200_000 else 1
        row = one(n, order, args.formulation, args.repeats, newton_repeats)
        print(json.dumps(row))
        return
    rows = []
    for config in args.configs:
        cmd = [sys.executable, __file__, "--one", config, "--formulation", args.formulation,
               "--repeats", str(args.repeats), "--newton-repeats", str(args.newton_repeats)]
        t0 = time.perf_counter()
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode != 0:
            print(f"{config}: failed\n{done.stderr[-3000:]}", file=sys.stderr)
            continue
        rows.append(json.loads(done.stdout.strip().splitlines()[-1]))
        print(f"{config}: {time.perf_counter() - t0:.0f} s, peak {rows[-1]['peak_mib']:,.0f} "
              f"MiB", file=sys.stderr, flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1) + "\n")
    print(summary_table(rows))
    print()
    print(newton_table(rows))
    print()
    print(parts_table(rows, "a", "(a) one-iterate step"))
    print()
    print(parts_table(rows, "b", "(b) modified Newton"))
    print()
    print(parts_table(rows, "c", "(c) full Newton"))


if __name__ == "__main__":
    main()
