"""The world of a run: one frozen value holding everything that moves.

A stage reads the world it is given and returns a new one (``dataclasses.replace``); nothing
edits a world in place, and no stage keeps a part of the world that another stage could
change. What a stage caches for speed (a smoothing operator, a factorization) is keyed on the
objects of the world it was derived from, so it is rebuilt when they are replaced.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from ..fracture.summary import CrackMeasures, crack_measures
from ..fracture.topology import fragments
from ..rigid.contact import Plane
from ..rigid.fragment import RigidFragment
from ..solve.discretization import Discretization
from ..solve.energy import Ledger
from ..solve.state import State


@dataclass(frozen=True, eq=False)
class Body:
    """The deformable part: a discretization and its committed state.

    ``labels (n_tets,)``: the piece (connected component over shared faces, and over
    cohesive crack faces that still hold) of every element, ``n_pieces`` their count;
    ``measured``: the crack faces and area of the mesh (:attr:`crack`);
    ``fields``: element fields ``(n_tets,)`` that stages publish for the output (the smoothed
    largest principal stress of the fracture criterion), carried through topology changes
    element by element.
    """

    disc: Discretization
    state: State
    labels: np.ndarray
    n_pieces: int
    measured: MeshCrack
    fields: dict = field(default_factory=dict)

    @property
    def mesh(self):
        return self.disc.mesh

    @property
    def crack(self) -> CrackMeasures:
        """The crack faces and area of the mesh, measured when first read (the output's, a
        step's last body: a batch's bodies in between are not measured)."""
        return self.measured.value

    def with_state(self, state: State, **fields) -> Body:
        """The same discretization with ``state`` and the ``fields`` published for it (the
        fields of the previous state go: they describe another state)."""
        return replace(self, state=state, fields=fields)

    def with_fields(self, **fields) -> Body:
        """The same state with ``fields`` published for it (beside those already there)."""
        return replace(self, fields={**self.fields, **fields})


def body_of(disc: Discretization, state: State, fields: dict | None = None,
            pieces: tuple[int, np.ndarray] | None = None) -> Body:
    """A body on a (new) discretization: its pieces (``pieces``: ``(count, labels)`` when
    already known, from :func:`~fem_frac.fracture.topology.fragments`) and cracks measured
    once."""
    if pieces is None:
        interface = disc.ops.interface
        links = interface.links(state.cohesive) if interface is not None else None
        pieces = fragments(disc.mesh.tets, links)
    n, labels = pieces
    return Body(disc, state, labels, n, MeshCrack(disc.mesh), dict(fields or {}))


class MeshCrack:
    """A mesh's :class:`CrackMeasures`, made at the first read of :attr:`value` and kept
    (a body's copies for other states share it: their mesh is the same)."""

    def __init__(self, mesh):
        self.mesh = mesh

    @cached_property
    def value(self) -> CrackMeasures:
        return crack_measures(self.mesh)


@dataclass(frozen=True, eq=False)
class World:
    """Everything that moves in a run, at time ``t``.

    ``body``: the deformable part, ``None`` once every piece has left the finite elements
    (or from the start when the whole body is rigid); ``rigid``: the rigid bodies in order of
    hand-off; ``obstacles``: fixed ground planes; ``gravity (3,)`` acts on rigid bodies;
    ``ledger``: the finite elements' energy balance (works from t = 0, and what left with
    rigid pieces).
    """

    t: float
    body: Body | None
    ledger: Ledger
    rigid: tuple[RigidFragment, ...] = ()
    obstacles: tuple[Plane, ...] = ()
    gravity: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def rigid_energies(self) -> tuple[float, float]:
        """Kinetic energy and gravitational potential energy (zero at the origin) of all
        rigid bodies."""
        from ..rigid.body import kinetic_energy

        kinetic = sum(kinetic_energy(f.body) for f in self.rigid)
        potential = -sum(f.body.mass * float(self.gravity @ f.body.position)
                         for f in self.rigid)
        return kinetic, potential
