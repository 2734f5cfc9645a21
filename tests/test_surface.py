"""Supports and loads from boundary triangles (fem_frac.fem.surface) against scikit-fem's
FacetBasis and facet dofs (fem_frac.fem.loads), which they replaced in build_problem: P1, P2,
curved P2, after a crack insertion, interface faces and reversed triples."""

from __future__ import annotations

import numpy as np
import pytest

from fem_frac.config import schema
from fem_frac.fem import loads, surface
from fem_frac.fem.space import build_space
from fem_frac.fracture import open_crack
from fem_frac.mesh import Mesh, exterior_facets
from fem_frac.mesh.mesh import TET_EDGES, TET_FACES, facet_keys
from fem_frac.solve.problem import build_problem, outer_facets
from meshes import structured_box

RTOL = 1e-13


def _named(mesh: Mesh) -> Mesh:
    """``mesh`` with groups xmin, xmax and zmax (its exterior faces on those planes)."""
    outer = exterior_facets(mesh.tets)
    x = mesh.points[outer]
    groups = {"xmin": np.all(np.abs(x[:, :, 0]) < 1e-12, axis=1),
              "xmax": np.all(np.abs(x[:, :, 0] - 1.0) < 1e-12, axis=1),
              "zmax": np.all(np.abs(x[:, :, 2] - 1.0) < 1e-12, axis=1)}
    return Mesh(mesh.points, mesh.tets, {k: outer[v] for k, v in groups.items()},
                edges=mesh.edges, edge_points=mesh.edge_points)


def _curved(mesh: Mesh) -> Mesh:
    edges = np.unique(np.sort(mesh.tets[:, TET_EDGES].reshape(-1, 2), axis=1), axis=0)
    rng = np.random.default_rng(5)
    shift = 0.02 * rng.uniform(-1, 1, (len(edges), 3))
    # the plane zmax stays a plane (its mid-edge nodes move within it): a symmetry plane
    shift[np.all(np.abs(mesh.points[edges][:, :, 2] - 1.0) < 1e-12, axis=1), 2] = 0.0
    mid = mesh.points[edges].mean(axis=1) + shift
    return Mesh(mesh.points, mesh.tets, mesh.boundaries, edges=edges, edge_points=mid)


def _cracked(mesh: Mesh) -> Mesh:
    """A crack through part of the plane x = 0.5 (open_crack, as the fracture stage)."""
    plane = np.flatnonzero(np.abs(mesh.points[:, 0] - 0.5) < 1e-12)[:6]
    new, _ = open_crack(mesh, plane, np.tile([1.0, 0.0, 0.0], (len(plane), 1)))
    assert len(new.boundaries["crack"]) > 0
    return new


def _meshes():
    box = _named(structured_box((4, 3, 3), distortion=0.15))
    return {"box": box, "curved": _curved(box), "cracked": _cracked(box),
            "cracked curved": _curved(_cracked(box))}


MESHES = _meshes()
CASES = [("box", 1), ("box", 2), ("curved", 2), ("cracked", 1), ("cracked", 2),
         ("cracked curved", 2)]


def _interior(mesh: Mesh) -> np.ndarray:
    """Some faces two tets share, reversed (an interface group)."""
    faces = mesh.tets[:, TET_FACES].reshape(-1, 3)
    _, first, count = np.unique(facet_keys(faces, mesh.n_points), return_index=True,
                                return_counts=True)
    return faces[first[count == 2]][::5, ::-1]


@pytest.mark.parametrize("name, order", CASES)
def test_faces_match_facet_basis(name, order):
    mesh = MESHES[name]
    space = build_space(mesh, order)
    lookup = surface.FaceLookup(mesh.tets, mesh.n_points)
    np.testing.assert_array_equal(lookup.exterior(), exterior_facets(mesh.tets))
    triples = np.vstack([exterior_facets(mesh.tets), _interior(mesh)])
    ids = space.facet_indices(triples)
    faces = surface.faces_of(space, triples, lookup)
    for load in ({"traction": (1.0, -2.0, 0.5)}, {"pressure": 3.0}):
        old = loads.surface_load(space, ids, **load)
        new = surface.face_load(space, faces, **load)
        np.testing.assert_allclose(new, old, rtol=0, atol=RTOL * np.abs(old).max())
    np.testing.assert_array_equal(surface.face_nodes(faces), loads.surface_nodes(space, ids))
    for group in ("xmin", "zmax"):
        g = mesh.boundaries[group]
        assert surface.normal_axis(surface.faces_of(space, g)) == \
            loads.mean_normal_axis(space, space.facet_indices(g))
    if mesh.boundaries.get("crack") is not None:
        crack = mesh.boundaries["crack"]
        np.testing.assert_array_equal(surface.face_nodes(surface.faces_of(space, crack)),
                                      loads.surface_nodes(space, space.facet_indices(crack)))


def test_a_triple_that_is_no_face_is_refused():
    mesh = MESHES["box"]
    space = build_space(mesh, 1)
    with pytest.raises(ValueError, match="not faces of the mesh"):
        surface.faces_of(space, np.array([[0, 1, mesh.n_points - 1]]))


