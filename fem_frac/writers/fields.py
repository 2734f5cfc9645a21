"""Fields people colour by, computed from quadrature-point state for output.

Quadrature-point fields are written as cell data (the volume-weighted mean over each tet's
points) and, for the plastic state, also as point data (:func:`nodal_average`): the value at
a node is the volume-weighted mean of the elements around it, which for P1 is the lumped-mass
L2 projection of the cell field onto the nodes."""

from __future__ import annotations

import numpy as np

from ..fem.space import Space
from ..fem.tensors import largest_values, tensor_from_mandel, von_mises


def cell_average(space: Space, qp: np.ndarray, cells: np.ndarray | None = None) -> np.ndarray:
    """Volume-weighted mean over each tet's quadrature points: ``(m, n_tets, n_qp)`` -> ``(m,
    n_tets)``; of the tets ``cells`` only when given (``(m, len(cells))``)."""
    dx = space.basis.dx
    if cells is not None:
        qp, dx = qp[:, cells], dx[cells]
    return np.einsum("meq,eq->me", qp, dx) / dx.sum(axis=1)


def nodal_average(space: Space, qp: np.ndarray) -> np.ndarray:
    """Point values ``(m, n_nodes)`` of a quadrature-point field ``(m, n_tets, n_qp)``: at
    node ``a`` the integral of the field over the elements ``e`` around ``a`` divided by
    their volume, ``sum_e int_e f / sum_e V_e`` (each element's mean weighted by its volume;
    P2: the ten nodes of an element, mid-edge nodes too).

    A constant field is reproduced exactly. A linear field ``f`` comes out as
    ``f(c_a)``, ``c_a`` the volume-weighted mean of the centroids of the elements around
    ``a`` (the quadrature of P1 and P2 integrates it exactly): exact where ``c_a`` is the
    node (a patch symmetric about it), off by ``grad f . (c_a - x_a)`` elsewhere, a bias of
    order the element size at the boundary, where the patch lies on one side of the node.
    Extrema of the elements are flattened (the mean of a peak element and its neighbours).
    For P1 this is the L2 projection onto the nodes with the lumped (row-sum) mass matrix:
    ``int phi_a f / int phi_a`` with ``int_e phi_a = V_e / 4``."""
    dx = space.basis.dx
    nodes = space.basis.element_dofs  # (n_local, n_tets)
    index = nodes.ravel()

    def spread(x: np.ndarray) -> np.ndarray:  # an element's value to each of its nodes
        return np.broadcast_to(x, nodes.shape).ravel()

    volume = np.bincount(index, weights=spread(dx.sum(axis=1)), minlength=space.n_nodes)
    integrals = np.einsum("meq,eq->me", qp, dx)
    total = np.stack([np.bincount(index, weights=spread(x), minlength=space.n_nodes)
                      for x in integrals])
    return np.divide(total, volume, out=np.zeros_like(total), where=volume > 0)


def stress_fields(space: Space, stress: np.ndarray,
                  cells: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Cell data from the Mandel stress ``(6, n_tets, n_qp)``: the tensor (6 components,
    VTK order XX YY ZZ XY YZ XZ), ``von_mises`` and ``max_principal_stress``; of the tets
    ``cells`` only when given."""
    mean = cell_average(space, stress, cells)
    return {
        "stress": np.ascontiguousarray(tensor_from_mandel(mean).T),
        "von_mises": von_mises(mean),
        "max_principal_stress": largest_values(mean),
    }


def plastic_fields(space: Space, state,
                   cells: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Cell data of a plastic state: ``plastic_strain`` (6 tensor components, VTK order),
    ``equivalent_plastic_strain`` and, with kinematic hardening, ``backstress``; of the tets
    ``cells`` only when given."""
    mean = cell_average(space, state.plastic_strain, cells)
    alpha = cell_average(space, state.equivalent_plastic_strain[None], cells)[0]
    fields = {
        "plastic_strain": np.ascontiguousarray(tensor_from_mandel(mean).T),
        "equivalent_plastic_strain": alpha,
    }
    if state.backstress is not None:
        back = cell_average(space, state.backstress, cells)
        fields["backstress"] = np.ascontiguousarray(tensor_from_mandel(back).T)
    return fields


def plastic_point_fields(space: Space, state) -> dict[str, np.ndarray]:
    """Point data of a plastic state (:func:`nodal_average`, beside the cell data of
    :func:`plastic_fields`): ``equivalent_plastic_strain_nodal`` and ``plastic_strain_nodal``
    (6 tensor components, VTK order)."""
    alpha = nodal_average(space, state.equivalent_plastic_strain[None])[0]
    strain = nodal_average(space, state.plastic_strain)
    return {"equivalent_plastic_strain_nodal": alpha,
            "plastic_strain_nodal": np.ascontiguousarray(tensor_from_mandel(strain).T)}


def vtk_cells(space: Space) -> tuple[str, np.ndarray]:
    """Cells for output: linear tets, or quadratic tets whose nodes are the P2 nodes.

    scikit-fem's P2 element dofs are the 4 vertices then the edges (01, 12, 02, 03, 13, 23),
    which is VTK's quadratic-tet node order (its edge 2 runs 2->0: same nodes).
    """
    nodes = space.basis.element_dofs.T
    return ("tetra", nodes) if space.order == 1 else ("tetra10", nodes)
