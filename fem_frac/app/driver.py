"""Run a case: validate and discretize it, compose the stages it asks for, march the world
through the time grid, write the output. Knows the order of the stages, not how any of them
works."""

from __future__ import annotations

import signal
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..cohesive.interface import InterfaceRecipe
from ..cohesive.law import TractionSeparation
from ..config.schema import Case, DynamicAnalysis, StaticAnalysis
from ..errors import CaseError, Interrupted, SolverError
from ..mesh.build import build_mesh
from ..solve.discretization import Discretization, Log, Recipe, discretize, quiet
from ..solve.energy import initial_ledger
from ..solve.loading import TimeGrid, time_grid
from ..solve.state import initial_state
from ..solve.stepping import ImplicitStepper
from ..timing import StageTimer
from ..world.equilibrium import EquilibriumStage
from ..world.stage import Stage, march
from ..world.state import World, body_of
from ..writers.directory import Manifest, check_directory, prepare_directory
from ..writers.ground import ObstacleSeries, write_ground
from ..writers.history import HistoryWriter
from ..writers.paraview import view_scale, write_paraview_script
from ..writers.series import SeriesWriter, series_writer
from ..writers.vtkhdf import check_format
from .budget import BOUNDS, Bounds, check_budget
from .initial import (  # noqa: F401 (initial_velocity: re-exported)
    check_initial,
    describe_initial,
    first_state,
    initial_velocity,
)
from .locking import locking_warnings
from .output import OutputPlan, OutputStage, Progress, Tally, TallyStage
from .probes import check_probes, probe_recorder
from .reference import check_reference, recorder, reference_error
from .results import CrackWriter, Layout, summary
from .status import NUMERICAL, RunStatus, terminated_as_interrupt, write_json
from .substeps import SubstepRows


@dataclass(frozen=True, eq=False)
class Setup:
    """A validated case ready to step: its time grid and the discretization of its mesh."""

    case: Case
    grid: TimeGrid
    disc: Discretization
    case_dir: Path = Path(".")  # where the case file lies (paths in it are relative to it)
    obstacles: tuple = ()  # the case's obstacles (fem_frac.rigid.obstacles.Obstacle)

    @property
    def dynamic(self) -> bool:
        return isinstance(self.case.analysis, DynamicAnalysis)


def recipe_of(case: Case, dt: float) -> Recipe:
    """The sections of ``case`` that say how to discretize a mesh."""
    return Recipe(case.mesh.order, case.mesh.formulation, case.material, tuple(case.regions),
                  case.plasticity, tuple(case.boundary_conditions), case.body_force,
                  case.load_curves, case.analysis, dt, interface_recipe(case.fracture))


def interface_recipe(fracture) -> InterfaceRecipe | None:
    """The cohesive faces' law of a ``fracture`` section, ``None`` when cracks are
    traction-free."""
    law = fracture.cohesive_law if fracture is not None else None
    if law is None:
        return None
    sigma, energy = fracture.tensile_strength, fracture.fracture_energy
    with np.errstate(over="ignore", under="ignore"):
        scales = (2.0 * energy / sigma, 2.0 * sigma**2 / energy)  # lambda_c, the least k0
    if not all(np.isfinite(x) and x > 0.0 for x in scales):
        raise CaseError(("fracture", "fracture_energy"),
                        f"G_c = {energy:g} with tensile_strength {sigma:g} is out of range: "
                        f"the critical opening 2 G_c / sigma_t = {scales[0]:g} and the "
                        f"faces' least stiffness 2 sigma_t^2 / G_c = {scales[1]:g} must be "
                        "finite and positive (is the unit right?)")
    return InterfaceRecipe(TractionSeparation(law.law, fracture.tensile_strength,
                                              fracture.fracture_energy, law.shear_weight),
                           law.penalty, law.quadrature)


