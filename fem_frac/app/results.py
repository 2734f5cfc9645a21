"""What a run writes: one output step of the series (finite elements, rigid fragments, crack
surface), a row of history.csv and summary.json. Read-only views of the run's state."""

from __future__ import annotations

import sys

import numpy as np

from .. import __version__
from ..fem.space import Space
from ..mesh.mesh import Mesh
from ..solve.problem import Problem
from ..solve.stepping import Ledger, State, StepInfo
from ..writers.fields import plastic_fields, stress_fields, vtk_cells
from ..writers.series import SeriesWriter


def write_step(writer: SeriesWriter, space: Space, state: State, dynamic: bool,
               fracture=None, rigid=None) -> None:
    """One output step: the finite elements, then every rigid fragment (its nodes at their
    reference positions, moved by ``displacement``), in one unstructured grid."""
    point_data = {"displacement": state.u.reshape(-1, 3)}
    if dynamic:
        point_data["velocity"] = state.v.reshape(-1, 3)
    cell_data = stress_fields(space, state.stress)
    if state.plastic is not None:
        cell_data.update(plastic_fields(space, state.plastic))
    if fracture is not None:
        cell_data["fragment_id"] = fracture.labels.astype(np.int32)
        sigma1, _ = fracture.principal(state)
        cell_data["smoothed_max_principal_stress"] = sigma1
    kind, cells = vtk_cells(space)
    points = space.node_points
    if rigid is not None:
        from ..rigid.output import with_rigid_fragments

        # rigid bodies keep their ids (order of hand-off) from frame to frame; the
        # deformable pieces are numbered after them
        if "fragment_id" in cell_data:
            cell_data["fragment_id"] = cell_data["fragment_id"] + len(rigid.fragments)
        points, cells, point_data, cell_data = with_rigid_fragments(
            rigid.fragments, points, cells, point_data, cell_data,
            none_deformable=rigid.only)
    writer.write(state.t, points, (kind, cells), point_data, cell_data)


def write_crack_surface(writer: SeriesWriter, mesh: Mesh, state: State,
                        none_deformable: bool = False) -> None:
    """The crack faces (both sides) of the deformable part as triangles over the mesh's
    vertices, with their displacement; written at every output step, empty before the first
    crack (ParaView drops a series' part that first appears mid-way)."""
    from ..fracture import CRACK

    tri = np.asarray(mesh.boundaries.get(CRACK, np.zeros((0, 3), dtype=np.int64)))
    if none_deformable:
        tri = tri[:0]
    u = state.u.reshape(-1, 3)[: mesh.n_points]  # P2: vertices come first
    writer.write(state.t, mesh.points, ("triangle", tri.astype(np.int64)),
                 {"displacement": u}, {})


def rigid_row(rigid) -> dict:
    """History columns of the fragments stage."""
    kinetic, potential = rigid.energies()
    return {
        "rigid_bodies": len(rigid.fragments),
        "rigid_kinetic_energy": kinetic,
        "rigid_potential_energy": potential,
        "handed_off_energy": rigid.handed_energy,
        "vibration_energy_removed": rigid.vibration_energy,
    }


def fracture_row(fracture, info: StepInfo) -> dict:
    """History columns of the fracture stage."""
    return {
        "crack_faces": fracture.crack.faces,
        "crack_area": fracture.crack.area,
        "fragments": fracture.n_fragments,
        "insertions": info.insertions,
        "fracture_passes": info.passes,
    }


def history_row(n: int, state: State, ledger: Ledger, info: StepInfo, problem: Problem,
                wall: float) -> dict:
    row = {
        "step": n,
        "time": state.t,
        "kinetic_energy": ledger.kinetic,
        "strain_energy": ledger.elastic,
        "plastic_dissipation": ledger.plastic_dissipation,
        "plastic_work": ledger.plastic_work,
        "damping_work": ledger.damping_work,
        "external_work": ledger.external_work,
        "fracture_energy": ledger.fracture,
        "handed_off": ledger.handed_off,
        "energy_error": ledger.error,
        "energy_error_relative": ledger.relative_error,
    }
    full = np.zeros(problem.space.n_dofs)
    full[problem.constraints.dofs] = state.reaction
    for label, dofs in problem.reaction_groups.items():
        total = full[dofs].reshape(-1, 3).sum(axis=0)
        for axis, value in zip("xyz", total, strict=True):
            row[f"reaction_{label}_{axis}"] = float(value)
    row["max_displacement"] = float(np.linalg.norm(state.u.reshape(-1, 3), axis=1).max(
        initial=0.0))
    if state.plastic is not None:
        alpha = state.plastic.equivalent_plastic_strain
        row["yielded_points"] = int(np.count_nonzero(alpha > 0.0))
        row["max_equivalent_plastic_strain"] = float(alpha.max())
    else:
        row["yielded_points"] = 0
    row["iterations"] = info.iterations
    row["cutbacks"] = info.cutbacks
    row["residual"] = info.residual
    row["wall_time"] = wall
    return row


