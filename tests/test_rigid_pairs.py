"""Contact between rigid bodies (fem_frac.rigid.collide, fem_frac.rigid.pairs)."""

import itertools
from dataclasses import replace

import numpy as np
import pytest

from fem_frac.rigid import contact, stage
from fem_frac.rigid.body import (
    angular_velocity,
    exp_map,
    fixed_body,
    kinetic_energy,
    make_body,
    point_velocities,
    velocity,
)
from fem_frac.rigid.collide import candidate_pairs, cross_pairs, touching
from fem_frac.rigid.contact import Plane
from fem_frac.rigid.fragment import RigidFragment
from fem_frac.rigid.pairs import FixedBody, PairLaw, contact_rows, resolve_rows, step_all

G = 9.81
GRAVITY = np.array([0.0, 0.0, -G])
UP = np.array([0.0, 0.0, 1.0])
CORNERS = np.array(list(itertools.product([-1.0, 1.0], repeat=3)))
# Gauss-Seidel stops when a sweep changes no velocity by more than 1e-13 of the largest, and
# the active-set solve it ends with is exact to round-off (accepted within 1e-12 of the
# velocities: active_set.ROUND_OFF): velocities after impulses hold to this, relative
SOLVE = 1e-12


def box(half, mass=1.0, **state):
    half = np.asarray(half, dtype=float)
    a, b, c = half
    inertia = mass / 3.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    return make_body(mass, inertia, CORNERS * half, **state)


def momenta(bodies):
    """Total linear momentum and angular momentum about the origin."""
    p = sum(b.momentum for b in bodies)
    ell = sum(np.cross(b.position, b.momentum) + b.angular_momentum for b in bodies)
    return p, ell


def impulses(a, b, law, dt=1e-3, v_rest=0.0):
    """The two bodies after the contact impulses at their present positions."""
    rows = contact_rows([a, b], np.ones(2, dtype=bool), np.array([[0, 1]]),
                        np.array([[law.restitution, law.friction]]), [], dt)
    return resolve_rows([a, b], np.ones(2, dtype=bool), rows, dt, v_rest)[0], rows


# --- geometry ------------------------------------------------------------------------------


def test_sort_and_sweep_finds_exactly_the_overlapping_boxes():
    rng = np.random.default_rng(3)
    lo = rng.uniform(0.0, 10.0, (400, 3))
    hi = lo + rng.uniform(0.0, 1.5, (400, 3))
    lo[5], hi[5] = lo[4], hi[4]  # coincident boxes, and touching ones below
    lo[7, 0] = hi[6, 0]
    found = {tuple(p) for p in candidate_pairs(lo, hi)}
    brute = {(i, j) for i in range(400) for j in range(i + 1, 400)
             if np.all(lo[i] <= hi[j]) and np.all(lo[j] <= hi[i])}
    assert found == brute and (4, 5) in found


def test_the_sweep_across_two_sets_finds_the_pairs_of_the_union_across_them():
    """cross_pairs: the pairs (i of the first set, j of the second) that candidate_pairs
    finds in the union, in the same order; equal starts (a tie counted once), coincident
    and touching boxes included."""
    rng = np.random.default_rng(5)
    lo = np.round(rng.uniform(0.0, 10.0, (500, 3)), 1)  # many equal starts
    hi = lo + np.round(rng.uniform(0.0, 1.5, (500, 3)), 1)
    lo[300], hi[300] = lo[10], hi[10]
    lo[301, 0] = hi[11, 0]
    na = 200
    union = candidate_pairs(lo, hi)
    across = union[(union[:, 0] < na) & (union[:, 1] >= na)] - [0, na]
    found = cross_pairs(lo[:na], hi[:na], lo[na:], hi[na:])
    np.testing.assert_array_equal(found, across)
    assert len(found) > 100 and [10, 100] in found.tolist()
    assert cross_pairs(lo[:0], hi[:0], lo, hi).shape == (0, 2)


