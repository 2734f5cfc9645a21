"""Bad input: one line naming file, line and key; exit code 2; no traceback."""

import textwrap

import pytest

from fem_frac.app.cli import main

BASE = textwrap.dedent(
    """\
    units: SI
    mesh:
      geometry:
        type: box
        lengths: [1.0, 0.5, 0.5]
      element_size: 0.5
      order: 1
    material:
      youngs_modulus: 210e9
      poissons_ratio: 0.3
      density: 7850
    boundary_conditions:
      - type: fixed
        boundary: xmin
      - type: traction
        boundary: xmax
        traction: [0, 0, -1e5]
    """
)


def _edit(old: str, new: str) -> str:
    assert old in BASE, old
    return BASE.replace(old, new, 1)


# (id, case text, line the message must name, key it must name, words it must contain)
BAD = [
    ("misspelt key", _edit("youngs_modulus: 210e9", "youngs_modulos: 210e9"), 9,
     "material.youngs_modulos", "did you mean 'youngs_modulus'"),
    ("wrong type", _edit("youngs_modulus: 210e9", "youngs_modulus: steel"), 9,
     "material.youngs_modulus", "must be a number"),
    ("E <= 0", _edit("youngs_modulus: 210e9", "youngs_modulus: -1"), 9,
     "material.youngs_modulus", "must be > 0"),
    ("nu = 0.5", _edit("poissons_ratio: 0.3", "poissons_ratio: 0.5"), 10,
     "material.poissons_ratio", "must be < 0.5"),
    ("nu <= -1", _edit("poissons_ratio: 0.3", "poissons_ratio: -1.2"), 10,
     "material.poissons_ratio", "must be > -1"),
    ("density <= 0", _edit("density: 7850", "density: 0"), 11,
     "material.density", "must be > 0"),
    ("element size <= 0", _edit("element_size: 0.5", "element_size: -0.1"), 6,
     "mesh.element_size", "must be > 0"),
    ("order 3", _edit("order: 1", "order: 3"), 7, "mesh.order", "must be one of 1 or 2"),
    ("missing section", BASE.replace("material:", "materials:"), 8, "materials",
     "did you mean 'material'"),
    ("unknown geometry", _edit("type: box", "type: boxx"), 3, "mesh.geometry",
     "did you mean 'box'"),
    ("unknown condition", _edit("type: traction", "type: tracton"), 15,
     "boundary_conditions[1]", "did you mean 'traction'"),
    ("short vector", _edit("traction: [0, 0, -1e5]", "traction: [0, -1e5]"), 17,
     "boundary_conditions[1].traction", "3 numbers"),
    ("duplicate key", _edit("  density: 7850", "  density: 7850\n  density: 10"),
     12, "", "duplicate"),
    ("missing mesh file", _edit(
        "  geometry:\n    type: box\n    lengths: [1.0, 0.5, 0.5]\n", "  file: nowhere.msh\n"),
     3, "mesh.file", "no such mesh file"),
    ("geometry and file", _edit("  element_size: 0.5", "  file: x.msh\n  element_size: 0.5"),
     2, "mesh", "exactly one of"),
    ("unknown boundary", _edit("boundary: xmax", "boundary: xmaks"), 16,
     "boundary_conditions[1].boundary", "did you mean 'xmax'"),
    ("empty box selection", _edit(
        "boundary: xmin", "box: {min: [5, 5, 5], max: [6, 6, 6]}"), 14,
     "boundary_conditions[0].box", "selects no boundary faces"),
    ("gravity without density",
     _edit("  density: 7850\n", "") + "body_force:\n  gravity: [0, 0, -9.81]\n",
     18, "body_force.gravity", "needs material.density"),
    ("YAML syntax", _edit("traction: [0, 0, -1e5]", "traction: [0, 0, -1e5"), 18, "", "YAML"),
    ("unknown load curve", _edit("traction: [0, 0, -1e5]", "traction: [0, 0, -1e5]\n"
                                 "    curve: pulse"), 18, "boundary_conditions[1].curve",
     "unknown load curve 'pulse'"),
    ("unknown curve type", BASE + "load_curves:\n  pulse: {type: tabel, points: [[0, 1]]}\n",
     19, "load_curves.pulse", "did you mean 'table'"),
    ("table not increasing",
     BASE + "load_curves:\n  pulse:\n    type: table\n    points: [[0, 0], [0, 1]]\n", 19,
     "load_curves.pulse", "must increase"),
    ("three of t_end dt steps", BASE + "analysis:\n  type: quasi_static\n  t_end: 1\n"
     "  dt: 0.1\n  steps: 10\n", 18, "analysis", "two of 't_end', 'dt' and 'steps'"),
    ("dynamic without times", BASE + "analysis:\n  type: dynamic\n  dt: 0.1\n", 18,
     "analysis", "two of"),
    ("HHT alpha out of range", BASE + "analysis:\n  type: dynamic\n  integrator: hht\n"
     "  alpha: -0.5\n  dt: 1e-5\n  steps: 2\n", 21, "analysis.alpha", ">= -0.333"),
    ("gamma below one half", BASE + "analysis:\n  type: dynamic\n  gamma: 0.4\n"
     "  dt: 1e-5\n  steps: 2\n", 18, "analysis", "gamma < 1/2"),
    ("explicit with consistent mass", BASE + "analysis:\n  type: dynamic\n"
     "  integrator: central_difference\n  mass: consistent\n  dt: 1e-9\n  steps: 2\n", 18,
     "analysis", "needs the lumped mass"),
    ("explicit step above the limit", BASE + "analysis:\n  type: dynamic\n"
     "  integrator: central_difference\n  dt: 1e-3\n  steps: 2\n", 21, "analysis.dt",
     "exceeds the stable step"),
    ("averaged P2", _edit("order: 1", "order: 2\n  formulation: averaged"), 2, "mesh",
     "for linear tets"),
    ("yield stress <= 0", BASE + "plasticity:\n  yield_stress: 0\n", 19,
     "plasticity.yield_stress", "must be > 0"),
    ("unknown equilibrium method", BASE + "analysis:\n  type: quasi_static\n"
     "  equilibrium: {method: newtom}\n", 20, "analysis.equilibrium.method", "newton"),
    ("dynamic without density", _edit("  density: 7850\n", "") + "analysis:\n"
     "  type: dynamic\n  dt: 1e-5\n  steps: 2\n", 8, "material.density", "needs"),
    ("a load on vertices", _edit("boundary: xmax", "vertices: {min: [1, 0, 0], max: [1, 0.5, 0]}"),
     16, "boundary_conditions[1].vertices", "unknown key"),
    ("a support on no node", _edit("boundary: xmin", "vertices: {min: [0.3, 0, 0], "
                                   "max: [0.3, 0.5, 0]}"), 14,
     "boundary_conditions[0].vertices", "holds no node"),
    ("two selections", _edit("boundary: xmin", "boundary: xmin\n    vertices: {min: [0, 0, 0], "
                             "max: [0, 0.5, 0]}"), 13, "boundary_conditions[0]",
     "exactly one of 'boundary', 'box' or 'vertices'"),
    ("crack planes with perturbation", BASE + "fracture:\n  tensile_strength: 1e6\n"
     "  smoothing: {rings: 1}\n  perturbation: {angle: 5}\n"
     "  planes: [{point: [0.5, 0, 0], normal: [1, 0, 0]}]\n", 18, "fracture",
     "give one or the other"),
    ("crack plane without normal", BASE + "fracture:\n  tensile_strength: 1e6\n"
     "  smoothing: {rings: 1}\n  planes: [{point: [0.5, 0, 0], normal: [0, 0, 0]}]\n", 21,
     "fracture.planes[0]", "non-zero"),
]


