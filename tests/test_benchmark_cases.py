"""benchmarks/cases.py on one small case: its floor, its books and its table row."""

import importlib.util
from pathlib import Path

from fem_frac.app.cli import main

ROOT = Path(__file__).parent.parent
SCRIPT = ROOT / "benchmarks" / "cases.py"
_spec = importlib.util.spec_from_file_location("bench_cases", SCRIPT)
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)


def test_floor_work_and_row_of_a_small_case(tmp_path):
    case = ROOT / "cases" / "vibrating_beam.yaml"
    floor = bench.floor(str(case))
    parts = ("back-solve", "strain", "law.update", "internal force")
    assert all(floor[k] > 0 for k in parts)
    assert floor["floor"] == sum(floor[k] for k in parts)
    out = tmp_path / "run"
    assert main(["run", str(case), "-o", str(out), "-q"]) == 0
    work = bench.work(out)
    start = bench.before_run(out)  # this test process's CPU before the run
    assert 0 < start
    assert work["steps"] > 0 and work["iterations"] >= work["steps"]
    assert work["stages"]["total"] > 0 and work["batches"] == 0
    row = {"case": "cases/vibrating_beam.yaml", "cpu": [2.0, 2.5], "wall": [1.5, 1.6],
           **floor, **work}
    ideal = work["iterations"] * floor["floor"]
    line = bench.table([row]).splitlines()[-1]
    assert line.startswith("| vibrating_beam |") and f"**{2.0 / ideal:.0f}**" in line
    # the floors of several rounds: the least, and their spread
    rounds = {**row, "floors": [1.5 * floor["floor"], floor["floor"]]}
    spread = f"{1e3 * floor['floor']:.2f} ({0.5e3 * floor['floor']:.2f})"
    assert f"| {spread} |" in bench.table([rounds]).splitlines()[-1]
    # each round's CPU time over that round's floor
    by_round = f"| {2.0 / (1.5 * ideal):.0f}-{2.5 / ideal:.0f} |"
    assert by_round in bench.table([rounds]).splitlines()[-1]
    assert "| - |" in bench.table([row]).splitlines()[-1]  # one floor for two runs
    # the least start-up over the runs, in seconds and in ideals
    started = {**row, "before_run": [0.4, 0.3, None]}
    assert f"| 0.30 ({0.3 / ideal:.1f}x) |" in bench.table([started]).splitlines()[-1]
    # a case without finite-element work has no ratio; a failed one says so
    rigid = {**row, "iterations": 0}
    assert "| - |" in bench.table([rigid]).splitlines()[-1]
    assert "error: boom" in bench.table([{"case": "x.yaml", "cpu": [], "error": "boom"}])
