"""``load_curves``, ``boundary_conditions`` and ``body_force``."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from .base import (
    BoxSelection,
    FiniteFloat,
    NonNegativeFloat,
    Pair,
    PositiveFloat,
    Section,
    Vector3,
)


class RampCurve(Section):
    """0 until ``t_start``, linear to ``value`` at ``t_end`` (default: the end of the
    analysis), then held."""

    type: Literal["ramp"]
    t_start: NonNegativeFloat = 0.0
    t_end: PositiveFloat | None = None
    value: FiniteFloat = 1.0

    @model_validator(mode="after")
    def _order(self):
        if self.t_end is not None and self.t_end <= self.t_start:
            raise ValueError("t_end must be later than t_start")
        return self


class ConstantCurve(Section):
    """``value`` at every time (a load applied at once)."""

    type: Literal["constant"]
    value: FiniteFloat = 1.0


class TableCurve(Section):
    """Piecewise linear through ``points`` ``[[t, factor], ...]`` (times increasing); held at
    the first and last factor outside them."""

    type: Literal["table"]
    points: list[Pair] = Field(min_length=1)

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


class _Where(Section):
    boundary: str | None = None
    box: BoxSelection | None = None

    @model_validator(mode="after")
    def _one_selection(self):
        if (self.boundary is None) == (self.box is None):
            raise ValueError("give exactly one of 'boundary' or 'box'")
        return self


class _Nodes(Section):
    """A support's selection: the nodes of a named boundary or of the exterior faces whose
    centroid lies in ``box``, or the nodes that lie in the box ``vertices`` (bounds
    included, widened by 1e-9 of the mesh's extent), which may be flat in two directions:
    the nodes along a mesh edge, a line support or a line load by displacement."""

    boundary: str | None = None
    box: BoxSelection | None = None
    vertices: BoxSelection | None = None

    @model_validator(mode="after")
    def _one_selection(self):
        if sum(x is not None for x in (self.boundary, self.box, self.vertices)) != 1:
            raise ValueError("give exactly one of 'boundary', 'box' or 'vertices'")
        return self


class Fixed(_Nodes):
    """All displacement components zero."""

    type: Literal["fixed"]


class Displacement(_Nodes):
    """Prescribed displacement components; an omitted component stays free."""

    type: Literal["displacement"]
    x: FiniteFloat | None = None
    y: FiniteFloat | None = None
    z: FiniteFloat | None = None
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
    pressure: FiniteFloat
    curve: CurveName | None = None


BoundaryCondition = Annotated[
    Fixed | Displacement | Symmetry | Traction | Pressure, Field(discriminator="type")
]


class BodyForce(Section):
    """Gravitational acceleration (m/s^2); needs ``material.density``."""

    gravity: Vector3
    curve: CurveName | None = None
