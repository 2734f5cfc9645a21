"""Hand-off of free pieces to rigid bodies (fem_frac.rigid.fragment, fem_frac.rigid.stage).

The rigid body of a piece gets P = sum (M v)_a and L = sum (x_a - X) x (M v)_a, so the sums
over the pieces of a parent equal the parent's own to round-off, whatever the velocity
field; the mass and the centre equal the finite-element ones because consistent and lumped
masses integrate constants and linear fields exactly on straight tets. The inertia is that of
the same mass: the tets' exact one for the consistent mass, the nodal point masses' for the
lumped one, so a rigid motion is handed off with its kinetic energy 1/2 v^T M v.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fem_frac.app.driver import prepare
from fem_frac.config.schema import Case
from fem_frac.fracture import fragments, open_crack
from fem_frac.rigid.body import angular_velocity, kinetic_energy, velocity
from fem_frac.rigid.fragment import rigid_piece
from fem_frac.rigid.stage import RigidStage
from fem_frac.solve.state import State
from fem_frac.timing import StageTimer
from fem_frac.world.state import body_of
from fem_frac.world.transfer import rediscretize
from meshes import structured_box


def _stages(order: int, mass: str):
    case = {
        "mesh": {"geometry": {"type": "box", "lengths": [2.0, 0.5, 0.5]},
                 "element_size": 0.25, "order": order},
        "material": {"youngs_modulus": 1e7, "poissons_ratio": 0.3, "density": 1000.0},
        "fracture": {"tensile_strength": 1e9, "smoothing": {"rings": 1}},
        "fragments": {},
        "analysis": {"type": "dynamic", "dt": 1e-3, "steps": 1, "mass": mass},
    }
    return prepare(Case.model_validate(case), Path("."), StageTimer())


def _on(setup, mesh):
    """The case's discretization on ``mesh``."""
    return rediscretize(setup.disc, mesh, StageTimer(), "on a cut mesh")


def hand_off(d, state, elements):
    return RigidStage.hand_off(body_of(d, state), elements)


def _cut_bar():
    """A 2 x 0.5 x 0.5 bar cut across at x = 1 into two pieces, plus a third piece cut off
    at x = 1.5: three free pieces."""
    mesh = structured_box((8, 2, 2), lengths=(2.0, 0.5, 0.5), distortion=0.2, seed=1)
    for x in (1.0, 1.5):
        plane = np.flatnonzero(np.abs(mesh.points[:, 0] - x) < 1e-12)
        mesh, _ = open_crack(mesh, plane, np.tile([1.0, 0.0, 0.0], (len(plane), 1)))
    assert fragments(mesh.tets)[0] == 3
    return mesh


def _moving(d, rng, spin=True):
    """A state translating, spinning and vibrating: v = V + w x x + noise; u small."""
    space = d.space
    x = space.node_points
    v = np.array([1.0, -2.0, 0.5]) + (np.cross([3.0, 1.0, -2.0], x) if spin else 0.0)
    v = (v + 0.3 * rng.normal(size=x.shape)).ravel()
    u = 1e-3 * rng.normal(size=space.n_dofs)
    stress, _, _ = d.law.update(d.ops.strain_operator.strain(u), None)
    n = space.n_dofs
    return State(0.0, u, v, np.zeros(n), stress, None, np.zeros(n),
                 np.zeros(len(d.constrained.dofs)))


@pytest.mark.parametrize("order,mass", [(1, "lumped"), (1, "consistent"), (2, "consistent")])
def test_pieces_keep_the_parents_momenta(order, mass):
    setup = _stages(order, mass)
    d = _on(setup, _cut_bar())
    state = _moving(d, np.random.default_rng(0))
    x = (d.space.node_points + state.u.reshape(-1, 3))
    mv = (d.ops.mass @ state.v).reshape(-1, 3)
    p_parent = mv.sum(axis=0)
    l_parent = np.cross(x, mv).sum(axis=0)  # about the origin
    _, labels = fragments(d.mesh.tets)
    bodies = [hand_off(d, state, np.flatnonzero(labels == k)).body for k in range(3)]
    p = sum(b.momentum for b in bodies)
    l_total = sum(b.angular_momentum + np.cross(b.position, b.momentum) for b in bodies)
    scale = np.abs(l_parent).max()
    np.testing.assert_allclose(p, p_parent, rtol=0, atol=1e-12 * np.abs(p_parent).max())
    np.testing.assert_allclose(l_total, l_parent, rtol=0, atol=1e-12 * scale)
    # masses and centres: the finite-element ones (constants and linear fields are exact)
    m_fe = (d.ops.mass @ np.tile([1.0, 0.0, 0.0], d.space.n_nodes))[0::3]
    assert sum(b.mass for b in bodies) == pytest.approx(m_fe.sum(), rel=1e-12)
    for k, b in enumerate(bodies):
        nodes = np.unique(d.space.basis.element_dofs[:, labels == k])
        first = (d.ops.mass @ (d.space.node_points + state.u.reshape(-1, 3))
                 .ravel()).reshape(-1, 3)[nodes].sum(axis=0)
        np.testing.assert_allclose(b.position, first / m_fe[nodes].sum(), rtol=0,
                                   atol=1e-12)


