"""Whole runs with numpy's OpenBLAS on one thread (the ``fem-frac`` default) against as many
threads as cores: process CPU time and wall time.

    python benchmarks/blas_threads.py                       # five cases, 3 runs each
    python benchmarks/blas_threads.py --cases cases/dcb.yaml --repeats 5

Each run is ``python -m fem_frac run CASE -o TMP -q`` in a fresh process with
``OPENBLAS_NUM_THREADS`` set to 1 or to the number of cores, the two alternating, round-robin
over the cases. CPU is user + system (``getrusage(RUSAGE_CHILDREN)``, every thread's), wall
the elapsed time; min and max of the runs.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from cases import ROOT, child  # noqa: E402

CASES = ["cases/notched_beam.yaml", "cases/impact_plate.yaml", "cases/dcb.yaml",
         "cases/hollow_sphere_plastic.yaml", "cases/breaking_beam.yaml"]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", nargs="+", default=CASES)
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args()
    threads = {"1": "1", "cores": str(os.cpu_count() or 1)}
    rows: dict[tuple[str, str], list[tuple[float, float]]] = {}
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(a.repeats):
            for case in a.cases:
                for name, value in threads.items():
                    os.environ["OPENBLAS_NUM_THREADS"] = value
                    out = Path(tmp) / f"{Path(case).stem}_{name}_{k}"
                    cpu, wall, res = child([sys.executable, "-m", "fem_frac", "run", case,
                                            "-o", str(out), "-q"])
                    if res.returncode != 0:
                        sys.exit(f"{case}: {res.stderr.strip().splitlines()[-1:]}")
                    rows.setdefault((case, name), []).append((cpu, wall))
                    print(f"run {k + 1}/{a.repeats} {case} OpenBLAS threads {value}: "
                          f"{cpu:.2f} CPU-s, {wall:.2f} s", flush=True)
    print(f"\n{os.cpu_count()} cores; load average before {load:.2f}, after "
          f"{os.getloadavg()[0]:.2f}; run from {ROOT}\n")
    print("| case | OpenBLAS threads | CPU s min-max | wall s min-max |")
    print("|---|---|---|---|")
    for (case, name), runs in rows.items():
        cpu, wall = [r[0] for r in runs], [r[1] for r in runs]
        print(f"| {Path(case).stem} | {threads[name]} | {min(cpu):.2f}-{max(cpu):.2f} | "
              f"{min(wall):.2f}-{max(wall):.2f} |")


if __name__ == "__main__":
    main()
