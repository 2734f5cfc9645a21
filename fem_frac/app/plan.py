"""Which stages a case runs, and why the others are left out."""

from __future__ import annotations

from dataclasses import dataclass

from ..config.schema import Case, DynamicAnalysis, StaticAnalysis
from ..mesh.build import describe_source
from ..solve.loading import time_grid

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
    analysis = case.analysis
    dynamic = isinstance(analysis, DynamicAnalysis)
    formulation = " with averaged volumetric strain (B-bar)" if (
        case.mesh.formulation == "averaged") else ""
    fields = "displacement" + (", velocity" if dynamic else "") + "; stress, von_mises, " \
        "max_principal_stress" + (
            ", plastic_strain, equivalent_plastic_strain" if case.plasticity else "") + (
            ", fragment_id, smoothed_max_principal_stress" if case.fracture else "") + (
            ", rigid" if case.fragments else "") + (
            "; crack surface series" if case.fracture and case.output.crack_surface else "") \
        + "; history.csv, summary.json"
    return [
        Stage("mesh", True, describe_source(case.mesh)),
        Stage(
            "space",
            True,
            f"vector P{order} tetrahedra{formulation}, {QUADRATURE_POINTS[order]} quadrature "
            "point(s) per tet",
        ),
        Stage("loads", True, loads),
        *_finite_elements(case),
        _plasticity(case),
        _fracture(case),
        _fragments(case),
        Stage("output", True, fields + _cadence(analysis)),
    ]


def _finite_elements(case: Case) -> list[Stage]:
    analysis = case.analysis
    if case.fragments is not None and case.fragments.whole_body:
        grid = time_grid(analysis)
        return [Stage("stiffness", False, "the body is rigid"),
                Stage("mass", True, _mass(analysis).detail + ", for the momenta at hand-off"),
                Stage("solve", True, f"rigid-body motion, {grid.steps} steps of {grid.dt:.4g} "
                      f"to t = {grid.t_end:.4g}: gravity exact, torque-free rotation by exact "
                      "principal-axis rotations, ground contact by impulses")]
    return [Stage("stiffness", True, "isotropic linear elasticity, assembled once"),
            _mass(analysis), *_initial(analysis), Stage("solve", True, _solve(analysis))]


def _initial(analysis) -> list[Stage]:
    """Dynamic: the state at t = 0 (static analyses start from the loads at t = 0)."""
    if not isinstance(analysis, DynamicAnalysis):
        return []
    spec, v0 = analysis.initial_displacement, analysis.initial_velocity
    moving = ", moving with initial_velocity" if v0 is not None else ""
    if spec is None:
        return [Stage("initial", False, f"undeformed{moving}")]
    if spec.preload is not None:
        text = (f"the static equilibrium under a preload of "
                f"{len(spec.preload.boundary_conditions)} condition(s), removed at t = 0+")
    elif spec.field is not None:
        text = "a displacement field of x, y, z"
    else:
        text = f"the last frame of the run in {spec.from_run.directory}" + (
            " with its velocity" if spec.from_run.velocity else "")
    return [Stage("initial", True, f"displaced: {text}{moving}; acceleration balanced")]


def _mass(analysis) -> Stage:
    if not isinstance(analysis, DynamicAnalysis):
        return Stage("mass", False, f"{analysis.type} analysis needs no mass matrix")
    damping = ""
    if analysis.rayleigh is not None:
        damping = (f", Rayleigh damping {analysis.rayleigh.mass:g} M + "
                   f"{analysis.rayleigh.stiffness:g} K")
    return Stage("mass", True, f"{analysis.mass_kind} mass{damping}")


def _solve(analysis) -> str:
    grid = time_grid(analysis)
    if isinstance(analysis, StaticAnalysis):
        text = "static, one step"
    elif isinstance(analysis, DynamicAnalysis):
        text = {
            "newmark": f"implicit Newmark (beta {analysis.newmark_beta:g}, "
                       f"gamma {analysis.newmark_gamma:g})",
            "hht": f"implicit HHT-alpha (alpha {analysis.alpha:g})",
            "central_difference": "explicit central difference",
        }[analysis.integrator]
        text += f", {grid.steps} steps of {grid.dt:.4g} to t = {grid.t_end:.4g}"
    else:
        text = f"quasi-static, {grid.steps} load steps of {grid.dt:.4g} to t = {grid.t_end:.4g}"
    if isinstance(analysis, DynamicAnalysis) and analysis.integrator == "central_difference":
        return text + ("; substeps below the stable step" if analysis.substeps else "")
    return text + f", linear solver {_solver(analysis.linear_solver)}"


