"""Free flight of a rigid body under gravity (DESIGN §2, "Fragments and rigid bodies").

Gravity acts at the centre of mass, so it exerts no torque: the translation is a parabola,
integrated exactly, and the rotation is the torque-free (Euler-Poinsot) motion, in which the
world angular momentum ``L`` is constant.

The rotation is advanced by the symmetric splitting of the free rigid body into exact
rotations about its principal axes (Dullweber, Leimkuhler & McLachlan 1997, J. Chem. Phys.
107, 5840). The kinetic energy ``T = sum_k Lb_k^2 / (2 I_k)`` (``Lb = R^T L``, body frame) is
a sum of three terms; the flow of each one alone is a rotation about one body axis at the
constant rate ``Lb_k / I_k``, which the body frame ``L`` follows backwards. Strang's
composition

    axis 1 for dt/2, axis 2 for dt/2, axis 3 for dt, axis 2 for dt/2, axis 1 for dt/2

is second order, time reversible and symplectic (Lie-Poisson), so

- ``L`` (world) is unchanged: each sub-rotation turns the body and its body-frame ``L``
  together, so ``R Lb`` is constant; |L| is kept to round-off;
- the energy error is bounded by O(dt^2) for all time (a nearby modified energy is kept
  exactly): it oscillates, it does not drift;
- the intermediate-axis (Dzhanibekov) flips come at the right times, to O(dt^2).

Not used: explicit gyroscopic updates (``omega += dt I^-1 (I omega x omega)``) gain energy at
every step (|L| grows by a factor 1 + O(dt^2) a step; tests/test_rigid_motion.py shows the
drift) and one-step implicit Euler loses it.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .body import RigidBody, exp_map, inverse_moments, rotation_matrix

# Strang splitting: (principal axis, fraction of dt) in the order applied.
_SPLITTING = ((0, 0.5), (1, 0.5), (2, 1.0), (1, 0.5), (0, 0.5))
_AXES = np.eye(3)


def _rotate_about(vector: np.ndarray, axis: int, angle: float) -> np.ndarray:
    """(3,) ``vector`` turned by ``angle`` rad about coordinate axis ``axis``."""
    i, j = (axis + 1) % 3, (axis + 2) % 3
    c, s = np.cos(angle), np.sin(angle)
    out = vector.copy()
    out[i] = c * vector[i] - s * vector[j]
    out[j] = s * vector[i] + c * vector[j]
    return out


def free_rotation(orientation, inertia, angular_momentum, dt: float) -> np.ndarray:
    """(4,) orientation after ``dt`` of torque-free rotation.

    orientation: (4,) unit quaternion, body -> world; inertia: (3,) principal moments;
    angular_momentum: (3,) world, constant during the step; dt: time.
    A degenerate axis (zero moment) is skipped: it has no flow (see body.py).
    """
    q = np.asarray(orientation, dtype=float)
    inv = inverse_moments(inertia)
    lb = rotation_matrix(q).T @ np.asarray(angular_momentum, dtype=float)
    for axis, fraction in _SPLITTING:
        angle = lb[axis] * inv[axis] * fraction * dt
        # body turns by +angle about its axis; seen from the body, L turns by -angle
        q = _multiply_axis(q, exp_map(angle * _AXES[axis]))
        lb = _rotate_about(lb, axis, -angle)
    # the unit norm is lost only to round-off; renormalizing keeps R orthogonal over long runs
    return q / np.linalg.norm(q)


def _multiply_axis(q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Hamilton product ``q * r`` (4,), written out: it runs five times per step."""
    w0, x0, y0, z0 = q
    w1, x1, y1, z1 = r
    return np.array(
        [
            w0 * w1 - x0 * x1 - y0 * y1 - z0 * z1,
            w0 * x1 + x0 * w1 + y0 * z1 - z0 * y1,
            w0 * y1 - x0 * z1 + y0 * w1 + z0 * x1,
            w0 * z1 + x0 * y1 - y0 * x1 + z0 * w1,
        ]
    )


def free_flight(body: RigidBody, dt: float, gravity) -> RigidBody:
    """The body after ``dt`` of flight under uniform ``gravity`` (3,) (acceleration).

    Translation is exact: ``x += v dt + g dt^2 / 2``, ``P += m g dt``. Rotation is torque-free:
    ``L`` is kept and the orientation advanced by :func:`free_rotation`.
    """
    g = np.asarray(gravity, dtype=float)
    v = body.momentum / body.mass
    return replace(
        body,
        position=body.position + v * dt + 0.5 * dt * dt * g,
        momentum=body.momentum + body.mass * dt * g,
        orientation=free_rotation(body.orientation, body.inertia, body.angular_momentum, dt),
    )


def rotational_energy(inertia, body_angular_momentum) -> float:
    """``sum_k Lb_k^2 / (2 I_k)`` of body-frame angular momentum (3,) (energy units)."""
    lb = np.asarray(body_angular_momentum, dtype=float)
    return 0.5 * float(inverse_moments(inertia) @ (lb * lb))
