"""benchmarks/stage_pieces.py on one small case: a function and a method timed in a run."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).parent.parent
SCRIPT = ROOT / "benchmarks" / "stage_pieces.py"


def test_a_function_and_a_method_are_timed():
    pieces = ["fem_frac.solve.discretization:build_operators",
              "fem_frac.solve.constrained:Constrained.factorize"]
    out = subprocess.run([sys.executable, str(SCRIPT), str(ROOT / "cases" / "vibrating_beam.yaml"),
                          "--pieces", *pieces], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    for piece in pieces:
        row = [line for line in out.stdout.splitlines() if line.startswith(f"| {piece} |")]
        assert len(row) == 1
        calls = int(row[0].split("|")[2])
        assert calls >= 1
