"""The least translation out of an overlap (fem_frac/rigid/separation.py) and where it acts:
rigid bodies moved out of the finite elements (deformable.separate), pieces born inside
another moved out at their birth (pairs.place), pieces touching by their own tets
separated by their tets' overlaps (pairs.separate)."""

from __future__ import annotations

import numpy as np
import pytest

from fem_frac.rigid.birth import place
from fem_frac.rigid.deformable import detect, separate
from fem_frac.rigid.nonconvex import own_shape
from fem_frac.rigid.separation import (
    WEDGED,
    least_translation,
    overlap_constraints,
    tet_overlaps,
    world_tets,
)
from tests.test_deformable_contact import _block_and_cube
from tests.test_rigid_nonconvex import _stepped_halves

ROUND_OFF = 1e-12
UNIT = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)


def test_the_least_translation_of_known_overlaps():
    """One face 0.1 deep: 0.1 along its normal. Two faces at right angles, 0.1 and 0.2
    deep: (0.1, 0.2, 0). Faces 150 degrees apart, each 0.1 deep: it would be
    0.1 / cos(75) = 3.9 times the depth, beyond WEDGED: none. Opposite faces: no translation closes
    both. Nothing inside: none."""
    np.testing.assert_allclose(least_translation([[0, 0, 1]], [-0.1]), [0, 0, 0.1],
                               atol=ROUND_OFF)
    np.testing.assert_allclose(least_translation([[1, 0, 0], [0, 1, 0]], [-0.1, -0.2]),
                               [0.1, 0.2, 0.0], atol=ROUND_OFF)
    angle = np.radians(150.0)
    n = [[1, 0, 0], [np.cos(angle), np.sin(angle), 0]]
    assert WEDGED < 3.8
    np.testing.assert_array_equal(least_translation(n, [-0.1, -0.1]), 0.0)
    np.testing.assert_array_equal(least_translation([[1, 0, 0], [-1, 0, 0]], [-0.1, -0.1]),
                                  0.0)
    np.testing.assert_array_equal(least_translation([[0, 0, 1]], [0.1]), 0.0)
    # faces 60 degrees apart, each 0.1 deep: the translation meets both exactly
    n = np.array([[1, 0, 0], [0.5, np.sqrt(0.75), 0]])
    s = least_translation(n, [-0.1, -0.1])
    np.testing.assert_allclose(n @ s, 0.1, rtol=1e-12)
    assert np.linalg.norm(s) == pytest.approx(0.1 / np.cos(np.radians(30.0)), rel=1e-12)


