"""The probes of a case: checked on the first mesh before anything is written (located
errors), then read at every step, written or not, into ``<name>_probes.csv``.

Where a probe reads and how: :mod:`fem_frac.writers.probes`. Its weights are computed once
per mesh and again on every mesh a topology change makes (a point is located anew, a
boundary follows its faces); a probe that no finite element holds any more (its piece left
as a rigid body, or none is left) reads NaN.
"""

from __future__ import annotations

import numpy as np

from ..config.schema import Case
from ..errors import CaseError
from ..fracture.stage import FIELD as SMOOTHED
from ..mesh.selection import named_facets
from ..solve.discretization import Discretization
from ..solve.problem import outer_facets
from ..world.state import Body, World
from ..writers.directory import Manifest
from ..writers.fields import plastic_fields, plastic_point_fields, stress_fields
from ..writers.probes import (
    ProbeFile,
    Stencil,
    boundary_stencil,
    empty_stencil,
    point_stencil,
    read,
    tet_boxes,
)

VECTOR, TENSOR = ("_x", "_y", "_z"), ("_xx", "_yy", "_zz", "_xy", "_yz", "_xz")
# the columns of each field (a scalar's column is the field's name)
COMPONENTS = {"displacement": VECTOR, "velocity": VECTOR, "stress": TENSOR,
              "plastic_strain": TENSOR, "backstress": TENSOR, "plastic_strain_nodal": TENSOR}
# fields on the nodes (point data); the others are on the elements (cell data)
POINT_FIELDS = ("displacement", "velocity", "plastic_strain_nodal",
                "equivalent_plastic_strain_nodal")
PLASTIC = ("plastic_strain", "equivalent_plastic_strain", "plastic_strain_nodal",
           "equivalent_plastic_strain_nodal")


def columns(probes) -> list[str]:
    """``step``, ``time``, then ``<probe>_<field><component>`` of every probe's fields."""
    return ["step", "time"] + [f"{p.name}_{f}{c}" for p in probes for f in p.fields
                               for c in COMPONENTS.get(f, ("",))]


def missing(case: Case, field: str) -> str | None:
    """Why the run writes no ``field`` (``None``: it does)."""
    plasticity = case.plasticity
    if field == "velocity" and case.analysis.type != "dynamic":
        return f"a {case.analysis.type} analysis has no velocity"
    if field in PLASTIC and plasticity is None:
        return f"{field} needs a plasticity section"
    if field == "backstress" and (plasticity is None or plasticity.kinematic_hardening == 0):
        return "backstress needs plasticity with kinematic_hardening > 0"
    if field in ("fragment_id", SMOOTHED) and case.fracture is None:
        return f"{field} needs a fracture section"
    return None


class Places:
    """What locating probes on the mesh of ``disc`` needs, made once for all of them (on
    first use): the tets' bounding boxes, the exterior faces less the cracks'."""

    def __init__(self, disc: Discretization):
        self.space = disc.space
        self._boxes = self._exterior = None

    def stencil(self, probe) -> Stencil:
        """Where ``probe`` reads the mesh. Raises LookupError for a boundary name the mesh
        does not have."""
        space = self.space
        if probe.point is not None:
            if self._boxes is None:
                self._boxes = tet_boxes(space)
            return point_stencil(space, probe.point, self._boxes)
        if self._exterior is None:
            self._exterior = outer_facets(space.mesh)
        triples = named_facets(space.mesh, probe.boundary, self._exterior)
        facets = space.facet_indices(triples) if len(triples) else np.zeros(0, dtype=np.int64)
        return boundary_stencil(space, facets)


def check_probes(case: Case, disc: Discretization) -> None:
    """Every probe's name is new, its fields are written by this case, its boundary
    exists and has faces, its point lies in the mesh: else a located :class:`CaseError`."""
    seen: set[str] = set()
    places = Places(disc)
    for i, probe in enumerate(case.probes):
        mine = columns([probe])[2:]
        if probe.name in seen or seen.intersection(mine):
            raise CaseError(("probes", i, "name"), f"the columns of probe {probe.name!r} "
                            "are those of an earlier probe: give another name")
        seen.update([probe.name, *mine])
        for j, field in enumerate(probe.fields):
            why = missing(case, field)
            if why is not None:
                raise CaseError(("probes", i, "fields", j), why)
        try:
            found = places.stencil(probe).found
        except LookupError as exc:
            raise CaseError(("probes", i, "boundary"), str(exc)) from None
        if not found and probe.point is not None:
            lo, hi = disc.mesh.points.min(axis=0), disc.mesh.points.max(axis=0)
            raise CaseError(("probes", i, "point"), f"{list(probe.point)} lies in no element "
                            f"of the mesh (bounding box {lo.tolist()} to {hi.tolist()})")
        if not found:
            raise CaseError(("probes", i, "boundary"), f"boundary '{probe.boundary}' has no "
                            "exterior faces")


