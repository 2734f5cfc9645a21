"""Compose the stages a case asks for. Knows the order of stages, not how any of them works."""

from __future__ import annotations

import json
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import __version__
from .config.schema import Case
from .errors import CaseError, SolverError
from .fem.elasticity import stiffness, strain, stress
from .fem.space import Space, build_space
from .fem.tensors import isotropic_tangent
from .mesh.build import build_mesh
from .mesh.mesh import Mesh
from .problem import Problem, build_problem, free_rigid_modes
from .timing import StageTimer
from .writers.directory import prepare_directory
from .writers.fields import stress_fields, vtk_cells
from .writers.series import SeriesWriter

Log = Callable[[str], None]


def quiet(_: str) -> None:
    pass


@dataclass(frozen=True, eq=False)
class Model:
    mesh: Mesh
    space: Space
    problem: Problem


def build_model(case: Case, case_dir: Path, timer: StageTimer, log: Log = quiet) -> Model:
    """Mesh, function space, supports and loads: everything before assembly."""
    with timer("mesh"):
        mesh = build_mesh(case.mesh, case_dir)
    log(f"mesh       {mesh.n_tets:,} tets, {mesh.n_points:,} vertices")
    with timer("space"):
        space = build_space(mesh, case.mesh.order)
    with timer("loads"):
        problem = build_problem(
            space, case.boundary_conditions, case.body_force, case.material.density
        )
    log(f"space      P{space.order}, {space.n_dofs:,} dofs")
    return Model(mesh, space, problem)


def output_location(case: Case, case_path: Path, directory: str | None) -> tuple[Path, str]:
    name = case.output.name or case_path.stem
    chosen = directory or case.output.directory or str(Path("out") / case_path.stem)
    return Path(chosen), name


def check_finite(array: np.ndarray, step: int, stage: str, field: str) -> None:
    bad = ~np.isfinite(array)
    if np.any(bad):
        raise SolverError(
            f"step {step}, stage {stage}: {field} is not finite in {np.count_nonzero(bad)} "
            f"of {array.size} entries; stopped before writing it"
        )


def solve_static(model: Model, tangent: np.ndarray, method: str, timer: StageTimer, log: Log):
    """Assemble, condense, factorize once and back-solve. Returns (u, K, factorization)."""
    from skfem import condense

    from .linalg import factorize

    space, problem = model.space, model.problem
    free = free_rigid_modes(space, problem.constraints.dofs)
    if free:
        raise CaseError(
            ("boundary_conditions",),
            "the supports leave rigid-body motions free (" + ", ".join(free) + "): "
            "a static solve is singular; add supports (fixed, displacement, symmetry)",
        )
    with timer("assemble"):
        k = stiffness(space, tangent)
    u = np.zeros(space.n_dofs)
    u[problem.constraints.dofs] = problem.constraints.values
    with timer("factorize"):
        a, b, _, interior = condense(k, problem.external_force, x=u, D=problem.constraints.dofs)
        factorization = factorize(a.tocsr(), method)
    log(f"factorize  {factorization.method}, {a.shape[0]:,} unknowns")
    with timer("solve"):
        u[interior] = factorization.solve(b)
    check_finite(u, 1, "solve", "displacement")
    return u, k, factorization


def run_case(
    case: Case,
    case_path: Path,
    out_dir: Path,
    name: str,
    overwrite: bool = False,
    log: Log = quiet,
    resolved_yaml: str | None = None,
) -> dict:
    """Run a static case end to end and write its output. Returns the summary."""
    timer = StageTimer()
    model = build_model(case, case_path.parent, timer, log)
    # after validation (a bad case never touches earlier results), before the long stages
    prepare_directory(out_dir, name, overwrite)
    space = model.space
    tangent = isotropic_tangent(case.material.youngs_modulus, case.material.poissons_ratio)
    u, k, factorization = solve_static(model, tangent, case.analysis.linear_solver, timer, log)
    with timer("stress"), np.errstate(over="ignore", invalid="ignore"):
        sigma = stress(tangent, strain(space, u))
        check_finite(sigma, 1, "stress", "stress")
        reactions = k @ u - model.problem.external_force
        check_finite(reactions, 1, "stress", "reaction force")
        magnitude = np.linalg.norm(u.reshape(-1, 3), axis=1)
        check_finite(magnitude, 1, "stress", "displacement magnitude")
        # linear elasticity: strain energy = half the work of all forces, reactions included
        energy = 0.5 * u @ (model.problem.external_force + reactions)
        check_finite(np.array([energy]), 1, "stress", "strain energy")
    with timer("output"):
        writer = SeriesWriter(out_dir, name)
        cell_data = stress_fields(space, sigma)
        writer.write(
            1.0,
            space.node_points,
            vtk_cells(space),
            {"displacement": u.reshape(-1, 3)},
            cell_data,
        )
    summary = _summary(case, case_path, model, magnitude, energy, reactions, factorization, timer)
    summary["output"] = {"pvd": str(writer.pvd_path), "steps": len(writer.entries)}
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    if resolved_yaml is not None:
        (out_dir / "case.resolved.yaml").write_text(resolved_yaml)
    log(f"output     {writer.pvd_path}")
    return summary


def _summary(case, case_path, model, magnitude, energy, reactions, factorization, timer) -> dict:
    space, problem = model.space, model.problem
    f = problem.external_force
    return {
        "case": str(case_path),
        "title": case.title,
        "fem_frac": __version__,
        "python": sys.version.split()[0],
        "counts": {
            "vertices": model.mesh.n_points,
            "nodes": space.n_nodes,
            "elements": model.mesh.n_tets,
            "dofs": space.n_dofs,
            "constrained_dofs": int(len(problem.constraints.dofs)),
            "element_order": space.order,
        },
        "linear_solver": factorization.method,
        "max_displacement": float(magnitude.max()),
        "strain_energy": float(energy),
        "reaction_force": {
            label: reactions[dofs].reshape(-1, 3).sum(axis=0).tolist()
            for label, dofs in problem.reaction_groups.items()
        },
        "external_force": f.reshape(-1, 3).sum(axis=0).tolist(),
        "wall_time_s": {**{k: round(v, 6) for k, v in timer.seconds.items()},
                        "total": round(timer.total(), 6)},
    }
