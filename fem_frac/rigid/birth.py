"""Pieces born inside other bodies: moved out at their birth.

A piece that leaves the finite elements may lie partly inside a body that left before it:
the finite elements' crack faces do not touch each other, so where they crossed in the
steps before, the new piece is born overlapping the older one. :func:`place` moves each
newborn piece out, the others held.
"""

from __future__ import annotations

import numpy as np

from .collide import candidate_pairs, hull
from .contact import project
from .pairs import contact_rows, separate


def place(bodies, newborn, planes, fixed=(), shapes=None) -> list:
    """The ``bodies`` with each ``newborn (n,)`` one moved out of the bodies it was born
    inside (a piece's crack faces may have crossed those of a piece that left the finite
    elements before it), the others held: the projection of :func:`separate` with only the
    newborn movable, then out of the planes; momenta kept. ``fixed``: the
    :class:`FixedBody` obstacles; ``shapes`` as for :func:`step_all`."""
    newborn = np.asarray(newborn, dtype=bool)
    if not np.any(newborn):
        return list(bodies)
    n = len(bodies)
    everything = list(bodies) + [f.body for f in fixed]
    shapes = (list(shapes) if shapes is not None else [None] * n) + [None] * len(fixed)
    movable = np.concatenate([newborn, np.zeros(len(fixed), dtype=bool)])
    radius = np.array([hull(b.points).radius for b in everything])
    centre = np.array([b.position for b in everything])
    near = candidate_pairs(centre - radius[:, None], centre + radius[:, None])
    near = near[movable[near].any(axis=1)]
    coefficients = np.zeros((len(near), 2))
    rows = contact_rows(everything, movable, near, coefficients, planes, 0.0, shapes=shapes)
    moved = separate(everything, movable, rows, shapes)
    return [project(b, planes) if newborn[k] else b for k, b in enumerate(moved[:n])]
