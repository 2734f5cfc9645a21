"""Contact between rigid bodies and the finite elements, by impulses through the lumped mass.

After a step has moved both the finite elements and the rigid bodies, :func:`detect` finds
the contacts between the exterior of the deformed finite-element body
(:func:`~fem_frac.rigid.surface.exterior`: its faces held by one tet, crack faces included)
and every rigid body (fragments, moving and fixed obstacles), both ways:

- **nodes in hulls**: exterior nodes (vertices, P2 mid-edge nodes) at their current
  positions ``X + u`` against the half-spaces of a body's convex hull (world coordinates);
  the gap is the largest signed distance to the hull's face planes (the depth of the least
  penetrated face inside, a lower bound of the distance outside), the normal that face's;
  for a fragment given its own shape (:func:`fragment_solid`), the nodes taken into its body
  frame and located in its tets instead: the gap minus the distance to its nearest exterior
  face inside (normal: that face's), the distance outside (normal: from the closest point);
- **hull vertices in elements**: the vertices of a body's hull (of a fragment given its
  shape: its exterior's vertices) located in the deformed tets
  (cKDTree on the centroids, barycentric coordinates); the gap is the distance to the
  nearest exterior face (negative inside), the normal that face's (outside: the direction
  to its closest point), and the contact acts on the face's three vertices with the
  barycentric weights of that closest point.

A pair counts when it touches, or when the motion the next step predicts closes its gap
(the speculative margin): ``gap + dt v_n + dt^2 / 2 a_n <= 0``, with the relative normal
velocity ``v_n`` and acceleration ``a_n`` (the finite elements' own, gravity for a rigid
body; a broad phase by the bodies' bounding spheres and the finite elements' bounding box
keeps far pairs out).

:func:`exchange` computes the impulses: each contact is a point of the finite elements
(a node, or a face's nodes by weight, each a point mass of the **lumped** mass the
integrator uses: an impulse ``p`` changes a node's velocity by ``p / m_a`` exactly, and
not at all on constrained dofs) against a rigid body (mass, world inertia, arm to the
contact point). The Delassus matrix ``J W J^T`` goes to the Poisson solver of
:func:`~fem_frac.rigid.contact.poisson_impulses` with Coulomb friction and e = 0: the
velocities it constrains are those that move the positions over the next step (central
difference's ``v + dt a / 2``, the rigid bodies' ``V + dt g / 2``), and the target
``v_n >= -max(gap, 0) / dt`` keeps a gap from closing past zero and a contact from going
deeper, without pushing apart (the nodes are never moved: that would change the strain
energy). Inelastic at the nodes: the rebound of an impact comes from the
elements' strain energy, not from a node thrown back. The impulses on the two sides are
equal and opposite: momentum is exchanged exactly; the kinetic energy of the constrained
velocities does not rise (``lambda . b + lambda . A lambda / 2 <= 0``), while the step-end
kinetic energy may change by up to ``dt / 2`` times the impulses' work on the relative
acceleration (what a contact force applied over the next step does).

:func:`separate` then moves the rigid bodies, not the nodes, out of what they still overlap
(an overlap the prediction missed: a turning body, an implicit step whose acceleration
differs from the predicted one, a piece born where its crack faces crossed): each movable
body by its least translation that closes every penetrating contact
(:mod:`~fem_frac.rigid.separation`; a wedged body stays), velocities kept, so no kinetic
energy is added and the finite elements' strain energy is untouched.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .body import (
    RigidBody,
    inverse_inertia_world,
    inverse_mass,
)
from .collide import hull
from .contact import frames, poisson_impulses
from .separation import least_translation
from .surface import (
    Exterior,
    Solid,
    face_normals,
    hull_gaps,
    inside_tets,
    nearest_faces,
    solid,
    solid_gaps,
    surface_points,
    within_box,
)
from .vectors import cross, length, lengths

# Gaps below this fraction of a body's radius count as touching.
_SLOP = 1e-9
# The factor on a node's bound of what a step closes of its gap (:func:`_near_box`): the
# norms and gaps it stands for are computed to round-off, far inside this.
_BOX_ROOM = 1.01


@dataclass(frozen=True, eq=False)
class Elements:
    """The finite elements at the end of a step: per scalar node ``x``, ``v``, ``a``
    ``(n, 3)`` (positions ``X + u``, velocities, accelerations) and ``inverse_mass (n, 3)``
    (the lumped mass' inverse, zero on constrained dofs); the mesh's ``tets (e, 4)``
    (vertex ids; vertices are the first nodes) and its ``exterior``."""

    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    inverse_mass: np.ndarray
    tets: np.ndarray
    exterior: Exterior

    @property
    def vertices(self) -> np.ndarray:
        return self.x[: int(self.tets.max()) + 1]


@dataclass(frozen=True, eq=False)
class Contacts:
    """``c`` contacts: rigid ``body (c,)`` (its index), finite-element ``nodes (c, 3)`` and
    their ``weights (c, 3)`` (a node: ``[1, 0, 0]``), the world ``point (c, 3)`` where the
    body is touched, the unit ``normal (c, 3)`` from the body towards the finite elements,
    ``gap (c,)`` (negative: overlapping), ``friction (c,)``."""

    body: np.ndarray
    nodes: np.ndarray
    weights: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    gap: np.ndarray
    friction: np.ndarray

    def __len__(self) -> int:
        return len(self.gap)

    def subset(self, keep) -> Contacts:
        return Contacts(*(getattr(self, f)[keep] for f in
                          ("body", "nodes", "weights", "point", "normal", "gap", "friction")))


def _concatenate(parts: list[tuple]) -> Contacts:
    if not parts:
        z = np.zeros(0)
        return Contacts(z.astype(np.int64), np.zeros((0, 3), dtype=np.int64),
                        np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), z, z)
    return Contacts(*(np.concatenate(column) for column in zip(*parts, strict=True)))


def _rigid_motion(body: RigidBody, x: np.ndarray) -> np.ndarray:
    """(k, 3) velocities of the body's material points at world ``x``."""
    omega = inverse_inertia_world(body) @ body.angular_momentum
    return body.momentum * inverse_mass(body) + cross(omega, x - body.position)


def _closing(gap, normal, dv, da, dt: float) -> np.ndarray:
    """The gaps the next step predicts, ``gap + dt v_n + dt^2 / 2 a_n``, of relative
    velocities ``dv`` and accelerations ``da (k, 3)`` (finite elements minus body)."""
    return (gap + dt * np.einsum("ij,ij->i", dv, normal)
            + 0.5 * dt * dt * np.einsum("ij,ij->i", da, normal))


def _near_nodes(el: Elements, body: RigidBody, radius: float, accel: np.ndarray,
                dt: float) -> np.ndarray:
    """The exterior nodes within reach of body ``body`` (its bounding sphere of ``radius``
    about the centre, grown by what the next step can move both sides)."""
    nodes = el.exterior.nodes
    omega = inverse_inertia_world(body) @ body.angular_momentum
    reach = (dt * (np.abs(el.v[nodes]).sum(axis=1).max(initial=0.0)
                   + length(body.momentum * inverse_mass(body))
                   + radius * length(omega))
             + 0.5 * dt * dt * (np.abs(el.a[nodes]).sum(axis=1).max(initial=0.0)
                                + length(accel))
             + _SLOP * radius)
    return nodes[lengths(el.x[nodes] - body.position) <= radius + reach]


def _near_box(el: Elements, near: np.ndarray, body: RigidBody, shape: Solid,
              radius: float, accel: np.ndarray, dt: float) -> np.ndarray:
    """The nodes of ``near`` that may touch the body's own tets ``shape`` within the next
    step: each node's distance from the box of the tets in the body frame (a lower bound of
    its gap, which for a :class:`Solid` is the distance to its surface) is at most what the
    step can close of it, ``dt |v - v_body(x)| + dt^2 / 2 |a - accel|`` bounded node by
    node, plus the contact slop, with room for round-off (:data:`_BOX_ROOM`). The others'
    gaps and predicted gaps exceed the slop: they are no contact, and their exact queries,
    most of a long piece's near nodes (its bounding sphere's), are spared."""
    if near.size == 0:
        return near
    x = el.x[near]
    omega = length(inverse_inertia_world(body) @ body.angular_momentum)
    speed = (lengths(el.v[near]) + length(body.momentum)
             * inverse_mass(body) + omega * lengths(x - body.position))
    close = (dt * speed + 0.5 * dt * dt * (lengths(el.a[near])
                                          + length(accel)) + _SLOP * radius)
    return near[within_box(x, body, shape, _BOX_ROOM * close + _SLOP * radius)]


def _nodes_in_body(el: Elements, k: int, body: RigidBody, shape: Solid | None,
                   friction: float, accel: np.ndarray, dt: float) -> tuple | None:
    """The exterior nodes touching body ``k`` (its own tets when it has a ``shape``, else
    its hull) or closing on it in the next step."""
    radius = hull(body.points).radius
    if shape is not None:
        radius = max(radius, shape.radius)
    near = _near_nodes(el, body, radius, accel, dt)
    if shape is not None:
        near = _near_box(el, near, body, shape, radius, accel, dt)
    if near.size == 0:
        return None
    x = el.x[near]
    gap, normal = hull_gaps(x, body) if shape is None else solid_gaps(x, body, shape)
    closing = _closing(gap, normal, el.v[near] - _rigid_motion(body, x),
                       el.a[near] - accel, dt)
    live = np.minimum(gap, closing) <= _SLOP * radius
    m = int(np.count_nonzero(live))
    if m == 0:
        return None
    nodes3 = np.zeros((m, 3), dtype=np.int64)
    nodes3[:, 0] = near[live]
    weights = np.zeros((m, 3))
    weights[:, 0] = 1.0
    return (np.full(m, k), nodes3, weights, x[live], normal[live], gap[live],
            np.full(m, friction))


def _vertices_in_elements(el: Elements, bodies, shapes, friction, accel,
                          dt: float) -> tuple | None:
    """The surface (fragments) or hull vertices of the bodies inside the deformed
    elements, or closing on their exterior in the next step."""
    points = [surface_points(b, s) for b, s in zip(bodies, shapes, strict=True)]
    owner = np.repeat(np.arange(len(bodies)), [len(p) for p in points])
    p = np.concatenate(points) if points else np.zeros((0, 3))
    xv = el.vertices
    faces = el.exterior.faces
    speed = max((length(b.momentum * inverse_mass(b))
                 + hull(b.points).radius
                 * length(inverse_inertia_world(b) @ b.angular_momentum)
                 for b in bodies), default=0.0)
    reach = (dt * (np.abs(el.v).sum(axis=1).max(initial=0.0) + speed)
             + 0.5 * dt * dt * (np.abs(el.a).sum(axis=1).max(initial=0.0)
                                + float(np.abs(accel).sum(axis=1).max(initial=0.0))))
    reach += _SLOP * float(np.ptp(xv, axis=0).max())
    near = np.flatnonzero(np.all((p >= xv.min(axis=0) - reach) & (p <= xv.max(axis=0) + reach),
                                 axis=1))
    if near.size == 0 or len(faces) == 0:
        return None
    p, owner = p[near], owner[near]
    inside = inside_tets(p, xv, el.tets)
    face, weights, distance = nearest_faces(p, xv, faces)
    corners = faces[face]
    closest = np.einsum("ij,ijk->ik", weights, xv[corners])
    outward = face_normals(xv, faces)[face]
    away = closest - p
    apart = (~inside) & (distance > _SLOP * reach)
    normal = np.where(apart[:, None], away / np.where(apart, distance, 1.0)[:, None],
                      -outward)
    gap = np.where(inside, -distance, distance)
    fe_v = np.einsum("ij,ijk->ik", weights, el.v[corners])
    fe_a = np.einsum("ij,ijk->ik", weights, el.a[corners])
    # owner is ascending (the bodies' points in order)
    rigid_v = np.concatenate([_rigid_motion(bodies[k], p[owner == k])
                              for k in range(len(bodies))])
    live = np.minimum(gap, _closing(gap, normal, fe_v - rigid_v, fe_a - accel[owner], dt)) \
        <= _SLOP * reach
    if not np.any(live):
        return None
    return (owner[live], corners[live], weights[live], p[live], normal[live], gap[live],
            np.asarray(friction, dtype=float)[owner[live]])


def detect(el: Elements, bodies, friction, accel, dt: float, shapes=None) -> Contacts:
    """The contacts between the finite elements ``el`` and the rigid ``bodies`` (module
    docstring); ``friction (n,)``: mu of each body against the finite elements,
    ``accel (n, 3)``: each body's acceleration over the next step (gravity; zero when
    fixed); ``shapes (n,)``: a fragment's :class:`~fem_frac.rigid.surface.Solid`
    (:func:`fragment_solid`), ``None`` for a body tested by its hull (all, when omitted)."""
    accel = np.asarray(accel, dtype=float).reshape(-1, 3)
    shapes = [None] * len(bodies) if shapes is None else list(shapes)
    parts = [_nodes_in_body(el, k, b, shapes[k], friction[k], accel[k], dt)
             for k, b in enumerate(bodies)]
    parts.append(_vertices_in_elements(el, bodies, shapes, friction, accel, dt))
    return _concatenate([part for part in parts if part is not None])


def fragment_solid(fragment) -> Solid:
    """The :class:`~fem_frac.rigid.surface.Solid` of a
    :class:`~fem_frac.rigid.fragment.RigidFragment` (its tets in its body frame; built once
    per piece)."""
    return solid(fragment.body_coords, fragment.cells)


@dataclass(frozen=True, eq=False)
class Exchange:
    """The impulses of one exchange: on the finite elements' ``nodes (m,)``, ``impulse
    (m, 3)`` and the velocity change ``dv (m, 3)``; on the rigid ``bodies (k,)`` (indices),
    ``rigid (k, 6)`` (linear impulse, angular impulse about the centre); ``constrained``:
    the change of the kinetic energy of the velocities the contacts constrain (<= 0);
    ``contacts`` the number of contact points."""

    nodes: np.ndarray
    impulse: np.ndarray
    dv: np.ndarray
    bodies: np.ndarray
    rigid: np.ndarray
    constrained: float = 0.0
    contacts: int = 0


def _jacobian(el: Elements, bodies, contacts: Contacts, nodes, used):
    """``(J (3c, 3m + 6k), W J^T, u)``: the rows (n, t1, t2 per contact) of the relative
    velocity of the finite elements over the body, their map from impulses to velocity
    changes, and the velocities they act on (``v + dt a / 2`` is given by the caller)."""
    c, m, k = len(contacts), len(nodes), len(used)
    d = frames(contacts.normal).reshape(-1, 3)
    rows = np.arange(3 * c)
    jac = np.zeros((3 * c, 3 * m + 6 * k))
    for j in range(3):  # the (up to) three nodes of each contact
        col = 3 * np.searchsorted(nodes, np.repeat(contacts.nodes[:, j], 3))
        np.add.at(jac, (rows[:, None], col[:, None] + np.arange(3)),
                  np.repeat(contacts.weights[:, j], 3)[:, None] * d)
    body = np.searchsorted(used, np.repeat(contacts.body, 3))
    col = 3 * m + 6 * body
    arm = np.repeat(contacts.point, 3, axis=0) - np.array(
        [bodies[b].position for b in used])[body]
    jac[rows[:, None], col[:, None] + np.arange(3)] = -d
    jac[rows[:, None], col[:, None] + 3 + np.arange(3)] = -cross(arm, d)
    w = np.zeros((k, 6, 6))
    for i, b in enumerate(used):
        w[i, :3, :3] = np.eye(3) * inverse_mass(bodies[b])
        w[i, 3:, 3:] = inverse_inertia_world(bodies[b])
    wjt = np.empty_like(jac.T)
    wjt[: 3 * m] = el.inverse_mass[nodes].reshape(-1, 1) * jac.T[: 3 * m]
    wjt[3 * m:] = np.einsum("kab,kbc->kac", w,
                            jac.T[3 * m:].reshape(k, 6, -1)).reshape(6 * k, -1)
    return jac, wjt


def exchange(el: Elements, bodies, contacts: Contacts, accel, dt: float) -> Exchange:
    """The impulses of ``contacts`` between the finite elements ``el`` and ``bodies``
    (module docstring); ``accel (n, 3)``: the bodies' accelerations over the next step."""
    nodes = np.unique(contacts.nodes)
    used = np.unique(contacts.body)
    jac, wjt = _jacobian(el, bodies, contacts, nodes, used)
    a = jac @ wjt
    # contacts along which nothing can move (a constrained node on a fixed body) drop out
    live = np.repeat(np.diagonal(a)[0::3] > 0.0, 3)
    m = len(nodes)
    if not np.any(live):
        return Exchange(nodes, np.zeros((m, 3)), np.zeros((m, 3)), used,
                        np.zeros((len(used), 6)))
    accel = np.asarray(accel, dtype=float).reshape(-1, 3)
    jac, wjt, a = jac[live], wjt[:, live], a[np.ix_(live, live)]
    kept = contacts.subset(live[0::3])
    now = jac @ _velocities(el, bodies, nodes, used, accel, 0.0)
    b = jac @ _velocities(el, bodies, nodes, used, accel, dt)
    target = -np.maximum(kept.gap, 0.0) / dt
    zero = np.zeros(len(kept))
    lam = poisson_impulses(a, b, target, kept.friction, zero, polish=True)
    # the guard: the step-end kinetic energy must not rise either (its change is
    # lam.now + lam.A.lam / 2); where it would, the impulses are scaled down to where it
    # does not (the constrained velocities' energy, convex in the scale, still does not)
    alam = a @ lam
    quadratic = float(lam @ alam)
    if float(lam @ now) + 0.5 * quadratic > 0.0 and quadratic > 0.0:
        lam = lam * min(max(-2.0 * float(lam @ now) / quadratic, 0.0), 1.0)
        alam = a @ lam
    impulse = jac.T @ lam
    fe = impulse[: 3 * m].reshape(m, 3)
    return Exchange(nodes, fe, el.inverse_mass[nodes] * fe, used,
                    impulse[3 * m:].reshape(-1, 6),
                    float(lam @ b + 0.5 * lam @ alam), len(kept))


def separate(bodies, movable, contacts: Contacts) -> np.ndarray:
    """``(n, 3)``: the translation of each of the ``bodies`` that closes every penetration
    (gap < 0) among ``contacts`` with the finite elements held in place
    (:func:`~fem_frac.rigid.separation.least_translation`, along minus the normals, which
    point from the body to the finite elements); zero for a body not ``movable`` (fixed)
    or wedged (left as it is)."""
    shift = np.zeros((len(bodies), 3))
    inside = contacts.gap < 0.0
    for k in np.unique(contacts.body[inside]):
        if movable[k]:
            mine = inside & (contacts.body == k)
            shift[k] = least_translation(-contacts.normal[mine], contacts.gap[mine])
    return shift


def _velocities(el: Elements, bodies, nodes, used, accel, dt: float) -> np.ndarray:
    """The velocities of the contacts' unknowns (the nodes' dofs, then each body's
    ``(V, omega)``), advanced by half a step ``dt`` of their accelerations (the velocities
    that move the positions over a step of central difference and of free flight)."""
    parts = [(el.v[nodes] + 0.5 * dt * el.a[nodes]).ravel()]
    for b in used:
        body = bodies[b]
        parts.append(np.concatenate([body.momentum * inverse_mass(body) + 0.5 * dt * accel[b],
                                     inverse_inertia_world(body) @ body.angular_momentum]))
    return np.concatenate(parts)
