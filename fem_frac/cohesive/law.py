"""Extrinsic cohesive traction-separation law (Ortiz & Pandolfi 1999), vectorized over points.

Kinematics at an interface point with unit normal n (from side a to side b) and displacement
jump d = u(b) - u(a):

    d_n = d . n,   d_s = d - d_n n,   lam = sqrt(<d_n>_+^2 + beta^2 |d_s|^2)
    P = beta^2 (I - n n^T) + H(d_n) n n^T,   so lam^2 = d^T P d   (H(x) = 1 if x > 0 else 0)

Envelope T(lam) of the effective traction, with the initial stiffness k0 per point and
lambda_0 = sigma_c / k0 (the stiff initial branch of the extrinsic law):

    lam <= lambda_0:          T = k0 lam                                    (elastic)
    linear:                   T = sigma_c (lambda_c - lam) / (lambda_c - lambda_0),
                              lambda_c = 2 G_c / sigma_c
    exponential:              T = sigma_c (exp(-s) - exp(-M)) / (1 - exp(-M)),
                              s = (lam - lambda_0) / ell,  lambda_c = lambda_0 + M ell,
                              ell = (G_c - sigma_c lambda_0 / 2) / (sigma_c c_M),
                              c_M = 1 - M exp(-M) / (1 - exp(-M)),  M = 6
    lam >= lambda_c:          T = 0

so the whole area under T is G_c for both laws; both need lambda_0 < lambda_c, which is
k0 > sigma_c^2 / (2 G_c).

History kappa (the largest effective opening reached, 0 at first), kappa_eff =
max(kappa, lambda_0): loading (lam >= kappa_eff) follows the envelope, unloading and reloading
(lam < kappa_eff) the line to the origin, T = T(kappa_eff) lam / kappa_eff. With the secant
slope s = T / lam (s = T(kappa_eff) / kappa_eff on unloading, so s = k0 at lam = 0 for an
undamaged point) the potential phi, the traction t = d phi / d d and its tangent are

    t = s P d + k0 min(d_n, 0) n          (compression: a penalty k0, never damaged)
    K = s P + [loading, lam > lambda_0] (T' - s) / lam^2 (P d)(P d)^T + k0 (1 - H(d_n)) n n^T

The secant stiffness s P + k0 (1 - H) n n^T is positive semidefinite. Energies per area:
stored = s lam^2 / 2 + k0 <d_n>_-^2 / 2, dissipated = W(kappa_eff) - T(kappa_eff) kappa_eff / 2
with W(lam) the integral of T from 0 to lam (G_c exactly once broken, kappa >= lambda_c).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

M = 6.0
"""Where the exponential envelope is truncated, in units of its length ell past lambda_0."""

_ONE_MINUS_EXP_M = -np.expm1(-M)  # 1 - exp(-M)
_EXP_M = np.exp(-M)
C_M = 1.0 - M * _EXP_M / _ONE_MINUS_EXP_M
"""Area of the exponential softening branch in units of sigma_c ell."""

KINDS = ("linear", "exponential")


@dataclass(frozen=True, eq=False)
class CohesiveResponse:
    """The law at ``k`` points: ``traction (k, 3)`` on side a from side b (d phi / d jump),
    ``tangent (k, 3, 3)`` d traction / d jump, ``secant (k, 3, 3)`` s(kappa_eff) P plus the
    compression penalty (positive semidefinite), the updated history ``kappa (k,)``, the energies
    per area ``stored`` and ``dissipated (k,)`` and ``broken (k,)`` (kappa >= lambda_c)."""

    traction: np.ndarray
    tangent: np.ndarray
    secant: np.ndarray
    kappa: np.ndarray
    stored: np.ndarray
    dissipated: np.ndarray
    broken: np.ndarray


@dataclass(frozen=True)
class _Scales:
    """Per-point openings of the envelope for the stiffness ``k0``."""

    k0: np.ndarray
    lam0: np.ndarray
    lamc: np.ndarray
    ell: np.ndarray  # exponential decay length (the softening length for the linear law)


@dataclass(frozen=True)
class TractionSeparation:
    """Cohesive law of ``kind`` ``"linear"`` or ``"exponential"`` with peak traction
    ``strength`` (sigma_c), fracture energy ``energy`` (G_c) and ``shear_weight`` (beta)."""

    kind: str
    strength: float
    energy: float
    shear_weight: float = 1.0

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"cohesive law kind {self.kind!r}: expected one of {KINDS}")
        for name in ("strength", "energy", "shear_weight"):
            value = getattr(self, name)
            if not (np.isscalar(value) and np.isfinite(value) and value > 0.0):
                raise ValueError(f"cohesive law {name} must be a finite number > 0, got {value!r}")

    def _scales(self, stiffness) -> _Scales:
        """lambda_0, lambda_c and ell for ``stiffness`` k0, checking lambda_0 < lambda_c."""
        k0 = np.asarray(stiffness, dtype=float)
        if not np.all(np.isfinite(k0) & (k0 > 0.0)):
            raise ValueError("cohesive stiffness k0 must be finite and > 0 at every point")
        sigma, gc = self.strength, self.energy
        k_min = sigma**2 / (2.0 * gc)
        bad = int(np.count_nonzero(k0 <= k_min))
        if bad:
            raise ValueError(
                f"cohesive law needs lambda_0 = sigma_c/k0 < lambda_c, i.e. k0 > sigma_c^2/(2 G_c)"
                f" = {k_min:.6g}; {bad} point(s) have k0 <= that (smallest {k0.min():.6g})")
        lam0 = sigma / k0
        if self.kind == "linear":
            lamc = np.broadcast_to(2.0 * gc / sigma, k0.shape)
            return _Scales(k0, lam0, lamc, lamc - lam0)
        ell = (gc - 0.5 * sigma * lam0) / (sigma * C_M)
        return _Scales(k0, lam0, lam0 + M * ell, ell)

    def peak_opening(self, stiffness) -> np.ndarray:
        """lambda_0 = sigma_c / k0, the opening at the peak traction."""
        return self._scales(stiffness).lam0

    def critical_opening(self, stiffness) -> np.ndarray:
        """lambda_c: 2 G_c / sigma_c (linear) or lambda_0 + M ell (exponential)."""
        return np.asarray(self._scales(stiffness).lamc)

    def envelope(self, lam, stiffness) -> tuple[np.ndarray, np.ndarray]:
        """The envelope T(lam) and its slope dT/dlam (0 past lambda_c, k0 up to lambda_0)."""
        return self._envelope(np.asarray(lam, dtype=float), self._scales(stiffness))

    def envelope_work(self, lam, stiffness) -> np.ndarray:
        """W(lam) = integral_0^lam T(x) dx in closed form (G_c for lam >= lambda_c)."""
        return self._work(np.asarray(lam, dtype=float), self._scales(stiffness))

    def _softening(self, lam: np.ndarray, sc: _Scales) -> tuple[np.ndarray, np.ndarray]:
        """The softening branch T and T' for lambda_0 <= lam <= lambda_c (clipped outside)."""
        sigma = self.strength
        if self.kind == "linear":
            t = sigma * (sc.lamc - lam) / sc.ell
            return t, np.broadcast_to(-sigma / sc.ell, t.shape)
        decay = np.exp(-np.clip((lam - sc.lam0) / sc.ell, 0.0, M))
        t = sigma * (decay - _EXP_M) / _ONE_MINUS_EXP_M
        return t, -sigma * decay / (sc.ell * _ONE_MINUS_EXP_M)

    def _envelope(self, lam: np.ndarray, sc: _Scales) -> tuple[np.ndarray, np.ndarray]:
        """T and T' on the three branches: elastic, softening, broken."""
        soft, dsoft = self._softening(lam, sc)
        elastic, gone = lam <= sc.lam0, lam >= sc.lamc
        t = np.where(elastic, sc.k0 * lam, np.where(gone, 0.0, soft))
        dt = np.where(elastic, sc.k0, np.where(gone, 0.0, dsoft))
        return t, dt

    def _work(self, lam: np.ndarray, sc: _Scales) -> np.ndarray:
        """W(lam): k0 lam^2 / 2, then sigma_c lambda_0 / 2 plus the softening area."""
        sigma = self.strength
        if self.kind == "linear":
            rest = np.clip(sc.lamc - lam, 0.0, None)
            soft = 0.5 * sigma * (sc.ell**2 - rest**2) / sc.ell
        else:
            x = np.clip((lam - sc.lam0) / sc.ell, 0.0, M)
            soft = sigma * sc.ell * (-np.expm1(-x) - x * _EXP_M) / _ONE_MINUS_EXP_M
        w = np.where(lam <= sc.lam0, 0.5 * sc.k0 * lam**2, 0.5 * sigma * sc.lam0 + soft)
        return np.where(lam >= sc.lamc, self.energy, w)

    def response(self, jump, normal, kappa, stiffness) -> CohesiveResponse:
        """Traction, tangent, secant, updated history and energies for ``jump (k, 3)``
        = u(b) - u(a), unit ``normal (k, 3)`` from a to b, history ``kappa (k,)`` and initial
        stiffness ``stiffness (k,)``; scalars and a single 3-vector broadcast."""
        jump, n, kappa, k0 = _points(jump, normal, kappa, stiffness)
        sc = self._scales(k0)
        dn = np.einsum("ki,ki->k", jump, n)
        tension = dn > 0.0
        beta2 = self.shear_weight**2
        ds = jump - dn[:, None] * n  # explicit, so lam has no cancellation error
        opening = np.maximum(dn, 0.0)
        lam = np.sqrt(opening**2 + beta2 * np.einsum("ki,ki->k", ds, ds))
        pj = beta2 * ds + opening[:, None] * n  # = P jump
        nn = n[:, :, None] * n[:, None, :]
        proj = beta2 * (np.eye(3) - nn) + np.where(tension, 1.0, 0.0)[:, None, None] * nn

        kappa_eff = np.maximum(kappa, sc.lam0)
        loading = lam >= kappa_eff
        t_lam, dt_lam = self._envelope(lam, sc)
        t_hist, _ = self._envelope(kappa_eff, sc)
        s = np.where(loading, t_lam / np.where(loading, lam, 1.0), t_hist / kappa_eff)

        closed = np.minimum(dn, 0.0)
        penalty = (sc.k0 * np.where(tension, 0.0, 1.0))[:, None, None] * nn
        secant = s[:, None, None] * proj + penalty
        traction = s[:, None] * pj + (sc.k0 * closed)[:, None] * n
        curved = loading & (lam > sc.lam0)
        coef = np.where(curved, (dt_lam - s) / np.where(curved, lam, 1.0) ** 2, 0.0)
        tangent = secant + coef[:, None, None] * pj[:, :, None] * pj[:, None, :]

        kappa_new = np.maximum(kappa, lam)
        hist = np.maximum(kappa_new, sc.lam0)
        t_new, _ = self._envelope(hist, sc)
        dissipated = np.where(hist <= sc.lam0, 0.0, self._work(hist, sc) - 0.5 * t_new * hist)
        stored = 0.5 * s * lam**2 + 0.5 * sc.k0 * closed**2
        return CohesiveResponse(traction, tangent, secant, kappa_new, stored, dissipated,
                                kappa_new >= sc.lamc)


def _points(jump, normal, kappa, stiffness):
    """Inputs broadcast to ``(k, 3), (k, 3), (k,), (k,)`` float arrays; the normals checked."""
    jump = np.atleast_2d(np.asarray(jump, dtype=float))
    normal = np.atleast_2d(np.asarray(normal, dtype=float))
    kappa = np.asarray(kappa, dtype=float)
    stiffness = np.asarray(stiffness, dtype=float)
    if jump.shape[-1] != 3 or normal.shape[-1] != 3 or jump.ndim != 2 or normal.ndim != 2:
        raise ValueError(f"jump and normal must be (k, 3), got {jump.shape} and {normal.shape}")
    (k,) = np.broadcast_shapes(jump.shape[:1], normal.shape[:1], kappa.shape, stiffness.shape)
    normal = np.broadcast_to(normal, (k, 3))
    if not np.allclose(np.linalg.norm(normal, axis=1), 1.0, rtol=0.0, atol=1e-6):
        raise ValueError("cohesive normals must be unit vectors")
    return (np.broadcast_to(jump, (k, 3)), normal, np.broadcast_to(kappa, (k,)),
            np.broadcast_to(stiffness, (k,)))
