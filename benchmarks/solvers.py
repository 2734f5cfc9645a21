"""Sparse direct solvers on clamped elasticity systems: factorization, back-solve, memory.

Builds a 4 x 1 x 1 box of ~N tets (scikit-fem's structured ``MeshTet.init_tensor``), P1 or P2
vector elements, isotropic linear elasticity, clamped at x = 0, and measures each backend of
``fem_frac.solve.linalg`` (plus ``cholespy`` when installed, as a candidate) in a fresh subprocess,
so that its peak memory (VmHWM, which sees MKL's and CHOLMOD's allocations) is its own.
Prints a markdown table; the numbers are recorded in docs/solvers.md.

    python benchmarks/solvers.py --sizes 10000 100000 --orders 1 2
    python benchmarks/solvers.py --sizes 10000 --orders 1 --methods pardiso superlu
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

LENGTHS = (4.0, 1.0, 1.0)
LIMIT_S = 300.0  # skip a run predicted (or seen) to take longer than this
LIMIT_MIB = 10 * 1024  # ... or to hold more memory than this
POLL_S = 0.2


def status_mib(field: str, pid: str = "self") -> float:
    """A memory figure (VmRSS, VmHWM) of a process from /proc, in MiB (Linux only)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


# ---------------------------------------------------------------- child: build the system

def build(n_tets: int, order: int, path: str) -> dict:
    """Assemble and condense the clamped system, save it to ``path`` (.npz). Returns facts."""
    import numpy as np
    import scipy.sparse as sp
    from skfem import Basis, ElementTetP1, ElementTetP2, ElementVector, MeshTet, asm, condense
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    start = time.perf_counter()
    m = max(1, round((n_tets / (6 * 4)) ** (1 / 3)))  # init_tensor: 6 tets per cube
    axes = [np.linspace(0.0, length, round(length * m) + 1) for length in LENGTHS]
    mesh = MeshTet.init_tensor(*axes)
    element = ElementVector(ElementTetP1() if order == 1 else ElementTetP2())
    basis = Basis(mesh, element, intorder=2 * (order - 1))  # exact for the strain products
    k = asm(linear_elasticity(*lame_parameters(210e9, 0.3)), basis)
    clamped = basis.get_dofs(lambda x: x[0] < 1e-12).all()
    a = condense(k, D=clamped, expand=False).tocsr()
    sp.save_npz(path, a, compressed=False)
    return {"tets": mesh.t.shape[1], "n": a.shape[0], "nnz": a.nnz,
            "assemble_s": time.perf_counter() - start}


# ---------------------------------------------------------------- child: one backend

def _cholespy(a):
    """Candidate not kept in fem_frac.solve.linalg: cholespy's CPU Cholesky (bundled CHOLMOD)."""
    import numpy as np
    from cholespy import CholeskySolverD, MatrixType

    start = time.perf_counter()
    lower = a.tocoo()  # COO of the full matrix
    solver = CholeskySolverD(a.shape[0], lower.row.astype(np.int32), lower.col.astype(np.int32),
                             lower.data, MatrixType.COO)

    def solve(b):
        x = np.empty_like(b)
        solver.solve(np.ascontiguousarray(b), x)
        return x

    return solve, time.perf_counter() - start


def measure(method: str, path: str, repeats: int) -> dict:
    """Factorize the saved matrix with ``method`` and time ``repeats`` back-solves."""
    import numpy as np
    import scipy.sparse as sp

    from fem_frac.solve.linalg import factorize

    a = sp.load_npz(path).tocsr()
    b = np.random.default_rng(1).standard_normal(a.shape[0])
    rss_before = status_mib("VmRSS")
    if method == "cholespy":
        solve, factor_s = _cholespy(a)
    else:
        factorization = factorize(a, method)
        solve, factor_s = factorization.solve, factorization.factor_time
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        x = solve(b)
        times.append(time.perf_counter() - start)
    residual = float(np.linalg.norm(a @ x - b) / np.linalg.norm(b))
    return {"factor_s": factor_s, "solve_ms": 1e3 * float(np.median(times)),
            "residual": residual, "factor_mib": status_mib("VmHWM") - rss_before,
            "peak_mib": status_mib("VmHWM")}


# ---------------------------------------------------------------- parent

def run_child(args: list[str], limit_s: float) -> tuple[dict | None, str]:
    """Run this script as a child; kill it past ``limit_s`` or LIMIT_MIB resident memory."""
    cmd = [sys.executable, __file__, *args]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    start = time.perf_counter()
    while proc.poll() is None:
        elapsed = time.perf_counter() - start
        try:
            rss = status_mib("VmRSS", str(proc.pid))
        except (FileNotFoundError, ProcessLookupError):
            rss = 0.0
        if elapsed > limit_s or rss > LIMIT_MIB:
            proc.kill()
            proc.wait()
            why = f"> {limit_s:.0f} s" if elapsed > limit_s else f"> {LIMIT_MIB / 1024:.0f} GiB"
            return None, f"stopped ({why})"
        time.sleep(POLL_S)
    out, err = proc.communicate()
    if proc.returncode != 0:
        return None, "failed: " + (err.strip().splitlines() or ["?"])[-1][:120]
    return json.loads(out.strip().splitlines()[-1]), ""


