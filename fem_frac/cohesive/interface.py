"""Cohesive crack faces of a discretization: the displacement jump at interface points, and
the forces and stiffness of their tractions.

Every paired crack face (:func:`~fem_frac.mesh.crack.crack_faces`: side ``a`` and side
``b``, normal from a to b) carries interface points on its reference triangle. The jump
``[u] = u(b) - u(a)`` at every point is one sparse operator ``J (3 q, n_dofs)`` applied to
the displacement, so that with the tractions ``t (q, 3)`` of the law and the area weights
``w (q,)``

    f_coh = J^T (w t),        K_coh = J^T diag(w dt/d[u]) J

are the cohesive internal force and its stiffness (the derivatives of the cohesive energy
``sum_p w_p phi_p([u]_p)``). Points: P1 faces use by default the vertex (Newton-Cotes)
rule, weight A/3 at each corner pair, which uncouples the springs of a face and avoids the
traction oscillations of Gauss points on stiff interfaces (Schellekens & de Borst 1993);
on request (``quadrature: gauss``) the three-point degree-2 rule at the points (2/3, 1/6,
1/6), which lie inside the face: where a crack ends at a line that is held shut (the load
line of a bend test, about which the broken halves turn) the vertex rule keeps the
points on that line shut for good, and their share of the faces' area never dissipates
its fracture energy. P2 faces use the six-point degree-4 rule (Dunavant 1985), exact for
the quadratic jump squared. Faces are taken flat (their corners' plane).

A point is named by its face's corner positions (sorted) and its barycentric weights in that
order, so that the history of a face survives later insertions and pieces leaving, which
keep reference positions: :func:`carry_history`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..fem.space import Space
from ..mesh.crack import crack_faces
from ..mesh.mesh import TET_FACES, Mesh, SortedKeys, edge_keys, facet_keys, match
from .law import CohesiveResponse, TractionSeparation

# Dunavant's six-point rule, degree 4: barycentric points and weights (sum 1).
_A, _B = 0.445948490915965, 0.091576213509771
_WA, _WB = 0.223381589678011, 0.109951743655322
GAUSS6 = np.array([[_A, _A, 1 - 2 * _A], [_A, 1 - 2 * _A, _A], [1 - 2 * _A, _A, _A],
                   [_B, _B, 1 - 2 * _B], [_B, 1 - 2 * _B, _B], [1 - 2 * _B, _B, _B]])
GAUSS6_WEIGHTS = np.array([_WA] * 3 + [_WB] * 3)
VERTICES = np.eye(3)
VERTEX_WEIGHTS = np.full(3, 1.0 / 3.0)
# The three-point rule, degree 2 (Strang & Fix): barycentric points and weights (sum 1).
GAUSS3 = np.full((3, 3), 1.0 / 6.0) + 0.5 * np.eye(3)
GAUSS3_WEIGHTS = np.full(3, 1.0 / 3.0)
# P2 triangle: corners, then the mid-nodes of edges (0, 1), (1, 2), (0, 2)
EDGES = np.array([[0, 1], [1, 2], [0, 2]])


@dataclass(frozen=True)
class InterfaceRecipe:
    """What the cohesive faces of any mesh need: the law, the factor of the initial
    stiffness ``k0 = penalty E / h`` (h the face's mean edge length, E its element's) and
    the ``quadrature`` of P1 faces (``vertices`` or ``gauss``; module docstring)."""

    law: TractionSeparation
    penalty: float
    quadrature: str = "vertices"


@dataclass(frozen=True, eq=False)
class CohesiveState:
    """The faces' state at the interface points: ``kappa (q,)`` the largest effective
    opening reached, ``jump (q, 3)`` and ``traction (q, 3)``; ``stored`` and
    ``dissipated``: their energies summed over the faces; ``secant (q, 3, 3)``: the law's
    secant stiffness there (the same at the updated history), when the law gave it."""

    kappa: np.ndarray
    jump: np.ndarray
    traction: np.ndarray
    stored: float = 0.0
    dissipated: float = 0.0
    secant: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class Interface:
    """The cohesive faces of one discretization (module docstring).

    ``jump (3 q, n_dofs)``; ``weights (q,)``; ``normals (q, 3)``; ``stiffness (q,)`` the
    initial stiffness k0; ``face (q,)`` the face of each point; ``sides (k, 2)`` the tets on
    sides a and b of each face; ``keys (q,)`` structured names of the points.
    """

    law: TractionSeparation
    jump: sp.csr_matrix
    weights: np.ndarray
    normals: np.ndarray
    stiffness: np.ndarray
    face: np.ndarray
    sides: np.ndarray
    keys: np.ndarray

    @property
    def n_points(self) -> int:
        return self.weights.shape[0]

    @property
    def n_faces(self) -> int:
        return self.sides.shape[0]

    def initial_state(self) -> CohesiveState:
        zeros = np.zeros((self.n_points, 3))
        return CohesiveState(np.zeros(self.n_points), zeros, zeros.copy())

    def openings(self, u: np.ndarray) -> np.ndarray:
        """The jump ``(q, 3)`` of the displacement ``u (n_dofs,)``."""
        return (self.jump @ u).reshape(-1, 3)

    def respond(self, u: np.ndarray, kappa: np.ndarray) -> tuple[CohesiveResponse,
                                                                 CohesiveState]:
        """The law at the jump of ``u`` from the history ``kappa``: its response and the
        state it leaves."""
        jump = self.openings(u)
        r = self.law.response(jump, self.normals, kappa, self.stiffness)
        state = CohesiveState(r.kappa, jump, r.traction, float(self.weights @ r.stored),
                              float(self.weights @ r.dissipated), r.secant)
        return r, state

    def force(self, traction: np.ndarray) -> np.ndarray:
        """``J^T (w t)``: the nodal forces ``(n_dofs,)`` of the tractions ``(q, 3)``."""
        return self.jump.T @ (self.weights[:, None] * traction).ravel()

    def matrix(self, tangent: np.ndarray) -> sp.csr_matrix:
        """``J^T diag(w D) J`` for a ``(q, 3, 3)`` traction tangent ``D``."""
        q = self.n_points
        rows = np.repeat(3 * np.arange(q)[:, None] + np.arange(3), 3, axis=1)
        cols = np.tile(3 * np.arange(q)[:, None] + np.arange(3), (1, 3))
        block = sp.csr_matrix(((self.weights[:, None, None] * tangent).ravel(),
                               (rows.ravel(), cols.ravel())), shape=(3 * q, 3 * q))
        return (self.jump.T @ block @ self.jump).tocsr()

    def joined(self, kappa: np.ndarray) -> np.ndarray:
        """``(k,)`` bool: faces that still hold their sides together (a point not broken)."""
        holding = kappa < self.law.critical_opening(self.stiffness)
        return np.bincount(self.face, weights=holding, minlength=self.n_faces) > 0

    def links(self, state: CohesiveState | None) -> np.ndarray:
        """Tet pairs ``(j, 2)`` joined by a face that holds (every face without a state)."""
        if state is None:
            return self.sides
        return self.sides[self.joined(state.kappa)]


def build_interface(recipe: InterfaceRecipe, mesh: Mesh, space: Space,
                    youngs_modulus) -> Interface | None:
    """The interface of ``mesh``'s paired crack faces, ``None`` when it has none."""
    faces = crack_faces(mesh)
    if len(faces) == 0:
        return None
    a, b = faces.a, faces.b
    p = mesh.points[a]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    bary, qw = _rule(space.order, recipe.quadrature)
    nq = len(qw)
    shape = _shape_functions(bary, space.order)  # (nq, n_local)
    nodes_a, nodes_b = _face_nodes(space, a), _face_nodes(space, b)
    jump = _jump_operator(shape, nodes_a, nodes_b, space.n_dofs)
    sides = np.stack([_tet_of(mesh, a), _tet_of(mesh, b)], axis=1)
    e = np.broadcast_to(np.asarray(youngs_modulus, dtype=float), (mesh.n_tets,))[sides[:, 0]]
    h = np.linalg.norm(p - np.roll(p, 1, axis=1), axis=2).mean(axis=1)
    law = recipe.law
    k0 = np.maximum(recipe.penalty * e / h, least_stiffness(law))
    face = np.repeat(np.arange(len(a)), nq)
    return Interface(law, jump, np.repeat(area, nq) * np.tile(qw, len(a)),
                     np.repeat(faces.normal, nq, axis=0), np.repeat(k0, nq), face, sides,
                     _point_keys(p, bary))


