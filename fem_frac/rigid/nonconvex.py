"""The narrow phase between rigid bodies of which one is far from convex: by its own tets.

A piece cut out by cracks through a mesh has a jagged surface: the two halves of a beam
broken across its span interlock along their crack (in the shipped breaking beam over
7.5 cm of its length), and the hull of each reaches into the other over that zone.
Separating the hulls threw the halves 19 mm apart along the beam, into the clamped stubs,
within one step. A fragment is **far from convex** when its hull holds more than
``NONCONVEX`` of its own volume beyond it (:attr:`~fem_frac.rigid.surface.Solid.
hull_excess`; a piece handed off whole, a block or a moving obstacle's drawing stays
convex). A pair with such a body touches where the surfaces are, not where the hulls are:

- every surface vertex of one body (its own exterior vertices, or its hull's) is tested
  against the other body (its own tets, or its hull's half-spaces), both ways
  (:func:`~fem_frac.rigid.surface.solid_gaps`, :func:`~fem_frac.rigid.surface.hull_gaps`);
- a vertex inside, or outside within the pair's speculative margin, is a contact point
  with the gap its signed distance to the other's surface (minus the depth inside) and the
  normal the other's outer normal there (turned to point from the first body to the second).

The depth of a pair is then its deepest vertex's, the measure of ``fem-frac overlap``;
edges that cross with no vertex inside the other body are not seen (a vertex is at most an
element's size from any point of the surface). The points go to the same impulse solver and
position projection as a hull's contact patch (:mod:`~fem_frac.rigid.pairs`), each with its
own normal and gap.
"""

from __future__ import annotations

import numpy as np

from .body import RigidBody
from .collide import Touch, hull
from .surface import Solid, hull_gaps, solid, solid_gaps, surface_points
from .vectors import lengths

# A piece whose convex hull exceeds its own volume by more than this fraction touches other
# bodies by its own tets. A piece strained at hand-off is convex to its strain (1e-3 bows
# its faces by far less than 1 % of its volume); a crack's zigzag through elements makes
# the hull several % larger (the breaking beam's halves: 4.6 % and 5.7 %, the piece cut
# off a stub 53 %).
NONCONVEX = 0.01


def own_shape(fragment) -> Solid | None:
    """A fragment's :class:`~fem_frac.rigid.surface.Solid` when it is far from convex
    (module docstring), else ``None`` (its hull is its shape, as for a body drawn with no
    cells)."""
    if len(fragment.cells) == 0:
        return None
    shape = solid(fragment.body_coords, fragment.cells)
    return shape if shape.hull_excess > NONCONVEX else None


def _radius(body: RigidBody, shape: Solid | None) -> float:
    radius = hull(body.points).radius
    if shape is not None:
        radius = max(radius, shape.radius)
    return radius


def _points_in(a: RigidBody, sa: Solid | None, b: RigidBody, sb: Solid | None,
               margin: float):
    """``(points, normals, gaps)`` of the surface vertices of ``a`` inside ``b`` or within
    ``margin`` of it; the normals are ``b``'s outer ones."""
    x = surface_points(a, sa)
    x = x[lengths(x - b.position) <= _radius(b, sb) + margin]
    if len(x) == 0:
        return x, np.zeros((0, 3)), np.zeros(0)
    gap, normal = hull_gaps(x, b) if sb is None else solid_gaps(x, b, sb)
    keep = gap <= margin
    return x[keep], normal[keep], gap[keep]


def touching_shapes(a: RigidBody, sa: Solid | None, b: RigidBody, sb: Solid | None,
                    margin: float) -> Touch | None:
    """Where ``a`` and ``b`` (shapes ``sa``, ``sb``: their own tets, ``None``: their hulls)
    touch or come within ``margin`` of each other (module docstring): a
    :class:`~fem_frac.rigid.collide.Touch` with a normal (from ``a`` to ``b``) and a gap per
    point, ``None`` if no vertex is that near."""
    pa, na, ga = _points_in(a, sa, b, sb, margin)
    pb, nb, gb = _points_in(b, sb, a, sa, margin)
    if len(ga) + len(gb) == 0:
        return None
    # a's vertices in b: b's outer normal points from b to a; b's in a: from a to b
    return Touch(np.vstack([pa, pb]), np.vstack([-na, nb]), np.concatenate([ga, gb]))
