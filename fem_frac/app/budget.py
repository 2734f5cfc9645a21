"""The work a case implies, estimated before anything is meshed, against stated bounds.

A tiny ``element_size``, a huge number of steps or a smoothing length far above the element
size asks for hours of work or more memory than the machine has; such a case is refused at
the key that asks for it, before meshing, unless the user raises the bounds
(``fem-frac run/check --allow-large``). The estimates:

- **tets** of a gmsh primitive: ``TETS_PER_H3 * V / h^3`` (V the closed-form volume, h the
  element size). gmsh gives 0.55 to 0.8 times the count of regular tets,
  ``V / (h^3 / (6 sqrt 2))``, on the shipped cases (coarse meshes the high end), which is
  4.7 to 6.8 ``V / h^3``. A ``.geo`` file: the bounding box of its ``Box`` and ``Point``
  statements when their coordinates are plain arithmetic, with ``element_size`` (or the
  file's ``Mesh.MeshSizeMax``) as h; a lower bound where the file refines locally; not
  estimated otherwise. A mesh file: its size on disk at ``BYTES_PER_TET`` (16 to 50 bytes
  per tet measured: compressed .vtu to ASCII .msh).
- **dofs**: 3 x ``NODES_PER_TET`` x tets (vertices for P1; vertices and edges for P2).
- **steps**: the analysis's steps, times the substeps of central difference (dt over
  ``0.7 h / c`` for P1, ``0.2 h / c`` for P2, c the dilatational wave speed; measured
  0.5 to 0.7 and 0.19) and the rigid bodies' contact substeps.
- **tet-steps**: tets x steps (no finite elements with ``fragments.whole_body``).
- **frames** written: steps / output_every.
- **tets per smoothing neighbourhood** (``fracture.smoothing.length``): the tets in a ball of
  radius ``length`` (at most the body's); ``nodal`` smoothing applies its operator
  ``length / h`` times.
"""

from __future__ import annotations

import ast
import math
import operator
import re
from dataclasses import dataclass, fields
from pathlib import Path

from ..config.schema import Case, DynamicAnalysis
from ..errors import CaseError, FemFracError
from ..mesh.build import mesh_file_path
from ..solve.loading import time_grid

TETS_PER_H3 = 5.0
BYTES_PER_TET = 20.0
NODES_PER_TET = {1: 0.25, 2: 1.5}
# the stable step of central difference in units of h / c (see the module's description)
STABLE_STEP_PER_H = {1: 0.7, 2: 0.2}
HOW_TO_RAISE = "pass --allow-large to run it anyway"


@dataclass(frozen=True)
class Bounds:
    """The most of each quantity a case may imply without ``--allow-large``."""

    tets: float = 5e6
    dofs: float = 1e7
    steps: float = 1e7
    tet_steps: float = 1e10
    frames: float = 1e5
    neighbourhood: float = 1e4
    smoothing_passes: float = 100

    def describe(self) -> str:
        return ", ".join(f"{f.name.replace('_', ' ')} {getattr(self, f.name):g}"
                         for f in fields(self))


BOUNDS = Bounds()


@dataclass(frozen=True)
class Estimate:
    """What a case implies; ``tets`` and ``h`` are ``None`` where they cannot be told."""

    tets: float | None
    tets_key: tuple
    tets_how: str
    h: float | None
    steps: float
    steps_key: tuple
    frames: float


def check_budget(case: Case, case_dir: Path, bounds: Bounds | None = BOUNDS) -> None:
    """Raise a located :class:`CaseError` when ``case`` implies more work than ``bounds``
    (``None``: no bounds). Reads no mesh: only the case and the size of a mesh file."""
    if bounds is None:
        return
    e = estimate(case, case_dir)
    order = case.mesh.order
    if e.tets is not None:
        dofs = 3 * NODES_PER_TET[order] * e.tets
        _bound(e.tets, bounds.tets, e.tets_key, f"about {e.tets:.3g} tets ({e.tets_how})",
               "tets")
        _bound(dofs, bounds.dofs, e.tets_key, f"about {dofs:.3g} dofs (P{order}, "
               f"{e.tets:.3g} tets: {e.tets_how})", "dofs")
    _bound(e.steps, bounds.steps, e.steps_key, f"{e.steps:.3g} steps", "steps")
    fe = case.fragments is None or not case.fragments.whole_body
    if e.tets is not None and fe:
        _bound(e.tets * e.steps, bounds.tet_steps, e.steps_key,
               f"{e.steps:.3g} steps of about {e.tets:.3g} tets", "tet-steps")
    _bound(e.frames, bounds.frames, ("analysis", "output_every"),
           f"{e.frames:.3g} output frames", "frames")
    _check_smoothing(case, e, bounds)