class ProbeRecorder:
    """An observer ``(n, world)`` of every committed step that writes a row of the probes'
    CSV. ``rigid``: the case hands pieces to rigid bodies (the series numbers the
    deformable pieces' ``fragment_id`` after them)."""

    name = "probes"

    def __init__(self, probes, file: ProbeFile, rigid: bool = False):
        self.probes, self.file, self.rigid = list(probes), file, rigid
        self._mesh = None
        self._stencils: list[Stencil] = []
        self._cells = np.zeros(0, dtype=np.int64)  # the elements any probe reads
        self._cell_rows: list = []  # each stencil's cell weights over those elements

    def __call__(self, n: int, world: World) -> None:
        self.file.write([n, float(world.t), *self.values(world)])

    def values(self, world: World) -> list[float]:
        """The probes' values at the committed ``world``, in the order of the columns."""
        body = world.body
        if body is None:
            return [np.nan] * (len(self.file.columns) - 2)
        if body.mesh is not self._mesh:
            self._locate(body.disc)
        fields = self._fields(body, world)
        out: list[float] = []
        for probe, st, cell_row in zip(self.probes, self._stencils, self._cell_rows,
                                       strict=True):
            for f in probe.fields:
                on_cells = f not in POINT_FIELDS
                value = fields[f]
                if value is None:  # a field not published at this step
                    out += [np.nan] * len(COMPONENTS.get(f, ("",)))
                    continue
                used = Stencil(st.nodes, cell_row, st.found) if on_cells else st
                out += read(used, value, on_cells).tolist()
        return out

    def _locate(self, disc: Discretization) -> None:
        self._mesh = disc.mesh
        self._stencils = []
        places = Places(disc)
        for probe in self.probes:
            try:
                self._stencils.append(places.stencil(probe))
            except LookupError:  # a group no face of this mesh carries any more
                self._stencils.append(empty_stencil(disc.space))
        self._cells = np.unique(np.concatenate(
            [st.cells.indices for st in self._stencils] + [np.zeros(0, dtype=np.int64)]))
        self._cell_rows = [st.cells[:, self._cells] for st in self._stencils]

    def _fields(self, body: Body, world: World) -> dict:
        """The fields the probes ask for: point fields on every node, cell fields on the
        elements the probes read."""
        wanted = {f for p in self.probes for f in p.fields}
        space, state, cells = body.disc.space, body.state, self._cells
        out: dict = {"displacement": state.u.reshape(-1, 3),
                     "velocity": state.v.reshape(-1, 3) if state.v is not None else None}
        if wanted & {"stress", "von_mises", "max_principal_stress"}:
            out.update(stress_fields(space, state.stress, cells))
        if wanted & {*PLASTIC, "backstress"} and state.plastic is not None:
            out.update(plastic_fields(space, state.plastic, cells))
            if wanted & {"plastic_strain_nodal", "equivalent_plastic_strain_nodal"}:
                out.update(plastic_point_fields(space, state.plastic))
        if "fragment_id" in wanted:
            offset = len(world.rigid) if self.rigid else 0
            out["fragment_id"] = body.labels[cells] + offset
        smoothed = body.fields.get(SMOOTHED)
        out[SMOOTHED] = smoothed[cells] if smoothed is not None else None
        return {f: out.get(f) for f in wanted}


def probe_recorder(case: Case, manifest: Manifest, name: str) -> ProbeRecorder | None:
    """The recorder of the case's probes writing ``<name>_probes.csv`` (entered in the
    manifest before it is created); ``None`` without probes."""
    if not case.probes:
        return None
    path = manifest.add(f"{name}_probes.csv")
    return ProbeRecorder(case.probes, ProbeFile(path, columns(case.probes)),
                         case.fragments is not None)
