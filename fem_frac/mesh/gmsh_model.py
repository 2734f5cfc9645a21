"""Run gmsh quietly and turn its current model into a :class:`Mesh`; check a ``.geo`` script
for commands that run programs or write files before gmsh reads it (:func:`check_geo_file`).

``gmsh`` is imported only inside functions: a case that reads a mesh file never loads it.

3D algorithm (``Mesh.Algorithm3D``), measured on the 2-core development machine with gmsh
4.15.2: a unit box meshed at ``element_size`` h, 2D + 3D meshing with gmsh's default
optimisation (conversion to :class:`Mesh` in brackets), seconds, two runs each:

=====================  =======================================  ====================
algorithm              h = 0.035 (~100k tets)                   h = 0.0165 / 0.0155
=====================  =======================================  ====================
Delaunay (1)           2.32, 2.34 (+0.09); 110,756 tets         28.7-31.1 (+1.6-2.4);
                                                                 1,016,007 tets (0.0165)
HXT (10), 1 thread     0.42, 0.48 (+0.05-0.07); 98,741 tets      3.45-3.53 (+0.9-1.2);
                                                                 1,069,450 tets (0.0155)
HXT (10), 2 threads    --                                        1.6-1.7; NOT repeatable
=====================  =======================================  ====================

Both algorithms gave identical node and tet arrays in repeated single-threaded runs; HXT with
``General.NumThreads`` = 2 gave different meshes on each run (886,258 vs 886,678 tets). So the
default is HXT, pinned to one thread: ~8x faster than Delaunay at 1M tets and repeatable.
HXT makes ~10 % fewer tets than Delaunay for the same h.
"""

from __future__ import annotations

import os
import re
import signal
import stat
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import MeshError
from .mesh import Mesh, SortedKeys, tet_volumes
from .reader import compact_corners, curved_edges, outward_boundaries

#: ``Mesh.Algorithm3D``: 10 = HXT (fast; repeatable single-threaded), 1 = Delaunay.
ALGORITHM_3D = 10
#: Tets whose gmsh quality (minimum signed inverse condition number, 1 for a regular tet) is
#: below this are degenerate (flat): HXT can leave one where a part is a single element
#: thick; the mesh is then redone with the Delaunay algorithm, which removes slivers.
DEGENERATE_QUALITY = 1e-6
#: ``Mesh.Algorithm3D`` of the fallback: 1 = Delaunay.
FALLBACK_ALGORITHM_3D = 1
#: Elements per 2*pi of curvature on curved surfaces (``Mesh.MeshSizeFromCurvature``): a
#: sphere meshed with h > 2*pi*R/12 still gets a sensible facetting.
CURVATURE_ELEMENTS = 12

# gmsh element types
_TRIANGLE, _TRIANGLE6, _TET, _TET10 = 2, 9, 4, 11
# gmsh's 10-node tet: corners, then mid nodes of (0,1),(1,2),(2,0),(3,0),(3,2),(3,1) -- not
# VTK's order, whose last two edges are (1,3),(2,3).
GMSH_TET10_EDGES = np.array([[0, 1], [1, 2], [2, 0], [3, 0], [3, 2], [3, 1]])


@contextmanager
def gmsh_session(verbose: bool = False) -> Iterator[None]:
    """Initialize gmsh (quiet unless ``verbose``) and always finalize it.

    If gmsh is already initialized by the caller, a fresh model is added instead and removed
    on exit, leaving the caller's session as it was.
    """
    import gmsh

    owner = not gmsh.isInitialized()
    main = threading.current_thread() is threading.main_thread()
    # Ctrl-C stops gmsh's own loops only with SIGINT at its default (which gmsh sets when
    # interruptible); Python's handler comes back afterwards, so an interrupted run can
    # still say how far it got
    handler = signal.getsignal(signal.SIGINT) if main else None
    if owner:
        gmsh.initialize(readConfigFiles=False, interruptible=main)
    else:
        gmsh.model.add("fem_frac")
    try:
        gmsh.option.setNumber("General.Terminal", 1 if verbose else 0)
        yield
    finally:
        if owner:
            gmsh.finalize()
        else:
            gmsh.model.remove()
        if handler is not None:
            signal.signal(signal.SIGINT, handler)


