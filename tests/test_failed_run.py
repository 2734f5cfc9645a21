"""A run that stops with exit 3 says so in its output directory: ``summary.json`` marked
``failed`` with the last step it completed (``step``, ``time``), where it stopped
(``stopped_at``), the reason (``message``), what a completed summary carries as far as it is
known (counts, wall times), and ``case.resolved.yaml`` beside it, whichever path it stopped
on: a numerical failure while discretizing, in setting up step 0, in an equilibrium step (a
non-finite state, an overflow, no convergence), in a fracture pass."""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_cli_errors import BASE

from fem_frac.app.cli import main
from fem_frac.config import load_case
from fem_frac.errors import SolverError

STEPPED = BASE + "analysis: {type: quasi_static, steps: 3}\n"
# far beyond the limit load of the bar (yield 250 MPa over 0.25 m^2: 62.5 MN): no step holds
BEYOND_LIMIT = STEPPED.replace("[0, 0, -1e5]", "[1e10, 0, 0]") + (
    "plasticity: {yield_stress: 250e6}\n")


def _run(tmp_path, text: str, capsys) -> tuple[dict, str]:
    case = tmp_path / "case.yaml"
    case.write_text(text)
    out = tmp_path / "out"
    assert main(["run", str(case), "-o", str(out), "-q"]) == 3
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert (out / "case.resolved.yaml").is_file()
    load_case(out / "case.resolved.yaml")  # a case that runs again as it was
    return json.loads((out / "summary.json").read_text()), err


def _failed(summary: dict, step: int, stopped: int, stage: str) -> None:
    assert summary["status"] == "failed"
    assert summary["step"] == step and summary["steps"] == 3
    assert summary["stopped_at"] == {"step": stopped, "stage": stage}
    assert summary["message"]
    assert summary["wall_time_s"]["total"] > 0
    assert summary["cpu_time_s"]["before_run"] > 0 and summary["cpu_time_s"]["run"] >= 0
    assert summary["counts"]["elements"] > 0 and summary["counts"]["dofs"] > 0


def test_an_overflow_in_a_step_leaves_a_failed_summary(tmp_path, capsys):
    """numpy's overflow warning, raised as an error during the run (exit 3), once left the
    summary marked ``running``."""
    soft = STEPPED.replace("210e9", "1e-100").replace("-1e5", "-1e100")
    summary, err = _run(tmp_path, soft, capsys)
    _failed(summary, 0, 1, summary["stopped_at"]["stage"])
    assert "overflow" in summary["message"] and summary["message"] in err
    assert summary["time"] == 0.0
    # what the last completed step (0) carried
    assert summary["analysis"]["steps"] == 3 and summary["strain_energy"] == 0.0


def test_no_convergence_leaves_the_last_step_completed(tmp_path, capsys):
    summary, err = _run(tmp_path, BEYOND_LIMIT, capsys)
    _failed(summary, 0, 1, "equilibrium")
    assert "after 4 levels of cut-back" in summary["message"]
    assert "may exceed what the structure carries" in summary["message"]
    assert summary["message"] in err


def test_a_failure_setting_up_step_0_leaves_a_failed_summary(tmp_path, capsys):
    """E = 1e-300: the elastic matrix cannot be factorized (before step 0 is complete)."""
    summary, _ = _run(tmp_path, STEPPED.replace("210e9", "1e-300"), capsys)
    _failed(summary, 0, 0, "set-up")
    assert summary["time"] == 0.0 and "strain_energy" not in summary


def test_a_failure_while_discretizing_claims_the_directory(tmp_path, capsys, monkeypatch):
    """A numerical failure after validation, before the output directory would be claimed,
    still leaves the summary and the resolved case (a bad case does not: exit 2)."""
    import fem_frac.app.driver as driver

    def broken(*args, **kwargs):
        raise FloatingPointError("overflow in the mass matrix")

    monkeypatch.setattr(driver, "discretize", broken)
    summary, err = _run(tmp_path, STEPPED, capsys)
    assert summary["status"] == "failed" and summary["stopped_at"]["stage"] == "set-up"
    assert "numerical failure: FloatingPointError: overflow in the mass matrix" in err
    assert summary["message"] in err and summary["wall_time_s"]["mesh"] > 0
    assert summary["cpu_time_s"]["run"] >= 0


def test_a_failure_in_a_fracture_pass_leaves_a_failed_summary(tmp_path, capsys, monkeypatch):
    from fem_frac.fracture.stage import FractureStage

    crack = FractureStage.__call__

    def failing(self, step, world):
        if step.n == 2:
            raise SolverError(f"step {step.n}, stage fracture: re-solve failed")
        return crack(self, step, world)

    monkeypatch.setattr(FractureStage, "__call__", failing)
    text = STEPPED + "fracture:\n  tensile_strength: 1e12\n  smoothing: {rings: 1}\n"
    summary, err = _run(tmp_path, text, capsys)
    _failed(summary, 1, 2, "fracture")
    assert summary["time"] == pytest.approx(1 / 3)
    assert summary["message"] == "step 2, stage fracture: re-solve failed"
    assert summary["fracture"]["crack_faces"] == 0
    assert summary["analysis"]["iterations"] >= 1  # the costs of the steps completed
    assert np.isfinite(summary["max_displacement"]) and summary["max_displacement"] > 0
