"""Rigid bodies against ground planes by impulses (fem_frac.rigid.contact)."""

import itertools
from dataclasses import replace

import numpy as np
import pytest

from fem_frac.rigid import contact
from fem_frac.rigid.body import (
    angular_velocity,
    exp_map,
    kinetic_energy,
    make_body,
    point_velocities,
    velocity,
    world_points,
)
from fem_frac.rigid.contact import Plane, find_contacts, resolve, signed_distance, step

G = 9.81
GRAVITY = np.array([0.0, 0.0, -G])
UP = np.array([0.0, 0.0, 1.0])
EPS = np.finfo(float).eps
CORNERS = np.array(list(itertools.product([-1.0, 1.0], repeat=3)))


def block(half, mass=2.0, **state):
    """A box of half sizes ``half`` (3,): its 8 corners are the contact points."""
    a, b, c = half
    inertia = mass / 3.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    return make_body(mass, inertia, CORNERS * half, **state)


def total_energy(body):
    return kinetic_energy(body) - body.mass * GRAVITY @ body.position


@pytest.mark.parametrize("e", [0.5, 0.8])
def test_bounce_height_ratio_is_e_squared(e):
    dt, h0, half = 1e-3, 1.0, np.full(3, 0.5)
    plane = Plane(np.zeros(3), UP, restitution=e, friction=0.0)
    body = block(half, position=[0.0, 0.0, h0 + half[2]])
    n = int(2.5 * np.sqrt(2 * h0 / G) / dt)  # down, up to the apex, and a little more
    height, vz = np.empty(n), np.empty(n)
    for i in range(n):
        body = step(body, dt, GRAVITY, [plane])
        height[i], vz[i] = body.position[2] - half[2], body.momentum[2]
    up = np.argmax(vz > 0)  # the step of the impact
    h1 = height[up:up + np.argmax(vz[up:] < 0) + 1].max()
    # the step is cut at the (linearly predicted) time of impact, so the rebound starts on the
    # plane; what is left is the parabola's curvature within the cut step (a penetration
    # <= g dt^2 / 2, which the projection turns into height) and the sampling of the apex at
    # step boundaries: |h1/h0 - e^2| <= 2 g dt^2 / h0 = 2e-5 (measured 2.4e-6 and 1.0e-6).
    # Bouncing at the step boundary instead, from up to |v| dt above the plane, would be off
    # by about (1 + e) |v| dt / h0 = 8e-3 here.
    assert abs(h1 / h0 - e * e) < 2 * G * dt * dt / h0
    assert np.abs(body.angular_momentum).max() < 1e-12  # a flat landing spins nothing


@pytest.mark.parametrize("drop", [0.0, 1e-3])
def test_block_rests_without_jitter(drop):
    dt, half, settle, n = 1e-3, np.array([0.5, 0.3, 0.2]), 200, 1250
    plane = Plane(np.zeros(3), UP, restitution=0.5, friction=0.5)
    body = block(half, position=[0.3, -0.2, half[2] + drop], orientation=exp_map([0, 0, 0.7]))
    x0 = body.position.copy()
    z, ke, vz = np.empty(n), np.empty(n), np.empty(n)
    for i in range(n):
        body = step(body, dt, GRAVITY, [plane])
        z[i], ke[i], vz[i] = body.position[2], kinetic_energy(body), body.momentum[2]
    # dropped from 1 mm it bounces (approach 0.14 m/s > v_rest = 2 g dt) with e = 0.5 until
    # the approach is below v_rest, then sits: all within the settling steps
    rest = slice(settle, None)
    assert np.ptp(z[rest]) < 1e-12 and abs(z[-1] - half[2]) < 1e-12
    assert np.abs(vz[rest]).max() < 1e-12
    assert ke[rest].max() < 1e-20
    start = 0 if drop == 0.0 else settle
    assert np.all(np.diff(ke[start:]) <= 1e-24)  # never increases (round-off of ~1e-27 allowed)
    np.testing.assert_allclose(body.position[:2], x0[:2], atol=1e-12)  # no sideways drift


def incline(theta_deg, mu, dt=2e-3, t_end=1.0):
    """Displacement along the incline (downhill) of a block released at rest; times."""
    theta = np.radians(theta_deg)
    normal = np.array([-np.sin(theta), 0.0, np.cos(theta)])
    downhill = np.array([-np.cos(theta), 0.0, -np.sin(theta)])
    plane = Plane(np.zeros(3), normal, restitution=0.3, friction=mu)
    half = np.array([0.5, 0.3, 0.2])
    body = block(half, position=half[2] * normal, orientation=exp_map([0.0, -theta, 0.0]))
    n = int(round(t_end / dt))
    s, gap = np.empty(n), np.empty(n)
    for i in range(n):
        body = step(body, dt, GRAVITY, [plane])
        s[i] = body.position @ downhill
        gap[i] = signed_distance(plane, world_points(body)).min()
    assert np.abs(gap).max() < 1e-12  # stays on the plane: no hop, no sinking
    assert np.linalg.norm(angular_velocity(body)) < 1e-9  # no tipping, no twisting
    return s - half[2] * normal @ downhill, dt * np.arange(1, n + 1)