def _bound(value: float, bound: float, key: tuple, what: str, unit: str) -> None:
    if not value <= bound:
        raise CaseError(key, f"{what}: over the bound of {bound:g} {unit}; {HOW_TO_RAISE}")


def _check_smoothing(case: Case, e: Estimate, bounds: Bounds) -> None:
    f = case.fracture
    if f is None or f.smoothing.length is None or e.h is None:
        return
    key = ("fracture", "smoothing", "length")
    ratio = f.smoothing.length / e.h
    if f.smoothing.method == "nodal":
        _bound(math.ceil(ratio), bounds.smoothing_passes, key,
               f"length / h = {ratio:.3g} passes of nodal smoothing (h = {e.h:g})", "passes")
        return
    ball = TETS_PER_H3 * 4.0 / 3.0 * math.pi * ratio**3
    tets = min(ball, e.tets) if e.tets is not None else ball
    _bound(tets, bounds.neighbourhood, key, f"about {tets:.3g} tets in a smoothing "
           f"neighbourhood (radius {f.smoothing.length:g}, h = {e.h:g})",
           "tets per neighbourhood")


def estimate(case: Case, case_dir: Path) -> Estimate:
    """The work ``case`` implies (see the module's description)."""
    mesh = case.mesh
    h = mesh.element_size
    tets, how, key = None, "", ("mesh", "element_size")
    if mesh.geometry is not None:
        tets, how = _primitive_tets(mesh.geometry, h), f"{TETS_PER_H3:g} V / h^3"
    else:
        path = mesh_file_path(mesh, case_dir)
        if path.suffix == ".geo":
            tets, h, how = _geo_tets(path, h)
            key = ("mesh", "element_size") if mesh.element_size is not None else ("mesh",
                                                                                    "file")
        elif path.is_file():
            size = path.stat().st_size
            tets, key = size / BYTES_PER_TET, ("mesh", "file")
            how = f"a file of {size / 1e6:.3g} MB at {BYTES_PER_TET:g} bytes per tet"
    grid = time_grid(case.analysis)
    steps = float(grid.steps) * _substeps(case, grid.dt, h)
    if case.fragments is not None:
        steps *= case.fragments.contact_substeps
    steps_key = ("analysis", "steps") if getattr(case.analysis, "steps", None) else (
        ("analysis", "dt") if getattr(case.analysis, "dt", None) else ("analysis",))
    every = getattr(case.analysis, "output_every", 1)
    return Estimate(tets, key, how, h, steps, steps_key, grid.steps / every + 1)


def _primitive_tets(g, h: float) -> float:
    """TETS_PER_H3 V / h^3 of a primitive, from ratios (no overflow for huge lengths)."""
    sector = {"full": 1.0, "half": 0.5, "quarter": 0.25, "octant": 0.125}
    if g.type == "box":
        v = math.prod(x / h for x in g.lengths)
    elif g.type == "cylinder":
        v = math.pi * (g.radius / h) ** 2 * (g.height / h)
    elif g.type == "sphere":
        v = 4.0 / 3.0 * math.pi * (g.radius / h) ** 3
    elif g.type == "hollow_sphere":
        a, b = g.inner_radius / h, g.outer_radius / h
        v = 4.0 / 3.0 * math.pi * (b**3 - a**3) * sector[g.sector]
    else:
        a, b = g.inner_radius / h, g.outer_radius / h
        v = math.pi * (b**2 - a**2) * (g.height / h) * sector[g.sector]
    return TETS_PER_H3 * v


