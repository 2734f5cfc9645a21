"""Rigid fragments through the solver: the breaking beam and the spinning brick."""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest

from fem_frac.app.cli import main
from fem_frac.writers.history import read_history

CASES = Path(__file__).parent.parent / "cases"


def _frames(out: Path, name: str):
    for vtu in sorted(out.glob(f"{name}_[0-9]*.vtu")):
        m = meshio.read(vtu)
        yield m, m.points + m.point_data["displacement"]


@pytest.fixture(scope="module")
def beam(tmp_path_factory):
    out = tmp_path_factory.mktemp("beam")
    assert main(["run", str(CASES / "breaking_beam.yaml"), "-o", str(out), "-q"]) == 0
    return out


def test_beam_fragments_fall_bounce_and_rest_on_the_ground(beam):
    """The pieces that break free fall, touch the ground (z = -0.5) and come to rest: no
    rigid point ends below the ground by more than the contact's slop, every fallen piece
    ends on it or on another fallen piece (the small piece cut off a stub leans on a half's
    end: the pieces touch each other), and the rigid bodies end (nearly) at rest."""
    h = read_history(beam / "history.csv")
    assert h["rigid_bodies"][-1] >= 2
    frames = list(_frames(beam, "breaking_beam"))
    lowest = []
    for m, x in frames:
        rigid = m.cell_data["rigid"][0] == 1
        nodes = np.unique(m.cells[0].data[rigid]) if rigid.any() else np.zeros(0, int)
        lowest.append(x[nodes, 2].min() if nodes.size else np.nan)
    lowest = np.array(lowest)
    assert np.nanmin(lowest) > -0.5 - 1e-3
    # they fell from the beam (z >= 0) all the way to the ground
    m, x = frames[-1]
    rigid = m.cell_data["rigid"][0] == 1
    ids = m.cell_data["fragment_id"][0]
    boxes = {}
    for k in np.unique(ids[rigid]):
        nodes = np.unique(m.cells[0].data[rigid & (ids == k)])
        boxes[k] = (x[nodes].min(axis=0), x[nodes].max(axis=0))
    on_ground = {k for k, (lo, _) in boxes.items() if abs(lo[2] + 0.5) < 1e-3}
    assert len(on_ground) >= 2
    for k in set(boxes) - on_ground:
        lo, hi = boxes[k]
        assert any(np.all(lo <= boxes[j][1] + 1e-3) and np.all(boxes[j][0] <= hi + 1e-3)
                   for j in on_ground), f"piece {k} rests on nothing: {lo}, {hi}"
    # at rest: the rigid kinetic energy at the end is a tiny part of its peak
    kinetic = np.array(h["rigid_kinetic_energy"])
    assert kinetic[-1] < 1e-3 * kinetic.max()
    # and in the last frames they no longer move
    np.testing.assert_allclose(frames[-1][1], frames[-2][1], atol=1e-4)


def test_beam_energy_ledger_balances_through_hand_offs(beam):
    """The finite-element ledger books what the pieces take along (handed_off) and stays
    balanced to the equilibrium tolerance (Newmark), insertions and hand-offs included."""
    h = read_history(beam / "history.csv")
    assert max(h["handed_off"]) > 0
    assert max(h["energy_error_relative"]) < 1e-9
    # the vibration removed at hand-off is a small part of what the pieces carried
    assert 0 <= h["vibration_energy_removed"][-1] < h["handed_off_energy"][-1]


def test_spinning_brick_flips_and_keeps_its_angular_momentum(tmp_path):
    """Spun about its intermediate axis, the brick flips (its y axis turns over) and keeps
    its kinetic energy within the splitting integrator's bounded error, below
    (|omega| dt)^2 / 12 = 7.5e-5 (|L| is kept to round-off: tests/test_rigid_motion.py)."""
    out = tmp_path / "spin"
    assert main(["run", str(CASES / "spinning_body.yaml"), "-o", str(out), "-q"]) == 0
    frames = list(_frames(out, "spinning_body"))
    ref = frames[0][0].points
    top, bottom = np.argmax(ref[:, 1]), np.argmin(ref[:, 1])
    axis = np.array([(x[top] - x[bottom]) / np.linalg.norm(x[top] - x[bottom])
                     for _, x in frames])
    assert axis[0, 1] > 0.999 and axis[:, 1].min() < -0.99  # turned over
    h = read_history(out / "history.csv")
    k = np.array(h["rigid_kinetic_energy"])
    assert np.abs(k / k[0] - 1).max() < (6.0 * 0.005) ** 2 / 12


