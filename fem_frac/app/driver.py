"""Compose the stages a case asks for. Knows the order of stages, not how any of them works."""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from ..config.schema import Case, DynamicAnalysis, StaticAnalysis
from ..errors import CaseError, SolverError
from ..fem.space import Space, build_space
from ..mesh.build import build_mesh
from ..mesh.mesh import Mesh
from ..plasticity.law import MaterialLaw, material_law
from ..plasticity.regions import ElementMaterials, element_materials
from ..solve import integrators
from ..solve.integrators import Implicit
from ..solve.loading import TimeGrid, time_grid
from ..solve.problem import Problem, build_problem, free_rigid_modes
from ..solve.stable_step import ExplicitLimit, explicit_limit
from ..solve.stepping import (
    Constrained,
    Counters,
    Equilibrium,
    ExplicitStepper,
    ImplicitStepper,
    Ledger,
    Observer,
    Operators,
    State,
    StepInfo,
    initial_state,
    march,
)
from ..timing import StageTimer
from ..verify.reference import Recorder, check_reference, reference_error
from ..writers.directory import prepare_directory
from ..writers.history import HistoryWriter
from ..writers.series import SeriesWriter
from . import results
from .results import fracture_row, history_row, rigid_row, write_crack_surface, write_step

Log = Callable[[str], None]


def quiet(_: str) -> None:
    pass


@dataclass(frozen=True, eq=False)
class Model:
    mesh: Mesh
    space: Space
    problem: Problem
    materials: ElementMaterials


def build_model(case: Case, case_dir: Path, timer: StageTimer, log: Log = quiet) -> Model:
    """Mesh, function space, supports and loads: everything before assembly."""
    with timer("mesh"):
        mesh = build_mesh(case.mesh, case_dir)
    log(f"mesh       {mesh.n_tets:,} tets, {mesh.n_points:,} vertices")
    model = model_on(case, mesh, timer)
    log(f"space      P{model.space.order}, {model.space.n_dofs:,} dofs")
    return model


def model_on(case: Case, mesh: Mesh, timer: StageTimer, strict: bool = True) -> Model:
    """Function space, materials, supports and loads of ``case`` on ``mesh`` (also a mesh
    that crack insertion made: named groups follow the faces they named; ``strict=False``
    lets a condition whose faces left with a rigid piece act on nothing)."""
    with timer("space"):
        space = build_space(mesh, case.mesh.order)
    with timer("loads"):
        materials = element_materials(case.material, case.regions, mesh)
        problem = build_problem(
            space, case.boundary_conditions, case.body_force, materials.density,
            case.analysis, case.load_curves, strict,
        )
    return Model(mesh, space, problem, materials)


def output_location(case: Case, case_path: Path, directory: str | None) -> tuple[Path, str]:
    name = case.output.name or case_path.stem
    chosen = directory or case.output.directory or str(Path("out") / case_path.stem)
    return Path(chosen), name


def build_operators(model: Model, case: Case, law: MaterialLaw, timer: StageTimer) -> Operators:
    """Strain operator and elastic stiffness; mass and damping when the analysis is
    dynamic."""
    from ..fem.operators import strain_operator

    space, analysis = model.space, case.analysis
    with timer("assemble"):
        op = strain_operator(space, case.mesh.formulation)
        d = law.elastic_tangent
        if d.ndim == 4:  # per element: one value for every quadrature point
            d = np.ascontiguousarray(np.broadcast_to(d, (6, 6) + op.weights.shape))
        k = op.stiffness(d)
    mass = damping = None
    if isinstance(analysis, DynamicAnalysis):
        from ..fem.mass import consistent_mass, lumped_mass

        with timer("mass"):
            density = model.materials.density
            if _mass_kind(analysis) == "lumped":
                mass = sp.diags(lumped_mass(space, density)).tocsr()
            else:
                mass = consistent_mass(space, density)
            if analysis.rayleigh is not None:
                r = analysis.rayleigh
                damping = (r.mass * mass + r.stiffness * k).tocsr()
    return Operators(op, k, mass, damping)


