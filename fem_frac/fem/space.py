"""Vector P1/P2 function spaces on a :class:`~fem_frac.mesh.Mesh`, built on scikit-fem.

Degrees of freedom are numbered ``3 * node + component`` where ``node`` is scikit-fem's
scalar dof (vertices first, then edge mid-nodes for P2). This is the numbering of
``ElementVector`` in scikit-fem, so its tools (``condense``, facet dofs) apply unchanged,
but only the scalar basis is evaluated: a vector P2 basis at 1e5 tets would hold ~1 GB of
redundant copies of the same gradients.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mesh.mesh import Mesh, edge_keys, facet_keys, match

# Quadrature order per element order: exact for the stiffness of straight-sided tets
# (P1: constant integrand, one point; P2: quadratic integrand, four points).
INTORDER = {1: 0, 2: 2}


@dataclass(frozen=True, eq=False)
class Space:
    """A vector-valued Lagrange space.

    Attributes
    ----------
    mesh: the mesh it lives on.
    order: 1 or 2.
    skmesh: the scikit-fem mesh (``MeshTet1``, or ``MeshTet2`` for curved quadratic geometry).
    basis: scalar scikit-fem ``CellBasis``; ``basis.dx`` is ``(n_tets, n_qp)``.
    element_dofs: ``(n_tets, 3 * n_local)`` vector dofs of each tet, ordered
        ``(local node a, component i) -> 3 a + i``.
    node_points: ``(n_nodes, 3)`` reference position of every scalar node.
    """

    mesh: Mesh
    order: int
    skmesh: object
    basis: object
    element_dofs: np.ndarray
    node_points: np.ndarray

    @property
    def n_nodes(self) -> int:
        return self.node_points.shape[0]

    @property
    def n_dofs(self) -> int:
        return 3 * self.n_nodes

    @property
    def n_qp(self) -> int:
        return self.basis.X.shape[1]

    def gradients(self) -> np.ndarray:
        """Scalar shape-function gradients ``(n_local, 3, n_tets, n_qp)`` in 1/length."""
        return np.stack([b[0].grad for b in self.basis.basis])

    def facet_indices(self, triples: np.ndarray) -> np.ndarray:
        """scikit-fem facet ids of boundary triangles given as vertex triples ``(k, 3)``."""
        n = self.mesh.n_points
        rows = match(facet_keys(self.skmesh.facets.T, n), facet_keys(triples, n))
        if np.any(rows < 0):
            raise ValueError(f"{np.count_nonzero(rows < 0)} facets are not faces of the mesh")
        return rows


def skfem_mesh(mesh: Mesh, order: int):
    """scikit-fem mesh for ``mesh``: isoparametric ``MeshTet2`` when curved and ``order == 2``."""
    from skfem import MeshTet1, MeshTet2

    linear = MeshTet1(
        np.ascontiguousarray(mesh.points.T, dtype=np.float64),
        np.ascontiguousarray(mesh.tets.T, dtype=np.int64),
    )
    if order == 1 or not mesh.curved:
        return linear
    quadratic = MeshTet2.from_mesh(linear)
    doflocs = quadratic.doflocs.copy()
    # MeshTet2 dofs: vertices, then one mid-node per edge in the order of ``linear.edges``.
    pos = match(edge_keys(linear.edges.T, mesh.n_points), edge_keys(mesh.edges, mesh.n_points))
    ok = pos >= 0
    doflocs[:, mesh.n_points + pos[ok]] = mesh.edge_points[ok].T
    from dataclasses import replace

    return replace(quadratic, doflocs=doflocs)


def build_space(mesh: Mesh, order: int, like: Space | None = None) -> Space:
    """The vector P``order`` space on ``mesh`` with its quadrature (see ``INTORDER``).
    ``like``: a space of the same order on a mesh whose tets ``mesh`` holds at the same
    places, in the same order, each with its corners in the same order (a crack's
    reconnection, :func:`~fem_frac.fem.reconnect.changed_tets`): where its geometry is
    affine, its mapping (each tet's Jacobian and its inverse) serves unchanged, the same
    bits, instead of being computed again."""
    from skfem import CellBasis, ElementTetP1, ElementTetP2, MeshTet1

    if order not in INTORDER:
        raise ValueError(f"element order must be 1 or 2, got {order}")
    m = skfem_mesh(mesh, order)
    element = ElementTetP1() if order == 1 else ElementTetP2()
    mapping = None
    if like is not None and like.order == order and type(m) is MeshTet1 \
            and type(like.skmesh) is MeshTet1:
        mapping = like.basis.mapping
    basis = CellBasis(m, element, mapping=mapping, intorder=INTORDER[order])
    scalar = basis.element_dofs.T  # (n_tets, n_local)
    element_dofs = (3 * scalar[:, :, None] + np.arange(3)).reshape(scalar.shape[0], -1)
    return Space(
        mesh=mesh,
        order=order,
        skmesh=m,
        basis=basis,
        element_dofs=element_dofs,
        node_points=np.ascontiguousarray(basis.doflocs.T),
    )
