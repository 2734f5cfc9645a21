"""What a run writes: one output step of the series (finite elements, rigid fragments, crack
surface), a row of history.csv and summary.json. Read-only views of the world."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import __version__
from ..config import schema
from ..fracture.stage import FractureEvent
from ..fracture.summary import CrackFaces, crack_faces, crack_openings
from ..solve.discretization import Discretization
from ..solve.loading import default_curve
from ..solve.state import State, StepInfo
from ..world.state import Body, World
from ..writers.fields import plastic_fields, plastic_point_fields, stress_fields, vtk_cells
from ..writers.series import SeriesWriter


@dataclass(frozen=True)
class Layout:
    """What the series shows: velocities (dynamic), the pieces' ``fragment_id`` (fracture),
    rigid fragments (fragments)."""

    dynamic: bool
    pieces: bool
    rigid: bool


def frame(disc: Discretization, body: Body, layout: Layout):
    """``(points, (kind, cells), point_data, cell_data)`` of the finite elements."""
    space = disc.space
    st = body.state
    u, v, stress, plastic = st.u, st.v, st.stress, st.plastic
    labels, fields = body.labels, body.fields
    point_data = {"displacement": u.reshape(-1, 3)}
    if layout.dynamic:
        point_data["velocity"] = v.reshape(-1, 3)
    cell_data = stress_fields(space, stress)
    if plastic is not None:
        cell_data.update(plastic_fields(space, plastic))
        point_data.update(plastic_point_fields(space, plastic))
    if layout.pieces:
        cell_data["fragment_id"] = labels.astype(np.int32)
    for name, values in fields.items():
        cell_data[name] = values
    kind, cells = vtk_cells(space)
    return space.node_points, (kind, cells), point_data, cell_data


def empty(data):
    """The same fields with no point and no cell."""
    points, (kind, cells), point_data, cell_data = data
    return (points[:0], (kind, cells[:0]), {k: v[:0] for k, v in point_data.items()},
            {k: np.asarray(v)[:0] for k, v in cell_data.items()})


def write_step(writer: SeriesWriter, world: World, data, layout: Layout) -> None:
    """One output step: the finite elements' ``data`` (:func:`frame`), then every rigid
    fragment (its nodes at their reference positions, moved by ``displacement``), in one
    unstructured grid."""
    points, (kind, cells), point_data, cell_data = data
    if layout.rigid:
        from ..rigid.output import with_rigid_fragments

        # rigid bodies keep their ids (order of hand-off) from frame to frame; the
        # deformable pieces are numbered after them
        if "fragment_id" in cell_data:
            cell_data = {**cell_data,
                         "fragment_id": cell_data["fragment_id"] + len(world.rigid)}
        points, cells, point_data, cell_data = with_rigid_fragments(
            world.rigid, points, cells, point_data, cell_data)
    writer.write(world.t, points, (kind, cells), point_data, cell_data)


class CrackWriter:
    """The crack-face series ``<name>_crack.pvd``: one triangle per crack face (its two sides
    paired, :func:`~fem_frac.fracture.summary.crack_faces`), at the reference position of
    its corners, with

    - point field ``displacement``: the mean of the two sides' displacements at the corner
      (Warp By Vector puts the face midway across the gap),
    - cell fields ``opening (3)``: the displacement jump ``u(b) - u(a)`` at the face's
      centroid, ``opening_norm``, ``normal_opening`` (its component along ``normal``,
      positive when the faces part), ``normal (3)``: the unit normal from side a to side b,
      ``opened_step`` and ``opened_time``: when the face first appeared.

    A face's step is the first step :meth:`record` saw it in (the output stage calls it
    every step, written or not; a CrackWriter is also an observer ``(n, world)``); faces are
    named by their corners' reference positions, which later cracks and extractions keep.
    Faces whose other side has left with a rigid body are not written. A step without a
    crack face (before the first crack, or once no finite element is left) holds one
    ``vertex`` cell at the centre of the mesh's bounding box with ``opened_step`` -1: meshio
    cannot read a .vtu without cells, ParaView drops a series' part that first appears
    mid-way, and the rigid fragments of the main series show their own faces."""

    def __init__(self, series: SeriesWriter):
        self.series = series
        self.opened: dict[bytes, tuple[int, float]] = {}
        self.step = -1  # the last step recorded (-1: none; a face first seen then is unknown)
        self._mesh, self._faces = None, None

    @property
    def pvd_path(self) -> Path:
        return self.series.pvd_path

    @property
    def entries(self) -> list[tuple[float, str]]:
        return self.series.entries

    def __call__(self, n: int, world: World) -> None:
        self.record(n, world)

    def record(self, n: int, world: World) -> None:
        """Note the crack faces of step ``n`` not seen before as opened in it."""
        self.step = n
        if world.body is not None and world.body.mesh is not self._mesh:
            self._note(self._faces_of(world.body.mesh), n, world.t)

    def write(self, world: World, last_mesh) -> Path:
        """One step of the series; ``last_mesh``: the mesh of the last body (placed the
        empty step's vertex once no finite element is left)."""
        body = world.body
        if body is None:
            data = _no_crack_face(last_mesh)
        else:
            faces = self._faces_of(body.mesh)
            self._note(faces, self.step, world.t)  # (where no step was recorded)
            data = (_no_crack_face(body.mesh) if len(faces) == 0
                    else self._frame(body, faces))
        return self.series.write(world.t, *data)

    def _faces_of(self, mesh) -> CrackFaces:
        if mesh is not self._mesh:
            self._mesh, self._faces = mesh, crack_faces(mesh)
        return self._faces

    def _note(self, faces: CrackFaces, n: int, t: float) -> None:
        for key in faces.keys:
            self.opened.setdefault(key, (n, t))

    def _frame(self, body: Body, faces: CrackFaces):
        u = body.state.u.reshape(-1, 3)
        opening = crack_openings(body.disc.space, faces, u)
        mid = 0.5 * (u[faces.a] + u[faces.b])  # (k, 3 corners, 3)
        when = [self.opened[key] for key in faces.keys]
        k = len(faces)
        damage, traction = _cohesive_faces(body, k)
        cell_data = {"opening": opening, "opening_norm": np.linalg.norm(opening, axis=1),
                     "normal_opening": np.einsum("ki,ki->k", opening, faces.normal),
                     "normal": faces.normal,
                     "opened_step": np.array([w[0] for w in when], dtype=np.int32),
                     "opened_time": np.array([w[1] for w in when], dtype=float),
                     "damage": damage, "traction": traction}
        return (body.mesh.points[faces.a].reshape(-1, 3),
                ("triangle", np.arange(3 * k, dtype=np.int64).reshape(k, 3)),
                {"displacement": mid.reshape(-1, 3)}, cell_data)


def _cohesive_faces(body: Body, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Per crack face (in :func:`crack_faces` order, as the interface's faces): the fraction
    of its fracture energy dissipated (1 for a traction-free face) and its mean traction."""
    interface, state = body.disc.ops.interface, body.state.cohesive
    if interface is None or state is None:
        return np.ones(k), np.zeros((k, 3))
    law, w, face = interface.law, interface.weights, interface.face
    r = law.response(state.jump, interface.normals, state.kappa, interface.stiffness)
    area = np.bincount(face, weights=w, minlength=k)
    damage = np.bincount(face, weights=w * r.dissipated, minlength=k) / (law.energy * area)
    traction = np.stack([np.bincount(face, weights=w * r.traction[:, i], minlength=k)
                         for i in range(3)], axis=1) / area[:, None]
    return damage, traction


def _no_crack_face(mesh):
    """A step of the crack series without a crack face: one vertex cell, every field."""
    centre = 0.5 * (mesh.points.min(axis=0) + mesh.points.max(axis=0))
    zero3 = np.zeros((1, 3))
    return (centre[None, :], ("vertex", np.zeros((1, 1), dtype=np.int64)),
            {"displacement": zero3},
            {"opening": zero3, "opening_norm": np.zeros(1), "normal_opening": np.zeros(1),
             "normal": zero3, "opened_step": np.full(1, -1, dtype=np.int32),
             "opened_time": np.full(1, np.nan), "damage": np.zeros(1), "traction": zero3})


def write_crack_surface(writer: CrackWriter | SeriesWriter, world: World, last_mesh) -> Path:
    """One step of the crack-face series (:class:`CrackWriter`). A plain ``SeriesWriter``
    gets a CrackWriter kept for it (no step is recorded then: ``opened_step`` is -1, and
    ``opened_time`` the first output time that showed the face)."""
    if not isinstance(writer, CrackWriter):
        kept = _KEPT.get(id(writer))
        if kept is None or kept.series is not writer or not writer.entries:
            kept = _KEPT[id(writer)] = CrackWriter(writer)
        writer = kept
    return writer.write(world, last_mesh)


# the CrackWriter of each plain SeriesWriter given to write_crack_surface
_KEPT: dict[int, CrackWriter] = {}


def reaction_forces(disc: Discretization, state: State | None) -> dict[str, np.ndarray]:
    """Total support force ``(3,)`` of every reaction group (zero without a state)."""
    full = np.zeros(disc.space.n_dofs)
    if state is not None:
        full[disc.constrained.dofs] = state.reaction
    return {label: full[dofs].reshape(-1, 3).sum(axis=0)
            for label, dofs in disc.problem.reaction_groups.items()}


def applied_columns(disc: Discretization, t: float) -> dict:
    """What the case applies at ``t``: the factor of every load curve (``curve_<name>``), the
    total force of every load on the finite elements, its curve's factor times its resultant
    at factor 1 (``load_<label>_<axis>``, the labels of
    :attr:`~fem_frac.solve.problem.Problem.resultants`), and the value of every prescribed
    displacement component, its curve's factor times the value in the case
    (``prescribed_<label>_<axis>``: the boundary name, or ``boundary_conditions[i]``)."""
    problem, recipe = disc.problem, disc.recipe
    factors = problem.factors(t)
    out = {f"curve_{name}": float(factors[c]) for c, name in enumerate(problem.curve_names)}
    for label, (c, force) in problem.resultants.items():
        for axis, value in zip("xyz", factors[c] * force, strict=True):
            out[f"load_{label}_{axis}"] = float(value)
    default = default_curve(recipe.analysis)
    labels: set[str] = set()
    for i, bc in enumerate(recipe.boundary_conditions):
        if not isinstance(bc, schema.Displacement):
            continue
        label = bc.boundary if bc.boundary is not None and bc.boundary not in labels \
            else f"boundary_conditions[{i}]"
        labels.add(label)
        factor = factors[problem.curve_names.index(bc.curve or default)]
        for axis, value in zip("xyz", (bc.x, bc.y, bc.z), strict=True):
            if value is not None:
                out[f"prescribed_{label}_{axis}"] = float(factor * value)
    return out


def history_row(n: int, world: World, info: StepInfo, fracture: FractureEvent | None,
                last: Body, wall: float, layout: Layout, substep: int = 0) -> dict:
    """One row of history.csv. ``last``: the body, or the last one once no finite element
    is left (its supports name the reaction columns, its cracks and pieces stay).
    ``substep`` k >= 1: the k-th sub-step a cut-back step ``n`` converged before its end
    (:mod:`~fem_frac.app.substeps`); 0: the step itself."""
    ledger, body, disc = world.ledger, world.body, last.disc
    row = {"step": n, "substep": substep, "time": world.t, "kinetic_energy": ledger.kinetic,
           "strain_energy": ledger.elastic, "plastic_dissipation": ledger.plastic_dissipation,
           "plastic_work": ledger.plastic_work, "damping_work": ledger.damping_work,
           "external_work": ledger.external_work, "fracture_energy": ledger.fracture,
           "handed_off": ledger.handed_off, "energy_error": ledger.error,
           "energy_error_relative": ledger.relative_error}
    if disc.recipe.cohesive is not None:
        row.update(cohesive_work=ledger.cohesive_work, cohesive_stored=ledger.cohesive_stored,
                   cohesive_dissipated=ledger.cohesive_dissipated)
    state = body.state if body is not None else None
    for label, total in reaction_forces(disc, state).items():
        for axis, value in zip("xyz", total, strict=True):
            row[f"reaction_{label}_{axis}"] = float(value)
    row.update(applied_columns(disc, world.t))
    u = body.state.u if body is not None else np.zeros(0)
    row["max_displacement"] = float(np.linalg.norm(u.reshape(-1, 3), axis=1).max(initial=0.0))
    if disc.law.plastic:
        alpha = (body.state.plastic.equivalent_plastic_strain if body is not None
                 else np.zeros(0))
        row["yielded_points"] = int(np.count_nonzero(alpha > 0.0))
        row["max_equivalent_plastic_strain"] = float(alpha.max(initial=0.0))
    else:
        row["yielded_points"] = 0
    row.update(iterations=info.iterations, cutbacks=info.cutbacks, residual=info.residual,
               wall_time=wall)
    if layout.pieces:
        row.update(_fracture_columns(last, fracture))
    if layout.rigid:
        row.update(_rigid_columns(world))
    return row


def _fracture_columns(last: Body, event: FractureEvent | None) -> dict:
    return {"crack_faces": last.crack.faces, "crack_area": last.crack.area,
            "fragments": last.n_pieces,
            "insertions": event.insertions if event is not None else 0,
            "fracture_passes": event.passes if event is not None else 0}


def _rigid_columns(world: World) -> dict:
    kinetic, potential = world.rigid_energies()
    return {"rigid_bodies": len(world.rigid), "rigid_kinetic_energy": kinetic,
            "rigid_potential_energy": potential,
            "handed_off_energy": world.ledger.handed_off,
            "vibration_energy_removed": world.ledger.vibration_removed,
            # the step's contact impulses (sums over the bodies of the sizes of their net
            # impulses), between bodies and from planes and fixed obstacles
            # (RigidFragment.contact_impulse)
            "rigid_impulse_between_bodies": sum(f.contact_impulse[0] for f in world.rigid),
            "rigid_impulse_from_obstacles": sum(f.contact_impulse[1] for f in world.rigid),
            # contact with the finite elements (fragments.finite_element_contact): the
            # kinetic energy its impulses gave the finite elements (in the ledger's balance)
            # and the kinetic energy they removed from both sides, from t = 0
            "contact_work": world.ledger.contact_work,
            "contact_dissipated": world.ledger.contact_dissipated}


def summary(case, case_path, grid, world: World, tally) -> dict:
    """summary.json: counts, costs, energies, reactions, wall times; the fracture and
    fragments sections when the case has them."""
    last, body = tally.body, world.body
    disc = last.disc
    space, problem, ledger = disc.space, disc.problem, world.ledger
    t = world.t
    state = body.state if body is not None else None
    u = [state.u.reshape(-1, 3)] if state is not None else []
    out = {
        "case": str(case_path), "title": case.title, "fem_frac": __version__,
        "python": sys.version.split()[0],
        "counts": {"vertices": disc.mesh.n_points, "nodes": space.n_nodes,
                   "elements": disc.mesh.n_tets, "dofs": space.n_dofs,
                   "constrained_dofs": int(len(problem.constraints.dofs)),
                   "element_order": space.order, "formulation": case.mesh.formulation},
        "analysis": _analysis(case, grid, tally, ledger, disc),
        "linear_solver": tally.solver or "none (explicit)",
        "max_displacement": max(
            [float(np.linalg.norm(x, axis=1).max(initial=0.0)) for x in u]
            + [float(np.linalg.norm(f.displacement(), axis=1).max()) for f in world.rigid]
            + [0.0]),
        "strain_energy": ledger.elastic, "kinetic_energy": ledger.kinetic,
        "plastic_dissipation": ledger.plastic_dissipation,
        "reaction_force": {k: v.tolist() for k, v in reaction_forces(disc, state).items()},
        "external_force": problem.external_force(t).reshape(-1, 3).sum(axis=0).tolist(),
        "wall_time_s": {},
    }
    if body is not None and body.state.plastic is not None:
        alpha = body.state.plastic.equivalent_plastic_strain
        out["max_equivalent_plastic_strain"] = float(alpha.max())
        out["yielded_points"] = int(np.count_nonzero(alpha > 0))
    if case.fracture is not None:
        out["fracture"] = _fracture_summary(world, grid, tally)
    if case.fragments is not None:
        out["fragments"] = _fragments_summary(world)
    return out


def _analysis(case, grid, tally, ledger, disc: Discretization) -> dict:
    out = {"type": case.analysis.type, "steps": grid.steps, "dt": grid.dt,
           "t_end": grid.t_end, "iterations": tally.iterations, "cutbacks": tally.cutbacks,
           "solves": tally.solves,
           # every factorization of a step's matrix: the elastic one once per topology
           # (implicit), Newton's tangents
           "factorizations": tally.factorizations,
           "max_relative_residual": tally.max_residual,
           "energy_error_relative": ledger.relative_error}
    if disc.limit is not None:
        out["stable_time_step"] = disc.limit.dt
        out["stable_time_step_method"] = disc.limit.method
    return out


def _fracture_summary(world: World, grid, tally) -> dict:
    batches, last = tally.batches, tally.body
    return {
        "crack_faces": last.crack.faces,
        "crack_area": last.crack.area,
        "fragments": last.n_pieces,
        "insertions": int(sum(b.sites for b in batches)),
        "batches": len(batches),
        "new_vertices": int(sum(b.new_vertices for b in batches)),
        "first_crack_time": grid.time(batches[0].step) if batches else None,
        "energy_released": world.ledger.fracture,
        "insertion_seconds": round(sum(b.insertion_seconds for b in batches), 6),
        **({"cohesive_work": world.ledger.cohesive_work,
            "cohesive_stored": world.ledger.cohesive_stored,
            "cohesive_dissipated": world.ledger.cohesive_dissipated}
           if last.disc.recipe.cohesive is not None else {}),
    }


def _fragments_summary(world: World) -> dict:
    kinetic, potential = world.rigid_energies()
    return {
        "rigid_bodies": len(world.rigid),
        "finite_elements_left": world.body is not None,
        "rigid_kinetic_energy": kinetic,
        "rigid_potential_energy": potential,
        "handed_off_energy": world.ledger.handed_off,
        "vibration_energy_removed": world.ledger.vibration_removed,
        "bodies": [{"mass": f.body.mass, "born": f.born,
                    "position": f.body.position.tolist(),
                    "momentum": f.body.momentum.tolist(),
                    "angular_momentum": f.body.angular_momentum.tolist()}
                   for f in world.rigid],
    }
