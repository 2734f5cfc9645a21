"""Mesh files (anything meshio reads: .msh, .vtu, .vtk, .xdmf, .med, ...) -> :class:`Mesh`.

Also holds the array helpers shared with :mod:`.gmsh_model` (curved edges of quadratic tets,
boundary facets checked against the tets and turned outward). Never imports gmsh.

Named groups come from, in this order:

1. meshio ``cell_sets`` (gmsh 4 files put physical names there; ``gmsh:*`` sets are skipped);
2. gmsh physical names: ``field_data`` name -> ``[tag, dim]`` with the ``gmsh:physical`` cell
   data (used for names step 1 did not give, e.g. gmsh 2.2 files);
3. only when neither gave a name: each integer cell-data array on triangles (tets) gives one
   boundary (subdomain) per value, named ``<array>_<value>`` (a ``gmsh:`` prefix is dropped,
   ``gmsh:geometrical`` is used only when no other integer array exists).

Triangles (``triangle``/``triangle6``; corners only) become boundaries, tets subdomains.
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np

from ..errors import MeshError
from .mesh import TET_FACES, Mesh, SortedKeys, facet_keys, tet_volumes

_TET_TYPES = ("tetra", "tetra10")
_TRI_TYPES = ("triangle", "triangle6")
# meshio's (VTK's) tetra10: corners, then mid nodes of (0,1),(1,2),(2,0),(0,3),(1,3),(2,3).
VTK_TET10_EDGES = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]])
# mid nodes closer to their edge's midpoint than this (relative to the edge length) are
# straight and not stored
STRAIGHT_TOL = 1e-10
# a tet with |V| <= ZERO_VOLUME * mean |V| is degenerate
ZERO_VOLUME = 1e-12


def read_mesh_file(path: str | Path, order_hint: int | None = None) -> Mesh:
    """Read a tetrahedral mesh file with meshio.

    ``order_hint`` is the element order the case will use: with 1 the mid-side nodes of a
    ``tetra10`` file are dropped (P1 sees straight tets anyway); otherwise the curved ones
    are kept as ``Mesh.edges``/``edge_points``. Unused nodes are dropped and the rest
    renumbered in file order. Tets that are all negatively oriented are flipped; mixed
    orientation or zero-volume tets raise :class:`MeshError`.
    """
    path = Path(path)
    raw = _read_meshio(path)
    blocks = list(raw.cells)
    tet_blocks = _tet_blocks(path, raw, blocks)
    try:
        xyz = np.asarray(raw.points, dtype=np.float64)
    except (TypeError, ValueError):
        raise MeshError(f"{path}: point coordinates are not numbers") from None
    if xyz.ndim != 2 or xyz.shape[1] != 3:
        dims = xyz.shape[1] if xyz.ndim == 2 else "not"
        raise MeshError(f"{path}: points are {dims}-dimensional, expected 3")
    _check_indices(path, blocks, len(xyz))
    corner_nodes = np.concatenate([blocks[i].data[:, :4] for i in tet_blocks]).astype(np.int64)
    used, new_id = compact_corners(corner_nodes, len(xyz))
    _check_finite(path, xyz, used)
    points = xyz[used]

    edges = edge_points = None
    quadratic = [i for i in tet_blocks if blocks[i].type == "tetra10"]
    if quadratic and order_hint != 1:
        t10 = np.concatenate([blocks[i].data for i in quadratic]).astype(np.int64)
        edges, edge_points = curved_edges(
            points, new_id[t10[:, :4]], xyz[t10[:, 4:]], VTK_TET10_EDGES
        )

    tets = _checked_orientation(path, points, new_id[corner_nodes])
    boundary_parts, subdomain_parts = _groups(raw, blocks)
    try:
        boundaries = outward_boundaries(tets, len(points),
                                        _boundary_triples(blocks, boundary_parts, new_id))
    except MeshError as exc:
        raise MeshError(f"{path}: {exc}") from None
    subdomains = _subdomain_tets(blocks, tet_blocks, subdomain_parts)
    return Mesh(points, tets, boundaries, subdomains, edges, edge_points)


# --- helpers shared with gmsh_model ------------------------------------------------------------


def curved_edges(
    points: np.ndarray, tets: np.ndarray, mid_points: np.ndarray, local_edges: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Curved edges of a quadratic tet mesh.

    ``points`` (n, 3) corners; ``tets`` (n_tets, 4) corner ids in the file's vertex order
    (before any orientation flip); ``mid_points`` (n_tets, 6, 3) mid-node positions, node j
    on the edge ``local_edges[j]`` (6, 2). Returns sorted vertex pairs (k, 2) and mid-node
    positions (k, 3) of the edges whose mid node is off the straight edge's midpoint; the
    first tet listing an edge decides its mid node.
    """
    pairs = np.sort(tets[:, local_edges].reshape(-1, 2), axis=1)
    pairs, first = np.unique(pairs, axis=0, return_index=True)
    mids = mid_points.reshape(-1, 3)[first]
    a, b = points[pairs[:, 0]], points[pairs[:, 1]]
    off = np.linalg.norm(mids - 0.5 * (a + b), axis=1)
    curved = off > STRAIGHT_TOL * np.linalg.norm(b - a, axis=1)
    return pairs[curved], mids[curved]


