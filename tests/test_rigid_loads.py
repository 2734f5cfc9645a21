"""Surface loads that leave with a rigid piece act on the rigid body (fem_frac.rigid.loads):
tractions keep their world direction, pressures turn with the body; the impulse is exact for
piecewise-linear curves whose breaks fall on steps."""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path

import meshio
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import fem_frac.rigid.loads as rigid_loads
import fem_frac.rigid.stage as rigid_stage
from fem_frac.rigid.body import rotation_matrix
from meshes import structured_box

CASES = Path(__file__).parent.parent / "cases"

# breaks on the steps of dt = 0.01 (and 0.005); its integral, exact: 0.09
TABLE = [[0.0, 0.0], [0.05, 1.0], [0.12, 0.4], [0.2, 0.0]]
AREA = sum((t1 - t0) * (f0 + f1) / 2 for (t0, f0), (t1, f1) in pairwise(TABLE))


def _brick(load: dict, dt: float = 0.01, mesh: dict | None = None) -> dict:
    """A free brick, rigid from the start, no gravity, ``load`` following the table."""
    return {
        "mesh": mesh or {"geometry": {"type": "box", "lengths": [0.3, 0.2, 0.1]},
                         "element_size": 0.05},
        "material": {"youngs_modulus": 1e9, "poissons_ratio": 0.3, "density": 1000.0},
        "boundary_conditions": [{**load, "curve": "c"}],
        "load_curves": {"c": {"type": "table", "points": TABLE}},
        "fragments": {"whole_body": True},
        "analysis": {"type": "dynamic", "dt": dt, "steps": round(0.2 / dt)},
    }


def _run(case: dict):
    from solve import simulate_dict

    setup, world, _ = simulate_dict(case)
    assert world.body is None and len(world.rigid) == 1
    return setup.disc.problem, world.rigid[0]


def _nodal(problem, kind: str) -> np.ndarray:
    """(n_nodes, 3) nodal forces of the load of curve ``c`` at factor 1."""
    c = problem.curve_names.index("c")
    return getattr(problem, kind)[c].reshape(-1, 3)


def _reference(f, follower: bool, forces: np.ndarray, t_end: float = 0.2):
    """``(P, L, R)`` at ``t_end`` of the rigid body of ``f`` from rest at its hand-off
    orientation under the nodal forces ``forces (k, 3)`` (world, at hand-off) times the
    table, world-fixed or ``follower``: solve_ivp (DOP853, rtol 1e-12, one segment per
    piece of the table) of dP = phi sum f_a, dL = phi sum (R b_a) x f_a, dq = (0, w) q / 2."""
    from fem_frac.rigid.body import quaternion_from_matrix

    b, inertia = f.body_coords, f.body.inertia
    curve = f.loads[0].factor
    r0 = _hand_off_rotation(f)
    body_forces = forces @ r0  # rows R0^T f_a

    def rhs(t, y):
        q = y[6:] / np.linalg.norm(y[6:])
        r = rotation_matrix(q)
        fa = body_forces @ r.T if follower else forces
        phi = float(curve(t))
        w = r @ ((r.T @ y[3:6]) / inertia)
        dq = 0.5 * _quat_mul(np.r_[0.0, w], q)
        return np.r_[phi * fa.sum(axis=0), phi * np.cross(b @ r.T, fa).sum(axis=0), dq]

    y = np.r_[np.zeros(6), quaternion_from_matrix(r0)]
    for (t0, _), (t1, _) in pairwise(TABLE):
        y = solve_ivp(rhs, (t0, min(t1, t_end)), y, method="DOP853", rtol=1e-12,
                      atol=1e-14).y[:, -1]
    return y[:3], y[3:6], rotation_matrix(y[6:] / np.linalg.norm(y[6:]))


