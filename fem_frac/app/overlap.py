"""How deep the bodies of a run's output lie in each other: ``fem-frac overlap OUT_DIR``.

Every frame of the run's series holds its bodies as cells with a ``fragment_id``: the
pieces of the finite-element part and the rigid fragments (``rigid/output.py``). A frame
is read as the solver wrote it, every point moved by its ``displacement``; the ground
planes come from ``<name>_ground.vtu``.

The fixed obstacles of ``<name>_obstacles.pvd`` count too: a closed surface as a solid
(points of a body inside it, by ``select_interior_points``, and its points inside a body),
an open square as a plane.

The measure, for each pair of bodies whose bounding boxes overlap: the largest distance
from a point of one body's surface that lies inside the other body (in one of its cells)
to that other body's surface, both ways; for a plane, the largest depth of a body's point
below it. This is the depth of the deepest vertex: two bodies whose edges cross with no
vertex inside the other are not seen (a lower bound of the true depth, exact when a corner
goes in first). Bodies that share faces across a crack touch with depth zero (their
common points lie on both surfaces).

The depth is judged against the smaller body's size, the side of the cube of its volume
``V^(1/3)``: overlap below 1 % of it is contact resolved to that tolerance.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# Overlap allowed, as a fraction of the smaller body's size V^(1/3).
TOLERANCE = 0.01
# pyvista's filter for the boundary faces of a volume mesh
SURFACE = "dataset_surface"


class OverlapError(Exception):
    """The directory holds no series to measure."""


@dataclass(frozen=True)
class Overlap:
    """The deepest overlap of one frame: ``depth`` (length), the ``pair`` of bodies
    (fragment ids; ``ground k`` for plane k) and ``fraction`` of the smaller body's size."""

    time: float
    depth: float
    pair: tuple[str, str]
    fraction: float


def _frames(pvd: Path) -> list[tuple[float, Path]]:
    text = pvd.read_text()
    return [(float(t), pvd.parent / f) for t, f in
            re.findall(r'<DataSet[^>]*timestep="([^"]+)"[^>]*file="([^"]+)"', text)]


def series_files(directory: Path) -> tuple[list[tuple[float, Path]], Path | None,
                                           Path | None]:
    """``([(time, .vtu)], ground .vtu or None, fixed obstacles .vtu or None)`` of the run in
    ``directory`` (the fixed obstacles never move: their first frame)."""
    directory = Path(directory)
    pvd = ground = fixed = None
    summary = directory / "summary.json"
    if summary.is_file():
        output = json.loads(summary.read_text()).get("output") or {}
        pvd = Path(output["pvd"]) if "pvd" in output else None
        ground = Path(output["ground"]) if "ground" in output else None
        fixed = Path(output["obstacles"]) if "obstacles" in output else None
    if pvd is None or not pvd.is_file():
        found = [p for p in sorted(directory.glob("*.pvd"))
                 if not p.stem.endswith(("_crack", "_obstacles"))]
        if not found:
            hdf = sorted(directory.glob("*.vtkhdf"))
            if hdf:  # output.format: vtkhdf
                raise OverlapError(f"{directory}: no .pvd series, only {hdf[0].name}: overlap "
                                   "reads the vtu format; run the case with --set "
                                   "output.format=vtu")
            raise OverlapError(f"{directory}: no .pvd series")
        pvd = found[0]
        grounds = sorted(directory.glob(f"{pvd.stem}_ground.vtu"))
        ground = grounds[0] if grounds else None
        named = directory / f"{pvd.stem}_obstacles.pvd"
        fixed = named if named.is_file() else None
    frames = _frames(pvd)
    if not frames:
        raise OverlapError(f"{pvd}: no frames")
    fixed_frames = _frames(fixed) if fixed is not None and fixed.is_file() else []
    return (frames, ground if ground is not None and ground.is_file() else None,
            fixed_frames[0][1] if fixed_frames else None)


def fixed_obstacles(path: Path | None) -> tuple[list, list[tuple[np.ndarray, np.ndarray]]]:
    """``([(id, closed surface)], [(point, normal)])`` of the fixed obstacles' file: the
    closed surfaces of solid obstacles, and the planes (drawn as open squares)."""
    if path is None:
        return [], []
    import pyvista as pv

    grid = pv.read(path)
    ids = np.asarray(grid.cell_data["obstacle_id"])
    normals = np.asarray(grid.cell_data["normal"], dtype=float).reshape(-1, 3)
    solids, flat = [], []
    for k in np.unique(ids):
        cells = np.flatnonzero(ids == k)
        surface = grid.extract_cells(cells).extract_surface(algorithm=SURFACE)
        if surface.n_open_edges == 0:
            solids.append((f"obstacle {k}", surface))
        else:
            corner = np.asarray(surface.points, dtype=float)[0]
            flat.append((corner, normals[cells[0]] / np.linalg.norm(normals[cells[0]])))
    return solids, flat


def planes(ground: Path | None) -> list[tuple[np.ndarray, np.ndarray]]:
    """``[(point, unit normal)]`` of the ground planes of ``<name>_ground.vtu``."""
    if ground is None:
        return []
    import pyvista as pv

    grid = pv.read(ground)
    normals = np.asarray(grid.cell_data["normal"], dtype=float).reshape(-1, 3)
    out = []
    for k in range(grid.n_cells):
        corner = np.asarray(grid.get_cell(k).points, dtype=float)[0]
        out.append((corner, normals[k] / np.linalg.norm(normals[k])))
    return out


