"""Rigid-body kinematics and torque-free free flight (fem_frac.rigid.body, .motion)."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fem_frac.rigid.body import (
    body_angular_momentum,
    exp_map,
    kinetic_energy,
    make_body,
    point_velocities,
    quaternion_from_matrix,
    quaternion_multiply,
    rotation_matrix,
    velocity,
    world_points,
)
from fem_frac.rigid.motion import free_flight, rotational_energy

NO_GRAVITY = np.zeros(3)
ONE_POINT = np.zeros((1, 3))
# Dzhanibekov body: spin near the intermediate axis 2, slightly perturbed
ASYMMETRIC = np.array([1.0, 2.0, 3.0])
NEAR_AXIS_2 = np.array([0.01, 1.0, 0.01])
EPS = np.finfo(float).eps


def random_quaternions(rng, n):
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    return q * np.sign(q[:, :1])


def rodrigues(phi):
    theta = np.linalg.norm(phi)
    if theta == 0.0:
        return np.eye(3)
    k = np.cross(np.eye(3), phi / theta)  # [k]x
    return np.eye(3) + np.sin(theta) * k + (1.0 - np.cos(theta)) * k @ k


# -- quaternion helpers ------------------------------------------------------------------------


def test_matrix_quaternion_round_trip():
    rng = np.random.default_rng(0)
    # random rotations, plus near-180-degree ones (w ~ 0) where a naive inverse loses digits
    qs = np.vstack([random_quaternions(rng, 200), [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 1]],
                    np.c_[np.full(3, 1e-9), np.eye(3)]])
    for q in qs:
        q = q / np.linalg.norm(q)
        r = rotation_matrix(q)
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
        assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-14)
        back = quaternion_from_matrix(r)
        assert back[0] >= 0.0
        # q and -q are the same rotation; compare on the w >= 0 sheet (a w ~ 0 pair may flip)
        assert min(np.abs(back - q).max(), np.abs(back + q).max()) < 1e-14
        np.testing.assert_allclose(rotation_matrix(back), r, atol=1e-15)


def test_exp_map_is_rodrigues():
    rng = np.random.default_rng(1)
    phis = [*rng.normal(size=(50, 3)) * 2.0, np.zeros(3), [1e-9, 0, 0], [3e-5, -2e-5, 1e-5],
            [0, 0, np.pi], [1.2e-4, 0.0, 0.0]]
    for phi in phis:
        q = exp_map(phi)
        assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)
        np.testing.assert_allclose(rotation_matrix(q), rodrigues(np.asarray(phi)), atol=2e-15)


def test_composition():
    rng = np.random.default_rng(2)
    a, b = random_quaternions(rng, 2)
    np.testing.assert_allclose(rotation_matrix(quaternion_multiply(a, b)),
                               rotation_matrix(a) @ rotation_matrix(b), atol=1e-15)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    np.testing.assert_allclose(quaternion_multiply(exp_map(0.3 * axis), exp_map(1.1 * axis)),
                               exp_map(1.4 * axis), atol=1e-15)


def test_point_velocities_and_energy():
    rng = np.random.default_rng(3)
    q = random_quaternions(rng, 1)[0]
    points = rng.normal(size=(5, 3))
    v, w = np.array([1.0, -2.0, 0.5]), np.array([0.3, 0.2, -1.0])
    body = make_body(2.0, [1.0, 2.0, 3.0], points, (1, 2, 3), q, v, w)
    x = world_points(body)
    np.testing.assert_allclose(point_velocities(body, x), v + np.cross(w, x - body.position))
    inertia_world = rotation_matrix(q) @ np.diag([1.0, 2.0, 3.0]) @ rotation_matrix(q).T
    assert kinetic_energy(body) == pytest.approx(0.5 * 2.0 * v @ v + 0.5 * w @ inertia_world @ w)


# -- free flight ---------------------------------------------------------------------------


def test_free_fall_is_exact():
    g = np.array([0.0, 0.0, -9.81])
    x0, v0, dt, n = np.array([1.0, -2.0, 10.0]), np.array([3.0, 1.0, 5.0]), 1e-3, 2000
    body = make_body(1.5, ASYMMETRIC, ONE_POINT, x0, velocity=v0, angular_velocity=[2, 5, -3])
    for _ in range(n):
        body = free_flight(body, dt, g)
    t = n * dt
    travel = np.linalg.norm(v0 * t + 0.5 * g * t * t)
    # the parabola is integrated exactly: only round-off of n additions, ~n eps relative
    np.testing.assert_allclose(body.position, x0 + v0 * t + 0.5 * g * t * t,
                               atol=1e-12 * travel)
    np.testing.assert_allclose(velocity(body), v0 + g * t, atol=1e-12 * np.linalg.norm(g * t))


def precession_rate_error(dt, periods=2.0):
    """Relative error of the precession rate of a torque-free symmetric top (I1 = I2)."""
    inertia = np.array([1.0, 1.0, 2.0])
    body = make_body(1.0, inertia, ONE_POINT, angular_velocity=[0.0, 0.6, 0.8])
    lhat = body.angular_momentum / np.linalg.norm(body.angular_momentum)
    rate = np.linalg.norm(body.angular_momentum) / inertia[0]  # analytic: period 2 pi I1 / |L|
    u = np.cross(lhat, [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(lhat, u)
    n = int(round(periods * 2 * np.pi / rate / dt))
    angle, cone = np.empty(n + 1), np.empty(n + 1)
    for i in range(n + 1):
        axis = rotation_matrix(body.orientation)[:, 2]  # symmetry axis, world
        angle[i], cone[i] = np.arctan2(axis @ w, axis @ u), axis @ lhat
        body = free_flight(body, dt, NO_GRAVITY)
    fitted = np.polyfit(dt * np.arange(n + 1), np.unwrap(angle), 1)[0]
    return fitted / rate - 1.0, np.ptp(cone), rate


def test_symmetric_top_precesses_at_the_analytic_rate():
    (err1, cone1, rate), (err2, cone2, _) = precession_rate_error(0.1), precession_rate_error(0.05)
    # Strang splitting: the error is O(dt^2), so halving dt divides it by 4
    assert 3.8 < err1 / err2 < 4.2
    # the constant is of the size of the splitting's commutator terms, (rate dt)^2 / 12 and
    # below (measured: 0.034 (rate dt)^2, i.e. 1.0e-3 at dt = 0.1 and 2.5e-4 at dt = 0.05)
    assert abs(err1) < (rate * 0.1) ** 2 / 12 and abs(err2) < (rate * 0.05) ** 2 / 12
    # the axis keeps its angle to L (exactly a cone): wobble O(dt^2) too (measured 1e-5, 2.5e-6)
    assert cone1 < 1e-4 and cone2 < cone1 / 3.5


def intermediate_axis_flips(dt, t_end):
    """Times at which the body-frame angular velocity along axis 2 changes sign."""
    body = make_body(1.0, ASYMMETRIC, ONE_POINT, angular_velocity=NEAR_AXIS_2)
    n = int(round(t_end / dt))
    w2 = np.empty(n + 1)
    for i in range(n + 1):
        w2[i] = body_angular_momentum(body)[1] / ASYMMETRIC[1]
        body = free_flight(body, dt, NO_GRAVITY)
    k = np.flatnonzero(np.sign(w2[1:]) != np.sign(w2[:-1]))
    return dt * (k + w2[k] / (w2[k] - w2[k + 1]))  # linear interpolation: O(dt^2) as well


def euler_equations(_t, w):
    i1, i2, i3 = ASYMMETRIC
    return [(i2 - i3) * w[1] * w[2] / i1, (i3 - i1) * w[2] * w[0] / i2,
            (i1 - i2) * w[0] * w[1] / i3]


def test_intermediate_axis_flip_times():
    t_end = 55.0
    sign_change = lambda _t, w: w[1]  # noqa: E731
    ref = solve_ivp(euler_equations, (0.0, t_end), NEAR_AXIS_2, method="DOP853", rtol=1e-12,
                    atol=1e-14, events=sign_change).t_events[0]
    assert len(ref) == 3  # flips near t = 10.9, 30.5, 50.0
    errors = []
    for dt in (0.01, 0.005):
        flips = intermediate_axis_flips(dt, t_end)
        assert len(flips) == len(ref)
        errors.append(np.abs(flips - ref))
    # second order: the flip-time error is a phase error accumulating at a rate ~ dt^2, so it
    # grows with t and drops 4x when dt halves; measured 0.041 dt^2 t (5.0e-5, 1.4e-4, 2.2e-4
    # at dt = 0.01); the bound 0.1 dt^2 t leaves room for the interpolation of the crossing
    for dt, err in zip((0.01, 0.005), errors, strict=True):
        assert np.all(err < 0.1 * dt * dt * ref)
    np.testing.assert_allclose(errors[0] / errors[1], 4.0, rtol=0.05)


@pytest.mark.parametrize("omega", [NEAR_AXIS_2, np.array([0.4, 1.0, -0.6])])
def test_long_run_keeps_angular_momentum_and_energy(omega):
    dt, n, window = 0.01, 10_000, 1000
    body = make_body(1.0, ASYMMETRIC, ONE_POINT, angular_velocity=omega)
    l0 = body.angular_momentum.copy()
    norm0, e0 = np.linalg.norm(l0), kinetic_energy(body)
    energy, l_error = np.empty(n), np.empty(n)
    for i in range(n):
        body = free_flight(body, dt, NO_GRAVITY)
        lb = body_angular_momentum(body)  # from the integrated orientation
        l_error[i] = abs(np.linalg.norm(lb) - norm0) / norm0
        energy[i] = (rotational_energy(ASYMMETRIC, lb) - e0) / e0
    np.testing.assert_array_equal(body.angular_momentum, l0)  # L (world) is never touched
    assert l_error.max() < 1e-12  # R stays orthogonal: |R^T L| = |L| (measured 1e-15)
    # bounded O(dt^2) energy error, below (|omega| dt)^2 / 12 (measured 0.007 and 0.001 of it)
    bound = (np.linalg.norm(omega) * dt) ** 2 / 12
    assert np.abs(energy).max() < bound
    # no drift: the error oscillates; the mean of the last 1000 steps is that of the first
    # 1000 to within a small fraction of the oscillation (measured < 0.02 of the max error)
    drift = abs(energy[-window:].mean() - energy[:window].mean())
    assert drift < 0.1 * np.abs(energy).max()

    # contrast: explicit Euler on Euler's equations (dLb/dt = Lb x omega_b) gains energy at
    # every step, |Lb| grows by dt^2 |Lb x omega|^2 a step, and its drift dwarfs the above
    lb = ASYMMETRIC * omega
    explicit = np.empty(n)
    for i in range(n):
        lb = lb + dt * np.cross(lb, lb / ASYMMETRIC)
        explicit[i] = (rotational_energy(ASYMMETRIC, lb) - e0) / e0
    assert np.all(np.diff(explicit) > 0)
    assert explicit[-window:].mean() - explicit[:window].mean() > 100 * np.abs(energy).max()


def test_orientation_stays_a_unit_quaternion_over_a_long_tumble():
    """10^4 steps of ``free_flight`` (every branch of ``contact.step``, the step of the rigid
    stage, advances the orientation through it; the impulses and the projection leave it
    alone) of a body tumbling fast near its intermediate axis (20 rad/s: ~30 turns, a flip
    every ~1 s), falling free.

    Every step ends in ``q / |q|`` (``motion.free_rotation``), so ``|q| - 1`` is the round-off
    of one normalization: the norm of four components is computed to ~2.5 units of round-off
    u = eps / 2, the division adds u, and measuring the result ~2.5 u again: at most 3 eps
    (measured at most 1 eps); ``R(q)`` is then orthogonal to the same order. Without the
    renormalization the five quaternion products of every step let |q| wander off 1 (a random
    walk of ~eps per product: measured past 4 eps within 20-70 steps, 40-170 eps after 10^4
    steps), and ``R(q)`` stops being a rotation with it.
    """
    dt, n = 1e-3, 10_000
    body = make_body(1.0, ASYMMETRIC, ONE_POINT, angular_velocity=20.0 * NEAR_AXIS_2)
    gravity = np.array([0.0, 0.0, -9.81])
    norm_error = np.empty(n)
    w2 = []
    for i in range(n):
        body = free_flight(body, dt, gravity)
        q = body.orientation
        norm_error[i] = abs(np.sqrt(q @ q) - 1.0)
        if i % 10 == 0:
            w2.append(body_angular_momentum(body)[1])
    assert np.count_nonzero(np.diff(np.sign(w2))) >= 5  # it does tumble
    assert norm_error.max() <= 4 * EPS
    r = rotation_matrix(body.orientation)
    assert np.abs(r @ r.T - np.eye(3)).max() <= 8 * EPS


def _rotation_on_numpy_scalars(q):
    """rotation_matrix as it was, on numpy's scalars (the reference of the test below)."""
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _inverse_moments_on_numpy(inertia):
    inertia = np.asarray(inertia, dtype=float)
    live = inertia > 1e-14 * max(float(inertia.max()), 0.0)
    return np.where(live, 1.0 / np.where(live, inertia, 1.0), 0.0)