def check_stages(case: Case) -> None:
    """Sections that only make sense together (located at the section that asks)."""
    check_format(case.output)
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
    if f.finite_element_contact and case.analysis.mass_kind != "lumped":
        raise CaseError(("analysis", "mass"), "fragments.finite_element_contact exchanges "
                        "impulses through the nodes' lumped masses: set analysis.mass: lumped "
                        f"(the {case.analysis.integrator} integrator's mass is "
                        f"{case.analysis.mass_kind})")
    if f.finite_element_contact and case.analysis.substeps:
        raise CaseError(("analysis", "substeps"), "fragments.finite_element_contact acts "
                        "between steps and predicts the finite elements' motion over the next "
                        "one from v + dt a / 2, which central difference's substeps do not "
                        "follow: take dt at most the stable step (fem-frac check prints it), "
                        "or newmark with analysis.mass: lumped")


def prepare(case: Case, case_dir: Path, timer: StageTimer, log: Log = quiet,
            bounds: Bounds | None = BOUNDS) -> Setup:
    """Everything before the first step; every input error is raised here, and the work
    the case implies is refused over ``bounds`` (``None``: no bound) before meshing."""
    check_stages(case)
    check_reference(case)
    check_initial(case, case_dir)
    check_budget(case, case_dir, bounds)
    from ..rigid.obstacles import build_obstacles

    obstacles = build_obstacles(case.obstacles, case_dir, case.fragments is not None)
    with timer("mesh"):
        mesh = build_mesh(case.mesh, case_dir)
    log(f"mesh       {mesh.n_tets:,} tets, {mesh.n_points:,} vertices")
    if case.fracture is not None:
        from ..fracture.stage import protected_vertices

        protected_vertices(case.fracture, mesh)  # names and boxes checked here
    grid = time_grid(case.analysis)
    disc = discretize(recipe_of(case, grid.dt), mesh, timer, log=log)
    check_probes(case, disc)
    log(f"space      P{disc.space.order}, {disc.space.n_dofs:,} dofs")
    # the initial displacement, checked here with the rest of the input
    initial = describe_initial(case, disc.space, disc.problem, case_dir)
    if initial is not None:
        log(f"initial    {initial}")
    return Setup(case, grid, disc, case_dir, obstacles)


def whole_body(case: Case) -> bool:
    return case.fragments is not None and case.fragments.whole_body


def start(setup: Setup, timer: StageTimer, log: Log = quiet) -> tuple[World, Tally]:
    """The world at t = 0, and the tally of what making it cost (the factorization of an
    implicit step's matrix, made here once)."""
    case, d = setup.case, setup.disc
    solver, factorizations = "", 0
    if isinstance(d.stepper, ImplicitStepper) and not whole_body(case):
        with timer("factorize"):
            factor = d.stepper.elastic_factor()
        solver, factorizations = factor.method, 1
        log(f"factorize  {factor.method}, {len(d.constrained.free):,} unknowns")
    with timer("initial state"):
        state = first_state(case, d, setup.case_dir) if setup.dynamic else \
            initial_state(d.problem, d.law, d.ops, None, d.constrained)
        if not setup.dynamic and (np.any(d.problem.external_force(0.0))
                                  or np.any(state.reaction)):
            # without inertia the state at t = 0 is the equilibrium under the loads at
            # t = 0 (a load on a 'constant' curve is on from the start); its energy is the
            # ledger's initial energy
            state, _ = d.stepper.step(state, 0.0, 0)
    body = body_of(d, state)
    world = World(0.0, body, initial_ledger(state, d.law, d.ops))
    if case.fragments is not None:
        from ..rigid import obstacles as obstacle
        from ..rigid.obstacle_output import rigid_bodies
        from ..rigid.stage import planes

        f = case.fragments
        gravity = f.gravity if f.gravity is not None else (
            case.body_force.gravity if case.body_force is not None else (0.0, 0.0, 0.0))
        # moving obstacles are the first rigid bodies; obstacle planes join the ground
        world = World(0.0, body, world.ledger,
                      obstacles=planes(f) + obstacle.planes(setup.obstacles),
                      gravity=np.asarray(gravity, dtype=float),
                      rigid=rigid_bodies(setup.obstacles, d.space.order))
    return world, Tally(body, solver, factorizations)


