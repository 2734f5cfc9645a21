"""Every shipped case runs from the CLI and writes a series ParaView and meshio read."""

import json
from pathlib import Path

import meshio
import numpy as np
import pytest

from fem_frac.app.cli import main
from fem_frac.writers.history import read_history

CASES = sorted((Path(__file__).parent.parent / "cases").glob("*.yaml"))
STATIC = Path(__file__).parent.parent / "cases" / "cantilever.yaml"


@pytest.mark.parametrize("case", CASES, ids=[c.stem for c in CASES])
def test_case_runs_and_writes_readable_output(case, tmp_path):
    out = tmp_path / case.stem
    assert main(["run", str(case), "-o", str(out), "-q"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    text = case.read_text()
    fracture = "fracture:" in text
    # a body broken under prescribed displacements may end unstrained, a rigid one is
    assert summary["max_displacement"] > 0 and (
        summary["strain_energy"] > 0 or fracture or "whole_body: true" in text)
    assert summary["wall_time_s"]["total"] > 0
    # the process's CPU before the run (this test process's imports and earlier cases) and
    # in it
    cpu = summary["cpu_time_s"]
    assert cpu["before_run"] > 0 and cpu["run"] > 0
    pvd = out / f"{case.stem}.pvd"
    assert pvd.is_file() and (out / "case.resolved.yaml").is_file()
    view = out / f"{case.stem}_view.py"  # the ParaView script beside the series
    compile(view.read_text(), str(view), "exec")
    assert summary["status"] == "completed" and summary["output"]["view"] == str(view)
    vtu = meshio.read(out / f"{case.stem}_000000.vtu")
    assert vtu.point_data["displacement"].shape == (len(vtu.points), 3)
    assert vtu.cell_data["stress"][0].shape[1] == 6
    for name in ("von_mises", "max_principal_stress"):
        assert np.all(np.isfinite(vtu.cell_data[name][0]))
    # the resolved copy reproduces the run
    assert main(["check", str(out / "case.resolved.yaml")]) == 0
    history = read_history(out / "history.csv")
    steps = summary["analysis"]["steps"]
    assert history["step"] == list(range(steps + 1))
    last = meshio.read(out / f"{case.stem}_{summary['output']['steps'] - 1:06d}.vtu")
    if fracture and "whole_body: true" not in text:
        check_cracks_open(out, case.stem, summary, history, vtu, last)
    if "fracture_energy:" in text:  # cohesive faces dissipate, and the books say so
        assert history["cohesive_dissipated"][-1] > 0
        assert summary["fracture"]["cohesive_dissipated"] == pytest.approx(
            history["cohesive_dissipated"][-1], rel=1e-9)  # the csv keeps 10 digits
    if "fragments:" in text:
        check_rigid_fragments(case, summary, history, last)
    if "plasticity:" in text:
        assert last.cell_data["plastic_strain"][0].shape[1] == 6
        assert np.max(last.cell_data["equivalent_plastic_strain"][0]) > 0
        assert max(history["yielded_points"]) > 0
        assert summary["plastic_dissipation"] > 0
    if "type: dynamic" in text:
        assert last.point_data["velocity"].shape == (len(last.points), 3)
    # a declared reference is reported; bounds from docs/verification.md and
    # docs/plasticity.md at these element sizes (P2): cantilever 3D end effect ~1 %, Lame
    # L2 error 9e-4 at h = 0.02, Hill u_b 1.5e-3 at h = 0.136 of the inner radius
    bound = {"cantilever": 0.02, "lame_sphere": 2e-3, "hill_sphere": 5e-3}
    if "reference" in summary:
        ref = summary["reference"]
        assert abs(ref["relative_error"]) < bound[ref["solution"]]
    # implicit steps balance energy exactly up to their equilibrium residual (1e-8 per step);
    # central difference only up to the O((omega dt)^2) share of the highest modes
    explicit = "central_difference" in text
    assert max(history["energy_error_relative"]) < (1e-2 if explicit else 1e-6)
    if "fragments:" in text:  # bodies do not pass through each other (last: may xfail)
        check_no_overlap(case, out)


# Cases whose bodies still pass through each other, and why; a case that comes within the
# tolerance fails here until it is taken off the list.
OVERLAP_PENDING: dict[str, str] = {}


def check_no_overlap(case: Path, out: Path) -> None:
    """At every frame, no body lies deeper in another (or below a ground plane) than
    ``TOLERANCE`` (1 %) of the smaller one's size (fem_frac.app.overlap)."""
    from fem_frac.app.overlap import TOLERANCE, run_overlaps

    worst = max(run_overlaps(out), key=lambda o: o.fraction)
    within = worst.fraction <= TOLERANCE
    if case.stem in OVERLAP_PENDING:
        assert not within, f"{case.stem} is now within the overlap tolerance: unlist it"
        pytest.xfail(OVERLAP_PENDING[case.stem])
    assert within, (f"{worst.depth:.3g} deep between {worst.pair} at t = {worst.time:g}: "
                    f"{100 * worst.fraction:.3g} % of the smaller body's size")


def check_cracks_open(out: Path, name: str, summary: dict, history: dict, first, last) -> None:
    """A fracture case cracks, and its series shows the cracks: the last step has more
    points than the first (duplicated vertices), each copy at its original's reference
    position, and under the displacement field (Warp By Vector) the copies have moved
    apart; ``fragment_id`` labels every cell; the crack surface series is readable."""
    f = summary["fracture"]
    assert f["crack_faces"] > 0 and f["insertions"] > 0
    assert history["crack_faces"][-1] == f["crack_faces"] and history["crack_area"][-1] > 0
    assert max(history["fragments"]) == f["fragments"]
    assert len(last.points) > len(first.points)
    ids = last.cell_data["fragment_id"][0]
    if "rigid" in last.cell_data:  # deformable pieces are numbered after the rigid bodies
        ids = ids[last.cell_data["rigid"][0] == 0] - summary["fragments"]["rigid_bodies"]
    assert ids.min() == 0 and ids.max() == f["fragments"] - 1
    # group points by reference position: the copies of a split vertex
    _, group, count = np.unique(np.round(last.points, 12), axis=0, return_inverse=True,
                                return_counts=True)
    group = group.ravel()
    copies = count[group] > 1
    assert copies.any()
    u = last.point_data["displacement"]
    spread = np.zeros(len(count))
    mean = np.zeros((len(count), 3))
    np.add.at(mean, group, u)
    mean /= count[:, None]
    np.maximum.at(spread, group, np.linalg.norm(u - mean[group], axis=1))
    assert spread[count > 1].max() > 1e-6 * np.abs(u).max()
    crack_pvd = out / f"{name}_crack.pvd"
    if crack_pvd.exists():
        check_crack_series(out, name, summary)


def check_crack_series(out: Path, name: str, summary: dict) -> None:
    """The crack-face series: written at every output step, every step readable by meshio
    (a step without a face holds one vertex cell), each crack face once (its two sides
    paired) with its opening and the time it opened."""
    f = summary["fracture"]
    series = sorted(out.glob(f"{name}_crack_*.vtu"))
    assert len(series) == summary["output"]["steps"]  # written at every output step
    surfaces = [meshio.read(path) for path in series]
    assert [c.type for c in surfaces[0].cells] == ["vertex"]  # no crack at t = 0
    last = surfaces[-1]
    faces = last.cells_dict["triangle"]
    # a face whose other side left with a rigid piece counts in crack_faces (one side left)
    # but is not in the series, which pairs the two sides of each face
    pieces = [b for b in summary.get("fragments", {}).get("bodies", []) if b["born"] > 0.0]
    if pieces:
        assert 0 < len(faces) < f["crack_faces"]
    else:
        assert len(faces) == f["crack_faces"]
    opening = last.cell_data["opening"][0]
    assert opening.shape == (len(faces), 3) and np.all(np.isfinite(opening))
    np.testing.assert_allclose(last.cell_data["opening_norm"][0],
                               np.linalg.norm(opening, axis=1), rtol=1e-12)
    assert last.cell_data["opening_norm"][0].max() > 0
    when = last.cell_data["opened_time"][0]
    assert when.min() >= f["first_crack_time"] - 1e-12 * summary["analysis"]["t_end"]
    assert when.max() <= summary["analysis"]["t_end"] * (1 + 1e-12)
    steps = last.cell_data["opened_step"][0]
    if np.all(steps >= 0):  # the steps are known where the output stage records them
        np.testing.assert_allclose(when, steps * summary["analysis"]["dt"], rtol=1e-9)


def check_rigid_fragments(case: Path, summary: dict, history: dict, last) -> None:
    """Rigid bodies are in the series, flagged ``rigid`` with their own ``fragment_id``,
    and where the case has a ground none of them ends below it."""
    from ruamel.yaml import YAML

    f = summary["fragments"]
    assert f["rigid_bodies"] > 0 and history["rigid_bodies"][-1] == f["rigid_bodies"]
    rigid = last.cell_data["rigid"][0] == 1
    assert rigid.any()
    ids = last.cell_data["fragment_id"][0]
    # rigid bodies are 0 .. n - 1 in order of hand-off
    np.testing.assert_array_equal(np.unique(ids[rigid]), np.arange(f["rigid_bodies"]))
    spec = YAML(typ="safe").load(case.read_text())
    nodes = np.unique(last.cells[0].data[rigid])
    x = last.points[nodes] + last.point_data["displacement"][nodes]
    for g in spec["fragments"].get("ground", []):
        n = np.asarray(g["normal"], float) / np.linalg.norm(g["normal"])
        # the contact projection leaves at most a small slop of penetration
        assert ((x - np.asarray(g["point"], float)) @ n).min() > -1e-3


def test_beam_bent_past_yield_keeps_a_residual_deflection(tmp_path):
    """Unloaded to zero load, an elastic beam returns to zero; this one keeps a plastic set
    and the history shows the load-unload cycle: reactions back to zero."""
    case = Path(__file__).parent.parent / "cases" / "beam_yield_unload.yaml"
    out = tmp_path / "beam"
    assert main(["run", str(case), "-o", str(out), "-q"]) == 0
    h = read_history(out / "history.csv")
    peak = int(np.argmax(h["max_displacement"]))
    assert h["time"][peak] == 1.0
    assert h["max_displacement"][-1] > 0.01 * h["max_displacement"][peak]
    assert abs(h["reaction_xmin_z"][-1]) < 1e-6 * abs(h["reaction_xmin_z"][peak])
    # the unloading branch is elastic: no new yielding after the peak
    assert h["plastic_work"][-1] == pytest.approx(h["plastic_work"][peak], rel=1e-9)


def test_run_refuses_to_overwrite_without_flag(tmp_path, capsys):
    case = STATIC
    out = tmp_path / "o"
    assert main(["run", str(case), "-o", str(out), "-q"]) == 0
    first = (out / "summary.json").read_text()
    assert main(["run", str(case), "-o", str(out), "-q"]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert (out / "summary.json").read_text() == first
    assert main(["run", str(case), "-o", str(out), "-q", "--overwrite"]) == 0


def test_pvd_series_opens_in_vtk(tmp_path):
    """VTK's own reader (what ParaView uses) opens the .pvd and finds the fields."""
    pyvista = pytest.importorskip("pyvista")
    case = STATIC
    out = tmp_path / "o"
    assert main(["run", str(case), "-o", str(out), "-q"]) == 0
    reader = pyvista.get_reader(str(out / f"{case.stem}.pvd"))
    assert reader.time_values == [1.0]
    grid = reader.read()[0]
    assert "displacement" in grid.point_data and "von_mises" in grid.cell_data
    assert grid.n_cells > 0


def test_overflowing_solution_stops_with_a_diagnostic_and_writes_no_field(tmp_path, capsys):
    """E = 1e-300 makes |u| ~ 1e305: its norm and the energy overflow."""
    from test_cli_errors import BASE

    case = tmp_path / "broken.yaml"
    case.write_text(BASE.replace("youngs_modulus: 210e9", "youngs_modulus: 1e-300"))
    out = tmp_path / "out"
    assert main(["run", str(case), "-o", str(out), "-q"]) == 3
    err = capsys.readouterr().err
    assert "error:" in err and ("not finite" in err or "overflowed" in err)
    assert not list(out.glob("*.vtu"))
    summary = json.loads((out / "summary.json").read_text())  # says how far it got
    assert summary["status"] == "failed" and summary["step"] == 0
    assert "not finite" in summary["message"] or "overflowed" in summary["message"]


def test_a_run_that_overflows_mid_way_stops_at_once_and_keeps_what_it_wrote(tmp_path, capsys):
    """The load jumps to 1e306 in step 3: the step loop stops there, names step, stage and
    field, and the series written before it (steps 0-2) stays valid and finite."""
    case = tmp_path / "blow.yaml"
    case.write_text(
        "mesh: {geometry: {type: box, lengths: [1.0, 0.2, 0.2]}, element_size: 0.1}\n"
        "material: {youngs_modulus: 200e9, poissons_ratio: 0.3}\n"
        "boundary_conditions:\n"
        "  - {type: fixed, boundary: xmin}\n"
        "  - {type: traction, boundary: xmax, traction: [0, 0, -1e6], curve: blow_up}\n"
        "load_curves:\n"
        "  blow_up: {type: table, points: [[0, 0], [2, 2], [3, 1e306]]}\n"
        "analysis: {type: quasi_static, t_end: 4, steps: 4}\n"
    )
    out = tmp_path / "out"
    assert main(["run", str(case), "-o", str(out), "-q"]) == 3
    err = capsys.readouterr().err
    assert "step 3, stage loads: external force is not finite" in err
    assert "Warning" not in err
    history = read_history(out / "history.csv")
    assert history["step"] == [0, 1, 2]
    import xml.etree.ElementTree as ET

    files = [d.get("file") for d in ET.parse(out / "blow.pvd").getroot().iter("DataSet")]
    assert len(files) == 3
    for name in files:
        mesh = meshio.read(out / name)
        assert np.all(np.isfinite(mesh.point_data["displacement"]))
        assert np.all(np.isfinite(mesh.cell_data["stress"][0]))