def _rule(order: int, quadrature: str) -> tuple[np.ndarray, np.ndarray]:
    """Barycentric points ``(nq, 3)`` and weights ``(nq,)`` of a face (module docstring)."""
    if order != 1:
        return GAUSS6, GAUSS6_WEIGHTS
    return (GAUSS3, GAUSS3_WEIGHTS) if quadrature == "gauss" else (VERTICES, VERTEX_WEIGHTS)


def least_stiffness(law: TractionSeparation) -> float:
    """The floor of a face's initial stiffness, ``2 sigma_t^2 / G_c``: it keeps the peak
    opening below a quarter of the critical one whatever the mesh."""
    return 2.0 * law.strength**2 / law.energy


def _shape_functions(bary: np.ndarray, order: int) -> np.ndarray:
    """Triangle shape functions ``(nq, 3)`` (P1) or ``(nq, 6)`` (P2) at barycentric points."""
    if order == 1:
        return bary.copy()
    corners = bary * (2.0 * bary - 1.0)
    mids = 4.0 * bary[:, EDGES[:, 0]] * bary[:, EDGES[:, 1]]
    return np.concatenate([corners, mids], axis=1)


def _face_nodes(space: Space, tri: np.ndarray) -> np.ndarray:
    """Scalar nodes ``(k, 3)`` (P1) or ``(k, 6)`` (P2: corners, then the mid-nodes of edges
    (0, 1), (1, 2), (0, 2)) of triangles ``tri (k, 3)``."""
    if space.order == 1:
        return tri
    n = space.mesh.n_points
    pairs = tri[:, EDGES].reshape(-1, 2)
    # scikit-fem numbers the mid-node of its edge e as n + e
    edge = match(edge_keys(np.asarray(space.skmesh.edges).T, n), edge_keys(pairs, n))
    return np.concatenate([tri, n + edge.reshape(-1, 3)], axis=1)


