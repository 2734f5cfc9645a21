"""PETSc (CG + GAMG with the rigid-body modes) against PARDISO on P1 elasticity: a ~1M-tet
static case through ``fem-frac run``, the solver alone at a few sizes on one and two MPI
ranks, with CPU time and peak memory per rank. Needs the environment of
scripts/petsc-env.sh; the numbers are recorded in docs/performance.md and docs/solvers.md.

    python benchmarks/petsc.py sizes --m 10 16 20 25 32      # solver alone, 1 rank each
    python benchmarks/petsc.py ranks --m 25                  # 200k unknowns, 1 and 2 ranks
    python benchmarks/petsc.py large --tets 1000000          # fem-frac run, PETSc and PARDISO

``sizes`` and ``ranks``: a 4 x 1 x 1 box of ``24 m^3`` structured tets (scikit-fem's
``MeshTet.init_tensor``), clamped at x = 0, a uniform load along z; each run in its own
process (``mpiexec -n R`` for R ranks). ``large``: the case below, meshed by gmsh, through
the whole command (output included). A run is killed when its processes together hold
more than ``--limit-gib`` (default 10), and reported so.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LENGTHS = (4.0, 1.0, 1.0)
POLL_S = 0.2
UNKNOWNS = re.compile(r"^factorize .*, ([\d,]+) unknowns")
MPIEXEC = ["mpiexec", "--allow-run-as-root", "--oversubscribe"]
# gmsh's unstructured tets: n_tets ~ TETS_PER_H3 * volume / h^3 (benchmarks/pipeline.py)
TETS_PER_H3 = 4.5
LARGE_CASE = """\
title: P1 box for the PETSc benchmark
units: SI
mesh:
  geometry: {{type: box, lengths: [4.0, 1.0, 1.0]}}
  element_size: {h}
  order: 1
material: {{youngs_modulus: 210e9, poissons_ratio: 0.3}}
boundary_conditions:
  - {{type: fixed, boundary: xmin}}
  - {{type: traction, boundary: xmax, traction: [0, 0, -1e6]}}
analysis:
  type: static
  linear_solver: {solver}
  petsc: {{options: {{ksp_converged_reason: true}}}}