def mesh_current_model(
    element_size: float | None,
    order: int = 1,
    *,
    algorithm_3d: int | None = ALGORITHM_3D,
    curvature_elements: int = CURVATURE_ELEMENTS,
) -> Mesh:
    """Mesh the current gmsh model in 3D and convert it to a :class:`Mesh`.

    ``element_size`` (model length units) caps the edge length (``Mesh.MeshSizeMax``) and
    turns on curvature-based refinement (``curvature_elements`` per 2*pi); ``None`` keeps the
    model's own sizes. ``order`` 2 adds mid-side nodes on the geometry (``setOrder(2)``); the
    curved ones become ``Mesh.edges``/``edge_points``. ``algorithm_3d`` None keeps the
    model's choice.
    """
    import gmsh

    if order not in (1, 2):
        raise MeshError(f"geometry order must be 1 or 2, got {order}")
    try:
        if element_size is not None:
            gmsh.option.setNumber("Mesh.MeshSizeMax", float(element_size))
            gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", curvature_elements)
        if algorithm_3d is not None:
            gmsh.option.setNumber("Mesh.Algorithm3D", algorithm_3d)
        gmsh.option.setNumber("General.NumThreads", 1)  # multi-threaded HXT is not repeatable
        gmsh.option.setNumber("Mesh.ElementOrder", 1)  # a .geo may ask for 2: we do it below
        gmsh.model.mesh.clear()
        gmsh.model.mesh.generate(3)
        if _degenerate_tets() and algorithm_3d != FALLBACK_ALGORITHM_3D:
            gmsh.option.setNumber("Mesh.Algorithm3D", FALLBACK_ALGORITHM_3D)
            gmsh.model.mesh.clear()
            gmsh.model.mesh.generate(3)
        bad = _degenerate_tets()
        if bad:
            raise MeshError(
                f"gmsh produced {bad} degenerate (flat) tetrahedra; a part of the geometry is "
                "about one element thick: use a smaller element_size"
            )
        if order == 2:
            gmsh.model.mesh.setOrder(2)
        return model_to_mesh(order)
    except MeshError:
        raise
    except Exception as exc:  # gmsh raises bare Exception with its last error message
        raise MeshError(f"gmsh failed to mesh the geometry: {_one_line(exc)}") from None


def _degenerate_tets() -> int:
    """Number of linear tets of the current gmsh mesh below ``DEGENERATE_QUALITY``."""
    import gmsh

    tags, _ = gmsh.model.mesh.getElementsByType(_TET)
    if len(tags) == 0:
        return 0
    quality = np.abs(gmsh.model.mesh.getElementQualities(tags, "minSICN"))
    return int(np.count_nonzero(quality < DEGENERATE_QUALITY))


def model_to_mesh(order: int = 1) -> Mesh:
    """Convert the current gmsh mesh (already generated) to a :class:`Mesh`, vectorized.

    Keeps only nodes that are tet corners (renumbered 0..n-1 in increasing gmsh tag order),
    flips negatively oriented tets, takes boundaries from 2D physical groups (corner triples
    of their triangles, exterior ones turned outward) and subdomains from 3D physical groups
    (tet ids). For ``order`` 2 the curved mid-side nodes become ``edges``/``edge_points``
    (straight ones are not stored). Unnamed physical groups are called ``physical_<tag>``.
    """
    import gmsh

    mesh_api = gmsh.model.mesh
    tet_type = _tet_type(mesh_api, order)
    row, xyz = _nodes(mesh_api)
    tet_tags, tet_nodes = _entity_elements(mesh_api, 3, -1, (tet_type,))
    corner_tags, new_id = compact_corners(tet_nodes[:, :4], row.size)
    points = xyz[row[corner_tags]]
    tets = new_id[tet_nodes[:, :4]]

    edges = edge_points = None
    if order == 2:
        mids = xyz[row[tet_nodes[:, 4:]]]
        edges, edge_points = curved_edges(points, tets, mids, GMSH_TET10_EDGES)

    inverted = tet_volumes(points, tets) < 0
    tets[inverted] = tets[inverted][:, [0, 2, 1, 3]]

    boundaries, subdomains = _physical_groups(mesh_api, tet_type, tet_tags, new_id)
    boundaries = outward_boundaries(tets, len(points), boundaries)
    return Mesh(points, tets, boundaries, subdomains, edges, edge_points)


