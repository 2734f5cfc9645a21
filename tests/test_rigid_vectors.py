"""fem_frac.rigid.vectors is numpy to the bit: cross is np.cross (the same products and
differences), length and lengths np.linalg.norm (the same sums and roots), on vectors,
rows, broadcast and strided shapes, extreme scales and special values."""

from __future__ import annotations

import numpy as np
import pytest

from fem_frac.rigid.vectors import cross

RNG = np.random.default_rng(7)


def _same_bits(x, y):
    x, y = np.asarray(x), np.asarray(y)
    assert x.shape == y.shape and x.dtype == y.dtype == np.float64
    assert x.tobytes() == y.tobytes()


@pytest.mark.parametrize("shapes", [((3,), (3,)), ((50, 3), (50, 3)), ((3,), (40, 3)),
                                    ((40, 3), (3,)), ((7, 4, 3), (7, 4, 3)),
                                    ((9, 6, 1, 3), (9, 1, 6, 3)), ((0, 3), (0, 3))])
def test_cross_is_numpys_to_the_bit(shapes):
    for scale in (1.0, 1e-300, 1e300, 1e-8):
        a = RNG.standard_normal(shapes[0]) * scale
        b = RNG.standard_normal(shapes[1]) * (1 / scale if scale > 1e200 else scale)
        _same_bits(cross(a, b), np.cross(a, b))


def test_cross_keeps_special_values_and_signed_zeros():
    values = np.array([0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan, 5e-324, 1.7e308])
    grid = np.stack(np.meshgrid(values, values, values, indexing="ij"), axis=-1).reshape(-1, 3)
    b = grid[::-1].copy()
    with np.errstate(all="ignore"):
        _same_bits(cross(grid, b), np.cross(grid, b))
        for k in range(0, len(grid), 37):  # the vector path (Python floats)
            _same_bits(cross(grid[k], b[k]), np.cross(grid[k], b[k]))


def test_cross_takes_lists_and_integers_as_floats():
    _same_bits(cross([1, 0, 0], [0, 1, 0]), np.cross([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]))
    _same_bits(cross(np.arange(6).reshape(2, 3), [[1, 2, 3]]),
               np.cross(np.arange(6.0).reshape(2, 3), [[1.0, 2.0, 3.0]]))


def test_a_rigid_motions_arms_signed_zeros_and_six_decades():
    """One angular velocity ``w (3,)`` times a body's arms ``r (k, 3)`` (the velocities of its
    points), signed zeros and six decades of scale included."""
    rng = np.random.default_rng(5)
    for k in (0, 1, 3, 100):
        for _ in range(50):
            w = rng.standard_normal(3) * 10.0 ** rng.integers(-6, 6, 3)
            r = rng.standard_normal((k, 3)) * 10.0 ** rng.integers(-6, 6, (k, 3))
            w[rng.random(3) < 0.3] = -0.0
            r[rng.random((k, 3)) < 0.3] = rng.choice([0.0, -0.0])
            _same_bits(cross(w, r), np.cross(w, r))


def test_lengths_are_numpys_norms_to_the_bit():
    """length (one vector, a numpy scalar) and lengths (the last axis) against
    np.linalg.norm, on contiguous and strided vectors, over and underflowing scales."""
    from fem_frac.rigid.vectors import length, lengths

    for scale in (1.0, 1e-170, 1e170, 1e-320):
        _lengths_at(RNG.standard_normal((60, 4, 3)) * scale, length, lengths)
    assert length([3, 4, 0]) == 5.0 and np.isnan(length([np.nan, 0.0, 0.0]))


def _lengths_at(v, length, lengths):
    with np.errstate(over="ignore", under="ignore"):
        got, want = lengths(v), np.linalg.norm(v, axis=-1)
        assert got.tobytes() == want.tobytes()
        assert lengths(v[:, 0]).tobytes() == np.linalg.norm(v[:, 0], axis=1).tobytes()
        for row in v[:, 1]:
            assert type(length(row)) is type(np.linalg.norm(row))
            assert length(row).tobytes() == np.linalg.norm(row).tobytes()
        strided = v[:, :, 0][:, :3]  # a (60, 3) view whose rows are not contiguous
        for row in strided:
            assert length(row).tobytes() == np.linalg.norm(row).tobytes()