def summary(setup, case_path, state, ledger, counters, timer, fracture=None,
             rigid=None) -> dict:
    case, model, grid, limit = setup.case, setup.model, setup.grid, setup.limit
    if fracture is not None:
        model, limit = fracture.current.model, fracture.current.limit
    space, problem = model.space, model.problem
    reaction = np.zeros(space.n_dofs)
    reaction[problem.constraints.dofs] = state.reaction
    out = {
        "case": str(case_path),
        "title": case.title,
        "fem_frac": __version__,
        "python": sys.version.split()[0],
        "counts": {
            "vertices": model.mesh.n_points,
            "nodes": space.n_nodes,
            "elements": model.mesh.n_tets,
            "dofs": space.n_dofs,
            "constrained_dofs": int(len(problem.constraints.dofs)),
            "element_order": space.order,
            "formulation": case.mesh.formulation,
        },
        "analysis": {
            "type": case.analysis.type,
            "steps": grid.steps,
            "dt": grid.dt,
            "t_end": grid.t_end,
            "iterations": counters.iterations,
            "cutbacks": counters.cutbacks,
            "solves": counters.solves,
            # the elastic matrix once per topology (implicit), Newton's tangents
            "factorizations": counters.factorizations + (
                (1 + (len(fracture.batches) if fracture is not None else 0))
                if counters.solver else 0),
            "max_relative_residual": counters.max_residual,
            "energy_error_relative": ledger.relative_error,
        },
        "linear_solver": counters.solver or "none (explicit)",
        "max_displacement": max(
            [float(np.linalg.norm(state.u.reshape(-1, 3), axis=1).max(initial=0.0))]
            + [float(np.linalg.norm(f.displacement(), axis=1).max())
               for f in (rigid.fragments if rigid is not None else [])]),
        "strain_energy": ledger.elastic,
        "kinetic_energy": ledger.kinetic,
        "plastic_dissipation": ledger.plastic_dissipation,
        "reaction_force": {
            label: reaction[dofs].reshape(-1, 3).sum(axis=0).tolist()
            for label, dofs in problem.reaction_groups.items()
        },
        "external_force": problem.external_force(state.t).reshape(-1, 3).sum(axis=0).tolist(),
        "wall_time_s": {**{k: round(v, 6) for k, v in timer.seconds.items()},
                        "total": round(timer.total(), 6)},
    }
    if limit is not None:
        out["analysis"]["stable_time_step"] = limit.dt
        out["analysis"]["stable_time_step_method"] = limit.method
    if state.plastic is not None:
        alpha = state.plastic.equivalent_plastic_strain
        out["max_equivalent_plastic_strain"] = float(alpha.max())
        out["yielded_points"] = int(np.count_nonzero(alpha > 0))
    if fracture is not None:
        batches = fracture.batches
        out["fracture"] = {
            "crack_faces": fracture.crack.faces,
            "crack_area": fracture.crack.area,
            "fragments": fracture.n_fragments,
            "insertions": int(sum(b.sites for b in batches)),
            "batches": len(batches),
            "new_vertices": int(sum(b.new_vertices for b in batches)),
            "first_crack_time": _first_crack_time(setup, batches),
            "energy_released": ledger.fracture,
            "insertion_seconds": round(fracture.rebuild_seconds, 6),
        }
    if rigid is not None:
        kinetic, potential = rigid.energies()
        out["fragments"] = {
            "rigid_bodies": len(rigid.fragments),
            "finite_elements_left": not rigid.only,
            "rigid_kinetic_energy": kinetic,
            "rigid_potential_energy": potential,
            "handed_off_energy": rigid.handed_energy,
            "vibration_energy_removed": rigid.vibration_energy,
            "bodies": [{"mass": f.body.mass, "born": f.born,
                        "position": f.body.position.tolist(),
                        "momentum": f.body.momentum.tolist(),
                        "angular_momentum": f.body.angular_momentum.tolist()}
                       for f in rigid.fragments],
        }
    return out


def _first_crack_time(setup, batches) -> float | None:
    return setup.grid.time(batches[0].step) if batches else None
