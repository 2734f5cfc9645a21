"""The constitutive law at quadrature points: linear elastic, or von Mises elastoplastic.

One interface for the step loop: ``update(strain, state)`` returns the stress, the state the
step would commit and (on request) the tangent. Elastic laws carry no state (``None``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import schema
from .fem.tensors import isotropic_tangent, lame_parameters
from .plasticity.return_map import PlasticState, radial_return


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
    def elastic_tangent(self) -> np.ndarray:
        """Mandel ``(6, 6)``."""
        return isotropic_tangent(self.youngs_modulus, self.poissons_ratio)

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
            return np.einsum("ab,beq->aeq", d, strain), None, (d if tangent else None)
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


def material_law(material: schema.Material, plasticity: schema.Plasticity | None) -> MaterialLaw:
    if plasticity is None:
        return MaterialLaw(material.youngs_modulus, material.poissons_ratio)
    return MaterialLaw(
        material.youngs_modulus,
        material.poissons_ratio,
        plasticity.yield_stress,
        plasticity.hardening,
        plasticity.kinematic_hardening,
    )