def _plasticity(case: Case) -> Stage:
    if case.plasticity is None:
        return Stage("plasticity", False, "not requested")
    p, eq = case.plasticity, case.analysis.equilibrium
    law = "perfectly plastic" if p.hardening == 0 else f"isotropic hardening H = {p.hardening:g}"
    iteration = {
        "modified_newton": "modified Newton (elastic matrix factorized once)",
        "newton": "full Newton (consistent tangent, refactorized per iteration)",
        "single_pass": "single pass (no equilibrium iteration)",
    }[eq.method]
    if case.analysis.type == "dynamic" and case.analysis.integrator == "central_difference":
        iteration = "explicit: return map once per step"
    else:
        if eq.method == "modified_newton" and eq.acceleration == "anderson":
            iteration += ", Anderson-accelerated"
        iteration += f", relative residual <= {eq.tolerance:g}"
    return Stage("plasticity", True,
                 f"von Mises radial return, yield stress {p.yield_stress:g}, {law}; {iteration}")


def _fracture(case: Case) -> Stage:
    f = case.fracture
    if f is None:
        return Stage("fracture", False, "not requested")
    s = f.smoothing
    size = f"length {s.length:g}" if s.length is not None else f"{s.rings} ring(s)"
    what = (f"normal stress on {len(f.planes)} prescribed plane(s)" if f.planes
            else "max principal stress")
    text = (f"smoothed ({s.method}, {size}) {what} > {f.tensile_strength:g} opens "
            f"cracks by face separation: up to {f.batch_size} site(s) a batch, "
            f"{f.passes} re-solve(s) and {f.max_insertions_per_step} site(s) a step")
    if f.perturbation is not None:
        text += f"; normals tilted up to {f.perturbation.angle:g} deg (seed {f.perturbation.seed})"
    if f.protect:
        text += f"; {len(f.protect)} protected part(s)"
    law = f.cohesive_law
    front = (", each front element against its own stress"
             if law is not None and law.front_stress == "element" else "")
    text += (f"; faces cohesive ({law.law} softening, G_c {f.fracture_energy:g}), growing "
             f"from crack fronts{front}" if law is not None else "; faces traction-free")
    return Stage("fracture", True, text)


def _fragments(case: Case) -> Stage:
    f = case.fragments
    if f is not None and f.whole_body:
        return Stage("fragments", True, "the whole body is one rigid body from the start "
                     "(exact mass properties; no finite-element solve)"
                     + _ground(f, case.obstacles))
    if case.fracture is None:
        return Stage("fragments", False, "not requested")
    text = ("connected components over shared faces after every insertion (fragment_id, "
            "count in history.csv); ")
    if f is None or f.become_rigid == "never":
        return Stage("fragments", True, text + "free pieces stay deformable")
    rule = {"all": "every free piece", "small": f"free pieces up to volume {f.max_volume}",
            "settled": f"free pieces once their vibration is below {f.vibration_tolerance:g} "
                       "of their rigid kinetic energy"}[f.become_rigid]
    return Stage("fragments", True, text + f"{rule} becomes a rigid body"
                 + _ground(f, case.obstacles))


def _ground(f, obstacles=()) -> str:
    bodies = "" if not obstacles else \
        f"; {len(obstacles)} obstacle(s) (fem-frac check lists them)"
    if f.finite_element_contact:
        bodies += "; rigid bodies touch the finite elements (impulses through the lumped mass)"
    if not f.ground:
        return ("; no ground" if not obstacles else "") + bodies
    return "; " + ", ".join(f"ground through {list(g.point)} normal {list(g.normal)} "
                            f"(restitution {g.restitution:g}, friction {g.friction:g})"
                            for g in f.ground) + bodies


def _cadence(analysis) -> str:
    if isinstance(analysis, StaticAnalysis):
        return ""
    every = analysis.output_every
    return "; output at t = 0 and every step" if every == 1 else \
        f"; output at t = 0, every {every} steps and the last"


def _solver(method: str) -> str:
    from ..solve.linalg import available_methods

    return f"auto ({available_methods()[0]})" if method == "auto" else method


def format_plan(plan: list[Stage]) -> str:
    width = max(len(s.name) for s in plan)
    rows = [f"  {'run ' if s.runs else 'skip'}  {s.name:<{width}}  {s.detail}" for s in plan]
    return "\n".join(rows)
