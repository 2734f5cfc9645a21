"""How an equilibrium iteration is accelerated and judged: Anderson mixing of modified
Newton's corrections, and the contraction rate of the residual that predicts whether an
iteration will reach its tolerance within its cap (the limit-load rule of
:class:`~fem_frac.solve.stepping.ImplicitStepper`, docs/solvers.md)."""

from __future__ import annotations

import math

import numpy as np

# Past corrections Anderson mixing keeps (Walker & Ni 2011 use 1 to 10; 5 is a common choice).
ANDERSON_DEPTH = 5
# Iterations over which the contraction rate of the residual is measured (docs/solvers.md,
# "Near a limit load"): the best residual of the last RATE_WINDOW iterations against the best
# of the RATE_WINDOW before, so the rule reads 2 RATE_WINDOW iterations before it can fire.
RATE_WINDOW = 10


def norm(x) -> float:
    """Euclidean norm of a residual or correction without BLAS: ``np.linalg.norm`` goes
    through a threaded BLAS dot that costs milliseconds under contention for a vector that
    einsum sums in microseconds."""
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.einsum("i,i->", x, x))) if x.ndim else abs(float(x))


class Anderson:
    """Anderson acceleration of the fixed-point iteration u <- u + J0^-1 R(u) of modified
    Newton (Walker & Ni, SIAM J. Numer. Anal. 49, 2011): the next iterate combines the last
    ``depth`` iterates so as to minimize the linearized correction. The corrections are
    J0-preconditioned residuals already computed by the back-solve, so it costs a few dot
    products per iteration; a converged iteration is unchanged (the correction vanishes).
    """

    def __init__(self, depth: int):
        self.depth = depth
        self.u: list[np.ndarray] = []
        self.f: list[np.ndarray] = []

    def __call__(self, u: np.ndarray, f: np.ndarray) -> np.ndarray:
        """The step to take from ``u`` given the plain correction ``f``."""
        self.u.append(u.copy())
        self.f.append(f)
        if len(self.u) > self.depth + 1:
            self.u.pop(0)
            self.f.pop(0)
        if len(self.u) < 2:
            return f
        df = np.stack([b - a for a, b in zip(self.f[:-1], self.f[1:], strict=True)], axis=1)
        du = np.stack([b - a for a, b in zip(self.u[:-1], self.u[1:], strict=True)], axis=1)
        gamma, *_ = np.linalg.lstsq(df, f, rcond=1e-10)
        if not np.all(np.isfinite(gamma)):
            self.u, self.f = self.u[-1:], self.f[-1:]
            return f
        return f - (du + df) @ gamma


def contraction(residuals: list[float], window: int = RATE_WINDOW) -> float | None:
    """The mean contraction of the residual an iteration: the best (least) residual of the
    last ``window`` iterations against the best of the ``window`` before, to the power
    1 / ``window`` (Anderson mixing makes single iterations go up and down). ``None``
    before ``2 window`` residuals are recorded."""
    if len(residuals) < 2 * window:
        return None
    recent, before = min(residuals[-window:]), min(residuals[-2 * window:-window])
    return (recent / before) ** (1.0 / window) if before > 0.0 else 0.0


def iterations_left(residuals: list[float], tolerance: float,
                    window: int = RATE_WINDOW) -> float | None:
    """The iterations still needed to bring the residual under ``tolerance`` at the
    :func:`contraction` rate (``inf`` when it does not contract); ``None`` before the rate
    can be measured."""
    rate = contraction(residuals, window)
    if rate is None:
        return None
    best = min(residuals[-window:])
    if best <= tolerance or rate == 0.0:
        return 0.0
    return math.log(tolerance / best) / math.log(rate) if rate < 1.0 else math.inf
