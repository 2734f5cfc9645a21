"""The least translation that takes a body out of what it overlaps.

A body moved by ``s`` changes the gap of a contact point with normal ``n`` (pointing the
way the body must go to open it) by ``n . s``; the least translation that closes every
penetration (gap < 0) solves ``min |s|`` subject to ``n_c . s >= -gap_c``: a
least-distance problem, solved exactly as a non-negative least-squares problem (Lawson and
Hanson, *Solving Least Squares Problems*, 1974, ch. 23): with ``E = [N^T; h^T]``
(``h = -gap``) and the solution ``u >= 0`` of ``min |E u - (0, 0, 0, 1)|``, the residual
``r`` gives ``s = -r[:3] / r[3]``; ``r = 0`` means no translation closes them all.

Where a vertex sits on an edge of a jagged crack, its two nearest faces can have nearly
opposite normals (a beam's two side faces), and the least translation that closes both is
far longer than either depth (18 mm for millimetres deep in the breaking beam). Such a
body is **wedged**: a translation longer than ``WEDGED`` times the deepest penetration
(normals more than 120 degrees apart, for two of equal depth ``d``: ``d / cos 60``) is not
taken, and the body is left where it is.
"""

from __future__ import annotations

import numpy as np

from ..mesh.mesh import TET_EDGES, TET_FACES
from .body import rotation_matrix
from .vectors import cross, lengths

WEDGED = 2.0


def least_translation(normals, gaps) -> np.ndarray:
    """``(3,)``: the least translation with ``n_c . s >= -gap_c`` for every contact with
    ``gap_c < 0`` (module docstring); zero when none penetrates, when no translation
    closes them all, or when the body is wedged."""
    normals = np.asarray(normals, dtype=float).reshape(-1, 3)
    gaps = np.asarray(gaps, dtype=float).ravel()
    inside = gaps < 0.0
    if not np.any(inside):
        return np.zeros(3)
    from scipy.optimize import nnls

    h = -gaps[inside]
    scale = float(h.max())
    e = np.vstack([normals[inside].T, h[None, :] / scale])
    f = np.array([0.0, 0.0, 0.0, 1.0])
    u, _ = nnls(e, f)
    r = e @ u - f
    if r[3] > -1e-12:  # no translation closes them all
        return np.zeros(3)
    s = -r[:3] / r[3] * scale
    return s if np.linalg.norm(s) <= WEDGED * scale else np.zeros(3)


def _face_axes(x: np.ndarray) -> np.ndarray:
    """(k, 4, 3) the (unnormalized) face normals of tets ``x (k, 4, 3)``."""
    c = x[:, TET_FACES]
    return cross(c[:, :, 1] - c[:, :, 0], c[:, :, 2] - c[:, :, 0])


