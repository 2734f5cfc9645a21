"""Text for people: the ``check`` report and the resolved copy of a case."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from .. import __version__
from ..config.loader import Source
from ..config.schema import Case, DynamicAnalysis
from ..fem.loads import facet_basis
from ..mesh.build import build_mesh, mesh_file_path
from ..mesh.mesh import min_dihedral_angles
from ..mesh.selection import boundary_names, named_facets
from ..solve.discretization import check_model, model_on
from ..solve.loading import time_grid
from ..timing import StageTimer
from .driver import check_stages, recipe_of
from .plan import format_plan, make_plan

# Tets with a smaller minimum dihedral angle than this are reported as poorly shaped.
POOR_DIHEDRAL_DEG = 10.0


def _area(space, triples: np.ndarray) -> float:
    """Area of boundary faces, curved ones included (quadrature on the facet basis)."""
    return float(facet_basis(space, space.facet_indices(triples)).dx.sum())


def check_report(case: Case, source: Source) -> str:
    """Validate, mesh and resolve supports and loads; describe the result. No solve."""
    timer = StageTimer()
    check_stages(case)
    with timer("mesh"):
        mesh = build_mesh(case.mesh, source.path.parent)
    recipe = recipe_of(case, time_grid(case.analysis).dt)
    space, materials, problem = model_on(recipe, mesh, timer)
    check_model(recipe, space, materials, problem)
    angles = min_dihedral_angles(mesh.points, mesh.tets)
    lo, hi = mesh.points.min(axis=0), mesh.points.max(axis=0)
    volume = float(space.basis.dx.sum())
    lines = [
        f"case        {source.path}: valid" + (f" ({case.title})" if case.title else ""),
        f"units       {case.units}",
        f"mesh        {mesh.n_tets:,} tets, {mesh.n_points:,} vertices, "
        f"{space.n_nodes:,} nodes (P{space.order}), {space.n_dofs:,} dofs "
        f"({timer.seconds['mesh']:.2f} s)",
        f"            volume {volume:.6g}, bounding box {np.array2string(lo, precision=4)} "
        f"to {np.array2string(hi, precision=4)}",
        f"quality     minimum dihedral angle {angles.min():.2f} deg "
        f"(median {np.median(angles):.1f}); "
        f"{np.count_nonzero(angles < POOR_DIHEDRAL_DEG)} tets below {POOR_DIHEDRAL_DEG:g} deg",
        "boundaries",
    ]
    for name in boundary_names(mesh):
        triples = named_facets(mesh, name)
        area = _area(space, triples)
        lines.append(f"  {name:<18} {len(triples):>8,} faces   area {area:.6g}")
    if case.regions:
        lines.append("regions")
        for i, (region, count) in enumerate(zip(case.regions, materials.counts,
                                                strict=True)):
            where = (f"subdomain {region.subdomain}" if region.subdomain is not None
                     else f"box {list(region.box.min)} to {list(region.box.max)}")
            values = ", ".join(f"{k} {v:g}" for k, v in region.model_dump(
                include={"youngs_modulus", "poissons_ratio", "density"}).items()
                if v is not None)
            lines.append(f"  [{i}] {where}: {count:,} tets; {values}")
    lines.append("supports and loads")
    lines += [f"  {d}" for d in problem.descriptions] or ["  (none)"]
    if case.fracture is not None:
        lines += _fracture_lines(case, mesh)
    if isinstance(case.analysis, DynamicAnalysis):
        lines += _time_step_lines(recipe, space, materials, problem)
    lines.append("plan")
    lines.append(format_plan(make_plan(case)))
    return "\n".join(lines)


def _time_step_lines(recipe, space, materials, problem) -> list[str]:
    """The stable step of central difference (and how the case's dt compares)."""
    from ..fem.mass import lumped_mass
    from ..plasticity.law import material_law
    from ..solve.constrained import Constrained
    from ..solve.discretization import build_operators, explicit_substeps
    from ..solve.stable_step import stable_limit

    analysis = recipe.analysis
    ops = build_operators(recipe, space, materials, material_law(materials, None),
                          StageTimer())
    limit = stable_limit(space, ops.stiffness, lumped_mass(space, materials.density),
                         Constrained(problem, "auto").free, materials, analysis.rayleigh)
    dt = recipe.dt
    verdict = ""
    if analysis.integrator == "central_difference":
        substeps = explicit_substeps(limit, dt, analysis.substeps)  # refuses as run does
        verdict = (f"; dt {dt:.4g} is {dt / limit.dt:.3g} of it" if substeps == 1
                   else f"; dt {dt:.4g} runs as {substeps} substeps")
    return [
        f"time step   stable step of central difference {limit.dt:.4g} "
        f"({limit.method}; element bound {limit.element_bound_dt:.4g}){verdict}",
    ]


def resolved_case(case: Case, source: Source, directory: Path, name: str) -> Case:
    """``case`` made self-contained: absolute mesh file path and the actual output place."""
    mesh = case.mesh
    if mesh.file is not None:
        path = mesh_file_path(mesh, source.path.parent).resolve()
        mesh = mesh.model_copy(update={"file": str(path)})
    output = case.output.model_copy(update={"directory": str(directory), "name": name})
    return case.model_copy(update={"mesh": mesh, "output": output})


def resolved_yaml(case: Case, source: Source) -> str:
    """The case with every default filled in, as YAML, headed by where it came from."""
    from ruamel.yaml import YAML

    yaml = YAML(typ="rt")
    yaml.default_flow_style = None
    buffer = io.StringIO()
    yaml.dump(case.model_dump(mode="json", exclude_none=True), buffer)
    header = [f"# resolved by fem-frac {__version__} from {source.path}"]
    header += [f"# --set {text}" for text in source.overrides.values()]
    return "\n".join(header) + "\n" + buffer.getvalue()


def _fracture_lines(case: Case, mesh) -> list[str]:
    """The protected vertices (names and boxes checked here) and the smoothing size."""
    from ..fracture.smoothing import mean_edge_length
    from ..fracture.stage import protected_vertices

    f = case.fracture
    protected = protected_vertices(f, mesh)
    edge = mean_edge_length(mesh.points, mesh.tets)
    s = f.smoothing
    size = (f"length {s.length:g} = {s.length / edge:.2f} mean edge lengths"
            if s.length is not None else f"{s.rings} ring(s) of neighbours")
    return ["fracture",
            f"  tensile strength {f.tensile_strength:g}; smoothing {s.method}, {size} "
            f"(mean edge {edge:.4g})",
            f"  {np.count_nonzero(protected):,} of {mesh.n_points:,} vertices protected"]

