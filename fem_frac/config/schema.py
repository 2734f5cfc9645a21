"""The case file as typed, validated, immutable models (pydantic v2).

A section that is absent switches its stage off. Every model forbids unknown keys, so a
misspelt key is an error, never silently ignored. Units are the case's consistent system
(``units``); the descriptions below give SI units.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

PositiveFloat = Annotated[float, Field(gt=0)]
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

    @model_validator(mode="after")
    def _one_source(self):
        if (self.geometry is None) == (self.file is None):
            raise ValueError("give exactly one of 'geometry' or 'file'")
        if self.geometry is not None and self.element_size is None:
            raise ValueError("'element_size' is required to mesh a geometry")
        return self


# --- material -----------------------------------------------------------------------------


class Material(Section):
    youngs_modulus: PositiveFloat
    poissons_ratio: Annotated[float, Field(gt=-1.0, lt=0.5)]
    density: PositiveFloat | None = None


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


class Pressure(_Where):
    """Pressure (Pa) acting against the outward normal: positive pushes into the body."""

    type: Literal["pressure"]
    pressure: float


BoundaryCondition = Annotated[
    Fixed | Displacement | Symmetry | Traction | Pressure, Field(discriminator="type")
]


class BodyForce(Section):
    """Gravitational acceleration (m/s^2); needs ``material.density``."""

    gravity: Vector3


# --- analysis and output ------------------------------------------------------------------


class StaticAnalysis(Section):
    type: Literal["static"] = "static"
    linear_solver: Literal["auto", "pardiso", "cholmod", "superlu"] = "auto"


Analysis = Annotated[StaticAnalysis, Field(discriminator="type")]


class Output(Section):
    directory: str | None = Field(
        default=None, description="default: out/<case name> under the working directory"
    )
    name: str | None = Field(default=None, description="base name of the .pvd; default: case")


UNIT_SYSTEMS = ("SI", "mm-N-s")


class Case(Section):
    """A whole scene. ``mesh`` and ``material`` are required; everything else has defaults."""

    title: str | None = None
    units: Literal["SI", "mm-N-s"] = "SI"
    mesh: MeshSection
    material: Material
    boundary_conditions: list[BoundaryCondition] = []
    body_force: BodyForce | None = None
    analysis: Analysis = StaticAnalysis()
    output: Output = Output()
