"""Probes: where on a mesh each probe reads its fields, and the CSV the values go to.

A probe reads a mesh through two sparse rows of weights, computed once per mesh
(:func:`point_stencil`, :func:`boundary_stencil`): one over the nodes for point fields
(displacement, velocity, the nodal projections) and one over the elements for cell fields
(stress, plastic strain, ...). A step's value is a sparse product with the field, so a
probe costs a few multiplications per step, whatever the mesh.

- A point: located in the tet that holds it (the straight-sided tet of its four vertices;
  on a face, edge or vertex shared by several, the one it lies deepest in, the first of
  equals). Point fields are interpolated with the element's shape functions at the point
  (P1: its barycentric coordinates; P2: the quadratic ones, so a probe at a node reads
  that node's value); cell fields take that element's value.
- A boundary: the mean over its faces, ``int_S f dA / A``: point fields through the shape
  functions (exact for the finite-element field), cell fields as the value of each face's
  element weighted by the face's area.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from ..fem.loads import facet_basis
from ..fem.space import Space
from .directory import create_plain

# A point belongs to a tet when its barycentric coordinates are all above -INSIDE.
INSIDE = 1e-9


@dataclass(frozen=True, eq=False)
class Stencil:
    """The weights of one probe: ``nodes (n_nodes,)`` and ``cells (n_tets,)`` as sparse
    rows; ``found``: whether the probe reads anything on this mesh (a point outside it, a
    boundary without faces: not)."""

    nodes: sp.csr_matrix
    cells: sp.csr_matrix
    found: bool


def tet_boxes(space: Space) -> tuple[np.ndarray, np.ndarray]:
    """The bounding box ``(lo, hi)``, each ``(n_tets, 3)``, of every tet (scikit-fem's
    vertex order): computed once per mesh for all its point probes."""
    corners = space.mesh.points[space.skmesh.t.T[:, :4]]
    return corners.min(axis=1), corners.max(axis=1)


def locate(space: Space, point, boxes=None) -> tuple[int, np.ndarray, float]:
    """The tet that holds ``point`` and the point's barycentric coordinates ``(4,)`` in it
    (scikit-fem's vertex order), and the least of them: below ``-INSIDE`` when no tet holds
    the point (then the nearest by that measure; ``-inf`` when no tet's box holds it).
    ``boxes``: :func:`tet_boxes` of the space, when already made."""
    x = np.asarray(point, dtype=float)
    lo, hi = boxes if boxes is not None else tet_boxes(space)
    points = space.mesh.points
    extent = np.ptp(points, axis=0).max() if len(points) else 0.0
    pad = INSIDE * max(extent, 1.0)
    near = np.flatnonzero(np.all((lo - pad <= x) & (x <= hi + pad), axis=1))
    if len(near) == 0:
        return -1, np.zeros(4), -np.inf
    bary = barycentric(points[space.skmesh.t.T[near, :4]], x)
    least = bary.min(axis=1)
    best = int(np.argmax(least))
    return int(near[best]), bary[best], float(least[best])


def barycentric(corners: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Barycentric coordinates ``(k, 4)`` of ``x (3,)`` in tets ``(k, 4, 3)``."""
    jac = np.transpose(corners[:, 1:] - corners[:, :1], (0, 2, 1))  # (k, 3, 3) columns
    ref = np.linalg.solve(jac, (x - corners[:, 0])[:, :, None])[:, :, 0]
    return np.concatenate([1.0 - ref.sum(axis=1, keepdims=True), ref], axis=1)


def point_stencil(space: Space, point, boxes=None) -> Stencil:
    """A point probe's weights (module docstring); ``found`` false outside the mesh.
    ``boxes``: :func:`tet_boxes` of the space, when already made."""
    element, bary, least = locate(space, point, boxes)
    if least < -INSIDE:
        return empty_stencil(space)
    elem = space.basis.elem
    ref = bary[1:, None]  # reference coordinates (3, 1)
    phi = np.array([elem.lbasis(ref, i)[0][0] for i in range(elem.doflocs.shape[0])])
    nodes = space.basis.element_dofs[:, element]
    row = sp.csr_matrix((phi, (np.zeros_like(nodes), nodes)), shape=(1, space.n_nodes))
    cells = sp.csr_matrix(([1.0], ([0], [element])), shape=(1, space.mesh.n_tets))
    return Stencil(row, cells, True)


def boundary_stencil(space: Space, facet_ids: np.ndarray) -> Stencil:
    """A boundary probe's weights over the scikit-fem facets ``facet_ids``; ``found``
    false without any."""
    if len(facet_ids) == 0:
        return empty_stencil(space)
    fb = facet_basis(space, facet_ids)
    phi = np.stack([np.asarray(b[0]) for b in fb.basis])  # (n_local, n_facets, n_qp)
    area = fb.dx.sum(axis=1)
    total = area.sum()
    w = np.einsum("afq,fq->af", phi, fb.dx) / total
    nodes = fb.element_dofs  # (n_local, n_facets)
    row = sp.csr_matrix((w.ravel(), (np.zeros(nodes.size, dtype=np.int64), nodes.ravel())),
                        shape=(1, space.n_nodes))
    cells = sp.csr_matrix((area / total, (np.zeros(len(area), dtype=np.int64), fb.tind)),
                          shape=(1, space.mesh.n_tets))
    row.sum_duplicates()
    cells.sum_duplicates()
    return Stencil(row, cells, True)


def empty_stencil(space: Space) -> Stencil:
    return Stencil(sp.csr_matrix((1, space.n_nodes)), sp.csr_matrix((1, space.mesh.n_tets)),
                   False)


def read(stencil: Stencil, values: np.ndarray, on_cells: bool) -> np.ndarray:
    """The probe's value ``(m,)`` of a field ``(n, m)`` or ``(n,)`` on the nodes or the
    cells (``on_cells``); NaN when the probe is not found on the mesh."""
    values = np.asarray(values, dtype=float)
    m = 1 if values.ndim == 1 else values.shape[1]
    if not stencil.found:
        return np.full(m, np.nan)
    rows = stencil.cells if on_cells else stencil.nodes
    return np.atleast_1d(rows @ values.reshape(values.shape[0], m)).ravel()


class ProbeFile:
    """The CSV of the probes: a fixed header, then one row a step, appended and closed at
    each (a killed run keeps every step it finished). Floats are written as the shortest
    text that reads back as the same double (``repr``): the values themselves; NaN as
    ``nan``."""

    def __init__(self, path: Path, columns: list[str]):
        self.path, self.columns = Path(path), list(columns)
        create_plain(self.path)
        self._append(self.columns)

    def write(self, values: list) -> None:
        self._append([_format(v) for v in values])

    def _append(self, cells: list[str]) -> None:
        text = io.StringIO()
        csv.writer(text, lineterminator="\n").writerow(cells)
        with open(self.path, "a", newline="") as f:
            f.write(text.getvalue())


def _format(value) -> str:
    if isinstance(value, (float, np.floating)):
        return repr(float(value))  # the shortest text that reads back as the same double
    return str(value)