def _mass_kind(analysis: DynamicAnalysis) -> str:
    if analysis.mass is not None:
        return analysis.mass
    return "lumped" if analysis.integrator == "central_difference" else "consistent"


def initial_velocity(space: Space, spec) -> np.ndarray | None:
    """Nodal velocity ``(n_dofs,)`` of a uniform motion plus a rigid rotation."""
    if spec is None:
        return None
    x = space.node_points
    center = np.asarray(spec.center) if spec.center is not None else x.mean(axis=0)
    v = np.asarray(spec.uniform) + np.cross(np.asarray(spec.angular_velocity), x - center)
    return v.ravel()


def scheme(analysis, dt: float) -> Implicit:
    if isinstance(analysis, DynamicAnalysis):
        if analysis.integrator == "hht":
            return integrators.hht(dt, analysis.alpha)
        return integrators.newmark(dt, analysis.beta, analysis.gamma)
    return integrators.quasi_static(dt)


def explicit_substeps(limit: ExplicitLimit, dt: float, allow: bool) -> int:
    """Substeps per step for central difference; refuses ``dt`` above the limit unless
    ``allow``."""
    if dt <= limit.dt:
        return 1
    if not allow:
        raise CaseError(
            ("analysis", "dt"),
            f"time step {dt:.4g} exceeds the stable step of central difference "
            f"{limit.dt:.4g} (2/omega_max, {limit.method}); use dt <= {limit.dt:.4g}, "
            "an implicit integrator, or substeps: true",
        )
    return int(np.ceil(dt / limit.dt))


@dataclass(frozen=True, eq=False)
class Discretization:
    """What one mesh provides: the model, operators, constrained split and stepper (and the
    explicit stable step). Rebuilt after every topology change."""

    model: Model
    ops: Operators
    constrained: Constrained
    stepper: object
    limit: ExplicitLimit | None
    law: MaterialLaw


@dataclass(frozen=True, eq=False)
class Setup:
    """A validated case ready to step: model, law, time grid, operators and stepper."""

    case: Case
    model: Model
    law: MaterialLaw
    grid: TimeGrid
    ops: Operators
    constrained: Constrained
    stepper: object
    limit: ExplicitLimit | None

    @property
    def dynamic(self) -> bool:
        return isinstance(self.case.analysis, DynamicAnalysis)

    @property
    def discretization(self) -> Discretization:
        return Discretization(self.model, self.ops, self.constrained, self.stepper, self.limit,
                              self.law)


def check_stages(case: Case) -> None:
    """Sections that only make sense together (located at the section that asks)."""
    f = case.fragments
    if f is None:
        return
    if case.analysis.type != "dynamic":
        raise CaseError(("fragments",), "fragments need a dynamic analysis (rigid bodies "
                        "move in time)")
    if f.whole_body and case.fracture is not None:
        raise CaseError(("fragments", "whole_body"), "whole_body makes the body rigid: it "
                        "cannot fracture (drop one of the two)")
    if not f.whole_body and case.fracture is None:
        raise CaseError(("fragments",), "fragments need a fracture section (pieces break "
                        "free) or whole_body: true")