def stages(setup: Setup, timer: StageTimer, log: Log = quiet) -> list[Stage]:
    """The stages the case asks for, in order (the output comes last, from the caller)."""
    case = setup.case
    out: list[Stage] = [EquilibriumStage()]
    if case.fracture is not None:
        from ..fracture.stage import FractureStage

        out.append(FractureStage(case.fracture, setup.dynamic, timer, log,
                                 getattr(log, "note", None)))
    if case.fragments is not None:
        from ..rigid.obstacles import bodies
        from ..rigid.stage import RigidStage

        out.append(RigidStage(case.fragments, timer, log, obstacles=bodies(setup.obstacles)))
        if case.fragments.finite_element_contact:
            from ..rigid.stage import ElementContactStage

            out.append(ElementContactStage(case.fragments, bodies(setup.obstacles)))
    return out


def times(grid: TimeGrid) -> np.ndarray:
    return np.array([grid.time(n) for n in range(grid.steps + 1)])


def simulate(setup: Setup, timer: StageTimer, log: Log = quiet,
             observers: tuple[Stage, ...] = ()) -> tuple[World, Tally]:
    """Every step of the case without files: the last world and the tally; ``observers``
    (stages that return the world they are given) run last in every step."""
    world, tally = start(setup, timer, log)
    with timer("steps"):
        world = march(world, [*stages(setup, timer, log), TallyStage(tally), *observers],
                      times(setup.grid), timer)
    return world, tally


def layout_of(case: Case) -> Layout:
    return Layout(isinstance(case.analysis, DynamicAnalysis), case.fracture is not None,
                  case.fragments is not None)


def output_plan(case: Case, grid: TimeGrid) -> OutputPlan:
    every = None if isinstance(case.analysis, StaticAnalysis) else case.analysis.output_every
    return OutputPlan(grid.steps, every)


def output_location(case: Case, case_path: Path, directory: str | None) -> tuple[Path, str]:
    name = case.output.name or case_path.stem
    chosen = directory or case.output.directory or str(Path("out") / case_path.stem)
    return Path(chosen), name


def run_case(case: Case, case_path: Path, out_dir: Path, name: str, overwrite: bool = False,
             log: Log = quiet, resolved_yaml: str | None = None,
             bounds: Bounds | None = BOUNDS) -> dict:
    """Run a case end to end and write its output. Returns the summary.

    The resolved case and a summary marked ``running`` are written before the first step
    (:mod:`~fem_frac.app.status`); an interrupted or failed run marks the summary with the
    step it reached and raises on (:class:`~fem_frac.errors.Interrupted`, the exception
    that stopped it), its output kept. A numerical failure while discretizing (after
    validation) claims the output directory too, so that every run that stops with exit 3
    leaves ``summary.json`` and ``case.resolved.yaml``."""
    timer = StageTimer()
    check_directory(out_dir, name, overwrite)  # an occupied directory: before meshing
    try:
        setup = prepare(case, case_path.parent, timer, log, bounds)
    except NUMERICAL as exc:
        _, status = _claim(out_dir, name, overwrite, resolved_yaml, case_path,
                           time_grid(case.analysis).steps)
        status.fail(exc, {"wall_time_s": _wall(timer), "cpu_time_s": timer.cpu()})
        raise
    # after validation (a bad case never touches earlier results), before the long stages
    manifest, status = _claim(out_dir, name, overwrite, resolved_yaml, case_path,
                              setup.grid.steps)
    warn_locking(setup)
    with terminated_as_interrupt():
        try:
            result = _run(setup, case_path, name, manifest, status, timer, log)
        except (KeyboardInterrupt, Interrupted) as exc:
            signum = exc.signum if isinstance(exc, Interrupted) else signal.SIGINT
            status.record("interrupted", message=f"interrupted by {signal.Signals(signum).name}"
                          f" at step {status.step} of {status.steps}; output so far kept")
            raise Interrupted(signum, status.step, status.steps, out_dir) from None
        except Exception as exc:  # every failure leaves its summary (then the CLI's exit)
            status.fail(exc, _known(setup, case_path, status, timer))
            raise
    write_json(out_dir / "summary.json", result)
    _warn_single_pass(case, setup, status.tally)
    log(f"output     {result['output'][_SERIES_KEY[case.output.format]]}")
    return result


