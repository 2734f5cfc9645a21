"""The point data of quadrature-point fields (fem_frac.writers.fields.nodal_average): at a
node, the volume-weighted mean of the elements around it.

What it guarantees, and what is tested here to round-off: a constant is reproduced; a
linear field ``f`` comes out as ``f(c_a)``, ``c_a`` the volume-weighted mean of the
centroids of the elements around node ``a`` (each element's mean of a linear field is its
value at the centroid, and the quadrature of P1 and P2 integrates it exactly), so it is
exact wherever the patch is symmetric about the node (the interior vertices of the
structured box) and biased by ``grad f . (c_a - x_a)`` elsewhere (the boundary). A run
writes it as point data beside the cell data it is made of.

Round-off: each value is a ratio of two sums of at most ``k`` positive terms (``k``: the
elements around a node times their quadrature points), so its relative error is below
``2 k eps``.
"""

from __future__ import annotations

import meshio
import numpy as np
import pytest

from fem_frac.app.cli import main
from fem_frac.fem.space import build_space
from fem_frac.mesh import tet_volumes
from fem_frac.writers.fields import nodal_average
from meshes import structured_box
from solve import write_case

EPS = np.finfo(float).eps
GRAD, C0 = np.array([1.0, -2.0, 0.5]), 3.0


def linear(space) -> np.ndarray:
    """``C0 + GRAD . x`` at the quadrature points ``(n_tets, n_qp)``."""
    x = np.asarray(space.basis.global_coordinates())
    return C0 + np.einsum("i,ieq->eq", GRAD, x)


def round_off(space) -> float:
    """``2 k eps``: ``k`` the most elements around a node times the quadrature points."""
    per_node = np.bincount(space.basis.element_dofs.ravel(), minlength=space.n_nodes)
    return 2 * per_node.max() * space.n_qp * EPS


def patch_centroids(space) -> np.ndarray:
    """``c_a (n_nodes, 3)``: the volume-weighted mean of the centroids of the elements
    around each node (from the vertices: straight-sided tets)."""
    mesh = space.mesh
    v = tet_volumes(mesh.points, mesh.tets)
    centroid = mesh.points[mesh.tets].mean(axis=1)
    out = np.zeros((space.n_nodes, 3))
    for a, elements in enumerate(patches(space)):
        out[a] = v[elements] @ centroid[elements] / v[elements].sum()
    return out


def patches(space) -> list[np.ndarray]:
    """The elements around each node, one node at a time (the reference the vectorized
    projection is checked against)."""
    dofs = space.basis.element_dofs.T  # (n_tets, n_local)
    return [np.flatnonzero((dofs == a).any(axis=1)) for a in range(space.n_nodes)]


@pytest.mark.parametrize("order", [1, 2])
def test_a_constant_is_reproduced_at_every_node(order):
    space = build_space(structured_box((3, 3, 2), distortion=0.3, seed=1), order)
    value = -7.25
    p = nodal_average(space, np.full((1, space.mesh.n_tets, space.n_qp), value))[0]
    assert np.abs(p - value).max() <= round_off(space) * abs(value)


@pytest.mark.parametrize("order", [1, 2])
def test_a_linear_field_comes_out_at_the_patch_centroid(order):
    """``p_a = f(c_a)`` at every node of a distorted mesh, the boundary included."""
    space = build_space(structured_box((3, 3, 2), distortion=0.3, seed=2), order)
    p = nodal_average(space, linear(space)[None])[0]
    expected = C0 + patch_centroids(space) @ GRAD
    scale = np.abs(linear(space)).max()
    assert np.abs(p - expected).max() <= round_off(space) * scale
    # the bias at the boundary: of the order of the element size times the gradient
    exact_at_node = C0 + space.node_points @ GRAD
    assert np.abs(p - exact_at_node).max() > 0.1 * np.linalg.norm(GRAD) / 3


@pytest.mark.parametrize("order", [1, 2])
def test_a_linear_field_is_exact_at_interior_nodes_of_symmetric_patches(order):
    """The structured box's tets are symmetric about every interior vertex (and mid-edge
    node): there ``c_a = x_a`` and the projection is exact."""
    space = build_space(structured_box((4, 4, 4)), order)
    x = space.node_points
    interior = np.all((x > 1e-9) & (x < 1.0 - 1e-9), axis=1)
    assert np.abs(patch_centroids(space)[interior] - x[interior]).max() <= 1e-15
    p = nodal_average(space, linear(space)[None])[0]
    scale = np.abs(linear(space)).max()
    assert np.abs(p - (C0 + x @ GRAD))[interior].max() <= round_off(space) * scale


BEAM = {
    "mesh": {"geometry": {"type": "box", "lengths": [1.0, 0.2, 0.2]}, "element_size": 0.1,
             "order": 1},
    "material": {"youngs_modulus": 200e9, "poissons_ratio": 0.3},
    "plasticity": {"yield_stress": 250e6, "hardening": 1e10},
    "boundary_conditions": [
        {"type": "fixed", "boundary": "xmin"},
        {"type": "displacement", "boundary": "xmax", "z": -1e-2},
    ],
    "analysis": {"type": "quasi_static", "steps": 3},
}


def test_a_run_writes_the_plastic_strain_as_point_data_beside_the_cell_data(tmp_path):
    """In the last .vtu of a beam bent past yield, every node's
    ``equivalent_plastic_strain_nodal`` is the volume-weighted mean of the cell values
    ``equivalent_plastic_strain`` around it, computed here from the file."""
    path = write_case(tmp_path / "beam.yaml", BEAM)
    assert main(["run", str(path), "-o", str(tmp_path / "out"), "-q"]) == 0
    m = meshio.read(sorted((tmp_path / "out").glob("beam_*.vtu"))[-1])
    tets = m.cells_dict["tetra"]
    cell = m.cell_data_dict["equivalent_plastic_strain"]["tetra"]
    assert cell.max() > 0 and cell.min() == 0  # yielded at the root only
    v = np.abs(tet_volumes(m.points, tets))
    total = np.bincount(tets.ravel(), weights=np.repeat(v * cell, 4), minlength=len(m.points))
    volume = np.bincount(tets.ravel(), weights=np.repeat(v, 4), minlength=len(m.points))
    point = m.point_data["equivalent_plastic_strain_nodal"]
    # sums of at most k terms each (k: tets around a node), volumes computed two ways
    k = np.bincount(tets.ravel()).max()
    assert np.abs(point - total / volume).max() <= 4 * k * EPS * cell.max()
    assert m.point_data["plastic_strain_nodal"].shape == (len(m.points), 6)
    assert "plastic_strain" in m.cell_data_dict  # the cell data is kept
