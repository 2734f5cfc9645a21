"""The fracture stage: find crack sites, open them, re-solve the step.

After a step is committed on the current mesh (DESIGN §3, steps 3-4), up to ``passes``
times: smooth the element stresses, take the largest principal stress and its direction,
choose a batch of sites (:mod:`~fem_frac.fracture.sites`), open them
(:func:`~fem_frac.fracture.topology.open_crack`), discretize the new mesh (operators
refactorized once per batch), carry the state at the start of the step over to it
(:func:`~fem_frac.world.transfer.carry`) and take the step again. The step that is finally
committed is the last re-solve. Without inertia the energy the crack releases has nowhere
to go and is booked as ``Ledger.fracture``.

With a fracture energy the new faces are cohesive (:mod:`fem_frac.cohesive`): they hold
their sides together until the law has dissipated ``G_c`` per unit area, so an insertion
never cuts a piece off (no debris check), and pieces come apart when the last face between
them breaks, which the stage finds after every step.

The stage publishes the smoothed largest principal stress of the committed state as the
body's field ``smoothed_max_principal_stress``; its caches (smoothing operator, protected
vertices, refused sites) belong to one mesh and are rebuilt for any other.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from ..config import schema
from ..errors import CaseError, SolverError
from ..fem.tensors import largest_value_bound, largest_values
from ..mesh.mesh import Mesh, tet_volumes
from ..plasticity.regions import selected_elements
from ..solve.problem import free_rigid_modes
from ..solve.state import StepInfo
from ..solve.stepping import advance
from ..timing import StageTimer
from ..world.stage import Step
from ..world.state import Body, World, body_of
from ..world.transfer import carry, rediscretize
from ..writers.fields import cell_average
from .front import continue_planes, crack_front, front_normals, near_crack
from .planes import PlaneSites, normal_stress, plane_sites
from .sites import Sites, no_sites, select_sites, star, tilt
from .smoothing import (
    centroids as tet_centres,
)
from .smoothing import (
    neighbourhoods,
    principal_stress,
    smooth,
    smoothing_operator,
    update_operator,
)
from .topology import CRACK, check_separated, cut_tets, extract, fragments, rebuilt

# A piece that a crack cuts off without support in a static run is dropped as a sliver when
# its volume is below this fraction of the body's (larger ones stop the run).
SLIVER = 0.01

FIELD = "smoothed_max_principal_stress"


@dataclass(frozen=True)
class Batch:
    """One insertion batch: ``step``, sites opened, vertices added, the largest smoothed
    stress among them, wall seconds (insertion and rebuild; with the re-solve), and the
    reference position ``(sites, 3)`` of each split vertex."""

    step: int
    sites: int
    new_vertices: int
    max_stress: float
    insertion_seconds: float
    seconds: float
    where: np.ndarray


@dataclass(frozen=True)
class FractureEvent:
    """What the fracture stage did in one step: the batches it opened, the re-solves of
    the step on the cracked meshes (``None`` when nothing opened)."""

    batches: tuple[Batch, ...] = ()
    passes: int = 0
    resolve: StepInfo | None = None

    @property
    def insertions(self) -> int:
        return sum(b.sites for b in self.batches)


def protected_vertices(config: schema.Fracture, mesh: Mesh, strict: bool = True,
                       planes: PlaneSites | None = None,
                       tet_centroids: np.ndarray | None = None) -> np.ndarray:
    """``(n_points,)`` bool: vertices of the ``protect`` entries, which never split, and
    with ``planes`` the vertices that may not split in them (:func:`plane_sites`, made here
    when not given). ``strict``: a box that selects no element is an error (in the case as
    given; later a piece holding it may have left the mesh). ``tet_centroids``: the tets'
    where known."""
    mask = np.zeros(mesh.n_points, dtype=bool)
    if config.planes:
        planes = planes if planes is not None else plane_sites(mesh.points, mesh.tets,
                                                               config.planes)
        mask |= ~planes.usable
    centroids = tet_centroids
    for i, p in enumerate(config.protect):
        if p.boundary is not None:
            if p.boundary not in mesh.boundaries:
                known = ", ".join(sorted(mesh.boundaries)) or "none"
                raise CaseError(("fracture", "protect", i, "boundary"),
                                f"the mesh has no boundary {p.boundary!r} (groups: {known})")
            mask[np.asarray(mesh.boundaries[p.boundary]).ravel()] = True
            continue
        if p.vertices is not None:
            inside = np.all((mesh.points >= np.asarray(p.vertices.min))
                            & (mesh.points <= np.asarray(p.vertices.max)), axis=1)
            if strict and not inside.any():
                raise CaseError(("fracture", "protect", i, "vertices"), "holds no vertex")
            mask |= inside
            continue
        if p.box is not None and centroids is None:
            centroids = tet_centres(mesh.points, mesh.tets)
        tets = selected_elements(mesh, p.subdomain, p.box, ("fracture", "protect", i),
                                 centroids, strict)
        mask[mesh.tets[tets].ravel()] = True
    return mask


def smoothing_of(config: schema.Fracture, mesh: Mesh):
    s = config.smoothing
    return smoothing_operator(mesh.points, mesh.tets, length=s.length, rings=s.rings,
                              method=s.method)


@dataclass(eq=False)
class _Topology:
    """The stage's caches for one mesh. ``refused``: vertices whose split would shed
    debris; they stay refused until the mesh changes (the debris is a matter of geometry:
    the same sites would be tried and refused again)."""

    mesh: Mesh
    smoothing: object
    protected: np.ndarray
    star: object
    volumes: np.ndarray
    debris_volume: float
    on_crack: np.ndarray
    refused: np.ndarray
    front: np.ndarray | None = None  # cohesive cracks: vertices of their fronts
    near: np.ndarray | None = None  # and the tets whose neighbourhood reaches a crack
    front_normals: np.ndarray | None = None  # the crack's normal at tets on a front
    principal: tuple | None = None  # (stress, (sigma1, direction), smoothed) last asked
    smoothed: tuple | None = None  # (stress, smoothed stress) last asked
    planes: PlaneSites | None = None  # fracture.planes: where cracks may open
    own: np.ndarray | None = None  # tets checked against their own stress (front_stress)
    centroids: np.ndarray | None = None  # of the tets (a crack keeps them)


def _topology(config: schema.Fracture, mesh: Mesh, smoothing, strict: bool,
              volumes: np.ndarray | None = None, centroids: np.ndarray | None = None
              ) -> _Topology:
    """The caches of ``mesh``; ``volumes``, ``centroids``: its tets' where known (a crack
    keeps them: its copies of vertices are at the originals' coordinates, to the bit)."""
    volumes = tet_volumes(mesh.points, mesh.tets) if volumes is None else volumes
    centroids = tet_centres(mesh.points, mesh.tets) if centroids is None else centroids
    # debris: a new piece smaller than the median smoothing neighbourhood
    pattern = neighbourhoods(smoothing)
    on_crack = np.zeros(mesh.n_points, dtype=bool)
    on_crack[np.asarray(mesh.boundaries.get(CRACK, np.zeros((0, 3), int))).ravel()] = True
    front = near = normals = None
    if config.fracture_energy is not None:
        # cohesive cracks grow from their fronts (fem_frac.fracture.sites), in their planes
        front, near = crack_front(mesh), near_crack(mesh, pattern)
        normals = front_normals(mesh, front)
    planes = plane_sites(mesh.points, mesh.tets, config.planes) if config.planes else None
    protected = protected_vertices(config, mesh, strict, planes, centroids)
    own = None
    if front is not None and config.cohesive_law.front_stress == "element":
        own = front[mesh.tets].any(axis=1)  # the tets at a crack front
    return _Topology(mesh, smoothing, protected, star(mesh.tets, mesh.n_points), volumes,
                     float(np.median(smooth(pattern, volumes[None])[0])), on_crack,
                     np.zeros(mesh.n_points, dtype=bool), front, near, normals,
                     planes=planes, own=own, centroids=centroids)


