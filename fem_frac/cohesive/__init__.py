"""Cohesive crack faces: the extrinsic traction-separation law at interface points."""

from .law import CohesiveResponse, TractionSeparation

__all__ = ["CohesiveResponse", "TractionSeparation"]
