"""``probes``: places whose fields a run writes at every step, to ``<name>_probes.csv``."""

from __future__ import annotations

import re
from typing import Literal

from pydantic import Field, field_validator, model_validator

from .base import Section, Vector3

#: Most probes a case may hold (each is read at every step).
MAX_PROBES = 1000

#: The fields a probe may record: those of the output series (docs/input.md, "Probes").
PROBE_FIELDS = (
    "displacement", "velocity", "stress", "von_mises", "max_principal_stress",
    "plastic_strain", "equivalent_plastic_strain", "backstress",
    "plastic_strain_nodal", "equivalent_plastic_strain_nodal",
    "fragment_id", "smoothed_max_principal_stress",
)
ProbeField = Literal[PROBE_FIELDS]  # type: ignore[valid-type]

_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,63}")


class Probe(Section):
    """A point (``point``: the fields interpolated in the element that holds it) or a named
    boundary (``boundary``: their mean over its faces), and the ``fields`` written for it."""

    name: str
    point: Vector3 | None = None
    boundary: str | None = None
    fields: list[ProbeField] = Field(min_length=1)

    @field_validator("name")
    @classmethod
    def _column_name(cls, v: str) -> str:
        if not _NAME.fullmatch(v):
            raise ValueError("must start with a letter and hold only letters, digits, '_' "
                             "and '-' (at most 64): it names the probe's columns")
        return v

    @field_validator("fields")
    @classmethod
    def _once(cls, v: list[str]) -> list[str]:
        twice = sorted({f for f in v if v.count(f) > 1})
        if twice:
            raise ValueError(f"{', '.join(twice)} given more than once")
        return v

    @model_validator(mode="after")
    def _one_place(self):
        if (self.point is None) == (self.boundary is None):
            raise ValueError("give exactly one of 'point' or 'boundary'")
        return self


Probes = list[Probe]