def _conditions() -> list:
    return [
        schema.Fixed(type="fixed", boundary="xmin"),
        schema.Symmetry(type="symmetry", boundary="zmax"),
        schema.Displacement(type="displacement", boundary="xmax", x=0.01),
        schema.Traction(type="traction", boundary="xmax", traction=(0.5, 0, -1.0)),
        schema.Pressure(type="pressure", boundary="boundary", pressure=2.0),
        schema.Pressure(type="pressure", box={"min": (0, 0, 0), "max": (1, 1, 0)},
                        pressure=-1.5),
        schema.Traction(type="traction", boundary="crack", traction=(1.0, 2.0, 3.0)),
    ]


def _previous(space, conditions) -> tuple[np.ndarray, dict]:
    """Forces and prescribed dofs as build_problem made them with scikit-fem's facets."""
    mesh = space.mesh
    exterior = outer_facets(mesh)
    force = np.zeros(space.n_dofs)
    fixed: dict[int, float] = {}
    for bc in conditions:
        if bc.boundary is None:
            x = mesh.points[exterior].mean(axis=1)
            triples = exterior[np.all((x >= np.array(bc.box.min) - 1e-12)
                                      & (x <= np.array(bc.box.max) + 1e-12), axis=1)]
        else:
            triples = exterior if bc.boundary == "boundary" else mesh.boundaries[bc.boundary]
        ids = space.facet_indices(triples)
        if isinstance(bc, schema.Traction):
            force += loads.surface_load(space, ids, traction=bc.traction)
        elif isinstance(bc, schema.Pressure):
            force += loads.surface_load(space, ids, pressure=bc.pressure)
        else:
            nodes = loads.surface_nodes(space, ids)
            comps = {schema.Fixed: {0: 0.0, 1: 0.0, 2: 0.0},
                     schema.Symmetry: {loads.mean_normal_axis(space, ids): 0.0},
                     schema.Displacement: {0: 0.01}}[type(bc)]
            fixed.update({3 * int(n) + c: v for c, v in comps.items() for n in nodes})
    return force, fixed


@pytest.mark.parametrize("name, order", [("cracked", 1), ("cracked", 2),
                                         ("cracked curved", 2)])
def test_build_problem_as_before(name, order):
    space = build_space(MESHES[name], order)
    conditions = _conditions()
    problem = build_problem(space, conditions, None, None)
    force, fixed = _previous(space, conditions)
    new = problem.external_force(1.0)
    np.testing.assert_allclose(new, force, rtol=0, atol=RTOL * np.abs(force).max())
    dofs = np.array(sorted(fixed))
    np.testing.assert_array_equal(problem.constraints.dofs, dofs)
    np.testing.assert_array_equal(problem.prescribed(1.0), [fixed[d] for d in dofs])


def _recracked(mesh: Mesh) -> Mesh:
    """``mesh`` (:func:`_cracked`) cracked again, through part of the plane y = 1/3."""
    plane = np.flatnonzero(np.abs(mesh.points[:, 1] - 1 / 3) < 1e-12)[:5]
    new, _ = open_crack(mesh, plane, np.tile([0.0, 1.0, 0.0], (len(plane), 1)))
    assert len(new.boundaries["crack"]) > len(mesh.boundaries["crack"])
    return new


@pytest.mark.parametrize("order", [1, 2])
def test_a_reconnected_mesh_takes_its_selections_at_their_rows(order, monkeypatch):
    """After a crack insertion, supports and loads built on the faces the old mesh selected
    (its rows: :attr:`Problem.selections`) equal a fresh build to the bit: the same faces in
    the same order. The crack group, which the insertion extends, and a box of vertices
    are selected afresh; without them no face table is made."""
    before = MESHES["cracked"]
    after = _recracked(before)
    vertices = schema.Displacement(type="displacement", vertices={"min": (0, 0, 0),
                                                                  "max": (0.3, 1, 1)}, y=0.0)
    conditions = _conditions() + [vertices]
    old = build_problem(build_space(before, order), conditions, None, None)
    assert old.selections[-1] is None and old.selections[-2] is None  # vertices, crack
    assert all(rows is not None for rows in old.selections[:-2])
    space = build_space(after, order)
    fresh = build_problem(space, conditions, None, None)
    carried = build_problem(space, conditions, None, None, carried=old.selections)
    for name in ("forces", "tractions", "pressures"):
        np.testing.assert_array_equal(getattr(carried, name), getattr(fresh, name))
    for name in ("dofs", "values", "curve"):
        np.testing.assert_array_equal(getattr(carried.constraints, name),
                                      getattr(fresh.constraints, name))
    assert carried.reaction_groups.keys() == fresh.reaction_groups.keys()
    for key, dofs in fresh.reaction_groups.items():
        np.testing.assert_array_equal(carried.reaction_groups[key], dofs)
    assert carried.descriptions == fresh.descriptions
    for a, b in zip(carried.selections, fresh.selections, strict=True):
        assert (a is None) == (b is None) and (a is None or np.array_equal(a, b))

    plain = conditions[:-2]
    expected = build_problem(space, plain, None, None)

    def no_table(*args):
        raise AssertionError("a face table was made")

    monkeypatch.setattr("fem_frac.solve.problem.FaceLookup", no_table)
    again = build_problem(space, plain, None, None, carried=old.selections[:-2])
    np.testing.assert_array_equal(again.forces, expected.forces)
    np.testing.assert_array_equal(again.constraints.dofs, expected.constraints.dofs)
