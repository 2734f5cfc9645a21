"""Obstacles (the case's ``obstacles``) as rigid bodies: mass properties, contact geometry,
the rigid bodies of the world, the picture of the fixed ones.

Every body obstacle becomes an :class:`Obstacle` holding a :class:`~.body.RigidBody` in its
principal frame (origin at the centre of mass, axes along the principal axes of inertia), a
:class:`Shape` (the exact primitive and a triangulated surface, in that frame) and the
coefficients of its contacts. Planes stay :class:`~.contact.Plane` (the ground planes'
kind).

**Mass properties**, exact (density rho, volume V, mass m = rho V):

- sphere of radius r: ``V = 4/3 pi r^3``, ``I = 2/5 m r^2`` about every axis;
- box of edges a, b, c: ``V = a b c``, ``I = m (b^2 + c^2) / 12``, ``m (a^2 + c^2) / 12``,
  ``m (a^2 + b^2) / 12`` about its edges' directions;
- cylinder of radius r and height h: ``V = pi r^2 h``, ``I = m r^2 / 2`` about its axis
  (body z), ``m (3 r^2 + h^2) / 12`` about any diameter through the centre;
- closed triangle surface: by the divergence theorem, as the signed tets from a reference
  point (the mean of its vertices) to every triangle, summed in closed form by
  :func:`~.mass.mass_properties` (each tet's density carries the sign of its volume, so
  the surface need not be star-shaped; exact to round-off for any closed, consistently
  oriented surface).

**Contact geometry.** ``body.points``: the vertices of a convex hull in the body frame
(what :mod:`.contact` uses against planes, and what a narrow phase on convex hulls takes):
a box's 8 corners and a mesh's hull vertices are exact; a sphere is an icosphere of
``SPHERE_SUBDIVISIONS`` subdivisions (642 vertices on the sphere, its faces at most
``SPHERE_GAP`` = 4.5e-3 r inside it) and a cylinder a prism of ``CYLINDER_SEGMENTS`` sides
(its side faces ``CYLINDER_GAP`` = 2.1e-3 r inside it): inscribed, so a contact through the
hull is late by at most that gap. ``shape`` describes the exact primitive for a narrow
phase that has one (coal's ``Sphere(radius)``, ``Box(*size)``, ``Cylinder(radius, height)``
along body z, all centred at the body's origin): ``Shape.exact``.

**Fixed obstacles** have infinite mass: ``body.mass`` and ``body.inertia`` are ``inf`` and
their momenta zero, so ``1 / mass``, :func:`~.body.inverse_inertia_world`,
:func:`~.body.velocity` and :func:`~.body.point_velocities` are zero
(:attr:`Obstacle.inverse_mass`, :attr:`Obstacle.inverse_inertia`); they are never flown.
**Moving obstacles** are rigid bodies of the world from t = 0 (:func:`rigid_bodies`: the
first of ``World.rigid``, ``rigid_index`` their place), flown like fragments under
gravity and drawn in the series like them.
"""

from __future__ import annotations

import contextlib
import io
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import CaseError
from .body import RigidBody, fixed_body, make_body, quaternion_from_matrix, rotation_matrix
from .contact import Plane
from .fragment import contact_points
from .mass import mass_properties

SPHERE_SUBDIVISIONS = 3
SPHERE_GAP = 4.53e-3  # 1 - min over faces of the distance of the face plane, unit sphere
CYLINDER_SEGMENTS = 48
CYLINDER_GAP = 2.15e-3  # 1 - cos(pi / CYLINDER_SEGMENTS)
# An obstacle mesh file larger than this is refused before it is read.
MAX_MESH_BYTES = 100_000_000
# A closed surface enclosing less than this fraction of its bounding box's diagonal cubed
# encloses no volume.
FLAT = 1e-12
# VTK's tetra10: corners, then the mid nodes of these edges.
TET10_EDGES = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]])