# summary.json's key of the series file, by output.format
_SERIES_KEY = {"vtu": "pvd", "vtkhdf": "vtkhdf"}


def _claim(out_dir: Path, name: str, overwrite: bool, resolved_yaml: str | None,
           case_path: Path, steps: int) -> tuple[Manifest, RunStatus]:
    """Take the output directory: the resolved case and a summary marked ``running``."""
    prepare_directory(out_dir, name, overwrite)
    manifest = Manifest(out_dir)
    if resolved_yaml is not None:
        manifest.add("case.resolved.yaml").write_text(resolved_yaml)
    manifest.add("summary.json")
    status = RunStatus(out_dir / "summary.json", case_path, steps)
    status.record("running")
    return manifest, status


def _run(setup: Setup, case_path: Path, name: str, manifest: Manifest, status: RunStatus,
         timer: StageTimer, log: Log) -> dict:
    """The steps and the files of a run whose directory is claimed: its summary."""
    case, out_dir = setup.case, manifest.directory
    ground = None
    if case.fragments is not None:  # the planes fragments rest on, once: they never move
        from ..rigid.stage import planes

        ground = write_ground(manifest, name, planes(case.fragments), setup.disc.mesh.points)
    series = series_writer(out_dir, name, manifest=manifest,
                           compression=case.output.compression, format=case.output.format)
    shown = _obstacle_series(setup, manifest, name)
    world, tally, record = _march(setup, manifest, series, status, timer, log,
                                  () if shown is None else (shown,))
    result = _summary(case, case_path, setup, world, tally, timer, log, record)
    result["output"] = {_SERIES_KEY[case.output.format]: str(series.path),
                        "steps": len(series.entries),
                        "history": str(out_dir / "history.csv")}
    if case.probes:
        result["output"]["probes"] = str(out_dir / f"{name}_probes.csv")
    manifest.add(f"{name}_view.py")
    result["output"]["view"] = str(write_paraview_script(
        out_dir, name, view_scale(result["max_displacement"], setup.disc.mesh.points),
        case.fracture is not None and case.output.crack_surface, ground=ground is not None,
        obstacles=shown is not None, suffix=series.path.suffix))
    if ground is not None:
        result["output"]["ground"] = str(ground)
    if shown is not None:
        result["output"]["obstacles"] = str(shown.series.path)
    return result


def _obstacle_series(setup: Setup, manifest: Manifest, name: str) -> ObstacleSeries | None:
    """The series of the case's fixed obstacles and planes (``None`` without any)."""
    from ..rigid.obstacle_output import fixed_surface

    surface = fixed_surface(setup.obstacles, setup.disc.mesh.points)
    if surface is None:
        return None
    return ObstacleSeries(manifest, name, output_plan(setup.case, setup.grid).due, *surface,
                          format=setup.case.output.format)