def prepare(case: Case, case_dir: Path, timer: StageTimer, log: Log = quiet) -> Setup:
    """Everything before the first step; every input error is raised here."""
    analysis = case.analysis
    check_stages(case)
    check_reference(case)
    model = build_model(case, case_dir, timer, log)
    space, problem = model.space, model.problem
    dynamic = isinstance(analysis, DynamicAnalysis)
    if dynamic and not model.materials.has_density():
        raise CaseError(("material", "density"), "a dynamic analysis needs material.density "
                        "(for every element)")
    if not dynamic:
        free = free_rigid_modes(space, problem.constraints.dofs)
        if free:
            raise CaseError(
                ("boundary_conditions",),
                "the supports leave rigid-body motions free (" + ", ".join(free) + "): "
                "a static solve is singular; add supports (fixed, displacement, symmetry)",
            )
    if case.fracture is not None:
        from ..fracture.stage import protected_vertices

        protected_vertices(case.fracture, model.mesh)  # names and boxes checked here
    law = material_law(model.materials, case.plasticity)
    grid = time_grid(analysis)
    d = discretize(case, model, law, grid.dt, timer, log)
    return Setup(case, d.model, law, grid, d.ops, d.constrained, d.stepper, d.limit)


def discretize(case: Case, model: Model, law: MaterialLaw, dt: float, timer: StageTimer,
               log: Log = quiet) -> Discretization:
    """Operators and stepper of ``model`` (factorization deferred to the first step)."""
    analysis = case.analysis
    explicit = isinstance(analysis, DynamicAnalysis) and (
        analysis.integrator == "central_difference")
    problem = model.problem
    ops = build_operators(model, case, law, timer)
    constrained = Constrained(problem, analysis.linear_solver)
    limit = None
    if explicit:
        with timer("time step"):
            r = analysis.rayleigh
            m = model.materials
            limit = explicit_limit(
                model.space, ops.stiffness, ops.mass.diagonal(), constrained.free,
                m.youngs_modulus, m.poissons_ratio, m.density,
                r.mass if r else 0.0, r.stiffness if r else 0.0,
            )
        substeps = explicit_substeps(limit, dt, analysis.substeps)
        log(f"time step  dt {dt:.4g}, stable limit {limit.dt:.4g} ({limit.method})"
            + (f", {substeps} substeps per step" if substeps > 1 else ""))
        stepper = ExplicitStepper(problem, law, ops, dt, substeps, constrained)
    else:
        equilibrium = Equilibrium(**analysis.equilibrium.model_dump())
        stepper = ImplicitStepper(problem, law, ops, scheme(analysis, dt), equilibrium,
                                  constrained)
    return Discretization(model, ops, constrained, stepper, limit, law)


def fracture_stage(setup: Setup, timer: StageTimer, log: Log = quiet):
    """The fracture stage of a case with a ``fracture:`` section (``None`` without)."""
    case = setup.case
    if case.fracture is None:
        return None
    from ..fracture.stage import FractureStage

    def build(mesh: Mesh) -> Discretization:
        with timer("fracture rebuild"):
            model = model_on(case, mesh, timer, strict=False)
            # per-element properties follow the elements (a piece may have left the mesh)
            law = material_law(model.materials, case.plasticity)
            try:
                return discretize(case, model, law, setup.grid.dt, timer)
            except CaseError as exc:
                raise SolverError(f"after crack insertion: {exc.message}") from None

    return FractureStage(case.fracture, setup.discretization, build, setup.dynamic, log)


def rigid_stage(setup: Setup, fracture, log: Log = quiet):
    """The fragments stage of a case with a ``fragments:`` section (``None`` without)."""
    case = setup.case
    if case.fragments is None:
        return None
    from ..rigid.stage import RigidStage

    f = case.fragments
    gravity = f.gravity if f.gravity is not None else (
        case.body_force.gravity if case.body_force is not None else (0.0, 0.0, 0.0))
    return RigidStage(f, gravity, fracture, log)


class Chain:
    """Stages run in order after every step (fracture, then fragments); the last system a
    stage returns replaces the step loop's."""

    def __init__(self, *stages):
        self.stages = [s for s in stages if s is not None]

    def __call__(self, n, start, start_ledger, end, ledger, info):
        system = None
        for stage in self.stages:
            end, ledger, info, changed = stage(n, start, start_ledger, end, ledger, info)
            system = changed if changed is not None else system
        return end, ledger, info, system


