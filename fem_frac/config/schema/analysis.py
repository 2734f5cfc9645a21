"""``analysis``: static, quasi-static or dynamic, and how each step reaches equilibrium."""

from __future__ import annotations

import importlib.util
import os
from typing import Annotated, Literal

from pydantic import AfterValidator, Field, ValidationInfo, field_validator, model_validator

from ..expression import parse
from .base import FiniteFloat, NonNegativeFloat, PositiveFloat, PositiveInt, Section, Vector3
from .loads import BoundaryCondition

PETSC_INSTALL = "scripts/petsc-env.sh (docs/solvers.md, 'PETSc')"
# What MPI launchers (Open MPI's mpiexec, MPICH's Hydra) tell each process of the job's
# size: fem_frac.solve.ranks.MPI_SIZE_VARIABLES (config cannot import solve; a test keeps
# the two equal).
MPI_SIZE_VARIABLES = ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE")


def launched_ranks() -> int:
    """The number of MPI ranks this process was started among (1 outside ``mpiexec``)."""
    for name in MPI_SIZE_VARIABLES:
        value = os.environ.get(name, "")
        if value.isdigit():
            return int(value)
    return 1


# The optional solvers' packages, and how to get them.
_SOLVER_PACKAGES = {
    "pardiso": ("pypardiso", "pip install pypardiso (MKL, x86-64 only)"),
    "cholmod": ("sksparse", "apt install libsuitesparse-dev, then pip install scikit-sparse"),
}


def _solver_here(method: str) -> str:
    """``petsc``, ``pardiso`` and ``cholmod`` need their packages; several MPI ranks need a
    solver that uses them."""
    if method == "petsc" and importlib.util.find_spec("petsc4py") is None:
        raise ValueError(f"petsc4py is not installed; install it with {PETSC_INSTALL}, or "
                         "use linear_solver: auto")
    if method in _SOLVER_PACKAGES:
        package, install = _SOLVER_PACKAGES[method]
        if importlib.util.find_spec(package) is None:
            raise ValueError(f"{method} needs {package}, which is not installed ({install}); "
                             "or use linear_solver: auto")
    ranks = launched_ranks()
    if ranks > 1 and method not in ("auto", "petsc"):
        raise ValueError(f"{method} solves on one rank, and this run has {ranks} MPI ranks; "
                         "use linear_solver: petsc (or auto), or run without mpiexec")
    return method


LinearSolver = Annotated[Literal["auto", "pardiso", "cholmod", "superlu", "petsc"],
                         AfterValidator(_solver_here)]


class PetscOptions(Section):
    """How ``linear_solver: petsc`` solves (fem_frac/solve/petsc.py, docs/solvers.md).

    ``pc``: ``gamg`` (algebraic multigrid with the rigid-body modes as near-null space,
    the default), ``hypre`` (BoomerAMG) or ``mumps`` (a Cholesky factorization by MUMPS,
    distributed over the ranks). ``ksp``: the Krylov method, default ``cg`` (``preonly``
    with ``mumps``). ``rtol``: the relative residual each solve reaches (of the true
    residual; the default matches PARDISO's displacements to 1e-8). ``options``: further
    PETSc options, by name without the leading dash (``{pc_gamg_threshold: 0.02}``).
    """

    ksp: Literal["cg", "gmres", "preonly"] | None = None
    pc: Literal["gamg", "hypre", "mumps"] = "gamg"
    rtol: Annotated[float, Field(gt=0, lt=1, allow_inf_nan=False)] = 1e-10
    max_iterations: PositiveInt = 1000
    options: dict[str, str | int | float | bool] = {}

    @model_validator(mode="after")
    def _consistent(self):
        if self.ksp == "preonly" and self.pc != "mumps":
            raise ValueError(f"ksp: preonly applies the preconditioner once: with pc: {self.pc} "
                             "that is one multigrid cycle, not a solve; use ksp: cg")
        for name in self.options:
            if not name or name.startswith("-") or not all(c.isalnum() or c == "_"
                                                           for c in name):
                raise ValueError(f"options: {name!r} is not a PETSc option name (letters, "
                                 "digits and underscores, without the leading dash)")
        return self


# The Newmark integrator's defaults: average acceleration (unconditionally stable, no
# numerical damping). DynamicAnalysis.newmark_beta / newmark_gamma resolve them.
NEWMARK_BETA = 0.25
NEWMARK_GAMMA = 0.5


