"""benchmarks/reconnect.py still runs against the code it times (a small box, one repeat):
the reconnection with and without the kept diagonal gives the same stiffness, and the
graph's components are the same with either weights (the script asserts both)."""

import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).parent.parent / "benchmarks" / "reconnect.py"


def test_the_reconnection_benchmark_runs():
    out = subprocess.run([sys.executable, str(SCRIPT), "--tets", "3000", "--repeats", "1"],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "touched rows" in out.stdout and "(the same bits)" in out.stdout
    assert "float64 weights" in out.stdout and "(the same components)" in out.stdout
