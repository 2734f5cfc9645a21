"""What a run writes: one output step of the series (finite elements, rigid fragments, crack
surface), a row of history.csv and summary.json. Read-only views of the world."""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from .. import __version__
from ..fracture.stage import FractureEvent
from ..fracture.topology import CRACK
from ..solve.discretization import Discretization
from ..solve.state import State, StepInfo
from ..world.state import Body, World
from ..writers.fields import plastic_fields, stress_fields, vtk_cells
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


def write_crack_surface(writer: SeriesWriter, world: World, last_mesh) -> None:
    """The crack faces (both sides) of the deformable part as triangles over the mesh's
    vertices, with their displacement; written at every output step, empty before the first
    crack and once no finite element is left (ParaView drops a series' part that first
    appears mid-way)."""
    body = world.body
    mesh = body.mesh if body is not None else last_mesh
    tri = np.asarray(mesh.boundaries.get(CRACK, np.zeros((0, 3), dtype=np.int64)))
    if body is None:
        tri, u = tri[:0], np.zeros((mesh.n_points, 3))
    else:
        u = body.state.u.reshape(-1, 3)[: mesh.n_points]  # P2: vertices come first
    writer.write(world.t, mesh.points, ("triangle", tri.astype(np.int64)),
                 {"displacement": u}, {})


def reaction_forces(disc: Discretization, state: State | None) -> dict[str, np.ndarray]:
    """Total support force ``(3,)`` of every reaction group (zero without a state)."""
    full = np.zeros(disc.space.n_dofs)
    if state is not None:
        full[disc.constrained.dofs] = state.reaction
    return {label: full[dofs].reshape(-1, 3).sum(axis=0)
            for label, dofs in disc.problem.reaction_groups.items()}


def history_row(n: int, world: World, info: StepInfo, fracture: FractureEvent | None,
                last: Body, wall: float, layout: Layout) -> dict:
    """One row of history.csv. ``last``: the body, or the last one once no finite element
    is left (its supports name the reaction columns, its cracks and pieces stay)."""
    ledger, body, disc = world.ledger, world.body, last.disc
    row = {"step": n, "time": world.t, "kinetic_energy": ledger.kinetic,
           "strain_energy": ledger.elastic, "plastic_dissipation": ledger.plastic_dissipation,
           "plastic_work": ledger.plastic_work, "damping_work": ledger.damping_work,
           "external_work": ledger.external_work, "fracture_energy": ledger.fracture,
           "handed_off": ledger.handed_off, "energy_error": ledger.error,
           "energy_error_relative": ledger.relative_error}
    state = body.state if body is not None else None
    for label, total in reaction_forces(disc, state).items():
        for axis, value in zip("xyz", total, strict=True):
            row[f"reaction_{label}_{axis}"] = float(value)
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
            "vibration_energy_removed": world.ledger.vibration_removed}


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
