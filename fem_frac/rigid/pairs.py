"""Contact between rigid bodies by impulses: bodies against bodies, fixed obstacles and planes.

One step ``dt`` of all bodies (:func:`step_all`):

1. broad and narrow phase (:mod:`~fem_frac.rigid.collide`; a pair with a body far from
   convex by its own tets, :mod:`~fem_frac.rigid.nonconvex`): the pairs of bodies that touch
   or may touch within the step (the speculative margin: their relative speed, spin times
   radius, over ``dt``);
2. islands: bodies joined by touching pairs (fixed bodies join nothing); a body that touches
   no other body takes the single-body step of :func:`~fem_frac.rigid.contact.step`,
   unchanged;
3. each island takes :func:`step_island`, the same scheme with all its bodies at once: kick,
   contact points (the pairs' patches and every body's plane contacts), impulses, drift,
   projection; cut at the first bouncing point's time of impact as for planes.

**Impulses** (:func:`resolve_rows`): a contact point between bodies ``i`` and ``j`` with
normal ``n`` from ``i`` to ``j`` has rows ``d`` in ``(n, t1, t2)`` acting on ``j`` with
``[d, r_j x d]`` and on ``i`` with ``-[d, r_i x d]``, ``r = p - X`` the arms from the
centres to the same world point ``p``; a plane is a fixed ``i``. The Delassus matrix
``J W J^T`` of the island (``W`` block diagonal: ``1/m``, the world inverse inertia; zero for
a fixed or sleeping body) goes to the Poisson solver of
:func:`~fem_frac.rigid.contact.poisson_impulses` (compression with Coulomb friction by block
Gauss-Seidel over the contact points, e times the compression impulse, the energy guard, an
inelastic last pass), so what holds for a body on planes holds here: the kinetic energy does
not rise (e <= 1, friction, any number of points), resting points take the speculative target
``v_n >= -gap / dt`` and come to rest exactly, without jitter. Equal and opposite impulses at
one point conserve linear momentum and angular momentum about any fixed point to round-off.
The Gauss-Seidel loop runs over contact points in Python; the matrices are dense per island
(an island of ``c`` points costs ``(3c)^2`` memory: fine for the few pieces that touch at
once, not for a heap of thousands).

**Projection** (:func:`separate`): points left inside another body (linear prediction of
the time of impact, rotation within a step, a piece born inside another) are separated by
translations along the normals, the mass-weighted least displacement (the same
Gauss-Seidel, at the position level, before the drift); velocities are kept, so no kinetic
energy is added. A pair touching by its own tets (:mod:`~fem_frac.rigid.nonconvex`), whose
points' normals may nearly oppose at a jagged crack, enters it as one point: the least
relative translation that clears every pair of their tets that overlaps, and none where
one body is wedged in the other (:mod:`~fem_frac.rigid.separation`).

**Sleeping**: a sleeping body stays asleep against bodies that rest too (it is then fixed in
their island); a moving body that reaches it wakes it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .body import RigidBody, inverse_inertia_world, inverse_mass, world_points
from .collide import Touch, candidate_pairs, hull, swept_boxes, touching
from .contact import (
    contact_frame,
    find_contacts,
    frames,
    poisson_impulses,
    project,
    signed_distance,
    step,
    targets,
)
from .motion import free_flight
from .nonconvex import touching_shapes
from .separation import least_translation, overlap_constraints, world_tets
from .vectors import cross, length

# Pairs closer than this fraction of their radii count as touching (a resting contact at
# gap 0, or a round-off apart, stays found).
_SLOP = 1e-9


@dataclass(frozen=True)
class PairLaw:
    """Restitution e in [0, 1] and Coulomb friction mu >= 0 between two bodies."""

    restitution: float = 0.0
    friction: float = 0.0

    def __post_init__(self):
        if not (0.0 <= self.restitution <= 1.0 and self.friction >= 0.0):
            raise ValueError(f"need restitution in [0, 1], friction >= 0: {self}")


@dataclass(frozen=True, eq=False)
class FixedBody:
    """A fixed obstacle: ``body`` of infinite mass (:func:`~fem_frac.rigid.body.fixed_body`,
    its ``points`` the vertices of its convex shape) with the restitution and friction of a
    body touching it."""

    body: RigidBody
    restitution: float = 0.0
    friction: float = 0.0


@dataclass(frozen=True, eq=False)
class Rows:
    """``c`` contact points: bodies ``first``, ``second`` (c,) (-1: a plane), the world
    ``point (c, 3)``, ``frame (c, 3, 3)`` (rows n, t1, t2; n from first to second), ``gap``,
    ``restitution``, ``friction`` (c,), ``pair`` (c,): between two bodies (else a plane),
    ``projected`` (c,): a penetration the position projection closes (:func:`separate`)."""

    first: np.ndarray
    second: np.ndarray
    point: np.ndarray
    frame: np.ndarray
    gap: np.ndarray
    restitution: np.ndarray
    friction: np.ndarray
    pair: np.ndarray
    projected: np.ndarray

    def __len__(self):
        return len(self.gap)


_SETTLE_PASSES = 3  # of the projection after the drift (:func:`_settle`)
_FIELDS = ("first", "second", "point", "frame", "gap", "restitution", "friction", "pair",
           "projected")


def _concatenate(parts: list[tuple]) -> Rows:
    if not parts:
        z = np.zeros(0)
        return Rows(z.astype(int), z.astype(int), np.zeros((0, 3)), np.zeros((0, 3, 3)),
                    z, z, z, z.astype(bool), z.astype(bool))
    return Rows(*(np.concatenate(column) for column in zip(*parts, strict=True)))


def _pair_part(i: int, j: int, touch: Touch, restitution: float, friction: float) -> tuple:
    m = touch.points.shape[0]
    frame = (np.broadcast_to(contact_frame(touch.normal), (m, 3, 3))
             if np.ndim(touch.normal) == 1 else frames(touch.normal))
    return (np.full(m, i), np.full(m, j), touch.points, frame,
            np.broadcast_to(np.asarray(touch.gap, dtype=float), (m,)),
            np.full(m, restitution), np.full(m, friction), np.ones(m, dtype=bool),
            np.full(m, np.ndim(touch.normal) == 1))


def pair_touch(a: RigidBody, b: RigidBody, shapes: tuple, margin: float) -> Touch | None:
    """Where ``a`` and ``b`` touch: by their hulls (coal, :func:`~fem_frac.rigid.collide.
    touching`) when both are convex enough, else by their own tets
    (:func:`~fem_frac.rigid.nonconvex.touching_shapes`); ``shapes``: their
    :class:`~fem_frac.rigid.surface.Solid` or ``None`` (:func:`~fem_frac.rigid.nonconvex.
    own_shape`)."""
    if shapes[0] is None and shapes[1] is None:
        return touching(a, b, margin)
    return touching_shapes(a, shapes[0], b, shapes[1], margin)


def _plane_parts(bodies, movable, planes, horizon: float) -> list[tuple]:
    parts = []
    for k in np.flatnonzero(movable):
        c = find_contacts(bodies[k], planes, horizon)
        m = len(c.gap)
        if m:
            parts.append((np.full(m, -1), np.full(m, k), bodies[k].position + c.arm, c.frame,
                          c.gap, c.restitution, c.friction, np.zeros(m, dtype=bool),
                          np.ones(m, dtype=bool)))
    return parts


def margin(a: RigidBody, b: RigidBody, dt: float) -> float:
    """How near ``a`` and ``b`` must be to touch within ``dt``: relative speed plus spin
    times radius, over ``dt``, plus a slop of ``_SLOP`` of their radii."""
    ra, rb = hull(a.points).radius, hull(b.points).radius
    va = a.momentum * inverse_mass(a)
    vb = b.momentum * inverse_mass(b)
    spin = (ra * length(inverse_inertia_world(a) @ a.angular_momentum)
            + rb * length(inverse_inertia_world(b) @ b.angular_momentum))
    return float(dt * (length(vb - va) + spin) + _SLOP * (ra + rb))


def contact_rows(bodies, movable, pairs, coefficients, planes, dt: float,
                 touches=None, shapes=None) -> Rows:
    """The contact points of ``bodies`` over a step ``dt``: of the ``pairs (k, 2)`` (with
    ``coefficients (k, 2)``: e, mu) as found by the narrow phase (or given as ``touches``),
    and of the ``movable`` bodies with the planes; ``shapes``: each body's own tets where it
    touches by them (:func:`pair_touch`), ``None`` for all hulls."""
    shapes = [None] * len(bodies) if shapes is None else shapes
    parts = []
    for k, (i, j) in enumerate(pairs):
        touch = (touches[k] if touches is not None
                 else pair_touch(bodies[i], bodies[j], (shapes[i], shapes[j]),
                                 margin(bodies[i], bodies[j], dt)))
        if touch is not None:
            parts.append(_pair_part(i, j, touch, *coefficients[k]))
    return _concatenate(parts + _plane_parts(bodies, movable, planes, dt))


def _jacobian(rows: Rows, positions: np.ndarray, n: int) -> np.ndarray:
    """(3c, 6n): row (point, direction) maps the bodies' (v, omega) to the relative velocity
    of the second body's point over the first's along the direction."""
    c = len(rows)
    d = rows.frame.reshape(-1, 3)
    point = np.repeat(rows.point, 3, axis=0)
    jac = np.zeros((3 * c, 6 * n))
    for side, sign in ((rows.second, 1.0), (rows.first, -1.0)):
        body = np.repeat(side, 3)
        live = np.flatnonzero(body >= 0)
        arm = point[live] - positions[body[live]]
        block = sign * np.hstack([d[live], cross(arm, d[live])])
        jac[live[:, None], 6 * body[live][:, None] + np.arange(6)] = block
    return jac


def _inverse_masses(bodies, movable) -> np.ndarray:
    """(n, 6, 6) block-diagonal inverse mass; zero for bodies that do not move."""
    w = np.zeros((len(bodies), 6, 6))
    for k in np.flatnonzero(movable):
        w[k, :3, :3] = np.eye(3) * inverse_mass(bodies[k])
        w[k, 3:, 3:] = inverse_inertia_world(bodies[k])
    return w


def _system(bodies, movable, rows: Rows):
    """``(J, W J^T, b)``: the Jacobian, the impulse-to-velocity map and the velocities."""
    n = len(bodies)
    positions = np.array([b.position for b in bodies])
    jac = _jacobian(rows, positions, n)
    w = _inverse_masses(bodies, movable)
    u = np.concatenate([np.concatenate([b.momentum * inverse_mass(b),
                                        inverse_inertia_world(b) @ b.angular_momentum])
                        for b in bodies])
    wjt = np.einsum("nkl,nlc->nkc", w, jac.T.reshape(n, 6, -1)).reshape(6 * n, -1)
    return jac, wjt, jac @ u


def resolve_rows(bodies, movable, rows: Rows, dt: float, v_rest: float):
    """``(bodies, impulses (c, 3))``: the bodies after the contact impulses of ``rows`` and
    each point's impulse on its second body (world; minus that on the first). Rest and
    bounce as for planes (:func:`~fem_frac.rigid.contact.targets`)."""
    if len(rows) == 0:
        return list(bodies), np.zeros((0, 3))
    jac, wjt, b = _system(bodies, movable, rows)
    a = jac @ wjt
    target, e = targets(rows.gap, -b[0::3], rows.restitution, dt, v_rest)
    lam = poisson_impulses(a, b, target, rows.friction, e, polish=True)
    delta = (jac.T @ lam).reshape(-1, 6)
    out = [replace(body, momentum=body.momentum + delta[k, :3],
                   angular_momentum=body.angular_momentum + delta[k, 3:]) if movable[k]
           else body for k, body in enumerate(bodies)]
    return out, np.einsum("cij,ci->cj", rows.frame, lam.reshape(-1, 3))


def separate(bodies, movable, rows: Rows, shapes=None) -> list:
    """The bodies translated along the normals, the least mass-weighted displacement that
    closes every penetration (gap < 0) of the ``projected`` ``rows`` and of each pair
    touching by their own tets when the bodies' ``shapes`` are given (:func:`_own_rows`),
    and closes no other gap past zero; momenta kept."""
    own = _own_rows(bodies, movable, rows, shapes) if shapes is not None else []
    if not (own or np.any((rows.gap < 0.0) & rows.projected)):
        return list(bodies)
    # the points still apart take part as limits (not pushed into another body or a plane)
    kept = np.flatnonzero(rows.projected)
    sub = _concatenate([tuple(getattr(rows, f)[kept] for f in _FIELDS)] + own)
    n = len(bodies)
    # translations only: the (v) columns of the Jacobian, inverse masses 1/m
    jac = _jacobian(sub, np.array([b.position for b in bodies]), n).reshape(-1, n, 6)[:, :, :3]
    w = np.array([inverse_mass(b) if movable[k] else 0.0 for k, b in enumerate(bodies)])
    wjt = (jac * w[None, :, None]).reshape(len(jac), -1).T
    jac = jac.reshape(len(jac), -1)
    zero = np.zeros(len(sub))
    lam = poisson_impulses(jac @ wjt, np.zeros(len(jac)), -sub.gap, zero, zero, polish=True,
                           scale=float(-sub.gap.min()))
    shift = (wjt @ lam).reshape(n, 3)
    return [replace(b, position=b.position + shift[k]) if movable[k] else b
            for k, b in enumerate(bodies)]


def _own_rows(bodies, movable, rows: Rows, shapes) -> list[tuple]:
    """One row per pair touching by their own tets (:mod:`~fem_frac.rigid.nonconvex`) with
    a point inside the other: the least relative translation ``delta`` of the second body
    over the first that clears every pair of their tets that overlaps (separating axes:
    :func:`~fem_frac.rigid.separation.overlap_constraints`), as a point of normal
    ``delta / |delta|`` and gap ``-|delta|``; none where one is wedged in the other
    (:func:`~fem_frac.rigid.separation.least_translation`). The projection then solves
    these with the planes' and the hulls' points at once."""
    own = (rows.gap < 0.0) & rows.pair & ~rows.projected
    return _own_parts(bodies, movable,
                      np.unique(np.column_stack([rows.first[own], rows.second[own]]), axis=0),
                      shapes)


def _own_parts(bodies, movable, pairs, shapes) -> list[tuple]:
    """The rows of :func:`_own_rows` of the given ``pairs (k, 2)`` of bodies."""
    parts = []
    for i, j in pairs:
        if not (movable[i] or movable[j]):
            continue
        a, b = bodies[i], bodies[j]
        tolerance = _SLOP * (hull(a.points).radius + hull(b.points).radius)
        normal, depth = overlap_constraints(world_tets(a, shapes[i]),
                                            world_tets(b, shapes[j]), tolerance)
        delta = least_translation(normal, -depth)
        size = float(length(delta))
        if size > 0.0:
            parts.append((np.array([i]), np.array([j]), 0.5 * (a.position + b.position)[None],
                          contact_frame(delta / size)[None], np.array([-size]),
                          np.zeros(1), np.zeros(1), np.ones(1, dtype=bool),
                          np.ones(1, dtype=bool)))
    return parts


def _per_body(rows: Rows, impulses: np.ndarray, obstacle: np.ndarray) -> np.ndarray:
    """(n, 2): the size of the net impulse on each body from other bodies (column 0) and from
    planes and fixed bodies (column 1); ``impulses (c, 3)`` of the points on their second
    bodies; ``obstacle (n,)`` marks the fixed bodies."""
    out = np.zeros((obstacle.size, 2, 3))
    for side, other, sign in ((rows.first, rows.second, -1.0), (rows.second, rows.first, 1.0)):
        live = side >= 0
        column = np.where((other[live] >= 0) & ~obstacle[np.maximum(other[live], 0)], 0, 1)
        np.add.at(out, (side[live], column), sign * impulses[live])
    return np.linalg.norm(out, axis=2)


@dataclass(frozen=True, eq=False)
class Island:
    """Bodies that touch, for one step: ``bodies`` (movable, sleeping and fixed ones),
    ``movable (n,)``, ``obstacle (n,)`` (the fixed ones), the touching ``pairs (k, 2)``
    (local indices), their ``coefficients (k, 2)`` (e, mu), ``touches`` (at the start
    of the step) and the bodies' ``shapes`` (:func:`pair_touch`)."""

    bodies: list
    movable: np.ndarray
    obstacle: np.ndarray
    pairs: np.ndarray
    coefficients: np.ndarray
    touches: list
    shapes: list


