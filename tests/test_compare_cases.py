"""benchmarks/compare_cases.py's comparison, on tiny output folders written here (no solver)."""

import importlib.util
import json
from pathlib import Path

import meshio
import numpy as np
import pytest

SCRIPT = Path(__file__).parent.parent / "benchmarks" / "compare_cases.py"
_spec = importlib.util.spec_from_file_location("compare_cases", SCRIPT)
compare_cases = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(compare_cases)

POINTS = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]])
TETS = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
HISTORY = {
    "step": ["0", "1"], "time": ["0", "0.5"], "strain_energy": ["0", "2.5"],
    "energy_error": ["0", "1e-14"], "reaction_xmin_x": ["0", "1000"],
    "reaction_xmin_y": ["0", "3e-9"], "residual": ["0", "1e-13"], "iterations": ["0", "2"],
    "wall_time": ["0.1", "0.2"],
}
SUMMARY = {
    "case": "cases/tiny.yaml", "python": "3.11.7", "counts": {"vertices": 5, "elements": 2},
    "strain_energy": 2.5, "reaction_force": {"xmin": [1000.0, 3e-9, 0.0]},
    "analysis": {"max_relative_residual": 1e-13}, "linear_solver": "pardiso",
    "wall_time_s": {"total": 0.3}, "fracture": {"first_crack_time": None},
    "output": {"pvd": "/somewhere/tiny.pvd"},
}


def write_case(folder: Path, scale: float = 1.0, history=None, summary=None, wall=0.3):
    """One case 'tiny' in folder: two steps, a .pvd, an empty crack file, history, summary."""
    case = folder / "tiny"
    case.mkdir(parents=True)
    entries = []
    for step in range(2):
        u = scale * step * (POINTS + 1.0) * 1e-4
        mesh = meshio.Mesh(POINTS, [("tetra", TETS)], point_data={"displacement": u},
                           cell_data={"stress": [np.full((2, 6), 1e6 * step)],
                                      "region": [np.array([1, 2], dtype=np.int32)]})
        mesh.write(case / f"tiny_{step:06d}.vtu")
        entries.append(f'<DataSet timestep="{0.5 * step}" file="tiny_{step:06d}.vtu"/>')
    # a crack that has no face yet: meshio writes it but cannot read it back
    meshio.Mesh(POINTS[:3], [("triangle", np.zeros((0, 3), dtype=int))],
                point_data={"displacement": scale * POINTS[:3]}).write(case / "crack_000000.vtu")
    (case / "tiny.pvd").write_text(
        '<?xml version="1.0"?>\n<VTKFile type="Collection"><Collection>'
        + "".join(entries) + "</Collection></VTKFile>\n")
    history = history or HISTORY
    rows = [list(history)] + [list(r) for r in zip(*history.values(), strict=True)]
    (case / "history.csv").write_text("".join(",".join(r) + "\n" for r in rows))
    summary = json.loads(json.dumps(summary or SUMMARY))
    summary["wall_time_s"]["total"] = wall
    (case / "summary.json").write_text(json.dumps(summary))
    return folder


def compare(tmp_path, capsys, *args):
    code = compare_cases.main(["compare", str(tmp_path / "ref"), str(tmp_path / "cand"), *args])
    return code, capsys.readouterr().out


def test_identical_folders_agree(tmp_path, capsys):
    write_case(tmp_path / "ref")
    write_case(tmp_path / "cand", wall=9.9)  # timing differs: not compared
    code, out = compare(tmp_path, capsys)
    assert code == 0, out
    assert "tiny: OK" in out


def test_round_off_passes_and_a_real_change_is_named(tmp_path, capsys):
    write_case(tmp_path / "ref")
    write_case(tmp_path / "cand", scale=1 + 1e-14)
    assert compare(tmp_path, capsys)[0] == 0
    write_case(tmp_path / "big", scale=1 + 1e-6)
    code = compare_cases.main(["compare", str(tmp_path / "ref"), str(tmp_path / "big")])
    out = capsys.readouterr().out
    assert code == 1
    assert "tiny_000001.vtu: point_data.displacement: max|diff|" in out
    assert "crack_000000.vtu: PointData.displacement" in out  # read without meshio
    assert "tiny_000000.vtu" not in out  # zero displacement at step 0: unchanged
    ignored = ["compare", str(tmp_path / "ref"), str(tmp_path / "big"), "--ignore", "displacement"]
    assert compare_cases.main(ignored) == 0, capsys.readouterr().out


def test_missing_and_changed_columns_are_reported(tmp_path, capsys):
    write_case(tmp_path / "ref")
    history = {k: v for k, v in HISTORY.items() if k != "residual"}
    history["iterations"] = ["0", "3"]
    write_case(tmp_path / "cand", history=history)
    code, out = compare(tmp_path, capsys)
    assert code == 1
    assert "history.csv: residual: only in REF" in out
    assert "history.csv: iterations: [0, 2] != [0, 3]" in out


@pytest.mark.parametrize(("key", "value", "message"), [
    # noise in a tiny component or a ratio, against its reaction or against 1: passes
    ("reaction_xmin_y", "3.1e-9", None),
    ("residual", "2e-13", None),
    ("energy_error", "3e-14", None),
    ("strain_energy", "2.5000001", "history.csv: strain_energy: max|diff| 1.000e-07"),
])
def test_history_scales(tmp_path, capsys, key, value, message):
    write_case(tmp_path / "ref")
    write_case(tmp_path / "cand", history={**HISTORY, key: ["0", value]})
    code, out = compare(tmp_path, capsys)
    assert (code, message is None or message in out) == (0 if message is None else 1, True), out


def test_summary_keys(tmp_path, capsys):
    write_case(tmp_path / "ref")
    summary = json.loads(json.dumps(SUMMARY))
    summary["case"] = "elsewhere/tiny.yaml"  # paths and versions: skipped
    summary["python"] = "3.13.0"
    summary["reaction_force"]["xmin"][1] = 4e-9  # against the 1000 of the same vector
    summary["counts"]["elements"] = 3
    summary["linear_solver"] = "superlu"
    summary["new_key"] = 1.0
    write_case(tmp_path / "cand", summary=summary)
    code, out = compare(tmp_path, capsys)
    assert code == 1
    mismatches = [line.strip() for line in out.splitlines() if line.startswith("    ")]
    assert mismatches == ["summary.json: counts.elements: 2 != 3",
                          "summary.json: linear_solver: 'pardiso' != 'superlu'",
                          "summary.json: new_key: only in CAND"]
    code, out = compare(tmp_path, capsys, "--ignore", "counts.elements", "--ignore",
                        "linear_solver", "--ignore", "new_key")
    assert code == 0, out


def test_missing_files_and_exit_codes(tmp_path, capsys):
    write_case(tmp_path / "ref")
    write_case(tmp_path / "cand")
    (tmp_path / "cand" / "tiny" / "tiny_000001.vtu").unlink()
    (tmp_path / "ref" / "runs.json").write_text(json.dumps({"tiny": {"exit_code": 0}}))
    (tmp_path / "cand" / "runs.json").write_text(json.dumps({"tiny": {"exit_code": 3}}))
    code, out = compare(tmp_path, capsys)
    assert code == 1
    assert "exit code 0 != 3" in out
    assert "tiny_000001.vtu: file only in REF" in out