@pytest.mark.parametrize("gap", [0.2, 1e-12, 0.0, -1e-9, -0.1])
def test_two_cubes_distance_normal_and_points(gap):
    a = box([0.5, 0.5, 0.5])
    b = box([0.25, 0.25, 0.25], position=[0.3, 0.2, 0.75 + gap])
    touch = touching(a, b, 0.5)
    # the face normal and the support separation from the vertices: exact to round-off even
    # a round-off apart, where GJK's own normal is off by 1e-13 / gap rad
    assert touch.gap == pytest.approx(gap, abs=1e-15)
    np.testing.assert_allclose(touch.normal, UP, atol=1e-15)
    # the patch: b's lower face clipped by a's upper face, in the plane between them
    corners = {(x, y) for x in (0.05, 0.5) for y in (-0.05, 0.45)}
    assert {tuple(np.round(p[:2], 12)) for p in touch.points} == corners
    np.testing.assert_allclose(touch.points[:, 2], 0.5 + gap / 2, atol=1e-15)


def test_an_edge_against_a_face():
    a = box([0.5, 0.5, 0.5])
    b = box([0.5, 0.5, 0.5], position=[1.3, 0.0, 0.0], orientation=exp_map([0, 0, np.pi / 4]))
    touch = touching(a, b, 0.5)
    assert touch.gap == pytest.approx(0.8 - np.sqrt(0.5), abs=1e-15)
    np.testing.assert_allclose(touch.normal, [1.0, 0.0, 0.0], atol=1e-15)
    # the edge's two ends
    np.testing.assert_allclose(np.sort(touch.points[:, 2]), [-0.5, 0.5], atol=1e-15)
    assert touching(a, replace(b, position=np.array([2.0, 0.0, 0.0])), 0.5) is None


# --- impulses ------------------------------------------------------------------------------


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_head_on_collision_of_two_equal_cubes(e):
    v = 2.0
    a = box([0.5, 0.5, 0.5], position=[-0.5, 0.0, 0.0], velocity=[v / 2, 0.0, 0.0])
    b = box([0.5, 0.5, 0.5], position=[0.5, 0.0, 0.0], velocity=[-v / 2, 0.0, 0.0])
    p0, l0 = momenta([a, b])
    (a1, b1), rows = impulses(a, b, PairLaw(e, 0.4))
    assert len(rows) == 4  # the face's four corners
    p1, l1 = momenta([a1, b1])
    scale = a.mass * v
    np.testing.assert_allclose(p1, p0, rtol=0, atol=1e-15 * scale)
    np.testing.assert_allclose(l1, l0, rtol=0, atol=1e-15 * scale)
    # Poisson (and Newton, for one point of symmetry): relative normal velocity -e v
    assert (velocity(b1) - velocity(a1))[0] == pytest.approx(e * v, rel=SOLVE, abs=SOLVE * v)
    np.testing.assert_allclose(angular_velocity(a1), 0.0, atol=SOLVE * v)
    # a whole step without gravity: the same, and the cubes leave the contact apart
    (a2, b2), _, _, pairs = step_all([a, b], [False, False], [True, True], 1e-3, np.zeros(3),
                                     [], law=PairLaw(e, 0.4))[:4]
    assert pairs == 1
    np.testing.assert_allclose(momenta([a2, b2])[0], p0, rtol=0, atol=1e-15 * scale)
    np.testing.assert_allclose(momenta([a2, b2])[1], l0, rtol=0, atol=1e-15 * scale)
    assert (velocity(b2) - velocity(a2))[0] == pytest.approx(e * v, rel=SOLVE, abs=SOLVE * v)
    assert b2.position[0] - a2.position[0] >= 1.0


def test_oblique_collision_with_friction_keeps_momenta_and_loses_energy():
    a = box([0.5, 0.4, 0.3], mass=2.0, position=[0.0, 0.0, 0.0], velocity=[1.0, 0.3, -0.2],
            angular_velocity=[0.5, -1.0, 2.0])
    b = box([0.3, 0.3, 0.6], mass=1.0, position=[0.8, 0.2, 0.1],
            orientation=exp_map([0.3, 0.2, 0.1]), velocity=[-1.5, 1.0, 0.5],
            angular_velocity=[-2.0, 1.0, 0.5])
    touch = touching(a, b, 1.0)
    b = replace(b, position=b.position - (touch.gap + 1e-3) * touch.normal)  # 1 mm inside
    p0, l0 = momenta([a, b])
    centre = (a.mass * a.position + b.mass * b.position) / (a.mass + b.mass)
    lc0 = l0 - np.cross(centre, p0)
    t0 = kinetic_energy(a) + kinetic_energy(b)
    (a1, b1), rows = impulses(a, b, PairLaw(0.5, 0.8))
    assert len(rows) > 0
    p1, l1 = momenta([a1, b1])
    scale = np.abs(p0).max() + a.mass * np.abs(velocity(a1)).max()
    np.testing.assert_allclose(p1, p0, rtol=0, atol=1e-15 * scale)
    # about the common centre of mass, as about any fixed point
    np.testing.assert_allclose(l1 - np.cross(centre, p1), lc0, rtol=0, atol=1e-14 * scale)
    t1 = kinetic_energy(a1) + kinetic_energy(b1)
    assert t1 < t0  # it approached, and friction and e < 1 dissipate
    # no contact point left approaching
    vn = [(point_velocities(b1, p[None])[0] - point_velocities(a1, p[None])[0]) @ f[0]
          for p, f in zip(rows.point, rows.frame, strict=True)]
    assert min(vn) >= -SOLVE * scale


