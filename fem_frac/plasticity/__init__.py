"""Von Mises plasticity: the return map at quadrature points."""

from .return_map import PlasticState, radial_return

__all__ = ["PlasticState", "radial_return"]
