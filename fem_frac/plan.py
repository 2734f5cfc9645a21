"""Which stages a case runs, and why the others are left out."""

from __future__ import annotations

from dataclasses import dataclass

from .config.schema import Case
from .mesh.build import describe_source

# Quadrature points per tet for each order (scikit-fem's rules for fem.space.INTORDER).
QUADRATURE_POINTS = {1: 1, 2: 4}


@dataclass(frozen=True)
class Stage:
    name: str
    runs: bool
    detail: str


def make_plan(case: Case) -> list[Stage]:
    order = case.mesh.order
    n_loads = sum(bc.type in ("traction", "pressure") for bc in case.boundary_conditions)
    n_supports = len(case.boundary_conditions) - n_loads
    loads = f"{n_supports} support(s), {n_loads} surface load(s)"
    if case.body_force is not None:
        loads += ", gravity"
    return [
        Stage("mesh", True, describe_source(case.mesh)),
        Stage(
            "space",
            True,
            f"vector P{order} tetrahedra, {QUADRATURE_POINTS[order]} quadrature point(s) per tet",
        ),
        Stage("loads", True, loads),
        Stage("stiffness", True, "isotropic linear elasticity, assembled once"),
        Stage("mass", False, "static analysis needs no mass matrix"),
        Stage("solve", True, f"static, linear solver {_solver(case.analysis.linear_solver)}"),
        Stage("plasticity", False, "not requested"),
        Stage("fracture", False, "not requested"),
        Stage("fragments", False, "not requested"),
        Stage(
            "output",
            True,
            "displacement; stress, von_mises, max_principal_stress; summary.json",
        ),
    ]


def _solver(method: str) -> str:
    from .linalg import available_methods

    return f"auto ({available_methods()[0]})" if method == "auto" else method


def format_plan(plan: list[Stage]) -> str:
    width = max(len(s.name) for s in plan)
    rows = [f"  {'run ' if s.runs else 'skip'}  {s.name:<{width}}  {s.detail}" for s in plan]
    return "\n".join(rows)
