"""What the command's process skips (fem_frac/app/startup.py), measured on whole runs.

    python benchmarks/startup.py                                   # bar_tension_break, 14 rounds
    python benchmarks/startup.py --case cases/plate_with_hole.yaml --rounds 10

Each round runs the case once in each of five ways, in a fresh process each, in turn:

- ``usual``: ``fem_frac.app.cli.main()`` then ``sys.exit``: scipy imported as it comes, the
  interpreter torn down at exit (what ``fem-frac run`` did before);
- ``lean``: scipy imported without numpy's unread submodules, usual exit;
- ``frozen``: a run's modules imported with the garbage collector off, then frozen;
- ``leave``: usual import, the exit without teardown;
- ``command``: ``python -m fem_frac run`` (all three, and pydantic's plugin search off).

CPU is the child's user + system time (``getrusage(RUSAGE_CHILDREN)``). Reported per way:
median and minimum over the rounds, and against ``usual`` the median of the paired
differences and in how many rounds the way took less. Children start in this checkout
(``-m`` and ``-c`` put the working directory first on ``sys.path``), with compiled modules
cached, one OpenBLAS thread, as the command runs.
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

LAUNCH = """
import gc, sys
from fem_frac.app.cli import main
from fem_frac.app.startup import import_scipy_lean, leave
lean, frozen, fast = (flag == "1" for flag in sys.argv[1:4])
sys.argv = ["fem-frac", *sys.argv[4:]]
if lean:
    import_scipy_lean()
if frozen:
    gc.disable()
    import skfem, fem_frac.config.loader, fem_frac.app.driver  # as import_for_run
    gc.freeze()
    gc.enable()
code = main()
leave(code) if fast else sys.exit(code)
"""
WAYS = {"usual": ("0", "0", "0"), "lean": ("1", "0", "0"), "frozen": ("0", "1", "0"),
        "leave": ("0", "0", "1"), "command": None}


def child_env() -> dict[str, str]:
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    return env


def cpu_of(args: list[str]) -> float:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run(args, cwd=ROOT, env=child_env(), capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(args[:4])}...: exit {done.returncode}\n{done.stderr}")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--case", default="cases/bar_tension_break.yaml")
    p.add_argument("--rounds", type=int, default=14)
    args = p.parse_args()
    times: dict[str, list[float]] = {w: [] for w in WAYS}
    with tempfile.TemporaryDirectory() as tmp:
        run = ["run", args.case, "-o", str(Path(tmp) / "out"), "-q", "--overwrite"]
        cpu_of([sys.executable, "-m", "fem_frac", *run])  # compiled modules cached
        for _ in range(args.rounds):
            for way, flags in WAYS.items():
                argv = ([sys.executable, "-m", "fem_frac", *run] if flags is None
                        else [sys.executable, "-c", LAUNCH, *flags, *run])
                times[way].append(cpu_of(argv))
    print(f"{args.case}, {args.rounds} rounds, process CPU s")
    usual = times["usual"]
    for way, t in times.items():
        line = f"{way:8s} median {statistics.median(t):.3f}  min {min(t):.3f}"
        if way != "usual":
            diff = [u - x for u, x in zip(usual, t, strict=True)]
            line += (f"  less than usual by {statistics.median(diff):+.3f} (median), in "
                     f"{sum(d > 0 for d in diff)} of {len(diff)} rounds")
        print(line)


if __name__ == "__main__":
    main()
