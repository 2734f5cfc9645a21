"""The notched beam with cohesive cracks (cases/notched_beam_cohesive.yaml, mesh study in
docs/fracture/cohesive_convergence.md).

Default size (5 mm = l_cz / 4, about 30 s): the first crack opens on the ligament plane at
the notch tip, the load peaks and softens, the energy ledger balances, no face dissipates
more than G_c, every crack face lies within one element size of the ligament plane and the
crack area stays below 1.3 ligament areas. The slow tests run the three-mesh study: the peak
load converges, the crack area stays below 1.3 ligament areas at every size. The runs stop
at 36 um, before complete failure (the docs say why); the dissipated energy at complete
failure is checked on the beam broken along its ligament (tests/test_cohesive_ligament.py).
"""

import numpy as np
import pytest
from notched_beam import ROOT, assert_peak_load_converges, run_case
from notched_beam import study_runs as run_study

CASE = ROOT / "cases" / "notched_beam_cohesive.yaml"
STUDY = ROOT / "studies" / "notched_beam_cohesive.yaml"

XM, NOTCH_TIP_Z, LIGAMENT_AREA, G_C = 0.085, 0.02, 0.02 * 0.005, 6.0


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("cohesive") / "beam"
    return (out, *run_case(CASE, out))


def test_first_crack_opens_on_the_ligament_plane_at_the_notch_tip(default_run):
    import meshio

    out, summary, history, _ = default_run
    assert summary["status"] == "completed"
    h = 0.005
    first = int(np.argmax(history["crack_faces"] > 0))
    assert first > 0
    crack = meshio.read(out / f"notched_beam_cohesive_crack_{first:06d}.vtu")
    corners = crack.points[crack.cells_dict["triangle"]]
    assert np.all(np.abs(corners[:, :, 0] - XM) < 1e-9)  # on the plane x = XM
    assert corners[:, :, 2].min() == pytest.approx(NOTCH_TIP_Z, abs=1e-9)  # from the tip
    assert corners[:, :, 2].max() <= NOTCH_TIP_Z + h + 1e-9


def test_load_peaks_and_softens(default_run):
    _, _, history, run = default_run
    load = -history["reaction_load_z"]
    peak = int(np.argmax(load))
    first_crack = int(np.argmax(history["crack_faces"] > 0))
    # elastic and linear up to the first crack (the stiffness is constant)
    elastic = slice(1, first_crack)
    stiffness = load[elastic] / run["delta"][elastic]
    np.testing.assert_allclose(stiffness, stiffness[0], rtol=1e-6)
    assert first_crack <= peak < len(load) - 1
    assert 30.0 < load[peak] < 60.0  # N; 44.0 measured
    # softening: past the peak the load falls to 0.53 of it (measured), and ends below 0.75
    # of it (0.68 measured: it climbs again as the load strip ties the halves at the top)
    assert load[peak:].min() < 0.6 * load[peak]
    assert load[-1] < 0.75 * load[peak]


def test_energy_ledger_balances(default_run):
    _, summary, history, _ = default_run
    assert np.max(history["energy_error_relative"]) < 1e-6
    # quasi-static, no plasticity: external work = strain energy + cohesive work + the
    # energy released by insertions
    np.testing.assert_allclose(
        history["external_work"],
        history["strain_energy"] + history["cohesive_work"] + history["fracture_energy"],
        rtol=1e-6, atol=1e-12)
    f = summary["fracture"]
    assert f["cohesive_dissipated"] > 0 and f["cohesive_stored"] >= 0
    # no face dissipates more than G_c per unit area
    assert np.all(history["cohesive_dissipated"] <= G_C * history["crack_area"] * (1 + 1e-9))


def test_crack_stays_within_one_element_of_the_ligament_plane(default_run):
    assert default_run[3]["max_offset"] <= 0.005


def test_crack_area_below_1_3_ligament_areas(default_run):
    assert default_run[3]["crack_area"] < 1.3


@pytest.fixture(scope="module")
def study_runs(tmp_path_factory):
    return run_study(STUDY, tmp_path_factory.mktemp("cohesive_study"))


@pytest.mark.slow
def test_study_peak_load_converges(study_runs):
    """The peak loads of l_cz/2, l_cz/4, l_cz/8 (56.7, 44.0, 37.3 N measured): differences
    shrink, observed order above 0.5 (0.94 measured; the meshes are not similar from one
    size to the next and the crack advances by whole vertex stars). All three run to the
    end; the coarsest one at least well past its peak."""
    assert [r["status"] for r in study_runs[1:]] == ["completed", "completed"]
    coarse = study_runs[0]
    assert coarse["steps"] > int(np.argmax(coarse["load"])) + 5
    assert_peak_load_converges(study_runs)


@pytest.mark.slow
def test_study_crack_area_below_1_3_ligament_areas_at_every_size(study_runs):
    """No diffuse band at any size (measured 1.14, 0.75, 0.78 ligament areas; at l_cz / 2
    before cohesive cracks started at their element's most stressed vertex: 5.8)."""
    assert all(r["crack_area"] < 1.3 for r in study_runs)


def test_states_no_tet_can_crack_skip_the_eigen_decomposition(tmp_path, monkeypatch):
    """A cohesive crack's stage decomposes every tet's smoothed stress to choose sites, but
    only on the states where an upper bound of some tet's largest principal stress reaches
    the strength: in this run on some of the states it looks for sites on, not all (the
    first steps load the beam far under its strength)."""
    import fem_frac.fracture.stage as stage
    from fem_frac.app.cli import main

    calls = {"decomposed": 0, "looked": 0}
    decompose, look = stage.principal_stress, stage.FractureStage.sites

    def principal_stress(*args, **kwargs):
        calls["decomposed"] += 1
        return decompose(*args, **kwargs)

    def sites(self, *args, **kwargs):
        calls["looked"] += 1
        return look(self, *args, **kwargs)

    monkeypatch.setattr(stage, "principal_stress", principal_stress)
    monkeypatch.setattr(stage.FractureStage, "sites", sites)
    assert main(["run", str(CASE), "-o", str(tmp_path / "beam"), "-q"]) == 0
    assert 0 < calls["decomposed"] < calls["looked"]