def random_hull(rng, **state):
    half = rng.uniform(0.2, 1.0, 3)
    points = rng.uniform(-1.0, 1.0, (14, 3)) * half
    q = rng.normal(size=4)
    return make_body(rng.uniform(0.5, 3.0), rng.uniform(0.2, 1.0, 3), points,
                     orientation=q / np.linalg.norm(q), **state)


def test_random_pair_impacts_never_gain_energy():
    rng = np.random.default_rng(11)
    hits = 0
    for trial in range(200):
        a = random_hull(rng, velocity=rng.normal(size=3), angular_velocity=rng.normal(size=3) * 3)
        b = random_hull(rng, position=rng.normal(size=3) * 3,
                        velocity=rng.normal(size=3), angular_velocity=rng.normal(size=3) * 3)
        touch = touching(a, b, 100.0)
        # b moved to touch a, up to 2 cm inside, and thrown at it
        b = replace(b, position=b.position - (touch.gap + rng.uniform(0, 0.02)) * touch.normal,
                    momentum=b.momentum - b.mass * rng.uniform(0.5, 3.0) * touch.normal)
        e = 1.0 if trial % 4 == 0 else rng.uniform(0.0, 1.0)
        mu = 0.0 if trial % 3 == 0 else rng.uniform(0.0, 1.5)
        (a1, b1), rows = impulses(a, b, PairLaw(e, mu))
        if len(rows) == 0:
            continue
        hits += 1
        t0 = kinetic_energy(a) + kinetic_energy(b)
        # Poisson restitution cannot add energy (contact module docstring): round-off only
        assert kinetic_energy(a1) + kinetic_energy(b1) <= t0 * (1.0 + 1e-14)
        p0, p1 = momenta([a, b]), momenta([a1, b1])
        scale = np.abs(p0[0]).max() + np.abs(p0[1]).max() + 1.0
        np.testing.assert_allclose(p1[0], p0[0], rtol=0, atol=1e-14 * scale)
        np.testing.assert_allclose(p1[1], p0[1], rtol=0, atol=1e-13 * scale)
    assert hits >= 190


def test_infinite_mass_is_a_fixed_obstacle():
    wall = FixedBody(fixed_body(CORNERS * [0.5, 2.0, 2.0], position=[1.0, 0.0, 0.0]), 0.5, 0.0)
    ball = box([0.25, 0.25, 0.25], position=[0.25, 0.0, 0.0], velocity=[2.0, 0.0, 0.0])
    (out,), received, _, pairs = step_all([ball], [False], [True], 1e-3, np.zeros(3), [],
                                          fixed=(wall,))
    assert pairs == 1
    np.testing.assert_allclose(velocity(out), [-1.0, 0.0, 0.0], rtol=SOLVE)
    # what the wall gave: m (1 + e) v, booked as an obstacle's impulse
    np.testing.assert_allclose(received[0], [0.0, 3.0], rtol=SOLVE)


# --- resting and stacking ------------------------------------------------------------------


def stack(offsets=(0.0, 0.1, -0.05)):
    """Three boxes on the ground, each resting on the one below (exactly touching)."""
    halves = [np.array([0.6, 0.5, 0.25]), np.array([0.5, 0.4, 0.2]), np.array([0.3, 0.3, 0.3])]
    bodies, z = [], 0.0
    for k, (half, dx) in enumerate(zip(halves, offsets, strict=True)):
        bodies.append(box(half, mass=1.0 + k, position=[dx, 0.5 * dx, z + half[2]]))
        z += 2 * half[2]
    return bodies