@pytest.mark.parametrize("order", [1, 2])
def test_a_lumped_whole_body_keeps_its_energy_at_hand_off(order):
    """The spinning brick with central differences (lumped mass; P2: HRZ): the rigid body
    gets the finite-element kinetic energy it was handed (its inertia is that of the nodal
    point masses, the mass L is taken from), so no vibration energy is removed, and its L is
    the finite-element one. With the tets' exact inertia the P1 brick gained 9.1 % (the P2
    one 2.4 %) at hand-off and spun faster than its parent."""
    from ruamel.yaml import YAML

    from fem_frac.rigid.body import kinetic_energy
    from solve import simulate_dict

    case = YAML(typ="safe").load((CASES / "spinning_body.yaml").read_text())
    case["mesh"]["order"] = order
    case["analysis"].update(integrator="central_difference", substeps=True, steps=40)
    setup, world, _ = simulate_dict(case, CASES)
    ledger, body = world.ledger, world.rigid[0].body
    assert world.body is None and setup.disc.ops.lumped
    assert ledger.handed_off > 0 and abs(ledger.vibration_removed) < 1e-12 * ledger.handed_off
    # the finite-element L of the initial spin w x x about the (lumped) centre
    m = setup.disc.ops.mass.diagonal()[0::3]
    x = setup.disc.space.node_points
    mv = m[:, None] * np.cross(case["analysis"]["initial_velocity"]["angular_velocity"], x)
    center = (m[:, None] * x).sum(axis=0) / m.sum()
    angular = np.cross(x - center, mv).sum(axis=0)
    np.testing.assert_allclose(body.angular_momentum, angular, rtol=0,
                               atol=1e-12 * np.abs(angular).max())
    # and keeps its energy as it spins (the splitting's bounded error)
    assert abs(kinetic_energy(body) / ledger.handed_off - 1) < (6.0 * 0.005) ** 2 / 12


@pytest.mark.parametrize("rule,expect", [
    ({"become_rigid": "all"}, "some"),
    ({"become_rigid": "never"}, "none"),
    ({"become_rigid": "small", "max_volume": 1e-6}, "none"),  # every piece is larger
    ({"become_rigid": "small", "max_volume": 1.0}, "some"),
    ({"become_rigid": "settled", "vibration_tolerance": 1e-12}, "none"),  # still ringing
    ({"become_rigid": "settled", "vibration_tolerance": 1e6}, "some"),
])
def test_which_free_pieces_become_rigid(rule, expect):
    """The first 10 steps of the breaking beam (it breaks in steps 1-4) under each rule."""
    from ruamel.yaml import YAML

    from solve import simulate_dict

    case = YAML(typ="safe").load((CASES / "breaking_beam.yaml").read_text())
    case["fragments"] = {**rule, "ground": case["fragments"]["ground"]}
    case["analysis"]["steps"] = 10
    _, world, _ = simulate_dict(case, CASES)
    ledger = world.ledger
    assert (len(world.rigid) > 0) == (expect == "some")
    # the beam broke either way; pieces left deformable stay in the finite elements
    assert world.body.crack.faces > 0
    if expect == "none":
        assert world.body.n_pieces > 1 and ledger.handed_off == 0.0


@pytest.mark.parametrize("edit,key,message", [
    (lambda c: c["analysis"].update(type="quasi_static", integrator=None), "fragments",
     "fragments need a dynamic analysis"),
    (lambda c: c["fragments"].update(become_rigid="small"), "fragments",
     "become_rigid 'small' goes with max_volume"),
    (lambda c: c["fragments"].update(whole_body=True), "fragments.whole_body",
     "whole_body makes the body rigid"),
    (lambda c: c["fragments"]["ground"][0].update(restitution=1.5),
     "fragments.ground[0].restitution", "must be <= 1"),
])
def test_bad_fragments_sections_are_located(tmp_path, capsys, edit, key, message):
    from ruamel.yaml import YAML

    from solve import write_case

    case = YAML(typ="safe").load((CASES / "breaking_beam.yaml").read_text())
    edit(case)
    case["analysis"] = {k: v for k, v in case["analysis"].items() if v is not None}
    if case["analysis"]["type"] == "quasi_static":
        case["analysis"] = {"type": "quasi_static", "steps": 2}
    path = write_case(tmp_path / "bad.yaml", case)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: {path}:") and f": {key}:" in err and message in err, err
    assert len(err.splitlines()) == 1


def test_a_body_free_of_supports_goes_rigid_and_flies_on(tmp_path):
    """With no support at all the whole body is a free piece after the first step: it is
    handed off, no finite element is left, and the rest of the run moves the rigid body
    alone, on the exact parabola from its hand-off state."""
    import json

    from solve import write_case

    case = {
        "mesh": {"geometry": {"type": "box", "lengths": [0.2, 0.1, 0.1]}, "element_size": 0.05},
        "material": {"youngs_modulus": 1e9, "poissons_ratio": 0.3, "density": 1000.0},
        "body_force": {"gravity": [0.0, 0.0, -9.81]},
        "fracture": {"tensile_strength": 1e12, "smoothing": {"rings": 1}},
        "fragments": {},
        "analysis": {"type": "dynamic", "dt": 0.01, "steps": 20,
                     "initial_velocity": {"uniform": [1.0, 0.0, 2.0]}},
    }
    path = write_case(tmp_path / "free.yaml", case)
    out = tmp_path / "out"
    assert main(["run", str(path), "-o", str(out), "-q"]) == 0
    s = json.loads((out / "summary.json").read_text())
    f = s["fragments"]
    assert f["rigid_bodies"] == 1 and not f["finite_elements_left"]
    body = f["bodies"][0]
    born = body["born"]
    assert born == pytest.approx(0.01)
    h = read_history(out / "history.csv")
    assert h["step"] == list(range(21))
    # momentum at the end: m (v0 + g t); the hand-off kept the FE momentum of step 1
    m, t = body["mass"], 0.2
    np.testing.assert_allclose(body["momentum"], m * np.array([1.0, 0.0, 2.0 - 9.81 * t]),
                               rtol=0, atol=1e-9 * m)
    assert max(h["energy_error_relative"]) < 1e-9
