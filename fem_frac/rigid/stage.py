"""The fragments stage: rigid bodies move, and free pieces leave the finite elements as
rigid bodies.

Every step, the rigid bodies are moved over the interval by
:func:`~fem_frac.rigid.pairs.step_all` (gravity exact, torque-free rotation by exact
principal-axis rotations, ground planes, fixed obstacles and each other by impulses; a body
that touches no other body takes :func:`~fem_frac.rigid.contact.step`), between half kicks
by the loads that left with them (:func:`~fem_frac.rigid.loads.kick`). Then every piece of
the deformable body that no support holds is a candidate; the ``fragments`` section decides
which become rigid. Each is handed over (:func:`~fem_frac.rigid.fragment.rigid_piece`: momenta kept
exactly), its elements leave the finite-element mesh
(:func:`~fem_frac.fracture.topology.extract`), and the body is discretized once more for all
pieces of the step. The tractions and pressures on the piece's nodes go with it
(:mod:`fem_frac.rigid.loads`). With ``whole_body`` the body is handed over whole at step 0.

Energy: what the pieces carried (kinetic and strain energy) leaves the finite-element ledger
as ``Ledger.handed_off`` (of which ``Ledger.vibration_removed`` is the motion about the rigid
motion and the strain), so its balance still holds; the rigid bodies' own kinetic and
potential energy are the world's (:meth:`~fem_frac.world.state.World.rigid_energies`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from ..config import schema
from ..fracture.topology import extract
from ..timing import StageTimer
from ..world.stage import Step
from ..world.state import Body, World, body_of
from ..world.transfer import carry, rediscretize
from . import deformable
from . import loads as rigid_loads
from .birth import place
from .body import kinetic_energy
from .contact import Plane
from .fragment import RigidFragment, rigid_piece
from .loads import piece_loads
from .nonconvex import own_shape
from .pairs import PairLaw, step_all
from .surface import exterior

# Steps at rest on the ground after which a rigid body sleeps (see RigidStage.move).
SLEEP_STEPS = 20


@dataclass(frozen=True)
class HandOffEvent:
    """The pieces that became rigid in one step, with the number of elements of each."""

    pieces: tuple[RigidFragment, ...] = ()
    elements: tuple[int, ...] = ()


def planes(config: schema.Fragments) -> tuple[Plane, ...]:
    """The ground planes of a ``fragments`` section."""
    out = []
    for g in config.ground:
        n = np.asarray(g.normal, dtype=float)
        out.append(Plane(np.asarray(g.point, dtype=float), n / np.linalg.norm(n),
                         g.restitution, g.friction))
    return tuple(out)


def move(fragments: tuple[RigidFragment, ...], t0: float, t1: float, gravity: np.ndarray,
         obstacles: tuple[Plane, ...], substeps: int, law: PairLaw | None = None,
         fixed: tuple = ()) -> tuple[RigidFragment, ...]:
    """Every rigid body from ``t0`` to ``t1`` in ``substeps`` contact steps, under gravity and
    its loads (half kicks of :func:`~fem_frac.rigid.loads.kick` about each step of
    :func:`~fem_frac.rigid.pairs.step_all`: the planes ``obstacles``, the ``fixed`` bodies
    (:class:`~fem_frac.rigid.pairs.FixedBody` or any object with ``body``, ``restitution``,
    ``friction``) and each other, with ``law`` between two bodies, default e = mu = 0).

    A body that has rested for ``SLEEP_STEPS`` steps (kinetic energy below what one step of
    free fall from rest gives it, no load acting) sleeps: it is not stepped while its loads'
    curves are zero at the substeps' ends (all the kicks see) and no moving body reaches it
    (then it wakes). Each fragment keeps the impulses it received (``contact_impulse``)."""
    law = law or PairLaw()
    h = (t1 - t0) / substeps
    quiet = 0.5 * float(gravity @ gravity) * h * h
    times = [t0 + (t1 - t0) * i / substeps for i in range(substeps)] + [t1]
    loaded = np.array([any(float(load.factor(t)) != 0.0 for load in f.loads for t in times)
                       for f in fragments], dtype=bool)
    asleep = np.array([f.resting >= SLEEP_STEPS for f in fragments], dtype=bool) & ~loaded
    moving = np.array([f.resting == 0 for f in fragments], dtype=bool)
    bodies = [f.body for f in fragments]
    shapes = [own_shape(f) for f in fragments] if len(fragments) > 1 or fixed else None
    impulses = np.zeros((len(fragments), 2))
    woke = np.zeros(len(fragments), dtype=bool)
    for t in times[:-1]:
        bodies = _kicks(bodies, fragments, asleep, t, 0.5 * h)
        bodies, received, woken, _ = step_all(bodies, asleep, moving, h, gravity, obstacles,
                                              fixed, law, shapes)
        asleep, woke, impulses = asleep & ~woken, woke | woken, impulses + received
        bodies = _kicks(bodies, fragments, asleep, t + h, 0.5 * h)
    supported = bool(obstacles) or bool(fixed) or len(fragments) > 1
    moved = []
    for k, f in enumerate(fragments):
        if asleep[k]:
            moved.append(f)
            continue
        resting = (not loaded[k] and supported and quiet > 0
                   and kinetic_energy(bodies[k]) < quiet * bodies[k].mass)
        count = f.resting + 1 if resting and not woke[k] else 0
        moved.append(replace(f, body=bodies[k], resting=count,
                             contact_impulse=(float(impulses[k, 0]), float(impulses[k, 1]))))
    return tuple(moved)


def _kicks(bodies, fragments, asleep, t: float, dt: float) -> list:
    """The awake bodies after ``dt`` times their loads at time ``t``."""
    return [b if asleep[k] else rigid_loads.kick(b, fragments[k].loads, t, dt)
            for k, b in enumerate(bodies)]


class RigidStage:
    """The stage of a ``fragments:`` section (module docstring); the event is a
    :class:`HandOffEvent` when pieces became rigid."""

    name = "fragments"

    def __init__(self, config: schema.Fragments, timer: StageTimer,
                 log: Callable[[str], None] | None = None, obstacles: tuple = ()):
        self.config, self.timer, self.obstacles = config, timer, tuple(obstacles)
        self.log = log or (lambda _: None)
        # the fixed ones among the obstacles that are bodies (moving ones are rigid bodies of
        # the world); they touch the rigid bodies as bodies of infinite mass
        self.fixed = tuple(o for o in self.obstacles if np.isinf(o.body.mass))
        self.law = PairLaw(config.body_contact.restitution, config.body_contact.friction)

    def __call__(self, step: Step, world: World) -> tuple[World, HandOffEvent | None]:
        if step.initial:
            if self.config.whole_body and world.body is not None:
                body = world.body
                whole = self.hand_off(body, np.arange(body.mesh.n_tets), 0)
                return self._without(world, [(np.arange(body.mesh.n_tets), whole)], 0)
            return world, None
        world = replace(world, rigid=move(world.rigid, step.start.t, step.t, world.gravity,
                                          world.obstacles, self.config.contact_substeps,
                                          self.law, self.fixed))
        if world.body is None or self.config.become_rigid == "never":
            return world, None
        pieces = self.free_pieces(world.body, len(world.rigid))
        if not pieces:
            return world, None
        return self._without(world, pieces, step.n)

    def _without(self, world: World, pieces: list, n: int) -> tuple[World, HandOffEvent]:
        """The world after ``pieces`` (``(element ids, rigid fragment)``) left the body."""
        body = world.body
        leaving = np.zeros(body.mesh.n_tets, dtype=bool)
        kinetic = strain = vibration = 0.0
        for elements, f in pieces:
            leaving[elements] = True
            kinetic, strain = kinetic + f.kinetic, strain + f.strain
            vibration += f.vibration_energy
            self.log(f"fragments  step {n}: a piece of {len(elements)} elements is rigid "
                     f"(mass {f.body.mass:.4g}; vibration energy {f.vibration_energy:.3g} "
                     "removed)")
        ledger = world.ledger
        handed = kinetic + strain
        rest = None
        if leaving.all():
            # the finite elements' energies are all gone with them (exactly zero)
            kinetic, strain = ledger.kinetic, ledger.elastic
        else:
            mesh, transfer = extract(body.mesh, ~leaving)
            with self.timer("fragments rebuild"):
                disc = rediscretize(body.disc, mesh, self.timer, "after a piece left",
                                    transfer)
            state = carry(body.state, body.disc, disc, transfer, inertia=True)
            rest = body_of(disc, state, {k: v[transfer.element_map]
                                         for k, v in body.fields.items()})
        # the finite elements' energies of this step lose what the pieces took along
        ledger = replace(ledger, kinetic=ledger.kinetic - kinetic,
                         elastic=ledger.elastic - strain,
                         handed_off=ledger.handed_off + handed,
                         vibration_removed=ledger.vibration_removed + vibration)
        event = HandOffEvent(tuple(f for _, f in pieces), tuple(len(e) for e, _ in pieces))
        return replace(world, body=rest, ledger=ledger,
                       rigid=self._placed(world, event.pieces)), event

    def _placed(self, world: World, pieces: tuple) -> tuple[RigidFragment, ...]:
        """The rigid bodies with the new ``pieces``, each moved out of the bodies it was
        born inside (:func:`~fem_frac.rigid.birth.place`)."""
        everything = world.rigid + pieces
        if len(everything) == 1 and not self.fixed:
            return everything
        newborn = np.arange(len(everything)) >= len(world.rigid)
        bodies = place([f.body for f in everything], newborn, world.obstacles, self.fixed,
                       [own_shape(f) for f in everything])
        return tuple(replace(f, body=b) if b is not f.body else f
                     for f, b in zip(everything, bodies, strict=True))

    def free_pieces(self, body: Body, first_id: int) -> list[tuple[np.ndarray, RigidFragment]]:
        """``(element ids, rigid fragment)`` of every piece without a constrained node that
        the section turns rigid now (ids from ``first_id``, in order)."""
        labels, count = body.labels, body.n_pieces
        space = body.disc.space
        nodes = space.basis.element_dofs  # (n_local, n_tets)
        held = np.zeros(space.n_nodes, dtype=bool)
        held[np.asarray(body.disc.constrained.dofs) // 3] = True
        held_piece = np.zeros(count, dtype=bool)
        np.logical_or.at(held_piece, np.repeat(labels, nodes.shape[0]), held[nodes.T].ravel())
        out = []
        volumes = space.basis.dx.sum(axis=1)
        rule = self.config.become_rigid
        for k in np.flatnonzero(~held_piece).tolist():
            elements = np.flatnonzero(labels == k)
            if rule == "small" and volumes[elements].sum() > self.config.max_volume:
                continue
            f = self.hand_off(body, elements, first_id + len(out))
            if rule == "settled" and f.vibration_energy > self.config.vibration_tolerance * max(
                    kinetic_energy(f.body), 1e-300):
                continue
            out.append((elements, f))
        return out

    @staticmethod
    def hand_off(body: Body, elements: np.ndarray, fragment_id: int = 0) -> RigidFragment:
        """The rigid fragment of the piece ``elements`` of the body."""
        d, state = body.disc, body.state
        space, mesh = d.space, d.mesh
        # vertices first (they have the lower ids)
        nodes = np.unique(space.basis.element_dofs[:, elements])
        local = np.full(space.n_nodes, -1, dtype=np.int64)
        local[nodes] = np.arange(nodes.size)
        cells = local[space.basis.element_dofs[:, elements].T]
        tets = local[mesh.tets[elements]]
        n_vertices = int(np.count_nonzero(nodes < mesh.n_points))
        points = mesh.points[nodes[:n_vertices]]
        u = state.u.reshape(-1, 3)[nodes]
        v = state.v.reshape(-1, 3)[nodes]
        mv = (d.ops.mass @ state.v).reshape(-1, 3)[nodes]
        x = space.node_points[nodes] + u
        positions = (space.node_points + state.u.reshape(-1, 3)).ravel()
        mx = (d.ops.mass @ positions).reshape(-1, 3)[nodes]
        # the inertia goes with the mass L is taken from: lumped -> the nodal point masses
        nodal_mass = d.ops.mass.diagonal()[0::3][nodes] if d.ops.lumped else None
        density = d.materials.density
        rho = density if np.ndim(density) == 0 else np.asarray(density)[elements]
        weights = np.zeros_like(d.ops.weights)
        weights[elements] = d.ops.weights[elements]
        strain = d.law.elastic_energy(state.stress, weights)
        frozen = {}
        if state.plastic is not None:
            dx = d.ops.weights[elements]
            alpha = state.plastic.equivalent_plastic_strain[elements]
            frozen["equivalent_plastic_strain"] = (alpha * dx).sum(axis=1) / dx.sum(axis=1)
        f = rigid_piece(points, tets, space.node_points[nodes], cells, x, mv, v, rho, strain,
                        fragment_id, state.t, frozen, mx, nodal_mass)
        # the tractions and pressures on its faces go with it
        loads = piece_loads(d.problem, nodes, f.body_coords, f.body.orientation)
        return replace(f, loads=loads) if loads else f


@dataclass(frozen=True)
class ElementContactEvent:
    """One step's exchange between the rigid bodies and the finite elements: ``contacts``
    (points), the total impulse ``on_elements (3,)`` the finite elements received (their
    constrained dofs included) and ``on_bodies (3,)`` the rigid bodies received (fixed ones
    included): equal and opposite; ``work``: the kinetic energy it gave the finite
    elements; ``rigid``: the rigid bodies' kinetic energy change; ``constrained``: the
    change of the kinetic energy of the velocities it constrains (<= 0)."""

    contacts: int = 0
    on_elements: np.ndarray = field(default_factory=lambda: np.zeros(3))
    on_bodies: np.ndarray = field(default_factory=lambda: np.zeros(3))
    work: float = 0.0
    rigid: float = 0.0
    constrained: float = 0.0


class ElementContactStage:
    """Contact between the rigid bodies (fragments, moving and fixed obstacles) and the
    finite elements, after the rigid bodies have moved (:mod:`~fem_frac.rigid.deformable`):
    the finite elements' velocities and the rigid bodies' momenta change by equal and
    opposite impulses; the finite-element ledger books the kinetic energy they gave as
    ``contact_work``, both sides' loss as ``contact_dissipated``."""

    name = "element contact"

    def __init__(self, config: schema.Fragments, obstacles: tuple = ()):
        self.fixed = tuple(o for o in obstacles if np.isinf(o.body.mass))
        # moving obstacles: their own friction, by their place among the rigid bodies
        self.friction = {o.rigid_index: o.friction for o in obstacles
                         if o.rigid_index is not None}
        self.default = config.body_contact.friction
        self._mesh, self._exterior = None, None

    def __call__(self, step: Step, world: World) -> tuple[World, ElementContactEvent | None]:
        body = world.body
        if step.initial or body is None or not (world.rigid or self.fixed):
            return world, None
        bodies = [f.body for f in world.rigid] + [o.body for o in self.fixed]
        n = len(world.rigid)
        friction = [self.friction.get(k, self.default) for k in range(n)] + \
            [o.friction for o in self.fixed]
        dt = step.t - step.start.t
        # each body's acceleration over the next step: gravity and the loads that left with
        # it (their mean over the step), as its motion will take them
        accel = np.zeros((len(bodies), 3))
        accel[:n] = world.gravity + np.array(
            [0.5 * (rigid_loads.acceleration(f.body, f.loads, step.t)
                    + rigid_loads.acceleration(f.body, f.loads, step.t + dt))
             for f in world.rigid]).reshape(-1, 3)
        # fragments touch by their own tets, moving obstacles and fixed ones by their hulls
        shapes = [None if k in self.friction else deformable.fragment_solid(f)
                  for k, f in enumerate(world.rigid)] + [None] * len(self.fixed)
        elements = self.elements(body)
        contacts = deformable.detect(elements, bodies, friction, accel, dt, shapes)
        if len(contacts) == 0:
            return world, ElementContactEvent()
        ex = deformable.exchange(elements, bodies, contacts, accel, dt)
        world, event = self._apply(world, ex, n)
        # what the bodies still overlap, they leave by a translation (the nodes stay)
        shift = deformable.separate(bodies, np.arange(len(bodies)) < n, contacts)[:n]
        if np.any(shift):
            world = replace(world, rigid=tuple(
                replace(f, body=replace(f.body, position=f.body.position + s))
                if np.any(s) else f for f, s in zip(world.rigid, shift, strict=True)))
        return world, event

    def elements(self, body: Body) -> deformable.Elements:
        """The finite-element side of the body's state (exterior cached per mesh)."""
        d, state = body.disc, body.state
        if body.mesh is not self._mesh:
            self._mesh = body.mesh
            self._exterior = exterior(body.mesh.tets, body.mesh.n_points,
                                      d.space.basis.element_dofs)
        inverse = 1.0 / d.ops.mass.diagonal()
        inverse[np.asarray(d.constrained.dofs)] = 0.0
        x = d.space.node_points + state.u.reshape(-1, 3)
        return deformable.Elements(x, state.v.reshape(-1, 3), state.a.reshape(-1, 3),
                                   inverse.reshape(-1, 3), body.mesh.tets, self._exterior)

    @staticmethod
    def _apply(world: World, ex, n: int) -> tuple[World, ElementContactEvent]:
        body = world.body
        state = body.state
        v = state.v.reshape(-1, 3).copy()
        m = body.disc.ops.mass.diagonal().reshape(-1, 3)[ex.nodes]
        before = v[ex.nodes]
        v[ex.nodes] = before + ex.dv
        work = 0.5 * float(np.sum(m * (v[ex.nodes] ** 2 - before ** 2)))
        rigid, change = list(world.rigid), 0.0
        for i, k in enumerate(ex.bodies):
            if k >= n or not np.any(ex.rigid[i]):
                continue  # a fixed obstacle takes its impulse without moving
            f = rigid[k]
            moved = replace(f.body, momentum=f.body.momentum + ex.rigid[i, :3],
                            angular_momentum=f.body.angular_momentum + ex.rigid[i, 3:])
            change += kinetic_energy(moved) - kinetic_energy(f.body)
            rigid[k] = replace(f, body=moved, resting=0)
        ledger = world.ledger
        contact = ledger.contact_work + work
        ledger = replace(ledger, kinetic=ledger.kinetic + work, contact_work=contact,
                         contact_dissipated=ledger.contact_dissipated - work - change,
                         scale=max(ledger.scale, abs(contact)))
        event = ElementContactEvent(ex.contacts, ex.impulse.sum(axis=0),
                                    ex.rigid[:, :3].sum(axis=0), work, change, ex.constrained)
        # only the velocities change: the fields published for the state still hold
        body = replace(body, state=replace(state, v=v.reshape(-1)))
        return replace(world, body=body, rigid=tuple(rigid), ledger=ledger), event
