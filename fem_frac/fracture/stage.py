"""The fracture stage between steps: find crack sites, open them, re-solve the step.

After a step is committed on the current mesh (DESIGN §3, steps 3-4), up to ``passes``
times: smooth the element stresses, take the largest principal stress and its direction,
choose a batch of sites (:mod:`~fem_frac.fracture.sites`), open them
(:func:`~fem_frac.fracture.topology.open_crack`), rebuild the discretization on the new mesh
(operators refactorized once per batch), carry the state at the start of the step over to it
and take the step again. The step that is finally committed is the last re-solve.

Carrying a state over: nodal values are copied to the new nodes, element state stays with
its element (elements are never cut). That keeps the displacement field, the stresses, the
elastic and kinetic energies, the mass and the linear and angular momenta exactly. With
inertia the acceleration is re-balanced on the new mesh (the force on a vertex is now shared
by its copies), so the energy ledger of the re-solved step still balances; without inertia
the energy the crack releases has nowhere to go and is booked as ``Ledger.fracture``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from scipy.sparse.csgraph import connected_components

from ..config import schema
from ..errors import CaseError, SolverError
from ..mesh.mesh import Mesh, tet_volumes
from ..plasticity.regions import selected_elements
from ..solve.problem import free_rigid_modes
from ..solve.stepping import Ledger, State, StepInfo, System, advance
from ..writers.fields import cell_average
from .remap import dof_transfer, node_transfer, transfer_plastic
from .sites import select_sites, star, tilt
from .smoothing import principal_stress, smooth, smoothing_operator, update_operator
from .summary import crack_measures
from .topology import CRACK, Transfer, fragments, open_crack

# ``build(mesh)`` -> the discretization on a mesh: an object with ``model`` (``mesh``,
# ``space``, ``problem``, ``materials``), ``ops``, ``constrained``, ``stepper``, ``limit``
# and ``law`` (fem_frac.app.driver.Discretization).
Build = Callable[[Mesh], object]


@dataclass(frozen=True)
class Batch:
    """One insertion batch, for the log and the history."""

    step: int
    sites: int
    new_vertices: int
    max_stress: float
    seconds: float
    where: np.ndarray  # (sites, 3) reference position of each split vertex


def protected_vertices(config: schema.Fracture, mesh: Mesh, strict: bool = True) -> np.ndarray:
    """``(n_points,)`` bool: vertices of the ``protect`` entries, which never split.
    ``strict``: a box that selects no element is an error (in the case as given; later a
    piece holding it may have left the mesh)."""
    mask = np.zeros(mesh.n_points, dtype=bool)
    centroids = None
    for i, p in enumerate(config.protect):
        if p.boundary is not None:
            if p.boundary not in mesh.boundaries:
                known = ", ".join(sorted(mesh.boundaries)) or "none"
                raise CaseError(("fracture", "protect", i, "boundary"),
                                f"the mesh has no boundary {p.boundary!r} (groups: {known})")
            mask[np.asarray(mesh.boundaries[p.boundary]).ravel()] = True
            continue
        if p.box is not None and centroids is None:
            centroids = mesh.points[mesh.tets].mean(axis=1)
        tets = selected_elements(mesh, p.subdomain, p.box, ("fracture", "protect", i),
                                 centroids, strict)
        mask[mesh.tets[tets].ravel()] = True
    return mask


def smoothing_of(config: schema.Fracture, mesh: Mesh):
    s = config.smoothing
    return smoothing_operator(mesh.points, mesh.tets, length=s.length, rings=s.rings,
                              method=s.method)


class FractureStage:
    """The ``after_step`` hook of :func:`~fem_frac.solve.stepping.march` for a ``fracture:``
    section; ``current`` is the discretization in use, ``labels`` the fragment of every
    element."""

    def __init__(self, config: schema.Fracture, current, build: Build, inertia: bool,
                 log: Callable[[str], None] | None = None):
        self.config, self.build, self.inertia = config, build, inertia
        self.log = log or (lambda _: None)
        self.current = current
        self.batches: list[Batch] = []
        self.rebuild_seconds = 0.0
        self._prepare(current.model.mesh)

    def _prepare(self, mesh: Mesh, split: np.ndarray | None = None,
                 smoothing=None) -> None:
        """Per-topology caches: smoothing operator (given, or updated near the ``split``
        vertex positions when given, or built), protected vertices, fragments."""
        if smoothing is not None:
            self.smoothing = smoothing
        elif split is None:
            self.smoothing = smoothing_of(self.config, mesh)
        else:
            s = self.config.smoothing
            self.smoothing = update_operator(self.smoothing, mesh.points, mesh.tets, split,
                                             length=s.length, rings=s.rings, method=s.method)
        self.protected = protected_vertices(self.config, mesh, strict=split is None
                                            and smoothing is None)
        self.star = star(mesh.tets, mesh.n_points)
        n, labels = connected_components(self.star.adjacency, directed=False)
        self.n_fragments, self.labels = int(n), labels.astype(np.int64)
        self.volumes = tet_volumes(mesh.points, mesh.tets)
        # debris: a new piece smaller than the median smoothing neighbourhood
        pattern = self.smoothing.copy()
        pattern.data[:] = 1.0
        self.debris_volume = float(np.median(pattern @ self.volumes))
        self.crack = crack_measures(mesh)
        self.refused = np.zeros(mesh.n_points, dtype=bool)
        self.on_crack = np.zeros(mesh.n_points, dtype=bool)
        self.on_crack[np.asarray(mesh.boundaries.get(CRACK, np.zeros((0, 3), int))).ravel()] = True
        self._principal = None  # (stress array, result) of the last state asked about

    # -- the hook --------------------------------------------------------------------------

    def __call__(self, n: int, start: State, start_ledger: Ledger, end: State,
                 ledger: Ledger, info: StepInfo):
        cfg = self.config
        regular = ledger  # the step on the uncracked mesh
        changed = False
        inserted = passes = 0
        # vertices whose split would shed debris stay refused until the mesh changes (the
        # debris is a matter of geometry: the same sites would be tried and refused again)
        refused = self.refused
        while passes < cfg.passes and inserted < cfg.max_insertions_per_step:
            limit = min(cfg.batch_size, cfg.max_insertions_per_step - inserted)
            t0 = time.perf_counter()
            sites = self.sites(end, n, passes, limit, refused)
            if len(sites) == 0:
                break
            old = self.current
            sites, mesh, transfer, dropped = self.open(old.model.mesh, sites)
            refused[dropped] = True  # for the rest of this step: choose other sites
            if mesh is None:
                continue
            new = self.build(mesh)
            self._prepare(mesh, old.model.mesh.points[sites.vertices])
            refused = self.refused
            if not self.inertia:
                self._check_supports(new, n)
            start = self.carry(start, old, new, transfer)  # the next pass starts from it
            self.current = new
            self.rebuild_seconds += time.perf_counter() - t0
            end, ledger, step_info = advance(new.stepper, start, start.t, end.t,
                                             start_ledger, new.model.problem, new.law,
                                             new.ops, n)
            info = replace(step_info, iterations=info.iterations + step_info.iterations,
                           solves=info.solves + step_info.solves,
                           factorizations=info.factorizations + step_info.factorizations,
                           cutbacks=info.cutbacks + step_info.cutbacks)
            batch = Batch(n, len(sites), transfer.n_new_points - old.model.mesh.n_points,
                          float(sites.stress.max()), time.perf_counter() - t0,
                          old.model.mesh.points[sites.vertices])
            self.batches.append(batch)
            inserted += len(sites)
            passes += 1
            changed = True
        self.refused = refused
        if not changed:
            return end, ledger, info, None
        if not self.inertia:
            # the re-solved step's imbalance beyond the regular step's is the released energy
            ledger = replace(ledger, fracture=ledger.fracture - (ledger.error - regular.error))
        info = replace(info, insertions=inserted, passes=passes)
        self.log(f"fracture   step {n}: {inserted} site(s) in {passes} pass(es), "
                 f"{self.crack.faces} crack faces, {self.n_fragments} fragment(s)")
        return end, ledger, info, self.system()

    def adopt(self, mesh: Mesh, transfer: Transfer, state: State) -> State:
        """Continue on ``mesh``, the current one less pieces that left it (``transfer``
        from :func:`~fem_frac.fracture.topology.extract`): rebuild, and carry ``state``."""
        old = self.current
        new = self.build(mesh)
        keep = transfer.element_map
        # the pieces that left share no face with the rest: no neighbourhood reaches them
        smoothing = self.smoothing[keep][:, keep].tocsr()
        self._prepare(mesh, smoothing=smoothing)
        state = self.carry(state, old, new, transfer)
        self.current = new
        return state

    def system(self) -> System:
        cur = self.current
        return System(cur.model.problem, cur.ops, cur.stepper, cur.law)

    # -- parts -----------------------------------------------------------------------------

    def open(self, mesh: Mesh, sites):
        """Open ``sites`` on ``mesh``: ``(sites kept, new mesh, transfer, dropped vertices)``,
        the mesh ``None`` when nothing opens. Sites that would shed debris (a new piece
        smaller than one smoothing neighbourhood, whose stress the smoothing cannot even
        resolve) are dropped and the rest opened again from ``mesh``."""
        dropped = []
        while len(sites):
            new, transfer = open_crack(mesh, sites.vertices, sites.normals)
            if transfer.n_new_points == mesh.n_points:
                dropped.extend(sites.vertices.tolist())
                break
            count, labels = fragments(new.tets)
            volume = np.bincount(labels, weights=self.volumes, minlength=count)
            debris = np.flatnonzero(volume < self.debris_volume)
            if count == self.n_fragments or debris.size == 0:
                return sites, new, transfer, np.array(dropped, dtype=np.int64)
            touched = transfer.node_map[new.tets[np.isin(labels, debris)]].ravel()
            bad = np.isin(sites.vertices, touched)
            if not bad.any():  # not caused by a split of this batch: nothing to drop
                return sites, new, transfer, np.array(dropped, dtype=np.int64)
            dropped.extend(sites.vertices[bad].tolist())
            sites = sites.subset(~bad)
        return sites, None, None, np.array(dropped, dtype=np.int64)

    def principal(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        """Smoothed largest principal stress ``(m,)`` and its direction ``(m, 3)`` (the
        last one kept: the output asks about the state the stage has just looked at)."""
        if self._principal is not None and self._principal[0] is state.stress:
            return self._principal[1]
        mean = cell_average(self.current.model.space, state.stress)
        result = principal_stress(smooth(self.smoothing, mean))
        self._principal = (state.stress, result)
        return result

    def sites(self, state: State, n: int, batch: int, limit: int,
              refused: np.ndarray | None = None):
        mesh = self.current.model.mesh
        sigma1, direction = self.principal(state)
        p = self.config.perturbation
        if p is not None:
            rng = np.random.default_rng([p.seed, n, batch])
            direction = tilt(direction, np.radians(p.angle), rng)
        return select_sites(mesh.points, mesh.tets, sigma1, direction,
                            self.config.tensile_strength, self.smoothing, self.on_crack,
                            self.protected if refused is None else self.protected | refused,
                            limit, self.star)

    def carry(self, state: State, old, new, transfer: Transfer) -> State:
        """``state`` of ``old`` onto ``new`` (module docstring)."""
        dofs = dof_transfer(node_transfer(old.model.space, new.model.space, transfer))
        u, v, a = state.u[dofs], state.v[dofs], state.a[dofs]
        stress = transfer.transfer_elemental(state.stress, axis=1)
        plastic = transfer_plastic(state.plastic, transfer)
        ops, problem, constrained = new.ops, new.model.problem, new.constrained
        f_int = ops.strain_operator.internal_force(stress)
        f_ext = problem.external_force(state.t)
        fixed, free = constrained.dofs, constrained.free
        reaction = f_int - f_ext
        if self.inertia and ops.mass is not None:
            damping = ops.damping @ v if ops.damping is not None else 0.0
            unbalanced = f_ext - f_int - damping - ops.mass @ a
            if np.any(unbalanced[free]):
                a = a.copy()
                mass = ops.mass
                if mass.nnz == mass.shape[0]:  # diagonal (lumped)
                    a[free] += unbalanced[free] / mass.diagonal()[free]
                else:
                    a[free] += constrained.factorize(mass).solve(unbalanced[free])
            reaction = reaction + ops.mass @ a + damping
        return State(state.t, u, v, a, stress, plastic, f_int, reaction[fixed])

    def _check_supports(self, new, n: int) -> None:
        """Without inertia a piece with no support makes the solve singular: say which."""
        space, dofs = new.model.space, new.constrained.dofs
        node_fragment = np.empty(space.n_nodes, dtype=np.int64)
        nodes = space.basis.element_dofs.T
        node_fragment[nodes] = self.labels[:, None]
        for k in range(self.n_fragments):
            free = free_rigid_modes(space, dofs, np.flatnonzero(node_fragment == k))
            if free:
                count = int(np.count_nonzero(self.labels == k))
                raise SolverError(
                    f"step {n}, stage fracture: a crack cut off a piece of {count} elements "
                    f"that no support holds ({', '.join(free)} free): a static or "
                    "quasi-static solve is singular; use a dynamic analysis, or support "
                    "every piece (output so far kept)")
