"""The case file as typed, validated, immutable models (pydantic v2).

A section that is absent switches its stage off. Every model forbids unknown keys, so a
misspelt key is an error, never silently ignored. Units are the case's consistent system
(``units``); the descriptions below give SI units.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

PositiveFloat = Annotated[float, Field(gt=0)]
NonNegativeFloat = Annotated[float, Field(ge=0)]
PositiveInt = Annotated[int, Field(gt=0)]
Vector3 = tuple[float, float, float]
PositiveVector3 = tuple[PositiveFloat, PositiveFloat, PositiveFloat]


class Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


# --- geometry ---------------------------------------------------------------------------


class BoxGeometry(Section):
    """Axis-aligned box; faces ``xmin xmax ymin ymax zmin zmax``."""

    type: Literal["box"]
    origin: Vector3 = (0.0, 0.0, 0.0)
    lengths: PositiveVector3


class CylinderGeometry(Section):
    """Solid cylinder along +z from ``origin`` (centre of the bottom); ``bottom top outer``."""

    type: Literal["cylinder"]
    origin: Vector3 = (0.0, 0.0, 0.0)
    radius: PositiveFloat
    height: PositiveFloat


class SphereGeometry(Section):
    """Solid sphere; face ``outer``."""

    type: Literal["sphere"]
    center: Vector3 = (0.0, 0.0, 0.0)
    radius: PositiveFloat


class _Shell(Section):
    inner_radius: PositiveFloat
    outer_radius: PositiveFloat

    @model_validator(mode="after")
    def _radii(self):
        if self.inner_radius >= self.outer_radius:
            raise ValueError("inner_radius must be smaller than outer_radius")
        return self


class HollowSphereGeometry(_Shell):
    """Thick-walled sphere; ``inner outer`` (+ ``symmetry_x/y/z`` for the octant)."""

    type: Literal["hollow_sphere"]
    center: Vector3 = (0.0, 0.0, 0.0)
    sector: Literal["full", "octant"] = "full"


class HollowCylinderGeometry(_Shell):
    """Thick-walled tube along +z; ``inner outer bottom top`` (+ symmetry planes of sectors)."""

    type: Literal["hollow_cylinder"]
    origin: Vector3 = (0.0, 0.0, 0.0)
    height: PositiveFloat
    sector: Literal["full", "half", "quarter"] = "full"


Geometry = Annotated[
    BoxGeometry | CylinderGeometry | SphereGeometry | HollowSphereGeometry | HollowCylinderGeometry,
    Field(discriminator="type"),
]


class MeshSection(Section):
    """Either a gmsh primitive (``geometry``) or a file (``.geo`` meshed by gmsh; any other
    extension read by meshio). ``element_size`` is the target edge length."""

    geometry: Geometry | None = None
    file: str | None = None
    element_size: PositiveFloat | None = None
    order: Literal[1, 2] = 1
    formulation: Literal["standard", "averaged"] = Field(
        default="standard",
        description="'averaged': linear tets with the volumetric strain averaged over the "
        "elements around each vertex (B-bar), which removes volumetric locking under "
        "isochoric plastic flow and near-incompressibility; order 1 only",
    )

    @model_validator(mode="after")
    def _one_source(self):
        if (self.geometry is None) == (self.file is None):
            raise ValueError("give exactly one of 'geometry' or 'file'")
        if self.geometry is not None and self.element_size is None:
            raise ValueError("'element_size' is required to mesh a geometry")
        if self.formulation == "averaged" and self.order != 1:
            raise ValueError("formulation 'averaged' is for linear tets (order 1); "
                             "quadratic tets do not lock")
        return self


# --- material -----------------------------------------------------------------------------


class Material(Section):
    youngs_modulus: PositiveFloat
    poissons_ratio: Annotated[float, Field(gt=-1.0, lt=0.5)]
    density: PositiveFloat | None = None


class Region(Section):
    """Elements whose centroid lies in ``box`` (or that belong to the mesh file's volume
    group ``subdomain``) take these values in place of ``material``'s; later regions win."""

    subdomain: str | None = None
    box: BoxSelection | None = None
    youngs_modulus: PositiveFloat | None = None
    poissons_ratio: Annotated[float, Field(gt=-1.0, lt=0.5)] | None = None
    density: PositiveFloat | None = None

    @model_validator(mode="after")
    def _where_and_what(self):
        if (self.subdomain is None) == (self.box is None):
            raise ValueError("give exactly one of 'subdomain' or 'box'")
        if self.youngs_modulus is None and self.poissons_ratio is None and self.density is None:
            raise ValueError("give at least one of 'youngs_modulus', 'poissons_ratio', "
                             "'density'")
        return self