def _nodes(mesh_api) -> tuple[np.ndarray, np.ndarray]:
    """``(row, xyz)``: node positions ``xyz (k, 3)`` and, for every gmsh node tag up to the
    largest, its row in ``xyz`` (-1 for a tag no node has)."""
    node_tags, coords, _ = mesh_api.getNodes(returnParametricCoord=False)
    node_tags = np.asarray(node_tags, dtype=np.int64)
    row = np.full(node_tags.max() + 1, -1, dtype=np.int64)
    row[node_tags] = np.arange(node_tags.size)
    return row, np.asarray(coords, dtype=np.float64).reshape(-1, 3)


def _tet_type(mesh_api, order: int) -> int:
    """The gmsh type of the tets of an ``order`` mesh; :class:`MeshError` when the 3D mesh
    has none or holds other elements."""
    types_3d = set(int(t) for t in mesh_api.getElementTypes(dim=3))
    tet_type = _TET10 if order == 2 else _TET
    other = types_3d - {tet_type}
    if other:
        names = ", ".join(mesh_api.getElementProperties(t)[0] for t in sorted(other))
        raise MeshError(f"the 3D mesh has non-tetrahedral (or other-order) elements: {names}")
    if tet_type not in types_3d:
        raise MeshError("gmsh produced no tetrahedra (is the geometry a closed volume?)")
    return tet_type


def _physical_groups(mesh_api, tet_type: int, tet_tags: np.ndarray,
                     new_id: np.ndarray) -> tuple[dict, dict]:
    """Boundaries (name -> corner triples in new ids, -1 for a node that is no tet corner)
    and subdomains (name -> tet ids, rows of ``tet_tags``) of the physical groups; groups of
    the same name are merged."""
    import gmsh

    boundaries: dict[str, np.ndarray] = {}
    subdomains: dict[str, np.ndarray] = {}
    tet_rows = SortedKeys(tet_tags)
    for dim, tag in gmsh.model.getPhysicalGroups():
        name = gmsh.model.getPhysicalName(dim, tag) or f"physical_{tag}"
        entities = gmsh.model.getEntitiesForPhysicalGroup(dim, tag)
        if dim == 2:
            tris = [_entity_elements(mesh_api, 2, e, (_TRIANGLE, _TRIANGLE6)) for e in entities]
            tris = np.concatenate([t[1][:, :3] for t in tris]) if tris else np.empty((0, 3))
            boundaries[name] = _merge(boundaries.get(name), new_id[tris.astype(np.int64)])
        elif dim == 3:
            tags = [_entity_elements(mesh_api, 3, e, (tet_type,))[0] for e in entities]
            tags = np.concatenate(tags) if tags else np.empty(0, dtype=np.int64)
            ids = tet_rows.rows(tags)  # never -1: getElementsByType listed them all
            subdomains[name] = np.unique(_merge(subdomains.get(name), ids))
    return boundaries, subdomains


def _entity_elements(mesh_api, dim: int, tag: int, types: tuple[int, ...]):
    """Element tags ``(k,)`` and node tags ``(k, nodes_per_element)`` of one entity."""
    for element_type in types:
        tags, nodes = mesh_api.getElementsByType(element_type, tag)
        if len(tags):
            tags = np.asarray(tags, dtype=np.int64)
            return tags, np.asarray(nodes, dtype=np.int64).reshape(tags.size, -1)
    return np.empty(0, dtype=np.int64), np.empty((0, 3), dtype=np.int64)


def _merge(old: np.ndarray | None, new: np.ndarray) -> np.ndarray:
    return new if old is None else np.concatenate([old, new])


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


# --- what a .geo file may do ------------------------------------------------------------------
#
# gmsh's scripting language (src/parser/Gmsh.l and Gmsh.y of gmsh 4.x) can run programs and
# write files. These are refused unless the case allows them (mesh.allow_geo_commands);
# docs/security.md lists them with the reasons.