def tet_overlaps(xa: np.ndarray, xb: np.ndarray,
                 size: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(normal (k, 3), depth (k,))`` of each pair of tets ``xa[k]``, ``xb[k]`` (each
    ``(k, 4, 3)``, world vertices) by the separating-axis theorem: over the axes of the two
    tets' face normals and the cross products of their edges (44), the one along which
    their projections overlap least; ``depth`` that overlap (<= 0: apart) and ``normal``
    the unit direction along which ``b`` must move that far to leave ``a``."""
    k = len(xa)
    if k == 0:
        return np.zeros((0, 3)), np.zeros(0)
    ea = xa[:, TET_EDGES[:, 1]] - xa[:, TET_EDGES[:, 0]]
    eb = xb[:, TET_EDGES[:, 1]] - xb[:, TET_EDGES[:, 0]]
    edges = cross(ea[:, :, None], eb[:, None, :]).reshape(k, 36, 3)
    axes = np.concatenate([_face_axes(xa), _face_axes(xb), edges], axis=1)
    length = lengths(axes)
    if size is None:
        size = max(float(np.abs(ea).max()), float(np.abs(eb).max()))
    valid = length > 1e-9 * size * size  # parallel edges give no axis
    axes = axes / np.where(valid, length, 1.0)[:, :, None]
    pa = np.einsum("kai,kvi->kav", axes, xa)
    pb = np.einsum("kai,kvi->kav", axes, xb)
    forward = pa.max(axis=2) - pb.min(axis=2)  # b moves +axis this far to clear a
    backward = pb.max(axis=2) - pa.min(axis=2)  # or -axis this far
    overlap = np.where(valid, np.minimum(forward, backward), np.inf)
    best = np.argmin(overlap, axis=1)
    rows = np.arange(k)
    sign = np.where(forward[rows, best] <= backward[rows, best], 1.0, -1.0)
    return axes[rows, best] * sign[:, None], overlap[rows, best]


def world_tets(body, shape) -> np.ndarray:
    """``(e, 4, 3)``: a body's tets in world coordinates: its own (``shape``, a
    :class:`~fem_frac.rigid.surface.Solid`), else its hull's Delaunay tets."""
    if shape is not None:
        x, tets = shape.vertices, shape.tets
    else:
        from scipy.spatial import Delaunay

        x = np.asarray(body.points, dtype=float)
        tets = Delaunay(x).simplices
    return body.position + x[tets] @ rotation_matrix(body.orientation).T


def overlap_constraints(xa: np.ndarray, xb: np.ndarray, tolerance: float):
    """``(normal (k, 3), depth (k,))``: the tets of ``b`` (``xb (eb, 4, 3)``) that overlap
    tets of ``a`` (``xa (ea, 4, 3)``) deeper than ``tolerance``: for each such pair, the
    direction ``b`` must move to clear it and how far (:func:`tet_overlaps`); the pairs
    found by their bounding boxes (sort and sweep)."""
    from .collide import cross_pairs

    pairs = cross_pairs(xa.min(axis=1), xa.max(axis=1), xb.min(axis=1), xb.max(axis=1))
    pa, pb = xa[pairs[:, 0]], xb[pairs[:, 1]]
    size = _edge_size(pa, pb)
    # the depth is the least overlap over all the axes, so a pair whose face normals alone
    # overlap it no more than tolerance is no deeper (a round-off's slack more kept): only
    # the others need the 36 edge axes
    deep = _face_overlap(pa, pb, size) > tolerance - 1e-9 * size
    normal, depth = tet_overlaps(pa[deep], pb[deep], size)
    keep = depth > tolerance
    return normal[keep], depth[keep]


def _edge_size(xa: np.ndarray, xb: np.ndarray) -> float:
    """The largest edge component of the tets ``xa``, ``xb`` (k, 4, 3): the scale of
    :func:`tet_overlaps`' test for parallel edges."""
    if len(xa) == 0:
        return 0.0
    ea = xa[:, TET_EDGES[:, 1]] - xa[:, TET_EDGES[:, 0]]
    eb = xb[:, TET_EDGES[:, 1]] - xb[:, TET_EDGES[:, 0]]
    return max(float(np.abs(ea).max()), float(np.abs(eb).max()))


def _face_overlap(xa: np.ndarray, xb: np.ndarray, size: float) -> np.ndarray:
    """``(k,)``: the least overlap of the tets' projections over their 8 face normals, an
    upper bound of :func:`tet_overlaps`' depth with the same ``size`` (the same axes,
    valid where they are valid there, and the same arithmetic)."""
    if len(xa) == 0:
        return np.zeros(0)
    axes = np.concatenate([_face_axes(xa), _face_axes(xb)], axis=1)
    length = lengths(axes)
    valid = length > 1e-9 * size * size
    axes = axes / np.where(valid, length, 1.0)[:, :, None]
    pa = np.einsum("kai,kvi->kav", axes, xa)
    pb = np.einsum("kai,kvi->kav", axes, xb)
    overlap = np.minimum(pa.max(axis=2) - pb.min(axis=2), pb.max(axis=2) - pa.min(axis=2))
    return np.where(valid, overlap, np.inf).min(axis=1)