def compact_corners(corners: np.ndarray, n_nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """The node ids ``corners`` (any shape) uses, ascending ``(n,)``, and the map ``(n_nodes,)``
    from a node id to its new id ``0..n-1`` (-1 for a node that is no tet corner)."""
    used = np.unique(corners)
    new_id = np.full(n_nodes, -1, dtype=np.int64)
    new_id[used] = np.arange(used.size)
    return used, new_id


def outward_boundaries(
    tets: np.ndarray, n_points: int, boundaries: dict[str, np.ndarray]
) -> dict[str, np.ndarray]:
    """Check every boundary triangle is a tet face; orient the exterior ones outward.

    ``tets`` (n_tets, 4) positively oriented; ``boundaries`` name -> (k, 3) vertex triples,
    -1 for a node that is no tet corner (see :func:`compact_corners`). Facets on the exterior
    get the outward orientation of their tet (as :func:`~fem_frac.mesh.mesh.exterior_facets`);
    interior ones (interfaces) keep theirs. Raises :class:`MeshError` for a triangle that is
    no face of any tet, first for one with a vertex that is no tet corner.
    """
    for name, tris in boundaries.items():
        if np.any(tris < 0):
            raise MeshError(f"boundary {name!r} has vertices that are not tet corners")
    if not boundaries:
        return {}
    faces = tets[:, TET_FACES].reshape(-1, 3)
    table = SortedKeys(facet_keys(faces, n_points))
    out = {}
    for name, tris in boundaries.items():
        wanted = facet_keys(tris, n_points)
        row = table.rows(wanted)
        if np.any(row < 0):
            raise MeshError(
                f"boundary {name!r}: {np.count_nonzero(row < 0)} triangles are not tet faces"
            )
        exterior = table.counts(wanted) == 1
        out[name] = np.where(exterior[:, None], faces[row], tris).astype(np.int64)
    return out


# --- file-specific helpers ---------------------------------------------------------------------


def _read_meshio(path: Path):
    """``meshio.read`` with its chatter captured; any failure is one :class:`MeshError`."""
    import meshio

    # meshio tries every format an extension may mean (.msh: ansys, then gmsh), prints each
    # failure to stdout and calls sys.exit(1) when none works: name gmsh for .msh, capture the
    # chatter, and turn SystemExit into a MeshError.
    chatter = io.StringIO()
    try:
        with contextlib.redirect_stdout(chatter), contextlib.redirect_stderr(chatter):
            return meshio.read(path, file_format=_file_format(path))
    except (Exception, SystemExit) as exc:  # ReadError, KeyError, ValueError, SystemExit...
        text = str(exc) if not isinstance(exc, SystemExit) else chatter.getvalue()
        reason = " ".join(text.replace("Error:", " ").split()) or type(exc).__name__
        raise MeshError(f"{path}: cannot read mesh file: {reason}") from None


def _check_indices(path: Path, blocks, n_points: int) -> None:
    """Every node index of the tet and triangle blocks names a point of the file."""
    for b in blocks:
        if b.type not in _TET_TYPES + _TRI_TYPES:
            continue
        data = np.asarray(b.data)
        if not np.issubdtype(data.dtype, np.integer):
            raise MeshError(f"{path}: {b.type} node indices are not integers")
        width = {"tetra": 4, "tetra10": 10, "triangle": 3, "triangle6": 6}[b.type]
        if data.ndim != 2 or data.shape[1] != width:
            raise MeshError(f"{path}: {b.type} cells have {data.shape[1:] or 'no'} node "
                            f"indices, expected {width}")
        bad = (data < 0) | (data >= n_points)
        if np.any(bad):
            row = int(np.flatnonzero(bad.any(axis=1))[0])
            raise MeshError(f"{path}: {np.count_nonzero(bad.any(axis=1))} {b.type} cells name "
                            f"nodes outside 0..{n_points - 1} (first: cell {row} of its block, "
                            f"node {int(data[bad][0])})")


def _check_finite(path: Path, xyz: np.ndarray, used: np.ndarray) -> None:
    """The tet corners have finite coordinates (NaN or Inf breaks every later step)."""
    bad = ~np.isfinite(xyz[used]).all(axis=1)
    if np.any(bad):
        raise MeshError(f"{path}: {np.count_nonzero(bad)} points have non-finite coordinates "
                        f"(first: point {int(used[np.flatnonzero(bad)[0]])})")
    scale = float(np.abs(xyz[used]).max(initial=0.0))
    if scale > 1e100:
        raise MeshError(f"{path}: coordinates up to {scale:g}: too large to compute with "
                        "(volumes overflow); scale the mesh")


def _file_format(path: Path) -> str | None:
    return "gmsh" if path.suffix.lower() == ".msh" else None


def _tet_blocks(path: Path, raw, blocks) -> list[int]:
    """Indices of the tet cell blocks; :class:`MeshError` when there is none."""
    tet_blocks = [i for i, b in enumerate(blocks) if b.type in _TET_TYPES]
    if not tet_blocks:
        types = ", ".join(sorted({b.type for b in blocks})) or "none"
        hint = ""
        if _file_format(path) == "gmsh" and raw.field_data:
            hint = (
                "; gmsh saves only elements of physical groups: add a Physical Volume"
                " (or set Mesh.SaveAll = 1)"
            )
        raise MeshError(f"{path}: no tetrahedra (cell types: {types}){hint}")
    return tet_blocks


def _boundary_triples(blocks, parts: dict, new_id: np.ndarray) -> dict[str, np.ndarray]:
    """Boundary name -> corner triples ``(k, 3)`` in new ids (-1: no tet corner)."""
    out = {}
    for name, rows_of in parts.items():
        tris = np.concatenate([blocks[i].data[rows, :3] for i, rows in rows_of])
        out[name] = new_id[tris.astype(np.int64)]
    return out


def _subdomain_tets(blocks, tet_blocks: list[int], parts: dict) -> dict[str, np.ndarray]:
    """Subdomain name -> tet ids: a block's rows offset by the tets of the blocks before."""
    sizes = [len(blocks[i].data) for i in tet_blocks]
    tet_offset = dict(zip(tet_blocks, np.cumsum([0, *sizes[:-1]]), strict=True))
    return {
        name: np.unique(np.concatenate([tet_offset[i] + rows for i, rows in rows_of]))
        for name, rows_of in parts.items()
    }


def _checked_orientation(path: Path, points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Tets positively oriented: flip all if all are negative; refuse mixed or degenerate."""
    v = tet_volumes(points, tets)
    scale = np.mean(np.abs(v))
    zero = np.abs(v) <= ZERO_VOLUME * scale
    if np.any(zero):
        raise MeshError(f"{path}: {_ids(zero)} zero-volume tetrahedra")
    negative = v < 0
    if np.all(negative):
        return tets[:, [0, 2, 1, 3]]
    if np.any(negative):
        raise MeshError(f"{path}: {_ids(negative)} inverted tetrahedra (mixed orientation)")
    return tets


def _ids(mask: np.ndarray, shown: int = 5) -> str:
    ids = np.flatnonzero(mask)
    first = ", ".join(str(i) for i in ids[:shown])
    more = ", ..." if ids.size > shown else ""
    return f"{ids.size} of {mask.size} tets (ids from 0: {first}{more}) are"


def _groups(raw, blocks) -> tuple[dict, dict]:
    """Boundary and subdomain groups: name -> list of (block index, row indices)."""
    kinds = {
        i: ("b" if b.type in _TRI_TYPES else "s" if b.type in _TET_TYPES else None)
        for i, b in enumerate(blocks)
    }
    found: dict[str, dict] = {"b": {}, "s": {}}

    def add(name: str, block: int, rows: np.ndarray) -> None:
        kind = kinds[block]
        if kind is not None and len(rows):
            found[kind].setdefault(name, []).append((block, np.asarray(rows, dtype=np.int64)))

    for name, per_block in (raw.cell_sets or {}).items():
        if name.startswith("gmsh:") or len(per_block) != len(blocks):
            continue
        for i, rows in enumerate(per_block):
            if rows is not None:
                add(name, i, rows)

    named = set(found["b"]) | set(found["s"])
    physical = raw.cell_data.get("gmsh:physical")
    if physical is not None and len(physical) == len(blocks):
        for name, value in (raw.field_data or {}).items():
            value = np.asarray(value).ravel()
            if name in named or value.size != 2:
                continue
            tag, dim = int(value[0]), int(value[1])
            for i, tags in enumerate(physical):
                if (kinds[i], dim) in (("b", 2), ("s", 3)):
                    add(name, i, np.flatnonzero(np.asarray(tags) == tag))

    if not (found["b"] or found["s"]):
        arrays = {
            k: v
            for k, v in raw.cell_data.items()
            if len(v) == len(blocks)
            and all(np.issubdtype(np.asarray(a).dtype, np.integer) for a in v)
        }
        if len(arrays) > 1:
            arrays.pop("gmsh:geometrical", None)
        for array, per_block in arrays.items():
            label = array.removeprefix("gmsh:")
            for i, values in enumerate(per_block):
                if kinds[i] is None:
                    continue
                values = np.asarray(values).ravel()
                uniq, inverse = np.unique(values, return_inverse=True)
                rows = np.argsort(inverse, kind="stable")
                splits = np.cumsum(np.bincount(inverse, minlength=uniq.size))[:-1]
                for v, r in zip(uniq, np.split(rows, splits), strict=True):
                    add(f"{label}_{v}", i, r)
    return found["b"], found["s"]