class FractureStage:
    """The stage of a ``fracture:`` section (module docstring); the event is a
    :class:`FractureEvent`."""

    name = "fracture"

    def __init__(self, config: schema.Fracture, inertia: bool, timer: StageTimer,
                 log: Callable[[str], None] | None = None,
                 note: Callable[[str], None] | None = None):
        self.config, self.inertia, self.timer = config, inertia, timer
        self.log = log or (lambda _: None)
        self.note = note or (lambda _: None)  # work under way, shown while it lasts
        self._topo: _Topology | None = None

    def __call__(self, step: Step, world: World) -> tuple[World, FractureEvent | None]:
        body = world.body
        if body is None:
            return world, None
        topo = self._caches(body.mesh)
        if step.initial:
            return replace(world, body=self._published(body, topo)), None
        separated, released = self._separated(body, step.n)
        if separated.mesh is not body.mesh:
            # slivers dropped: the step's start lives on the old mesh, so no insertion
            # re-solves this step; the next one looks for sites on the new mesh
            ledger = replace(world.ledger, fracture=world.ledger.fracture + released)
            end = self._published(separated, self._caches(separated.mesh))
            return replace(world, body=end, ledger=ledger), None
        body = separated
        end, ledger, event = self._insert(step, body, world.ledger, topo)
        if event.batches and not self.inertia:
            # the re-solved step's imbalance beyond the regular step's is the released
            # energy
            ledger = replace(ledger, fracture=ledger.fracture
                             - (ledger.error - world.ledger.error))
        if event.batches:
            self.log(f"fracture   step {step.n}: {event.insertions} site(s) in "
                     f"{event.passes} pass(es), {end.crack.faces} crack faces, "
                     f"{end.n_pieces} fragment(s)")
        end = self._published(end, self._caches(end.mesh))
        return replace(world, body=end, ledger=ledger), event

    def _insert(self, step: Step, body: Body, ledger, topo: _Topology):
        """Batches of insertions, each followed by a re-solve of the step from its start:
        ``(body, ledger, event)`` of the last re-solve (the arguments when nothing opens)."""
        cfg = self.config
        start, start_ledger = step.start.body.state, step.start.ledger
        batches, resolve, passes, inserted = [], None, 0, 0
        while passes < cfg.passes and inserted < cfg.max_insertions_per_step:
            t0 = time.perf_counter()
            limit = min(cfg.batch_size, cfg.max_insertions_per_step - inserted)
            sites = self.sites(body, topo, step.n, passes, limit)
            if len(sites) == 0:
                break
            self.note(f"fracture   step {step.n}: pass {passes + 1}, opening {len(sites)} "
                      f"site(s), {inserted} opened so far")
            sites, mesh, transfer, dropped, pieces = self.open(topo, body.n_pieces, sites)
            topo.refused[dropped] = True  # for the rest of this step: choose other sites
            if mesh is None:
                continue
            with self.timer("fracture rebuild"):
                disc = rediscretize(body.disc, mesh, self.timer, "after crack insertion",
                                    transfer)
            topo = self._updated(topo, mesh, body.mesh.points[sites.vertices])
            start = carry(start, body.disc, disc, transfer, self.inertia)
            new = body_of(disc, start, pieces=pieces)
            if not self.inertia:
                new, _ = self.loose(new, step.n)
                disc, start = new.disc, new.state
                topo = self._caches(new.mesh)
            seconds = time.perf_counter() - t0
            state, ledger, info = advance(disc.stepper, start, step.t, start_ledger, step.n)
            resolve = info if resolve is None else resolve.then(info)
            batches.append(Batch(step.n, len(sites), mesh.n_points - body.mesh.n_points,
                                 float(sites.stress.max()), seconds,
                                 time.perf_counter() - t0, body.mesh.points[sites.vertices]))
            body = new.with_state(state)
            inserted += len(sites)
            passes += 1
        return body, ledger, FractureEvent(tuple(batches), passes, resolve)

    def _separated(self, body: Body, n: int) -> tuple[Body, float]:
        """The body with its pieces counted again when cohesive faces have broken (pieces
        hold together through the faces that still carry traction), and the energy of
        slivers dropped (:meth:`loose`)."""
        if body.disc.ops.interface is None or body.state.cohesive is None:
            return body, 0.0
        new = body_of(body.disc, body.state, body.fields)
        if new.n_pieces == body.n_pieces or self.inertia:
            return new, 0.0
        return self.loose(new, n)

    def loose(self, body: Body, n: int) -> tuple[Body, float]:
        """Without inertia: pieces no support holds. Slivers (each below ``SLIVER`` of the
        body's volume, cut off where a crack meets coarse cells) are dropped from the mesh,
        with the energy they held (returned); a larger loose piece stops the run."""
        loose = _unsupported(body)
        if not loose:
            return body, 0.0
        volumes = np.bincount(body.labels, weights=tet_volumes(body.mesh.points,
                                                               body.mesh.tets),
                              minlength=body.n_pieces)
        for k, free in loose:
            if volumes[k] > SLIVER * volumes.sum():
                count = int(np.count_nonzero(body.labels == k))
                raise SolverError(
                    f"step {n}, stage fracture: a crack cut off a piece of {count} elements "
                    f"that no support holds ({', '.join(free)} free): a static or "
                    "quasi-static solve is singular; use a dynamic analysis, or support "
                    "every piece (output so far kept)")
        gone = np.isin(body.labels, [k for k, _ in loose])
        mesh, transfer = extract(body.mesh, ~gone)
        disc = rediscretize(body.disc, mesh, self.timer, "after dropping loose slivers",
                            transfer)
        state = carry(body.state, body.disc, disc, transfer, inertia=False)
        self.log(f"fracture   step {n}: dropped {len(loose)} loose sliver(s) of "
                 f"{np.count_nonzero(gone)} elements ({volumes[[k for k, _ in loose]].sum():.3g}"
                 " in volume) that no support holds")
        before, after = _stored(body), _stored(body_of(disc, state))
        return body_of(disc, state, {k: v[~gone] for k, v in body.fields.items()}), \
            before - after

    # -- caches ----------------------------------------------------------------------------

    def _caches(self, mesh: Mesh) -> _Topology:
        """The caches of ``mesh``: kept, or built for a mesh another stage made (pieces
        left: the neighbourhoods of the rest are unchanged, since the pieces share no face
        with it)."""
        if self._topo is None or self._topo.mesh is not mesh:
            strict = self._topo is None
            # the cuts of a mesh whose vertices are each one fan separate around their
            # splits only (fracture.topology.cut_tets)
            check_separated(mesh)
            self._topo = _topology(self.config, mesh, smoothing_of(self.config, mesh), strict)
        return self._topo

    def _updated(self, topo: _Topology, mesh: Mesh, split: np.ndarray) -> _Topology:
        """The caches of ``mesh``, which opening cracks at the ``split`` vertex positions
        made from ``topo.mesh``: the smoothing operator is rebuilt near them only."""
        s = self.config.smoothing
        smoothing = update_operator(topo.smoothing, mesh.points, mesh.tets, split,
                                    length=s.length, rings=s.rings, method=s.method,
                                    volumes=topo.volumes)
        self._topo = _topology(self.config, mesh, smoothing, strict=False,
                               volumes=topo.volumes, centroids=topo.centroids)
        return self._topo


    # -- parts -----------------------------------------------------------------------------

    def principal(self, body: Body, topo: _Topology) -> tuple[np.ndarray, np.ndarray]:
        """Smoothed largest principal stress ``(m,)`` and its direction ``(m, 3)`` of the
        body's state (the last one kept: the stage asks about the same state twice); at a
        cohesive crack's front with ``front_stress: element``, each tet's own."""
        stress = body.state.stress
        if topo.principal is not None and topo.principal[0] is stress:
            return topo.principal[1]
        smoothed = self._smoothed(body, topo)
        # the values that decide sites by eigh, the rest in closed form; cohesive cracks
        # also weigh the values and directions below the strength (peaks, fronts)
        exact = self.config.tensile_strength if self.config.fracture_energy is None else None
        result = principal_stress(smoothed, exact_above=exact)
        topo.principal = (stress, result, smoothed)
        return result

    def _smoothed(self, body: Body, topo: _Topology) -> np.ndarray:
        """The smoothed Mandel stress ``(6, m)`` of the body's state (each tet's own at a
        cohesive front with ``front_stress: element``), kept for the state last asked."""
        stress = body.state.stress
        if topo.smoothed is not None and topo.smoothed[0] is stress:
            return topo.smoothed[1]
        own = cell_average(body.disc.space, stress)
        smoothed = smooth(topo.smoothing, own)
        if topo.own is not None:
            smoothed = np.where(topo.own, own, smoothed)
        topo.smoothed = (stress, smoothed)
        return smoothed

    def _published(self, body: Body, topo: _Topology) -> Body:
        """The body with its field :data:`FIELD`: the values of :meth:`principal` where the
        stage has them for this state, else the largest values alone (no site is chosen on
        this state: a step's last one; fem.tensors.largest_values, within ~100 ulps of the
        size of the eigen-decomposition's, whose directions nobody would read)."""
        stress = body.state.stress
        if topo.principal is not None and topo.principal[0] is stress:
            sigma1 = topo.principal[1][0]
        else:
            sigma1 = largest_values(self._smoothed(body, topo))
        return body.with_fields(**{FIELD: sigma1})

    def sites(self, body: Body, topo: _Topology, n: int, batch: int, limit: int) -> Sites:
        """Up to ``limit`` crack sites of the body's state (batch ``batch`` of step ``n``)."""
        if not self._may_reach(body, topo):
            return no_sites()
        mesh = body.mesh
        sigma1, direction = self.principal(body, topo)
        if topo.planes is not None:  # the normal stress on the prescribed planes
            direction = topo.planes.normal
            sigma1 = np.where(topo.planes.elements,
                              normal_stress(topo.principal[2], direction), 0.0)
        elif topo.front_normals is not None:
            direction = continue_planes(direction, topo.principal[2], sigma1,
                                        topo.front_normals)
        p = self.config.perturbation
        if p is not None:
            rng = np.random.default_rng([p.seed, n, batch])
            # only the candidates' directions are read (select_sites)
            direction = tilt(direction, np.radians(p.angle), rng,
                             only=sigma1 > self.config.tensile_strength)
        return select_sites(mesh.points, mesh.tets, sigma1, direction,
                            self.config.tensile_strength, topo.smoothing, topo.on_crack,
                            topo.protected | topo.refused, limit, topo.star,
                            front=topo.front, near=topo.near,
                            peak_first=self.config.fracture_energy is not None,
                            centroids=topo.centroids)

    def _may_reach(self, body: Body, topo: _Topology) -> bool:
        """Whether a tet's smoothed largest principal stress may reach the strength. A
        cohesive crack's stage decomposes every tet's stress (the directions below the
        strength weigh at peaks and fronts), but only to choose sites, and a site needs a
        tet over the strength: where an upper bound of every tet's value
        (:func:`~fem_frac.fem.tensors.largest_value_bound`) stays under it, none is
        chosen, and the decomposition is not made (the published field then comes from
        ``largest_values``, within ~100 ulps of it). Brittle cracks decompose only the
        tets near the strength anyway."""
        if self.config.fracture_energy is None or (
                topo.principal is not None and topo.principal[0] is body.state.stress):
            return True
        bound = largest_value_bound(self._smoothed(body, topo))
        return bool(np.any(bound >= self.config.tensile_strength))

    def open(self, topo: _Topology, n_pieces: int, sites: Sites):
        """Open ``sites`` on ``topo.mesh``: ``(sites kept, new mesh, transfer, dropped
        vertices, (count, labels) of the new mesh's pieces)``, the mesh ``None`` when
        nothing opens. Sites that would shed debris (a
        new piece smaller than one smoothing neighbourhood, whose stress the smoothing
        cannot even resolve) are dropped and the rest opened again from the mesh."""
        mesh, dropped = topo.mesh, []
        while len(sites):
            # the tets first: a batch that sheds debris is tried again without its sites
            # before the mesh around the tets is made
            tets, node_map = cut_tets(mesh, sites.vertices, sites.normals)
            if node_map.size == mesh.n_points:
                dropped.extend(sites.vertices.tolist())
                break
            if self.config.fracture_energy is not None:
                # new cohesive faces hold: nothing comes off (pieces counted on the state)
                return (sites, *rebuilt(mesh, tets, node_map),
                        np.array(dropped, dtype=np.int64), None)
            count, labels = fragments(tets)
            volume = np.bincount(labels, weights=topo.volumes, minlength=count)
            debris = np.flatnonzero(volume < topo.debris_volume)
            if count == n_pieces or debris.size == 0:
                return (sites, *rebuilt(mesh, tets, node_map),
                        np.array(dropped, dtype=np.int64), (count, labels))
            touched = node_map[tets[np.isin(labels, debris)]].ravel()
            bad = np.isin(sites.vertices, touched)
            if not bad.any():  # not caused by a split of this batch: nothing to drop
                return (sites, *rebuilt(mesh, tets, node_map),
                        np.array(dropped, dtype=np.int64), (count, labels))
            dropped.extend(sites.vertices[bad].tolist())
            sites = sites.subset(~bad)
        return sites, None, None, np.array(dropped, dtype=np.int64), None


def _unsupported(body: Body) -> list[tuple[int, list[str]]]:
    """The pieces no support holds, with the rigid motions each leaves free (without
    inertia such a piece makes the solve singular)."""
    space, dofs = body.disc.space, body.disc.constrained.dofs
    node_fragment = np.empty(space.n_nodes, dtype=np.int64)
    nodes = space.basis.element_dofs.T
    node_fragment[nodes] = body.labels[:, None]
    out = []
    for k in range(body.n_pieces):
        free = free_rigid_modes(space, dofs, np.flatnonzero(node_fragment == k))
        if free:
            out.append((k, free))
    return out


def _stored(body: Body) -> float:
    """Strain energy of the body's state, with what its cohesive faces store."""
    state, disc = body.state, body.disc
    faces = state.cohesive.stored if state.cohesive is not None else 0.0
    return disc.law.elastic_energy(state.stress, disc.ops.weights) + faces
