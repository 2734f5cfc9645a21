"""Which rigid bodies touch, and where: the broad and narrow phases of contact between bodies.

A body's collision shape is the convex hull of its contact points (``RigidBody.points``: for
a fragment the vertices of the hull of its nodes, :func:`~fem_frac.rigid.fragment.
contact_points`). A fixed obstacle is a body of infinite mass (:func:`~fem_frac.rigid.body.
fixed_body`): it takes part in the geometry like any other and receives no impulse.

**Broad phase** (:func:`candidate_pairs`): one axis-aligned box per body, the bounding sphere
about its centre swept from the start to the end of the step (its free-flight centre) and
widened by the speculative margin; sort and sweep along x (``argsort`` + ``searchsorted``),
then the y and z overlaps: ``O(N log N + K)`` for ``N`` bodies and ``K`` pairs overlapping in
x, all numpy.

**Narrow phase** (:func:`touching`): coal (the maintained successor of FCL: GJK, EPA, contact
patches) on each candidate pair, one call per pair (a Python loop over pairs, not over
contact points). coal's normal is refined: near touching, GJK's normal is known only to
about ``1e-13 / distance`` rad (1.2e-4 rad at 1e-12 m apart), which would tilt a resting
stack's contact forces. The signed distance of two convex bodies is the largest separation
of their support planes over all directions, ``d(n) = min_B x.n - max_A x.n`` (a lower bound
for every ``n``), so among coal's normal and every hull face normal of either body, the one
with the largest ``d`` is kept, with ``d`` from the vertices: exact to round-off for a face
against anything (a resting contact), coal's for edge against edge. (For two boxes resting
face on face a nanometre apart coal's normal can be 70 deg off, so the face normals are not
restricted to those near it.) The contact
points are coal's contact patch in that plane (the two support polygons clipped against each
other: 4 corners for a face on a face), all with the gap ``d``.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from .body import RigidBody, rotation_matrix

# Support features within this fraction of the smaller body's radius of the contact plane
# belong to the contact patch (a hull face of a deformed piece is flat only to its strain).
# A face tilted by up to about this angle against another still touches it by its corners:
# an impact's round-off leaves tilts of ~5e-5 rad (a box dropped on a stack, depending on
# the BLAS kernel), and at 1e-6 the patch of such a face was one corner, the box rocked on
# it and the separation of the overlap it left kept the rocking going (tests/
# test_rigid_pairs.py, the boxes set down tilted; docs/fragments.md).
_PATCH_TOLERANCE = 1e-4


@dataclass(eq=False)
class Hull:
    """The collision shape of a body, in its body frame: ``vertices (k, 3)``, the unit outer
    ``normals (f, 3)`` of its faces (none if flat), ``radius`` (of the bounding sphere about
    the centre) and the coal shape (built on first use)."""

    vertices: np.ndarray
    normals: np.ndarray
    radius: float
    coal_shape: object = None

    def shape(self):
        if self.coal_shape is None:
            import coal

            points = coal.StdVec_Vec3s()
            points.extend(list(self.vertices))
            self.coal_shape = coal.Convex.convexHull(points, True, "Qt")
        return self.coal_shape


_HULLS: dict[int, Hull] = {}


def hull(points: np.ndarray) -> Hull:
    """The hull of a body's contact points ``(k, 3)``; kept while the array lives (a body's
    points are shared by all its states, so this runs once per body)."""
    key = id(points)
    found = _HULLS.get(key)
    if found is None:
        from scipy.spatial import ConvexHull, QhullError

        vertices = np.asarray(points, dtype=float)
        try:
            normals = np.unique(np.round(ConvexHull(vertices).equations[:, :3], 14), axis=0)
        except (QhullError, ValueError):
            normals = np.zeros((0, 3))
        radius = float(np.sqrt((vertices * vertices).sum(axis=1).max(initial=0.0)))
        found = _HULLS[key] = Hull(vertices, normals, radius)
        weakref.finalize(points, _HULLS.pop, key, None)
    return found


def candidate_pairs(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``(k, 2)`` index pairs ``i < j`` of the boxes ``[lo, hi]`` (each ``(N, 3)``) that
    overlap (closed boxes): sort and sweep on x, then y and z."""
    n = lo.shape[0]
    if n < 2:
        return np.zeros((0, 2), dtype=np.int64)
    order = np.argsort(lo[:, 0], kind="stable")
    start = lo[order, 0]
    # boxes starting at or before the end of box k (in sweep order), after k
    end = np.searchsorted(start, hi[order, 0], side="right")
    count = np.maximum(end - np.arange(n) - 1, 0)
    first = np.repeat(np.arange(n), count)
    offset = np.arange(first.size) - np.repeat(np.cumsum(count) - count, count)
    second = first + 1 + offset
    i, j = order[first], order[second]
    keep = np.all((lo[i, 1:] <= hi[j, 1:]) & (lo[j, 1:] <= hi[i, 1:]), axis=1)
    pairs = np.sort(np.stack([i[keep], j[keep]], axis=1), axis=1)
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def cross_pairs(lo_a: np.ndarray, hi_a: np.ndarray, lo_b: np.ndarray,
                hi_b: np.ndarray) -> np.ndarray:
    """``(k, 2)`` index pairs ``(i, j)``, sorted, of a box ``[lo_a[i], hi_a[i]]`` of one
    set and a box ``[lo_b[j], hi_b[j]]`` of another (each ``(N, 3)``) that overlap (closed
    boxes): the pairs across the two sets that :func:`candidate_pairs` finds in their union,
    without the pairs within a set (two pieces' tets: each piece's neighbours overlap).
    Sweep on x from each side: the boxes of the other set starting within a box (from its
    own start, inclusive on the first side only, so a tie counts once), then y and z."""
    found = []
    for lo, hi, lo2, hi2, inclusive in ((lo_a, hi_a, lo_b, hi_b, True),
                                        (lo_b, hi_b, lo_a, hi_a, False)):
        order = np.argsort(lo2[:, 0], kind="stable")
        start = lo2[order, 0]
        first = np.searchsorted(start, lo[:, 0], side="left" if inclusive else "right")
        end = np.searchsorted(start, hi[:, 0], side="right")
        count = np.maximum(end - first, 0)
        mine = np.repeat(np.arange(len(lo)), count)
        offset = np.arange(mine.size) - np.repeat(np.cumsum(count) - count, count)
        other = order[np.repeat(first, count) + offset]
        keep = np.all((lo[mine, 1:] <= hi2[other, 1:]) & (lo2[other, 1:] <= hi[mine, 1:]),
                      axis=1)
        pair = (mine[keep], other[keep])
        found.append(np.stack(pair if inclusive else pair[::-1], axis=1))
    pairs = np.concatenate(found).reshape(-1, 2)
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def swept_boxes(bodies, dt: float, gravity, margin: np.ndarray):
    """``(lo, hi)``, each ``(N, 3)``: the bounding spheres of ``bodies`` swept over ``dt`` of
    free flight of their centres and widened by ``margin (N,)``."""
    x0 = np.array([b.position for b in bodies]).reshape(-1, 3)
    v = np.array([b.momentum / b.mass for b in bodies]).reshape(-1, 3)
    x1 = x0 + v * dt + 0.5 * dt * dt * np.asarray(gravity, dtype=float)
    fixed = np.array([np.isinf(b.mass) for b in bodies], dtype=bool)
    x1[fixed] = x0[fixed]
    reach = np.array([hull(b.points).radius for b in bodies]) + margin
    return (np.minimum(x0, x1) - reach[:, None], np.maximum(x0, x1) + reach[:, None])


