"""Fields people colour by, computed from quadrature-point state for output."""

from __future__ import annotations

import numpy as np

from ..fem.space import Space
from ..fem.tensors import principal_values, tensor_from_mandel, von_mises


def cell_average(space: Space, qp: np.ndarray) -> np.ndarray:
    """Volume-weighted mean over each tet's quadrature points: ``(m, n_tets, n_qp)`` -> ``(m,
    n_tets)``."""
    dx = space.basis.dx
    return np.einsum("meq,eq->me", qp, dx) / dx.sum(axis=1)


def stress_fields(space: Space, stress: np.ndarray) -> dict[str, np.ndarray]:
    """Cell data from the Mandel stress ``(6, n_tets, n_qp)``: the tensor (6 components,
    VTK order XX YY ZZ XY YZ XZ), ``von_mises`` and ``max_principal_stress``."""
    mean = cell_average(space, stress)
    return {
        "stress": np.ascontiguousarray(tensor_from_mandel(mean).T),
        "von_mises": von_mises(mean),
        "max_principal_stress": principal_values(mean)[-1],
    }


def plastic_fields(space: Space, state) -> dict[str, np.ndarray]:
    """Cell data of a plastic state: ``plastic_strain`` (6 tensor components, VTK order),
    ``equivalent_plastic_strain`` and, with kinematic hardening, ``backstress``."""
    mean = cell_average(space, state.plastic_strain)
    alpha = cell_average(space, state.equivalent_plastic_strain[None])[0]
    fields = {
        "plastic_strain": np.ascontiguousarray(tensor_from_mandel(mean).T),
        "equivalent_plastic_strain": alpha,
    }
    if state.backstress is not None:
        back = cell_average(space, state.backstress)
        fields["backstress"] = np.ascontiguousarray(tensor_from_mandel(back).T)
    return fields


def vtk_cells(space: Space) -> tuple[str, np.ndarray]:
    """Cells for output: linear tets, or quadratic tets whose nodes are the P2 nodes.

    scikit-fem's P2 element dofs are the 4 vertices then the edges (01, 12, 02, 03, 13, 23),
    which is VTK's quadratic-tet node order (its edge 2 runs 2->0: same nodes).
    """
    nodes = space.basis.element_dofs.T
    return ("tetra", nodes) if space.order == 1 else ("tetra10", nodes)
