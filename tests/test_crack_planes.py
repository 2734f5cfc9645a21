"""Prescribed crack planes (fem_frac.fracture.planes) and supports on the nodes of a box
(boundary conditions with ``vertices``)."""

from __future__ import annotations

import numpy as np

from fem_frac.config.schema import CrackPlane
from fem_frac.fem.tensors import mandel_from_matrix
from fem_frac.fracture.planes import normal_stress, plane_sites
from meshes import structured_box


def _plane(point, normal):
    return CrackPlane(point=point, normal=normal)


def test_a_plane_through_a_layer_of_vertices_is_usable_everywhere():
    mesh = structured_box((4, 2, 2), lengths=(1.0, 0.5, 0.5))
    sites = plane_sites(mesh.points, mesh.tets, [_plane([0.5, 0, 0], [2.0, 0, 0])])
    on = np.abs(mesh.points[:, 0] - 0.5) < 1e-12
    np.testing.assert_array_equal(sites.usable, on)
    assert not sites.crossing.any()
    # the tets touching the plane take its (unit) normal, the others none
    touching = on[mesh.tets].any(axis=1)
    np.testing.assert_array_equal(sites.elements, touching)
    np.testing.assert_allclose(sites.normal[touching], np.tile([1.0, 0, 0], (touching.sum(), 1)))
    np.testing.assert_array_equal(sites.normal[~touching], 0.0)


def test_a_plane_between_vertex_layers_offers_no_vertex():
    mesh = structured_box((4, 2, 2), lengths=(1.0, 0.5, 0.5))
    sites = plane_sites(mesh.points, mesh.tets, [_plane([0.4, 0, 0], [1, 0, 0])])
    assert not sites.usable.any() and not sites.elements.any()
    # it crosses the layer of cells x in [0.25, 0.5]
    centroids = mesh.points[mesh.tets].mean(axis=1)
    layer = (centroids[:, 0] > 0.25) & (centroids[:, 0] < 0.5)
    np.testing.assert_array_equal(sites.crossing, layer)


def test_a_vertex_whose_tets_cross_the_plane_may_not_split():
    """A diagonal plane of the box passes through vertices but also through tets: only the
    vertices none of whose tets it crosses may split."""
    mesh = structured_box((2, 2, 2), lengths=(1.0, 1.0, 1.0))
    sites = plane_sites(mesh.points, mesh.tets, [_plane([0, 0, 0], [1, -1, 0])])
    d = mesh.points[:, 0] - mesh.points[:, 1]
    crossing_tets = (d[mesh.tets].min(axis=1) < -1e-12) & (d[mesh.tets].max(axis=1) > 1e-12)
    np.testing.assert_array_equal(sites.crossing, crossing_tets)
    blocked = np.zeros(mesh.n_points, dtype=bool)
    blocked[mesh.tets[crossing_tets].ravel()] = True
    np.testing.assert_array_equal(sites.usable, (np.abs(d) < 1e-12) & ~blocked)


def test_normal_stress_on_the_plane():
    sigma = np.array([[3.0, 1.0, 0.0], [1.0, -2.0, 0.5], [0.0, 0.5, 1.0]])
    smoothed = np.stack([mandel_from_matrix(sigma), mandel_from_matrix(2 * sigma)], axis=1)
    n = np.array([[1.0, 0.0, 0.0], [0.0, 0.6, 0.8]])
    expected = [n[0] @ sigma @ n[0], n[1] @ (2 * sigma) @ n[1]]
    np.testing.assert_allclose(normal_stress(smoothed, n), expected, rtol=1e-14)


def test_vertices_support_holds_the_nodes_of_a_line(tmp_path):
    """A cantilever held only along one edge line (x = 0, z = 0) would turn about it; held
    along two lines it stands, and the support holds exactly the nodes on the lines (P2:
    with the mid-edge nodes)."""
    from fem_frac.app.driver import prepare
    from fem_frac.config.schema import Case
    from fem_frac.timing import StageTimer

    case = {
        "units": "SI",
        "mesh": {"geometry": {"type": "box", "lengths": [1.0, 0.2, 0.2]},
                 "element_size": 0.1, "order": 2},
        "material": {"youngs_modulus": 1e9, "poissons_ratio": 0.3},
        "boundary_conditions": [
            {"type": "fixed", "vertices": {"min": [0, 0, 0], "max": [0, 0.2, 0]}},
            {"type": "displacement", "vertices": {"min": [0, 0, 0.2], "max": [0, 0.2, 0.2]},
             "x": 0.0, "z": 0.0},
            {"type": "traction", "boundary": "xmax", "traction": [0, 0, -1e3]}],
    }
    setup = prepare(Case.model_validate(case), tmp_path, StageTimer())
    space = setup.disc.space
    x = space.node_points
    bottom = np.flatnonzero((np.abs(x[:, 0]) < 1e-12) & (np.abs(x[:, 2]) < 1e-12))
    top = np.flatnonzero((np.abs(x[:, 0]) < 1e-12) & (np.abs(x[:, 2] - 0.2) < 1e-12))
    assert len(bottom) >= 3  # corners and a mid-edge node at least
    expected = np.concatenate([3 * bottom[:, None] + np.arange(3),
                               3 * top[:, None] + np.array([0, 2])], axis=None)
    np.testing.assert_array_equal(setup.disc.constrained.dofs, np.sort(expected))
