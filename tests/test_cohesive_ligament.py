"""The notched beam broken completely along its ligament (cases/notched_beam_ligament.yaml,
study in docs/fracture/cohesive_convergence.md).

Default size (5 mm = l_cz / 4, about 8 s): every crack face lies in the ligament plane
(``fracture.planes``), the beam fails completely (the load falls to zero) and the law has
then dissipated G_c over the ligament area, to round-off; the ledger balances. With the
vertex rule the points on the load line, which stays shut, never dissipate: the shortfall is
exactly their share of the faces' area. The slow test runs the three-mesh study: the peak
load converges and the dissipated energy at complete failure is G_c A within 10 % at every
size.
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


@pytest.fixture(scope="module")
def study_runs(tmp_path_factory):
    return run_study(STUDY, tmp_path_factory.mktemp("ligament_study"))


@pytest.mark.slow
def test_study_peak_load_converges(study_runs):
    """Peak loads at l_cz/2, l_cz/4, l_cz/8 (53.4, 39.3, 35.9 N measured): the differences
    shrink; observed order above 0.5 (2.02 measured; the meshes are not similar from one
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