def test_two_tets_overlap_by_their_least_separating_translation():
    """Random pairs of overlapping tets: moved along the returned normal by the depth (plus
    a round-off) they are apart; moved by 99.9 % of the depth along any of 200 random
    directions, they still overlap: the depth is the least translation (for convex
    polyhedra the separating axes are the face normals and the edge cross products)."""
    rng = np.random.default_rng(7)
    found = 0
    for _ in range(50):
        a = UNIT + rng.normal(scale=0.2, size=(4, 3))
        b = rng.permutation(UNIT) * rng.uniform(0.5, 1.5) + rng.normal(scale=0.3, size=3)
        normal, depth = tet_overlaps(a[None], b[None])
        if depth[0] <= 1e-6:
            continue
        found += 1
        assert np.linalg.norm(normal[0]) == pytest.approx(1.0, rel=1e-12)
        moved = b + normal[0] * (depth[0] * (1 + 1e-9) + 1e-12)
        assert tet_overlaps(a[None], moved[None])[1][0] <= 1e-12
        d = rng.normal(size=(200, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        short = b[None] + 0.999 * depth[0] * d[:, None, :]
        assert np.all(tet_overlaps(np.repeat(a[None], 200, axis=0), short)[1] > 0.0)
    assert found > 20
    apart = tet_overlaps(UNIT[None], (UNIT + [2.0, 0, 0])[None])[1]
    assert apart[0] == pytest.approx(-1.0, rel=1e-12)


def test_a_cube_pressed_into_the_finite_elements_is_moved_out_by_its_depth():
    """The cube 0.01 deep in the block of tets: its translation is 0.01 up, the nodes stay
    where they are, and moved so the cube touches without a gap below zero; a body that
    cannot move (a fixed obstacle) is not moved."""
    el, cube = _block_and_cube(0.01)
    contacts = detect(el, [cube], [0.4], np.zeros((1, 3)), 1e-3)
    shift = separate([cube], [True], contacts)
    np.testing.assert_allclose(shift, [[0.0, 0.0, 0.01]], atol=ROUND_OFF)
    from dataclasses import replace

    moved = replace(cube, position=cube.position + shift[0])
    after = detect(el, [moved], [0.4], np.zeros((1, 3)), 1e-3)
    assert after.gap.min() > -ROUND_OFF
    np.testing.assert_array_equal(separate([cube], [False], contacts), 0.0)


def test_a_piece_born_inside_another_is_moved_out_and_the_other_stays():
    """The L-shaped piece B born 0.01 inside A along -x, on a plane it must not pass: moved
    out by 0.01 along +x, A untouched, momenta kept; their tets no longer overlap."""
    from fem_frac.rigid.contact import Plane

    a, b = _stepped_halves(shift_b=(-0.01, 0.0, 0.0))
    shapes = [own_shape(a), own_shape(b)]
    ground = Plane(np.zeros(3), np.array([0.0, 0.0, 1.0]))
    bodies = place([a.body, b.body], [False, True], [ground], shapes=shapes)
    assert bodies[0] is a.body
    np.testing.assert_allclose(bodies[1].position - b.body.position, [0.01, 0.0, 0.0],
                               atol=ROUND_OFF)
    np.testing.assert_array_equal(bodies[1].momentum, b.body.momentum)
    xa, xb = world_tets(bodies[0], shapes[0]), world_tets(bodies[1], shapes[1])
    depth = tet_overlaps(np.repeat(xa, len(xb), axis=0), np.tile(xb, (len(xa), 1, 1)))[1]
    assert depth.max() <= ROUND_OFF


def _overlap(a, sa, b, sb) -> float:
    xa, xb = world_tets(a, sa), world_tets(b, sb)
    return float(tet_overlaps(np.repeat(xa, len(xb), axis=0), np.tile(xb, (len(xa), 1, 1)))[1]
                 .max())


def test_pieces_touching_by_their_tets_are_separated_within_one_step():
    """B 0.01 inside A (their vertices' normals all +x, but by their hulls they would be
    thrown apart): one step of both, no gravity, leaves their tets apart to round-off, each
    moved in inverse proportion to its mass (A holds 1.25 of the 2 units of volume), with
    the momenta as they were (zero)."""
    from fem_frac.rigid.pairs import PairLaw, step_all

    a, b = _stepped_halves(shift_b=(-0.01, 0.0, 0.0))
    shapes = [own_shape(a), own_shape(b)]
    assert _overlap(a.body, shapes[0], b.body, shapes[1]) == pytest.approx(0.01, rel=1e-9)
    bodies = step_all([a.body, b.body], [False, False], [True, True], 1e-3, np.zeros(3), [],
                      law=PairLaw(0.0, 0.5), shapes=shapes)[0]
    assert _overlap(bodies[0], shapes[0], bodies[1], shapes[1]) <= ROUND_OFF
    moved = [bodies[k].position - body.position for k, body in enumerate((a.body, b.body))]
    np.testing.assert_allclose(moved[0], [-0.01 * 0.75 / 2.0, 0.0, 0.0], atol=ROUND_OFF)
    np.testing.assert_allclose(moved[1], [0.01 * 1.25 / 2.0, 0.0, 0.0], atol=ROUND_OFF)
    for body in bodies:
        np.testing.assert_allclose(body.momentum, 0.0, atol=ROUND_OFF)


@pytest.mark.parametrize("tolerance", [0.0, 1e-3, 0.05])
def test_overlap_constraints_are_every_pair_of_tets_deeper_than_the_tolerance(tolerance):
    """Two jagged clouds of tets, partly overlapping: the constraints (the boxes' sweep
    across the two sets, the face normals' bound, then all 44 axes) are those of every pair
    of tets through tet_overlaps with the same scale, in the same order, to the bit."""
    rng = np.random.default_rng(9)

    def cloud(n, centre):
        base = rng.uniform(-0.5, 0.5, (n, 1, 3)) + centre
        return base + rng.uniform(-0.15, 0.15, (n, 4, 3))

    xa, xb = cloud(120, [0.0, 0.0, 0.0]), cloud(90, [0.6, 0.1, 0.0])
    normal, depth = overlap_constraints(xa, xb, tolerance)
    pa, pb = np.repeat(xa, len(xb), axis=0), np.tile(xb, (len(xa), 1, 1))
    lo_a, hi_a, lo_b, hi_b = pa.min(axis=1), pa.max(axis=1), pb.min(axis=1), pb.max(axis=1)
    boxed = np.all((lo_a <= hi_b) & (lo_b <= hi_a), axis=1)
    edges = np.abs(np.concatenate([pa[boxed], pb[boxed]])[:, [1, 2, 3, 2, 3, 3]]
                   - np.concatenate([pa[boxed], pb[boxed]])[:, [0, 0, 0, 1, 1, 2]]).max()
    every_normal, every_depth = tet_overlaps(pa[boxed], pb[boxed], float(edges))
    deeper = every_depth > tolerance
    assert deeper.sum() > 10
    np.testing.assert_array_equal(depth, every_depth[deeper])
    np.testing.assert_array_equal(normal, every_normal[deeper])