class Equilibrium(Section):
    """How each step reaches equilibrium when the material is nonlinear.

    ``modified_newton``: iterate with the elastic matrix factorized once (initial stiffness);
    ``newton``: the consistent tangent, reassembled and refactorized every iteration;
    ``single_pass``: one solve per step, the return map after it, no iteration (the residual
    left is reported, not reduced). ``tolerance`` bounds the residual norm relative to the
    largest force norm of the step. ``acceleration: anderson`` mixes the last iterates of
    modified Newton (Anderson acceleration), which cuts its iterations several-fold at the
    cost of a few dot products; ``none`` is the plain iteration. A static or quasi-static
    step that does not converge in ``max_iterations`` is halved, up to ``cutbacks`` times,
    before the run stops.
    """

    method: Literal["modified_newton", "newton", "single_pass"] = "modified_newton"
    acceleration: Literal["anderson", "none"] = "anderson"
    tolerance: PositiveFloat = 1e-8
    max_iterations: PositiveInt = 500
    cutbacks: Annotated[int, Field(ge=0, le=20)] = 4


class StaticAnalysis(Section):
    """One solve with every load at its value at t = 1."""

    type: Literal["static"] = "static"
    linear_solver: LinearSolver = "auto"
    petsc: PetscOptions = PetscOptions()
    equilibrium: Equilibrium = Equilibrium()


class _Stepped(Section):
    t_end: PositiveFloat | None = None
    dt: PositiveFloat | None = None
    steps: PositiveInt | None = Field(default=None, description="number of time steps")
    output_every: PositiveInt = Field(default=1, description="write every n-th step")
    linear_solver: LinearSolver = "auto"
    petsc: PetscOptions = PetscOptions()
    equilibrium: Equilibrium = Equilibrium()

    def _check_times(self, default_end: float | None):
        given = [k for k in ("t_end", "dt", "steps") if getattr(self, k) is not None]
        if self.t_end is None and default_end is not None and len(given) < 2:
            given.append("t_end")
        if len(given) != 2:
            raise ValueError("give two of 't_end', 'dt' and 'steps'")
        return self


class QuasiStaticAnalysis(_Stepped):
    """Load stepping without inertia; loads follow their curves over ``[0, t_end]``
    (default t_end = 1, so time reads as the load factor)."""

    type: Literal["quasi_static"]

    @model_validator(mode="after")
    def _times(self):
        return self._check_times(default_end=1.0)


class RayleighDamping(Section):
    """C = mass M + stiffness K (elastic stiffness)."""

    mass: NonNegativeFloat = 0.0
    stiffness: NonNegativeFloat = 0.0


class InitialVelocity(Section):
    """v0(x) = uniform + angular_velocity x (x - center); center default: the centroid."""

    uniform: Vector3 = (0.0, 0.0, 0.0)
    angular_velocity: Vector3 = (0.0, 0.0, 0.0)
    center: Vector3 | None = None


class Preload(Section):
    """Supports and loads solved statically before t = 0 and removed at t = 0+: the body
    starts at rest in that equilibrium (a plucked string, a released spring). The case's own
    supports hold during the preload (where both prescribe a dof, the case's value wins) and,
    with ``case_loads``, the case's loads at t = 0 act too; ``steps`` load steps reach the
    preload (more for a plastic one)."""

    boundary_conditions: list[BoundaryCondition] = Field(min_length=1)
    case_loads: bool = True
    steps: PositiveInt = 1

    @field_validator("boundary_conditions")
    @classmethod
    def _no_curve(cls, conditions):
        for bc in conditions:
            if getattr(bc, "curve", None) is not None:
                raise ValueError("a preload acts at its full value: no 'curve' (it is "
                                 "reached in 'steps' load steps and removed at t = 0+)")
        return conditions


AXIS_NAMES = ("x", "y", "z")


class DisplacementField(Section):
    """u0(x, y, z) per component: an arithmetic expression of the coordinates ``x``, ``y``,
    ``z``, the named ``constants``, ``pi`` and ``e`` (``+ - * / **``, parentheses and
    functions such as ``sin``, ``exp``, ``sqrt``: fem_frac/config/expression.py); an
    omitted component is 0. Never evaluated as Python."""

    constants: dict[str, FiniteFloat] = {}  # before x, y, z: their validator reads it
    x: str = "0"
    y: str = "0"
    z: str = "0"

    @field_validator("constants")
    @classmethod
    def _names(cls, constants):
        for name in constants:
            if not name.isidentifier() or name in AXIS_NAMES:
                raise ValueError(f"'{name}' cannot name a constant (a name like L or "
                                 "amplitude, not x, y or z)")
        return constants

    @field_validator("x", "y", "z")
    @classmethod
    def _expression(cls, text: str, info: ValidationInfo) -> str:
        parse(text, set(AXIS_NAMES) | set(info.data.get("constants", {})))
        return text