#: ``Name "string";`` commands (an identifier followed by a string expression).
GEO_STRING_COMMANDS = {
    "SystemCall": "runs a shell command",
    "System": "runs a shell command",
    "NonBlockingSystemCall": "runs a shell command",
    "OnelabRun": "runs a program (an ONELAB client)",
    "CreateDir": "creates a directory",
    "Save": "writes a file",
    "Print": "writes a file (an image)",
}
#: Keywords refused wherever they stand.
GEO_KEYWORDS = {
    "Exit": "ends the whole process (fem_frac with it)",
    "Plugin": "runs a post-processing plugin (some write files)",
    "OnelabRun": "runs a program (an ONELAB client)",
}
#: Commands that read another file: an included file is parsed as a .geo script.
GEO_INCLUDES = ("Include", "Merge", "MergeWithBoundingBox")
#: Extensions gmsh's ``Merge`` reads with a reader of their own (never as a script).
GEO_DATA_EXTENSIONS = frozenset(
    e for ext in ("stl brep rle brp xao iges igs step stp sat x_t xmt_txt x_b xmt_bin unv vtk "
                  "wrl vrml iv mesh off obj diff med mmed rmed bdf nas neu dat p3d pnm pbm pgm "
                  "ppm bmp jpg jpeg png ply2 ply geom cgns pch").split()
    for e in (f".{ext}", f".{ext.upper()}"))
#: ``Merge`` of these runs a program: gmsh uncompresses ``.gz`` with a shell command and
#: takes ``.py``/``.m``/``.exe`` for a solver to run.
GEO_PROGRAM_EXTENSIONS = {".gz": "is uncompressed by a shell command",
                          **dict.fromkeys((".py", ".PY", ".m", ".M", ".exe", ".EXE"),
                                          "is a program gmsh would run")}
#: First bytes of the files ``Merge`` reads as a mesh or a post-processing view.
GEO_DATA_HEADERS = (b"$PTS", b"$NO", b"$PARA", b"$ELM", b"$MeshFormat", b"$Comments",
                    b"$PostFormat", b"$View")
#: Options that write a file or name a program (``General.LogFileName`` opens its file at
#: once; the rest take effect in gmsh's GUI or its ONELAB clients).
GEO_OPTION_SUFFIXES = ("FileName", "Command", "Executable", "Interpreter", "RemoteLogin",
                       "TextEditor", "WatchFilePattern")

_GEO_TOKEN = re.compile(
    r"""(?P<space>[ \t\r\f\v]+)|(?P<newline>\n)|(?P<comment>//[^\n]*|/\*.*?(?:\*/|\Z))
    |(?P<string>"[^"]*(?:"|\Z)|'[^']*(?:'|\Z))
    |(?P<number>(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)
    |(?P<name>[A-Za-z_][A-Za-z0-9_]*)|(?P<op>>>|.)""",
    re.S | re.X,
)


@dataclass(frozen=True)
class GeoCommand:
    """A use of a refused command: the file, its line, the command and what it does."""

    path: Path
    line: int
    command: str
    why: str

    def __str__(self) -> str:
        return f"{self.path}:{self.line}: {self.command} {self.why}"


def check_geo_file(path: str | Path) -> None:
    """Raise :class:`MeshError` naming the file, line and command of the first command of
    ``path`` (or of a file it includes) that runs a program or writes a file."""
    found = geo_commands(path)
    if found:
        raise MeshError(f"{found[0]} (refused: set mesh.allow_geo_commands: true only for a "
                        "file you trust; see docs/security.md)")


def geo_commands(path: str | Path) -> list[GeoCommand]:
    """Every use in ``path`` and the files it includes (``Include``, ``Merge`` of a script,
    recursively, relative paths from the including file's directory) of a command that runs
    a program or writes a file, in reading order."""
    found: list[GeoCommand] = []
    _scan_geo(Path(path), found, set())
    return found