"""


# ---------------------------------------------------------------- one solve (child)

def system(m: int):
    """Stiffness, free dofs and node coordinates of the clamped box of 24 m^3 P1 tets."""
    import numpy as np
    from skfem import Basis, ElementTetP1, ElementVector, MeshTet, asm
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    axes = [np.linspace(0.0, length, round(length * m) + 1) for length in LENGTHS]
    mesh = MeshTet.init_tensor(*axes)
    basis = Basis(mesh, ElementVector(ElementTetP1()), intorder=0)
    k = asm(linear_elasticity(*lame_parameters(210e9, 0.3)), basis).tocsr()
    fixed = basis.get_dofs(lambda x: x[0] < 1e-12).all()
    free = np.setdiff1d(np.arange(k.shape[0]), fixed)
    return k, free, mesh.p.T.copy(), mesh.t.shape[1]


def child(args) -> int:
    """Under ``fem_frac.solve.ranks.main``: rank 0 assembles and solves, the others serve.
    Each rank prints one JSON line with its CPU seconds and peak RSS (rank 0: also the CPU
    seconds from the setup to the end of the second solve; the other ranks do nothing but
    the solver's work)."""
    import resource

    from fem_frac.solve import ranks

    cpu0 = time.process_time()
    row: dict = {}

    def run(_argv) -> int:
        import numpy as np

        from fem_frac.solve.linalg import factorize
        from fem_frac.solve.petsc import PetscFactorization, Settings

        t = time.perf_counter()
        k, free, points, tets = system(args.m)
        row.update(tets=tets, n=len(free), assemble_s=time.perf_counter() - t)
        b = np.zeros(k.shape[0])
        b[2::3] = -1.0 / len(points)  # a uniform load along z
        b = b[free]
        cpu = time.process_time()
        t = time.perf_counter()
        if args.method == "petsc":
            f = PetscFactorization(k, free, points, Settings(), ranks.active())
        else:
            f = factorize(k[free][:, free], args.method)
        row["setup_s"] = time.perf_counter() - t
        t = time.perf_counter()
        x = f.solve(b)
        row["solve_s"] = time.perf_counter() - t
        t = time.perf_counter()
        f.solve(b)
        row["again_s"] = time.perf_counter() - t  # with the factor / preconditioner kept
        row["solver_cpu_s"] = time.process_time() - cpu
        row["iterations"] = getattr(f, "iterations", [None])[0]
        r = k[free][:, free] @ x - b
        row["residual"] = float(np.linalg.norm(r) / np.linalg.norm(b))
        return 0

    code = ranks.main(run, None)
    comm_rank = int(os.environ.get("OMPI_COMM_WORLD_RANK", "0"))
    row.update(rank=comm_rank, cpu_s=time.process_time() - cpu0,
               peak_mib=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0)
    print("ROW " + json.dumps(row), flush=True)
    return code


# ---------------------------------------------------------------- running children

def tree_rss_mib(pid: int) -> float:
    """Resident memory of a process and all its descendants, in MiB (Linux /proc)."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(entry.name))
    total, stack = 0.0, [pid]
    while stack:
        p = stack.pop()
        stack.extend(children.get(p, []))
        try:
            for line in Path(f"/proc/{p}/status").read_text().splitlines():
                if line.startswith("VmRSS:"):
                    total += int(line.split()[1]) / 1024.0
        except OSError:
            pass
    return total


def watched(command: list[str], limit_mib: float, cwd=None) -> dict:
    """Run ``command``; kill its process group past ``limit_mib`` resident. Returns the
    output, wall seconds, the most memory seen and how it ended."""
    start = time.perf_counter()
    with tempfile.TemporaryFile("w+") as out:
        proc = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT, text=True,
                                cwd=cwd, start_new_session=True)
        most, killed = 0.0, False
        while proc.poll() is None:
            rss = tree_rss_mib(proc.pid)
            most = max(most, rss)
            if rss > limit_mib:
                os.killpg(proc.pid, signal.SIGKILL)
                killed = True
                proc.wait()
                break
            time.sleep(POLL_S)
        out.seek(0)
        text = out.read()
    return {"text": text, "wall_s": time.perf_counter() - start, "tree_mib": most,
            "killed": killed, "code": proc.returncode}


def solver_rows(m: int, method: str, n_ranks: int, limit_mib: float) -> list[dict]:
    command = [sys.executable, __file__, "child", "--m", str(m), "--method", method]
    if n_ranks > 1:
        command = [*MPIEXEC, "-n", str(n_ranks), *command]
    done = watched(command, limit_mib)
    rows = [json.loads(line[4:]) for line in done["text"].splitlines()
            if line.startswith("ROW ")]
    if done["code"] != 0 or not rows:
        tail = done["text"].strip().splitlines()[-1:] or [""]
        note = f"killed past {limit_mib / 1024:.0f} GiB" if done["killed"] else tail[0][:80]
        return [{"rank": 0, "note": note, "tree_mib": done["tree_mib"]}]
    return sorted(rows, key=lambda r: r["rank"])


def fmt(value, spec: str) -> str:
    return "" if value is None else format(value, spec)


def sizes(args) -> None:
    print("| tets | unknowns | method | setup s | solve s | again s | iterations | solver CPU s "
          "| peak MiB | residual | note |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for m in args.m:
        for method in args.methods:
            r = solver_rows(m, method, 1, args.limit_gib * 1024)[0]
            print(f"| {fmt(r.get('tets'), ',')} | {fmt(r.get('n'), ',')} | {method} | "
                  f"{fmt(r.get('setup_s'), '.2f')} | {fmt(r.get('solve_s'), '.2f')} | "
                  f"{fmt(r.get('again_s'), '.3f')} | {fmt(r.get('iterations'), 'd')} | "
                  f"{fmt(r.get('solver_cpu_s'), '.1f')} | {fmt(r.get('peak_mib'), ',.0f')} | "
                  f"{fmt(r.get('residual'), '.1e')} | {r.get('note', '')} |", flush=True)


def by_rank(args) -> None:
    print("| unknowns | ranks | rank | setup s | solve s | again s | iterations | solver CPU s "
          "| process CPU s | peak MiB | note |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for m in args.m:
        for n_ranks in args.ranks:
            rows = solver_rows(m, "petsc", n_ranks, args.limit_gib * 1024)
            n = rows[0].get("n")
            for r in rows:
                print(f"| {fmt(n, ',')} | {n_ranks} | {r['rank']} | "
                      f"{fmt(r.get('setup_s'), '.2f')} | {fmt(r.get('solve_s'), '.2f')} | "
                      f"{fmt(r.get('again_s'), '.2f')} | {fmt(r.get('iterations'), 'd')} | "
                      f"{fmt(r.get('solver_cpu_s', r.get('cpu_s')), '.1f')} | "
                      f"{fmt(r.get('cpu_s'), '.1f')} | {fmt(r.get('peak_mib'), ',.0f')} | "
                      f"{r.get('note', '')} |", flush=True)


def large(args) -> None:
    """``fem-frac run`` of the box at ~``--tets`` P1 tets, with PETSc and with PARDISO."""
    h = (TETS_PER_H3 * LENGTHS[0] * LENGTHS[1] * LENGTHS[2] / args.tets) ** (1 / 3)
    print("| solver | tets | unknowns | mesh s | assemble s | setup s | solve s | total s | "
          "iterations | peak MiB | note |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for solver in args.solvers:
            case = Path(tmp) / f"box_{solver}.yaml"
            case.write_text(LARGE_CASE.format(h=f"{h:.5f}", solver=solver))
            command = [sys.executable, "-m", "fem_frac", "run", str(case), "-o",
                       str(Path(tmp) / solver), "--allow-large"]
            done = watched(command, args.limit_gib * 1024)
            text = done["text"]
            summary_path = Path(tmp) / solver / "summary.json"
            summary = json.loads(summary_path.read_text()) if summary_path.exists() else {}
            wall = summary.get("wall_time_s", {})
            its = [int(line.rsplit(" ", 1)[1]) for line in text.splitlines()
                   if "solve converged" in line]
            tets = next((line.split()[1] for line in text.splitlines()
                         if line.startswith("mesh ")), "")
            unknowns = next((m.group(1) for m in map(UNKNOWNS.search, text.splitlines())
                             if m), "")
            note = (f"killed at {done['tree_mib'] / 1024:.1f} GiB (limit "
                    f"{args.limit_gib:g} GiB) during {_last_stage(text)}" if done["killed"]
                    else "" if done["code"] == 0 else text.strip().splitlines()[-1][:100])
            status = summary.get("status", "")
            print(f"| {solver} | {tets} | {unknowns} | {fmt(wall.get('mesh'), '.1f')} | "
                  f"{fmt(wall.get('assemble'), '.1f')} | {fmt(wall.get('factorize'), '.1f')} | "
                  f"{fmt(wall.get('equilibrium'), '.1f')} | {fmt(wall.get('total'), '.1f')} | "
                  f"{'+'.join(map(str, its))} | {done['tree_mib']:,.0f} | {note or status} |",
                  flush=True)


def _last_stage(text: str) -> str:
    lines = [line.split()[0] for line in text.splitlines() if line.strip()]
    return {"space": "assembly or factorization", "factorize": "the solve"}.get(
        lines[-1] if lines else "", lines[-1] if lines else "start")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    c = sub.add_parser("child")
    c.add_argument("--m", type=int, required=True)
    c.add_argument("--method", default="petsc")
    s = sub.add_parser("sizes")
    s.add_argument("--m", type=int, nargs="+", default=[10, 16, 20, 25, 32])
    s.add_argument("--methods", nargs="+", default=["pardiso", "petsc"])
    r = sub.add_parser("ranks")
    r.add_argument("--m", type=int, nargs="+", default=[25])
    r.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    g = sub.add_parser("large")
    g.add_argument("--tets", type=float, default=1e6)
    g.add_argument("--solvers", nargs="+", default=["petsc", "pardiso"])
    for p in (s, r, g):
        p.add_argument("--limit-gib", type=float, default=10.0)
    args = parser.parse_args()
    if args.command == "child":
        sys.exit(child(args))
    print(f"Machine: {os.cpu_count()} cores, Python {platform.python_version()}", flush=True)
    {"sizes": sizes, "ranks": by_rank, "large": large}[args.command](args)


if __name__ == "__main__":
    main()
