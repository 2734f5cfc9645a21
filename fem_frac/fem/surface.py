"""Boundary triangles of a space: the tet that holds each, its scalar nodes and a surface
quadrature, built from the triangles with numpy.

scikit-fem's ``FacetBasis`` and ``Basis.get_dofs(facets=...)`` need the mesh's global facet
table (and, for P2, its facet-to-edge table), built with ``np.unique(axis=1)`` over every
face of every tet: at 1e5 tets it cost as much as assembling the stiffness, on every
topology change. Here one sort of the tets' face keys (:class:`FaceLookup`) finds the tet
holding each triangle; its element dofs give the triangle's nodes (P2: the mid-edge nodes
of its three edges), and the quadrature is scikit-fem's rule on the reference triangle,
mapped as scikit-fem maps a facet: affine from the corners in ascending vertex order, or
isoparametric (P2 triangle) on a curved quadratic mesh. Normals point out of the holding
tet; a face that two tets share (an interface) is held by the one scikit-fem's ``f2t[0]``
names, so results match ``FacetBasis`` on the same faces to round-off.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from ..mesh.mesh import TET_EDGES, TET_FACES, SortedKeys, edge_keys, facet_keys
from .space import Space

# Edges of a triangle in scikit-fem's ``RefTri`` order (the P2 triangle's mid-edge nodes).
TRI_EDGES = np.array([[0, 1], [1, 2], [0, 2]])


class FaceLookup:
    """The faces of a mesh's tets (rows ``4 tet + local face`` of
    ``tets[:, TET_FACES]``), sorted by key once for every look-up on that topology."""

    def __init__(self, tets: np.ndarray, n_points: int):
        self.tets = np.asarray(tets, dtype=np.int64)
        self.n_points = n_points
        self.faces = self.tets[:, TET_FACES].reshape(-1, 3)
        self.table = SortedKeys(facet_keys(self.faces, n_points))

    def exterior(self) -> np.ndarray:
        """Corner triples ``(n, 3)`` of the faces held by one tet only, outward, in row
        order: :func:`fem_frac.mesh.mesh.exterior_facets`."""
        s = self.table.sorted
        if s.size == 0:
            return np.zeros((0, 3), dtype=np.int64)
        new = np.r_[True, s[1:] != s[:-1], True]
        starts = np.flatnonzero(new)
        single = starts[:-1][np.diff(starts) == 1]
        return self.faces[np.sort(self.table.order[single])]

    def holders(self, triples: np.ndarray) -> tuple[np.ndarray, bool]:
        """Row ``4 tet + local face`` holding each triple ``(k, 3)``: its only tet, or for a
        face two tets share, the one scikit-fem's ``f2t[0]`` names (the lowest local facet
        number in scikit-fem's order, then the lowest tet); and whether every triple has
        one tet only. ValueError for a triple that is no face of the mesh."""
        wanted = facet_keys(triples, self.n_points)
        first = self.table.rows(wanted)
        if np.any(first < 0):
            raise ValueError(f"{np.count_nonzero(first < 0)} facets are not faces of the mesh")
        shared = np.flatnonzero(self.table.counts(wanted) > 1)
        if len(shared):
            pos = np.searchsorted(self.table.sorted, wanted[shared])
            rows = self.table.order[np.stack([pos, pos + 1])]  # (2, k): both holders
            # scikit-fem's local facet j is opposite vertex 3 - j (TET_FACES: opposite i)
            rank = (3 - rows % 4) * len(self.tets) + rows // 4
            first[shared] = rows[np.argmin(rank, axis=0), np.arange(len(shared))]
        return first, len(shared) == 0


@dataclass(frozen=True, eq=False)
class Faces:
    """Boundary triangles of a space with their quadrature.

    ``nodes`` ``(k, n_local)``: scalar nodes of each triangle (corners in ascending order,
    then for P2 the mid-edge nodes of its edges in ``TRI_EDGES`` order); ``phi``
    ``(n_local, n_qp)``: the shape functions at the quadrature points; ``dx`` ``(k, n_qp)``:
    the area weights; ``normals`` ``(3, k, n_qp)``: unit normals out of the holding tet.
    """

    nodes: np.ndarray
    phi: np.ndarray
    dx: np.ndarray
    normals: np.ndarray
    # the face rows ``4 tet + local face`` of the holding tets, and whether every face is
    # held by that tet only (an exterior face, not an interface): a mesh a crack reconnected
    # keeps such rows and their faces (fem_frac.solve.problem.build_problem)
    rows: np.ndarray | None = None
    exterior: bool = False

    def __len__(self) -> int:
        return self.nodes.shape[0]


def faces_of(space: Space, triples: np.ndarray, lookup: FaceLookup | None = None) -> Faces:
    """The triangles ``triples (k, 3)`` of ``space``'s mesh with their nodes and quadrature
    (exact for quadratic data on P2, as the loads' ``FacetBasis`` was)."""
    mesh = space.mesh
    lookup = lookup if lookup is not None else FaceLookup(mesh.tets, mesh.n_points)
    triples = np.asarray(triples, dtype=np.int64).reshape(-1, 3)
    rows, exterior = lookup.holders(triples)
    return faces_at(space, rows, exterior)


def faces_at(space: Space, rows: np.ndarray, exterior: bool = False) -> Faces:
    """The faces at ``rows (k,)`` (``4 tet + local face``, oriented out of that tet) of
    ``space``'s mesh with their nodes and quadrature: :func:`faces_of` once their holders
    are known. ``exterior``: every face is held by its tet only (recorded)."""
    mesh = space.mesh
    rows = np.asarray(rows, dtype=np.int64)
    outward = np.take_along_axis(np.asarray(mesh.tets, dtype=np.int64)[rows // 4],
                                 TET_FACES[rows % 4], axis=1)
    corners = np.sort(outward, axis=1)
    nodes = corners if space.order == 1 else np.hstack(
        [corners, _mid_nodes(space, rows // 4, corners)])
    curved = space.order == 2 and mesh.curved  # the space's MeshTet2: isoparametric faces
    W, phi, dshape = _reference_face(space.order, curved)
    x = space.node_points[nodes[:, : 6 if curved else 3]]  # (k, n_geom, 3)
    tangents = np.einsum("kgi,gjq->jikq", x, dshape)  # (2, 3, k, q)
    cross = np.cross(tangents[0], tangents[1], axis=0)  # (3, k, q)
    area = np.sqrt(np.einsum("ikq,ikq->kq", cross, cross))
    # the ascending corners run the same way round as the outward triple when they are an
    # even permutation of it
    o = outward
    odd = ((o[:, 0] > o[:, 1]).astype(int) + (o[:, 0] > o[:, 2]) + (o[:, 1] > o[:, 2])) % 2
    sign = np.where(odd == 1, -1.0, 1.0)
    normals = cross * (sign[:, None] / area)[None]
    return Faces(nodes, phi, area * W[None, :], normals, rows, exterior)


@cache
def _reference_face(order: int, curved: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(W (q,), phi (n, q), dshape (g, 2, q))`` on the reference triangle: the quadrature
    weights of degree ``2 order``, the values of the ``n`` basis functions of order
    ``order`` and the derivatives of the ``g`` geometry functions (P2 where ``curved``)
    at its points; made once (read-only: a face set's arrays are computed from them)."""
    from skfem import ElementTriP1, ElementTriP2
    from skfem.quadrature import get_quadrature
    from skfem.refdom import RefTri

    X, W = get_quadrature(RefTri, 2 * order)
    element = ElementTriP1() if order == 1 else ElementTriP2()
    phi = np.stack([element.lbasis(X, a)[0] for a in range(3 if order == 1 else 6)])
    geometry = ElementTriP2() if curved else ElementTriP1()
    dshape = np.stack([geometry.lbasis(X, a)[1] for a in range(6 if curved else 3)])
    for a in (W, phi, dshape):
        a.flags.writeable = False
    return W, phi, dshape


def _mid_nodes(space: Space, tets: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Mid-edge nodes ``(k, 3)`` of the edges ``TRI_EDGES`` of triangles ``corners (k, 3)``,
    read from the element dofs of the tets ``(k,)`` holding them."""
    n = space.mesh.n_points
    local = np.asarray(space.skmesh.t, dtype=np.int64).T[tets]  # the space's own tets
    tet_edges = edge_keys(local[:, TET_EDGES].reshape(-1, 2), n).reshape(-1, 6)
    tri_edges = edge_keys(corners[:, TRI_EDGES].reshape(-1, 2), n).reshape(-1, 3)
    k = np.argmax(tri_edges[:, :, None] == tet_edges[:, None, :], axis=2)  # (k, 3)
    scalar = space.element_dofs[tets][:, ::3] // 3  # (k, 10): corners, then the 6 edges
    return np.take_along_axis(scalar, 4 + k, axis=1)


def face_load(space: Space, faces: Faces, traction=None, pressure=None) -> np.ndarray:
    """Consistent nodal forces ``(n_dofs,)`` of a constant traction (force/area, ``(3,)``)
    and/or a pressure (force/area along the inward normal) on ``faces``."""
    t = np.zeros((3,) + faces.dx.shape)
    if traction is not None:
        t += np.asarray(traction, dtype=float)[:, None, None]
    if pressure is not None:
        t -= pressure * faces.normals
    nodal = np.einsum("aq,ikq,kq->kai", faces.phi, t, faces.dx)
    dofs = 3 * faces.nodes[:, :, None] + np.arange(3)
    return np.bincount(dofs.ravel(), weights=nodal.ravel(), minlength=space.n_dofs)


def face_nodes(faces: Faces) -> np.ndarray:
    """Scalar node ids on ``faces`` (corners and, for P2, mid-edge nodes), ascending."""
    return np.unique(faces.nodes)


def normal_axis(faces: Faces, tol: float = 1e-6) -> int | None:
    """The coordinate axis every face is normal to, or None if they are not axis-aligned."""
    n = faces.normals.reshape(3, -1)
    axis = int(np.argmax(np.abs(n[:, 0])))
    return axis if np.all(np.abs(np.abs(n[axis]) - 1.0) < tol) else None
