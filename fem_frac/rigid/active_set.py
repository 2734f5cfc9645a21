"""The exact contact impulses on an active set, tried by the Gauss-Seidel of
:mod:`~fem_frac.rigid.contact` every few sweeps (its ``_polish``).

Gauss-Seidel converges slowly through a stack of bodies; once its iterate shows which
points push, which stick and which slide (and which way), the impulses on that active set
solve a linear system. Where they meet every condition of the contact problem, they are
its solution, exact to round-off, and the sweeps stop.
"""

from __future__ import annotations

import numpy as np

# The slack of the conditions: round-off of a least-squares solve, as a fraction of the
# velocities.
ROUND_OFF = 1e-12


def exact_on_active_set(a, b, lam, target, friction, scale, failed=None):
    """The exact impulses on the active set of ``lam`` (3c,), or ``None`` if they break a
    condition. Points with a normal impulse are active: sticking ones (inside the friction
    disc) reach ``v_n = target``, ``v_t = 0``; sliding ones (on the rim) ``v_n = target``
    with ``lambda_t = mu lambda_n s`` along their present direction ``s``. That linear
    system is solved by least squares (its minimum-norm solution: more points than freedoms
    leave it singular), then checked: ``lambda_n >= 0``, sticking impulses in the disc,
    sliding velocities against ``s``, every point's ``v_n >= target`` (to :data:`ROUND_OFF` of
    the velocities). failed: a list of one item that keeps the system of the last try that
    did not hold (its active, sticking and sliding points and the sliding directions); a
    try on the same system is the same computation, so it is not made again."""
    c = len(target)
    pts = lam.reshape(c, 3)
    active = pts[:, 0] > 0.0
    tangential = _lengths(pts[:, 1], pts[:, 2])
    sliding = active & (friction > 0.0) & (tangential >= friction * pts[:, 0] * (1 - 1e-9))
    sticking = active & (friction > 0.0) & ~sliding
    # the unknowns: the entries of lam at ``rows``, a sliding point's friction following
    # its normal impulse (``lam_t = mu lam_n s``)
    rows_n, rows_t = 3 * active.nonzero()[0], 3 * sticking.nonzero()[0]
    rows = np.sort(np.concatenate([rows_n, rows_t + 1, rows_t + 2]))
    slide = sliding.nonzero()[0]
    direction = pts[slide, 1:] / tangential[slide, None]
    col = np.searchsorted(rows, 3 * slide)
    follow = friction[slide, None] * direction  # (sliding, 2)
    system = (active.tobytes(), sticking.tobytes(), follow.tobytes())
    if failed is not None and failed[0] == system:
        return None
    # (the blocks of ``a`` by plain indexing: np.ix_'s, without its checks)
    across = rows[:, None]
    matrix = a[across, rows]
    matrix[:, col] += (a[across, 3 * slide + 1] * follow[:, 0]
                       + a[across, 3 * slide + 2] * follow[:, 1])
    rhs = np.zeros(3 * c)
    rhs[0::3] = target
    x = np.linalg.lstsq(matrix, (rhs - b)[rows], rcond=None)[0]
    exact = np.zeros(3 * c)
    exact[rows] = x
    exact[3 * slide + 1] = follow[:, 0] * x[col]
    exact[3 * slide + 2] = follow[:, 1] * x[col]
    v = (b + a @ exact).reshape(c, 3)
    pts = exact.reshape(c, 3)
    slack = ROUND_OFF * scale
    inside = _lengths(pts[:, 1], pts[:, 2]) <= friction * pts[:, 0] * (1 + 1e-12) + slack
    against = np.einsum("ij,ij->i", v[slide, 1:], direction) <= slack
    along = np.abs(v[slide, 1] * direction[:, 1] - v[slide, 2] * direction[:, 0]) <= slack
    if ((pts[:, 0] >= 0.0).all() and (v[:, 0] >= target - slack).all()
            and inside[sticking].all() and against.all() and along.all()):
        return exact
    if failed is not None:
        failed[0] = system
    return None


def _lengths(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``(k,)`` the lengths of the 2-vectors ``(x, y)``: np.linalg.norm's of their rows, to
    the bit (the same squares and sum), without its overhead."""
    return np.sqrt(x * x + y * y)
