"""``mesh``: a gmsh primitive (``geometry``) or a mesh file."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from .base import NotBool, PositiveFloat, PositiveVector3, Section, Vector3


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
    order: Annotated[Literal[1, 2], NotBool] = 1
    formulation: Literal["standard", "averaged"] = Field(
        default="standard",
        description="'averaged': linear tets with the volumetric strain averaged over the "
        "elements around each vertex (B-bar), which removes volumetric locking under "
        "isochoric plastic flow and near-incompressibility; order 1 only",
    )
    allow_geo_commands: bool = Field(
        default=False,
        description="let a .geo file (and the files it includes) use the gmsh commands that "
        "run programs or write, create or remove files (SystemCall, Printf > file, Save, "
        "Print, CreateDir, Exit, Plugin, OnelabRun, ..., and options naming log files or "
        "programs). These run with your permissions when the mesh is built, so a .geo from "
        "someone else can do anything you can: set true only for a file you trust. "
        "See docs/security.md",
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
