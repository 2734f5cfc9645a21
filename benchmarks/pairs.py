"""Two checkouts of fem-frac on the same cases, interleaved: process CPU time per run.

    git worktree add ../before HEAD~1
    python benchmarks/pairs.py --before ../before --cases notched_beam_cohesive dcb
    python benchmarks/pairs.py --before ../before --after . --cases dcb --rounds 5

Each round runs every case once under each checkout (``python -m fem_frac run
ROOT/cases/CASE.yaml`` with ROOT the working directory, so that each run imports its own
checkout's package), alternating which goes first from round to round, each in a fresh
process with compiled modules cached and one OpenBLAS thread, as the command runs. CPU is
the child's user + system time (``getrusage(RUSAGE_CHILDREN)``, PARDISO's threads
included). Reported per case: both checkouts' times, the median of the paired
differences (after - before) and in how many rounds ``after`` took less. On a shared
machine whose speed drifts between minutes, the paired differences are the figure to read.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def child_env() -> dict:
    """The environment of a run as a user's installation has it: compiled modules cached
    (no PYTHONDONTWRITEBYTECODE), OpenBLAS on one thread unless the environment says."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    return env


def cpu_of_run(root: Path, case: str) -> float:
    """CPU seconds of one ``fem-frac run`` of ``root/cases/<case>.yaml`` from ``root``."""
    with tempfile.TemporaryDirectory() as out:
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        done = subprocess.run([sys.executable, "-m", "fem_frac", "run",
                               str(root / "cases" / f"{case}.yaml"), "-o", out, "-q"],
                              cwd=root, env=child_env(), capture_output=True, text=True)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["?"])[-1]
        raise SystemExit(f"{root}: {case} failed: {last}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def check_imports(root: Path) -> None:
    """Stop unless a process started in ``root`` imports ``root``'s fem_frac (an installed
    copy found first would make both checkouts the same)."""
    done = subprocess.run([sys.executable, "-c", "import fem_frac; print(fem_frac.__file__)"],
                          cwd=root, env=child_env(), capture_output=True, text=True)
    found = Path(done.stdout.strip() or ".").resolve()
    if root not in found.parents:
        raise SystemExit(f"{root}: a process started there imports fem_frac from {found}")


def measure(before: Path, after: Path, cases: list[str], rounds: int) -> dict:
    """``{case: {"before": [...], "after": [...]}}``, CPU seconds per round."""
    for root in (before, after):
        check_imports(root)
    times = {c: {"before": [], "after": []} for c in cases}
    for k in range(rounds):
        for case in cases:
            order = [("before", before), ("after", after)]
            if k % 2:
                order.reverse()
            for name, root in order:
                times[case][name].append(cpu_of_run(root, case))
    return times


def report(times: dict) -> str:
    lines = ["| case | before: CPU s | after: CPU s | median of after - before | after less |",
             "|---|---|---|---|---|"]
    for case, t in times.items():
        diff = [a - b for b, a in zip(t["before"], t["after"], strict=True)]
        lines.append(f"| {case} | {' '.join(f'{x:.2f}' for x in t['before'])} | "
                     f"{' '.join(f'{x:.2f}' for x in t['after'])} | "
                     f"{statistics.median(diff):+.2f} | "
                     f"{sum(d < 0 for d in diff)} of {len(diff)} |")
    return "\n".join(lines)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--before", type=Path, required=True, help="a checkout (git worktree)")
    p.add_argument("--after", type=Path, default=ROOT, help="another (default: this one)")
    p.add_argument("--cases", nargs="+", required=True, help="names in cases/, no .yaml")
    p.add_argument("--rounds", type=int, default=3)
    a = p.parse_args()
    load = os.getloadavg()[0]
    times = measure(a.before.resolve(), a.after.resolve(), a.cases, a.rounds)
    print(f"load average before: {load:.2f}; after: {os.getloadavg()[0]:.2f}")
    print(report(times))


if __name__ == "__main__":
    main()
