"""The building blocks of every section: strict frozen models, constrained numbers,
vectors and the box selection of faces or elements."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

PositiveFloat = Annotated[float, Field(gt=0)]
NonNegativeFloat = Annotated[float, Field(ge=0)]
PositiveInt = Annotated[int, Field(gt=0)]
Vector3 = tuple[float, float, float]
PositiveVector3 = tuple[PositiveFloat, PositiveFloat, PositiveFloat]


class Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class BoxSelection(Section):
    """Exterior faces whose three vertices all lie inside the box ``[min, max]``."""

    min: Vector3
    max: Vector3