class Plasticity(Section):
    """Von Mises plasticity, associative, with linear isotropic hardening (``hardening`` H)
    and linear kinematic (Prager) hardening (``kinematic_hardening`` K); both 0: perfectly
    plastic. The flow stress is ``yield_stress + hardening * alpha``, alpha the equivalent
    plastic strain; the yield surface's centre (backstress) moves by (2/3) K d eps_p."""

    model: Literal["von_mises"] = "von_mises"
    yield_stress: PositiveFloat
    hardening: NonNegativeFloat = 0.0
    kinematic_hardening: NonNegativeFloat = 0.0


# --- fracture -----------------------------------------------------------------------------


class Smoothing(Section):
    """How element stresses are smoothed before the strength check. ``neighbours``: the
    volume-weighted mean over the elements reachable through shared faces whose centroids lie
    within ``length`` (or ``rings`` face-steps); ``nodal``: projection to the vertices
    (volume-weighted) and back. Smoothing never reaches across a crack."""

    method: Literal["neighbours", "nodal"] = "neighbours"
    length: PositiveFloat | None = Field(
        default=None, description="smoothing radius in the case's length unit (physical: "
        "set it from the material, e.g. a few grain sizes or the process-zone size)")
    rings: Annotated[int, Field(ge=0, le=10)] | None = Field(
        default=None, description="or: neighbour rings through shared faces (0: none)")

    @model_validator(mode="after")
    def _one_size(self):
        if (self.length is None) == (self.rings is None):
            raise ValueError("give exactly one of 'length' or 'rings'")
        return self


class Perturbation(Section):
    """Seeded random tilt of every crack normal, uniform on the cap of half-angle
    ``angle`` (degrees) around the principal direction; the same seed gives the same run."""

    angle: Annotated[float, Field(gt=0.0, lt=90.0)]
    seed: int = 0


class Protect(Section):
    """Where no crack may open: the vertices of a named boundary, of a mesh volume group
    (``subdomain``) or of the elements whose centroid lies in ``box``."""

    boundary: str | None = None
    subdomain: str | None = None
    box: BoxSelection | None = None

    @model_validator(mode="after")
    def _one(self):
        if sum(x is not None for x in (self.boundary, self.subdomain, self.box)) != 1:
            raise ValueError("give exactly one of 'boundary', 'subdomain' or 'box'")
        return self


class Fracture(Section):
    """Cracks open where the smoothed largest principal stress exceeds ``tensile_strength``,
    perpendicular to its direction, by separating the mesh along faces (vertices duplicated).

    Within a step, up to ``passes`` batches are inserted; each batch holds at most
    ``batch_size`` sites (no two within one smoothing neighbourhood) and is followed by a
    re-solve of the step on the new mesh; a step inserts at most
    ``max_insertions_per_step`` sites in all."""

    tensile_strength: PositiveFloat
    smoothing: Smoothing
    batch_size: PositiveInt = 4
    passes: Annotated[int, Field(ge=1, le=1000)] = 8
    max_insertions_per_step: PositiveInt = 64
    perturbation: Perturbation | None = None
    protect: list[Protect] = []


# --- rigid fragments ----------------------------------------------------------------------


class Ground(Section):
    """A ground plane through ``point`` with upward ``normal``; rigid fragments bounce off it
    with ``restitution`` (0: no bounce, 1: elastic) and slide with Coulomb ``friction``."""

    point: Vector3 = (0.0, 0.0, 0.0)
    normal: Vector3 = (0.0, 0.0, 1.0)
    restitution: Annotated[float, Field(ge=0.0, le=1.0)] = 0.5
    friction: NonNegativeFloat = 0.5

    @model_validator(mode="after")
    def _normal(self):
        if sum(c * c for c in self.normal) == 0.0:
            raise ValueError("normal must not be zero")
        return self


class Fragments(Section):
    """Pieces that break free (no support left) become rigid bodies: ``all`` of them,
    those no larger than ``max_volume`` (``small``), or each once its vibration has decayed
    (``settled``: strain plus vibrational kinetic energy below ``vibration_tolerance`` of
    its rigid kinetic energy); ``never`` keeps them deformable. ``whole_body`` makes the
    whole body one rigid body from the start (no finite elements: ``analysis`` gives the time
    steps and the initial velocity). ``gravity`` (default: ``body_force.gravity``) acts on
    rigid bodies; ``ground`` planes stop them."""

    become_rigid: Literal["all", "small", "settled", "never"] = "all"
    max_volume: PositiveFloat | None = None
    vibration_tolerance: PositiveFloat = 1e-3
    whole_body: bool = False
    gravity: Vector3 | None = None
    ground: list[Ground] = []
    contact_substeps: PositiveInt = Field(
        default=1, description="rigid-body steps per analysis step (finer contact resolution)")

    @model_validator(mode="after")
    def _small(self):
        if (self.become_rigid == "small") != (self.max_volume is not None):
            raise ValueError("become_rigid 'small' goes with max_volume (and only it)")
        return self


# --- load curves --------------------------------------------------------------------------


