"""``fem-frac study``: grid expansion, CSV, plot, resume, failed runs, bad study files,
Richardson extrapolation."""

import csv
import json
import math
import sys
import textwrap

import numpy as np
import pytest

from fem_frac.app.cli import main
from fem_frac.app.study import convergence_rate, load_study, pareto_front, richardson, run_id

CASE = textwrap.dedent(
    """\
    mesh:
      geometry: {type: box, lengths: [1.0, 0.25, 0.25]}
      element_size: 0.25
      order: 1
    material: {youngs_modulus: 210e9, poissons_ratio: 0.3}
    boundary_conditions:
      - {type: fixed, boundary: xmin}
      - {type: traction, boundary: xmax, traction: [0, 0, -1e5]}
    reference: {solution: cantilever}
    """
)

STUDY = textwrap.dedent(
    """\
    title: tiny cantilever
    case: beam.yaml
    method: [mesh.order]
    grid:
      mesh.order: [1]
      mesh.element_size: [0.2, 0.14, 0.098]
    error: reference
    workers: 2
    """
)


def _write(tmp_path, study=STUDY, name="tiny.yaml"):
    (tmp_path / "beam.yaml").write_text(CASE)
    path = tmp_path / name
    path.write_text(study)
    return path


def _rows(path):
    with path.open() as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def done(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("study")
    path = _write(tmp)
    out = tmp / "out"
    assert main(["study", str(path), "-o", str(out), "-q"]) == 0
    return path, out


def test_csv_rows_and_columns(done):
    _, out = done
    rows = _rows(out / "study.csv")
    assert [r["mesh.element_size"] for r in rows] == ["0.2", "0.14", "0.098"]
    for col in ("run_id", "mesh.order", "method", "status", "dofs", "h", "wall_time_s",
                "time_factorize_s", "peak_mib", "quantity", "value", "error"):
        assert col in rows[0], col
    for r in rows:
        assert r["status"] == "ok" and r["method"] == "P1"
        assert float(r["wall_time_s"]) > 0 and float(r["peak_mib"]) > 10
        assert 0 < float(r["error"]) < 1
        assert (out / "runs" / r["run_id"] / "summary.json").is_file()
    dofs = [int(r["dofs"]) for r in rows]
    assert dofs == sorted(dofs)
    assert float(rows[-1]["error"]) < float(rows[0]["error"])  # refining helps
    info = json.loads((out / "study.json").read_text())
    assert info["rates"]["P1"] > 0  # P1 in bending, coarse: locked, slow
    assert info["pareto_front"]


def test_png_written(done):
    _, out = done
    png = out / "study.png"
    assert png.is_file() and png.stat().st_size > 5000
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_resume_skips_finished_runs(done, capsys):
    path, out = done
    summaries = sorted((out / "runs").glob("*/summary.json"))
    assert len(summaries) == 3
    before = {p: p.stat().st_mtime_ns for p in summaries}
    redo, stopped = summaries[1], summaries[2]
    redo.unlink()
    # a run that stopped leaves a summary saying how far it got: it is run again
    stopped.write_text(json.dumps({"status": "failed", "step": 1}))
    capsys.readouterr()
    assert main(["study", str(path), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert err.count("done earlier") == 1
    for p, t in before.items():
        if p not in (redo, stopped):
            assert p.stat().st_mtime_ns == t  # not run again
    assert redo.is_file()
    assert json.loads(stopped.read_text())["status"] == "completed"
    assert len(_rows(out / "study.csv")) == 3


def test_quantity_error_by_richardson(done):
    path, out = done  # the same runs, compared by a summary quantity: nothing is rerun
    qpath = path.with_name("q.yaml")
    qpath.write_text(path.read_text().replace("error: reference",
                                              "error: {quantity: max_displacement}"))
    assert main(["study", str(qpath), "-o", str(out), "-q"]) == 0
    rows = _rows(out / "study.csv")
    assert [r["quantity"] for r in rows] == ["max_displacement"] * 3
    ex = json.loads((out / "study.json").read_text())["extrapolation"]["P1"]
    assert ex["method"] in ("richardson", "finest"), ex
    if ex["method"] == "richardson":
        assert abs(ex["ratio"] - 0.2 / 0.14) < 1e-9 and ex["order"] > 0
    for r in rows:
        assert float(r["reference_value"]) == pytest.approx(ex["value"], rel=1e-9)
        v = float(r["value"])
        assert float(r["error"]) == pytest.approx(abs(v - ex["value"]) / abs(ex["value"]),
                                                  rel=1e-6, abs=1e-8)


def test_without_matplotlib(done, monkeypatch, capsys):
    path, out = done
    (out / "study.png").unlink()
    (out / "study.csv").unlink()
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib -> ImportError
    assert main(["study", str(path), "-o", str(out), "-q"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pip install 'fem-frac[study]'" in err[0], err
    assert (out / "study.csv").is_file() and not (out / "study.png").exists()
    monkeypatch.undo()
    assert main(["study", str(path), "-o", str(out), "-q"]) == 0  # leave the plot for others
    assert (out / "study.png").is_file()


def test_failed_run_recorded(tmp_path, capsys):
    study = STUDY.replace("mesh.element_size: [0.2, 0.14, 0.098]",
                          "mesh.element_size: [0.25]\n  material.poissons_ratio: [0.3, 0.7]")
    path = _write(tmp_path, study)
    assert main(["study", str(path), "-o", str(tmp_path / "out"), "--workers", "2"]) == 1
    assert "FAILED (exit 2)" in capsys.readouterr().err
    rows = _rows(tmp_path / "out" / "study.csv")
    assert [r["status"] for r in rows] == ["ok", "failed"]
    assert rows[1]["exit_code"] == "2"
    assert "poissons_ratio" in rows[1]["message"] and "0.5" in rows[1]["message"]
    assert rows[1]["error"] == ""


def test_a_study_with_failing_runs_exits_non_zero(tmp_path, capsys):
    """A run that stops with exit 3 (E = 1e-300: its matrix cannot be factorized) fails the
    study (exit 1, the run named on stderr even with -q); run again into the same
    directory, the failed run (its summary marked failed) is run again and reported, the
    completed one kept, and nothing reads the short summary as a completed one."""
    study = STUDY.replace("mesh.element_size: [0.2, 0.14, 0.098]",
                          "mesh.element_size: [0.25]\n  material.youngs_modulus: [210e9, 1e-300]")
    path = _write(tmp_path, study)
    out = tmp_path / "out"
    for _attempt in range(2):  # the second time into the same directory
        assert main(["study", str(path), "-o", str(out), "-q"]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        bad = [r for r in _rows(out / "study.csv") if r["status"] == "failed"]
        assert len(bad) == 1 and bad[0]["exit_code"] == "3", bad
        run = out / "runs" / bad[0]["run_id"]
        assert err == [f"error: run {bad[0]['run_id']} failed (exit 3, stopped after step 0 "
                       f"of 1): {bad[0]['message']}"], err
        assert json.loads((run / "summary.json").read_text())["status"] == "failed"
        assert bad[0]["last_step"] == "0" and float(bad[0]["wall_time_s"]) > 0
        assert (run / "case.resolved.yaml").is_file()
    info = json.loads((out / "study.json").read_text())
    assert info["failed"] == [bad[0]["run_id"]] and info["runs"] == 2


@pytest.mark.parametrize(
    "old, new, line, words",
    [
        ("grid:", "gird:", 4, "gird: unknown key (did you mean 'grid'?)"),
        ("workers: 2", "workers: 0", 8, "workers: must be > 0"),
        ("method: [mesh.order]", "method: [mesh.ordr]", 3, "method[0]: 'mesh.ordr' is not a "
         "key of grid"),
        ("error: reference", "error: exact", 7, "error: must be 'reference'"),
        ("error: reference", "error: {quantty: max_displacement}", 7,
         "error.quantty: unknown key (did you mean 'quantity'?)"),
        ("case: beam.yaml", "case: nothere.yaml", 2, "case: no such case file"),
        ("  mesh.order: [1]", "  mesh.order: []", 5, "grid.mesh.order: must list at least"),
    ],
)
def test_bad_study_file(tmp_path, capsys, old, new, line, words):
    assert old in STUDY
    path = _write(tmp_path, STUDY.replace(old, new))
    assert main(["study", str(path), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert all(e.startswith(f"error: {path}:") for e in err), err  # one located line each
    assert any(e.startswith(f"error: {path}:{line}:") and words in e for e in err), err
    assert "Traceback" not in "".join(err)
    assert not (tmp_path / "out").exists()


def test_no_reference_needs_quantity(tmp_path, capsys):
    path = _write(tmp_path)
    (tmp_path / "beam.yaml").write_text(CASE.replace("reference: {solution: cantilever}\n", ""))
    assert main(["study", str(path)]) == 2
    assert "declares no reference" in capsys.readouterr().err


def test_grid_expansion_and_ids(tmp_path):
    study = STUDY.replace("  mesh.order: [1]\n", '  "mesh.order,mesh.formulation": '
                          "[[1, standard], [1, averaged], [2, standard]]\n")
    s = load_study(_write(tmp_path, study.replace("method: [mesh.order]",
                                                  "method: [\"mesh.order,mesh.formulation\"]")))
    assert len(s.runs) == 9
    assert s.runs[3].settings == {"mesh.order": 1, "mesh.formulation": "averaged",
                                  "mesh.element_size": 0.2}
    assert s.runs[3].overrides == ('mesh.order=1', 'mesh.formulation="averaged"',
                                   "mesh.element_size=0.2")
    assert s.runs[3].method == "P1, formulation=averaged"
    assert len({r.run_id for r in s.runs}) == 9
    assert run_id({"a.b": 1, "c": 0.5}) == run_id({"a.b": 1, "c": 0.5}) == "a.b=1_c=0.5"
    odd = run_id({"boundary_conditions[1].pressure": 2e6})
    assert "/" not in odd and "[" not in odd and odd != run_id({"x": 2e6})


@pytest.mark.parametrize("r, p", [(2.0, 2.0), (1.5, 3.0), (np.sqrt(2), 1.0)])
def test_richardson_exact_on_power_law(r, p):
    q_star, c = 0.123456, -3.7
    h = 0.2 / r ** np.arange(4)
    q = q_star + c * h**p
    ex = richardson(h[::-1], q[::-1])  # any order of runs
    assert ex.method == "richardson"
    assert abs(ex.value - q_star) <= 1e-10 * abs(q_star)
    assert abs(ex.order - p) <= 1e-10
    assert abs(ex.ratio - r) <= 1e-12 * r


def test_richardson_falls_back_to_finest():
    h = np.array([0.4, 0.3, 0.1])  # ratios 1.33, 3
    q = 1.0 + h**2
    ex = richardson(h, q)
    assert ex.method == "finest" and ex.value == q[-1] and "ratio" in ex.note
    ex = richardson([0.4, 0.2, 0.1], [1.0, 2.0, 1.5])  # oscillating
    assert ex.method == "finest" and ex.value == 1.5
    assert richardson([0.2, 0.1], [1.0, 1.1]).method == "finest"


def test_rate_and_pareto():
    h = np.array([0.1, 0.05, 0.025])
    assert math.isclose(convergence_rate(h, 3 * h**2), 2.0)
    assert convergence_rate([0.1], [1.0]) is None

    class R:
        def __init__(self, t, e):
            self.wall_s, self.error, self.ok = t, e, True

    runs = [R(1, 0.1), R(2, 0.2), R(3, 0.01), R(0.5, 0.5), R(4, 0.01)]
    assert [(r.wall_s, r.error) for r in pareto_front(runs)] == [(0.5, 0.5), (1, 0.1),
                                                                  (3, 0.01)]


def test_refinement_key_sets_the_size_of_a_time_step_study(tmp_path):
    """With ``refinement: analysis.dt`` the runs' size h is their time step."""
    from pathlib import Path

    study_file = tmp_path / "dt.yaml"
    case = Path(__file__).parent.parent / "cases" / "vibrating_beam.yaml"
    study_file.write_text(
        f"case: {case}\n"
        "grid:\n  analysis.dt: [1.0e-4, 5.0e-5]\n"
        "error: {quantity: max_displacement}\n"
        "refinement: analysis.dt\n"
    )
    study = load_study(study_file)
    assert [r.size for r in study.runs] == [1.0e-4, 5.0e-5]


def test_runs_side_by_side_share_the_cores_out(tmp_path, monkeypatch):
    """Each run of a study gets OMP_NUM_THREADS = cores // workers (at least 1: PARDISO's
    and the element-wise work's threads), unless the environment sets it."""
    from fem_frac.app.study import runs

    seen = []

    def start(self, argv, env):
        seen.append(env.get("OMP_NUM_THREADS"))
        return None  # not run

    monkeypatch.setattr(runs._Children, "start", start)
    monkeypatch.setattr(runs, "cores", lambda: 8)
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    assert [runs.run_threads(w) for w in (1, 2, 3, 8, 16)] == [8, 4, 2, 1, 1]
    for threads in (None, 4, 1):
        runs.execute("case.yaml", str(tmp_path / "r"), (), threads=threads)
    assert seen == [None, "4", "1"]
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    runs.execute("case.yaml", str(tmp_path / "r"), (), threads=1)
    assert seen[-1] == "3"
    # the study's runs, three at a time on the 8 cores: 2 threads each
    given = []
    monkeypatch.setattr(runs, "execute", lambda *args: given.append(args[4]) or
                        {"exit_code": None, "message": "not run"})
    study = type("S", (), {"case_path": tmp_path / "case.yaml"})()
    todo = [runs.Run(i, f"r{i}", {}, (), "") for i in range(4)]
    assert len(list(runs._run_all(study, todo, tmp_path, 3))) == 4
    assert given == [2, 2, 2, 2]