def _quat_mul(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def _hand_off_rotation(f) -> np.ndarray:
    """The orientation at hand-off: the body coordinates are ``(x - X) R0`` of the nodes at
    rest (``nodes``, the body undeformed at t = 0), so R0 = lstsq."""
    x = f.nodes - f.nodes.mean(axis=0)
    b = f.body_coords - f.body_coords.mean(axis=0)
    r0, *_ = np.linalg.lstsq(x, b, rcond=None)
    return r0


def test_a_traction_on_an_off_centre_patch_gives_the_exact_impulse():
    """A world-fixed traction on part of the top face (a box selection) of a free brick:
    the final momentum is the time integral of the force, exactly (the trapezoidal rule on
    the piecewise-linear table), although the brick turns; the moment at any orientation is
    that of the nodal forces at their turned lever arms; L and the orientation match an
    accurate integration of the rigid-body equations to second order in dt."""
    load = {"type": "traction", "box": {"min": [0.15, 0.0, 0.1], "max": [0.3, 0.1, 0.1]},
            "traction": [1e3, 2e3, -3e3]}
    problem, f = _run(_brick(load))
    nodal = _nodal(problem, "tractions")
    force = nodal.sum(axis=0)
    (rl,) = f.loads
    assert not rl.follower and rl.curve == "c"
    np.testing.assert_allclose(rl.force, force, rtol=1e-14)
    np.testing.assert_allclose(f.body.momentum, force * AREA, rtol=1e-10)
    # the surface loads are the problem's external force on the face (no gravity here)
    np.testing.assert_allclose(nodal, problem.forces[problem.curve_names.index("c")]
                               .reshape(-1, 3), rtol=0, atol=0)
    # the moment: sum (R b_a) x f_a at the orientation it has now, and at hand-off the
    # finite-element moment about the centre
    r = rotation_matrix(f.body.orientation)
    _, moment = rl.resultant(r)
    exact = np.cross(f.body_coords @ r.T, nodal).sum(axis=0)
    np.testing.assert_allclose(moment, exact, rtol=0, atol=1e-13 * np.abs(exact).max())
    r0 = _hand_off_rotation(f)
    center = (f.nodes - f.body_coords @ r0.T).mean(axis=0)
    fe = np.cross(f.nodes - center, nodal).sum(axis=0)
    np.testing.assert_allclose(rl.resultant(r0)[1], fe, rtol=0, atol=1e-12 * np.abs(fe).max())
    # it turned (the lever arms turned with it) ...
    assert np.degrees(np.arccos((np.trace(r.T @ r0) - 1) / 2)) > 10
    # ... and L follows the rigid-body equations, to second order in dt
    _, ell, rot = _reference(f, False, nodal)
    errors = []
    for dt in (0.01, 0.005):
        _, g = _run(_brick(load, dt))
        np.testing.assert_allclose(g.body.momentum, force * AREA, rtol=1e-10)
        errors.append(np.linalg.norm(g.body.angular_momentum - ell) / np.linalg.norm(ell))
    assert errors[0] < 2e-3 and 3.0 < errors[0] / errors[1] < 5.0


def test_a_pressure_turns_with_the_body_and_gives_the_exact_angular_impulse(tmp_path):
    """A pressure (a follower load) on the half x > 0.15 of the top face of a structured
    brick: its moment about the centre is along the principal axis y, so the brick turns
    about y, the moment stays put, and the final angular momentum is the integral of the
    moment, exactly. Its force turns with the brick: the momentum is that of the turning
    force (accurate integration, second order in dt), not the world-fixed impulse."""
    box = structured_box((6, 4, 2), (0.3, 0.2, 0.1))
    meshio.write(tmp_path / "brick.vtu", meshio.Mesh(box.points, [("tetra", box.tets)]))
    mesh = {"file": str(tmp_path / "brick.vtu")}
    load = {"type": "pressure", "box": {"min": [0.15, 0.0, 0.1], "max": [0.3, 0.2, 0.1]},
            "pressure": 2e3}
    problem, f = _run(_brick(load, mesh=mesh))
    nodal = _nodal(problem, "pressures")
    force = nodal.sum(axis=0)
    np.testing.assert_allclose(force, [0, 0, -2e3 * 0.15 * 0.2], rtol=0, atol=1e-10)
    # the moment about the centre (0.15, 0.1, 0.05): (0.075, 0, 0.05) x F, about y
    moment = np.cross([0.075, 0.0, 0.05], force)
    (rl,) = f.loads
    assert rl.follower
    r = rotation_matrix(f.body.orientation)
    np.testing.assert_allclose(rl.resultant(r)[1], moment, rtol=0,
                               atol=1e-12 * np.abs(moment).max())
    np.testing.assert_allclose(f.body.angular_momentum, moment * AREA, rtol=0,
                               atol=1e-10 * np.abs(moment * AREA).max())
    # it turned about y, and its force with it
    turned = np.degrees(np.arccos((np.trace(r.T @ _hand_off_rotation(f)) - 1) / 2))
    assert turned > 10
    p, _, _ = _reference(f, True, nodal)
    assert np.linalg.norm(p - force * AREA) > 0.05 * np.linalg.norm(p)
    errors = []
    for dt in (0.01, 0.005):
        _, g = _run(_brick(load, dt, mesh))
        errors.append(np.linalg.norm(g.body.momentum - p) / np.linalg.norm(p))
        np.testing.assert_allclose(g.body.angular_momentum, moment * AREA, rtol=0,
                                   atol=1e-10 * np.abs(moment * AREA).max())
    assert errors[0] < 2e-3 and 3.0 < errors[0] / errors[1] < 5.0


def test_the_breaking_beam_gets_the_whole_pulse(monkeypatch):
    """The breaking beam: the pulse's patch leaves with the two halves at 4 ms, mid-pulse.
    All of its load goes with them, and the rigid bodies receive what the finite elements
    no longer apply: the impulse of the rest of the pulse, exactly, so the beam gets the
    whole pulse (62.5 N s; before, the 37.5 N s after the hand-off were dropped)."""
    from ruamel.yaml import YAML

    from solve import simulate_dict

    handed, kicks = [], {}
    piece_loads, kick = rigid_stage.piece_loads, rigid_loads.kick

    def recorded_piece_loads(problem, nodes, body_coords, orientation):
        c = problem.curve_names.index("pulse")
        handed.append(problem.pressures[c].reshape(-1, 3)[nodes].sum(axis=0))
        return piece_loads(problem, nodes, body_coords, orientation)

    def recorded_kick(body, loads, t, dt):
        out = kick(body, loads, t, dt)
        if loads:
            kicks.setdefault(id(loads), []).append(np.linalg.norm(out.momentum - body.momentum))
        return out

    monkeypatch.setattr(rigid_stage, "piece_loads", recorded_piece_loads)
    monkeypatch.setattr(rigid_loads, "kick", recorded_kick)
    case = YAML(typ="safe").load((CASES / "breaking_beam.yaml").read_text())
    case["analysis"]["steps"] = 10
    setup, world, _ = simulate_dict(case, CASES)
    problem = setup.disc.problem
    c = problem.curve_names.index("pulse")
    patch = problem.pressures[c].reshape(-1, 3).sum(axis=0)
    # all of the patch's load left with the pieces
    np.testing.assert_allclose(np.sum(handed, axis=0), patch, rtol=0,
                               atol=1e-12 * np.linalg.norm(patch))
    loaded = [f for f in world.rigid if f.loads]
    assert len(loaded) == 2 and all(f.born < 0.01 for f in loaded)
    curve = problem.curves[c]
    times = np.linspace(0.0, 0.02, 11)

    def integral(t0):
        t = times[times >= t0 - 1e-15]
        return np.trapezoid([curve(s) for s in t], t)

    total = 0.0
    for f in loaded:
        (rl,) = f.loads
        assert rl.follower and rl.curve == "pulse"
        magnitude = np.linalg.norm(rl.force)
        delivered = sum(kicks[id(f.loads)])
        # the rigid body: the rest of the pulse, exactly
        np.testing.assert_allclose(delivered, magnitude * integral(f.born), rtol=1e-12)
        # the finite elements: the pulse up to the hand-off
        total += magnitude * (integral(0.0) - integral(f.born)) + delivered
    whole = np.linalg.norm(patch) * integral(0.0)
    assert whole == pytest.approx(62.478, rel=1e-4)
    np.testing.assert_allclose(total, whole, rtol=1e-12)


def test_a_load_wakes_a_sleeping_body():
    """A brick resting on a frictionless ground falls asleep (20 steps at rest), then a
    horizontal traction that rises at 0.3 s wakes it and pushes it: its momentum is the
    load's impulse."""
    case = _brick({"type": "traction", "boundary": "xmin", "traction": [1e3, 0.0, 0.0]})
    case["load_curves"]["c"]["points"] = [[0.0, 0.0], [0.3, 0.0], [0.4, 1.0], [0.6, 1.0]]
    case["fragments"].update(gravity=[0.0, 0.0, -9.81],
                             ground=[{"point": [0, 0, 0], "normal": [0, 0, 1],
                                      "restitution": 0.0, "friction": 0.0}])
    case["analysis"].update(steps=30)
    asleep = _run(case)[1]
    assert asleep.resting >= rigid_stage.SLEEP_STEPS
    np.testing.assert_allclose(asleep.body.momentum, 0.0, atol=1e-12)
    case["analysis"].update(steps=60)
    problem, f = _run(case)
    force = _nodal(problem, "tractions").sum(axis=0)
    np.testing.assert_allclose(force, [1e3 * 0.02, 0, 0], rtol=1e-12)
    np.testing.assert_allclose(f.body.momentum[:2], force[:2] * 0.25, rtol=1e-10, atol=1e-12)
    assert f.resting == 0
