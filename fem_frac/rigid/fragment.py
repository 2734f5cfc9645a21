"""A piece of the mesh handed over to rigid-body motion (DESIGN §2, "hand-off").

The finite-element piece (nodal positions ``x``, velocities ``v``, mass matrix ``M``) is
replaced by a rigid body with the same linear momentum ``P = sum (M v)_a`` and the same
angular momentum about its centre ``L = sum (x_a - X) x (M v)_a``: both conserved exactly by
construction. The inertia is that of the same mass ``M``, so that a rigid velocity field
``V + w x r`` gives ``L = J w`` and keeps its kinetic energy ``1/2 v^T M v``:

- consistent mass: the piece's tets exactly (:mod:`fem_frac.rigid.mass`, closed form), at
  the positions they have at hand-off, each tet keeping its reference mass (the consistent
  mass integrates ``rho r r^T`` exactly);
- lumped (diagonal) mass: the nodal point masses ``m_a`` (P2: HRZ, vertices and mid-edge
  nodes), ``J = sum m_a (|r_a|^2 I - r_a r_a^T)``, ``r_a = x_a - X``. The tets' exact
  inertia is smaller (the lumped masses sit at the nodes), and with ``L`` from the lumped
  mass it made the body spin faster than its parent and gain kinetic energy.

The centre is the finite-element piece's (``sum (M x) / m``, the tets' own centroid for P1,
and for P2 the centroid with its displaced edge nodes). The rigid motion is then the
``M``-orthogonal projection of the velocity on the rigid fields, and the kinetic energy of
the vibration about it (``1/2 (v - v_rigid)^T M (v - v_rigid) >= 0``) and the strain energy
leave with the finite elements: logged as ``vibration_energy``.

The piece's shape is frozen at hand-off: a node's body-frame coordinates ``b`` stay fixed,
its world position is ``X(t) + R(t) b``, and the output shows it through the point field
``displacement = X + R b - reference position`` (Warp By Vector moves it).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..mesh.mesh import tet_volumes
from .body import RigidBody, kinetic_energy, quaternion_from_matrix, rotation_matrix
from .mass import mass_properties, point_mass_properties


@dataclass(frozen=True, eq=False)
class RigidFragment:
    """A rigid body with the nodes and cells it is drawn with.

    ``nodes (k, 3)``: reference positions of its scalar nodes (vertices, then P2 mid-edge
    nodes); ``cells (e, 4 | 10)``: local node ids in VTK order; ``body_coords (k, 3)``:
    the nodes in the body frame; ``cell_data``: the element fields frozen at hand-off;
    ``fragment_id``: its id in the output; ``born``: the time of hand-off;
    ``vibration_energy``: the energy that left with the finite elements; ``kinetic`` and
    ``strain``: the piece's kinetic and strain energy in the finite elements at hand-off;
    ``resting``: steps it has rested on the ground (see fem_frac.rigid.stage); ``loads``:
    the surface loads that left the finite elements with it
    (:class:`~fem_frac.rigid.loads.RigidLoad`); ``contact_impulse``: the sizes of the net
    contact impulses it received in the last step from other bodies and from planes and
    fixed obstacles (:func:`~fem_frac.rigid.pairs.step_all`)."""

    body: RigidBody
    nodes: np.ndarray
    cells: np.ndarray
    body_coords: np.ndarray
    fragment_id: int
    born: float
    vibration_energy: float = 0.0
    cell_data: dict = field(default_factory=dict)
    kinetic: float = 0.0
    strain: float = 0.0
    resting: int = 0
    loads: tuple = ()
    contact_impulse: tuple[float, float] = (0.0, 0.0)

    def world(self) -> np.ndarray:
        """World positions ``(k, 3)`` of the nodes."""
        return self.body.position + self.body_coords @ rotation_matrix(self.body.orientation).T

    def displacement(self) -> np.ndarray:
        return self.world() - self.nodes


def contact_points(body_coords: np.ndarray) -> np.ndarray:
    """The vertices of the convex hull of ``body_coords`` (all of them if degenerate): the
    only points of a rigid body that can touch a plane first."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        return body_coords[ConvexHull(body_coords).vertices]
    except (QhullError, ValueError):
        return body_coords


def rigid_piece(points: np.ndarray, tets: np.ndarray, nodes: np.ndarray, cells: np.ndarray,
                x: np.ndarray, mv: np.ndarray, v: np.ndarray, density,
                strain_energy: float = 0.0, fragment_id: int = 0, born: float = 0.0,
                cell_data: dict | None = None, mx: np.ndarray | None = None,
                nodal_mass: np.ndarray | None = None) -> RigidFragment:
    """The rigid fragment of a piece.

    ``points (n, 3)``, ``tets (e, 4)``: the piece's reference vertices and tets (local ids);
    ``nodes (k, 3)``: its reference scalar nodes (vertices first), ``cells (e, k_e)``;
    ``x (k, 3)`` current node positions, ``v (k, 3)`` velocities and ``mv (k, 3)`` the
    momentum ``M v`` of each node (the piece's rows of the mass matrix times ``v``);
    ``density``: scalar or ``(e,)``, the reference density; ``mx (k, 3)``: the first
    moment ``M x`` of each node, whose sum over the mass is the centre of the
    finite-element piece (P2: with its curved, displaced edges); without it the centre of
    the straight tets through the displaced vertices (the same for P1). ``nodal_mass (k,)``:
    the nodes' masses when the mass matrix is lumped (diagonal); mass, centre and inertia are
    then those of these point masses at ``x`` (``density`` and ``mx`` are not used), else
    those of the tets.
    """
    if nodal_mass is not None:
        mp = point_mass_properties(x, nodal_mass)
        center = mp.center
    else:
        n = points.shape[0]
        current = x[:n]  # vertices come first among the nodes
        rho = np.broadcast_to(np.asarray(density, dtype=float), (tets.shape[0],))
        # each tet keeps its reference mass: density scaled by the volume change
        ratio = tet_volumes(points, tets) / tet_volumes(current, tets)
        mp = mass_properties(current, tets, rho * ratio)
        center = mp.center if mx is None else mx.sum(axis=0) / mp.mass
    momentum = mv.sum(axis=0)
    angular = np.cross(x - center, mv).sum(axis=0)
    body_coords = (x - center) @ mp.axes
    body = RigidBody(
        mass=float(mp.mass),
        inertia=np.asarray(mp.moments, dtype=float),
        position=np.asarray(center, dtype=float),
        orientation=quaternion_from_matrix(mp.axes),
        momentum=momentum,
        angular_momentum=angular,
        points=contact_points(body_coords),
    )
    finite_element_kinetic = 0.5 * float(np.sum(mv * v))
    vibration = finite_element_kinetic + strain_energy - kinetic_energy(body)
    return RigidFragment(body, np.asarray(nodes, dtype=float), np.asarray(cells),
                         body_coords, fragment_id, born, vibration, cell_data or {},
                         finite_element_kinetic, strain_energy)