def test_a_stack_of_three_boxes_rests():
    dt, n = 1e-3, 1000
    ground = Plane(np.zeros(3), UP, restitution=0.5, friction=0.5)
    law = PairLaw(0.5, 0.5)
    bodies = stack()
    x0 = np.array([b.position for b in bodies])
    energy = np.empty(n)
    drift = 0.0
    for i in range(n):
        bodies, received, _, pairs = step_all(bodies, [False] * 3, [True] * 3, dt, GRAVITY,
                                              [ground], law=law)
        assert pairs == 2
        energy[i] = sum(kinetic_energy(b) - b.mass * GRAVITY @ b.position for b in bodies)
        drift = max(drift, np.abs(np.array([b.position for b in bodies]) - x0).max())
    # speculative contact: the impulses bring every contact point to v_n = 0, v_t = 0 after
    # the kick, exactly but for the solve's acceptance slack (1e-12 of g dt), so a step moves
    # a body by at most 1e-12 g dt^2; over n steps (measured 1.7e-17 m)
    assert drift <= n * SOLVE * G * dt * dt
    assert np.all(np.diff(energy) <= 1e-15 * abs(energy[0]))  # never gains
    # the net impulses: the ground carries the whole stack's weight, m g dt a step; each
    # body's neighbours, its own (from below what is above it and itself, from above what
    # is above it); the bottom one gets from the box above what it carries
    weights = np.array([b.mass for b in bodies]) * G * dt
    np.testing.assert_allclose(received[:, 1], [weights.sum(), 0.0, 0.0], rtol=SOLVE, atol=0)
    np.testing.assert_allclose(received[:, 0], [weights[1:].sum(), weights[1], weights[2]],
                               rtol=SOLVE)


@pytest.mark.parametrize("tilt", [0.0, 3e-5, 1e-4])
def test_a_box_set_down_a_little_tilted_comes_to_rest(tilt):
    """A box set down on another with a tilt of the size an impact's round-off leaves
    (tilts of 5e-5 rad followed a box dropped on a stack, depending on the BLAS kernel):
    the corners of its face still touch (the contact patch takes the support features
    within collide._PATCH_TOLERANCE of the contact plane), so it settles flat instead of
    rocking on one corner, which the separation of the overlap it leaves kept going (1e-2 J
    after 2000 steps with a tolerance of 1e-6 of the radius)."""
    dt = 1e-3
    bottom = stack()[0]
    top_z = bottom.position[2] + 0.25 + 0.2 + 1e-7
    top = box([0.2, 0.2, 0.2], position=[0.05, 0.0, top_z],
              orientation=exp_map([tilt, 0.0, 0.3]))
    bodies, peak = _stepped_on_the_ground([bottom, top], 400, dt)
    assert peak <= 100 * sum(b.mass for b in bodies) * G * G * dt * dt
    assert sum(kinetic_energy(b) for b in bodies) < 1e-12  # at rest


def _stepped_on_the_ground(bodies, n: int, dt: float):
    """``(bodies, peak)``: ``bodies`` after ``n`` steps on a ground plane (e = 0.5, mu = 0.5
    for the ground and between bodies), and the largest rise of their energy (kinetic and
    potential) over the steps."""
    ground = Plane(np.zeros(3), UP, restitution=0.5, friction=0.5)
    law, k = PairLaw(0.5, 0.5), len(bodies)
    energy0 = sum(kinetic_energy(b) - b.mass * GRAVITY @ b.position for b in bodies)
    peak = 0.0
    for _ in range(n):
        bodies = step_all(bodies, [False] * k, [True] * k, dt, GRAVITY, [ground], law=law)[0]
        energy = sum(kinetic_energy(b) - b.mass * GRAVITY @ b.position for b in bodies)
        peak = max(peak, energy - energy0)
    return bodies, peak


def test_a_dropped_box_settles_on_a_stack_without_gaining_energy():
    dt = 1e-3
    bodies = stack((0.0, 0.1, -0.05))[:2]
    top = bodies[-1].position[2] + 0.2
    bodies.append(box([0.2, 0.2, 0.2], position=[0.05, 0.0, top + 0.2 + 0.05],
                      orientation=exp_map([0.0, 0.0, 0.3]), velocity=[0.0, 0.0, -0.5]))
    bodies, peak = _stepped_on_the_ground(bodies, 800, dt)
    # energy may rise only by what the time-of-impact cut leaves: a penetration of at most
    # g dt^2 / 2 turned into height by the projection, per impact (a few dozen here)
    assert peak <= 100 * sum(b.mass for b in bodies) * G * G * dt * dt
    assert sum(kinetic_energy(b) for b in bodies) < 1e-12  # at rest
    assert bodies[2].position[2] > bodies[1].position[2]  # on top


