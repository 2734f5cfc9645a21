"""Warnings, with numbers, for cases whose elements will be too stiff: linear tets locking
under plastic flow or near-incompressibility, and too few linear tets through the thickness
of a thin part to bend. ``check`` prints them in its report, ``run`` on stderr before its
first step. ``check`` also notes where quadratic tets are the better buy than the averaged
formulation (:func:`element_notes`). The figures they quote are measured in
docs/plasticity.md (Hill's sphere) and the cantilever by elements through its depth."""

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


def element_size(mesh) -> float:
    """The median of the tets' mean edge lengths."""
    x = mesh.points[mesh.tets[:, TET_EDGES]]  # (n_tets, 6, 2, 3)
    return float(np.median(np.linalg.norm(x[:, :, 1] - x[:, :, 0], axis=2).mean(axis=1)))


def across(mesh) -> np.ndarray:
    """``(3,)`` elements across the body along x, y, z: the bounding box's sides over the
    median element size (a plate's or a beam's thickness; a thin curved wall is not
    measured)."""
    return np.ptp(mesh.points, axis=0) / element_size(mesh)


def loaded_across(case: Case, problem) -> np.ndarray:
    """``(3,)`` whether anything moves the body along x, y, z: a force (surface loads,
    gravity), a non-zero prescribed displacement, an initial velocity (a rotation moves it
    every way) or an initial displacement along that axis. A thin part loaded only in its
    own plane (a bar pulled along its axis) does not bend."""
    out = np.any(problem.forces.reshape(-1, 3) != 0.0, axis=0)
    values = problem.constraints.values
    out[np.unique(problem.constraints.dofs[values != 0.0] % 3)] = True
    analysis = case.analysis
    v0 = getattr(analysis, "initial_velocity", None)
    if v0 is not None:
        out |= np.asarray(v0.uniform) != 0.0
        out |= np.any(np.asarray(v0.angular_velocity) != 0.0)
    start = getattr(analysis, "initial_displacement", None)
    if start is not None:
        field = start.field
        out |= [field is None or getattr(field, a).strip() != "0" for a in "xyz"]
    return out


def locking_warnings(case: Case, mesh, materials, problem) -> list[str]:
    """One line per reason the case's elements will be too stiff (none for P2, none for a
    body rigid from the start)."""
    rigid = case.fragments is not None and case.fragments.whole_body
    if case.mesh.order != 1 or rigid:
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
    counts = np.where(loaded_across(case, problem), across(mesh), np.inf)
    k = int(np.argmin(counts))
    if counts[k] < THIN_ELEMENTS:
        extent = float(np.ptp(mesh.points[:, k]))
        out.append(f"about {counts[k]:.3g} linear tets across the body's extent in "
                   f"{'xyz'[k]} ({extent:.4g} over a median element size "
                   f"{extent / counts[k]:.4g}; fewer than {THIN_ELEMENTS:g}), and loads "
                   "along it: linear tets bend far too stiffly with so few (a cantilever's "
                   "tip deflection is 45 % low at 1.6 across its depth, 15 % at 3.3, P2 "
                   "within 1.3 % at 1.2; docs/plasticity.md); use mesh.order: 2 or smaller "
                   "elements")
    return out


def element_notes(case: Case, materials) -> list[str]:
    """Where linear tets with the averaged volumetric strain meet what they are for (plastic
    flow, nu >= LOCKING_NU) in an implicit or static analysis: that quadratic tets reach a
    smaller error for less time, with Hill's sphere's figures (docs/plasticity.md, wall
    s). Not for explicit dynamics, where P2's stable step and lumped mass change the
    balance and nothing was measured."""
    analysis = case.analysis
    explicit = getattr(analysis, "integrator", None) == "central_difference"
    if case.mesh.order != 1 or case.mesh.formulation != "averaged" or explicit:
        return []
    if case.plasticity is not None:
        return ["quadratic tets are the better buy for accuracy than linear ones with the "
                "averaged volumetric strain: on Hill's sphere under plastic flow, P2 on the "
                "coarsest mesh (mean h 0.136, 1.1 s) puts the outer displacement within "
                "0.15 %, averaged P1 within 0.71 % on a mesh 2.3 times finer (7.4 s; "
                "docs/plasticity.md); consider mesh.order: 2"]
    if float(np.max(materials.poissons_ratio)) >= LOCKING_NU:
        return ["quadratic tets are the better buy for accuracy than linear ones with the "
                "averaged volumetric strain near incompressibility: on Hill's sphere at nu "
                "0.49, P2 puts the outer displacement within 0.26 % (1.0 s) on the mesh "
                "where averaged P1 is 7.9 % off (0.4 s), and 3.3 % on one 1.5 times finer "
                "(1.4 s; docs/plasticity.md); consider mesh.order: 2"]
    return []