def test_block_sticks_on_a_shallow_incline():
    s, _ = incline(20.0, 0.5)  # tan 20 deg = 0.36 < 0.5
    # sticking is an exact zero tangential velocity at the converged contact impulses; what
    # creeps is Gauss-Seidel's tolerance (1e-13 of the velocity) times 500 steps
    assert np.abs(s).max() < 1e-12


@pytest.mark.parametrize("theta_deg, mu", [(30.0, 0.3), (35.0, 0.2)])
def test_block_slides_with_coulomb_acceleration(theta_deg, mu):
    theta = np.radians(theta_deg)
    assert np.tan(theta) > mu
    s, t = incline(theta_deg, mu)
    a = 2.0 * np.polyfit(t, s, 2)[0]
    exact = G * (np.sin(theta) - mu * np.cos(theta))
    # kick, impulses, drift is symplectic Euler, whose positions under a constant force lie
    # exactly on a parabola with the exact acceleration; the friction impulse is mu times the
    # normal impulse m g cos(theta) dt once all four corners slide. So the fit is exact but for
    # the solver tolerance and round-off (measured 1e-14 relative); 1e-9 leaves room
    assert a == pytest.approx(exact, rel=1e-9)


def random_body(rng, **state):
    half = rng.uniform(0.2, 1.0, 3)
    points = rng.uniform(-1.0, 1.0, (12, 3)) * half
    q = rng.normal(size=4)
    return make_body(rng.uniform(0.5, 3.0), rng.uniform(0.2, 1.0, 3), points,
                     orientation=q / np.linalg.norm(q), **state)


def test_impacts_never_gain_energy():
    rng = np.random.default_rng(7)
    dt, resting = 1e-3, 2 * G * 1e-3
    hits = 0
    for trial in range(300):
        body = random_body(rng, velocity=rng.normal(size=3) * 2 - [0, 0, 3],
                           angular_velocity=rng.normal(size=3) * 5)
        # the lowest vertex up to 1 cm inside the plane
        body = replace(body, position=-(world_points(body)[:, 2].min() + rng.uniform(0, 0.01))
                       * UP)
        e = 1.0 if trial % 3 == 0 else rng.uniform(0.0, 1.0)
        mu = 0.0 if trial % 2 == 0 else rng.uniform(0.0, 1.5)
        contacts = find_contacts(body, [Plane(np.zeros(3), UP, e, mu)], dt)
        if len(contacts.gap) == 0:
            continue  # the lowest vertex was leaving
        hits += 1
        after = resolve(body, contacts, dt, resting)
        # Poisson restitution: T(after) <= T(before) for e <= 1 (module docstring); the energy
        # guard only trims round-off (it acts ~1 in 20 impacts, by < 1e-13 relative)
        assert kinetic_energy(after) <= kinetic_energy(body) * (1.0 + 1e-14)
        # and no contact vertex is left approaching the plane, beyond its speculative allowance
        # -gap / dt (a vertex not yet touching may close its gap within the step)
        vn = point_velocities(after, body.position + contacts.arm) @ UP
        allowed = -np.maximum(contacts.gap, 0.0) / dt
        assert np.all(vn >= allowed - 1e-12 * np.abs(contacts.approach).max())
    assert hits > 250


def test_spinning_bodies_bouncing_keep_energy_bounded():
    rng = np.random.default_rng(8)
    dt, n = 1e-3, 600
    for _ in range(4):
        w = rng.normal(size=3) * 5
        body = random_body(rng, position=[0.0, 0.0, 1.2], velocity=rng.normal(size=3),
                           angular_velocity=w)
        # e = 1, frictionless: the most energetic case; energy can only come from the
        # integration, O(dt^2): the rotation splitting, (|w| dt)^2 / 12 of the rotational
        # energy, and the O(g dt^2) linear time-of-impact prediction and projection
        plane = Plane(np.zeros(3), UP, restitution=1.0, friction=0.0)
        e0 = total_energy(body)
        bound = e0 * (np.linalg.norm(w) * dt) ** 2 + body.mass * G * G * dt * dt * 10
        impacts = 0
        for _ in range(n):
            before = total_energy(body)
            kicked = replace(body, momentum=body.momentum + body.mass * dt * GRAVITY)
            impacts += len(find_contacts(kicked, [Plane(np.zeros(3), UP)], dt).gap) > 0
            body = step(body, dt, GRAVITY, [plane])
            assert total_energy(body) <= before + bound
        assert total_energy(body) <= e0 + 10 * bound
        assert impacts > 0
        assert np.isfinite(velocity(body)).all()


