"""``fem-frac plot OUT_DIR``: the figures of a small run's history are PNG files beside it,
nothing else is touched, and a directory without a history is a one-line error, exit 2."""

import sys

import pytest

from fem_frac.app.cli import main
from solve import SMALL_CASE, write_case

pytest.importorskip("matplotlib")

PNG = b"\x89PNG\r\n\x1a\n"

CASE = SMALL_CASE


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("plot")
    case = write_case(folder / "beam.yaml", CASE)
    out = folder / "out"
    assert main(["run", str(case), "-o", str(out), "-q"]) == 0
    return out


def test_plot_writes_its_figures_as_png_and_prints_their_paths(run_dir, capsys):
    (run_dir / "plot_fracture.png").write_bytes(PNG)  # from an earlier run with cracks
    (run_dir / "notes.png").write_bytes(b"mine")
    before = {p.name: p.stat().st_mtime_ns for p in run_dir.iterdir()
              if not p.name.startswith("plot_")}
    assert main(["plot", str(run_dir)]) == 0
    printed = capsys.readouterr().out.split()
    names = ["plot_energy.png", "plot_reactions.png", "plot_solver.png"]
    assert printed == [str(run_dir / n) for n in names]
    for name in names:
        data = (run_dir / name).read_bytes()
        assert data.startswith(PNG) and 5_000 < len(data) < 200_000
    # no crack in this run: no fracture figure, and the stale one is gone
    assert not (run_dir / "plot_fracture.png").exists()
    after = {p.name: p.stat().st_mtime_ns for p in run_dir.iterdir()
             if not p.name.startswith("plot_")}
    assert after == before  # history, summary, series, notes.png: untouched


def _one_error_line(capsys) -> str:
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), captured.err
    assert "Traceback" not in captured.err and captured.out == ""
    return lines[0]


def test_a_missing_directory_is_one_line_exit_2(tmp_path, capsys):
    assert main(["plot", str(tmp_path / "nowhere")]) == 2
    assert "no such directory" in _one_error_line(capsys)


def test_a_directory_without_history_is_one_line_exit_2(tmp_path, capsys):
    assert main(["plot", str(tmp_path)]) == 2
    assert "no history.csv" in _one_error_line(capsys)
    (tmp_path / "history.csv").write_text("step,time,kinetic_energy\n")
    assert main(["plot", str(tmp_path)]) == 2
    assert "no step" in _one_error_line(capsys)
    assert [p.name for p in tmp_path.iterdir()] == ["history.csv"]


def test_without_matplotlib_it_says_what_to_install(run_dir, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)  # import fails
    assert main(["plot", str(run_dir)]) == 2
    assert "pip install 'fem-frac[study]'" in _one_error_line(capsys)
