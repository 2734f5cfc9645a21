"""The stable step of explicit central difference for a model.

Two estimates of the highest frequency omega_max of K u = omega^2 M_lumped u on the free
dofs: the element bound (max over tets of each tet's own omega_max; rigorous, never below
the true value, typically 1.5-2.5x above it on unstructured meshes: see
:mod:`fem_frac.fem.mass`), and Lanczos on the assembled system (scipy ``eigsh``, converged to
``LANCZOS_TOLERANCE``), which is the true value to that tolerance. The limit uses Lanczos
shrunk by the tolerance, and falls back on the element bound if Lanczos does not converge.
Plastic flow only lowers the stiffness, so the elastic limit stays safe once yielding starts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .integrators import central_difference_limit

LANCZOS_TOLERANCE = 1e-6


@dataclass(frozen=True)
class ExplicitLimit:
    dt: float  # the stable step, Rayleigh damping included
    omega_max: float  # rad/s, as used for dt
    element_bound_dt: float  # the same limit from the element bound
    method: str  # "lanczos" or "element bound"


def highest_frequency(stiffness: sp.csr_matrix, lumped: np.ndarray, free: np.ndarray) -> float:
    """omega_max of the free system by Lanczos on M^-1/2 K M^-1/2 (``nan`` if it fails)."""
    from scipy.sparse.linalg import ArpackNoConvergence, eigsh

    scale = 1.0 / np.sqrt(lumped[free])
    a = sp.diags(scale) @ stiffness[free][:, free] @ sp.diags(scale)
    if a.shape[0] < 3:
        return float(np.sqrt(max(np.linalg.eigvalsh(a.toarray()).max(), 0.0)))
    try:
        value = eigsh(a, k=1, which="LA", tol=LANCZOS_TOLERANCE, return_eigenvectors=False,
                      maxiter=5000, v0=np.ones(a.shape[0]))
    except ArpackNoConvergence:
        return float("nan")
    return float(np.sqrt(max(value[0], 0.0)))


def explicit_limit(space, stiffness, lumped, free, youngs_modulus, poissons_ratio, density,
                   mass_damping=0.0, stiffness_damping=0.0, extra=None) -> ExplicitLimit:
    """``extra``: a further stiffness (cohesive crack faces), added to the assembled one
    for Lanczos and to the element bound through Gershgorin's bound on ``M^-1 extra``
    (``lambda_max(A + B) <= lambda_max(A) + lambda_max(B)``)."""
    from ..fem.mass import element_frequencies

    if np.ndim(youngs_modulus) == 0 and np.ndim(density) == 0:
        bound = float(element_frequencies(space, youngs_modulus, poissons_ratio,
                                          density).max())
    else:
        # per-element properties: omega_e scales as sqrt(E_e / rho_e) at a given nu; with
        # the largest unit-property frequency over the body's distinct nu values the bound
        # stays rigorous
        nus = np.unique(np.broadcast_to(poissons_ratio, np.shape(space.mesh.tets)[:1]))
        unit = np.max([element_frequencies(space, 1.0, float(nu), 1.0) for nu in nus], axis=0)
        bound = float(np.max(unit * np.sqrt(np.asarray(youngs_modulus) / np.asarray(density))))
    if extra is not None:
        rows = np.asarray(abs(extra).sum(axis=1)).ravel()[free] / lumped[free]
        bound = float(np.sqrt(bound**2 + (rows.max() if rows.size else 0.0)))
        stiffness = stiffness + extra
    bound_dt = central_difference_limit(bound, mass_damping, stiffness_damping)
    omega = highest_frequency(stiffness, lumped, free)
    if not np.isfinite(omega) or omega <= 0.0 or omega > bound * (1 + 1e-9):
        return ExplicitLimit(bound_dt, bound, bound_dt, "element bound")
    omega *= 1.0 + 10 * LANCZOS_TOLERANCE
    dt = central_difference_limit(omega, mass_damping, stiffness_damping)
    return ExplicitLimit(dt, omega, bound_dt, "lanczos")


def stable_limit(space, stiffness, lumped: np.ndarray, free: np.ndarray, materials,
                 rayleigh=None, extra=None) -> ExplicitLimit:
    """The stable step of a discretization: ``materials`` holds ``youngs_modulus``,
    ``poissons_ratio`` and ``density`` (scalars or per element), ``rayleigh`` the
    ``analysis.rayleigh`` section or ``None``, ``extra`` the cohesive faces' stiffness."""
    return explicit_limit(space, stiffness, lumped, free, materials.youngs_modulus,
                          materials.poissons_ratio, materials.density,
                          rayleigh.mass if rayleigh else 0.0,
                          rayleigh.stiffness if rayleigh else 0.0, extra)
