"""``analysis``: static, quasi-static or dynamic, and how each step reaches equilibrium."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from .base import NonNegativeFloat, PositiveFloat, PositiveInt, Section, Vector3

LinearSolver = Literal["auto", "pardiso", "cholmod", "superlu"]

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
    equilibrium: Equilibrium = Equilibrium()


class _Stepped(Section):
    t_end: PositiveFloat | None = None
    dt: PositiveFloat | None = None
    steps: PositiveInt | None = Field(default=None, description="number of time steps")
    output_every: PositiveInt = Field(default=1, description="write every n-th step")
    linear_solver: LinearSolver = "auto"
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
