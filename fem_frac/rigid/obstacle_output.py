"""Obstacles in the output: moving ones as rigid bodies of the main series, fixed ones and
planes as the surface of ``<name>_obstacles.pvd``; their one-line descriptions.

A moving obstacle is a rigid body of the world (:func:`rigid_bodies`), drawn like a fragment:
cells in the main series, after the finite elements, moved by ``displacement``, ``rigid`` = 1
and ``fragment_id`` its place among the rigid bodies (moving obstacles come first). Its cells
are the tets from its centre of mass to its surface triangles (straight P2 tets, mid nodes on
the edges, when the mesh is quadratic): they draw its surface; for a mesh that is not
star-shaped about its centre some of them are inverted, which changes nothing drawn.

The fixed obstacles and the planes (:func:`fixed_surface`) never move: one triangle surface,
the same at every output step, at world positions, with cell fields ``obstacle_id``,
``restitution``, ``friction`` and ``normal`` (outward; a plane's normal). A plane is drawn
as a square of two triangles sized as the ground planes (:mod:`fem_frac.writers.ground`),
from the mesh and every obstacle's surface at t = 0.
"""

from __future__ import annotations

import numpy as np

from ..writers.ground import ground_quads
from .body import rotation_matrix
from .fragment import RigidFragment
from .obstacles import TET10_EDGES, Obstacle


def drawing(obstacle: Obstacle, order: int) -> tuple[np.ndarray, np.ndarray]:
    """``(nodes (k, 3), cells (e, 4 | 10))`` in the body frame: the centre (the body
    frame's origin, last of the vertices) joined to every surface triangle; ``order`` 2
    adds the edges' mid nodes (VTK tetra10 order)."""
    shape = obstacle.shape
    n = len(shape.vertices)
    nodes = np.vstack([shape.vertices, np.zeros((1, 3))])
    t = shape.triangles
    tets = np.column_stack([t[:, 0], t[:, 2], t[:, 1], np.full(len(t), n)])
    if order == 1:
        return nodes, tets
    edges = np.sort(tets[:, TET10_EDGES].reshape(-1, 2), axis=1)
    unique, inverse = np.unique(edges, axis=0, return_inverse=True)
    mid = 0.5 * (nodes[unique[:, 0]] + nodes[unique[:, 1]])
    cells = np.hstack([tets, inverse.reshape(len(tets), 6) + len(nodes)])
    return np.vstack([nodes, mid]), cells


def rigid_bodies(obstacles, order: int) -> tuple[RigidFragment, ...]:
    """The moving obstacles as rigid bodies of the world, in the order of their
    ``rigid_index`` (the first of ``World.rigid``), drawn for a mesh of element ``order``
    (:func:`drawing`), born at t = 0."""
    out = []
    for o in sorted((o for o in obstacles if o.body is not None and not o.fixed),
                    key=lambda o: o.rigid_index):
        coords, cells = drawing(o, order)
        nodes = o.body.position + coords @ rotation_matrix(o.body.orientation).T
        out.append(RigidFragment(o.body, nodes, cells, coords, o.rigid_index, 0.0))
    return tuple(out)


def fixed_surface(obstacles, scene_points) -> tuple | None:
    """``(points (n, 3), triangles (t, 3), cell_data)`` of the fixed obstacles and the
    planes (module docstring), ``None`` when there is none; ``scene_points (m, 3)``: the
    mesh's points at t = 0, which with every obstacle's surface size the planes' squares."""
    fixed = [o for o in obstacles if o.fixed]
    if not fixed:
        return None
    surfaces = {o.obstacle_id: world_surface(o) for o in obstacles if o.body is not None}
    scene = np.vstack([np.asarray(scene_points, dtype=float).reshape(-1, 3)]
                      + [x for x, _ in surfaces.values()])
    plane_list = [o.plane for o in fixed if o.plane is not None]
    squares = iter(ground_quads(plane_list, scene))
    points, triangles, owner, normals = [], [], [], []
    offset = 0
    for o in fixed:
        if o.plane is not None:
            x, t = next(squares), np.array([[0, 1, 2], [0, 2, 3]])
            normal = np.tile(o.plane.normal, (2, 1))
        else:
            x, t = surfaces[o.obstacle_id]
            corner = x[t]
            normal = np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0])
            normal /= np.linalg.norm(normal, axis=1)[:, None]
        points.append(x)
        triangles.append(t + offset)
        owner.append(np.full(len(t), fixed.index(o)))
        normals.append(normal)
        offset += len(x)
    owner = np.concatenate(owner)
    cell_data = {
        "obstacle_id": np.array([o.obstacle_id for o in fixed], dtype=np.int32)[owner],
        "restitution": np.array([float(o.restitution) for o in fixed])[owner],
        "friction": np.array([float(o.friction) for o in fixed])[owner],
        "normal": np.concatenate(normals),
    }
    return np.vstack(points), np.concatenate(triangles), cell_data


def world_surface(obstacle: Obstacle) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices (k, 3), triangles (t, 3))`` of a body obstacle at its initial pose."""
    body = obstacle.body
    x = body.position + obstacle.shape.vertices @ rotation_matrix(body.orientation).T
    return x, obstacle.shape.triangles


def _vector(v) -> str:
    return "[" + ", ".join(f"{float(c):.6g}" for c in v) + "]"


def describe(obstacle: Obstacle) -> str:
    """One line for ``fem-frac check``: kind, size, place, mass and initial motion,
    contact coefficients."""
    o = obstacle
    coefficients = f"restitution {o.restitution:g}, friction {o.friction:g}"
    if o.plane is not None:
        return (f"[{o.obstacle_id}] plane through {_vector(o.plane.point)}, normal "
                f"{_vector(o.plane.normal)}; {coefficients}")
    s, body = o.shape, o.body
    size = {"sphere": lambda: f"radius {s.radius:.6g}",
            "box": lambda: f"size {_vector(s.size)}",
            "cylinder": lambda: f"radius {s.radius:.6g}, height {s.height:.6g}",
            "mesh": lambda: f"{o.source}: {len(s.triangles):,} triangles, extent "
                            f"{_vector(np.ptp(s.vertices, axis=0))} (principal axes)"}[o.kind]()
    text = f"[{o.obstacle_id}] {o.kind}, {size}, centre {_vector(body.position)}, volume " \
           f"{o.volume:.6g}; "
    if o.fixed:
        return text + f"fixed; {coefficients}"
    r = rotation_matrix(body.orientation)
    spin = r @ ((r.T @ body.angular_momentum) / body.inertia)
    return text + (f"mass {body.mass:.6g} (density {o.density:.6g}), inertia "
                   f"{_vector(body.inertia)}, velocity {_vector(body.momentum / body.mass)}, "
                   f"angular velocity {_vector(spin)}; rigid body {o.rigid_index}; "
                   f"{coefficients}")