def _fly(bodies, movable, dt: float, gravity, planes) -> list:
    return [project(free_flight(b, dt, gravity), planes) if movable[k] else b
            for k, b in enumerate(bodies)]


def _settle(bodies, island: Island, planes) -> list:
    """The island's bodies after the drift, the pairs touching by their own tets that
    overlap now (a rotation, or contact points whose normals conflict, let the step carry
    them in) separated by :func:`separate`, the planes' points held."""
    shapes = island.shapes
    pairs = [(i, j) for i, j in island.pairs
             if shapes[i] is not None or shapes[j] is not None]
    # a translation that clears the tets overlapping now may reach others: a few passes
    for _ in range(_SETTLE_PASSES if pairs else 0):
        parts = _own_parts(bodies, island.movable, pairs, shapes)
        if not parts:
            break
        # the planes hold every vertex the projection could move through them
        reach = max(-float(part[4][0]) for part in parts)
        rows = _concatenate(parts + _planes_within(bodies, island.movable, planes, reach))
        bodies = separate(bodies, island.movable, rows)
    return bodies


def _planes_within(bodies, movable, planes, reach: float) -> list[tuple]:
    """Rows of every hull vertex of the ``movable`` bodies within ``reach`` of a plane."""
    parts = []
    for k in np.flatnonzero(movable):
        x = world_points(bodies[k])
        for plane in planes:
            gap = signed_distance(plane, x)
            near = np.flatnonzero(gap <= reach)
            m = len(near)
            if m:
                parts.append((np.full(m, -1), np.full(m, k), x[near],
                              np.broadcast_to(contact_frame(plane.normal), (m, 3, 3)),
                              gap[near], np.zeros(m), np.zeros(m), np.zeros(m, dtype=bool),
                              np.ones(m, dtype=bool)))
    return parts


