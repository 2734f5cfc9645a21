"""Turn a case's supports and loads into arrays on a :class:`~fem_frac.fem.space.Space`.

Errors name the case key they come from (``boundary_conditions[i].boundary``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..config import schema
from ..errors import CaseError
from ..fem import loads, surface
from ..fem.space import Space
from ..fem.surface import FaceLookup, Faces
from ..mesh.mesh import exterior_facets, facet_keys
from ..mesh.selection import ALL_BOUNDARY, box_facets, in_box, named_facets

AXES = "xyz"
# the boundary group of crack faces (fem_frac.fracture.topology.CRACK)
CRACK = "crack"


@dataclass(frozen=True, eq=False)
class Constraints:
    """Prescribed displacements: dof ids ``(k,)`` (sorted, unique), values ``(k,)`` at curve
    factor 1 and the index ``(k,)`` of the load curve each follows."""

    dofs: np.ndarray
    values: np.ndarray
    curve: np.ndarray


@dataclass(frozen=True, eq=False)
class Problem:
    """Supports and loads as functions of time.

    ``forces[c]`` is the external force ``(n_dofs,)`` that follows curve ``c``;
    ``tractions[c]`` and ``pressures[c]`` are its surface loads of each kind (tractions keep
    their world direction, pressures follow the face: what a rigid piece that takes their
    faces along needs, fem_frac.rigid.loads); ``reaction_groups`` maps a label (the
    boundary name, or ``boundary_conditions[i]``) to the dofs whose reaction forces it sums;
    ``resultants`` maps a label of every load (its boundary name, ``boundary_conditions[i]``
    where that name is taken, ``body_force``) to its curve index and its total force ``(3,)``
    at curve factor 1 on this space (zero where its faces have left). ``selections``: per
    condition, the face rows (``4 tet + local face``) it selected where every one is an
    exterior face and the group is not ``crack`` (which an insertion extends), else
    ``None``. A mesh a crack reconnected from this one (the same tets in the same order,
    old ids kept) holds the same exterior faces at the same rows, and its outer faces
    (those of every box and of ``boundary``) are the same rows in the same order, the
    crack's new faces going to its own group; so :func:`build_problem` takes them at their
    rows there, without sorting the mesh's faces: the same faces in the same order as a
    fresh selection.
    """

    space: Space
    constraints: Constraints
    forces: np.ndarray  # (n_curves, n_dofs)
    curves: list = field(default_factory=list)
    curve_names: list[str] = field(default_factory=list)
    reaction_groups: dict[str, np.ndarray] = field(default_factory=dict)
    descriptions: list[str] = field(default_factory=list)
    tractions: np.ndarray | None = None  # (n_curves, n_dofs), None: no surface loads
    pressures: np.ndarray | None = None  # (n_curves, n_dofs)
    resultants: dict[str, tuple[int, np.ndarray]] = field(default_factory=dict)
    selections: tuple = ()

    def factors(self, t: float) -> np.ndarray:
        return np.array([c(t) for c in self.curves] or [0.0])

    def external_force(self, t: float) -> np.ndarray:
        """External force ``(n_dofs,)`` at time ``t``."""
        return self.factors(t)[: len(self.forces)] @ self.forces

    def prescribed(self, t: float) -> np.ndarray:
        """Values ``(k,)`` of the constrained dofs at time ``t``."""
        return self.constraints.values * self.factors(t)[self.constraints.curve]


def outer_facets(mesh, lookup: FaceLookup | None = None) -> np.ndarray:
    """Exterior faces ``(k, 3)`` less the faces of cracks (group ``crack``): what the group
    ``boundary`` and box selections choose from, so crack faces stay traction-free
    (``lookup``: the mesh's faces, already sorted)."""
    exterior = exterior_facets(mesh.tets) if lookup is None else lookup.exterior()
    crack = mesh.boundaries.get(CRACK)
    if crack is None or len(crack) == 0:
        return exterior
    keys = facet_keys(exterior, mesh.n_points)
    return exterior[~np.isin(keys, facet_keys(crack, mesh.n_points))]


class _Tables:
    """The sorted faces of a mesh and its outer faces, made on first use (a problem whose
    selections all carry over from the mesh a crack reconnected needs neither)."""

    def __init__(self, mesh):
        self.mesh = mesh

    @cached_property
    def lookup(self) -> FaceLookup:
        return FaceLookup(self.mesh.tets, self.mesh.n_points)

    @cached_property
    def exterior(self) -> np.ndarray:
        return outer_facets(self.mesh, self.lookup)


def _select(space: Space, bc, index: int, tables: _Tables, strict: bool = True,
            rows: np.ndarray | None = None) -> Faces | np.ndarray | None:
    """The faces a condition selects, with their nodes and quadrature, or for a ``vertices``
    selection the scalar nodes in its box (None: nothing, and not ``strict``). ``rows``:
    the rows of its faces where known, all exterior (:func:`build_problem`)."""
    mesh = space.mesh
    if getattr(bc, "vertices", None) is not None:
        nodes = np.flatnonzero(in_box(mesh, space.node_points, bc.vertices.min,
                                      bc.vertices.max))
        if len(nodes) == 0:
            if not strict:
                return None
            raise CaseError(("boundary_conditions", index, "vertices"),
                            "the box 'vertices' holds no node of the mesh")
        return nodes
    if rows is not None:
        return surface.faces_at(space, rows, exterior=True)
    if bc.boundary is not None:
        try:
            triples = (tables.exterior if bc.boundary == ALL_BOUNDARY
                       and ALL_BOUNDARY not in mesh.boundaries
                       else named_facets(mesh, bc.boundary))
        except LookupError as exc:
            raise CaseError(("boundary_conditions", index, "boundary"), str(exc)) from None
        key = ("boundary_conditions", index, "boundary")
        what = f"boundary '{bc.boundary}'"
    else:
        triples = box_facets(mesh, bc.box.min, bc.box.max, tables.exterior)
        key = ("boundary_conditions", index, "box")
        what = "the box"
    if len(triples) == 0:
        if not strict:
            return None
        raise CaseError(key, f"{what} selects no boundary faces")
    return surface.faces_of(space, triples, tables.lookup)


def _label(bc, index: int) -> str:
    return bc.boundary if bc.boundary is not None else f"boundary_conditions[{index}]"


def build_problem(
    space: Space,
    conditions: list,
    body_force: schema.BodyForce | None,
    density,
    analysis=None,
    load_curves: dict | None = None,
    strict: bool = True,
    carried: tuple | None = None,
) -> Problem:
    """Constraints, external forces and reaction groups of the case on ``space``.

    Where two conditions prescribe the same dof, the later one wins. ``analysis`` sets the
    default curve and the end time of ramps (static when omitted). ``strict``: a selection
    without faces is an error; otherwise (a mesh whose loaded or supported part has left as
    a rigid piece) the condition acts on nothing here (the piece takes the loads on its
    faces along: fem_frac.rigid.loads). ``carried``: the :attr:`Problem.selections` of the
    mesh a crack reconnected into this one, taken at their rows (:class:`Problem`).
    """
    from .loading import resolve_curves

    analysis = analysis if analysis is not None else schema.StaticAnalysis()
    names, curves, curve_of = resolve_curves(_curve_keys(conditions, body_force),
                                             load_curves or {}, analysis)
    tables = _Tables(space.mesh)
    forces = np.zeros((len(names), space.n_dofs))
    surface = {schema.Traction: np.zeros_like(forces), schema.Pressure: np.zeros_like(forces)}
    groups: dict[str, np.ndarray] = {}
    resultants: dict[str, tuple[int, np.ndarray]] = {}
    described, supports, selections = [], [], []
    for i, bc in enumerate(conditions):
        facets = _select(space, bc, i, tables, strict, carried[i] if carried else None)
        selections.append(facets.rows if isinstance(facets, Faces) and facets.exterior
                          and bc.boundary != CRACK else None)
        label = _label(bc, i)
        timing = f", curve {names[curve_of[i]]}" if hasattr(bc, "curve") else ""
        if isinstance(bc, _LOADS):
            key = label if label not in resultants else f"boundary_conditions[{i}]"
            resultants[key] = (int(curve_of[i]), np.zeros(3))
        if facets is None:  # (only when not strict)
            if not isinstance(bc, _LOADS):
                groups[label] = np.zeros(0, dtype=np.int64)
            described.append(f"{bc.type} on {label} (no faces left)")
        elif isinstance(bc, _LOADS):
            load = _add_load(space, bc, facets, int(curve_of[i]), forces, surface)
            resultants[key] = (int(curve_of[i]), load.reshape(-1, 3).sum(axis=0))
            described.append(f"{bc.type} on {label} ({len(facets)} faces{timing})")
        else:
            nodes, comps = _supported(space, bc, i, facets)
            supports.append((nodes, comps, curve_of[i]))
            groups[label] = (3 * nodes[:, None] + np.arange(3)).ravel()
            fixed = "".join(AXES[c] for c in comps)
            described.append(f"{bc.type} ({fixed}) on {label} ({len(nodes)} nodes{timing})")
    if body_force is not None:
        curve = int(curve_of[-1])
        forces[curve] += _weight(space, body_force, density, curve, resultants)
        described.append(f"gravity {tuple(body_force.gravity)}, curve {names[curve]}")
    return Problem(space, _constraints(supports), forces, curves, names, groups, described,
                   surface[schema.Traction], surface[schema.Pressure], resultants,
                   tuple(selections))


# conditions that load the surface (the others prescribe displacements)
_LOADS = (schema.Traction, schema.Pressure)


def _curve_keys(conditions: list, body_force) -> list[tuple]:
    """(case key, curve name or None) of every condition, then of the body force."""
    keys = [(("boundary_conditions", i, "curve"), getattr(bc, "curve", None))
            for i, bc in enumerate(conditions)]
    if body_force is not None:
        keys.append((("body_force", "curve"), body_force.curve))
    return keys


def _add_load(space: Space, bc, facets: Faces, curve: int, forces: np.ndarray,
              surface: dict) -> np.ndarray:
    """:func:`_surface_force`, added to ``forces[curve]`` and to its kind's in
    ``surface``."""
    load = _surface_force(space, bc, facets)
    forces[curve] += load
    kind = schema.Pressure if isinstance(bc, schema.Pressure) else schema.Traction
    surface[kind][curve] += load
    return load


def _surface_force(space: Space, bc, facets: Faces) -> np.ndarray:
    """Nodal force ``(n_dofs,)`` of a traction or pressure at curve factor 1."""
    if isinstance(bc, schema.Traction):
        return surface.face_load(space, facets, traction=bc.traction)
    return surface.face_load(space, facets, pressure=bc.pressure)


def _supported(space: Space, bc, index: int,
               facets: Faces | np.ndarray) -> tuple[np.ndarray, dict]:
    """Scalar nodes of the faces (or the nodes selected) and the prescribed value of each
    constrained component."""
    nodes = facets if isinstance(facets, np.ndarray) else surface.face_nodes(facets)
    if isinstance(bc, schema.Fixed):
        return nodes, {0: 0.0, 1: 0.0, 2: 0.0}
    if isinstance(bc, schema.Displacement):
        return nodes, {k: v for k, v in enumerate((bc.x, bc.y, bc.z)) if v is not None}
    axis = surface.normal_axis(facets)  # symmetry
    if axis is None:
        raise CaseError(
            ("boundary_conditions", index, "boundary"),
            f"symmetry needs a plane normal to x, y or z; {_label(bc, index)} is not",
        )
    return nodes, {axis: 0.0}


def _constraints(supports: list[tuple]) -> Constraints:
    """Constraints of the ``(nodes, {component: value}, curve)`` supports in case order; a dof
    prescribed twice keeps the later value."""
    chunks = [(3 * nodes + comp, np.full(len(nodes), value), np.full(len(nodes), curve))
              for nodes, comps, curve in supports for comp, value in comps.items()]
    if not chunks:
        return Constraints(np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0, dtype=np.int64))
    all_dofs, all_values, all_curves = (np.concatenate(c) for c in zip(*chunks, strict=True))
    # keep the last occurrence of each dof: unique on the reversed arrays
    dofs, first = np.unique(all_dofs[::-1], return_index=True)
    return Constraints(dofs, all_values[::-1][first], all_curves[::-1][first])