@dataclass(frozen=True, eq=False)
class Touch:
    """Where two bodies ``a`` and ``b`` touch: the contact ``points (m, 3)`` (world), the
    unit ``normal`` from ``a`` to ``b`` and the signed ``gap`` between them (negative:
    penetration); one ``normal (3,)`` and ``gap`` for a hull's contact patch, one per point,
    ``(m, 3)`` and ``(m,)``, where a body touches by its own tets
    (:mod:`~fem_frac.rigid.nonconvex`)."""

    points: np.ndarray
    normal: np.ndarray
    gap: float | np.ndarray


def _transform(body: RigidBody):
    import coal

    return coal.Transform3s(rotation_matrix(body.orientation), body.position)


def _refine(a: RigidBody, b: RigidBody, normal: np.ndarray) -> tuple[np.ndarray, float, float]:
    """The normal (3,), from ``a`` to ``b``, with the largest support separation among
    ``normal`` and the face normals of either body; that separation; the height of ``a``'s
    support plane along it (module docstring). The separation along any direction is a
    lower bound of the signed distance, so the largest over more directions is never worse:
    every face normal is tried, not only those near coal's normal, which for two boxes
    resting face on face a nanometre apart can be 70 deg off (the gap along it then reads
    -0.17 m for a true -1e-9 m)."""
    ra, rb = rotation_matrix(a.orientation), rotation_matrix(b.orientation)
    ha, hb = hull(a.points), hull(b.points)
    xa = a.position + ha.vertices @ ra.T
    xb = b.position + hb.vertices @ rb.T
    candidates = [normal[None, :], ha.normals @ ra.T, -(hb.normals @ rb.T)]
    n = np.concatenate(candidates)
    separation = (xb @ n.T).min(axis=0) - (xa @ n.T).max(axis=0)
    k = int(np.argmax(separation))
    return n[k], float(separation[k]), float((xa @ n[k]).max())


def touching(a: RigidBody, b: RigidBody, margin: float) -> Touch | None:
    """Where ``a`` and ``b`` touch or come within ``margin`` (length) of each other; ``None``
    if they are farther apart."""
    import coal

    ha, hb = hull(a.points), hull(b.points)
    shape_a, shape_b = ha.shape(), hb.shape()
    ta, tb = _transform(a), _transform(b)
    request = coal.CollisionRequest()
    request.security_margin = float(margin)
    result = coal.CollisionResult()
    coal.collide(shape_a, ta, shape_b, tb, request, result)
    if not result.isCollision():
        return None
    first = result.getContact(0)
    normal, gap, support = _refine(a, b, np.asarray(first.normal, dtype=float))
    if gap > margin:
        return None
    # the mid-plane between the support planes, through coal's contact position
    pos = np.asarray(first.pos, dtype=float)
    pos = pos + (support + 0.5 * gap - pos @ normal) * normal
    refined = coal.CollisionResult()
    refined.addContact(coal.Contact(shape_a, shape_b, -1, -1, pos, normal, gap))
    patch_request = coal.ContactPatchRequest()
    patch_request.setPatchTolerance(_PATCH_TOLERANCE * min(ha.radius, hb.radius))
    patches = coal.ContactPatchResult(patch_request)
    coal.computeContactPatch(shape_a, ta, shape_b, tb, refined, patch_request, patches)
    points = [pos]
    if patches.numContactPatches() > 0:
        patch = patches.getContactPatch(0)
        if patch.size() > 0:
            points = [np.asarray(patch.getPoint(i), dtype=float) for i in range(patch.size())]
    return Touch(np.array(points), normal, gap)