def resting(d: Discretization, t: float) -> State:
    """A zero state of ``d`` at ``t``: what the finite elements report once none are left."""
    n = d.model.space.n_dofs
    z = np.zeros(n)
    return State(t, z, z, z, np.zeros((6,) + d.ops.weights.shape), None, z,
                 np.zeros(len(d.constrained.dofs)))


def simulate(setup: Setup, timer: StageTimer, observe: Observer, log: Log = quiet,
             fracture=None, rigid=None):
    """Factorize, take every step; ``observe(n, state, ledger, info)`` sees each committed
    step, step 0 included; ``fracture`` (a :class:`~fem_frac.fracture.stage.FractureStage`)
    and ``rigid`` (a :class:`~fem_frac.rigid.stage.RigidStage`) run after each. Once no
    finite element is left (or with ``fragments.whole_body``) only rigid bodies move.
    Returns ``(state, ledger, counters)``."""
    model, analysis = setup.model, setup.case.analysis
    counters = Counters()
    times = np.array([setup.grid.time(n) for n in range(setup.grid.steps + 1)])
    whole = rigid is not None and setup.case.fragments.whole_body
    if isinstance(setup.stepper, ImplicitStepper) and not whole:
        with timer("factorize"):
            factor = setup.stepper.elastic_factor()
        counters.solver = factor.method
        log(f"factorize  {factor.method}, {len(setup.constrained.free):,} unknowns")
    with timer("initial state"):
        v0 = initial_velocity(model.space, analysis.initial_velocity) if setup.dynamic else None
        state = initial_state(model.problem, setup.law, setup.ops, v0, setup.constrained,
                              analysis.linear_solver)
        problem = model.problem
        if not setup.dynamic and (np.any(problem.external_force(0.0))
                                  or np.any(state.reaction)):
            # without inertia the state at t = 0 is the equilibrium under the loads at
            # t = 0 (a load on a 'constant' curve is on from the start); its energy is the
            # ledger's initial energy
            state, _ = setup.stepper.step(state, 0.0, 0)
    if whole:
        from ..solve.stepping import initial_ledger

        d = setup.discretization
        body = rigid.hand_off(d, state, np.arange(model.mesh.n_tets))
        rigid.fragments.append(body)
        rigid.only = True
        ledger = initial_ledger(state, setup.law, setup.ops)
        ledger = replace(ledger, handed_off=ledger.kinetic + ledger.elastic, kinetic=0.0,
                         elastic=0.0)
        with timer("steps"):
            return march_rigid(rigid, times, 0, resting(d, 0.0), ledger, StepInfo(0, 0.0),
                               observe, counters)
    from ..rigid.stage import AllRigid

    with timer("steps"):
        try:
            state, ledger = march(setup.stepper, state, times, model.problem, setup.law,
                                  setup.ops, observe, counters,
                                  after_step=Chain(fracture, rigid))
        except AllRigid as done:
            counters.steps += 1
            d = fracture.current
            frozen = replace(done.ledger, kinetic=0.0, elastic=0.0)
            return march_rigid(rigid, times, done.step, resting(d, done.state.t), frozen,
                               done.info, observe, counters)
    return state, ledger, counters


def march_rigid(rigid, times: np.ndarray, n: int, state: State, ledger: Ledger,
                info: StepInfo, observe: Observer, counters: Counters):
    """Steps ``n`` (observed here) to the end with rigid bodies only."""
    observe(n, state, ledger, info)
    for k in range(n + 1, len(times)):
        rigid.move(float(times[k - 1]), float(times[k]))
        state = replace(state, t=float(times[k]))
        counters.steps += 1
        observe(k, state, ledger, StepInfo(0, 0.0))
    return state, ledger, counters