class FromRun(Section):
    """The last state written by an earlier run (its output directory): displacement, and
    velocity with ``velocity: true``, matched node by node by reference coordinates."""

    directory: str
    velocity: bool = False


class InitialDisplacement(Section):
    """Where the body starts: give one of ``preload`` (a static preload, released at
    t = 0+), ``field`` (expressions of x, y, z) or ``from_run`` (an earlier run's last
    state). The initial acceleration balances the initial state."""

    preload: Preload | None = None
    field: DisplacementField | None = None
    from_run: FromRun | None = None

    @model_validator(mode="after")
    def _one(self):
        given = [k for k in ("preload", "field", "from_run") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one of 'preload', 'field' or 'from_run'"
                             + (f" (got {', '.join(given)})" if given else ""))
        return self


class DynamicAnalysis(_Stepped):
    """Transient dynamics. ``newmark``: implicit, average acceleration by default (beta 1/4,
    gamma 1/2: no numerical damping); ``hht``: implicit HHT-alpha, ``alpha`` in [-1/3, 0]
    damps high frequencies (beta, gamma follow from alpha); ``central_difference``: explicit,
    lumped mass, dt limited by the critical step (refused above it unless ``substeps``)."""

    type: Literal["dynamic"]
    integrator: Literal["newmark", "hht", "central_difference"] = "newmark"
    beta: PositiveFloat | None = Field(default=None, description="Newmark beta; default 1/4")
    gamma: PositiveFloat | None = Field(default=None, description="Newmark gamma; default 1/2")
    alpha: Annotated[float, Field(ge=-1.0 / 3.0, le=0.0)] = -0.05
    mass: Literal["consistent", "lumped"] | None = Field(
        default=None, description="default: consistent (implicit), lumped (explicit)"
    )
    rayleigh: RayleighDamping | None = None
    initial_velocity: InitialVelocity | None = None
    initial_displacement: InitialDisplacement | None = None
    substeps: bool = Field(
        default=False,
        description="explicit only: split each step into enough substeps to stay below "
        "the critical time step instead of refusing",
    )

    @model_validator(mode="after")
    def _consistent(self):
        self._check_times(default_end=None)
        if self.integrator == "central_difference" and self.mass == "consistent":
            raise ValueError("central_difference needs the lumped mass")
        if self.integrator != "newmark" and (self.beta is not None or self.gamma is not None):
            raise ValueError(f"beta and gamma are for newmark; {self.integrator} sets its own")
        if self.gamma is not None and self.gamma < 0.5:
            raise ValueError("gamma < 1/2 adds energy (unstable); use gamma >= 1/2")
        start = self.initial_displacement
        if start is not None and start.from_run is not None and start.from_run.velocity \
                and self.initial_velocity is not None:
            raise ValueError("the initial velocity comes from initial_displacement.from_run "
                             "(velocity: true) or from initial_velocity, not both")
        return self

    @property
    def mass_kind(self) -> Literal["consistent", "lumped"]:
        """``mass``, or its default: lumped for ``central_difference``, else consistent."""
        if self.mass is not None:
            return self.mass
        return "lumped" if self.integrator == "central_difference" else "consistent"

    @property
    def newmark_beta(self) -> float:
        """``beta`` of the ``newmark`` integrator, or its default 1/4 (``hht`` derives its
        own from ``alpha``; ``central_difference`` has none)."""
        return self.beta if self.beta is not None else NEWMARK_BETA

    @property
    def newmark_gamma(self) -> float:
        """``gamma`` of the ``newmark`` integrator, or its default 1/2 (``hht`` derives its
        own from ``alpha``; ``central_difference`` has none)."""
        return self.gamma if self.gamma is not None else NEWMARK_GAMMA


Analysis = Annotated[
    StaticAnalysis | QuasiStaticAnalysis | DynamicAnalysis, Field(discriminator="type")
]
