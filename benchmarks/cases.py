"""Every shipped case against its floor: process CPU time, time per stage, multiple of the ideal.

    python benchmarks/cases.py                          # cases/*.yaml, 3 runs each
    python benchmarks/cases.py --cases 'cases/notched*.yaml' --repeats 5 --json out.json

For each case, in fresh subprocesses:

- **runs**: ``python -m fem_frac run CASE -o TMP -q``, ``--repeats`` times, round-robin over
  the cases (a change of load on the machine falls on all of them alike). CPU is the child's
  user + system time (``getrusage(RUSAGE_CHILDREN)``; PARDISO's threads count), wall the
  elapsed time; the table gives the minimum and the spread (max - min).
- **work**: from the first run's history.csv, the equilibrium iterations of every step summed
  (``iterations``; an explicit step counts 1 per stable substep) and the insertion batches
  (``fracture_passes``); from its summary.json the wall seconds of each stage, as the run's
  own timer books them (``wall_time_s``: mesh, space, loads, assemble, factorize, equilibrium,
  fracture, fragments, element contact, output, ...).
- **floor**: the case prepared and started in-process (its mesh, its elastic factorization);
  best of 5 from cold caches (a 64 MiB buffer written first) of one back-solve with the
  cached factor (explicit: the product with the inverse lumped mass) plus one pass over the
  quadrature points: strain ``B u``, ``law.update``, internal force ``B^T sigma dx``. This is
  the floor of DESIGN §7 and of benchmarks/fracture.py and plastic_step.py. One such process
  in each round, before the round's runs; the table gives the least and the spread (max -
  min) of the rounds' floors.

**ideal** = iterations x floor; the table reports CPU / ideal (the least CPU time over the
least floor, which may come from different rounds), each round's own ratio (its run's CPU
time over its floor: the machine's speed drifts between rounds minutes apart, by up to 2x,
and moves a round's floor and runs alike), and, for the stages that take the most wall
time, their seconds in units of the ideal and their share of the run; and the start-up, the
CPU seconds a run's process spent before its run began (Python's start, the imports,
reading the case: summary.json's ``cpu_time_s.before_run``, the least over the runs), part of
its CPU time, in units of the ideal too. A case whose body
turns rigid at once (``whole_body: true``) has no finite-element work and no ratio.
"""

from __future__ import annotations

import argparse
import csv
import gc
import glob
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# the floor's process runs numpy's OpenBLAS as the fem-frac command does (one thread, unless
# the environment says otherwise: fem_frac/app/cli.py), set before numpy loads it
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
FLUSH = np.zeros(0)


