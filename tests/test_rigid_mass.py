"""Exact mass properties of unions of tets (fem_frac.rigid.mass)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from fem_frac.rigid.mass import MassProperties, mass_properties, tet_moments
from meshes import structured_box

# Round-off bound for sums over O(100) tets with O(1) coordinates: a few hundred ulps.
RTOL = 1e-12

# Tonon (2004), J. Math. Stat. 1(1), worked example (positively oriented as printed).
TONON = np.array(
    [
        [8.33220, -11.86875, 0.93355],
        [0.75523, 5.00000, 16.37072],
        [52.61236, 5.00000, -5.38580],
        [2.00000, 5.00000, 3.00000],
    ]
)
# a, b, c (moments about x, y, z); a' = int yz, b' = int xz, c' = int xy about the centroid
TONON_ABC = np.array([43520.33257, 194711.28938, 191168.76173])
TONON_PRIMES = np.array([4417.66150, -46343.16662, 11996.20119])


def _tonon_components(J):
    """(a, b, c, a', b', c') of an inertia tensor: J_yz = -a', J_xz = -b', J_xy = -c'."""
    return np.array([J[0, 0], J[1, 1], J[2, 2], -J[1, 2], -J[0, 2], -J[0, 1]])


def test_tonon_example():
    mp = mass_properties(TONON, [[0, 1, 2, 3]], 1.0)
    # the printed order is positively oriented
    d = TONON[1:] - TONON[0]
    assert np.linalg.det(d) > 0
    # volume printed as 1873.23: half a unit in the last digit
    assert abs(mp.mass - 1873.23) <= 5e-3
    # centroid: y and z to the printed 5 decimals. The printed x = 15.92492 is a misprint: the
    # mean of the printed x coordinates is 15.9249475, and rounding each printed coordinate
    # (+-5e-6) moves the mean by at most 5e-6, far less than the 2.75e-5 gap.
    assert np.allclose(mp.center[1:], [0.78281, 3.72962], rtol=0, atol=5e-6 + 1e-12)
    assert mp.center[0] == pytest.approx(TONON[:, 0].mean(), abs=1e-13)
    assert abs(mp.center[0] - 15.92492) < 3e-5
    pub = np.concatenate([TONON_ABC, TONON_PRIMES])
    ours = _tonon_components(mp.inertia)
    # All six agree to a relative 1.6-1.7e-8, and the deviation is one common factor, i.e. a
    # volume: the printed numbers follow from 6V = 11239.4 while the printed (rounded) vertices
    # give 6V = 11239.40019 (rounding the vertices to 5 decimals alone allows ~1e-6 relative).
    assert np.allclose(ours, pub, rtol=2e-8, atol=0)
    # With that volume all six match to half a unit in the 5th decimal (5e-6; c' is off by
    # 5.5e-6, Tonon's own round-off), which pins the shape part of the formula and, with the
    # signs and the a'/b'/c' pairing, which off-diagonal entry is which.
    scale = 11239.4 / (6.0 * mp.mass)
    assert np.allclose(ours * scale, pub, rtol=0, atol=1e-5)
    # Tonon's printed matrix [[a, -b', -c'], ...] (b', c' swapped) is NOT what his numbers give
    swapped = np.array([ours[0], ours[1], ours[2], ours[3], ours[5], ours[4]])
    assert not np.allclose(swapped * scale, pub, rtol=0, atol=1.0)


def _quadratic_rule_moments(points, tets):
    """Reference second moments by the 4-point degree-2 rule (exact for quadratics)."""
    x = points[tets]
    vol = np.abs(np.linalg.det(x[:, 1:] - x[:, :1])) / 6.0
    alpha, beta = 0.5854101966249685, 0.1381966011250105
    bary = np.full((4, 4), beta) + np.eye(4) * (alpha - beta)
    q = np.einsum("qk,eki->eqi", bary, x)  # (m, 4 points, 3)
    return vol, np.einsum("e,eqi->ei", vol, q) / 4, np.einsum("e,eqi,eqj->eij", vol, q, q) / 4


def test_closed_form_matches_exact_quadrature():
    rng = np.random.default_rng(1)
    points = rng.normal(size=(40, 3)) * [1.0, 2.0, 0.5] + 3.0
    tets = np.array([rng.choice(40, 4, replace=False) for _ in range(30)])  # both orientations
    m, first, second = tet_moments(points, tets, 2.0)
    vol, qfirst, qsecond = _quadratic_rule_moments(points, tets)
    assert np.allclose(m, 2 * vol, rtol=RTOL, atol=0)
    assert np.allclose(first, 2 * qfirst, rtol=1e-11, atol=0)
    # second moment entries can nearly cancel only in the off-diagonals; scale by the diagonal
    assert np.allclose(second, 2 * qsecond, rtol=0, atol=1e-11 * np.abs(second).max())
    assert m.shape == (30,) and first.shape == (30, 3) and second.shape == (30, 3, 3)


CUBE = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=float)
# vertex index = 4i + 2j + k
CUBE_5 = [[0, 1, 2, 4], [3, 1, 2, 7], [5, 1, 4, 7], [6, 2, 4, 7], [1, 2, 4, 7]]
CUBE_6 = [[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]]


@pytest.mark.parametrize("tets", [CUBE_5, CUBE_6], ids=["5tets", "6tets"])
def test_unit_cube(tets):
    mp = mass_properties(CUBE, tets, 1.0)
    assert isinstance(mp, MassProperties)
    # all quantities are O(1) sums of a handful of terms: round-off only
    assert mp.mass == pytest.approx(1.0, abs=1e-14)
    assert np.allclose(mp.center, 0.5, rtol=0, atol=1e-14)
    assert np.allclose(mp.inertia, np.eye(3) / 6, rtol=0, atol=1e-14)
    assert np.allclose(mp.moments, 1 / 6, rtol=0, atol=1e-14)
    _check_axes(mp)


def _box_inertia(mass, a, b, c):
    return mass / 12 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])


@pytest.mark.parametrize("distortion", [0.0, 0.3])
def test_box_many_tets(distortion):
    lengths = (2.0, 1.0, 0.5)
    mesh = structured_box((5, 4, 3), lengths, distortion, seed=3)
    rho = 7.5
    mp = mass_properties(mesh.points, mesh.tets, rho)
    mass = rho * np.prod(lengths)
    # the union is the box whatever the interior vertices do: exact up to round-off
    assert mp.mass == pytest.approx(mass, rel=RTOL)
    assert np.allclose(mp.center, np.array(lengths) / 2, rtol=RTOL, atol=0)
    expected = _box_inertia(mass, *lengths)
    assert np.allclose(mp.inertia, expected, rtol=0, atol=RTOL * expected.max())
    assert np.allclose(mp.moments, np.sort(np.diag(expected)), rtol=RTOL)
    # distinct moments: the axes are the coordinate axes, signed by the documented rule
    assert np.allclose(np.abs(mp.axes), np.eye(3), atol=1e-10)
    _check_axes(mp)


def _check_axes(mp):
    axes = mp.axes
    assert np.allclose(axes.T @ axes, np.eye(3), rtol=0, atol=1e-13)
    assert np.linalg.det(axes) == pytest.approx(1.0, abs=1e-13)
    assert np.all(np.diff(mp.moments) >= 0)
    scale = np.abs(mp.inertia).max()
    assert np.allclose(axes @ np.diag(mp.moments) @ axes.T, mp.inertia, rtol=0, atol=1e-13 * scale)
    # sign rule: largest-magnitude component positive in the first two columns (the third
    # follows from det = +1 and carries the rule only where that is consistent)
    idx = np.argmax(np.abs(axes), axis=0)
    assert np.all(axes[idx[:2], [0, 1]] > 0)


def test_invariance_under_rigid_motion():
    mesh = structured_box((4, 3, 2), (1.5, 1.0, 0.7), 0.25, seed=5)
    rng = np.random.default_rng(7)
    R = Rotation.random(random_state=rng).as_matrix()
    t = rng.normal(size=3) * 10
    before = mass_properties(mesh.points, mesh.tets, 3.0)
    after = mass_properties(mesh.points @ R.T + t, mesh.tets, 3.0)
    # translating by ~10 loses a digit or two of the O(1) covariance to cancellation
    assert after.mass == pytest.approx(before.mass, rel=RTOL)
    assert np.allclose(after.center, R @ before.center + t, rtol=0, atol=1e-12)
    scale = np.abs(before.inertia).max()
    assert np.allclose(after.inertia, R @ before.inertia @ R.T, rtol=0, atol=1e-11 * scale)
    assert np.allclose(after.moments, before.moments, rtol=0, atol=1e-11 * scale)
    _check_axes(before)
    _check_axes(after)
    # distinct moments: the rotated axes equal R @ axes up to column signs
    assert np.allclose(np.abs(np.sum(after.axes * (R @ before.axes), axis=0)), 1.0, atol=1e-8)


def test_element_density_and_two_materials():
    mesh = structured_box((4, 2, 2), (2.0, 1.0, 1.0))
    scalar = mass_properties(mesh.points, mesh.tets, 2.5)
    per_tet = mass_properties(mesh.points, mesh.tets, np.full(len(mesh.tets), 2.5))
    assert per_tet.mass == pytest.approx(scalar.mass, rel=1e-15)
    assert np.allclose(per_tet.inertia, scalar.inertia, rtol=0, atol=1e-15)
    # two unit cubes side by side, densities 1 (x < 1) and 3 (x > 1)
    left = mesh.points[mesh.tets].mean(axis=1)[:, 0] < 1.0
    mp = mass_properties(mesh.points, mesh.tets, np.where(left, 1.0, 3.0))
    assert mp.mass == pytest.approx(4.0, rel=RTOL)
    centre = np.array([1.25, 0.5, 0.5])  # (1 * 0.5 + 3 * 1.5) / 4
    assert np.allclose(mp.center, centre, rtol=0, atol=1e-14)
    expected = np.zeros((3, 3))
    for m, cx in [(1.0, 0.5), (3.0, 1.5)]:  # two cubes, not tets: parallel-axis by hand
        d = np.array([cx, 0.5, 0.5]) - centre
        expected += m / 6 * np.eye(3) + m * (d @ d * np.eye(3) - np.outer(d, d))
    assert np.allclose(mp.inertia, expected, rtol=0, atol=1e-13)
    _check_axes(mp)


def test_additivity_of_disjoint_pieces():
    box = structured_box((3, 2, 2), (1.0, 0.6, 0.4), 0.2, seed=2)
    tet_pts = TONON / 20 + [3.0, -1.0, 2.0]
    points = np.vstack([box.points, tet_pts])
    tets = np.vstack([box.tets, [np.arange(4) + len(box.points)]])
    density = np.r_[np.full(len(box.tets), 2.0), 5.0]
    whole = mass_properties(points, tets, density)
    parts = [
        mass_properties(box.points, box.tets, 2.0),
        mass_properties(tet_pts, [[0, 1, 2, 3]], 5.0),
    ]
    mass = sum(p.mass for p in parts)
    centre = sum(p.mass * p.center for p in parts) / mass
    inertia = np.zeros((3, 3))
    for p in parts:
        d = p.center - centre
        inertia += p.inertia + p.mass * (d @ d * np.eye(3) - np.outer(d, d))
    assert whole.mass == pytest.approx(mass, rel=RTOL)
    assert np.allclose(whole.center, centre, rtol=0, atol=1e-13)
    assert np.allclose(whole.inertia, inertia, rtol=0, atol=1e-12 * np.abs(inertia).max())
    _check_axes(whole)


def test_zero_mass_rejected():
    with pytest.raises(ValueError, match="mass"):
        mass_properties(CUBE, CUBE_6, 0.0)
