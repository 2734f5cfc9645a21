"""Pieces no support holds: why a static or quasi-static solve of a cracked body is singular.

Without inertia every piece of the body must be held by its supports, or the stiffness has
a null space (its free rigid motions). Pieces are counted over the faces that hold
(:func:`~fem_frac.world.state.body_of`): shared faces, and cohesive faces that still carry
traction. A softened cohesive face still counts as holding, but its stiffness is a
vanishing share of the elements' (and a broken face pressed shut resists only closing), so a
piece held on only by such faces can leave the factorization singular: where it does,
:func:`held_only_by_faces` finds the piece by counting the pieces again with every crack face
open.
"""

from __future__ import annotations

import numpy as np

from ..errors import SingularMatrixError
from ..fracture.topology import fragments
from ..solve.problem import free_rigid_modes
from .state import Body


def unsupported(body: Body, labels: np.ndarray | None = None,
                count: int | None = None) -> list[tuple[int, list[str]]]:
    """The pieces no support holds, with the rigid motions each leaves free: of the body's
    own pieces, or of the pieces ``labels (m,)`` (``count`` of them) when given."""
    if labels is None:
        labels, count = body.labels, body.n_pieces
    space, dofs = body.disc.space, body.disc.constrained.dofs
    node_piece = np.empty(space.n_nodes, dtype=np.int64)
    node_piece[space.basis.element_dofs.T] = labels[:, None]
    out = []
    for k in range(count):
        free = free_rigid_modes(space, dofs, np.flatnonzero(node_piece == k))
        if free:
            out.append((k, free))
    return out


def held_only_by_faces(body: Body) -> list[tuple[int, list[str]]]:
    """``(elements, free motions)`` of each piece that, with every crack face open, no
    support holds, while the body's own count (cohesive faces holding) found none; empty
    for a body without cohesive faces."""
    if body.disc.ops.interface is None or unsupported(body):
        return []
    count, labels = fragments(body.mesh.tets)
    if count == body.n_pieces:
        return []
    sizes = np.bincount(labels, minlength=count)
    return [(int(sizes[k]), free) for k, free in unsupported(body, labels, count)]


def explain_singular(body: Body, exc: SingularMatrixError) -> SingularMatrixError | None:
    """Where the body's cohesive faces alone hold pieces to the supports, an error that says
    so in place of ``exc`` (a singular factorization); ``None`` where they do not."""
    pieces = held_only_by_faces(body)
    if not pieces:
        return None
    what = "; ".join(f"{n:,} elements, {', '.join(free)} free" for n, free in pieces)
    return SingularMatrixError(
        f"the stiffness became singular: {len(pieces)} piece(s) ({what}) are held to the "
        "supports only through cohesive faces that have softened or broken (closed, they "
        "resist only being pressed together), which no longer hold them; a static or "
        "quasi-static solve cannot follow them: use a dynamic analysis, or support every "
        f"piece (output so far kept) [{exc}]")