def _substeps(case: Case, dt: float, h: float | None) -> float:
    """Substeps per step of central difference with ``substeps: true`` (else 1)."""
    a = case.analysis
    if not (isinstance(a, DynamicAnalysis) and a.integrator == "central_difference"
            and a.substeps and h is not None):
        return 1.0
    materials = [case.material, *case.regions]
    e = max(m.youngs_modulus for m in materials if m.youngs_modulus is not None)
    rho = min((m.density for m in materials if m.density is not None), default=None)
    if rho is None:
        return 1.0  # refused elsewhere: a dynamic analysis needs a density
    nu = max(m.poissons_ratio for m in materials if m.poissons_ratio is not None)
    c = math.sqrt(e / rho * (1 - nu) / ((1 + nu) * (1 - 2 * nu)))
    return max(1.0, math.ceil(dt / (STABLE_STEP_PER_H[case.mesh.order] * h / c)))


# --- a .geo file's extent, when it is written in plain arithmetic ------------------------

_OPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
        ast.Div: operator.truediv, ast.USub: operator.neg, ast.UAdd: operator.pos}
_STATEMENT = re.compile(r"^\s*(?:(Box|Point)\s*\(\s*[\w\s+\-*/]*\)\s*=\s*\{(.*)\}"
                        r"|(Mesh\.MeshSizeMax|Mesh\.CharacteristicLengthMax|[A-Za-z_]\w*)"
                        r"\s*=\s*([^{}]*))\s*$", re.S)


def _geo_tets(path: Path, h: float | None) -> tuple[float | None, float | None, str]:
    """(tets, h, how) of a .geo file from the box around its Box and Point statements."""
    try:
        text = path.read_text(errors="replace") if path.stat().st_size < 2**20 else ""
    except OSError:
        return None, h, ""
    text = re.sub(r"/\*.*?\*/", " ", re.sub(r"//[^\n]*", " ", text), flags=re.S)
    names: dict[str, float] = {}
    lo, hi = [math.inf] * 3, [-math.inf] * 3
    size = None
    for statement in text.split(";"):
        m = _STATEMENT.match(statement)
        if m is None:
            continue
        values = [_value(x, names) for x in (m.group(2) or "").split(",")]
        if m.group(1) == "Box" and len(values) >= 6 and None not in values[:6]:
            corners = [values[:3], [a + b for a, b in zip(values[:3], values[3:6],
                                                           strict=True)]]
        elif m.group(1) == "Point" and len(values) >= 3 and None not in values[:3]:
            corners = [values[:3]]
        else:
            value = _value(m.group(4) or "", names) if m.group(3) else None
            if value is not None and m.group(3).startswith("Mesh."):
                size = value
            elif value is not None:
                names[m.group(3)] = value
            continue
        for corner in corners:
            lo = [min(a, b) for a, b in zip(lo, corner, strict=True)]
            hi = [max(a, b) for a, b in zip(hi, corner, strict=True)]
    h = h if h is not None else size
    extent = [b - a for a, b in zip(lo, hi, strict=True)]
    if h is None or not h > 0 or not all(math.isfinite(x) and x > 0 for x in extent):
        return None, h, ""
    return (TETS_PER_H3 * math.prod(x / h for x in extent), h,
            f"{TETS_PER_H3:g} V / h^3 over the bounding box of the .geo file's boxes and "
            "points")


def _value(text: str, names: dict[str, float]) -> float | None:
    """A plain arithmetic expression of numbers and known names, else ``None``."""
    try:
        return float(_eval(ast.parse(text.strip(), mode="eval").body, names))
    except (SyntaxError, ValueError, TypeError, KeyError, ZeroDivisionError, OverflowError,
            RecursionError, FemFracError):
        return None


def _eval(node, names: dict[str, float]) -> float:
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
            and not isinstance(node.value, bool):
        return float(node.value)
    if isinstance(node, ast.Name):
        return names[node.id]
    if isinstance(node, ast.BinOp) and type(node.op) in _OPS:
        return _OPS[type(node.op)](_eval(node.left, names), _eval(node.right, names))
    if isinstance(node, ast.UnaryOp) and type(node.op) in _OPS:
        return _OPS[type(node.op)](_eval(node.operand, names))
    raise ValueError("not plain arithmetic")