def fragment(body, k):
    return RigidFragment(body, np.zeros((0, 3)), np.zeros((0, 4), dtype=int),
                         np.zeros((0, 3)), k, 0.0)


def test_a_sleeping_body_wakes_when_struck():
    ground = Plane(np.zeros(3), UP, restitution=0.0, friction=0.5)
    resting = fragment(box([0.5, 0.5, 0.5], position=[0.0, 0.0, 0.5]), 0)
    resting = replace(resting, resting=stage.SLEEP_STEPS)
    falling = fragment(box([0.2, 0.2, 0.2], position=[0.0, 0.0, 1.3],
                           velocity=[0.0, 0.0, -2.0]), 1)
    world = (resting, falling)
    dt, woke = 1e-3, False
    for i in range(200):
        world = stage.move(world, i * dt, (i + 1) * dt, GRAVITY, (ground,), 1,
                           PairLaw(0.0, 0.5))
        # before the impact (at about 40 ms) it sleeps, unmoved
        assert world[0].resting >= stage.SLEEP_STEPS or i > 30
        woke = woke or world[0].resting == 0
    assert woke
    assert world[0].contact_impulse[0] > 0.0 or world[1].contact_impulse[0] > 0.0
    # the impact pushed the lower box into the ground, which stopped it: it rests again
    assert abs(world[0].body.position[2] - 0.5) < 1e-9
    assert world[1].body.position[2] == pytest.approx(1.2, abs=1e-9)


def test_one_body_on_planes_takes_the_single_body_step():
    ground = Plane(np.zeros(3), UP, restitution=0.5, friction=0.5)
    body = box([0.5, 0.3, 0.2], position=[0.0, 0.0, 0.4], velocity=[0.5, 0.0, -1.0])
    other = box([0.5, 0.3, 0.2], position=[10.0, 0.0, 0.4])
    for _ in range(300):
        alone = contact.step(body, 1e-3, GRAVITY, [ground])
        (both, _), _, _, pairs = step_all([body, other], [False, False], [True, True], 1e-3,
                                          GRAVITY, [ground])
        assert pairs == 0
        np.testing.assert_array_equal(both.position, alone.position)
        np.testing.assert_array_equal(both.momentum, alone.momentum)
        body = alone


def test_boxes_resting_face_on_face_a_nanometre_apart_touch_along_the_face_normal():
    """Two 0.1 x 0.2 x 0.1 boxes stacked face on face as a resting wall left them after a
    step: centres 0.1 - 1.18e-9 apart in z, turned by at most 6.8e-8 rad. coal's normal for
    this pair is 70 deg off (0.84, 0.42, 0.34); along it the support separation is -0.17 m,
    which once closed the gap by throwing the boxes apart. The face normal must win: the gap
    is the face overlap -1.18e-9 up to the turn (at most 6.8e-8 rad x 0.122 m = 8.3e-9 m at
    a corner), the normal +z to the same angle."""
    pts = np.array([[x, y, z] for x in (-0.05, 0.05) for y in (-0.1, 0.1)
                    for z in (-0.05, 0.05)])
    a = make_body(4.0, [1.0, 1.0, 1.0], pts,
                  position=[0.04999999864014015, -0.09999999994715401, 0.05000000125416784],
                  orientation=[1.0, 1.6765459734231217e-10, -1.2206369319738699e-08,
                               -6.9611457704730696e-10])
    b = make_body(4.0, [1.0, 1.0, 1.0], pts,
                  position=[0.04999998692426712, -0.10000000047617064, 0.15000000007264763],
                  orientation=[0.99999999999999778, 6.6674025911730535e-09,
                               -6.7896553723816926e-08, 6.8320480089108734e-09])
    t = touching(a, b, 3.1768217471213736e-08)
    assert t is not None
    assert abs(t.gap + 1.18e-9) <= 8.3e-9 + 1e-10
    assert t.normal @ UP >= np.cos(1e-6)
