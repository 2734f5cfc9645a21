"""Runs side by side, as a study runs them: with and without the cores shared out.

    python benchmarks/study_threads.py cases/dcb.yaml [--runs 2] [--rounds 2]

Each round starts ``--runs`` copies of ``fem-frac run CASE`` at once, twice: with the
environment as it is (each run's PARDISO and element-wise work take every core) and with
``OMP_NUM_THREADS = cores // runs``, what ``fem-frac study`` now gives each run
(``fem_frac.app.study.runs.run_threads``); the two alternate. Prints, per try, the wall
time until the last run ended and the runs' CPU time (user + system, summed). OpenBLAS
runs on one thread in both, as the ``fem-frac`` command sets it.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time


def side_by_side(case: str, runs: int, threads: int | None) -> tuple[float, float]:
    """``(wall s, CPU s)`` of ``runs`` copies of the case started at once."""
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # as an installation runs: modules cached
    env.pop("OMP_NUM_THREADS", None)
    if threads is not None:
        env["OMP_NUM_THREADS"] = str(threads)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        procs = [subprocess.Popen([sys.executable, "-m", "fem_frac", "run", case, "-o",
                                   os.path.join(out, str(k)), "-q"], env=env,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                 for k in range(runs)]
        codes = [p.wait() for p in procs]
        wall = time.perf_counter() - start
    if any(codes):
        raise SystemExit(f"{case}: exit codes {codes}")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("case")
    p.add_argument("--runs", type=int, default=2, help="copies started at once")
    p.add_argument("--rounds", type=int, default=2)
    args = p.parse_args()
    cores = len(os.sched_getaffinity(0))
    shared = max(1, cores // args.runs)
    print(f"{args.case}: {args.runs} runs at once on {cores} cores")
    for r in range(args.rounds):
        for label, threads in (("every core each", None), (f"{shared} thread(s) each", shared)):
            wall, cpu = side_by_side(args.case, args.runs, threads)
            print(f"round {r + 1}, {label}: wall {wall:.2f} s, CPU {cpu:.2f} s")


if __name__ == "__main__":
    main()
