"""benchmarks/fracture.py still runs against the code it times (a tiny bar, one repeat):
every piece of a batch is timed and the batch opens cracks."""

import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).parent.parent / "benchmarks" / "fracture.py"


def test_the_insertion_batch_benchmark_runs():
    out = subprocess.run([sys.executable, str(SCRIPT), "--sizes", "2000", "--repeats", "1",
                          "--profile", "20"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    table = out.stdout
    assert "failed" not in table
    for row in ("**floor**", "**open (stage.open)**", "**rebuild (rediscretize)**",
                "**refactorization**", "**support check**", "**batch warm**",
                "**second batch warm**"):
        assert row in table
    # the second batch under cProfile, after the table
    assert "under cProfile" in table and "stage.py" in table.split("under cProfile")[1]


def test_the_pardiso_halves_benchmark_runs():
    """benchmarks/pardiso_halves.py on a tiny bar: its table, and its check that forward
    then backward substitution is the back-solve to the bit (an assertion in the script)."""
    import pytest

    from fem_frac.solve.linalg import available_methods

    if "pardiso" not in available_methods():
        pytest.skip("PARDISO is not installed here")
    script = SCRIPT.parent / "pardiso_halves.py"
    out = subprocess.run([sys.executable, str(script), "--tets", "2000", "--repeats", "1",
                          "--columns", "1", "3"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "| 3 | " in out.stdout and "forward (331)" in out.stdout