def predict(history: list[dict], n: int) -> tuple[float, float]:
    """Time and memory extrapolated from the largest earlier run of the same backend.

    3D nested-dissection factorization: work ~ n^2, factor size ~ n^(4/3).
    """
    if not history:
        return 0.0, 0.0
    ref = max(history, key=lambda r: r["n"])
    ratio = n / ref["n"]
    return ref["factor_s"] * ratio**2, ref["factor_mib"] * ratio ** (4 / 3)


def candidate_methods() -> list[str]:
    from fem_frac.solve.linalg import available_methods

    methods = available_methods()
    try:
        import cholespy  # noqa: F401

        methods.append("cholespy")
    except ImportError:
        pass
    return methods


def machine() -> str:
    """One line: CPU model, cores, memory, library versions."""
    import importlib.metadata as md

    cpu = next((line.split(":", 1)[1].strip() for line in
                Path("/proc/cpuinfo").read_text().splitlines() if line.startswith("model name")),
               platform.processor())
    ram = _mem_total_gib()
    versions = []
    for dist in ("numpy", "scipy", "scikit-fem", "pypardiso", "mkl", "scikit-sparse", "cholespy"):
        try:
            versions.append(f"{dist} {md.version(dist)}")
        except md.PackageNotFoundError:
            pass
    return (f"{cpu}, {os.cpu_count()} cores, {ram:.0f} GiB RAM, Python "
            f"{platform.python_version()}; " + ", ".join(versions))


def _mem_total_gib() -> float:
    for line in Path("/proc/meminfo").read_text().splitlines():
        if line.startswith("MemTotal:"):
            return int(line.split()[1]) / 1024**2
    return float("nan")


COLUMNS = [("tets", "{:,}"), ("order", "P{}"), ("n", "{:,}"), ("nnz", "{:,}"),
           ("method", "{}"), ("factor_s", "{:.2f}"), ("solve_ms", "{:.1f}"),
           ("residual", "{:.1e}"), ("factor_mib", "{:,.0f}"), ("note", "{}")]
HEADERS = ["tets", "order", "unknowns", "nnz(A)", "method", "factorize s", "back-solve ms",
           "residual", "factor MiB", "note"]


def table(rows: list[dict]) -> str:
    lines = ["| " + " | ".join(HEADERS) + " |", "|" + "---|" * len(HEADERS)]
    for row in rows:
        cells = [fmt.format(row[key]) if row.get(key) is not None else "" for key, fmt in COLUMNS]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def run_all(sizes: list[int], orders: list[int], methods: list[str], repeats: int,
            workdir: str) -> list[dict]:
    rows: list[dict] = []
    history: dict[str, list[dict]] = {m: [] for m in methods}
    for size in sorted(sizes):
        for order in sorted(orders):
            path = os.path.join(workdir, f"a_{size}_{order}.npz")
            system, note = run_child(["--build", str(size), str(order), path], 3 * LIMIT_S)
            if system is None:
                rows.append({"tets": size, "order": order, "method": "-", "note": note})
                continue
            print(f"# built {system}", file=sys.stderr, flush=True)
            for method in methods:
                row = {**system, "order": order, "method": method}
                t, mib = predict(history[method], system["n"])
                if t > LIMIT_S or mib > LIMIT_MIB:
                    row["note"] = f"skipped (predicted ~{t:.0f} s, ~{mib / 1024:.1f} GiB)"
                else:
                    result, row["note"] = run_child(
                        ["--measure", method, path, str(repeats)], LIMIT_S)
                    if result:
                        row.update(result)
                        history[method].append(row)
                print(f"# {row}", file=sys.stderr, flush=True)
                rows.append(row)
            os.remove(path)
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000],
                        help="approximate numbers of tets")
    parser.add_argument("--orders", type=int, nargs="+", default=[1, 2], choices=[1, 2])
    parser.add_argument("--methods", nargs="+", help="backends (default: all available)")
    parser.add_argument("--repeats", type=int, default=7, help="back-solves timed (median)")
    parser.add_argument("--build", nargs=3, help=argparse.SUPPRESS)
    parser.add_argument("--measure", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.build:
        print(json.dumps(build(int(args.build[0]), int(args.build[1]), args.build[2])))
        return
    if args.measure:
        print(json.dumps(measure(args.measure[0], args.measure[1], int(args.measure[2]))))
        return
    methods = args.methods or candidate_methods()
    print(machine())
    with tempfile.TemporaryDirectory() as workdir:
        rows = run_all(args.sizes, args.orders, methods, args.repeats, workdir)
    print()
    print(table(rows))


if __name__ == "__main__":
    main()