@dataclass(frozen=True, eq=False)
class Shape:
    """The geometry of an obstacle in its body frame.

    kind: ``sphere``, ``box``, ``cylinder`` or ``mesh``; ``vertices (k, 3)`` and
    ``triangles (t, 3)``: its surface, counter-clockwise seen from outside (the
    tessellation of a sphere or a cylinder, a box's 12 triangles, a mesh's own); the exact
    primitive: ``radius`` (sphere, cylinder), ``size (3,)`` (box edges along body x, y, z),
    ``height`` (cylinder, along body z)."""

    kind: str
    vertices: np.ndarray
    triangles: np.ndarray
    radius: float = 0.0
    size: np.ndarray | None = None
    height: float = 0.0

    @property
    def exact(self) -> bool:
        """Whether a narrow phase can use the exact primitive (not the hull)."""
        return self.kind in ("sphere", "box", "cylinder")


@dataclass(frozen=True, eq=False)
class Obstacle:
    """One entry of ``obstacles``: ``obstacle_id`` its index there. A body has ``body``
    and ``shape`` (a plane has ``plane``); ``rigid_index``: its place in ``World.rigid``
    when it moves; ``volume`` and ``density`` (``None`` when fixed)."""

    obstacle_id: int
    kind: str
    fixed: bool
    restitution: float
    friction: float
    body: RigidBody | None = None
    shape: Shape | None = None
    volume: float = 0.0
    density: float | None = None
    plane: Plane | None = None
    rigid_index: int | None = None
    source: str = ""

    @property
    def inverse_mass(self) -> float:
        return 0.0 if self.fixed else 1.0 / self.body.mass

    @property
    def inverse_inertia(self) -> np.ndarray:
        """(3,) inverse principal moments (body frame); zero when fixed."""
        return np.zeros(3) if self.fixed else 1.0 / self.body.inertia


# --- surfaces --------------------------------------------------------------------------


