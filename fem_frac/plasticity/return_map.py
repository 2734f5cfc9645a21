"""Radial return for von Mises plasticity with linear isotropic and kinematic hardening,
vectorized.

All tensors are Mandel 6-vectors, components first: strain and stress ``(6, ...)``,
tangents ``(6, 6, ...)`` (see :mod:`fem_frac.fem.tensors`); ``...`` is any batch shape,
typically ``(n_tets, n_qp)``. Yield function

    f = sqrt(3/2) |dev sigma - beta| - (sigma_Y + H alpha)

with the isotropic modulus ``hardening`` H (H = 0: perfect plasticity, DESIGN §2) and the
backstress beta of linear kinematic (Prager) hardening, d beta = (2/3) K d eps_p with the
modulus ``kinematic_hardening`` K. In uniaxial stress both give the plastic slope
d sigma / d eps_p = H + K; they differ on reversal (Bauschinger effect: with K alone,
reverse yielding starts 2 sigma_Y below the stress reached).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fem.tensors import lame_parameters

_VOL = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])
_DEV = np.eye(6) - np.outer(_VOL, _VOL) / 3.0


@dataclass(frozen=True, eq=False)
class PlasticState:
    """Plastic strain ``(6, ...)`` (Mandel), equivalent plastic strain ``(...)`` and the
    backstress ``(6, ...)`` (Mandel, deviatoric; ``None`` without kinematic hardening)."""

    plastic_strain: np.ndarray
    equivalent_plastic_strain: np.ndarray
    backstress: np.ndarray | None = None

    @classmethod
    def zeros(cls, shape: tuple, kinematic: bool = False) -> PlasticState:
        back = np.zeros((6,) + tuple(shape)) if kinematic else None
        return cls(np.zeros((6,) + tuple(shape)), np.zeros(tuple(shape)), back)


def _batch(matrix: np.ndarray, shape: tuple) -> np.ndarray:
    return np.broadcast_to(matrix.reshape((6, 6) + (1,) * len(shape)), (6, 6) + shape)


def radial_return(
    strain: np.ndarray,
    state: PlasticState,
    youngs_modulus: float,
    poissons_ratio: float,
    yield_stress: float,
    hardening: float = 0.0,
    tangent: bool = True,
    kinematic_hardening: float = 0.0,
):
    """One return map from the total ``strain`` and the state at the start of the step.

    Returns ``(stress, new_state, algorithmic_tangent)``; the tangent (``None`` unless
    ``tangent``) is the consistent one, ``d stress / d strain``, which gives quadratic
    convergence of Newton's method. With ``kinematic_hardening`` the state must carry a
    backstress (``PlasticState.zeros(shape, kinematic=True)``).
    """
    lam, mu = lame_parameters(youngs_modulus, poissons_ratio)
    shape = strain.shape[1:]
    elastic = strain - state.plastic_strain
    trace = elastic[:3].sum(axis=0)
    trial = 2.0 * mu * elastic + lam * trace * _VOL.reshape((6,) + (1,) * len(shape))
    dev = trial - (trial[:3].sum(axis=0) / 3.0) * _VOL.reshape((6,) + (1,) * len(shape))
    kinematic = kinematic_hardening != 0.0
    if kinematic and state.backstress is None:
        raise ValueError("kinematic hardening needs a state with a backstress")
    relative = dev - state.backstress if kinematic else dev
    norm = np.sqrt(np.sum(relative**2, axis=0))
    q = np.sqrt(1.5) * norm
    flow_stress = yield_stress + hardening * state.equivalent_plastic_strain
    f = q - flow_stress
    plastic = f > 0.0
    modulus = hardening + kinematic_hardening
    dgamma = np.where(plastic, f, 0.0) / (3.0 * mu + modulus)
    safe = np.where(plastic, norm, 1.0)
    direction = relative / safe  # unit deviatoric direction N (Mandel)
    # plastic strain increment dgamma * n, n = (3/2) xi / q = sqrt(3/2) N
    increment = np.sqrt(1.5) * dgamma * direction
    stress = trial - 2.0 * mu * increment
    backstress = state.backstress
    if kinematic:
        backstress = backstress + (2.0 / 3.0) * kinematic_hardening * increment
    new_state = PlasticState(
        state.plastic_strain + increment, state.equivalent_plastic_strain + dgamma, backstress
    )
    if not tangent:
        return stress, new_state, None
    if np.ndim(mu) == 0:
        d = np.array(_batch(2.0 * mu * np.eye(6) + lam * np.outer(_VOL, _VOL), shape))
    else:  # moduli per point (arrays broadcasting against the batch shape)
        d = (2.0 * mu * _batch(np.eye(6), shape)
             + lam * _batch(np.outer(_VOL, _VOL), shape))
    if np.any(plastic):
        # C_ep = C - 2mu [3mu/(3mu+H+K) N(x)N + (3mu dgamma/q)(I_dev - N(x)N)]
        nn = np.einsum("a...,b...->ab...", direction, direction)
        ratio = np.where(plastic, 3.0 * mu * dgamma / np.where(plastic, q, 1.0), 0.0)
        beta = np.where(plastic, 3.0 * mu / (3.0 * mu + modulus), 0.0)
        d -= 2.0 * mu * (beta * nn + ratio * (_batch(_DEV, shape) - nn))
    return stress, new_state, d
