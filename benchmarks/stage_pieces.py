"""Wall time of named functions inside one run of a case: calls, total, per call.

    python benchmarks/stage_pieces.py cases/notched_beam.yaml
    python benchmarks/stage_pieces.py cases/dcb.yaml --pieces fem_frac.solve.linalg:factorize

Runs ``fem-frac run CASE -q`` in this process (into a temporary folder) with each piece,
``module:function``, wrapped by a timer where the module that calls it looks it up (so
name the module that *imports* the function, as the defaults do), or ``module:Class.method``,
wrapped on the class. Pieces nest: a piece's
time includes the pieces it calls. The defaults are the parts of a crack-insertion batch
(``fracture/stage.py``) and of the re-solve after it. OpenBLAS runs on one thread, as the
``fem-frac`` command runs it.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy, as fem_frac/app/cli.py

PIECES = [
    "fem_frac.fracture.stage:advance",  # the re-solve of the step after a batch
    "fem_frac.solve.bordered:bordered_factor",  # looked up there by the stepper
    "fem_frac.solve.constrained:factorize",  # fresh factorizations (the first included)
    "fem_frac.fracture.stage:update_operator",
    "fem_frac.fracture.stage:cut_tets",
    "fem_frac.fracture.stage:rebuilt",
    "fem_frac.fracture.stage:rediscretize",
    "fem_frac.fracture.stage:_topology",
    "fem_frac.fracture.stage:principal_stress",
    "fem_frac.fracture.stage:smooth",
    "fem_frac.fracture.stage:select_sites",
    "fem_frac.fracture.stage:fragments",
]


def wrap(piece: str, totals: dict) -> None:
    """Time ``piece``, ``module:function`` or ``module:Class.method`` (wrapped on the class,
    so every instance's calls count)."""
    module_name, name = piece.split(":")
    owner = importlib.import_module(module_name)
    *path, name = name.split(".")
    for part in path:
        owner = getattr(owner, part)
    inner = getattr(owner, name)

    def timed(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return inner(*args, **kwargs)
        finally:
            totals[piece][0] += 1
            totals[piece][1] += time.perf_counter() - t0

    setattr(owner, name, timed)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("case")
    p.add_argument("--pieces", nargs="+", default=PIECES)
    a = p.parse_args()
    totals: dict[str, list] = defaultdict(lambda: [0, 0.0])
    for piece in a.pieces:
        wrap(piece, totals)
    from fem_frac.app.cli import main as fem_frac

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        code = fem_frac(["run", a.case, "-o", str(Path(tmp) / "out"), "-q"])
        wall = time.perf_counter() - t0
    if code:
        sys.exit(f"the run exited with {code}")
    print(f"{a.case}: {wall:.2f} s in all\n")
    print("| piece | calls | s | ms per call |\n|---|---|---|---|")
    for piece, (calls, seconds) in sorted(totals.items(), key=lambda kv: -kv[1][1]):
        print(f"| {piece} | {calls} | {seconds:.3f} | {1e3 * seconds / max(calls, 1):.2f} |")


if __name__ == "__main__":
    main()