def _weight(space: Space, body_force, density, curve: int, resultants: dict) -> np.ndarray:
    """:func:`_gravity`, its resultant booked under ``body_force`` in ``resultants``."""
    weight = _gravity(space, body_force, density)
    resultants["body_force"] = (curve, weight.reshape(-1, 3).sum(axis=0))
    return weight


def _gravity(space: Space, body_force, density) -> np.ndarray:
    """Nodal force ``(n_dofs,)`` of gravity at curve factor 1 (density per element or one)."""
    if density is None or not np.all(np.isfinite(density)):
        raise CaseError(("body_force", "gravity"),
                        "gravity needs material.density (for every element)")
    g = np.asarray(body_force.gravity)
    rho = np.asarray(density, dtype=float)
    return loads.body_load(space, rho[:, None] * g if rho.ndim else rho * g)


def free_rigid_modes(space: Space, constrained: np.ndarray,
                     nodes: np.ndarray | None = None) -> list[str]:
    """Rigid-body motions the constraints leave free (names like ``translation x``).

    A static solve with any free mode is singular. Checked on the whole body, or on the
    scalar ``nodes`` of one piece of it (a fragment): translations and the rotations about
    its centroid, restricted to the constrained dofs among its own.
    """
    nodes = np.arange(space.n_nodes) if nodes is None else np.asarray(nodes, dtype=np.int64)
    x = space.node_points[nodes]
    x = x - x.mean(axis=0)
    scale = np.abs(x).max() or 1.0
    modes = np.zeros((3 * len(nodes), 6))
    for k in range(3):
        modes[k::3, k] = 1.0
    # rotation about axis k: velocity e_k x x
    for k in range(3):
        w = np.zeros(3)
        w[k] = 1.0
        modes[:, 3 + k] = (np.cross(w, x) / scale).ravel()
    local = np.full(space.n_nodes, -1, dtype=np.int64)
    local[nodes] = np.arange(len(nodes))
    c = np.asarray(constrained, dtype=np.int64)
    c = c[local[c // 3] >= 0]
    r = modes[3 * local[c // 3] + c % 3]
    names = [f"translation {a}" for a in AXES] + [f"rotation about {a}" for a in AXES]
    if r.shape[0] == 0:
        return names
    # the 6 columns' right singular vectors, from the small triangular factor of r (an SVD
    # of r itself with full_matrices would build a k x k matrix for k constrained dofs)
    if r.shape[0] > 6:
        r = np.linalg.qr(r, mode="r")
    _, s, vt = np.linalg.svd(r, full_matrices=True)
    rank = int(np.sum(s > 1e-9 * s.max()))
    if rank == 6:
        return []
    free = vt[rank:]
    return [names[int(np.argmax(np.abs(v)))] for v in free]
