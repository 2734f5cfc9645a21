"""The ground planes as a picture: ``<name>_ground.vtu``, one quad per plane, written once;
the fixed obstacles as a series: ``<name>_obstacles.pvd`` (or ``.vtkhdf``,
:class:`ObstacleSeries`).

The planes rigid fragments rest on (``fragments.ground``, the world's obstacles) are
infinite and fixed; this file shows them in ParaView as squares under the scene. Fixed
planes do not move, so one static ``.vtu`` is enough: ParaView shows a file without time
at every time of the series opened beside it (no ``.pvd`` needed).

Each plane's square (a VTK quad, counter-clockwise about the plane's normal, so its
right-hand normal is the plane's) is centred at the projection of the centre of the
bounding box of the mesh at t = 0 onto the plane, with edges along the world axis least
aligned with the normal (projected) and normal x that axis. Its half side is

    s = 1.5 D + 3 h

``D`` the diagonal of that bounding box (the side is 3 D, and the square reaches at least
D beyond the projection of every point of the mesh), ``h`` the height of the mesh's highest
point above the plane (0 when none is above it): a fragment thrown from there at the speed
it would gain falling that height, ``v = sqrt(2 g h)``, lands at most
``(v / g) sqrt(v^2 + 2 g h) = 2 sqrt(2) h`` away, whatever its direction and whatever g.
Faster fragments, or ones that slide far, can leave the square; the plane itself has no
edge. A mesh reduced to a point with nothing above the plane gets a unit half side.

Cell data: ``obstacle_id`` (the plane's index among the obstacles), ``restitution``,
``friction`` and ``normal``. The planes are taken as anything with ``point``, ``normal``
(unit), ``restitution`` and ``friction`` (:class:`fem_frac.rigid.contact.Plane`: this
layer does not import ``rigid``).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .directory import Manifest, create_plain
from .series import series_writer
from .vtu import write_vtu

# The half side: this many bounding-box diagonals, plus this many heights above the plane.
DIAGONALS = 1.5
HEIGHTS = 3.0


def ground_name(name: str) -> str:
    """The file name of the ground planes of the run ``name``."""
    return f"{name}_ground.vtu"


def in_plane_axes(normal) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors ``t1, t2`` with ``t1 x t2 = normal``: ``t1`` the world axis least
    aligned with ``normal``, projected onto the plane (x for a horizontal ground)."""
    n = np.asarray(normal, dtype=float)
    axis = np.eye(3)[int(np.argmin(np.abs(n)))]
    t1 = axis - (axis @ n) * n
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(n, t1)


def half_side(plane, points: np.ndarray) -> float:
    """The half side of ``plane``'s square for the mesh ``points (n, 3)`` (module docstring)."""
    x = np.asarray(points, dtype=float).reshape(-1, 3)
    diagonal = float(np.linalg.norm(np.ptp(x, axis=0))) if len(x) else 0.0
    above = (x - plane.point) @ plane.normal if len(x) else np.zeros(1)
    s = DIAGONALS * diagonal + HEIGHTS * max(float(above.max()), 0.0)
    return s if s > 0.0 else 1.0


def ground_quads(planes: Sequence, points: np.ndarray) -> np.ndarray:
    """``(k, 4, 3)``: the corners of each plane's square, counter-clockwise about its
    normal, centred at the projection of the centre of the bounding box of ``points``."""
    x = np.asarray(points, dtype=float).reshape(-1, 3)
    centre = 0.5 * (x.min(axis=0) + x.max(axis=0)) if len(x) else np.zeros(3)
    signs = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    out = np.empty((len(planes), 4, 3))
    for k, plane in enumerate(planes):
        p, n = np.asarray(plane.point, dtype=float), np.asarray(plane.normal, dtype=float)
        foot = centre - ((centre - p) @ n) * n
        t1, t2 = in_plane_axes(n)
        s = half_side(plane, x)
        out[k] = foot + s * (signs[:, :1] * t1 + signs[:, 1:] * t2)
    return out


def write_ground(target: Manifest | Path | str, name: str, planes: Sequence,
                 points: np.ndarray) -> Path | None:
    """Write ``<name>_ground.vtu`` (every plane of ``planes`` as a square sized from the
    mesh ``points (n, 3)`` at t = 0) into the directory of ``target`` (a
    :class:`~fem_frac.writers.directory.Manifest`, or a directory whose manifest records the
    file); its path, or ``None`` (nothing written) without planes."""
    if not planes:
        return None
    manifest = target if isinstance(target, Manifest) else Manifest(Path(target))
    filename = ground_name(name)
    scratch = f"{filename}.tmp"
    path = manifest.add(scratch, filename)
    corners = ground_quads(planes, points)
    k = len(planes)
    create_plain(manifest.directory / scratch)
    write_vtu(manifest.directory / scratch, corners.reshape(-1, 3),
              ("quad", np.arange(4 * k, dtype=np.int64).reshape(k, 4)), {},
              {"obstacle_id": np.arange(k, dtype=np.int32),
               "restitution": np.array([float(g.restitution) for g in planes]),
               "friction": np.array([float(g.friction) for g in planes]),
               "normal": np.array([np.asarray(g.normal, dtype=float) for g in planes])},
              compression="zlib")
    os.replace(manifest.directory / scratch, path)
    return path


class ObstacleSeries:
    """``<name>_obstacles.pvd``: the fixed obstacles and the planes of the case's
    ``obstacles`` at every output step, a triangle surface at world positions.

    They do not move, so every frame holds the same surface (``points (n, 3)``,
    ``triangles (t, 3)``, ``cell_data``: ``obstacle_id`` and the other fields of each
    triangle) with a zero point field ``displacement`` (Warp By Vector leaves it in
    place), at the times of the main series: ParaView's time steps and the
    ``<name>_view.py`` script treat it like the other series. An observer of the output
    stage: called with every committed step ``(n, world)``, it writes when ``due(n)``.
    ``format``: ``output.format`` (with ``vtkhdf``, ``<name>_obstacles.vtkhdf``, whose steps
    share the one surface)."""

    def __init__(self, manifest: Manifest, name: str, due, points: np.ndarray,
                 triangles: np.ndarray, cell_data: dict, format: str = "vtu"):
        self.series = series_writer(manifest.directory, obstacles_name(name),
                                    manifest=manifest, format=format)
        self.due, self.points, self.triangles = due, np.asarray(points, dtype=float), \
            np.asarray(triangles, dtype=np.int64)
        self.cell_data = dict(cell_data)

    def __call__(self, n: int, world) -> None:
        if self.due(n):
            self.series.write(world.t, self.points, ("triangle", self.triangles),
                              {"displacement": np.zeros_like(self.points)}, self.cell_data)


def obstacles_name(name: str) -> str:
    """The series name (``.pvd`` without suffix) of the fixed obstacles of the run ``name``."""
    return f"{name}_obstacles"