class RampCurve(Section):
    """0 until ``t_start``, linear to ``value`` at ``t_end`` (default: the end of the
    analysis), then held."""

    type: Literal["ramp"]
    t_start: NonNegativeFloat = 0.0
    t_end: PositiveFloat | None = None
    value: float = 1.0

    @model_validator(mode="after")
    def _order(self):
        if self.t_end is not None and self.t_end <= self.t_start:
            raise ValueError("t_end must be later than t_start")
        return self


class ConstantCurve(Section):
    """``value`` at every time (a load applied at once)."""

    type: Literal["constant"]
    value: float = 1.0


class TableCurve(Section):
    """Piecewise linear through ``points`` ``[[t, factor], ...]`` (times increasing); held at
    the first and last factor outside them."""

    type: Literal["table"]
    points: list[tuple[float, float]] = Field(min_length=1)

    @model_validator(mode="after")
    def _increasing(self):
        times = [t for t, _ in self.points]
        if any(b <= a for a, b in zip(times, times[1:], strict=False)):
            raise ValueError("the times of 'points' must increase")
        return self


LoadCurve = Annotated[RampCurve | ConstantCurve | TableCurve, Field(discriminator="type")]
# A condition's ``curve`` names an entry of ``load_curves`` or one of these.
BUILTIN_CURVES = ("ramp", "constant")
CurveName = Annotated[
    str,
    Field(
        description="a name in load_curves, or 'ramp' (0 to 1 over the analysis) or "
        "'constant' (1 throughout); default: constant for dynamic analyses, ramp for static "
        "and quasi-static ones"
    ),
]


# --- boundary conditions ------------------------------------------------------------------


class BoxSelection(Section):
    """Exterior faces whose three vertices all lie inside the box ``[min, max]``."""

    min: Vector3
    max: Vector3


class _Where(Section):
    boundary: str | None = None
    box: BoxSelection | None = None

    @model_validator(mode="after")
    def _one_selection(self):
        if (self.boundary is None) == (self.box is None):
            raise ValueError("give exactly one of 'boundary' or 'box'")
        return self


class Fixed(_Where):
    """All displacement components zero."""

    type: Literal["fixed"]


class Displacement(_Where):
    """Prescribed displacement components; an omitted component stays free."""

    type: Literal["displacement"]
    x: float | None = None
    y: float | None = None
    z: float | None = None
    curve: CurveName | None = None

    @model_validator(mode="after")
    def _some_component(self):
        if self.x is None and self.y is None and self.z is None:
            raise ValueError("give at least one of 'x', 'y', 'z'")
        return self


class Symmetry(_Where):
    """Zero normal displacement on a plane normal to a coordinate axis."""

    type: Literal["symmetry"]


class Traction(_Where):
    """Force per unit reference area (Pa), constant over the selected faces."""

    type: Literal["traction"]
    traction: Vector3
    curve: CurveName | None = None


class Pressure(_Where):
    """Pressure (Pa) acting against the outward normal: positive pushes into the body."""

    type: Literal["pressure"]
    pressure: float
    curve: CurveName | None = None


BoundaryCondition = Annotated[
    Fixed | Displacement | Symmetry | Traction | Pressure, Field(discriminator="type")
]


class BodyForce(Section):
    """Gravitational acceleration (m/s^2); needs ``material.density``."""

    gravity: Vector3
    curve: CurveName | None = None


# --- analysis and output ------------------------------------------------------------------


LinearSolver = Literal["auto", "pardiso", "cholmod", "superlu"]


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


Analysis = Annotated[
    StaticAnalysis | QuasiStaticAnalysis | DynamicAnalysis, Field(discriminator="type")
]


class Output(Section):
    directory: str | None = Field(
        default=None, description="default: out/<case name> under the working directory"
    )
    name: str | None = Field(default=None, description="base name of the .pvd; default: case")
    crack_surface: bool = Field(
        default=False, description="with fracture: also write the crack faces as a surface "
        "series <name>_crack.pvd (written, empty until the first crack, at every output step)")


class Reference(Section):
    """An exact solution the case is compared against; the error is reported in
    summary.json (see fem_frac/verify/reference.py for what each compares)."""

    solution: Literal["cantilever", "lame_sphere", "hill_sphere", "uniaxial_bar",
                      "free_vibration"]


UNIT_SYSTEMS = ("SI", "mm-N-s")


class Case(Section):
    """A whole scene. ``mesh`` and ``material`` are required; everything else has defaults."""

    title: str | None = None
    units: Literal["SI", "mm-N-s"] = "SI"
    mesh: MeshSection
    material: Material
    boundary_conditions: list[BoundaryCondition] = []
    body_force: BodyForce | None = None
    regions: list[Region] = []
    plasticity: Plasticity | None = None
    load_curves: dict[str, LoadCurve] = {}
    analysis: Analysis = StaticAnalysis()
    fracture: Fracture | None = None
    fragments: Fragments | None = None
    reference: Reference | None = None
    output: Output = Output()
