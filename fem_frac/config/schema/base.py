"""The building blocks of every section: strict frozen models, constrained numbers,
vectors and the box selection of faces or elements.

Every model is strict: a number is a YAML number (not a quoted string, not ``true``), a
flag is ``true`` or ``false`` (not ``yes``, ``on`` or 1), a whole number has no fraction,
and every float is finite (``.inf``, ``.nan`` and ``1e400``, which YAML reads as infinity,
are refused where they are written). A finite value the arithmetic of the solve cannot
carry (a load of 1e300 overflows the residual) is valid input: the run stops as a numerical
failure (exit 3).
"""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field

# The largest whole number a count or an index may take: numpy's int32 range, far above any
# sensible count (the work bounds of fem_frac.app.budget refuse much less).
MAX_INT = 2**31 - 1


def _as_tuple(value):
    """YAML gives lists; a strict tuple field takes tuples only."""
    return tuple(value) if isinstance(value, list) else value


def _not_bool(value):
    """``true`` is the integer 1 in Python: refuse it where a number is meant."""
    if isinstance(value, bool):
        raise ValueError(f"must be a number, got {str(value).lower()}")
    return value


FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegativeFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]
PositiveInt = Annotated[int, Field(gt=0, le=MAX_INT)]
NonNegativeInt = Annotated[int, Field(ge=0, le=MAX_INT)]
Vector3 = Annotated[tuple[FiniteFloat, FiniteFloat, FiniteFloat], BeforeValidator(_as_tuple)]
PositiveVector3 = Annotated[
    tuple[PositiveFloat, PositiveFloat, PositiveFloat], BeforeValidator(_as_tuple)
]
Pair = Annotated[tuple[FiniteFloat, FiniteFloat], BeforeValidator(_as_tuple)]
NotBool = BeforeValidator(_not_bool)


class Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False,
                              defer_build=True)


class BoxSelection(Section):
    """Exterior faces whose three vertices all lie inside the box ``[min, max]``."""

    min: Vector3
    max: Vector3
