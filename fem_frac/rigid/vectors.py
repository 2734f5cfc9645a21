"""Cross products and lengths of small vectors for the rigid-body steps, to numpy's bit.

The contact steps take tens of thousands of cross products and lengths of a few vectors
each (contact frames, Jacobian rows, the tets' face normals and edge axes of the overlap
tests, the reach of a body's step). ``np.cross`` and ``np.linalg.norm`` spend most of such
a call on their generality (axis arguments, ``moveaxis``, casts, dispatch); the functions
here do the same products, sums and roots in the same order, so their results are numpy's
to the bit (``tests/test_rigid_vectors.py``).
"""

from __future__ import annotations

import numpy as np


def cross(a, b) -> np.ndarray:
    """``np.cross(a, b)`` of float arrays of 3-vectors ``(..., 3)``, broadcast against each
    other: ``(a1 b2 - a2 b1, a2 b0 - a0 b2, a0 b1 - a1 b0)``, each product rounded, then
    the difference, as ``np.cross`` computes them."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if a.ndim == 1 and b.ndim == 1:
        # two vectors: Python floats round each product and difference as numpy's do
        (a0, a1, a2), (b0, b1, b2) = a.tolist(), b.tolist()
        return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])
    out = np.empty(np.broadcast_shapes(a.shape[:-1], b.shape[:-1]) + (3,))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    np.multiply(a1, b2, out=out[..., 0])
    out[..., 0] -= a2 * b1
    np.multiply(a2, b0, out=out[..., 1])
    out[..., 1] -= a0 * b2
    np.multiply(a0, b1, out=out[..., 2])
    out[..., 2] -= a1 * b0
    return out


def length(v) -> np.floating:
    """``np.linalg.norm(v)`` of one float vector: the square root of its dot product with
    itself, as ``norm`` takes it (``ravel``, then ``dot``), a numpy scalar."""
    x = np.asarray(v, dtype=float).ravel(order="K")
    return np.sqrt(x.dot(x))


def lengths(v: np.ndarray) -> np.ndarray:
    """``(...)`` the lengths of the vectors ``v (..., 3)``: ``np.linalg.norm(v, axis=-1)``,
    its sum of squares in the same order (numpy's reduction over three terms runs left to
    right)."""
    return np.sqrt(v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1] + v[..., 2] * v[..., 2])
