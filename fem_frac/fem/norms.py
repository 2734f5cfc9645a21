"""Discretization error norms against a known displacement field."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .space import Space


def l2_error(
    space: Space, u: np.ndarray, exact: Callable[[np.ndarray], np.ndarray], extra_order: int = 3
) -> tuple[float, float]:
    """(||u_h - u||, ||u||) in L2 over the mesh, with a quadrature ``extra_order`` above the
    stiffness rule so the error of the rule itself is negligible.

    ``exact`` maps points ``(3, n_tets, n_qp)`` to displacements of the same shape.
    """
    from skfem import CellBasis

    basis = CellBasis(space.skmesh, space.basis.elem, intorder=2 * space.order + extra_order)
    phi = np.stack([np.asarray(b[0]) for b in basis.basis])  # (n_local, n_tets, n_qp)
    ue = u[space.element_dofs].reshape(space.mesh.n_tets, -1, 3)
    uh = np.einsum("aeq,eai->ieq", phi, ue)
    ref = exact(basis.mapping.F(basis.X))
    err = np.sqrt(np.einsum("ieq,eq->", (uh - ref) ** 2, basis.dx))
    norm = np.sqrt(np.einsum("ieq,eq->", ref**2, basis.dx))
    return float(err), float(norm)
