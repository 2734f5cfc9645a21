"""Contact between rigid bodies and the finite elements (fem_frac/rigid/deformable.py): the
detection on a known configuration, and a box dropped on a clamped beam that exchanges
momentum exactly, keeps the finite elements' ledger at its contact-free identity, never
raises the kinetic energy through an exchange and does not pass into the beam; a box
resting on the beam loads it with its weight."""

from __future__ import annotations

import csv
import textwrap

import numpy as np
import pytest

from fem_frac.app.cli import main
from fem_frac.app.driver import prepare, simulate
from fem_frac.app.overlap import TOLERANCE, run_overlaps
from fem_frac.config import load_case
from fem_frac.rigid.body import make_body, quaternion_from_matrix
from fem_frac.rigid.deformable import Elements, detect, fragment_solid
from fem_frac.rigid.fragment import RigidFragment, contact_points
from fem_frac.rigid.stage import ElementContactEvent
from fem_frac.rigid.surface import closest_on_triangles, exterior
from fem_frac.timing import StageTimer
from tests.meshes import structured_box

# --- detection -------------------------------------------------------------------------------


def _block_and_cube(depth: float, velocity=(0.0, 0.0, 0.0)):
    """A block [0, 1] x [0, 1] x [0, 0.5] of tets (nodes every 0.2 in x and y), and a cube of
    side 0.3 above its centre whose bottom face is ``depth`` below the block's top (negative:
    above it)."""
    mesh = structured_box((5, 5, 3), (1.0, 1.0, 0.5))
    n = mesh.n_points
    el = Elements(mesh.points.copy(), np.zeros((n, 3)), np.zeros((n, 3)), np.ones((n, 3)),
                  mesh.tets, exterior(mesh.tets, n, mesh.tets.T))
    corners = 0.15 * np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)],
                              dtype=float)
    cube = make_body(1.0, np.full(3, 0.015), corners, (0.5, 0.5, 0.5 + 0.15 - depth),
                     velocity=velocity)
    return el, cube


def test_a_cube_pressed_into_a_block_is_found_both_ways():
    """The four top nodes under the cube lie in it, 0.01 below its bottom face; the cube's
    four bottom corners lie in the block, 0.01 below its top face: eight contacts, gap
    -0.01, normal -z (from the cube towards the block), the corners' closest points on the
    top face by barycentric weights that sum to 1."""
    depth = 0.01
    el, cube = _block_and_cube(depth)
    c = detect(el, [cube], [0.4], np.zeros((1, 3)), 1e-3)
    assert len(c) == 8
    np.testing.assert_allclose(c.gap, -depth, rtol=1e-12)
    np.testing.assert_allclose(c.normal, np.tile([0.0, 0.0, -1.0], (8, 1)), atol=1e-12)
    np.testing.assert_allclose(c.friction, 0.4)
    nodes = c.weights[:, 0] == 1.0
    top = el.x[c.nodes[nodes, 0]]
    assert sorted(map(tuple, np.round(top[:, :2], 12))) == [(0.4, 0.4), (0.4, 0.6),
                                                           (0.6, 0.4), (0.6, 0.6)]
    np.testing.assert_allclose(top[:, 2], 0.5)
    np.testing.assert_allclose(c.weights.sum(axis=1), 1.0, rtol=1e-15)
    corners = ~nodes
    closest = np.einsum("ij,ijk->ik", c.weights[corners], el.x[c.nodes[corners]])
    np.testing.assert_allclose(closest, c.point[corners] + [0.0, 0.0, depth], atol=1e-12)
    np.testing.assert_allclose(c.point[corners][:, 2], 0.5 - depth)


def test_the_speculative_margin_takes_what_the_next_step_closes():
    """A cube 0.01 above the block: found when its fall closes the gap within the step
    (20 m/s over 1 ms), not at 5 m/s; the gap is then its height above the block."""
    dt = 1e-3
    el, cube = _block_and_cube(-0.01, velocity=(0.0, 0.0, -20.0))
    c = detect(el, [cube], [0.0], np.zeros((1, 3)), dt)
    assert len(c) == 8
    np.testing.assert_allclose(c.gap, 0.01, rtol=1e-12)
    el, cube = _block_and_cube(-0.01, velocity=(0.0, 0.0, -5.0))
    assert len(detect(el, [cube], [0.0], np.zeros((1, 3)), dt)) == 0