def test_rotation_and_inverse_moments_in_python_floats_are_numpys_to_the_bit():
    """rotation_matrix and inverse_moments compute on Python floats: the same roundings
    as on numpy's scalars and arrays, signed zeros, degenerate and fixed bodies included."""
    from fem_frac.rigid.body import inverse_moments

    rng = np.random.default_rng(11)
    quaternions = list(rng.standard_normal((500, 4)))
    quaternions += [np.array(q, dtype=float) for q in
                    ((1, 0, 0, 0), (-0.0, 1, 0, -0.0), (0.5, -0.5, 0.5, -0.5), (0, 0, 0, 1))]
    for q in quaternions:
        q = q / np.linalg.norm(q)
        assert rotation_matrix(q).tobytes() == _rotation_on_numpy_scalars(q).tobytes()
    moments = list(np.abs(rng.standard_normal((500, 3))) * 10.0 ** rng.integers(-8, 8, (500, 3)))
    moments += [np.array(m, dtype=float) for m in
                ((1.0, 1.0, 0.0), (1.0, 1e-15, 1e-13), (np.inf,) * 3, (0.0, 0.0, 0.0),
                 (2.0, -0.0, 2.0))]
    for m in moments:
        got, want = inverse_moments(m), _inverse_moments_on_numpy(m)
        assert got.dtype == want.dtype and got.tobytes() == want.tobytes()
