"""Warnings, with numbers, for cases whose elements will be too stiff: linear tets locking
under plastic flow or near-incompressibility, and too few linear tets through the thickness
of a thin part to bend. ``check`` prints them in its report, ``run`` on stderr before its
first step. The figures they quote are measured in docs/plasticity.md (Hill's sphere) and
the cantilever by elements through its depth."""

from __future__ import annotations

import numpy as np

from ..config.schema import Case
from ..mesh.mesh import TET_EDGES

# Poisson's ratio from which standard linear tets lock in elasticity: the bulk modulus is
# then >= 9.7 times the shear modulus (K / G = 2 (1 + nu) / (3 (1 - 2 nu))).
LOCKING_NU = 0.45
# Fewer linear tets than this across the thinnest extent of the body bend far too stiffly
# (the P1 cantilever's tip deflection is 15 % low at 3.3 across its depth, 45 % at 1.6).
THIN_ELEMENTS = 4.0


def bulk_to_shear(nu: float) -> float:
    """K / G of an isotropic material of Poisson's ratio ``nu``."""
    return 2.0 * (1.0 + nu) / (3.0 * (1.0 - 2.0 * nu))


def elements_through(mesh) -> tuple[float, float, str]:
    """``(elements across the thinnest extent, median element size, axis)``: the bounding
    box's smallest side over the median of the tets' mean edge lengths (a plate's or a
    beam's thickness; a thin curved wall is not measured)."""
    x = mesh.points[mesh.tets[:, TET_EDGES]]  # (n_tets, 6, 2, 3)
    size = float(np.median(np.linalg.norm(x[:, :, 1] - x[:, :, 0], axis=2).mean(axis=1)))
    extent = np.ptp(mesh.points, axis=0)
    k = int(np.argmin(extent))
    return float(extent[k]) / size, size, "xyz"[k]


def locking_warnings(case: Case, mesh, materials) -> list[str]:
    """One line per reason the case's elements will be too stiff (none for P2)."""
    if case.mesh.order != 1:
        return []
    out = []
    standard = case.mesh.formulation == "standard"
    remedy = "use mesh.order: 2 or mesh.formulation: averaged"
    if standard and case.plasticity is not None:
        out.append("linear tets (mesh.order 1, formulation standard) lock under plastic "
                   "flow, which keeps the volume: one volumetric constraint per tet leaves "
                   "too few displacement fields (Hill's sphere: outer displacement 18 % low "
                   "at 1,284 dofs, 3.6 % averaged, 0.15 % P2; docs/plasticity.md); " + remedy)
    nu = float(np.max(materials.poissons_ratio))
    if standard and nu >= LOCKING_NU:
        out.append(f"linear tets (mesh.order 1, formulation standard) lock as nu -> 1/2: "
                   f"nu = {nu:g} >= {LOCKING_NU:g} makes the bulk modulus "
                   f"{bulk_to_shear(nu):.3g} times the shear modulus (Hill's sphere at nu "
                   "0.49: outer displacement 53 % low, 7.9 % averaged, 0.26 % P2; "
                   "docs/plasticity.md); " + remedy)
    through, size, axis = elements_through(mesh)
    if through < THIN_ELEMENTS:
        out.append(f"about {through:.3g} linear tets across the body's thinnest extent "
                   f"({axis}: {through * size:.4g} over a median element size {size:.4g}; "
                   f"fewer than {THIN_ELEMENTS:g}): linear tets bend far too stiffly with "
                   "so few (a cantilever's tip deflection is 45 % low at 1.6 across its "
                   "depth, 15 % at 3.3, P2 within 1.3 % at 1.2; docs/plasticity.md); use "
                   "mesh.order: 2 or smaller elements")
    return out
