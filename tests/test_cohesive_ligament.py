"""The notched beam broken completely along its ligament (cases/notched_beam_ligament.yaml,
study in docs/fracture/cohesive_convergence.md).

Default size (5 mm = l_cz / 4, about 8 s): every crack face lies in the ligament plane
(``fracture.planes``), the beam fails completely (the load falls to zero) and the law has
then dissipated G_c over the ligament area, to round-off; the ledger balances. With the
vertex rule the points on the load line, which stays shut, never dissipate: the shortfall is
exactly their share of the faces' area. The elements at the front are checked against their
own stress (``cohesive.front_stress: element``), so the insertions release far less than with
the smoothed stress. The slow tests run the three-mesh study: the peak load converges, the law
has dissipated G_c A at complete failure at every size, and the external work (the work of
fracture) tends to G_c A, within 10 % at l_cz / 8.
"""

import numpy as np
import pytest
from notched_beam import ROOT, assert_peak_load_converges, run_case
from notched_beam import study_runs as run_study

CASE = ROOT / "cases" / "notched_beam_ligament.yaml"
STUDY = ROOT / "studies" / "notched_beam_ligament.yaml"

XM, TOP, LIGAMENT_AREA, G_C = 0.085, 0.04, 0.02 * 0.005, 6.0


@pytest.fixture(scope="module")
def gauss_run(tmp_path_factory):
    return run_case(CASE, tmp_path_factory.mktemp("ligament") / "beam")


def test_crack_lies_in_the_ligament_plane_and_covers_it(gauss_run):
    summary, _, run = gauss_run
    assert summary["status"] == "completed"
    assert run["max_offset"] == 0.0  # every corner on x = XM, exactly
    # the ligament is a mesh surface: its faces cover it, to round-off
    assert run["crack_area"] == pytest.approx(1.0, rel=1e-12)


def test_complete_failure_dissipates_the_fracture_energy_of_the_ligament(gauss_run):
    _, history, run = gauss_run
    assert run["peak_load"] > 0
    # the halves turn freely about their lines: no load is left
    assert abs(run["end_load"]) < 1e-9 * run["peak_load"]
    # every interface point has opened past the critical opening: G_c per unit area
    np.testing.assert_allclose(history["cohesive_dissipated"][-1], G_C * LIGAMENT_AREA,
                               rtol=1e-12)
    assert history["cohesive_stored"][-1] == pytest.approx(0.0, abs=1e-15)


def test_energy_ledger_balances(gauss_run):
    _, history, _ = gauss_run
    assert np.max(history["energy_error_relative"]) < 1e-6
    np.testing.assert_allclose(
        history["external_work"],
        history["strain_energy"] + history["cohesive_work"] + history["fracture_energy"],
        rtol=1e-6, atol=1e-12)


def test_vertex_rule_keeps_the_load_line_shut(tmp_path):
    """At their corners the faces along the load line keep a point there, held shut by the
    line: each such corner's weight (a third of its face's area) never dissipates, every
    other point does: the dissipated energy is G_c (A - sum of those weights) exactly."""
    import meshio

    _, history, run = run_case(CASE, tmp_path / "vertices", "--set",
                               "fracture.cohesive.quadrature=vertices")
    assert abs(run["end_load"]) < 1e-9 * run["peak_load"]
    steps = sorted(p for p in (tmp_path / "vertices").glob("*_crack_*.vtu"))
    crack = meshio.read(steps[-1])
    corners = crack.points[crack.cells_dict["triangle"]]
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                         corners[:, 2] - corners[:, 0]), axis=1)
    on_line = np.abs(corners[:, :, 2] - TOP) < 1e-12  # (faces, 3)
    shut = float((area / 3.0 * on_line.sum(axis=1)).sum())
    assert 0 < shut < 0.2 * LIGAMENT_AREA
    np.testing.assert_allclose(history["cohesive_dissipated"][-1],
                               G_C * (LIGAMENT_AREA - shut), rtol=1e-12)


def test_front_checked_against_its_own_stress_releases_less(gauss_run, tmp_path):
    """A front element checked against the smoothed stress, which averages in the unloaded
    wake behind the front, splits late: its faces would carry more than the law allows, and
    the excess is released at the insertion. Against its own stress it splits when that
    reaches the strength (0.30 against 1.27 G_c A released in all, measured)."""
    _, own, _ = gauss_run
    _, smoothed, run = run_case(CASE, tmp_path / "smoothed", "--set",
                                "fracture.cohesive.front_stress=smoothed")
    assert abs(run["end_load"]) < 1e-9 * run["peak_load"]
    assert own["fracture_energy"][-1] < 0.5 * smoothed["fracture_energy"][-1]
    assert own["external_work"][-1] < smoothed["external_work"][-1]


@pytest.fixture(scope="module")
def study_runs(tmp_path_factory):
    return run_study(STUDY, tmp_path_factory.mktemp("ligament_study"))


@pytest.mark.slow
def test_study_peak_load_converges(study_runs):
    """Peak loads at l_cz/2, l_cz/4, l_cz/8 (53.4, 37.6, 35.9 N measured): the differences
    shrink; observed order above 0.5 (3.14 measured; the meshes are not similar from one
    size to the next)."""
    assert all(r["status"] == "completed" for r in study_runs)
    assert_peak_load_converges(study_runs)


@pytest.mark.slow
def test_study_dissipation_at_complete_failure(study_runs):
    """At every size the load falls to nothing and the law has dissipated G_c x ligament
    area within 10 % (1.000 measured at all three), with the crack on the ligament."""
    for r in study_runs:
        assert abs(r["end_load"]) < 1e-3 * r["peak_load"]
        assert abs(r["dissipated"] - 1.0) < 0.1
        assert r["crack_area"] < 1.3


@pytest.mark.slow
def test_study_work_of_fracture_tends_to_the_fracture_energy(study_runs):
    """The external work at complete failure over G_c A (2.52, 1.22, 1.07 measured): what the
    insertions release on top of the law's G_c A shrinks with every refinement, and at
    l_cz / 8 the work is G_c A within 10 %."""
    excess = [r["work"] - r["dissipated"] for r in study_runs]
    assert all(e > -1e-6 for e in excess)  # insertions release energy, never take it
    assert excess[0] > excess[1] > excess[2]
    assert abs(study_runs[-1]["work"] - 1.0) < 0.1
