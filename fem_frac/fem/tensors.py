"""Symmetric tensors as 6-vectors, components first: ``(6, ...)``.

Two layouts, both in VTK's component order XX, YY, ZZ, XY, YZ, XZ:

- *Mandel* (``m``): shear components scaled by sqrt(2). Double contraction is a plain dot
  product and a fourth-order tangent is a symmetric 6x6 matrix. Used inside the solver.
- *tensor* (``t``): plain components, what ParaView shows. Used for output only.
"""

from __future__ import annotations

import contextlib

import numpy as np

from ..errors import SolverError

SQRT2 = np.sqrt(2.0)
# (row, column) of each 6-vector component in the 3x3 tensor, VTK order.
COMPONENTS = ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2))
_MANDEL_SCALE = np.array([1.0, 1.0, 1.0, SQRT2, SQRT2, SQRT2])
# the inverse of COMPONENTS: the 6-vector component of each 3x3 entry
_MATRIX_INDEX = np.array([[0, 3, 5], [3, 1, 4], [5, 4, 2]])


def mandel_from_matrix(a: np.ndarray) -> np.ndarray:
    """``(3, 3, ...)`` symmetric (or symmetrized) tensor -> ``(6, ...)`` Mandel vector."""
    out = np.empty((6,) + a.shape[2:])
    for k, (i, j) in enumerate(COMPONENTS):
        out[k] = a[i, j] if i == j else (a[i, j] + a[j, i]) / SQRT2
    return out


def tensor_from_mandel(m: np.ndarray) -> np.ndarray:
    """``(6, ...)`` Mandel -> ``(6, ...)`` plain tensor components (VTK order)."""
    return m / _MANDEL_SCALE.reshape((6,) + (1,) * (m.ndim - 1))


def isotropic_tangent(youngs_modulus: float, poissons_ratio: float) -> np.ndarray:
    """Mandel 6x6 matrix of isotropic linear elasticity, ``sigma = D eps``."""
    lam, mu = lame_parameters(youngs_modulus, poissons_ratio)
    d = 2.0 * mu * np.eye(6)
    d[:3, :3] += lam
    return d


def lame_parameters(youngs_modulus: float, poissons_ratio: float) -> tuple[float, float]:
    """(lambda, mu) from E and nu."""
    e, nu = youngs_modulus, poissons_ratio
    return e * nu / ((1 + nu) * (1 - 2 * nu)), e / (2 * (1 + nu))


def von_mises(m: np.ndarray) -> np.ndarray:
    """Von Mises equivalent stress sqrt(3/2 |dev s|) of Mandel stresses ``(6, ...)``."""
    p = (m[0] + m[1] + m[2]) / 3.0
    dev2 = (m[0] - p) ** 2 + (m[1] - p) ** 2 + (m[2] - p) ** 2 + np.sum(m[3:] ** 2, axis=0)
    return np.sqrt(1.5 * dev2)


def matrices_from_mandel(m: np.ndarray) -> np.ndarray:
    """``(6, ...)`` Mandel -> ``(..., 3, 3)`` plain symmetric matrices (a view, components
    last, the layout :mod:`numpy.linalg` batches over)."""
    t = tensor_from_mandel(np.asarray(m, dtype=float))
    return np.moveaxis(t[_MATRIX_INDEX], (0, 1), (-2, -1))