@pytest.mark.parametrize("order,mass", [(1, "consistent"), (1, "lumped"), (2, "lumped")])
def test_a_rigid_parent_hands_off_its_rigid_motion_whole(order, mass):
    """A piece moving rigidly (no noise, no strain) keeps its velocity and spin exactly, and
    no vibrational energy is removed (the inertia is that of the analysis' mass: the exact
    one for the consistent P1 mass, the nodal point masses' for the lumped one)."""
    setup = _stages(order, mass)
    d = _on(setup, _cut_bar())
    space = d.space
    x = space.node_points
    w, c = np.array([0.3, -1.0, 2.0]), np.array([0.7, 0.2, 0.1])
    vel = np.array([0.5, 0.0, -1.0])
    n = space.n_dofs
    v = (vel + np.cross(w, x - c)).ravel()
    state = State(0.0, np.zeros(n), v, np.zeros(n), np.zeros((6,) + d.ops.weights.shape),
                  None, np.zeros(n), np.zeros(0))
    _, labels = fragments(d.mesh.tets)
    for k in range(3):
        f = hand_off(d, state, np.flatnonzero(labels == k))
        np.testing.assert_allclose(angular_velocity(f.body), w, rtol=1e-12)
        np.testing.assert_allclose(velocity(f.body), vel + np.cross(w, f.body.position - c),
                                   rtol=1e-12, atol=1e-12)
        assert abs(f.vibration_energy) < 1e-12 * kinetic_energy(f.body)
        # the drawn nodes sit where the piece is: zero displacement at hand-off
        np.testing.assert_allclose(f.displacement(), 0.0, atol=1e-12)


@pytest.mark.parametrize("order,mass", [(1, "consistent"), (2, "consistent"), (1, "lumped"),
                                        (2, "lumped")])
def test_vibration_removed_is_the_energy_of_the_motion_about_the_rigid_one(order, mass):
    """The rigid motion is the M-orthogonal projection of the velocity on the rigid fields
    (its inertia is that of the same mass M: exact tets for the consistent mass, nodal point
    masses for the lumped one), so the finite-element kinetic energy splits into the rigid
    body's and that of the velocity about the rigid motion: the removed vibrational energy
    is 1/2 (v - v_rigid)^T M (v - v_rigid), not negative (undisplaced, so the P2 tets are
    straight and their exact inertia is the consistent mass')."""
    setup = _stages(order, mass)
    d = _on(setup, _cut_bar())
    state = _moving(d, np.random.default_rng(2))
    state = State(0.0, np.zeros_like(state.u), state.v, state.a,
                  np.zeros_like(state.stress), None, state.internal_force, state.reaction)
    _, labels = fragments(d.mesh.tets)
    space = d.space
    for k in range(3):
        elements = np.flatnonzero(labels == k)
        f = hand_off(d, state, elements)
        nodes = np.unique(space.basis.element_dofs[:, elements])
        x = space.node_points[nodes]
        rigid = velocity(f.body) + np.cross(angular_velocity(f.body), x - f.body.position)
        dv = np.zeros((space.n_nodes, 3))
        dv[nodes] = state.v.reshape(-1, 3)[nodes] - rigid
        expected = 0.5 * dv.ravel() @ (d.ops.mass @ dv.ravel())
        assert f.vibration_energy >= 0
        assert f.vibration_energy == pytest.approx(expected, rel=1e-9)