def _jump_operator(shape: np.ndarray, nodes_a: np.ndarray, nodes_b: np.ndarray,
                   n_dofs: int) -> sp.csr_matrix:
    """``(3 k nq, n_dofs)``: row ``3 (f nq + p) + i`` is component i of the jump at point p
    of face f."""
    k, nl = nodes_a.shape
    nq = shape.shape[0]
    point = np.arange(k * nq).reshape(k, nq)
    rows = 3 * point[:, :, None, None] + np.arange(3)[None, None, None, :]  # (k,nq,1,3)
    rows = np.broadcast_to(rows, (k, nq, nl, 3))
    values = np.broadcast_to(shape[None, :, :, None], (k, nq, nl, 3))
    parts = []
    for nodes, sign in ((nodes_b, 1.0), (nodes_a, -1.0)):
        cols = np.broadcast_to(3 * nodes[:, None, :, None] + np.arange(3), (k, nq, nl, 3))
        parts.append((rows.ravel(), cols.ravel(), sign * values.ravel()))
    r, c, v = (np.concatenate(x) for x in zip(*parts, strict=True))
    keep = v != 0.0
    return sp.csr_matrix((v[keep], (r[keep], c[keep])), shape=(3 * k * nq, n_dofs))


def _tet_of(mesh: Mesh, tri: np.ndarray) -> np.ndarray:
    """The tet ``(k,)`` holding each exterior triangle of ``tri (k, 3)``."""
    faces = mesh.tets[:, TET_FACES].reshape(-1, 3)
    rows = match(facet_keys(faces, mesh.n_points), facet_keys(tri, mesh.n_points))
    if np.any(rows < 0):
        raise ValueError("a crack face is not a face of the mesh")
    return rows // 4


def _point_keys(corners: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """Structured keys ``(k nq,)``: a face's corner positions in lexicographic order, then
    the point's barycentric weights in that order (independent of how a face is wound)."""
    k = corners.shape[0]
    order = np.lexsort((corners[:, :, 2], corners[:, :, 1], corners[:, :, 0]), axis=-1) \
        if corners.size else np.zeros((0, 3), dtype=np.int64)
    sorted_corners = np.take_along_axis(corners, order[:, :, None], axis=1).reshape(k, 9)
    weights = bary[:, order].transpose(1, 0, 2)  # (k, nq, 3)
    nq = bary.shape[0]
    rows = np.concatenate([np.repeat(sorted_corners[:, None, :], nq, axis=1), weights],
                          axis=2).reshape(k * nq, 12)
    return np.ascontiguousarray(rows).view([("", np.float64)] * 12).ravel()


def carry_history(old: Interface | None, state: CohesiveState | None,
                  new: Interface | None) -> CohesiveState | None:
    """``state`` of ``old``'s points on ``new``'s: a point keeps its history, jump and
    traction; a new face starts closed and undamaged."""
    if new is None:
        return None
    fresh = new.initial_state()
    if old is None or state is None:
        return fresh
    rows = SortedKeys(old.keys).rows(new.keys)
    known = rows >= 0
    kappa, jump, traction = fresh.kappa, fresh.jump, fresh.traction
    kappa[known] = state.kappa[rows[known]]
    jump[known] = state.jump[rows[known]]
    traction[known] = state.traction[rows[known]]
    r = new.law.response(jump, new.normals, kappa, new.stiffness)
    return CohesiveState(r.kappa, jump, traction, float(new.weights @ r.stored),
                         float(new.weights @ r.dissipated), r.secant)