def principal(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues ``(..., 3)``, ascending, and unit eigenvectors ``(..., 3, 3)`` (column
    ``k`` belongs to value ``k``) of Mandel tensors ``(6, ...)``: batched
    :func:`numpy.linalg.eigh`, a large batch over the cores (:mod:`fem_frac.threads`, the
    same bits). Signs of the vectors are whatever LAPACK returns."""
    from ..threads import map_ranges

    matrices = matrices_from_mandel(m)
    with _converging():
        if matrices.ndim != 3:
            return np.linalg.eigh(matrices)
        parts = map_ranges(lambda a, b: np.linalg.eigh(matrices[a:b]), matrices.shape[0])
    if len(parts) == 1:
        return parts[0]
    return (np.concatenate([values for values, _ in parts]),
            np.concatenate([vectors for _, vectors in parts]))


def principal_values(m: np.ndarray) -> np.ndarray:
    """Eigenvalues, ascending, ``(3, ...)`` of Mandel tensors ``(6, ...)``.

    :func:`numpy.linalg.eigvalsh` of the matrices of :func:`principal`: cheaper than
    ``eigh`` when no vectors are wanted (the two may differ by a few ulps)."""
    with _converging():
        return np.moveaxis(np.linalg.eigvalsh(matrices_from_mandel(m)), -1, 0)


#: |cross product|^2 / |row|^4 of ``A - lambda I`` below which its rank is taken as 1
RANK_ONE = 1e-20


def largest_principal(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The largest eigenvalue ``(...)`` and a unit eigenvector ``(..., 3)`` of Mandel
    tensors ``(6, ...)`` in closed form, a few array operations instead of one LAPACK call
    per tensor (about 5x cheaper than :func:`principal` for 1e5 tensors).

    The value by the trigonometric solution of the characteristic cubic of the deviator
    (O. K. Smith, Comm. ACM 4(4), 1961), not :func:`principal`'s to the bit: its error is a
    few ulps of the deviator's size where the largest value stands apart (or the top two
    are equal), but where the top two nearly coincide (a gap of 1e-10 to 1e-7 of the
    size) the cubic's phase sits where ``arccos`` is ill-conditioned, and the error grows
    to ~sqrt(eps) of the size (1.6e-8 measured at a gap of 3e-8).
    The vector: the largest cross product of two rows of ``A - lambda I``; where the value
    is repeated (the cross products below ``RANK_ONE`` of the rows' size) one vector of
    its eigenspace, where all three are equal (0, 0, 1). Near a repeated value the vector
    is as ill-conditioned as any eigenvector there (error ~ eps |A| / gap).
    """
    t = tensor_from_mandel(np.asarray(m, dtype=float))
    value = _largest_value(t)
    rows = np.stack([np.stack([t[0] - value, t[3], t[5]], axis=-1),
                     np.stack([t[3], t[1] - value, t[4]], axis=-1),
                     np.stack([t[5], t[4], t[2] - value], axis=-1)])
    cross = np.stack([np.cross(rows[0], rows[1]), np.cross(rows[0], rows[2]),
                      np.cross(rows[1], rows[2])])  # (3, ..., 3)
    norm2 = np.sum(cross * cross, axis=-1)
    best = np.argmax(norm2, axis=0)
    vector = np.take_along_axis(cross, best[None, ..., None], axis=0)[0]
    size2 = np.take_along_axis(norm2, best[None], axis=0)[0]
    # the value repeated: A - lambda I has rank 1 (its rows parallel, their cross products
    # round-off); the eigenspace is the plane normal to its largest row
    row2 = np.sum(rows * rows, axis=-1)
    top = np.take_along_axis(rows, np.argmax(row2, axis=0)[None, ..., None], axis=0)[0]
    top2 = np.max(row2, axis=0)
    rank1 = size2 <= RANK_ONE * top2 * top2
    axis = np.eye(3)[np.argmin(np.abs(top), axis=-1)]
    vector = np.where(rank1[..., None], np.cross(top, axis), vector)
    size = np.sqrt(np.sum(vector * vector, axis=-1))
    flat = size == 0.0  # all three values equal
    vector = np.where(flat[..., None], [0.0, 0.0, 1.0],
                      vector / np.where(flat, 1.0, size)[..., None])
    return value, vector


def largest_value(m: np.ndarray) -> np.ndarray:
    """The largest eigenvalue ``(...)`` of Mandel tensors ``(6, ...)``: the value of
    :func:`largest_principal` (the same bits) without its vector, about a sixth of its
    cost (docs/performance.md)."""
    return _largest_value(tensor_from_mandel(np.asarray(m, dtype=float)))


#: ``1 + r`` (r the cosine of three times the deviator's phase, -1 where the top two values
#: coincide) below which :func:`largest_values` asks LAPACK: above it ``arccos`` is well
#: conditioned and the closed form's error is within ~100 ulps of the tensor's size (10.6
#: ulps of its largest component the most measured on 2e5 random tensors with gaps over 16
#: decades; docs/performance.md)
NEAR_DOUBLE = 1e-2


def largest_values(m: np.ndarray) -> np.ndarray:
    """The largest eigenvalue ``(...)`` of Mandel tensors ``(6, ...)``, within ~100 ulps of
    each tensor's size of :func:`principal_values`' (LAPACK's) at a twentieth of its
    cost: the closed form of :func:`largest_value`, and LAPACK's
    value itself (the same bits) where the top two values nearly coincide (the phase's
    ``1 + r < NEAR_DOUBLE``), where the closed form loses up to ~sqrt(eps) of the size."""
    m = np.asarray(m, dtype=float)
    q, p, r = _invariants(tensor_from_mandel(m))
    value = q + 2.0 * p * np.cos(np.arccos(r) / 3.0)
    near = 1.0 + r < NEAR_DOUBLE
    if np.any(near):
        value[near] = principal_values(m[:, near])[-1]
    return value


# The slack of largest_value_bound, of a tensor's size: round-off of the bound and of an
# eigen-decomposition is a few ulps of it.
BOUND_SLACK = 1e-12


def largest_value_bound(m: np.ndarray) -> np.ndarray:
    """An upper bound ``(...)`` of the largest eigenvalue of Mandel tensors ``(6, ...)``, for
    a few passes over them: ``p + sqrt(2/3) |dev|`` (``p`` the mean of the diagonal,
    ``|dev|`` the Frobenius norm of the deviator, whose largest eigenvalue is at most
    ``sqrt(2/3)`` of it; equal for a uniaxial tensor), raised by :data:`BOUND_SLACK` of the
    tensor's size ``|p| + |m|`` so that no computed eigenvalue exceeds it."""
    m = np.asarray(m, dtype=float)
    p = np.sum(m[:3], axis=0) / 3.0
    deviator = np.sum((m[:3] - p) ** 2, axis=0) + np.sum(m[3:] ** 2, axis=0)
    size = np.abs(p) + np.sqrt(np.sum(m * m, axis=0))
    return p + np.sqrt(2.0 / 3.0 * deviator) + BOUND_SLACK * size


def _largest_value(t: np.ndarray) -> np.ndarray:
    """The trigonometric solution of :func:`largest_principal` on tensor components ``t``
    (xx, yy, zz, xy, yz, xz)."""
    q, p, r = _invariants(t)
    return q + 2.0 * p * np.cos(np.arccos(r) / 3.0)


def _invariants(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(q, p, r)`` of tensor components ``t``: the mean of the diagonal, the deviator's
    size ``sqrt(|dev|^2 / 6)`` and ``det(dev) / (2 p^3)`` clipped to [-1, 1] (0 where
    ``p = 0``); the values are ``q + 2 p cos((arccos r + 2 pi k) / 3)``."""
    q = (t[0] + t[1] + t[2]) / 3.0
    a, b, c = t[0] - q, t[1] - q, t[2] - q
    d, e, f = t[3], t[4], t[5]
    p = np.sqrt((a * a + b * b + c * c + 2.0 * (d * d + e * e + f * f)) / 6.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        det = a * (b * c - e * e) - d * (d * c - e * f) + f * (d * e - b * f)
        r = np.clip(np.where(p > 0.0, det / (2.0 * np.where(p > 0.0, p, 1.0) ** 3), 0.0),
                    -1.0, 1.0)
    return q, p, r


@contextlib.contextmanager
def _converging():
    """LAPACK's failure to converge (on non-finite or absurdly large stresses) as a
    :class:`SolverError`: a numerical failure, not a bug."""
    try:
        yield
    except np.linalg.LinAlgError as exc:
        raise SolverError(f"principal stresses: {exc} (stresses not finite or too large: "
                          "an extreme load?)") from None
