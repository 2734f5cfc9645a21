"""Exact mass properties (mass, centre, inertia, principal axes) of a union of tets.

Closed form, no quadrature: for a tet with vertices ``v_k`` (k = 0..3), volume ``V`` and
``s = sum_k v_k``, and constant density ``rho``,

    int rho dV        = rho V
    int rho x dV      = rho V s / 4
    int rho x x^T dV  = rho V / 20 (sum_k v_k v_k^T + s s^T)

(the last is exact for quadratics: it is the covariance of the uniform measure on a simplex).

:func:`point_mass_properties` gives the same for point masses (a lumped mass matrix's nodal
masses at the nodes): the inertia that goes with angular momenta taken from that mass.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class MassProperties:
    """Mass properties of a rigid body, in the frame of the points it was computed from.

    ``inertia`` is about ``center``; ``moments`` are ascending and ``axes`` holds the principal
    axes as columns, a proper rotation, with ``inertia == axes @ diag(moments) @ axes.T``.
    """

    mass: float
    center: np.ndarray
    inertia: np.ndarray
    moments: np.ndarray
    axes: np.ndarray


def tet_moments(points, tets, density) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per tet: mass ``(m,)``, first moment ``(m, 3)`` = int rho x dV and second moment
    ``(m, 3, 3)`` = int rho x x^T dV, about the origin of the points' frame, in closed form.

    ``density`` is a scalar or ``(m,)``. The volume is ``|det|/6``, so either orientation works.
    """
    x = np.asarray(points, dtype=float)[np.asarray(tets)]  # (m, 4, 3)
    d = x[:, 1:] - x[:, :1]
    vol = np.abs(np.einsum("ei,ei->e", d[:, 0], np.cross(d[:, 1], d[:, 2]))) / 6.0
    rho = np.broadcast_to(np.asarray(density, dtype=float), vol.shape)
    mass = rho * vol
    s = x.sum(axis=1)  # (m, 3)
    first = mass[:, None] * s / 4.0
    outer = np.einsum("eki,ekj->eij", x, x) + np.einsum("ei,ej->eij", s, s)
    second = mass[:, None, None] * outer / 20.0
    return mass, first, second


def _proper_axes(axes: np.ndarray) -> np.ndarray:
    """Fix the signs of eigenvector columns deterministically.

    Rule: every column is flipped so that its largest-magnitude component (the first such on a
    tie) is positive; if the result has det = -1, the last column (largest moment) is negated,
    the only column whose rule is then broken. The result is a proper rotation.
    """
    axes = np.array(axes, dtype=float)
    idx = np.argmax(np.abs(axes), axis=0)
    axes *= np.sign(axes[idx, np.arange(3)])
    if np.linalg.det(axes) < 0.0:
        axes[:, 2] *= -1.0
    return axes


def mass_properties(points, tets, density) -> MassProperties:
    """Exact mass properties of the union of the tets (never a hull or a bounding box).

    Sums the per-tet moments of :func:`tet_moments`; centre = first / mass; the second moment
    is shifted to the centre (parallel-axis theorem), ``C = int rho (x-c)(x-c)^T dV``, and the
    inertia is ``J = trace(C) I - C``. Principal moments (ascending) and axes come from
    ``numpy.linalg.eigh``, with the column signs fixed as in :func:`_proper_axes`: each column's
    largest-magnitude component positive, except the last column when that is needed for
    ``det(axes) = +1``.
    """
    m, first, second = tet_moments(points, tets, density)
    mass = float(m.sum())
    if not mass > 0.0:
        raise ValueError(f"total mass must be positive, got {mass}")
    center = first.sum(axis=0) / mass
    return _about_center(mass, center, second.sum(axis=0) - mass * np.outer(center, center))


def point_mass_properties(points, masses) -> MassProperties:
    """Mass properties of point masses ``masses (k,)`` at ``points (k, 3)``.

    Centre ``X = sum m_a x_a / m``; ``C = sum m_a r_a r_a^T`` with ``r_a = x_a - X`` (taken
    about the centre directly, no parallel-axis shift), ``J = trace(C) I - C``; moments and
    axes as in :func:`mass_properties`. With the nodal masses of a lumped (diagonal) mass
    matrix this is the inertia that mass gives a rigid velocity field ``V + w x r``: its
    angular momentum ``sum r_a x m_a v_a`` is ``J w`` and its kinetic energy
    ``1/2 v^T M v = 1/2 m |V|^2 + 1/2 w . J w``, exactly.
    """
    x = np.asarray(points, dtype=float)
    m = np.asarray(masses, dtype=float)
    mass = float(m.sum())
    if not mass > 0.0:
        raise ValueError(f"total mass must be positive, got {mass}")
    center = (m[:, None] * x).sum(axis=0) / mass
    r = x - center
    return _about_center(mass, center, np.einsum("a,ai,aj->ij", m, r, r))


def _about_center(mass: float, center: np.ndarray, cov: np.ndarray) -> MassProperties:
    """Inertia ``trace(C) I - C``, principal moments and axes from the second moment ``C``
    about the centre."""
    cov = 0.5 * (cov + cov.T)
    inertia = np.trace(cov) * np.eye(3) - cov
    moments, axes = np.linalg.eigh(inertia)
    return MassProperties(mass, center, inertia, moments, _proper_axes(axes))