def test_plane_rejects_bad_parameters():
    for normal, e, mu in [((0, 0, 2.0), 0.5, 0.1), (UP, 1.5, 0.1), (UP, 0.5, -0.1)]:
        with pytest.raises(ValueError):
            Plane(np.zeros(3), np.asarray(normal, dtype=float), e, mu)


def _random_spd2(rng):
    """A random symmetric positive definite 2 x 2 matrix, anisotropic up to 1e6."""
    q, _ = np.linalg.qr(rng.normal(size=(2, 2)))
    return q @ np.diag(10.0 ** rng.uniform(-3, 3, size=2)) @ q.T


def test_closed_form_eigen_pairs_match_lapack():
    """_eigen2 against numpy's eigh: the same values, orthonormal eigenvectors, k q = q w;
    diagonal and repeated values included."""
    rng = np.random.default_rng(7)
    matrices = [_random_spd2(rng) for _ in range(200)]
    matrices += [np.diag([2.0, 1.0]), np.diag([1.0, 2.0]), np.eye(2) * 3.0,
                 np.array([[1.0, 1e-9], [1e-9, 1.0]])]
    for k in matrices:
        w0, w1, q00, q01, q10, q11 = contact._eigen2(k.tolist())
        q, w = np.array([[q00, q01], [q10, q11]]), np.array([w0, w1])
        scale = np.abs(k).max()
        assert np.allclose(w, np.linalg.eigvalsh(k), rtol=0, atol=8 * EPS * scale)
        assert np.allclose(q.T @ q, np.eye(2), rtol=0, atol=8 * EPS)
        assert np.allclose(k @ q, q * w, rtol=0, atol=8 * EPS * scale)


def test_friction_impulse_is_the_least_kinetic_energy_in_the_disc():
    """The tangential impulse minimizes x.k.x / 2 + f.x over |x| <= radius: inside, the
    unconstrained minimum; on the rim, no point of the rim (sampled at 20,000 angles, then
    refined) is lower, and k x + f is opposite to x (maximum dissipation)."""
    rng = np.random.default_rng(11)
    for _ in range(100):
        k = _random_spd2(rng)
        f = rng.normal(size=2) * 10.0 ** rng.uniform(-3, 3)
        free = -np.linalg.solve(k, f)
        radius = float(np.linalg.norm(free)) * rng.choice([0.1, 0.5, 0.99, 2.0])
        x = np.array(contact._friction_impulse(k.tolist(), [], f, radius))

        def energy(y, k=k, f=f):
            return 0.5 * np.einsum("...i,ij,...j->...", y, k, y) + y @ f

        if radius >= np.linalg.norm(free):
            assert np.allclose(x, free, rtol=1e-12, atol=0)
            continue
        assert np.isclose(np.linalg.norm(x), radius, rtol=1e-12)
        angle = np.linspace(0.0, 2 * np.pi, 20_000, endpoint=False)
        rim = radius * np.stack([np.cos(angle), np.sin(angle)], axis=1)
        best = angle[np.argmin(energy(rim))]
        fine = best + np.linspace(-4e-4, 4e-4, 20_001)
        rim = radius * np.stack([np.cos(fine), np.sin(fine)], axis=1)
        scale = np.abs(energy(rim)).max()
        assert energy(x) <= energy(rim).min() + 1e-10 * scale
        velocity = k @ x + f
        assert abs(velocity[0] * x[1] - velocity[1] * x[0]) <= 1e-9 * np.linalg.norm(
            velocity) * radius
        assert velocity @ x <= 0.0


def test_friction_impulse_without_a_normal_impulse_is_zero():
    k = np.array([[2.0, 0.3], [0.3, 1.0]])
    assert contact._friction_impulse(k.tolist(), [], np.array([1.0, -2.0]), 0.0) == (0.0, 0.0)


def _plain_gauss_seidel(a, b, target, friction, sweeps):
    """Block Gauss-Seidel as the solver's sweep, every point updated every sweep (no
    skipping), for the comparison below."""
    lam = np.zeros_like(b)
    points = contact._sweep_terms(a, b, target, friction, lam)
    for _ in range(sweeps):
        for j, row, pivot, rest, sliding, _reach in points:
            lam[j] = max(lam[j] + (rest - row @ lam) / pivot, 0.0)
            if sliding is None:
                continue
            mu, rows, entries, b_t, lam_t, eigen = sliding
            if mu * lam[j] <= 0.0:
                lam_t[:] = 0.0
                continue
            (k00, k01), (k10, k11) = entries
            (r0, r1), (l0, l1) = (rows @ lam).tolist(), lam_t.tolist()
            free = (b_t[0] + r0 - (k00 * l0 + k01 * l1), b_t[1] + r1 - (k10 * l0 + k11 * l1))
            lam_t[:] = contact._friction_impulse(entries, eigen, free, mu * lam[j])
    return lam


