"""benchmarks/pairs.py on one small case, this checkout against itself: one round, a row
with both times and the paired difference."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).parent.parent
SCRIPT = ROOT / "benchmarks" / "pairs.py"


def test_the_pairs_benchmark_runs():
    out = subprocess.run([sys.executable, str(SCRIPT), "--before", str(ROOT), "--cases",
                          "vibrating_beam", "--rounds", "1"],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    row = [line for line in out.stdout.splitlines() if line.startswith("| vibrating_beam |")]
    assert len(row) == 1
    cells = [c.strip() for c in row[0].strip("|").split("|")]
    before, after = float(cells[1]), float(cells[2])
    assert before > 0 and after > 0
    # the difference of the unrounded times, each cell rounded to 0.01
    assert abs(float(cells[3]) - (after - before)) <= 0.0151
    assert cells[4] == ("1 of 1" if float(cells[3]) < 0 else "0 of 1") or cells[3] == "+0.00" \
        or cells[3] == "-0.00"


def test_a_failed_run_is_named():
    out = subprocess.run([sys.executable, str(SCRIPT), "--before", str(ROOT), "--cases",
                          "no_such_case", "--rounds", "1"],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode != 0 and "no_such_case failed" in out.stderr


def test_a_checkout_that_imports_another_copy_is_refused(tmp_path):
    """A directory without its own fem_frac: its processes import another copy."""
    out = subprocess.run([sys.executable, str(SCRIPT), "--before", str(tmp_path), "--cases",
                          "vibrating_beam", "--rounds", "1"],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode != 0 and "imports fem_frac from" in out.stderr
