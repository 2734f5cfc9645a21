"""Rigid bodies far from convex touch by their own tets (fem_frac/rigid/nonconvex.py).

Two pieces of a 2 x 1 x 1 box of tets, cut along a step: piece A holds x < 1 below
z = 0.5 and x < 1.5 above it, piece B the rest. Each is an L whose hull holds a triangle of
the xz section more than itself (area 0.125: 10 % of A's 1.25, 1/6 of B's 0.75), and their
hulls overlap across the whole step, 0.5 deep along x.
"""

from __future__ import annotations

import numpy as np
import pytest

from fem_frac.rigid.body import angular_velocity, make_body, quaternion_from_matrix
from fem_frac.rigid.fragment import RigidFragment, contact_points
from fem_frac.rigid.mass import mass_properties
from fem_frac.rigid.nonconvex import NONCONVEX, own_shape, touching_shapes
from fem_frac.rigid.pairs import PairLaw, step_all
from tests.meshes import structured_box

ROUND_OFF = 1e-12


def _piece(points, tets, fragment_id, velocity=(0.0, 0.0, 0.0), shift=(0.0, 0.0, 0.0)):
    used, local = np.unique(tets, return_inverse=True)
    x = points[used] + np.asarray(shift)
    cells = local.reshape(tets.shape)
    mp = mass_properties(x, cells, 1.0)
    coords = (x - mp.center) @ mp.axes
    body = make_body(mp.mass, mp.moments, contact_points(coords), mp.center,
                     quaternion_from_matrix(mp.axes), velocity=velocity)
    return RigidFragment(body, x, cells, coords, fragment_id, 0.0)


def _stepped_halves(velocity_a=(0.0, 0.0, 0.0), shift_b=(0.0, 0.0, 0.0)):
    grid = structured_box((4, 2, 2), (2.0, 1.0, 1.0))
    c = grid.points[grid.tets].mean(axis=1)
    in_a = np.where(c[:, 2] < 0.5, c[:, 0] < 1.0, c[:, 0] < 1.5)
    return (_piece(grid.points, grid.tets[in_a], 0, velocity_a),
            _piece(grid.points, grid.tets[~in_a], 1, shift=shift_b))


def test_an_l_shaped_piece_is_far_from_convex_and_a_box_is_not():
    a, b = _stepped_halves()
    assert own_shape(a).hull_excess == pytest.approx(0.1, rel=1e-12)
    assert own_shape(b).hull_excess == pytest.approx(1.0 / 6.0, rel=1e-12)
    grid = structured_box((2, 2, 2), (1.0, 1.0, 1.0))
    box = _piece(grid.points, grid.tets, 2)
    assert own_shape(box) is None and 0.1 > NONCONVEX


def test_interlocked_pieces_at_rest_stay_where_they_are():
    """By their own tets the two pieces touch along the step with gap 0 and stay put over
    100 steps; by their hulls (the former narrow phase) the projection throws them apart."""
    a, b = _stepped_halves()
    shapes = [own_shape(a), own_shape(b)]
    touch = touching_shapes(a.body, shapes[0], b.body, shapes[1], 1e-9)
    assert touch is not None and np.abs(touch.gap).max() < ROUND_OFF
    bodies = [a.body, b.body]
    for _ in range(100):
        bodies = step_all(bodies, [False, False], [True, True], 1e-3, np.zeros(3), [],
                          law=PairLaw(0.0, 0.5), shapes=shapes)[0]
    for before, after in zip((a.body, b.body), bodies, strict=True):
        np.testing.assert_allclose(after.position, before.position, rtol=0, atol=ROUND_OFF)
        np.testing.assert_allclose(after.momentum, 0.0, rtol=0, atol=ROUND_OFF)
    hulls = step_all([a.body, b.body], [False, False], [True, True], 1e-3, np.zeros(3), [],
                     law=PairLaw(0.0, 0.5))[0]
    assert np.linalg.norm(hulls[0].position - a.body.position) > 0.1


def test_a_piece_pushed_into_the_step_is_found_at_its_depth():
    """B moved 0.01 towards A along -x: A's vertices on the faces x = 1 and x = 1.5 are 0.01
    inside B, B's on them 0.01 inside A; every point's normal is +x (from A to B)."""
    a, b = _stepped_halves(shift_b=(-0.01, 0.0, 0.0))
    touch = touching_shapes(a.body, own_shape(a), b.body, own_shape(b), 0.0)
    deep = touch.gap < -1e-3
    np.testing.assert_allclose(touch.gap[deep], -0.01, rtol=1e-9)
    np.testing.assert_allclose(touch.normal[deep], np.tile([1.0, 0.0, 0.0], (deep.sum(), 1)),
                               atol=1e-12)
    assert np.all(np.isin(np.round(touch.points[deep, 0], 9), [0.99, 1.0, 1.49, 1.5]))


def test_a_piece_driven_into_the_other_stops_without_passing_and_keeps_momentum():
    """A moving at 1 m/s along +x against B at rest (inelastic, no friction): over 20 steps
    of 1 ms momentum is kept to round-off, the kinetic energy never rises, and no vertex of
    either goes into the other beyond round-off (by their hulls, A would be inside B's hull
    from the start: the hulls overlap 0.5 along x)."""
    a, b = _stepped_halves(velocity_a=(1.0, 0.0, 0.0))
    shapes = [own_shape(a), own_shape(b)]
    bodies = [a.body, b.body]
    p0 = sum(x.momentum for x in bodies)
    energy = kinetic(bodies)
    for _ in range(20):
        bodies = step_all(bodies, [False, False], [True, True], 1e-3, np.zeros(3), [],
                          law=PairLaw(0.0, 0.0), shapes=shapes)[0]
        np.testing.assert_allclose(sum(x.momentum for x in bodies), p0, rtol=0,
                                   atol=ROUND_OFF * np.linalg.norm(p0))
        assert kinetic(bodies) <= energy * (1 + ROUND_OFF)
        energy = kinetic(bodies)
        touch = touching_shapes(bodies[0], shapes[0], bodies[1], shapes[1], 0.0)
        assert touch is None or touch.gap.min() > -ROUND_OFF
    assert energy < 0.99 * kinetic([a.body, b.body])


def kinetic(bodies) -> float:
    return sum(0.5 * x.momentum @ x.momentum / x.mass
               + 0.5 * x.angular_momentum @ angular_velocity(x) for x in bodies)