@pytest.mark.parametrize("seed", range(6))
def test_sweeps_that_skip_points_out_of_contact_are_the_same_bits(seed):
    """Points left out of contact are skipped while the impulses moved too little to bring
    them back (contact._sweep): the impulses equal, to the bit, those of updating every
    point every sweep, on random problems of two bodies (rank 12, more points than
    freedoms), some points pushing in and some leaving, with and without friction; and
    points are skipped."""
    rng = np.random.default_rng(seed)
    c = 30
    jac = rng.normal(size=(3 * c, 12))
    a = jac @ jac.T
    b = jac @ rng.normal(size=12)
    b[0::3] += rng.choice([-3.0, 3.0], size=c)  # approaching and leaving points
    target = -np.abs(rng.normal(scale=0.1, size=c))
    friction = np.where(rng.random(c) < 0.7, 0.5, 0.0)
    for sweeps in (1, 7, 40):
        lam = np.zeros_like(b)
        points = contact._sweep_terms(a, b, target, friction, lam)
        watch, moved = [None] * c, 0.0
        for _ in range(sweeps):
            moved = contact._sweep(points, lam, watch, moved)
        plain = _plain_gauss_seidel(a, b, target, friction, sweeps)
        # the bits, signed zeros included
        np.testing.assert_array_equal(lam.view(np.int64), plain.view(np.int64))
    assert any(w is not None for w in watch)


def _stack_problem(seed):
    """A random contact problem of a few bodies: rank 18, 24 points pushing in, friction
    at most of them."""
    rng = np.random.default_rng(seed)
    c = 24
    jac = rng.normal(size=(3 * c, 18))
    b = jac @ rng.normal(size=18)
    b[0::3] -= np.abs(rng.normal(scale=2.0, size=c))
    target = -np.abs(rng.normal(scale=0.1, size=c))
    friction = np.where(rng.random(c) < 0.6, rng.uniform(0.05, 0.8, c), 0.0)
    return jac @ jac.T, b, target, friction


@pytest.mark.parametrize("frictionless", [False, True])
def test_the_polish_memo_changes_no_bit(frictionless, monkeypatch):
    """contact._polish keeps the system of its last try that did not hold and does not
    solve it again: on eight random problems, the solver's impulses, sweeps and ending
    equal, to the bit, those of trying every time. Without friction the memo spares tries
    (counted: the last failed system is left as it was); with it, the sliding directions
    change between tries on these problems, and nothing is spared."""
    polish = contact._polish
    spared = [0]

    def counted(a, b, lam, target, friction, scale, failed=None):
        before = failed[0]
        out = polish(a, b, lam, target, friction, scale, failed)
        spared[0] += out is None and before is not None and failed[0] is before
        return out

    def every_time(a, b, lam, target, friction, scale, failed=None):
        return polish(a, b, lam, target, friction, scale)

    for seed in range(8):
        a, b, target, friction = _stack_problem(seed)
        if frictionless:
            friction = np.zeros_like(friction)
        monkeypatch.setattr(contact, "_polish", counted)
        kept = contact._gauss_seidel(a, b, target, friction, polish=True)
        monkeypatch.setattr(contact, "_polish", every_time)
        every = contact._gauss_seidel(a, b, target, friction, polish=True)
        np.testing.assert_array_equal(kept[0].view(np.int64), every[0].view(np.int64))
        assert kept[1:] == every[1:]
    assert (spared[0] > 0) == frictionless


def test_a_polish_that_failed_is_not_solved_again(monkeypatch):
    """The same system after a try that did not hold: no least-squares solve, None; another
    active set: solved."""
    a, b, target, friction = _stack_problem(0)
    lam = np.zeros_like(b)
    points = contact._sweep_terms(a, b, target, friction, lam)
    watch, moved = [None] * len(points), 0.0
    for _ in range(3):
        moved = contact._sweep(points, lam, watch, moved)
    solves = []
    lstsq = np.linalg.lstsq
    monkeypatch.setattr(np.linalg, "lstsq", lambda *args, **kw: solves.append(1)
                        or lstsq(*args, **kw))
    scale = float(np.abs(b).max())
    failed = [None]
    assert contact._polish(a, b, lam, target, friction, scale, failed) is None
    assert len(solves) == 1 and failed[0] is not None
    assert contact._polish(a, b, lam, target, friction, scale, failed) is None
    assert len(solves) == 1
    other = lam.copy()
    other[0::3][np.flatnonzero(other[0::3] > 0.0)[0]] = 0.0  # one point leaves
    contact._polish(a, b, other, target, friction, scale, failed)
    assert len(solves) == 2
