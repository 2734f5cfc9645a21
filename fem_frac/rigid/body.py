"""Rigid-body state and kinematics (DESIGN §2, "Fragments and rigid bodies").

A body is described in its principal frame: the body frame has its origin at the centre of
mass and its axes along the principal axes of inertia, so the body-frame inertia tensor is
``diag(inertia)``. The orientation quaternion ``q = (w, x, y, z)`` maps body to world:
``x_world = position + R(q) @ x_body``. The dynamic state is the pair of momenta (linear ``P``
and angular ``L`` about the centre, both in the world frame), because momenta, not
velocities, are what impulses change and what torque-free motion conserves.

Units are the caller's consistent system (SI: kg, kg m^2, m, kg m/s, kg m^2/s, rad).

Degenerate bodies: a principal moment that is zero (a point mass, a thin rod about its own
axis) has no rotational inertia about that axis. Its inverse is taken as zero (the
pseudo-inverse), so angular momentum along that axis produces no spin; the caller should not
give a degenerate body angular momentum along such an axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .vectors import cross, length

# Moments below this fraction of the largest count as zero (a degenerate axis).
_DEGENERATE = 1e-14
# Below this rotation angle (rad) exp_map uses its series: the truncation error ~theta^6/1e6
# is far below round-off, while sin(theta/2)/theta would lose digits to cancellation.
_SMALL_ANGLE = 1e-4


@dataclass(frozen=True, eq=False)
class RigidBody:
    """State of one rigid body; update with ``dataclasses.replace``.

    mass: float, > 0.
    inertia: (3,) principal moments, body frame (principal axes through the centre).
    position: (3,) centre of mass, world.
    orientation: (4,) unit quaternion (w, x, y, z), body -> world rotation.
    momentum: (3,) linear momentum, world.
    angular_momentum: (3,) angular momentum about the centre, world.
    points: (k, 3) body-frame coordinates of the vertices used for contact.
    """

    mass: float
    inertia: np.ndarray
    position: np.ndarray
    orientation: np.ndarray
    momentum: np.ndarray
    angular_momentum: np.ndarray
    points: np.ndarray


def make_body(
    mass: float,
    inertia,
    points,
    position=(0.0, 0.0, 0.0),
    orientation=(1.0, 0.0, 0.0, 0.0),
    velocity=(0.0, 0.0, 0.0),
    angular_velocity=(0.0, 0.0, 0.0),
) -> RigidBody:
    """A body from velocities: ``P = m v``, ``L = R diag(I) R^T omega`` (omega world, (3,))."""
    inertia = np.asarray(inertia, dtype=float)
    q = np.asarray(orientation, dtype=float)
    q = q / np.linalg.norm(q)
    r = rotation_matrix(q)
    omega = np.asarray(angular_velocity, dtype=float)
    return RigidBody(
        mass=float(mass),
        inertia=inertia,
        position=np.asarray(position, dtype=float),
        orientation=q,
        momentum=float(mass) * np.asarray(velocity, dtype=float),
        angular_momentum=r @ (inertia * (r.T @ omega)),
        points=np.asarray(points, dtype=float).reshape(-1, 3),
    )


def fixed_body(points, position=(0.0, 0.0, 0.0),
               orientation=(1.0, 0.0, 0.0, 0.0)) -> RigidBody:
    """A fixed obstacle as a body: infinite mass and moments (inverse mass and inverse
    inertia zero, :func:`inverse_mass`, :func:`inverse_moments`), at rest. Contact between
    bodies (:mod:`~fem_frac.rigid.pairs`) treats it as any body, and it receives no impulse;
    it is never moved (its velocity is zero: momentum 0 over mass inf)."""
    q = np.asarray(orientation, dtype=float)
    return RigidBody(mass=np.inf, inertia=np.full(3, np.inf),
                     position=np.asarray(position, dtype=float),
                     orientation=q / np.linalg.norm(q), momentum=np.zeros(3),
                     angular_momentum=np.zeros(3),
                     points=np.asarray(points, dtype=float).reshape(-1, 3))


def inverse_mass(body: RigidBody) -> float:
    """``1 / mass``; 0 for a fixed body (infinite mass)."""
    return 0.0 if np.isinf(body.mass) else 1.0 / body.mass


def rotation_matrix(q) -> np.ndarray:
    """(3, 3) rotation of the unit quaternion ``q`` (4,) = (w, x, y, z).

    In Python floats: the same roundings as on numpy's scalars, a third of their time
    (the contact steps ask it tens of thousands of times)."""
    w, x, y, z = np.asarray(q, dtype=float).tolist()
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def quaternion_from_matrix(r) -> np.ndarray:
    """(4,) unit quaternion with ``w >= 0`` of a (3, 3) rotation matrix.

    Shepperd's method: the square root is taken of the largest of 1 + trace and the three
    1 + 2 R_ii - trace, so the divisor is never small (at least 1/2) and no digits are lost
    near 180-degree rotations, where the naive ``w = sqrt(1 + trace) / 2`` goes to zero.
    """
    r = np.asarray(r, dtype=float)
    t = np.trace(r)
    k = int(np.argmax([t, r[0, 0], r[1, 1], r[2, 2]]))
    if k == 0:
        s = 2.0 * np.sqrt(1.0 + t)
        q = [s / 4, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    elif k == 1:
        s = 2.0 * np.sqrt(1.0 + 2 * r[0, 0] - t)
        q = [(r[2, 1] - r[1, 2]) / s, s / 4, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s]
    elif k == 2:
        s = 2.0 * np.sqrt(1.0 + 2 * r[1, 1] - t)
        q = [(r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, s / 4, (r[1, 2] + r[2, 1]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + 2 * r[2, 2] - t)
        q = [(r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, s / 4]
    q = np.array(q)
    q = q if q[0] >= 0 else -q
    return q / np.linalg.norm(q)


def quaternion_multiply(a, b) -> np.ndarray:
    """Hamilton product ``a * b`` (4,): ``R(a * b) = R(a) @ R(b)``."""
    aw, av = a[0], np.asarray(a[1:])
    bw, bv = b[0], np.asarray(b[1:])
    return np.concatenate(([aw * bw - av @ bv], aw * bv + bw * av + cross(av, bv)))


def exp_map(rotation_vector) -> np.ndarray:
    """(4,) unit quaternion of a rotation by ``|phi|`` rad about ``phi / |phi|``; phi (3,).

    Exact: (cos(theta/2), sin(theta/2) phi / theta), with the series of sin(theta/2)/theta
    for small theta.
    """
    phi = np.asarray(rotation_vector, dtype=float)
    theta = float(length(phi))
    if theta < _SMALL_ANGLE:
        t2 = theta * theta
        half_sinc = 0.5 - t2 / 48.0 + t2 * t2 / 3840.0
    else:
        half_sinc = np.sin(0.5 * theta) / theta
    return np.concatenate(([np.cos(0.5 * theta)], half_sinc * phi))


def inverse_moments(inertia) -> np.ndarray:
    """(3,) 1 / I_k, with 0 for a degenerate (zero) moment (below ``_DEGENERATE`` of the
    largest; all three for a fixed body's infinite ones): the pseudo-inverse. In Python
    floats, the same divisions as numpy's."""
    inertia = np.asarray(inertia, dtype=float)
    floor = _DEGENERATE * max(float(inertia.max()), 0.0)
    return np.array([1.0 / m if m > floor else 0.0 for m in inertia.tolist()])


def inverse_inertia_world(body: RigidBody) -> np.ndarray:
    """(3, 3) world inverse inertia ``R diag(1/I) R^T`` (pseudo-inverse if degenerate)."""
    r = rotation_matrix(body.orientation)
    return (r * inverse_moments(body.inertia)) @ r.T


def body_angular_momentum(body: RigidBody) -> np.ndarray:
    """(3,) angular momentum in the body (principal) frame, ``R^T L``."""
    return rotation_matrix(body.orientation).T @ body.angular_momentum


def velocity(body: RigidBody) -> np.ndarray:
    """(3,) velocity of the centre, world."""
    return body.momentum / body.mass


def angular_velocity(body: RigidBody) -> np.ndarray:
    """(3,) angular velocity, world: ``R diag(1/I) R^T L``."""
    return inverse_inertia_world(body) @ body.angular_momentum


def kinetic_energy(body: RigidBody) -> float:
    """Translational ``|P|^2 / 2m`` plus rotational ``sum_k Lb_k^2 / 2 I_k`` (energy units)."""
    lb = body_angular_momentum(body)
    rotational = 0.5 * float(inverse_moments(body.inertia) @ (lb * lb))
    return 0.5 * float(body.momentum @ body.momentum) / body.mass + rotational


def world_points(body: RigidBody) -> np.ndarray:
    """(k, 3) world coordinates of the contact vertices."""
    return body.position + body.points @ rotation_matrix(body.orientation).T


def point_velocities(body: RigidBody, x_world) -> np.ndarray:
    """(k, 3) velocities ``v + omega x (x - position)`` of world points ``x_world`` (k, 3)."""
    arm = np.asarray(x_world, dtype=float) - body.position
    return velocity(body) + cross(angular_velocity(body), arm)
