"""Strain operators: the global Mandel B-matrix as one sparse matrix, built once per mesh.

The time-stepping loop of the elastoplastic solver evaluates, many times per step, the
strain ``B u`` at every quadrature point and, after the return map, the internal force
``sum B^T sigma dx``. With ``B`` assembled once as a CSR matrix both are a single sparse
mat-vec, the fastest path in numpy/scipy (see ``benchmarks/operators.py``).

Rows are ordered component-major: row ``(c, e, q) -> c * n_tets * n_qp + e * n_qp + q``, so
``(B @ u).reshape(6, n_tets, n_qp)`` is the Mandel strain in the layout of
:mod:`~fem_frac.fem.tensors` (VTK order XX YY ZZ XY YZ XZ, shear scaled by sqrt 2).
This is the strain and internal force of the solver (``fem_frac.solve.stepping``).

Two formulations:

- ``"standard"``: the displacement-gradient B, ``B u`` the Mandel vector of ``sym grad u``;
  the same B as the element matrices of :func:`~fem_frac.fem.elasticity.strain_displacement`.
- ``"averaged"`` (P1 only): the average nodal volumetric strain tetrahedron (Bonet & Burton
  1998, "A simple average nodal pressure tetrahedral element for incompressible and nearly
  incompressible dynamic explicit applications"; the B-bar/F-bar family of de Souza Neto
  et al.). The volumetric strain ``theta_e = tr eps_e`` of every tet is replaced by
  ``theta_bar_e``, the mean over its four vertices of the nodal volumetric strain
  ``theta_a = sum_{e ∋ a} V_e theta_e / sum_{e ∋ a} V_e``; the deviatoric strain is kept:
  ``eps_bar = dev(eps) + theta_bar / 3 I``. Linear tets under isochoric (plastic or
  near-incompressible elastic) flow otherwise lock: one incompressibility constraint per
  tet against ~1/5 of a free vertex per tet. The averaged element has about one
  constraint per vertex instead. Its stencil is wider (a tet's strain depends on the
  vertices of all tets touching its vertices), which is expected.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .space import Space
from .tensors import SQRT2

FORMULATIONS = ("standard", "averaged")

# (Mandel row, [(displacement component i, gradient direction j), ...], scale)
_TERMS = (
    (0, ((0, 0),), 1.0),
    (1, ((1, 1),), 1.0),
    (2, ((2, 2),), 1.0),
    (3, ((0, 1), (1, 0)), 1.0 / SQRT2),
    (4, ((1, 2), (2, 1)), 1.0 / SQRT2),
    (5, ((0, 2), (2, 0)), 1.0 / SQRT2),
)


@dataclass(frozen=True, eq=False)
class StrainOperator:
    """Maps dofs to Mandel strains at every quadrature point, built once per mesh.

    Attributes
    ----------
    space: the vector space of the displacement.
    matrix: ``(6 * n_tets * n_qp, n_dofs)`` CSR of the formulation's B;
        row ``(c, e, q) -> c * n_tets * n_qp + e * n_qp + q``.
    weights: ``(n_tets, n_qp)`` quadrature weights ``dx`` (``space.basis.dx``).
    formulation: ``"standard"`` or ``"averaged"``.

    ``strain`` and ``internal_force`` do not go through ``matrix`` itself but through the
    standard B (the same object for ``"standard"``) and, for ``"averaged"``, two thin
    averaging matrices: the averaged ``matrix`` holds ~8x the nonzeros of the standard one
    (~100 per normal row) and the factored products are 4-8x faster, equal to round-off.
    ``internal_force`` multiplies by ``B.T``, a CSC view (column scatter into the small
    dof vector). A CSR copy of ``B^T`` (row gather) was measured and dropped: at best even
    (P1, and any renumbered mesh), up to 2x slower in gmsh's node order (5e4 P2 tets: 30 ms
    against 17 ms) and twice the memory; see ``benchmarks/operators.py``.
    """

    space: Space
    matrix: sp.csr_matrix
    weights: np.ndarray
    formulation: str
    _base: sp.csr_matrix = field(repr=False)  # standard B
    # averaged only: qp rows -> vertices (volume-weighted) and vertices -> qp rows (mean of
    # the tet's 4 vertices)
    _gather: sp.csr_matrix | None = field(default=None, repr=False)
    _spread: sp.csr_matrix | None = field(default=None, repr=False)

    @property
    def shape(self) -> tuple[int, int, int]:
        """``(6, n_tets, n_qp)``: the shape of a strain or stress field."""
        return (6,) + self.weights.shape

    def strain(self, u: np.ndarray) -> np.ndarray:
        """Mandel strain ``(6, n_tets, n_qp)`` of the displacement ``u`` ``(n_dofs,)``;
        equals ``(matrix @ u).reshape(6, n_tets, n_qp)``."""
        eps = (self._base @ u).reshape(6, -1)
        if self._gather is not None:
            theta = eps[0] + eps[1] + eps[2]
            eps[:3] += (self._spread @ (self._gather @ theta) - theta) / 3.0
        return eps.reshape(self.shape)

    def internal_force(self, stress: np.ndarray) -> np.ndarray:
        """Nodal internal force ``(n_dofs,)``: ``sum B^T sigma dx`` of a Mandel stress
        ``(6, n_tets, n_qp)``; equals ``matrix.T @ (stress * weights).ravel()``."""
        y = (stress * self.weights).reshape(6, -1)
        if self._gather is not None:
            p = (y[0] + y[1] + y[2]) / 3.0
            y[:3] += self._gather.T @ (self._spread.T @ p) - p
        return self._base.T @ y.ravel()

    def stiffness(self, tangent: np.ndarray) -> sp.csr_matrix:
        """Tangent stiffness ``sum B^T D B dx`` (``n_dofs x n_dofs``, CSR).

        ``tangent`` is a Mandel ``(6, 6)`` shared by all quadrature points or
        ``(6, 6, n_tets, n_qp)``. The faster of two equal (to round-off) assemblies, as
        measured in ``benchmarks/operators.py`` (shared D, best of 3):

        - P1 (either formulation): ``product_stiffness``, the sparse triple product. 1e5
          P1 tets: 0.24 s against 0.43 s for the element matrices of
          :func:`~fem_frac.fem.elasticity.stiffness` on an RCM-renumbered mesh, 0.40 s
          against 0.43 s in gmsh's node order. The averaged B has no element blocks and
          can only go this way.
        - P2: the element matrices. 5e4 P2 tets: 1.4 s against 2.8 s for the product in
          gmsh's node order, 1.3 s against 1.7 s renumbered.
        """
        tangent = self._checked(tangent)
        if self.space.order == 1:
            return self.product_stiffness(tangent)
        from .elasticity import stiffness

        return stiffness(self.space, tangent)

    def product_stiffness(self, tangent: np.ndarray) -> sp.csr_matrix:
        """``matrix.T @ blockdiag(D dx) @ matrix`` (CSR), either formulation.

        Symmetric to round-off. The averaged one has a wider stencil: ~10x the nonzeros of
        the standard stiffness at 1e5 P1 tets (a tet's strain reaches every vertex of the
        tets around its own vertices).
        """
        w = _weighted_tangent(self._checked(tangent), self.weights)
        return (self.matrix.T @ (w @ self.matrix)).tocsr()

    def _checked(self, tangent: np.ndarray) -> np.ndarray:
        tangent = np.asarray(tangent, dtype=float)
        if tangent.shape not in ((6, 6), (6, 6) + self.weights.shape):
            raise ValueError(
                f"tangent must be (6, 6) or (6, 6, {self.weights.shape[0]}, "
                f"{self.weights.shape[1]}), got {tangent.shape}"
            )
        return tangent


def strain_operator(space: Space, formulation: str = "standard") -> StrainOperator:
    """The :class:`StrainOperator` of ``space`` in the given formulation."""
    if formulation not in FORMULATIONS:
        raise ValueError(f"formulation must be one of {FORMULATIONS}, got {formulation!r}")
    if formulation == "averaged" and space.order != 1:
        raise ValueError(
            f"the averaged (nodal volumetric strain) formulation is for P1 only, "
            f"got order {space.order}"
        )
    weights = np.ascontiguousarray(space.basis.dx, dtype=float)
    base = standard_matrix(space)
    if formulation == "standard":
        return StrainOperator(space, base, weights, formulation, _base=base)
    gather, spread = _averaging(space, weights)
    return StrainOperator(
        space,
        _averaged_matrix(base, gather, spread),
        weights,
        formulation,
        _base=base,
        _gather=gather,
        _spread=spread,
    )


def standard_matrix(space: Space) -> sp.csr_matrix:
    """The standard B (``B u``: the Mandel vector of ``sym grad u``) as one CSR matrix.

    Each row holds only its nonzeros: ``n_local`` for the normal components, ``2 n_local``
    for the shear ones, with column indices sorted within the row.
    """
    grads = space.gradients()  # (n_local, 3, n_tets, n_qp)
    n_local, _, n_tets, n_qp = grads.shape
    n_rows = n_tets * n_qp
    nodes = 3 * space.basis.element_dofs.T.astype(np.int64)  # (n_tets, n_local)
    index = np.int32 if max(space.n_dofs, 9 * n_local * n_rows) < 2**31 - 1 else np.int64
    g = np.moveaxis(grads, (2, 3), (0, 1))  # (n_tets, n_qp, n_local, 3)
    indices, data, counts = [], [], []
    for _, pairs, scale in _TERMS:  # six Mandel rows, not a loop over the mesh
        cols = np.stack([np.broadcast_to(nodes[:, None, :] + i, g.shape[:3]) for i, _ in pairs])
        vals = np.stack([g[..., j] for _, j in pairs])  # (n_pairs, n_tets, n_qp, n_local)
        cols = np.moveaxis(cols, 0, -1).reshape(n_rows, -1)
        vals = scale * np.moveaxis(vals, 0, -1).reshape(n_rows, -1)
        order = np.argsort(cols, axis=1)
        indices.append(np.take_along_axis(cols, order, axis=1).astype(index).ravel())
        data.append(np.take_along_axis(vals, order, axis=1).ravel())
        counts.append(np.full(n_rows, cols.shape[1], dtype=index))
    indptr = np.zeros(6 * n_rows + 1, dtype=index)
    np.cumsum(np.concatenate(counts), out=indptr[1:])
    matrix = sp.csr_matrix(
        (np.concatenate(data), np.concatenate(indices), indptr),
        shape=(6 * n_rows, space.n_dofs),
    )
    matrix.has_sorted_indices = True
    return matrix


def _averaging(space: Space, weights: np.ndarray) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """``(gather, spread)`` of the averaged formulation, for P1.

    ``gather = A Q`` (``n_vertices x n_rows``): ``Q`` the volume mean over a tet's qps,
    ``A`` the volume-weighted average onto the vertices, ``theta_a = sum_{e ∋ a} V_e
    theta_e / sum_{e ∋ a} V_e``. ``spread = R E`` (``n_rows x n_vertices``): ``E`` the mean
    over a tet's 4 vertices, ``R`` the copy to the tet's qps. ``theta_bar = spread @ gather
    @ theta``.
    """
    n_tets, n_qp = weights.shape
    n_rows = n_tets * n_qp
    tets = space.basis.element_dofs.T.astype(np.int64)  # (n_tets, 4): P1 nodes are vertices
    volumes = weights.sum(axis=1)
    vertex_volume = np.bincount(
        tets.ravel(), weights=np.repeat(volumes, 4), minlength=space.n_nodes
    )
    # row (e, q) of a qp touches the 4 vertices of e
    rows = np.repeat(np.arange(n_rows), 4)
    vertices = np.repeat(tets, n_qp, axis=0).ravel()
    share = (weights[:, :, None] / vertex_volume[tets][:, None, :]).ravel()  # dx_eq / V_a
    gather = sp.csr_matrix((share, (vertices, rows)), shape=(space.n_nodes, n_rows))
    spread = sp.csr_matrix(
        (np.full(rows.size, 0.25), (rows, vertices)), shape=(n_rows, space.n_nodes)
    )
    return gather, spread


def _averaged_matrix(
    base: sp.csr_matrix, gather: sp.csr_matrix, spread: sp.csr_matrix
) -> sp.csr_matrix:
    """``base + (1/3) I ⊗ (theta_bar - theta)``: standard B with averaged volumetric part,
    ``theta = tr(B)`` (rows: qps), ``theta_bar = spread @ gather @ theta``."""
    n_rows = base.shape[0] // 6
    theta = base[:n_rows] + base[n_rows : 2 * n_rows] + base[2 * n_rows : 3 * n_rows]
    delta = (spread @ (gather @ theta) - theta) / 3.0
    empty = sp.csr_matrix(delta.shape)
    correction = sp.vstack([delta, delta, delta, empty, empty, empty], format="csr")
    out = (base + correction).tocsr()
    out.sort_indices()
    return out


def _weighted_tangent(tangent: np.ndarray, weights: np.ndarray) -> sp.csr_matrix:
    """``blockdiag(D dx)`` over the operator's rows: ``(6 N, 6 N)`` with ``N = n_tets n_qp``,
    entry ``(c N + k, d N + k) = D_cd(k) dx_k``; structural zeros of ``D`` dropped."""
    n = weights.size
    w = weights.ravel()
    if tangent.ndim == 2:
        data = tangent[:, None, :] * w[None, :, None]  # (6, n, 6)
    else:
        data = np.moveaxis(tangent.reshape(6, 6, n), 1, 2) * w[None, :, None]
    index = np.int32 if 36 * n < 2**31 - 1 else np.int64
    k = np.arange(n, dtype=index)
    indices = np.broadcast_to(k[None, :, None] + (n * np.arange(6, dtype=index)), (6, n, 6))
    indptr = np.arange(0, 36 * n + 1, 6, dtype=index)
    out = sp.csr_matrix((data.ravel(), indices.ravel(), indptr), shape=(6 * n, 6 * n))
    out.eliminate_zeros()
    return out
