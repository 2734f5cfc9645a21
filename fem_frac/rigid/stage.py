"""The fragments stage between steps: free pieces leave the finite elements as rigid bodies.

After a dynamic step (and its crack insertions), every piece of the mesh that no support
holds is a candidate; the ``fragments`` section decides which become rigid. Each is handed
over (:func:`~fem_frac.rigid.fragment.rigid_piece`: momenta kept exactly), its elements
leave the finite-element mesh (:func:`~fem_frac.fracture.topology.extract`), and the
discretization is rebuilt and refactorized once for all pieces of the step. The rigid bodies
already there are moved over every step by :func:`~fem_frac.rigid.contact.step` (gravity
exact, torque-free rotation by exact principal-axis rotations, ground planes by impulses).

Energy: what the pieces carried (kinetic and strain energy) leaves the finite-element ledger
as ``Ledger.handed_off``, so its balance still holds; the rigid bodies' own kinetic and
potential energy and the vibrational energy removed at hand-off are reported beside it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ..config import schema
from ..fracture.topology import extract
from ..solve.stepping import Ledger, State, StepInfo
from .body import kinetic_energy
from .contact import Plane, step
from .fragment import RigidFragment, rigid_piece

# Steps at rest on the ground after which a rigid body sleeps (see RigidStage.move).
SLEEP_STEPS = 20


class AllRigid(Exception):  # noqa: N818 (a signal, not an error)
    """Every piece left the finite elements after step ``step``: the rest of the run is
    rigid bodies only."""

    def __init__(self, step: int, state: State, ledger: Ledger, info: StepInfo):
        super().__init__("all pieces are rigid")
        self.step, self.state, self.ledger, self.info = step, state, ledger, info


def planes(config: schema.Fragments) -> list[Plane]:
    out = []
    for g in config.ground:
        n = np.asarray(g.normal, dtype=float)
        out.append(Plane(np.asarray(g.point, dtype=float), n / np.linalg.norm(n),
                         g.restitution, g.friction))
    return out


class RigidStage:
    """Rigid bodies and the hand-off of free pieces. ``fracture`` is the
    :class:`~fem_frac.fracture.stage.FractureStage` that owns the current discretization
    (``None`` when the whole body is rigid from the start)."""

    def __init__(self, config: schema.Fragments, gravity, fracture=None,
                 log: Callable[[str], None] | None = None):
        self.config, self.fracture = config, fracture
        self.gravity = np.asarray(gravity, dtype=float)
        self.planes = planes(config)
        self.log = log or (lambda _: None)
        self.fragments: list[RigidFragment] = []
        self.vibration_energy = 0.0  # removed at hand-offs, in all
        self.handed_energy = 0.0  # kinetic + strain energy the pieces took along
        self.only = False  # no finite elements left

    # -- rigid motion ----------------------------------------------------------------------

    def move(self, t0: float, t1: float) -> None:
        """Advance every rigid body from ``t0`` to ``t1``.

        A body that has rested on the ground for ``SLEEP_STEPS`` steps (kinetic energy below
        what one step of free fall from rest gives it) sleeps: nothing can wake it (no
        body-body contact, fixed planes, constant gravity), so it is no longer stepped."""
        k = self.config.contact_substeps
        h = (t1 - t0) / k
        quiet = 0.5 * float(self.gravity @ self.gravity) * h * h
        moved = []
        for f in self.fragments:
            if f.resting >= SLEEP_STEPS:
                moved.append(f)
                continue
            body = f.body
            for _ in range(k):
                body = step(body, h, self.gravity, self.planes)
            resting = self.planes and quiet > 0 and kinetic_energy(body) < quiet * body.mass
            moved.append(replace(f, body=body, resting=f.resting + 1 if resting else 0))
        self.fragments = moved

    def energies(self) -> tuple[float, float]:
        """Kinetic energy and gravitational potential energy (zero at the origin) of all
        rigid bodies."""
        kinetic = sum(kinetic_energy(f.body) for f in self.fragments)
        potential = -sum(f.body.mass * float(self.gravity @ f.body.position)
                         for f in self.fragments)
        return kinetic, potential

    # -- the hook --------------------------------------------------------------------------

    def __call__(self, n: int, start: State, start_ledger: Ledger, end: State, ledger: Ledger,
                 info: StepInfo):
        self.move(start.t, end.t)
        if self.fracture is None or self.config.become_rigid == "never":
            return end, ledger, info, None
        current = self.fracture.current
        pieces = self.free_pieces(current, end)
        if not pieces:
            return end, ledger, info, None
        mesh = current.model.mesh
        leaving = np.zeros(mesh.n_tets, dtype=bool)
        kinetic = strain = 0.0
        for elements, f in pieces:
            leaving[elements] = True
            self.fragments.append(f)
            self.vibration_energy += f.vibration_energy
            kinetic, strain = kinetic + f.kinetic, strain + f.strain
            self.log(f"fragments  step {n}: a piece of {len(elements)} elements is rigid "
                     f"(mass {f.body.mass:.4g}; vibration energy {f.vibration_energy:.3g} "
                     "removed)")
        handed = kinetic + strain
        self.handed_energy += handed
        # the finite elements' energies of this step lose what the pieces took along
        ledger = replace(ledger, kinetic=ledger.kinetic - kinetic,
                         elastic=ledger.elastic - strain,
                         handed_off=ledger.handed_off + handed)
        if leaving.all():
            self.only = True
            raise AllRigid(n, end, ledger, info)
        new_mesh, transfer = extract(mesh, ~leaving)
        end = self.fracture.adopt(new_mesh, transfer, end)
        return end, ledger, info, self.fracture.system()

    # -- parts -----------------------------------------------------------------------------

    def free_pieces(self, current, state: State) -> list[tuple[np.ndarray, RigidFragment]]:
        """``(element ids, rigid fragment)`` of every piece without a constrained node that
        the section turns rigid now."""
        labels, count = self.fracture.labels, self.fracture.n_fragments
        space = current.model.space
        nodes = space.basis.element_dofs  # (n_local, n_tets)
        held = np.zeros(space.n_nodes, dtype=bool)
        held[np.asarray(current.constrained.dofs) // 3] = True
        held_piece = np.zeros(count, dtype=bool)
        np.logical_or.at(held_piece, np.repeat(labels, nodes.shape[0]), held[nodes.T].ravel())
        out = []
        volumes = current.model.space.basis.dx.sum(axis=1)
        rule = self.config.become_rigid
        for k in np.flatnonzero(~held_piece).tolist():
            elements = np.flatnonzero(labels == k)
            if rule == "small" and volumes[elements].sum() > self.config.max_volume:
                continue
            f = self.hand_off(current, state, elements, len(self.fragments) + len(out))
            if rule == "settled" and f.vibration_energy > self.config.vibration_tolerance * max(
                    kinetic_energy(f.body), 1e-300):
                continue
            out.append((elements, f))
        return out

    def hand_off(self, current, state: State, elements: np.ndarray,
                 fragment_id: int = 0) -> RigidFragment:
        """The rigid fragment of the piece ``elements`` of the current mesh."""
        space, mesh = current.model.space, current.model.mesh
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
        mv = (current.ops.mass @ state.v).reshape(-1, 3)[nodes]
        x = space.node_points[nodes] + u
        positions = (space.node_points + state.u.reshape(-1, 3)).ravel()
        mx = (current.ops.mass @ positions).reshape(-1, 3)[nodes]
        density = current.model.materials.density
        rho = density if np.ndim(density) == 0 else np.asarray(density)[elements]
        weights = np.zeros_like(current.ops.weights)
        weights[elements] = current.ops.weights[elements]
        strain = current.law.elastic_energy(state.stress, weights)
        frozen = {}
        if state.plastic is not None:
            dx = current.ops.weights[elements]
            alpha = state.plastic.equivalent_plastic_strain[elements]
            frozen["equivalent_plastic_strain"] = (alpha * dx).sum(axis=1) / dx.sum(axis=1)
        return rigid_piece(points, tets, space.node_points[nodes], cells, x, mv, v, rho,
                           strain, fragment_id, state.t, frozen, mx)
