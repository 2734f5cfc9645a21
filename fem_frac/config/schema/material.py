"""``material``, ``regions`` and ``plasticity``."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from .base import BoxSelection, NonNegativeFloat, PositiveFloat, Section


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