def test_an_l_shaped_fragment_touches_where_it_is_not_where_its_hull_is():
    """An L of unit cubes ([0, 2] x [0, 1] and [0, 1] x [1, 2], z in [0, 1]) and a cube of
    side 0.2 of finite elements at [0.95, 1.15] x [1.05, 1.25] x [0.45, 0.65]: its four
    corners at x = 0.95 lie in the L's arm, 0.05 from its face x = 1; the four at x = 1.15
    lie in the notch, inside the L's hull but 0.05 outside the L. With the fragment's own
    tets: the four in the arm, gap -0.05, normal +x, and none in the notch; the hull finds
    all eight. Moved to (0.3, -0.2, 0.1) and turned 90 degrees about z, the same."""
    grid = structured_box((2, 2, 1), (2.0, 2.0, 1.0))
    centroid = grid.points[grid.tets].mean(axis=1)
    tets = grid.tets[~((centroid[:, 0] > 1.0) & (centroid[:, 1] > 1.0))]
    coords = grid.points
    for turn, shift in ((np.eye(3), np.zeros(3)),
                        (np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]),
                         np.array([0.3, -0.2, 0.1]))):
        body = make_body(1.0, np.ones(3), contact_points(coords), shift,
                         quaternion_from_matrix(turn))
        piece = RigidFragment(body, coords, tets, coords, 0, 0.0)
        cube = structured_box((1, 1, 1), (0.2, 0.2, 0.2))
        n = cube.n_points
        x = shift + (cube.points + [0.95, 1.05, 0.45]) @ turn.T
        el = Elements(x, np.zeros((n, 3)), np.zeros((n, 3)), np.ones((n, 3)), cube.tets,
                      exterior(cube.tets, n, cube.tets.T))
        c = detect(el, [body], [0.0], np.zeros((1, 3)), 1e-3, [fragment_solid(piece)])
        assert len(c) == 4
        assert np.all(c.weights[:, 0] == 1.0)
        local = (el.x[c.nodes[:, 0]] - shift) @ turn
        np.testing.assert_allclose(local[:, 0], 0.95, atol=1e-12)
        np.testing.assert_allclose(c.gap, -0.05, rtol=1e-9)
        np.testing.assert_allclose(c.normal, np.tile(turn[:, 0], (4, 1)), atol=1e-12)
        assert len(detect(el, [body], [0.0], np.zeros((1, 3)), 1e-3)) == 8


def test_closest_points_on_triangles_in_every_region():
    """Ericson's seven regions: the corners, the edges and the face of one triangle."""
    a, b, c = np.eye(3)[0] * 0, np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    p = np.array([[-1, -1, 1], [2, -0.5, 0], [-0.5, 2, 0], [0.5, -1, 0], [-1, 0.5, 0],
                  [1, 1, 0], [0.2, 0.3, 5]], dtype=float)
    expected = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.5, 0.5, 0], [0.5, 0, 0.5],
                         [0, 0.5, 0.5], [0.5, 0.2, 0.3]])
    w = closest_on_triangles(p, *(np.tile(x, (7, 1)) for x in (a, b, c)))
    np.testing.assert_allclose(w, expected, atol=1e-15)


# --- a box dropped on a clamped beam -------------------------------------------------------

# A soft beam (0.4 x 0.05 x 0.05, 1 kg) clamped at both ends under gravity; a box of
# 0.144 kg 2 mm above its middle falling at 1 m/s; central difference (lumped mass). The
# fracture section never opens a crack (it is what lets the fragments stage run).
DROP = textwrap.dedent("""\
    mesh:
      geometry: {type: box, origin: [0, 0, 0], lengths: [0.4, 0.05, 0.05]}
      element_size: 0.025
    material: {youngs_modulus: 1.0e7, poissons_ratio: 0.3, density: 1000}
    boundary_conditions:
      - {type: fixed, boundary: xmin}
      - {type: fixed, boundary: xmax}
    body_force: {gravity: [0, 0, -9.81]}
    fracture: {tensile_strength: 1.0e12, smoothing: {length: 0.03}}
    fragments: {finite_element_contact: true}
    obstacles:
      - {type: box, center: [0.2, 0.025, 0.072], size: [0.06, 0.06, 0.04], density: 1000,
         velocity: [0, 0, -1], friction: 0.3}
    analysis: {type: dynamic, integrator: central_difference, dt: 1.0e-4, steps: 400,
               output_every: 20}
    """)