def outward(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The triangles of a surface star-shaped about the origin, each turned to face away
    from it."""
    x = vertices[triangles]
    normal = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    inward = np.einsum("ij,ij->i", normal, x.sum(axis=1)) < 0.0
    return np.where(inward[:, None], triangles[:, [0, 2, 1]], triangles)


def icosphere(subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    """The unit icosphere: the icosahedron's faces split in four ``subdivisions`` times,
    new vertices pushed onto the sphere; ``(vertices, triangles)``."""
    t = (1.0 + np.sqrt(5.0)) / 2.0
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]])
    v = v / np.linalg.norm(v, axis=1)[:, None]
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9],
                  [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2],
                  [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
                  [8, 6, 7], [9, 8, 1]])
    for _ in range(subdivisions):
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        unique, inverse = np.unique(edges, axis=0, return_inverse=True)
        mid = v[unique[:, 0]] + v[unique[:, 1]]
        m = inverse.reshape(3, len(f)) + len(v)  # mid nodes of edges 01, 12, 20
        a, b, c = f.T
        f = np.concatenate([np.stack(s, axis=1) for s in
                            ((a, m[0], m[2]), (b, m[1], m[0]), (c, m[2], m[1]), m)])
        v = np.vstack([v, mid / np.linalg.norm(mid, axis=1)[:, None]])
    return v, outward(v, f)


def box_surface(size) -> tuple[np.ndarray, np.ndarray]:
    """The 8 corners and 12 triangles of a box of edges ``size`` about the origin."""
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)],
                       dtype=float) * (0.5 * np.asarray(size, dtype=float))
    quads = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4],
                      [1, 5, 7, 3]])
    triangles = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return corners, outward(corners, triangles)


def cylinder_surface(radius: float, height: float,
                     segments: int = CYLINDER_SEGMENTS) -> tuple[np.ndarray, np.ndarray]:
    """A prism of ``segments`` sides inscribed in the cylinder about the origin, axis z:
    the bottom ring, then the top ring; sides and fanned caps."""
    angle = 2.0 * np.pi * np.arange(segments) / segments
    ring = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    vertices = np.vstack([np.column_stack([ring, np.full(segments, -0.5 * height)]),
                          np.column_stack([ring, np.full(segments, 0.5 * height)])])
    k = np.arange(segments)
    n = (k + 1) % segments
    fan = np.arange(1, segments - 1)
    triangles = np.concatenate([
        np.column_stack([k, n, n + segments]), np.column_stack([k, n + segments, k + segments]),
        np.column_stack([np.zeros_like(fan), fan + 1, fan]),
        np.column_stack([np.full_like(fan, segments), fan + segments, fan + 1 + segments])])
    return vertices, outward(vertices, triangles)


# --- a closed surface from a file -------------------------------------------------------


def read_surface(path: Path, key: tuple) -> tuple[np.ndarray, np.ndarray]:
    """``(points, triangles)`` of the closed surface in ``path``, duplicated points merged,
    the triangles turned outward; any problem is a :class:`CaseError` at ``key``."""
    if path.suffix.lower() == ".geo":
        raise CaseError(key, f"{path}: a .geo file is not read for an obstacle (gmsh would "
                        "run it): give a surface mesh file (.stl, .obj, .ply, .vtu, .msh, ...)")
    if not path.is_file():
        raise CaseError(key, f"no such obstacle mesh file: {path}")
    if path.stat().st_size > MAX_MESH_BYTES:
        raise CaseError(key, f"{path}: larger than {MAX_MESH_BYTES / 1e6:g} MB: too large "
                        "for an obstacle's surface")
    raw = _read(path, key)
    try:
        points = np.asarray(raw.points, dtype=np.float64)
    except (TypeError, ValueError):
        raise CaseError(key, f"{path}: point coordinates are not numbers") from None
    if points.ndim != 2 or points.shape[1] != 3:
        raise CaseError(key, f"{path}: points are not 3-dimensional")
    triangles = _triangles(path, key, raw.cells, len(points))
    used, local = np.unique(triangles, return_inverse=True)
    if not np.isfinite(points[used]).all() or np.abs(points[used]).max() > 1e100:
        raise CaseError(key, f"{path}: coordinates that are not finite or too large")
    # the same point written once per triangle (STL): merged when the coordinates are equal
    merged, inverse = np.unique(points[used], axis=0, return_inverse=True)
    triangles = inverse.ravel()[local.reshape(triangles.shape)]
    return merged, _closed(path, key, merged, triangles)


def _read(path: Path, key: tuple):
    """``meshio.read`` with its chatter captured; any failure is a located error."""
    import meshio

    chatter = io.StringIO()
    try:
        # meshio's format probes overflow on text files (warnings, not errors): silenced
        with contextlib.redirect_stdout(chatter), contextlib.redirect_stderr(chatter), \
                warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            return meshio.read(path, file_format="gmsh" if path.suffix.lower() == ".msh"
                               else None)
    except (Exception, SystemExit) as exc:  # ReadError, KeyError, ValueError, SystemExit...
        text = chatter.getvalue() if isinstance(exc, SystemExit) else str(exc)
        reason = " ".join(text.replace("Error:", " ").split()) or type(exc).__name__
        raise CaseError(key, f"{path}: cannot read the obstacle mesh: {reason}") from None


def _triangles(path: Path, key: tuple, blocks, n_points: int) -> np.ndarray:
    """The triangles of the file's triangle, triangle6 (corners) and quad blocks."""
    parts = []
    for b in blocks:
        data = np.asarray(b.data)
        if b.type not in ("triangle", "triangle6", "quad"):
            continue
        if not np.issubdtype(data.dtype, np.integer) or data.ndim != 2:
            raise CaseError(key, f"{path}: {b.type} node indices are not integers")
        if np.any((data < 0) | (data >= n_points)):
            raise CaseError(key, f"{path}: {b.type} cells name nodes outside 0..{n_points - 1}")
        corners = data[:, :4].astype(np.int64) if b.type == "quad" else \
            data[:, :3].astype(np.int64)
        parts.append(np.concatenate([corners[:, [0, 1, 2]], corners[:, [0, 2, 3]]])
                     if b.type == "quad" else corners)
    if not parts:
        kinds = ", ".join(sorted({b.type for b in blocks})) or "none"
        raise CaseError(key, f"{path}: no triangles (cell types: {kinds}): an obstacle is "
                        "a closed triangle surface")
    return np.concatenate(parts)


def _closed(path: Path, key: tuple, points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The triangles, turned outward, of a closed and consistently oriented surface: every
    edge in exactly two triangles, run one way in one and the other way in the other."""
    if np.any((triangles[:, 0] == triangles[:, 1]) | (triangles[:, 1] == triangles[:, 2])
              | (triangles[:, 2] == triangles[:, 0])):
        raise CaseError(key, f"{path}: a triangle has a repeated corner (a degenerate "
                        "triangle): not a closed surface")
    directed = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]],
                               triangles[:, [2, 0]]])
    edges, count = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    if np.any(count != 2):
        bad = edges[count != 2][0]
        what = "an open surface" if np.any(count == 1) else "not a manifold surface"
        raise CaseError(key, f"{path}: {what}: {np.count_nonzero(count != 2)} edges "
                        f"belong to {'one triangle' if np.any(count == 1) else 'more than two'}"
                        f" (first: points {bad[0]} and {bad[1]}); an obstacle mesh must be "
                        "a closed surface")
    if len(np.unique(directed, axis=0)) != len(directed):
        raise CaseError(key, f"{path}: the triangles are not consistently oriented (an edge "
                        "runs the same way in both its triangles)")
    volume = float(np.einsum("ij,ij->i", points[triangles[:, 0]] - points.mean(axis=0),
                             np.cross(points[triangles[:, 1]] - points[triangles[:, 0]],
                                      points[triangles[:, 2]] - points[triangles[:, 0]])).sum())
    diagonal = float(np.linalg.norm(np.ptp(points, axis=0)))
    if not abs(volume) / 6.0 > FLAT * diagonal**3:
        raise CaseError(key, f"{path}: the surface encloses no volume")
    return triangles if volume > 0.0 else triangles[:, [0, 2, 1]]


def surface_mass_properties(points: np.ndarray, triangles: np.ndarray, density=1.0):
    """Exact mass properties (:class:`~.mass.MassProperties`) of the solid a closed,
    outward-oriented triangle surface bounds: the signed tets from the vertices' mean to
    every triangle (divergence theorem), in closed form."""
    reference = points.mean(axis=0)
    x = np.vstack([points - reference, np.zeros((1, 3))])
    tets = np.column_stack([np.full(len(triangles), len(points)), triangles])
    d = x[tets[:, 1:]] - x[tets[:, :1]]
    sign = np.sign(np.einsum("ei,ei->e", d[:, 0], np.cross(d[:, 1], d[:, 2])))
    mp = mass_properties(x, tets, density * sign)
    return type(mp)(mp.mass, mp.center + reference, mp.inertia, mp.moments, mp.axes)


# --- building the obstacles of a case ----------------------------------------------------


def orientation_matrix(orientation) -> np.ndarray:
    """(3, 3) rotation of an ``Orientation`` section (identity for ``None``)."""
    if orientation is None:
        return np.eye(3)
    if orientation.quaternion is not None:
        q = np.asarray(orientation.quaternion, dtype=float)
    else:
        n = np.asarray(orientation.axis, dtype=float)
        half = 0.5 * np.radians(orientation.angle)
        q = np.concatenate([[np.cos(half)], np.sin(half) * n / np.linalg.norm(n)])
    return rotation_matrix(q / np.linalg.norm(q))


def axis_frame(axis) -> np.ndarray:
    """(3, 3) rotation whose third column is the unit ``axis`` (the first: the world axis
    least aligned with it, projected)."""
    z = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    x = np.eye(3)[int(np.argmin(np.abs(z)))]
    x = x - (x @ z) * z
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def _geometry(c, case_dir: Path, key: tuple):
    """``(shape, volume, centre, rotation, inertia per unit mass (3,))`` of a body
    obstacle's section ``c`` (the module's closed forms)."""
    if c.type == "sphere":
        r = np.float64(c.radius)
        unit, triangles = icosphere(SPHERE_SUBDIVISIONS)
        return (Shape("sphere", r * unit, triangles, radius=r), 4.0 / 3.0 * np.pi * r**3,
                np.asarray(c.center, dtype=float), np.eye(3), np.full(3, 0.4 * r * r))
    if c.type == "box":
        a, b, h = size = np.asarray(c.size, dtype=float)
        vertices, triangles = box_surface(size)
        moments = np.array([b * b + h * h, a * a + h * h, a * a + b * b]) / 12.0
        return (Shape("box", vertices, triangles, size=size), float(a * b * h),
                np.asarray(c.center, dtype=float), orientation_matrix(c.orientation),
                moments)
    if c.type == "cylinder":
        r, h = np.float64(c.radius), np.float64(c.height)
        vertices, triangles = cylinder_surface(r, h)
        across = (3.0 * r * r + h * h) / 12.0
        return (Shape("cylinder", vertices, triangles, radius=r, height=h),
                np.pi * r * r * h, np.asarray(c.center, dtype=float), axis_frame(c.axis),
                np.array([across, across, 0.5 * r * r]))
    path = Path(c.file).expanduser()
    path = path if path.is_absolute() else case_dir / path
    points, triangles = read_surface(path, (*key, "file"))
    mp = surface_mass_properties(points, triangles)
    vertices = (points - mp.center) @ mp.axes
    return (Shape("mesh", vertices, triangles), mp.mass, mp.center, mp.axes,
            mp.moments / mp.mass)


def _size_key(c) -> str:
    return {"sphere": "radius", "box": "size", "cylinder": "radius", "mesh": "file"}[c.type]


def body_obstacle(c, obstacle_id: int, case_dir: Path, rigid_index: int | None) -> Obstacle:
    """The :class:`Obstacle` of a body section ``c`` (``obstacles[obstacle_id]``)."""
    key = ("obstacles", obstacle_id)
    with np.errstate(over="ignore", invalid="ignore"):  # out of range: refused below
        shape, volume, centre, rotation, per_mass = _geometry(c, case_dir, key)
    q = quaternion_from_matrix(rotation)
    hull = shape.vertices if shape.exact else contact_points(shape.vertices)
    if c.fixed:
        body = fixed_body(hull, centre, q)
        return Obstacle(obstacle_id, c.type, True, c.restitution, c.friction, body, shape,
                        volume, source=getattr(c, "file", ""))
    with np.errstate(over="ignore", invalid="ignore"):
        mass = c.mass if c.mass is not None else c.density * volume
        moments = mass * per_mass
    if not (np.isfinite(volume) and volume > 0 and np.isfinite(mass) and mass > 0
            and np.all(np.isfinite(moments)) and np.all(moments > 0)):
        raise CaseError((*key, _size_key(c)), f"volume {volume:g}, mass {mass:g} and moments "
                        f"of inertia {moments.tolist()} must be finite and positive: out of "
                        "range (is the unit right?)")
    body = make_body(mass, moments, hull, centre, q, c.velocity, c.angular_velocity)
    return Obstacle(obstacle_id, c.type, False, c.restitution, c.friction, body, shape,
                    volume, mass / volume, rigid_index=rigid_index,
                    source=getattr(c, "file", ""))


def build_obstacles(configs, case_dir: Path, rigid_stage: bool) -> tuple[Obstacle, ...]:
    """The obstacles of the ``obstacles`` sections ``configs`` (paths relative to
    ``case_dir``); ``rigid_stage``: whether the case has the stage that moves rigid bodies
    (a ``fragments`` section), without which obstacles are refused."""
    if configs and not rigid_stage:
        raise CaseError(("obstacles",), "obstacles need a 'fragments' section: its stage "
                        "moves rigid bodies and keeps them off planes")
    out, moving = [], 0
    for i, c in enumerate(configs):
        if c.type == "plane":
            n = np.asarray(c.normal, dtype=float)
            plane = Plane(np.asarray(c.point, dtype=float), n / np.linalg.norm(n),
                          c.restitution, c.friction)
            out.append(Obstacle(i, "plane", True, c.restitution, c.friction, plane=plane))
            continue
        out.append(body_obstacle(c, i, case_dir, None if c.fixed else moving))
        moving += not c.fixed
    return tuple(out)


def bodies(obstacles) -> tuple[Obstacle, ...]:
    """The obstacles that are bodies (not planes), fixed and moving."""
    return tuple(o for o in obstacles if o.plane is None)


def planes(obstacles) -> tuple[Plane, ...]:
    """The planes among the obstacles (the ground planes' kind)."""
    return tuple(o.plane for o in obstacles if o.plane is not None)
