"""Element matrices of small-strain elasticity on a :class:`~fem_frac.fem.space.Space`,
vectorized over tets.

The per-element Mandel B-matrices (:func:`strain_displacement`) and the stiffness assembled
from element matrices (:func:`stiffness`). The solver reaches this module through
:meth:`~fem_frac.fem.operators.StrainOperator.stiffness` (the P2 stiffness, where element
matrices beat the sparse triple product) and through the element frequencies of
:mod:`~fem_frac.fem.mass`; the strain and the internal force of the step loop are the
strain operator's (:mod:`~fem_frac.fem.operators`).

The material law enters only as a Mandel tangent ``D``: ``(6, 6)`` shared, or
``(6, 6, n_tets, n_qp)`` per quadrature point.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .space import Space
from .tensors import SQRT2

# Bytes of B-matrix workspace per chunk of tets; bounds peak memory of the assembly.
_CHUNK_BYTES = 64 * 2**20


def _chunks(space: Space):
    n_local = space.element_dofs.shape[1]
    per_tet = 8 * space.n_qp * 6 * n_local * 3
    step = max(1, _CHUNK_BYTES // per_tet)
    for start in range(0, space.mesh.n_tets, step):
        yield slice(start, min(start + step, space.mesh.n_tets))


def strain_displacement(grads: np.ndarray) -> np.ndarray:
    """Mandel B-matrices ``(n_tets, n_qp, 6, 3 n_local)`` from scalar gradients.

    ``grads`` is ``(n_local, 3, n_tets, n_qp)``; column ``3 a + i`` of B is the Mandel strain
    of the shape function of node ``a`` in direction ``i``.
    """
    g = np.moveaxis(grads, (2, 3), (0, 1))  # (nel, nq, n_local, 3)
    gx, gy, gz = g[..., 0], g[..., 1], g[..., 2]
    b = np.zeros(g.shape[:2] + (6, g.shape[2], 3))
    b[:, :, 0, :, 0] = gx
    b[:, :, 1, :, 1] = gy
    b[:, :, 2, :, 2] = gz
    b[:, :, 3, :, 0] = gy / SQRT2
    b[:, :, 3, :, 1] = gx / SQRT2
    b[:, :, 4, :, 1] = gz / SQRT2
    b[:, :, 4, :, 2] = gy / SQRT2
    b[:, :, 5, :, 0] = gz / SQRT2
    b[:, :, 5, :, 2] = gx / SQRT2
    return b.reshape(g.shape[:2] + (6, 3 * g.shape[2]))


def _tangent_chunk(tangent: np.ndarray, sl: slice) -> np.ndarray:
    if tangent.ndim == 2:
        return tangent
    return np.moveaxis(tangent[:, :, sl], (0, 1), (2, 3))


def element_stiffness(space: Space, tangent: np.ndarray) -> np.ndarray:
    """Element matrices ``(n_tets, 3 n_local, 3 n_local)``: sum over qp of ``B^T D B dx``."""
    grads = space.gradients()
    n = space.element_dofs.shape[1]
    ke = np.empty((space.mesh.n_tets, n, n))
    for sl in _chunks(space):
        b = strain_displacement(grads[:, :, sl])
        db = _tangent_chunk(tangent, sl) @ b
        bw = b * space.basis.dx[sl, :, None, None]
        nel, nq = b.shape[:2]
        ke[sl] = np.matmul(
            bw.reshape(nel, nq * 6, n).transpose(0, 2, 1), db.reshape(nel, nq * 6, n)
        )
    return ke


def assemble_matrix(space: Space, element_matrices: np.ndarray) -> sp.csr_matrix:
    """Sum element matrices ``(n_tets, k, k)`` into a CSR matrix over the space's dofs."""
    dofs = space.element_dofs
    index = np.int32 if space.n_dofs < 2**31 - 1 else np.int64
    k = dofs.shape[1]
    rows = np.broadcast_to(dofs[:, :, None], (dofs.shape[0], k, k)).astype(index).ravel()
    cols = np.broadcast_to(dofs[:, None, :], (dofs.shape[0], k, k)).astype(index).ravel()
    a = sp.coo_matrix(
        (element_matrices.ravel(), (rows, cols)), shape=(space.n_dofs, space.n_dofs)
    )
    return a.tocsr()


def stiffness(space: Space, tangent: np.ndarray) -> sp.csr_matrix:
    """Global stiffness matrix ``K`` (``n_dofs x n_dofs``, CSR)."""
    return assemble_matrix(space, element_stiffness(space, tangent))