class _Watch:
    """Every step's contact event, ledger error and ``a^T M a`` over the free dofs."""

    name = "watch"

    def __init__(self):
        self.rows = []

    def __call__(self, step, world):
        d, state = world.body.disc, world.body.state
        free = d.constrained.free
        ama = float(np.sum(d.ops.mass.diagonal()[free] * state.a[free] ** 2))
        self.rows.append((step.event(ElementContactEvent), world.ledger.error, ama))
        return world, None


def test_a_box_dropped_on_a_clamped_beam_exchanges_momentum_exactly(tmp_path):
    """The box lands, presses the beam down and is thrown back up by it.

    - Every step the impulse the beam's nodes receive (their supports' share included) is
      minus the box's, to round-off.
    - The finite elements' ledger: for linear elasticity under constant loads central
      difference keeps ``1/2 v.M v + U(u) - dt^2/8 a.M a`` exactly, and an impulse changes
      only v, by the ``contact_work`` booked, so the energy error is
      ``dt^2/8 (a.M a - a0.M a0)`` at every step with contact as without: to round-off.
    - No exchange raises the kinetic energy: not that of the velocities it constrains, and
      here not the step-end kinetic energy of beam and box together.
    - ``fem-frac overlap`` of the written run stays within 1 % of the box's size."""
    path = tmp_path / "drop.yaml"
    path.write_text(DROP)
    case, _ = load_case(path)
    timer = StageTimer()
    setup = prepare(case, tmp_path, timer)
    watch = _Watch()
    world, _ = simulate(setup, timer, observers=(watch,))
    dt = setup.grid.dt
    a0 = watch.rows[0][2]
    scale = world.ledger.scale
    touching = 0
    for event, error, ama in watch.rows:
        assert abs(error - dt * dt / 8 * (ama - a0)) <= 1e-12 * scale
        if event is None or event.contacts == 0:
            continue
        touching += 1
        size = np.abs(event.on_bodies).max()
        assert np.abs(event.on_elements + event.on_bodies).max() <= 1e-14 * max(size, 1e-300)
        assert event.constrained <= 1e-15 * scale
        assert event.work + event.rigid <= 1e-15 * scale
    assert touching >= 10
    ledger = world.ledger
    assert ledger.contact_work > 0.01 and ledger.contact_dissipated > 0.0
    box = world.rigid[0].body
    assert box.momentum[2] > 0.0  # thrown back up
    out = tmp_path / "out"
    assert main(["run", str(path), "-o", str(out), "-q"]) == 0
    worst = max(run_overlaps(out), key=lambda o: o.fraction)
    assert worst.fraction <= TOLERANCE
    with open(out / "history.csv") as f:
        last = list(csv.DictReader(f))[-1]
    assert float(last["contact_work"]) == pytest.approx(ledger.contact_work, rel=1e-9)
    assert float(last["contact_dissipated"]) == pytest.approx(ledger.contact_dissipated,
                                                              rel=1e-9)


def test_a_box_resting_on_the_beam_loads_it_with_its_weight(tmp_path):
    """A 0.72 kg box set down on the beam at rest (mass-proportional damping settles the
    beam): over the last 500 steps the supports carry the weight of beam and box, 16.87 N,
    within 2 % (measured 0.3 %; the box's slow rocking on the beam is what is left)."""
    path = tmp_path / "rest.yaml"
    path.write_text(DROP.replace("center: [0.2, 0.025, 0.072]", "center: [0.2, 0.025, 0.07]")
                    .replace("density: 1000,\n     velocity: [0, 0, -1], ",
                             "density: 5000,\n     ")
                    .replace("steps: 400", "steps: 1000, rayleigh: {mass: 114}"))
    out = tmp_path / "out"
    assert main(["run", str(path), "-o", str(out), "-q"]) == 0
    with open(out / "history.csv") as f:
        rows = list(csv.DictReader(f))
    carried = np.mean([float(r["reaction_xmin_z"]) + float(r["reaction_xmax_z"])
                       for r in rows[-500:]])
    assert carried == pytest.approx((1.0 + 0.72) * 9.81, rel=0.02)
    assert max(run_overlaps(out), key=lambda o: o.fraction).fraction <= TOLERANCE


