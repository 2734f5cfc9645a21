"""Time-integration schemes as coefficients and pure updates (DESIGN §2).

Implicit schemes share one residual form, solved for u at t_{n+1}:

    R(u) = (1+alpha) F_{n+1} - alpha F_n - M a(u) - (1+alpha) (C v(u) + f_int(u))
           + alpha (C v_n + f_int_n)

with the Newmark relations a(u) = (u - u~) / (beta dt^2), v(u) = v~ + gamma dt a(u), where
the predictors u~ = u_n + dt v_n + dt^2 (1/2 - beta) a_n and v~ = v_n + (1 - gamma) dt a_n.
``alpha = 0`` is Newmark; HHT-alpha takes alpha in [-1/3, 0] with beta = (1 - alpha)^2 / 4
and gamma = 1/2 - alpha. A quasi-static step is the same form with M = C = 0. The Jacobian
is ``c_mass M + (1 + alpha) (c_damping C + K)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config.schema import NEWMARK_BETA, NEWMARK_GAMMA


@dataclass(frozen=True)
class Implicit:
    """Coefficients of one implicit scheme at a fixed step ``dt``."""

    dt: float
    beta: float = NEWMARK_BETA  # the schema's defaults (average acceleration)
    gamma: float = NEWMARK_GAMMA
    alpha: float = 0.0
    inertia: bool = True

    @property
    def c_mass(self) -> float:
        return 1.0 / (self.beta * self.dt**2) if self.inertia else 0.0

    @property
    def c_damping(self) -> float:
        return self.gamma / (self.beta * self.dt) if self.inertia else 0.0

    def predict(self, u: np.ndarray, v: np.ndarray, a: np.ndarray):
        """``(u~, v~)`` of the Newmark relations."""
        dt = self.dt
        return (
            u + dt * v + dt * dt * (0.5 - self.beta) * a,
            v + (1.0 - self.gamma) * dt * a,
        )

    def rates(self, u: np.ndarray, u_pred: np.ndarray, v_pred: np.ndarray):
        """``(v, a)`` at t_{n+1} of the displacement ``u`` there."""
        if not self.inertia:
            return np.zeros_like(u), np.zeros_like(u)
        a = (u - u_pred) * self.c_mass
        return v_pred + self.gamma * self.dt * a, a


def quasi_static(dt: float) -> Implicit:
    return Implicit(dt=dt, inertia=False)


def newmark(dt: float, beta: float, gamma: float) -> Implicit:
    """Newmark with ``beta``, ``gamma`` as the case resolves them
    (``DynamicAnalysis.newmark_beta`` / ``newmark_gamma``: by default average acceleration,
    beta 1/4 and gamma 1/2, unconditionally stable and energy-conserving for linear
    problems)."""
    return Implicit(dt=dt, beta=beta, gamma=gamma)


def hht(dt: float, alpha: float) -> Implicit:
    """HHT-alpha (Hilber, Hughes, Taylor 1977): second order, unconditionally stable for
    alpha in [-1/3, 0], damping high frequencies more as alpha decreases."""
    if not -1.0 / 3.0 <= alpha <= 0.0:
        raise ValueError(f"HHT alpha must lie in [-1/3, 0], got {alpha}")
    return Implicit(dt=dt, beta=(1.0 - alpha) ** 2 / 4.0, gamma=0.5 - alpha, alpha=alpha)


def central_difference_limit(omega_max: float, mass_damping: float = 0.0,
                             stiffness_damping: float = 0.0) -> float:
    """Stable step of central difference for the highest frequency ``omega_max`` with
    Rayleigh damping C = a0 M + a1 K: dt = (2 / omega) (sqrt(1 + xi^2) - xi), where
    xi = a0 / (2 omega) + a1 omega / 2 is that mode's damping ratio (Belytschko, Liu, Moran,
    Nonlinear Finite Elements, §6.2). Undamped: 2 / omega."""
    xi = mass_damping / (2.0 * omega_max) + stiffness_damping * omega_max / 2.0
    return 2.0 / omega_max * (np.sqrt(1.0 + xi * xi) - xi)