@pytest.mark.parametrize("text,line,key,words", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_input_exits_2_with_located_one_line_message(tmp_path, capsys, text, line, key, words):
    case = tmp_path / "case.yaml"
    case.write_text(text)
    assert main(["check", str(case)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "Traceback" not in "\n".join(err)
    hits = [e for e in err if f"{case}:{line}:" in e and key in e and words in e]
    assert hits, err


def test_base_case_is_valid(tmp_path, capsys):
    case = tmp_path / "case.yaml"
    case.write_text(BASE)
    assert main(["check", str(case)]) == 0
    out = capsys.readouterr().out
    assert "xmin" in out and "plan" in out


def test_bad_override_names_the_option(tmp_path, capsys):
    case = tmp_path / "case.yaml"
    case.write_text(BASE)
    assert main(["check", str(case), "--set", "material.youngs_modulus=-5"]) == 2
    err = capsys.readouterr().err
    assert "--set material.youngs_modulus=-5" in err and "must be > 0" in err


def test_missing_case_file(tmp_path, capsys):
    assert main(["check", str(tmp_path / "absent.yaml")]) == 2
    assert "absent.yaml" in capsys.readouterr().err


def _write_mesh(path, cells):
    import meshio
    import numpy as np

    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], dtype=float)
    meshio.write(path, meshio.Mesh(points, cells))


@pytest.mark.parametrize(
    "cells,words",
    [
        ([("triangle", [[0, 1, 2], [0, 1, 3]])], "no tetrahedra"),
        # the second tet is the first one reflected: mixed orientation = inverted element
        ([("tetra", [[0, 1, 2, 3], [1, 2, 3, 4], [0, 2, 1, 4]])], "inverted"),
        ([("tetra", [[0, 1, 2, 3], [0, 1, 2, 0]])], "zero-volume"),
    ],
    ids=["no tetrahedra", "inverted", "zero volume"],
)
def test_unusable_mesh_file_names_the_mesh_key(tmp_path, capsys, cells, words):
    mesh_file = tmp_path / "bad.vtu"
    _write_mesh(mesh_file, cells)
    text = BASE.replace(
        "  geometry:\n    type: box\n    lengths: [1.0, 0.5, 0.5]\n", f"  file: {mesh_file}\n"
    )
    text = text.replace("boundary: xmin", "boundary: boundary").replace("xmax", "boundary")
    case = tmp_path / "case.yaml"
    case.write_text(text)
    assert main(["check", str(case)]) == 2
    err = capsys.readouterr().err
    assert f"{case}:3:" in err and "mesh.file" in err and words in err, err
    assert "Traceback" not in err


def test_unsupported_body_is_refused_before_solving(tmp_path, capsys):
    case = tmp_path / "case.yaml"
    # symmetry on one face leaves two translations and one rotation free
    case.write_text(_edit("type: fixed", "type: symmetry"))
    assert main(["run", str(case), "-o", str(tmp_path / "out"), "-q"]) == 2
    err = capsys.readouterr().err
    assert f"{case}:12:1: boundary_conditions:" in err
    assert "translation y" in err and "rotation about x" in err


def _one_error(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    errors = [line for line in err if line.startswith("error: ")]
    assert len(errors) == 1 and "Traceback" not in "\n".join(err), err
    return errors[0]


def test_hill_reference_at_the_limit_load_is_refused_before_solving(tmp_path, capsys):
    from pathlib import Path

    shipped = Path(__file__).resolve().parents[1] / "cases" / "hollow_sphere_plastic.yaml"
    text = shipped.read_text()
    case = tmp_path / "case.yaml"
    # limit load 2 sigma_Y ln(b/a) = 2 * 250e6 * ln 2 = 346.6 MPa
    case.write_text(text.replace("pressure: 299.1e6", "pressure: 350e6"))
    line = text[: text.index("pressure: 299.1e6")].count("\n") + 1
    assert main(["check", str(case)]) == 2
    error = _one_error(capsys)
    assert f"{case}:{line}:" in error and "limit load 2 sigma_Y ln(b/a) = 3.466e+08" in error
    assert main(["run", str(shipped), "-o", str(tmp_path / "out"), "-q",
                 "--set", "boundary_conditions[3].pressure=-400e6"]) == 2
    assert "--set boundary_conditions[3].pressure=-400e6" in _one_error(capsys)
    assert not (tmp_path / "out").exists()


def test_a_numerical_failure_names_the_step_and_stage(tmp_path, capsys, monkeypatch):
    import numpy as np

    from fem_frac.errors import SolverError
    from fem_frac.world.equilibrium import EquilibriumStage

    step_of = EquilibriumStage.__call__

    def failing(self, step, world):
        if step.n == 1:
            from fem_frac.fem.tensors import principal

            principal(np.full((6, 2), np.nan))  # LAPACK does not converge
        return step_of(self, step, world)

    monkeypatch.setattr(EquilibriumStage, "__call__", failing)
    case = tmp_path / "case.yaml"
    case.write_text(BASE)
    assert main(["run", str(case), "-o", str(tmp_path / "out"), "-q"]) == 3
    error = _one_error(capsys)
    assert error.startswith(f"error: {case}: step 1, stage equilibrium: principal stresses: "
                            "Eigenvalues did not converge"), error
    assert SolverError.__name__ not in error


def test_an_unforeseen_exception_is_one_line_exit_1(tmp_path, capsys, monkeypatch):
    import fem_frac.app.report as report

    def broken(case, source):
        raise KeyError("nowhere\nat all")

    monkeypatch.setattr(report, "check_report", broken)
    case = tmp_path / "case.yaml"
    case.write_text(BASE)
    assert main(["check", str(case)]) == 1
    error = _one_error(capsys)
    assert error == (f"error: {case}: internal error (KeyError: 'nowhere\\nat all'); please "
                     "report it with the case file")


def test_an_overflow_is_a_numerical_failure(tmp_path, capsys):
    case = tmp_path / "case.yaml"
    # every value within the schema's bounds, the displacements 1e200 and their work not
    case.write_text(BASE.replace("210e9", "1e-100").replace("-1e5", "-1e100"))
    assert main(["run", str(case), "-o", str(tmp_path / "out"), "-q"]) == 3
    error = _one_error(capsys)
    assert f"{case}: step 1, stage " in error and "overflow" in error, error
