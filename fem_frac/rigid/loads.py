"""Surface loads that leave with a rigid piece (DESIGN §2, "Fragments and rigid bodies").

A traction or pressure whose faces leave the finite elements with a piece acts on the rigid
body from then on (before, it acted on nothing). At hand-off, for each load curve ``c`` and
kind, the nodal forces ``f_a`` at curve factor 1 (``Problem.tractions[c]`` or
``Problem.pressures[c]``, on the piece's nodes, those of its elements) are reduced to

    F = sum_a f_a,        C = sum_a b_a f_a^T  (3 x 3),

``b_a`` the node's body-frame coordinates (fixed: the shape is frozen). The moment about the
centre at orientation ``R`` is ``M = sum_a (R b_a) x f_a``, the axial vector of ``R C``: exact
at every orientation, and at hand-off the moment of the finite-element nodal forces.

- Tractions keep their world direction on faces that turn (the finite elements' tractions
  are fixed world vectors): ``F`` and ``C`` with ``f_a`` in the world frame, force ``F``,
  moment ``axial(R C)``; the lever arms turn with the body.
- Pressures follow the face (a follower load): ``f_a`` in the body frame (``R0^T f_a``),
  force ``R F``, moment ``R axial(C)``.

Time integration (:func:`advance`): impulse splitting per substep ``[t, t + h]``: a half
kick of ``P`` and ``L`` by ``h/2`` times the load at ``t``, the exact free flight / contact
step under gravity (:func:`~fem_frac.rigid.contact.step`), a half kick by ``h/2`` times the
load at ``t + h`` (at the orientation then). The impulse of a world-fixed load is the
trapezoidal rule of ``factor(t) F`` over the substep: exact for a piecewise-linear curve
whose breaks fall on substep ends; the motion under gravity alone stays exact.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from .body import RigidBody, rotation_matrix
from .contact import step


@dataclass(frozen=True, eq=False)
class RigidLoad:
    """A load on a rigid body: ``factor(t)`` times the force ``force (3,)`` with the lever
    arms ``arms (3, 3)`` (``sum_a b_a f_a^T``), in the world frame for a world-fixed load
    (traction), in the body frame for a ``follower`` (pressure); ``curve``: the curve's
    name."""

    factor: Callable[[float], float]
    force: np.ndarray
    arms: np.ndarray
    follower: bool
    curve: str = ""

    def resultant(self, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World force and moment about the centre ``(3,), (3,)`` at curve factor 1 and
        orientation ``r`` (3, 3)."""
        if self.follower:
            return r @ self.force, r @ _axial(self.arms)
        return self.force, _axial(r @ self.arms)


def _axial(c: np.ndarray) -> np.ndarray:
    """``sum_a r_a x f_a`` of ``c = sum_a r_a f_a^T``."""
    return np.array([c[1, 2] - c[2, 1], c[2, 0] - c[0, 2], c[0, 1] - c[1, 0]])


def piece_loads(problem, nodes: np.ndarray, body_coords: np.ndarray,
                orientation: np.ndarray) -> tuple[RigidLoad, ...]:
    """The loads of ``problem`` on the scalar ``nodes (k,)`` of a piece whose body-frame
    coordinates are ``body_coords (k, 3)`` and orientation ``orientation`` (quaternion)."""
    r0 = rotation_matrix(orientation)
    out = []
    for forces, follower in ((problem.tractions, False), (problem.pressures, True)):
        if forces is None:
            continue
        for c, force in enumerate(forces):
            f = force.reshape(-1, 3)[nodes]
            if not np.any(f):
                continue
            if follower:
                f = f @ r0  # rows R0^T f_a: the body frame
            out.append(RigidLoad(problem.curves[c], f.sum(axis=0), body_coords.T @ f,
                                 follower, problem.curve_names[c]))
    return tuple(out)


def acceleration(body: RigidBody, loads: tuple[RigidLoad, ...], t: float) -> np.ndarray:
    """``(3,)``: the acceleration of the centre of ``body`` its loads give at time ``t`` (at
    its orientation now; gravity not included)."""
    if not loads:
        return np.zeros(3)
    r = rotation_matrix(body.orientation)
    force = sum(float(load.factor(t)) * load.resultant(r)[0] for load in loads)
    return np.asarray(force, dtype=float) / body.mass


def kick(body: RigidBody, loads: tuple[RigidLoad, ...], t: float, dt: float) -> RigidBody:
    """``body`` after the impulse ``dt`` times its loads at time ``t`` (at its orientation
    now)."""
    if not loads:
        return body
    r = rotation_matrix(body.orientation)
    p, ell = body.momentum, body.angular_momentum
    for load in loads:
        k = dt * float(load.factor(t))
        if k != 0.0:
            force, moment = load.resultant(r)
            p, ell = p + k * force, ell + k * moment
    return replace(body, momentum=p, angular_momentum=ell)


def advance(body: RigidBody, loads: tuple[RigidLoad, ...], t: float, h: float, gravity,
            planes) -> RigidBody:
    """One substep ``[t, t + h]``: half kick by the loads, contact step, half kick."""
    body = kick(body, loads, t, 0.5 * h)
    body = step(body, h, gravity, planes)
    return kick(body, loads, t + h, 0.5 * h)
