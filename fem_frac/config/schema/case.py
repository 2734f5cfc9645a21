"""``output``, ``reference`` and the whole :class:`Case`."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from .analysis import Analysis, StaticAnalysis
from .base import Section
from .fracture import Fracture, Fragments
from .geometry import MeshSection
from .loads import BodyForce, BoundaryCondition, LoadCurve
from .material import Material, Plasticity, Region


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
