"""Shared by the notched-beam cohesive tests (test_cohesive_beam, test_cohesive_ligament): the
study script of the docs, one run of a case and the runs of a study."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np

from fem_frac.app.cli import main
from fem_frac.writers.history import read_history

ROOT = Path(__file__).parent.parent
SCRIPT = ROOT / "docs" / "fracture" / "cohesive_study.py"


def study_script():
    """docs/fracture/cohesive_study.py as a module."""
    spec = importlib.util.spec_from_file_location("cohesive_study", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run_case(case: Path, out: Path, *options: str) -> tuple[dict, dict, dict]:
    """Run ``case`` into ``out``: its summary, its history (arrays) and the study script's
    record of the run."""
    assert main(["run", str(case), "-o", str(out), "-q", *options]) == 0
    summary = json.loads((out / "summary.json").read_text())
    history = {k: np.asarray(v, dtype=float)
               for k, v in read_history(out / "history.csv").items()}
    return summary, history, study_script().read_run(out)


def study_runs(study: Path, out: Path) -> list[dict]:
    """Run the mesh study ``study`` into ``out``: the records of its runs, coarse to fine."""
    assert main(["study", str(study), "-o", str(out), "-q"]) == 0
    script = study_script()
    runs = sorted((script.read_run(d) for d in (out / "runs").iterdir()), key=lambda r: -r["h"])
    assert [r["h"] for r in runs] == [0.01, 0.005, 0.0025]
    return runs


def assert_peak_load_converges(runs: list[dict], least_order: float = 0.5) -> None:
    """The peak loads of three runs, coarse to fine: the differences shrink, with an observed
    order above ``least_order``."""
    h = [r["h"] for r in runs]
    peaks = [r["peak_load"] for r in runs]
    assert abs(peaks[0] - peaks[1]) > abs(peaks[1] - peaks[2])
    order = study_script().observed_order(h, peaks)
    assert order is not None and order > least_order