def step_island(island: Island, dt: float, gravity, planes):
    """``(bodies, impulses (n, 2))``: the island after one step ``dt`` (module docstring),
    and the impulses each body received (:func:`_per_body`)."""
    g = np.asarray(gravity, dtype=float)
    bodies, movable = island.bodies, island.movable
    kicked = [replace(b, momentum=b.momentum + b.mass * dt * g) if movable[k] else b
              for k, b in enumerate(bodies)]
    rows = contact_rows(kicked, movable, island.pairs, island.coefficients, planes, dt,
                        island.touches)
    v_rest = 2.0 * float(np.linalg.norm(g)) * dt
    approach = -_system(kicked, movable, rows)[2][0::3] if len(rows) else np.zeros(0)
    fast = rows.restitution * approach > v_rest
    if not np.any(fast):
        # resting contact: kick, impulses, separation, drift
        hit, impulses = resolve_rows(kicked, movable, rows, dt, v_rest)
        moved = _fly(separate(hit, movable, rows, island.shapes), movable, dt, np.zeros(3),
                     planes)
        return _settle(moved, island, planes), _per_body(rows, impulses, island.obstacle)
    # an impact: all the island flies to the first bouncing point's time of impact, the
    # impulses act there, and it flies on (as contact.step for one body)
    tau = float(np.clip(np.min(np.maximum(rows.gap[fast], 0.0) / approach[fast]), 0.0, dt))
    at_impact = _fly(bodies, movable, tau, g, planes)
    rest = dt - tau
    rows = contact_rows(at_impact, movable, island.pairs, island.coefficients, planes, rest,
                        shapes=island.shapes)
    threshold = v_rest - float(np.linalg.norm(g)) * rest
    hit, impulses = resolve_rows(at_impact, movable, rows, dt, threshold)
    moved = _fly(separate(hit, movable, rows, island.shapes), movable, rest, g, planes)
    return _settle(moved, island, planes), _per_body(rows, impulses, island.obstacle)