def _spinning_whole_body(order: int):
    """The case's brick (lumped mass) translating and spinning about a non-principal axis
    through an off-centre point, its nodes slightly displaced (the rigid field is taken at
    the displaced positions), no stress: v = V + w x (x - c)."""
    d = _stages(order, "lumped").disc
    space = d.space
    x = space.node_points + 1e-3 * np.random.default_rng(3).normal(size=space.node_points.shape)
    w, c = np.array([0.3, -1.0, 2.0]), np.array([0.7, 0.2, 0.1])
    vel = np.array([0.5, 0.0, -1.0])
    n = space.n_dofs
    v = (vel + np.cross(w, x - c)).ravel()
    state = State(0.0, (x - space.node_points).ravel(), v, np.zeros(n),
                  np.zeros((6,) + d.ops.weights.shape), None, np.zeros(n), np.zeros(0))
    return d, state, w


@pytest.mark.parametrize("order", [1, 2])
def test_a_lumped_spinning_body_keeps_its_energy_and_momenta_at_hand_off(order):
    """The whole body spinning about a non-principal axis, lumped mass (P1: row sums, P2:
    HRZ, mid-edge nodes included): the rigid body's kinetic energy is 1/2 v^T M v, and P
    and L are the finite-element ones, to round-off; its spin is the body's."""
    d, state, w = _spinning_whole_body(order)
    assert d.ops.lumped
    f = hand_off(d, state, np.arange(d.mesh.n_tets))
    b = f.body
    x = (d.space.node_points + state.u.reshape(-1, 3))
    mv = (d.ops.mass @ state.v).reshape(-1, 3)
    fe_kinetic = 0.5 * state.v @ (d.ops.mass @ state.v)
    p, l_origin = mv.sum(axis=0), np.cross(x, mv).sum(axis=0)
    assert kinetic_energy(b) == pytest.approx(fe_kinetic, rel=1e-12)
    assert abs(f.vibration_energy) < 1e-12 * fe_kinetic
    np.testing.assert_allclose(b.momentum, p, rtol=0, atol=1e-12 * np.abs(p).max())
    np.testing.assert_allclose(b.angular_momentum + np.cross(b.position, b.momentum),
                               l_origin, rtol=0, atol=1e-12 * np.abs(l_origin).max())
    np.testing.assert_allclose(angular_velocity(b), w, rtol=1e-12)
    # the inertia is the nodal point masses' about the finite-element centre
    m = d.ops.mass.diagonal()[0::3]
    r = x - b.position
    inertia = (m * (r * r).sum(axis=1)).sum() * np.eye(3) - np.einsum("a,ai,aj->ij", m, r, r)
    assert b.mass == pytest.approx(m.sum(), rel=1e-12)
    np.testing.assert_allclose(np.sort(b.inertia), np.linalg.eigvalsh(inertia), rtol=1e-12)


@pytest.mark.parametrize("order,least", [(1, 0.03), (2, 0.007)])
def test_the_exact_inertia_with_a_lumped_mass_gains_energy(order, least):
    """What the hand-off did before: L from the lumped mass, the inertia from the tets'
    exact second moments (the consistent mass' inertia). The lumped masses sit at the
    nodes, farther out than the distributed mass, so the body spun faster than its parent
    and gained kinetic energy: on this coarse bar (two elements across) 4.1 % (P1) and
    1.0 % (P2), 6.7 % and 1.7 % faster; the vibration energy came out negative."""
    d, state, _ = _spinning_whole_body(order)
    space, mesh = d.space, d.mesh
    x = space.node_points + state.u.reshape(-1, 3)
    mv = (d.ops.mass @ state.v).reshape(-1, 3)
    mx = (d.ops.mass @ x.ravel()).reshape(-1, 3)
    exact = rigid_piece(mesh.points, mesh.tets, space.node_points, space.basis.element_dofs.T,
                        x, mv, state.v.reshape(-1, 3), d.materials.density, mx=mx)
    fe_kinetic = 0.5 * state.v @ (d.ops.mass @ state.v)
    assert kinetic_energy(exact.body) / fe_kinetic - 1 > least
    assert exact.vibration_energy < 0  # energy out of nothing
    # the same piece with its nodal masses: none gained
    lumped = rigid_piece(mesh.points, mesh.tets, space.node_points, space.basis.element_dofs.T,
                         x, mv, state.v.reshape(-1, 3), d.materials.density, mx=mx,
                         nodal_mass=d.ops.mass.diagonal()[0::3])
    assert kinetic_energy(lumped.body) == pytest.approx(fe_kinetic, rel=1e-12)