def _bodies(path: Path) -> dict[int, object]:
    import pyvista as pv

    grid = pv.read(path)
    if grid.n_cells == 0 or "fragment_id" not in grid.cell_data:
        return {}
    if "displacement" in grid.point_data:
        grid.points = grid.points + np.asarray(grid.point_data["displacement"])
    ids = np.asarray(grid.cell_data["fragment_id"])
    return {int(k): grid.extract_cells(np.flatnonzero(ids == k)) for k in np.unique(ids)}


def _depth_in(a, b) -> float:
    """The largest distance to ``b``'s surface of a point of ``a``'s surface inside ``b``."""
    import pyvista as pv

    surface_a = a.extract_surface(algorithm=SURFACE)
    inside = np.asarray(b.find_containing_cell(surface_a.points)) >= 0
    if not inside.any():
        return 0.0
    probe = pv.PolyData(np.asarray(surface_a.points)[inside])
    surface_b = b.extract_surface(algorithm=SURFACE)
    distance = probe.compute_implicit_distance(surface_b)["implicit_distance"]
    return float(np.max(np.abs(distance)))


def _size(body) -> float:
    volume = float(np.sum(np.abs(body.compute_cell_sizes(length=False, area=False,
                                                           volume=True)["Volume"])))
    return volume ** (1.0 / 3.0)


def _boxes_meet(a, b) -> bool:
    lo = np.maximum(np.asarray(a.bounds[0::2]), np.asarray(b.bounds[0::2]))
    hi = np.minimum(np.asarray(a.bounds[1::2]), np.asarray(b.bounds[1::2]))
    return bool(np.all(lo <= hi))


def frame_overlap(time: float, path: Path, ground: list[tuple[np.ndarray, np.ndarray]],
                  solids: list = ()) -> Overlap:
    """The deepest overlap between the bodies of one frame, and of each with the planes and
    the fixed ``solids`` (``[(name, closed surface)]``)."""
    bodies = _bodies(path)
    sizes = {k: _size(b) for k, b in bodies.items()}
    best = Overlap(time, 0.0, ("", ""), 0.0)
    keys = sorted(bodies)
    for i, ka in enumerate(keys):
        for kb in keys[i + 1:]:
            a, b = bodies[ka], bodies[kb]
            if not _boxes_meet(a, b):
                continue
            depth = max(_depth_in(a, b), _depth_in(b, a))
            scale = min(sizes[ka], sizes[kb])
            if depth > best.depth:
                best = Overlap(time, depth, (str(ka), str(kb)), depth / scale)
        for j, (point, normal) in enumerate(ground):
            depth = float(np.max(-(np.asarray(bodies[ka].points) - point) @ normal,
                                 initial=0.0))
            if depth > best.depth:
                best = Overlap(time, depth, (str(ka), f"ground {j}"), depth / sizes[ka])
        for name, surface in solids:
            if not _boxes_meet(bodies[ka], surface):
                continue
            depth = _depth_in_closed(bodies[ka], surface)
            scale = min(sizes[ka], _closed_volume(surface) ** (1.0 / 3.0))
            if depth > best.depth:
                best = Overlap(time, depth, (str(ka), name), depth / scale)
    return best


def run_overlaps(directory: Path) -> list[Overlap]:
    """The deepest overlap of every frame of the run in ``directory``."""
    frames, ground, fixed = series_files(directory)
    solids, flat = fixed_obstacles(fixed)
    surfaces = planes(ground) + flat
    return [frame_overlap(t, path, surfaces, solids) for t, path in frames]


def _depth_in_closed(body, surface) -> float:
    """The largest distance to the closed ``surface`` of a surface point of ``body``
    inside it, and of a point of ``surface`` inside ``body``."""
    import pyvista as pv

    points = pv.PolyData(np.asarray(body.extract_surface(algorithm=SURFACE).points))
    inside = np.asarray(points.select_interior_points(surface, check_surface=False)
                        ["selected_points"], dtype=bool)
    depth = 0.0
    if inside.any():
        probe = pv.PolyData(np.asarray(points.points)[inside])
        depth = float(np.max(np.abs(probe.compute_implicit_distance(surface)
                                    ["implicit_distance"])))
    within = np.asarray(body.find_containing_cell(surface.points)) >= 0
    if within.any():
        probe = pv.PolyData(np.asarray(surface.points)[within])
        outer = body.extract_surface(algorithm=SURFACE)
        depth = max(depth, float(np.max(np.abs(probe.compute_implicit_distance(outer)
                                                ["implicit_distance"]))))
    return depth


def _closed_volume(surface) -> float:
    return abs(float(surface.volume))


def report(overlaps: list[Overlap]) -> str:
    """One line per frame with an overlap, and the worst."""
    lines = [f"t = {o.time:.6g}: {o.depth:.3g} deep between {o.pair[0]} and {o.pair[1]} "
             f"({100 * o.fraction:.2g} % of the smaller body's size)"
             for o in overlaps if o.depth > 0.0]
    worst = max(overlaps, key=lambda o: o.fraction)
    verdict = "within" if worst.fraction <= TOLERANCE else "beyond"
    lines.append(f"deepest: {100 * worst.fraction:.3g} % of the smaller body's size at "
                 f"t = {worst.time:.6g} ({worst.depth:.3g}), {verdict} the "
                 f"{100 * TOLERANCE:g} % tolerance, over {len(overlaps)} frames")
    return "\n".join(lines)