def _touches(everything, awake, dt: float, gravity, shapes) -> list[tuple[int, int, Touch]]:
    """``(i, j, touch)`` of every pair with an awake body that touches or may touch within
    ``dt``: broad phase on swept boxes, then the narrow phase (:func:`pair_touch`)."""
    speed = np.array([length(b.momentum) * inverse_mass(b)
                      + hull(b.points).radius
                      * length(inverse_inertia_world(b) @ b.angular_momentum)
                      for b in everything])
    radius = np.array([hull(b.points).radius for b in everything])
    lo, hi = swept_boxes(everything, dt, gravity, dt * speed + _SLOP * radius)
    out = []
    for i, j in candidate_pairs(lo, hi):
        if awake[i] or awake[j]:
            touch = pair_touch(everything[i], everything[j], (shapes[i], shapes[j]),
                               margin(everything[i], everything[j], dt))
            if touch is not None:
                out.append((int(i), int(j), touch))
    return out


def _islands(n: int, touches) -> np.ndarray:
    """(n,) island label of each body (-1: touches nothing) over the touching pairs."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    ij = np.array([(i, j) for i, j, _ in touches if i < n and j < n], dtype=int).reshape(-1, 2)
    graph = coo_matrix((np.ones(len(ij)), (ij[:, 0], ij[:, 1])), shape=(n, n))
    labels = connected_components(graph, directed=False)[1]
    involved = np.zeros(n, dtype=bool)
    for i, j, _ in touches:
        involved[[k for k in (i, j) if k < n]] = True
    return np.where(involved, labels, -1)


def _island(members, touches, everything, movable, n: int, law: PairLaw, fixed,
            shapes) -> Island:
    """The island of the bodies ``members`` (global ids) with the fixed bodies they touch."""
    mine = [(i, j, t) for i, j, t in touches if i in members or j in members]
    ids = sorted(set(members) | {k for i, j, _ in mine for k in (i, j)})
    local = {k: m for m, k in enumerate(ids)}
    coefficients = [(fixed[j - n].restitution, fixed[j - n].friction) if j >= n
                    else (fixed[i - n].restitution, fixed[i - n].friction) if i >= n
                    else (law.restitution, law.friction) for i, j, _ in mine]
    return Island([everything[k] for k in ids], movable[ids], np.array(ids) >= n,
                  np.array([(local[i], local[j]) for i, j, _ in mine]).reshape(-1, 2),
                  np.array(coefficients).reshape(-1, 2), [t for _, _, t in mine],
                  [shapes[k] for k in ids])


def step_all(bodies, asleep, moving, dt: float, gravity, planes, fixed=(),
             law: PairLaw = PairLaw(), shapes=None):
    """One step ``dt`` of every body (module docstring).

    bodies: the rigid bodies; asleep (n,): not stepped unless a moving body reaches them;
    moving (n,): bodies that moved in the last step (those wake the sleepers they touch);
    planes; fixed: :class:`FixedBody` obstacles; law: e and mu between two bodies;
    shapes (n,): a body's own tets where it is far from convex
    (:func:`~fem_frac.rigid.nonconvex.own_shape`), ``None`` where its hull is its shape
    (all, when omitted; fixed bodies always).
    Returns ``(bodies, impulses (n, 2), woken (n,), pairs)``: the size of the net impulse
    each body received in the step from other bodies and from planes or fixed bodies, the
    sleepers woken, and the number of touching pairs.
    """
    g = np.asarray(gravity, dtype=float)
    n = len(bodies)
    asleep, moving = np.asarray(asleep, dtype=bool), np.asarray(moving, dtype=bool)
    everything = list(bodies) + [f.body for f in fixed]
    awake = np.concatenate([~asleep, np.zeros(len(fixed), dtype=bool)])
    shapes = (list(shapes) if shapes is not None else [None] * n) + [None] * len(fixed)
    touches = _touches(everything, awake, dt, g, shapes) if len(everything) > 1 else []
    labels = _islands(n, touches)
    out, impulses = list(bodies), np.zeros((n, 2))
    woken = np.zeros(n, dtype=bool)
    for k in np.flatnonzero((labels < 0) & ~asleep):
        out[k] = step(bodies[k], dt, g, planes)
        # what the planes gave: all but gravity (exactly 0 in free flight)
        kicked = bodies[k].momentum + bodies[k].mass * dt * g
        impulses[k, 1] = np.linalg.norm(out[k].momentum - kicked)
    for label in np.unique(labels[labels >= 0]):
        members = np.flatnonzero(labels == label)
        if np.all(asleep[members]):
            continue
        # sleepers wake when a moving body reaches them; against resting ones they stay put
        wake = bool(np.any(moving[members] & ~asleep[members]))
        woken[members] = asleep[members] & wake
        movable = np.concatenate([~asleep | woken, np.zeros(len(fixed), dtype=bool)])
        island = _island(set(members.tolist()), touches, everything, movable, n, law, fixed,
                         shapes)
        moved, received = step_island(island, dt, g, planes)
        ids = sorted(set(members.tolist()) | {k for i, j, _ in touches
                                              if i in members or j in members
                                              for k in (i, j)})
        for m, k in enumerate(ids):
            if k < n:
                out[k], impulses[k] = moved[m], received[m]
    return out, impulses, woken, len(touches)
