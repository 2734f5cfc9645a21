"""State through a crack insertion: nodal values copied to the new nodes, element state kept.

A :class:`~fem_frac.fracture.topology.Transfer` maps mesh vertices. A P2 space also has one
node per edge; an edge of the new mesh is a copy of the old edge between the originals of
its two vertices, and takes that edge's values. Element state (stress, plastic strain,
backstress at the quadrature points) belongs to elements, which are never cut.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..fem.space import Space
from ..mesh.mesh import edge_keys, match
from ..plasticity.return_map import PlasticState
from .topology import Transfer


def node_transfer(old: Space, new: Space, transfer: Transfer) -> np.ndarray:
    """For every scalar node of ``new`` the node of ``old`` it copies, ``(new.n_nodes,)``.

    Vertices first (``transfer.node_map``), then, for P2, the mid-edge nodes: scikit-fem
    numbers them after the vertices in the order of ``skmesh.edges``.
    """
    node_map = np.asarray(transfer.node_map, dtype=np.int64)
    if new.order == 1:
        return node_map
    n_old = old.mesh.n_points
    old_edges = np.asarray(old.skmesh.edges, dtype=np.int64).T
    new_edges = node_map[np.asarray(new.skmesh.edges, dtype=np.int64).T]
    pos = match(edge_keys(old_edges, n_old), edge_keys(new_edges, n_old))
    if np.any(pos < 0):
        raise ValueError("an edge of the new mesh is not a copy of an edge of the old one")
    return np.concatenate([node_map, n_old + pos])


def dof_transfer(nodes: np.ndarray) -> np.ndarray:
    """Vector dof map ``(3 n_new,)`` from a scalar node map (``3 node + component``)."""
    return (3 * np.asarray(nodes, dtype=np.int64)[:, None] + np.arange(3)).ravel()


def transfer_plastic(state: PlasticState | None, transfer: Transfer) -> PlasticState | None:
    """Plastic state ``(6, n_tets, n_qp)`` / ``(n_tets, n_qp)`` onto the new element ids."""
    if state is None:
        return None
    take = transfer.transfer_elemental
    back = state.backstress
    return replace(
        state,
        plastic_strain=take(state.plastic_strain, axis=1),
        equivalent_plastic_strain=take(state.equivalent_plastic_strain, axis=0),
        backstress=None if back is None else take(back, axis=1),
    )
