"""Run a case given as a dict through the driver, without files."""

from __future__ import annotations

from pathlib import Path

from fem_frac.config.schema import Case
from fem_frac.driver import build_model, solve_static
from fem_frac.fem.tensors import isotropic_tangent
from fem_frac.timing import StageTimer


def solve(case_dict: dict, case_dir: Path = Path(".")):
    """(case, model, displacement) of a static case."""
    case = Case.model_validate(case_dict)
    timer = StageTimer()
    model = build_model(case, case_dir, timer)
    tangent = isotropic_tangent(case.material.youngs_modulus, case.material.poissons_ratio)
    u, _, _ = solve_static(model, tangent, case.analysis.linear_solver, timer, lambda m: None)
    return case, model, u
