"""Load vectors: surface tractions, pressure and body forces, as ``(n_dofs,)`` arrays.

The surface functions here take scikit-fem facet ids (``Space.facet_indices``) and build the
mesh's global facet tables; supports and loads of a case come from the boundary triangles
themselves (:mod:`fem_frac.fem.surface`), which is far cheaper on every new mesh.
"""

from __future__ import annotations

import numpy as np

from .space import Space


def facet_basis(space: Space, facet_ids: np.ndarray):
    """Scalar scikit-fem ``FacetBasis`` on the given facets, exact for quadratic data on P2."""
    from skfem import FacetBasis

    return FacetBasis(
        space.skmesh, space.basis.elem, facets=facet_ids, intorder=2 * space.order
    )


def _scatter(space: Space, fb, nodal: np.ndarray) -> np.ndarray:
    """Sum per-facet nodal loads ``(n_facets, n_local, 3)`` into a global vector."""
    dofs = 3 * fb.element_dofs.T[:, :, None] + np.arange(3)
    return np.bincount(dofs.ravel(), weights=nodal.ravel(), minlength=space.n_dofs)


def surface_load(space: Space, facet_ids: np.ndarray, traction=None, pressure=None):
    """Consistent nodal forces of a constant traction (force/area, ``(3,)``) and/or a
    pressure (force/area acting along the inward normal) on the given facets."""
    fb = facet_basis(space, facet_ids)
    phi = np.stack([np.asarray(b[0]) for b in fb.basis])  # (n_local, n_facets, n_qp)
    t = np.zeros((3,) + fb.dx.shape)
    if traction is not None:
        t += np.asarray(traction, dtype=float)[:, None, None]
    if pressure is not None:
        t -= pressure * fb.normals  # outward unit normals (3, n_facets, n_qp)
    nodal = np.einsum("afq,ifq,fq->fai", phi, t, fb.dx)
    return _scatter(space, fb, nodal)


def body_load(space: Space, force_density) -> np.ndarray:
    """Consistent nodal forces of a body force (force/volume): ``(3,)`` constant, or
    ``(n_tets, 3)`` constant per element."""
    phi = np.stack([np.asarray(b[0]) for b in space.basis.basis])  # (n_local, n_tets, n_qp)
    w = np.einsum("aeq,eq->ea", phi, space.basis.dx)
    f = np.asarray(force_density, dtype=float)
    nodal = w[:, :, None] * (f[:, None, :] if f.ndim == 2 else f)
    return np.bincount(
        space.element_dofs.ravel(), weights=nodal.ravel(), minlength=space.n_dofs
    )


def surface_nodes(space: Space, facet_ids: np.ndarray) -> np.ndarray:
    """Scalar node ids on the given facets (vertices and, for P2, edge mid-nodes)."""
    return np.unique(space.basis.get_dofs(facets=facet_ids).flatten())


def mean_normal_axis(space: Space, facet_ids: np.ndarray, tol: float = 1e-6) -> int | None:
    """The coordinate axis all facets are normal to, or None if they are not axis-aligned."""
    fb = facet_basis(space, facet_ids)
    n = fb.normals.reshape(3, -1)
    axis = int(np.argmax(np.abs(n[:, 0])))
    return axis if np.all(np.abs(np.abs(n[axis]) - 1.0) < tol) else None