def run_case(
    case: Case,
    case_path: Path,
    out_dir: Path,
    name: str,
    overwrite: bool = False,
    log: Log = quiet,
    resolved_yaml: str | None = None,
) -> dict:
    """Run a case end to end and write its output. Returns the summary."""
    timer = StageTimer()
    setup = prepare(case, case_path.parent, timer, log)
    # after validation (a bad case never touches earlier results), before the long stages
    prepare_directory(out_dir, name, overwrite)
    writer = SeriesWriter(out_dir, name)
    output = OutputPlan(case.analysis, setup.grid.steps)
    progress = Progress(log, setup.grid.steps)
    recorder = Recorder(setup)
    fracture = fracture_stage(setup, timer, log)
    rigid = rigid_stage(setup, fracture, log)
    cracks = None
    if fracture is not None and case.output.crack_surface:
        cracks = SeriesWriter(out_dir, f"{name}_crack")
    with HistoryWriter(out_dir / "history.csv") as history:

        def observe(n: int, st: State, ledger: Ledger, info: StepInfo) -> None:
            current = fracture.current.model if fracture is not None else setup.model
            row = history_row(n, st, ledger, info, current.problem, timer.total())
            if fracture is not None:
                row.update(fracture_row(fracture, info))
            if rigid is not None:
                row.update(rigid_row(rigid))
            history.write(row)
            recorder(n, st)
            if output.due(n):
                with timer("output"):
                    write_step(writer, current.space, st, setup.dynamic, fracture, rigid)
                    if cracks is not None:
                        write_crack_surface(cracks, current.mesh, st,
                                            rigid is not None and rigid.only)
            progress(n, st, info)

        state, ledger, counters = simulate(setup, timer, observe, log, fracture, rigid)
    summary = results.summary(setup, case_path, state, ledger, counters, timer, fracture,
                              rigid)
    if case.reference is not None:
        summary["reference"] = reference_error(setup, state, recorder)
        ref = summary["reference"]
        log(f"reference  {ref['solution']}: {ref['quantity']} {ref['computed']:.6g}, exact "
            f"{ref['exact']:.6g}, relative error {ref['relative_error']:+.3e}")
    summary["output"] = {"pvd": str(writer.pvd_path), "steps": len(writer.entries),
                         "history": str(out_dir / "history.csv")}
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    if resolved_yaml is not None:
        (out_dir / "case.resolved.yaml").write_text(resolved_yaml)
    eq = getattr(case.analysis, "equilibrium", None)
    if (eq is not None and eq.method == "single_pass" and setup.law.plastic
            and counters.max_residual > SINGLE_PASS_WARNING):
        print(f"warning: single_pass left a relative residual of up to "
              f"{counters.max_residual:.2e} (> {SINGLE_PASS_WARNING:g}): the states are not in "
              "equilibrium; use modified_newton or smaller steps", file=sys.stderr)
    log(f"output     {writer.pvd_path}")
    return summary


# A single-pass run whose residual exceeds this is reported as out of equilibrium.
SINGLE_PASS_WARNING = 1e-2


@dataclass(frozen=True)
class OutputPlan:
    """Which steps are written: step 0 and every ``output_every``-th of a stepped analysis,
    always the last; a static analysis writes its one solution."""

    analysis: object
    steps: int

    def due(self, n: int) -> bool:
        if isinstance(self.analysis, StaticAnalysis):
            return n == self.steps
        return n == self.steps or n % self.analysis.output_every == 0


class Progress:
    """A line every ~2 s of wall time, and at the end (into ``log``)."""

    def __init__(self, log: Log, steps: int, every: float = 2.0):
        self.log, self.steps, self.every = log, steps, every
        self.last = time.perf_counter()

    def __call__(self, n: int, state: State, info: StepInfo) -> None:
        now = time.perf_counter()
        if n == 0 or (n < self.steps and now - self.last < self.every):
            return
        self.last = now
        self.log(f"step       {n}/{self.steps}  t = {state.t:.6g}  "
                 f"iterations {info.iterations}  residual {info.residual:.1e}")
