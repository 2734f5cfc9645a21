"""fem_frac: finite-element elastoplastic fracture on tetrahedra."""

__version__ = "0.1.0"