def best(fn, repeats: int = 5) -> float:
    """Best wall seconds of ``repeats`` calls of ``fn``, each from cold caches."""
    global FLUSH
    if FLUSH.size == 0:
        FLUSH = np.zeros(64 * 2**20 // 8)
    times = []
    for _ in range(repeats):
        FLUSH += 1.0
        gc.collect()
        gc.disable()
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
        gc.enable()
    return min(times)


def floor(case_path: str) -> dict:
    """The floor of ``case_path`` (module docstring), measured in this process."""
    from fem_frac.app.driver import prepare, start, whole_body
    from fem_frac.config.loader import load_case
    from fem_frac.solve.stepping import ImplicitStepper
    from fem_frac.timing import StageTimer

    path = Path(case_path)
    case, _ = load_case(path)
    setup = prepare(case, path.parent, StageTimer())
    disc = setup.disc
    out = {"tets": int(disc.mesh.n_tets), "dofs": int(disc.space.n_dofs)}
    if whole_body(case):
        return out
    world, _ = start(setup, StageTimer())
    st, ops, law = disc.stepper, disc.ops, disc.law
    rng = np.random.default_rng(0)
    if isinstance(st, ImplicitStepper):
        factor = st.elastic_factor()
        rhs = rng.standard_normal(len(disc.constrained.free))
        out["back-solve"] = best(lambda: factor.solve(rhs))
    else:
        force = rng.standard_normal(disc.space.n_dofs)
        out["back-solve"] = best(lambda: force * st.inverse_mass)
    op = ops.strain_operator
    state = world.body.state
    u = 1e-9 * rng.standard_normal(disc.space.n_dofs)
    strain = op.strain(u)
    stress, _, _ = law.update(strain, state.plastic)
    out["strain"] = best(lambda: op.strain(u))
    out["law.update"] = best(lambda: law.update(strain, state.plastic))
    out["internal force"] = best(lambda: op.internal_force(stress))
    out["floor"] = sum(out[k] for k in ("back-solve", "strain", "law.update", "internal force"))
    return out


# as a user's installation runs: Python may cache the compiled modules (a shell that sets
# PYTHONDONTWRITEBYTECODE makes every run compile fem-frac's ~100 modules, 0.12 CPU s; the
# first of the repeats writes them, the minimum is taken)
def child_env() -> dict:
    return {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def child(args: list[str]) -> tuple[float, float, subprocess.CompletedProcess]:
    """``(cpu, wall, result)`` of one subprocess."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    result = subprocess.run(args, capture_output=True, text=True, cwd=ROOT, env=child_env())
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall, result


def work(out: Path) -> dict:
    """Iterations, batches and the stages' wall seconds of a finished run."""
    with open(out / "history.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    summary = json.loads((out / "summary.json").read_text())
    column = lambda k: sum(int(float(r[k])) for r in rows if r.get(k) not in (None, ""))  # noqa: E731
    return {"steps": len(rows) - 1, "iterations": column("iterations"),
            "batches": column("fracture_passes") if "fracture_passes" in rows[0] else 0,
            "stages": summary.get("wall_time_s", {}), "status": summary.get("status")}


def before_run(out: Path) -> float | None:
    """The CPU seconds the run's process spent before the run began (Python's start, the
    imports, reading the case: summary.json's ``cpu_time_s``), ``None`` where not given."""
    summary = json.loads((out / "summary.json").read_text())
    return summary.get("cpu_time_s", {}).get("before_run")


def measure_floor(row: dict, c: str) -> None:
    """One more floor of case ``c`` into ``row`` (its ``floors``; the parts of the least)."""
    cpu, wall, res = child([sys.executable, __file__, "--floor", c])
    if res.returncode != 0:
        row["error"] = (res.stderr.strip().splitlines() or ["?"])[-1]
        return
    parts = json.loads(res.stdout.strip().splitlines()[-1])
    row.setdefault("floors", []).append(parts["floor"])
    if parts["floor"] <= min(row["floors"]):
        row.update(parts)
    print(f"floor  {c}: {parts['floor'] * 1e3:.2f} ms", flush=True)


def measure(cases: list[str], repeats: int) -> list[dict]:
    rows = {c: {"case": c, "cpu": [], "wall": []} for c in cases}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(repeats):
            # a floor in each round, as the runs (the machine's speed drifts over minutes)
            for c in cases:
                if "error" not in rows[c]:
                    measure_floor(rows[c], c)
            for c in cases:
                if "error" in rows[c]:
                    continue
                out = Path(tmp) / f"{Path(c).stem}_{k}"
                cpu, wall, res = child([sys.executable, "-m", "fem_frac", "run", c, "-o",
                                        str(out), "-q"])
                if res.returncode != 0:
                    rows[c]["error"] = (res.stderr.strip().splitlines() or ["?"])[-1]
                    continue
                rows[c]["cpu"].append(cpu)
                rows[c]["wall"].append(wall)
                rows[c].setdefault("before_run", []).append(before_run(out))
                if k == 0:
                    rows[c].update(work(out))
                print(f"run {k + 1}/{repeats}  {c}: {cpu:.2f} CPU-s, {wall:.2f} s", flush=True)
    return list(rows.values())


# summary.json's books that hold others ("steps": the step loop) or are booked inside
# another ("fracture rebuild" inside "fracture", "fragments rebuild" inside "fragments")
NESTED = {"steps", "total", "fracture rebuild", "fragments rebuild"}


def where(stages: dict, ideal: float | None, top: int = 4) -> str:
    """The ``top`` stages by wall time: ``name s (x ideal, share of the total)``."""
    total = stages.get("total", 0.0)
    parts = sorted(((v, k) for k, v in stages.items() if k not in NESTED), reverse=True)
    out = []
    for v, k in parts[:top]:
        times = f"{v / ideal:.1f}x, " if ideal else ""
        out.append(f"{k} {v:.2f} ({times}{100 * v / total:.0f} %)" if total else f"{k} {v:.2f}")
    for k in ("fracture rebuild", "fragments rebuild"):
        if k in stages and stages[k] > 0.05 * total:
            out.append(f"of which {k} {stages[k]:.2f}")
    return "; ".join(out)


def _floor_cell(r: dict) -> str:
    """The least floor in ms, with the spread over the rounds where there are several."""
    fl, floors = r.get("floor"), r.get("floors", [])
    if not fl:
        return "-"
    spread = f" ({1e3 * (max(floors) - min(floors)):.2f})" if len(floors) > 1 else ""
    return f"{fl * 1e3:.2f}{spread}"


def _rounds_cell(r: dict) -> str:
    """Each round's CPU / ideal (its run's CPU time over that round's floor): the least and
    the largest, where every round has both."""
    floors, cpu = r.get("floors", []), r.get("cpu", [])
    if not r.get("iterations") or len(floors) != len(cpu) or len(cpu) < 2:
        return "-"
    ratios = [c / (r["iterations"] * f) for c, f in zip(cpu, floors, strict=True)]
    return f"{min(ratios):.0f}-{max(ratios):.0f}"


def _start_cell(r: dict, ideal: float | None) -> str:
    """The least CPU time the runs' processes spent before the run (start-up), in seconds
    and in units of the ideal."""
    start = [b for b in r.get("before_run", []) if b is not None]
    if not start:
        return "-"
    return f"{min(start):.2f}" + (f" ({min(start) / ideal:.1f}x)" if ideal else "")


def table(rows: list[dict]) -> str:
    head = ("| case | tets | dofs | steps | iterations | batches | floor ms min (spread) | ideal s "
            "| CPU s min (spread) | wall s min | CPU / ideal | by round | of which start-up: "
            "CPU s (x ideal) | where the wall time goes: stage s (x ideal, share) |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        name = Path(r["case"]).stem
        if "error" in r or not r["cpu"]:
            lines.append(f"| {name} | error: {r.get('error', '?')[:80]} |")
            continue
        cpu, wall = np.array(r["cpu"]), np.array(r["wall"])
        fl = r.get("floor")
        ideal = r["iterations"] * fl if fl and r["iterations"] else None
        cells = [name, f"{r['tets']:,}", f"{r['dofs']:,}", str(r["steps"]),
                 f"{r['iterations']:,}", str(r["batches"]),
                 _floor_cell(r), f"{ideal:.3f}" if ideal else "-",
                 f"{cpu.min():.2f} ({np.ptp(cpu):.2f})", f"{wall.min():.2f}",
                 f"**{cpu.min() / ideal:.0f}**" if ideal else "-", _rounds_cell(r),
                 _start_cell(r, ideal), where(r.get("stages", {}), ideal)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", nargs="*", default=["cases/*.yaml"])
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--json", type=Path)
    p.add_argument("--floor", help=argparse.SUPPRESS)
    a = p.parse_args()
    if a.floor:
        print(json.dumps(floor(a.floor)))
        return
    cases = sorted({os.path.relpath(f, ROOT) for g in a.cases
                    for f in glob.glob(str(ROOT / g) if not os.path.isabs(g) else g)})
    load = os.getloadavg()
    rows = measure(cases, a.repeats)
    if a.json:
        a.json.write_text(json.dumps(rows, indent=1))
    print(f"\nload average before: {load[0]:.2f}; after: {os.getloadavg()[0]:.2f}")
    print(table(rows))


if __name__ == "__main__":
    main()
