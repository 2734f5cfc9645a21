"""The crack faces of a mesh: the boundary group ``crack`` holds both sides of every face
opened by crack insertion (:mod:`fem_frac.fracture.topology`); here they are paired."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .mesh import Mesh

CRACK = "crack"


@dataclass(frozen=True, eq=False)
class CrackFaces:
    """The crack faces of a mesh, each once, from its two sides.

    ``a``, ``b (k, 3)``: the vertex triples of a face's two sides (triangles of the
    ``crack`` group on copies of the same reference vertices), corners matched (``a[:, j]``
    and ``b[:, j]`` are copies of one vertex) and ordered as ``a`` is in the group, so that
    ``normal (k, 3)``, the unit normal of ``a``'s triangle, points out of side a's element
    into side b's. Sides are chosen so that the normal's largest component is positive: an
    opening ``u(b) - u(a)`` along ``+normal`` separates the faces. ``keys (k,)``: bytes
    naming a face by the reference positions of its corners (stable through later cracks
    and extractions, which keep reference positions). ``unpaired (m, 3)``: triangles whose
    other side has left the mesh (handed over to a rigid body).
    """

    a: np.ndarray
    b: np.ndarray
    normal: np.ndarray
    keys: list[bytes]
    unpaired: np.ndarray

    def __len__(self) -> int:
        return len(self.a)


def crack_faces(mesh: Mesh) -> CrackFaces:
    """Pair the two sides of every crack face of ``mesh`` (see :class:`CrackFaces`).

    Split vertices are copies at the same reference position, so the sides of a face are
    the two triangles whose corners sit at the same three positions."""
    tri = np.asarray(mesh.boundaries.get(CRACK, np.zeros((0, 3), dtype=np.int64)),
                     dtype=np.int64).reshape(-1, 3)
    empty = np.zeros((0, 3), dtype=np.int64)
    if len(tri) == 0:
        return CrackFaces(empty, empty, np.zeros((0, 3)), [], empty)
    x = mesh.points[tri]  # (n, 3, 3)
    # one id per reference position; np.unique orders the positions lexicographically
    positions, place = np.unique(x.reshape(-1, 3), axis=0, return_inverse=True)
    place = place.reshape(-1, 3)
    corners = np.sort(place, axis=1)
    order = np.lexsort((corners[:, 2], corners[:, 1], corners[:, 0]))
    same = np.all(corners[order[1:]] == corners[order[:-1]], axis=1)
    # pair neighbours in sorted order, a face at a time (a triangle pairs at most once)
    first = np.zeros(len(tri), dtype=bool)
    taken = np.zeros(len(tri), dtype=bool)
    for i in np.flatnonzero(same):
        if not taken[i] and not taken[i + 1]:
            first[i] = taken[i] = taken[i + 1] = True
    i1, i2 = order[:-1][first[:-1]], order[1:][first[:-1]]
    unpaired = tri[np.sort(order[~taken])]
    t1, t2 = tri[i1], tri[i2]
    # corner j of t2 that sits where corner j of t1 does
    match = np.argmax(place[i2][:, None, :] == place[i1][:, :, None], axis=2)
    t2 = np.take_along_axis(t2, match, axis=1)
    p = mesh.points[t1]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    # where the normal points down, side a is t2, wound the other way round (its normal -n)
    flip = _points_down(n)[:, None]
    a = np.where(flip, t2[:, [0, 2, 1]], t1)
    b = np.where(flip, t1[:, [0, 2, 1]], t2)
    keys = [positions[c].tobytes() for c in corners[i1]]
    return CrackFaces(a, b, np.where(flip, -n, n), keys, unpaired)


def _points_down(n: np.ndarray) -> np.ndarray:
    """Whether each unit normal's largest component (the first of those equal to it within
    1e-9, so that a normal and its negative pick the same one) is negative."""
    big = np.abs(n)
    k = np.argmax(big >= big.max(axis=1, keepdims=True) - 1e-9, axis=1)
    return n[np.arange(len(n)), k] < 0.0