def test_contact_with_the_finite_elements_needs_the_lumped_mass(tmp_path, capsys):
    """Newmark's consistent mass is refused at analysis.mass, central difference's substeps
    at analysis.substeps, located, exit 2."""
    path = tmp_path / "drop.yaml"
    path.write_text(DROP.replace("integrator: central_difference", "integrator: newmark"))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "analysis.mass" in err[0] and "lumped" in err[0], err
    path.write_text(DROP.replace("integrator: central_difference",
                                 "integrator: central_difference, substeps: true"))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "analysis.substeps" in err[0], err
    path.write_text(DROP.replace("integrator: central_difference",
                                 "integrator: newmark, mass: lumped"))
    assert main(["check", str(path)]) == 0


def test_the_box_around_a_fragment_drops_no_contact(monkeypatch):
    """A long L-shaped fragment, moving and turning, among the nodes of a block of finite
    elements with random velocities and accelerations, in 40 random placements: the nodes
    the box of its tets drops before the exact queries (deformable._near_box) change no
    contact (its geometry only at round-off), against the queries on every node of its
    bounding sphere; and it drops most of them (those the step cannot bring to it)."""
    import fem_frac.rigid.deformable as deformable

    grid = structured_box((6, 2, 2), (3.0, 1.0, 1.0))
    centroid = grid.points[grid.tets].mean(axis=1)
    tets = grid.tets[~((centroid[:, 0] > 1.0) & (centroid[:, 1] > 0.5) & (centroid[:, 2] > 0.5))]
    coords = grid.points - grid.points.mean(axis=0)
    block = structured_box((8, 8, 8), (4.0, 4.0, 4.0))
    n = block.n_points
    rng = np.random.default_rng(7)
    kept, offered, found = [], [], 0
    box = deformable._near_box

    def counted(el, near, body, shape, radius, accel, dt):
        out = box(el, near, body, shape, radius, accel, dt)
        offered.append(near.size)
        kept.append(out.size)
        return out

    for _ in range(40):
        turn = rng.standard_normal(4)
        body = make_body(2.0, np.ones(3), contact_points(coords), rng.uniform(1.5, 2.5, 3),
                         turn / np.linalg.norm(turn), velocity=rng.normal(0, 5, 3),
                         angular_velocity=rng.normal(0, 5, 3))
        piece = RigidFragment(body, coords, tets, coords, 0, 0.0)
        el = Elements(block.points + rng.normal(0, 0.05, (n, 3)), rng.normal(0, 5, (n, 3)),
                      rng.normal(0, 50, (n, 3)), np.ones((n, 3)), block.tets,
                      exterior(block.tets, n, block.tets.T))
        args = (el, [body], [0.3], rng.normal(0, 10, (1, 3)), 0.02, [fragment_solid(piece)])
        monkeypatch.setattr(deformable, "_near_box", counted)
        with_box = detect(*args)
        monkeypatch.setattr(deformable, "_near_box", lambda el, near, *rest: near)
        every = detect(*args)
        found += len(every)
        # the same contacts; their geometry to round-off (BLAS's products of the points
        # with the 3 x 3 rotation depend on the rows around them)
        for name in ("body", "nodes", "point", "friction"):
            np.testing.assert_array_equal(getattr(with_box, name), getattr(every, name))
        for name in ("weights", "normal", "gap"):
            np.testing.assert_allclose(getattr(with_box, name), getattr(every, name),
                                       rtol=0, atol=1e-12)
    assert found > 100
    assert sum(kept) < 0.5 * sum(offered)