def _known(setup: Setup, case_path: Path, status: RunStatus, timer: StageTimer) -> dict:
    """What the summary of a failed run can say: the summary of its last completed step
    (counts, costs and energies of the steps completed) and the wall times so far."""
    d = setup.disc
    known = {"counts": {"vertices": d.mesh.n_points, "nodes": d.space.n_nodes,
                        "elements": d.mesh.n_tets, "dofs": d.space.n_dofs,
                        "constrained_dofs": int(len(d.problem.constraints.dofs)),
                        "element_order": d.space.order,
                        "formulation": setup.case.mesh.formulation}}
    if status.world is not None and status.tally is not None:
        try:
            known = summary(setup.case, case_path, setup.grid, status.world, status.tally)
        except Exception:  # noqa: BLE001 (the failure is reported, whatever this one is)
            pass
    known["wall_time_s"] = _wall(timer)
    known["cpu_time_s"] = timer.cpu()
    return known


def _wall(timer: StageTimer) -> dict:
    return {**{k: round(v, 6) for k, v in timer.seconds.items()},
            "total": round(timer.total(), 6)}


def _march(setup: Setup, manifest: Manifest, series: SeriesWriter, status: RunStatus,
           timer: StageTimer, log: Log, shown: tuple = ()):
    """Every step of the case with its output: the last world, the tally and the
    reference's recorder (``None`` when the case declares none that needs one)."""
    case, out_dir = setup.case, manifest.directory
    cracks = CrackWriter(series_writer(out_dir, f"{series.name}_crack", manifest=manifest,
                                       compression=series.compression,
                                       format=case.output.format)) \
        if case.fracture is not None and case.output.crack_surface else None
    world, tally = start(setup, timer, log)
    status.tally = tally
    record = recorder(case, setup.disc.problem)
    probes = probe_recorder(case, manifest, series.name)
    observers = tuple(o for o in (record, probes) if o is not None) + shown + (status,)
    with HistoryWriter(manifest.add("history.csv")) as history:
        output = OutputStage(output_plan(case, setup.grid), layout_of(case), series, history,
                             tally, timer, cracks, Progress(log, setup.grid.steps), observers)
        substeps = SubstepRows(history, layout_of(case), timer, series)
        with timer("steps"):
            try:
                world = march(world, [*stages(setup, timer, log), substeps, output],
                              times(setup.grid), timer)
            except SolverError as exc:  # what converged of the step is kept
                substeps.failed(exc, status.step + 1)
                raise
    return world, tally, record


def _summary(case: Case, case_path: Path, setup: Setup, world: World, tally: Tally,
             timer: StageTimer, log: Log, record) -> dict:
    result = {"status": "completed", **summary(case, case_path, setup.grid, world, tally)}
    result["wall_time_s"] = _wall(timer)
    result["cpu_time_s"] = timer.cpu()
    if case.reference is not None:
        body = world.body or tally.body
        ref = reference_error(case, setup.grid, body.disc, body.state, record)
        result["reference"] = ref
        log(f"reference  {ref['solution']}: {ref['quantity']} {ref['computed']:.6g}, exact "
            f"{ref['exact']:.6g}, relative error {ref['relative_error']:+.3e}")
    return result


def warn_locking(setup: Setup) -> None:
    """Before the first step: the reasons the case's elements will be too stiff
    (:mod:`~fem_frac.app.locking`), one ``warning:`` line each on stderr."""
    d = setup.disc
    for text in locking_warnings(setup.case, d.mesh, d.materials, d.problem):
        print(f"warning: {text}", file=sys.stderr)


# A single-pass run whose residual exceeds this is reported as out of equilibrium.
SINGLE_PASS_WARNING = 1e-2


def _warn_single_pass(case: Case, setup: Setup, tally: Tally) -> None:
    eq = getattr(case.analysis, "equilibrium", None)
    if (eq is not None and eq.method == "single_pass" and setup.disc.law.plastic
            and tally.max_residual > SINGLE_PASS_WARNING):
        print(f"warning: single_pass left a relative residual of up to "
              f"{tally.max_residual:.2e} (> {SINGLE_PASS_WARNING:g}): the states are not in "
              "equilibrium; use modified_newton or smaller steps", file=sys.stderr)
