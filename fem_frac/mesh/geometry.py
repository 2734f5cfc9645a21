"""Meshes of gmsh (OpenCASCADE) primitives and of ``.geo`` files.

Every builder makes the solid, names its faces as 2D physical groups (the boundary names
listed in each docstring; no subdomains) and meshes it with
:func:`~fem_frac.mesh.gmsh_model.mesh_current_model`. Lengths are in the case's units;
``element_size`` is the target tet edge length. Faces are recognised by their bounding boxes
(tolerance relative to the body's size), never by OCC tag numbers.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..errors import MeshError
from .gmsh_model import ALGORITHM_3D, check_geo_file, gmsh_session, mesh_current_model
from .mesh import Mesh

Vector = Sequence[float]
# bounding boxes: (xmin, ymin, zmin, xmax, ymax, zmax)
Box = tuple[float, float, float, float, float, float]


def box(origin: Vector, lengths: Vector, *, element_size: float, order: int = 1) -> Mesh:
    """Box ``[origin, origin + lengths]``; faces ``xmin xmax ymin ymax zmin zmax``."""
    o, n = _vec(origin), _vec(lengths)
    if np.any(n <= 0):
        raise MeshError(f"box lengths must be > 0, got {n.tolist()}")
    hi = o + n

    def make(occ) -> dict[str, list[Box]]:
        occ.addBox(*o, *n)
        return {
            f"{axis}{side}": [_slab(o, hi, i, (o if side == "min" else hi)[i])]
            for i, axis in enumerate("xyz")
            for side in ("min", "max")
        }

    return _build(make, None, float(np.max(n)), element_size, order)


def cylinder(
    origin: Vector, radius: float, height: float, *, element_size: float, order: int = 1
) -> Mesh:
    """Solid cylinder along +z, ``origin`` the centre of the bottom; ``bottom top outer``."""
    o = _vec(origin)
    _positive(radius=radius, height=height)
    lo, hi = o - [radius, radius, 0.0], o + [radius, radius, height]

    def make(occ) -> dict[str, list[Box]]:
        occ.addCylinder(*o, 0.0, 0.0, height, radius)
        return {"bottom": [_slab(lo, hi, 2, o[2])], "top": [_slab(lo, hi, 2, o[2] + height)]}

    return _build(make, "outer", max(radius, height), element_size, order)


def sphere(center: Vector, radius: float, *, element_size: float, order: int = 1) -> Mesh:
    """Solid sphere; face ``outer``."""
    c = _vec(center)
    _positive(radius=radius)

    def make(occ) -> dict[str, list[Box]]:
        occ.addSphere(*c, radius)
        return {}

    return _build(make, "outer", radius, element_size, order)


def hollow_sphere(
    center: Vector,
    inner_radius: float,
    outer_radius: float,
    sector: str = "full",
    *,
    element_size: float,
    order: int = 1,
) -> Mesh:
    """Thick spherical shell; faces ``inner outer``.

    ``sector`` ``"octant"`` keeps the part with x, y, z >= centre and adds the planes
    ``symmetry_x symmetry_y symmetry_z`` (normal to x, y, z through the centre).
    """
    c = _vec(center)
    a, b = inner_radius, outer_radius
    _positive(inner_radius=a, outer_radius=b)
    _ordered(a, b)
    _sector(sector, ("full", "octant"))
    lo = c - b if sector == "full" else c.copy()
    hi = c + b

    def make(occ) -> dict[str, list[Box]]:
        shell = _cut(occ, occ.addSphere(*c, b), occ.addSphere(*c, a))
        groups: dict[str, list[Box]] = {"inner": [(*(c - a), *(c + a))]}
        if sector == "octant":
            occ.intersect(shell, [(3, occ.addBox(*c, b, b, b))])
            for i, axis in enumerate("xyz"):
                groups[f"symmetry_{axis}"] = [_slab(lo, hi, i, c[i])]
        return groups

    return _build(make, "outer", b, element_size, order)


def hollow_cylinder(
    origin: Vector,
    inner_radius: float,
    outer_radius: float,
    height: float,
    sector: str = "full",
    *,
    element_size: float,
    order: int = 1,
) -> Mesh:
    """Thick-walled tube along +z from ``origin`` (centre of the bottom).

    Faces ``inner outer bottom top``; ``sector`` ``"half"`` keeps y >= origin y and adds
    ``symmetry_y`` (the plane normal to y), ``"quarter"`` keeps x, y >= origin and adds
    ``symmetry_x symmetry_y``.
    """
    o = _vec(origin)
    a, b = inner_radius, outer_radius
    _positive(inner_radius=a, outer_radius=b, height=height)
    _ordered(a, b)
    _sector(sector, ("full", "half", "quarter"))
    lo = o + [0.0 if sector == "quarter" else -b, -b if sector == "full" else 0.0, 0.0]
    hi = o + [b, b, height]

    def make(occ) -> dict[str, list[Box]]:
        core = occ.addCylinder(o[0], o[1], o[2] - height, 0.0, 0.0, 3.0 * height, a)
        tube = _cut(occ, occ.addCylinder(*o, 0.0, 0.0, height, b), core)
        groups: dict[str, list[Box]] = {
            "inner": [(o[0] - a, o[1] - a, o[2], o[0] + a, o[1] + a, o[2] + height)],
            "bottom": [_slab(lo, hi, 2, o[2])],
            "top": [_slab(lo, hi, 2, o[2] + height)],
        }
        if sector != "full":
            occ.intersect(tube, [(3, occ.addBox(*lo, *(hi - lo)))])
            groups["symmetry_y"] = [_slab(lo, hi, 1, o[1])]
        if sector == "quarter":
            groups["symmetry_x"] = [_slab(lo, hi, 0, o[0])]
        return groups

    return _build(make, "outer", max(b, height), element_size, order)


def from_geo_file(path: str | Path, element_size: float | None = None, order: int = 1, *,
                  allow_commands: bool = False) -> Mesh:
    """Mesh a gmsh ``.geo`` file; ``element_size`` (if given) caps the edge length.

    Boundaries are the file's named physical surfaces, subdomains its physical volumes; a
    file without physical surfaces gives no boundaries. The file's ``Mesh.Algorithm3D`` is
    kept unless it left the default (Delaunay), which is replaced by HXT.

    Unless ``allow_commands``, a file that (or whose included files) runs programs or
    writes files is refused before gmsh reads it
    (:func:`~fem_frac.mesh.gmsh_model.check_geo_file`).
    """
    import gmsh

    path = Path(path)
    if not allow_commands:
        check_geo_file(path)
    with gmsh_session():
        try:
            gmsh.open(str(path))
        except Exception as exc:
            raise MeshError(f"{path}: gmsh cannot read it: {_one_line(exc)}") from None
        if gmsh.model.getDimension() < 3:
            raise MeshError(f"{path}: the geometry has no volume to mesh")
        kept = int(gmsh.option.getNumber("Mesh.Algorithm3D"))
        try:
            return mesh_current_model(
                element_size, order, algorithm_3d=ALGORITHM_3D if kept == 1 else None
            )
        except MeshError as exc:
            raise MeshError(f"{path}: {exc}") from None


BUILDERS: dict[str, Callable[..., Mesh]] = {
    "box": box,
    "cylinder": cylinder,
    "sphere": sphere,
    "hollow_sphere": hollow_sphere,
    "hollow_cylinder": hollow_cylinder,
}


def build(kind: str, params: dict, element_size: float, order: int = 1) -> Mesh:
    """Mesh primitive ``kind`` (a key of :data:`BUILDERS`) with keyword ``params``."""
    try:
        builder = BUILDERS[kind]
    except KeyError:
        raise MeshError(f"unknown geometry {kind!r}; expected one of {sorted(BUILDERS)}") from None
    if element_size is None or not element_size > 0:
        raise MeshError(f"element_size must be > 0, got {element_size}")
    try:
        return builder(**params, element_size=element_size, order=order)
    except TypeError as exc:
        raise MeshError(f"geometry {kind!r}: {exc}") from None


# --- helpers ---------------------------------------------------------------------------------

# OpenCASCADE's bounding boxes are padded by its absolute tolerance, 1e-7 (model units):
# without a margin above it, a face of a body a few millimetres across in SI units is missed.
OCC_PADDING = 1e-6


def _build(make: Callable, rest: str | None, size: float, element_size: float, order: int) -> Mesh:
    """Run ``make(occ)`` in a gmsh session, name the faces, mesh.

    ``make`` builds one solid and returns name -> bounding boxes of its faces; faces found
    in none of them are called ``rest``. Boxes are widened by ``1e-6 * size`` plus
    ``OCC_PADDING``: OpenCASCADE pads every bounding box by its absolute tolerance.
    """
    import gmsh

    if not element_size > 0:
        raise MeshError(f"element_size must be > 0, got {element_size}")
    with gmsh_session():
        try:
            occ = gmsh.model.occ
            groups = make(occ)
            occ.synchronize()
            faces = _classify(gmsh.model, groups, rest, 1e-6 * size + OCC_PADDING)
        except MeshError:
            raise
        except Exception as exc:
            raise MeshError(f"gmsh failed to build the geometry: {_one_line(exc)}") from None
        for name, tags in faces.items():
            gmsh.model.setPhysicalName(2, gmsh.model.addPhysicalGroup(2, tags), name)
        # OCC points carry no size: without this gmsh falls back to ~1/10 of the model's
        # bounding-box diagonal, which overrides a larger element_size
        gmsh.model.mesh.setSize(gmsh.model.getEntities(0), element_size)
        return mesh_current_model(element_size, order)


def _classify(model, groups: dict[str, list[Box]], rest: str | None, eps: float):
    """name -> surface tags; each surface of the model gets exactly one name."""
    surfaces = {tag for _, tag in model.getEntities(2)}
    faces: dict[str, list[int]] = {}
    taken: set[int] = set()
    for name, boxes in groups.items():
        tags: set[int] = set()
        for lo_hi in boxes:
            widened = np.add(lo_hi, [-eps] * 3 + [eps] * 3)
            tags |= {tag for _, tag in model.getEntitiesInBoundingBox(*widened, dim=2)}
        if not tags or tags & taken:
            raise MeshError(f"internal error: cannot identify the face(s) {name!r}")
        faces[name] = sorted(tags)
        taken |= tags
    left = sorted(surfaces - taken)
    if rest is not None:
        if not left:
            raise MeshError(f"internal error: cannot identify the face(s) {rest!r}")
        faces[rest] = left
    elif left:
        raise MeshError(f"internal error: {len(left)} faces have no name")
    return faces


def _cut(occ, body: int, tool: int) -> list[tuple[int, int]]:
    out, _ = occ.cut([(3, body)], [(3, tool)])
    return out


def _slab(lo: np.ndarray, hi: np.ndarray, axis: int, value: float) -> Box:
    """The bounding box ``[lo, hi]`` flattened to ``value`` along ``axis``."""
    a, b = np.array(lo, dtype=float), np.array(hi, dtype=float)
    a[axis] = b[axis] = value
    return (*a, *b)


def _vec(v: Vector) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise MeshError(f"expected a finite 3-vector, got {v!r}")
    return a


def _positive(**values: float) -> None:
    for name, value in values.items():
        if not (np.isfinite(value) and value > 0):
            raise MeshError(f"{name} must be > 0, got {value}")


def _ordered(inner: float, outer: float) -> None:
    if inner >= outer:
        raise MeshError(f"inner_radius ({inner}) must be smaller than outer_radius ({outer})")


def _sector(sector: str, allowed: tuple[str, ...]) -> None:
    if sector not in allowed:
        raise MeshError(f"sector must be one of {', '.join(allowed)}; got {sector!r}")


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__
