"""The constitutive law at quadrature points: linear elastic, or von Mises elastoplastic.

One interface for the step loop: ``update(strain, state)`` returns the stress, the state the
step would commit and (on request) the tangent. Elastic laws carry no state (``None``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import schema
from ..fem.tensors import isotropic_tangent, lame_parameters
from .return_map import PlasticState, radial_return


@dataclass(frozen=True)
class MaterialLaw:
    """Isotropic elasticity, with von Mises plasticity when ``yield_stress`` is set."""

    youngs_modulus: float
    poissons_ratio: float
    yield_stress: float | None = None
    hardening: float = 0.0
    kinematic_hardening: float = 0.0

    @property
    def plastic(self) -> bool:
        return self.yield_stress is not None

    @property
    def uniform(self) -> bool:
        return np.ndim(self.youngs_modulus) == 0 and np.ndim(self.poissons_ratio) == 0

    @property
    def elastic_tangent(self) -> np.ndarray:
        """Mandel ``(6, 6)``, or ``(6, 6, n_tets, 1)`` with properties per element."""
        if self.uniform:
            return isotropic_tangent(self.youngs_modulus, self.poissons_ratio)
        lam, mu = lame_parameters(self.youngs_modulus, self.poissons_ratio)
        eye, vol = np.eye(6)[:, :, None, None], np.zeros((6, 6, 1, 1))
        vol[:3, :3] = 1.0
        return 2.0 * mu * eye + lam * vol

    def initial_state(self, shape: tuple) -> PlasticState | None:
        if not self.plastic:
            return None
        return PlasticState.zeros(shape, kinematic=self.kinematic_hardening > 0.0)

    def update(self, strain: np.ndarray, state: PlasticState | None, tangent: bool = False):
        """``(stress, trial_state, D)`` for total Mandel ``strain`` ``(6, n_tets, n_qp)`` from
        the committed ``state``; ``D`` is ``(6, 6)`` or ``(6, 6, n_tets, n_qp)``, or ``None``
        when not asked for."""
        if not self.plastic:
            d = self.elastic_tangent
            if d.ndim == 2:
                return np.einsum("ab,beq->aeq", d, strain), None, (d if tangent else None)
            d = np.broadcast_to(d, (6, 6) + strain.shape[1:])
            return np.einsum("abeq,beq->aeq", d, strain), None, (d if tangent else None)
        return radial_return(
            strain,
            state,
            self.youngs_modulus,
            self.poissons_ratio,
            self.yield_stress,
            self.hardening,
            tangent=tangent,
            kinematic_hardening=self.kinematic_hardening,
        )

    def elastic_energy(self, stress: np.ndarray, weights: np.ndarray) -> float:
        """Stored elastic energy, the integral of sigma : C^-1 : sigma / 2 (``weights`` dx)."""
        lam, mu = lame_parameters(self.youngs_modulus, self.poissons_ratio)
        p = stress[:3].sum(axis=0) / 3.0
        dev2 = np.sum(stress**2, axis=0) - 3.0 * p**2
        bulk = lam + 2.0 * mu / 3.0
        density = dev2 / (4.0 * mu) + p**2 / (2.0 * bulk)
        return float(np.sum(density * weights))

    def hardening_energy(self, state: PlasticState | None, weights: np.ndarray) -> float:
        """Energy stored by hardening: the integral of H alpha^2 / 2 (isotropic) plus
        3 |beta|^2 / (4 K) (kinematic, beta the backstress)."""
        if state is None:
            return 0.0
        energy = 0.5 * self.hardening * np.sum(state.equivalent_plastic_strain**2 * weights)
        if self.kinematic_hardening > 0.0:
            back = np.sum(state.backstress**2, axis=0)
            energy += 0.75 / self.kinematic_hardening * np.sum(back * weights)
        return float(energy)


def material_law(materials, plasticity: schema.Plasticity | None) -> MaterialLaw:
    """The law of a case: ``materials`` is a ``schema.Material`` or the per-element
    :class:`~fem_frac.plasticity.regions.ElementMaterials` (arrays become ``(n_tets, 1)``)."""
    e, nu = materials.youngs_modulus, materials.poissons_ratio
    if np.ndim(e):
        e, nu = np.asarray(e)[:, None], np.asarray(nu)[:, None]
    if plasticity is None:
        return MaterialLaw(e, nu)
    return MaterialLaw(
        e,
        nu,
        plasticity.yield_stress,
        plasticity.hardening,
        plasticity.kinematic_hardening,
    )