def _scan_geo(path: Path, found: list[GeoCommand], seen: set) -> None:
    if not _regular_file(path):
        return  # gmsh reports a file it cannot read (and a device or pipe is no script)
    key = os.path.realpath(path)
    if key in seen:
        return
    seen.add(key)
    try:
        text = path.read_bytes().decode("latin-1")
    except OSError:
        return
    tokens = _geo_tokens(text)
    for i, (kind, word, line) in enumerate(tokens):
        if kind != "name":
            continue
        before = tokens[i - 1][1] if i > 0 else ";"
        after = tokens[i + 1] if i + 1 < len(tokens) else ("op", ";", line)
        if before == ".":
            if after[1] == "=" and _writing_option(tokens, i):
                found.append(GeoCommand(path, line, _option_name(tokens, i),
                                        "names a file gmsh writes or a program it runs"))
            continue
        starts_string = after[0] in ("string", "name")
        if word in GEO_KEYWORDS:
            found.append(GeoCommand(path, line, word, GEO_KEYWORDS[word]))
        elif word in GEO_STRING_COMMANDS and starts_string:
            found.append(GeoCommand(path, line, word, GEO_STRING_COMMANDS[word]))
        elif word == "Printf" and _redirected(tokens, i + 1):
            found.append(GeoCommand(path, line, "Printf > file", "writes a file"))
        elif word in GEO_INCLUDES and starts_string:
            if after[0] != "string":
                found.append(GeoCommand(path, line, word, "reads a file whose name is computed "
                                        "(it cannot be checked before gmsh runs it)"))
                continue
            target = _relative_to(path, after[1][1:-1] if len(after[1]) > 1 else "")
            if word == "Include" or _read_as_script(target, path, line, word, found):
                _scan_geo(target, found, seen)


def _geo_tokens(text: str) -> list[tuple[str, str, int]]:
    """``(kind, text, line)`` of the tokens of a .geo text (blanks and comments dropped);
    strings are quoted by ``"`` or ``'`` without escapes, as gmsh's lexer reads them."""
    out, line = [], 1
    for m in _GEO_TOKEN.finditer(text):
        kind, value = m.lastgroup, m.group()
        if kind not in ("space", "newline", "comment"):
            out.append((kind, value, line))
        line += value.count("\n")
    return out


def _redirected(tokens, i: int) -> bool:
    """The ``Printf`` whose ``(`` is ``tokens[i]`` is followed by ``>`` or ``>>``."""
    if i >= len(tokens) or tokens[i][1] != "(":
        return False
    depth = 0
    for j in range(i, len(tokens)):
        depth += {"(": 1, ")": -1}.get(tokens[j][1], 0)
        if depth == 0:
            return j + 1 < len(tokens) and tokens[j + 1][1] in (">", ">>")
    return False


def _option_name(tokens, i: int) -> str:
    """``Category.Option`` (``Category[n].Option``) of the option name at ``tokens[i]``."""
    j = i - 2
    if j >= 0 and tokens[j][1] == "]":
        depth = 0
        while j >= 0:
            depth += {"]": 1, "[": -1}.get(tokens[j][1], 0)
            if depth == 0:
                break
            j -= 1
        j -= 1
    category = tokens[j][1] if j >= 0 and tokens[j][0] == "name" else "?"
    return f"{category}.{tokens[i][1]}"


def _writing_option(tokens, i: int) -> bool:
    category, option = _option_name(tokens, i).split(".", 1)
    return category == "Solver" or option.rstrip("0123456789").endswith(GEO_OPTION_SUFFIXES)


def _regular_file(path: Path) -> bool:
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except (OSError, ValueError):
        return False


def _relative_to(including: Path, name: str) -> Path:
    """gmsh's FixRelativePath: a relative name is taken from the including file's
    directory."""
    target = Path(name)
    return target if target.is_absolute() else including.parent / target


def _read_as_script(target: Path, path: Path, line: int, word: str,
                    found: list[GeoCommand]) -> bool:
    """Whether gmsh's ``Merge`` parses ``target`` as a script (else it is data, or a
    program, which is recorded in ``found``)."""
    ext = target.suffix
    if ext in GEO_PROGRAM_EXTENSIONS:
        found.append(GeoCommand(path, line, f"{word} {target.name}",
                                GEO_PROGRAM_EXTENSIONS[ext]))
        return False
    if ext in GEO_DATA_EXTENSIONS or not _regular_file(target):
        return False
    try:
        with open(target, "rb") as f:
            head = f.read(16)
    except OSError:
        return False
    return not head.startswith(GEO_DATA_HEADERS)
