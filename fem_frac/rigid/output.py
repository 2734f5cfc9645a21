"""Rigid fragments in the output: appended to the finite elements as one unstructured grid.

Each fragment brings its nodes at their reference positions and the point field
``displacement`` of its rigid motion, so Warp By Vector moves the whole scene; cell fields
are zero where a rigid body has none (stress), frozen at hand-off where it has
(``equivalent_plastic_strain``), with ``fragment_id`` (its order of hand-off) and the flag
``rigid`` (1).
"""

from __future__ import annotations

import numpy as np

from .body import point_velocities


def with_rigid_fragments(fragments, points: np.ndarray, cells: np.ndarray,
                         point_data: dict, cell_data: dict):
    """``(points, cells, point_data, cell_data)`` of the finite elements (none, once every
    piece is rigid) followed by every fragment of ``fragments``; fragment ``k`` gets
    ``fragment_id`` ``k`` (its order of hand-off: stable from frame to frame; number the
    deformable pieces after them)."""
    n_cells = cells.shape[0]
    cell_data = dict(cell_data)
    cell_data.setdefault("fragment_id", np.zeros(n_cells, dtype=np.int32))
    cell_data["rigid"] = np.zeros(n_cells, dtype=np.int8)
    all_points, all_cells = [points], [cells]
    pdata = {k: [np.asarray(v)] for k, v in point_data.items()}
    cdata = {k: [np.asarray(v)] for k, v in cell_data.items()}
    offset = points.shape[0]
    for k, f in enumerate(fragments):
        m = f.cells.shape[0]
        all_points.append(f.nodes)
        all_cells.append(f.cells + offset)
        offset += f.nodes.shape[0]
        world = f.world()
        own = {"displacement": world - f.nodes,
               "velocity": point_velocities(f.body, world)}
        for name, parts in pdata.items():
            parts.append(own.get(name, np.zeros((f.nodes.shape[0],) + parts[0].shape[1:])))
        frozen = dict(f.cell_data, fragment_id=np.full(m, k, dtype=np.int32),
                      rigid=np.ones(m, dtype=np.int8))
        for name, parts in cdata.items():
            value = frozen.get(name)
            if value is None:
                value = np.zeros((m,) + parts[0].shape[1:], dtype=parts[0].dtype)
            parts.append(np.asarray(value, dtype=parts[0].dtype))
    return (np.concatenate(all_points), np.concatenate(all_cells),
            {k: np.concatenate(v) for k, v in pdata.items()},
            {k: np.concatenate(v) for k, v in cdata.items()})
