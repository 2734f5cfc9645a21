"""Declared exact references: the error each run reports, and refusals of misfits."""

from __future__ import annotations

import json

import pytest

from fem_frac.app.cli import main

BAR = """\
mesh:
  geometry: {type: box, lengths: [1.0, 0.2, 0.2]}
  element_size: 0.1
material: {youngs_modulus: 200e9, poissons_ratio: 0.3}
plasticity: {yield_stress: 250e6, hardening: 1e10}
boundary_conditions:
  - {type: symmetry, boundary: xmin}
  - {type: symmetry, boundary: ymin}
  - {type: symmetry, boundary: zmin}
  - {type: displacement, boundary: xmax, x: 3.75e-3, curve: cycle}
load_curves:
  cycle: {type: table, points: [[0, 0], [1, 1], [2, -0.5]]}
analysis: {type: quasi_static, t_end: 2, steps: 8, equilibrium: {tolerance: 1e-11}}
reference: {solution: uniaxial_bar}
"""


def run(tmp_path, text: str) -> dict:
    tmp_path.mkdir(parents=True, exist_ok=True)
    case = tmp_path / "case.yaml"
    case.write_text(text)
    assert main(["run", str(case), "-o", str(tmp_path / "out"), "-q"]) == 0
    return json.loads((tmp_path / "out" / "summary.json").read_text())["reference"]


def test_uniaxial_bar_reports_the_exact_stress_to_the_equilibrium_tolerance(tmp_path):
    """A homogeneous state is exact in P1: the only error left is the residual (1e-11)."""
    ref = run(tmp_path, BAR)
    assert ref["solution"] == "uniaxial_bar" and ref["quantity"] == "axial stress"
    assert ref["exact"] < 0  # reversed past yield: compressive at the end of the cycle
    assert abs(ref["relative_error"]) < 1e-8


def test_elastic_bar_reference_is_hookes_law(tmp_path):
    """Without plasticity the exact stress is E times the final strain: -0.5 x 3.75e-3 x E."""
    ref = run(tmp_path, BAR.replace("plasticity: {yield_stress: 250e6, hardening: 1e10}\n", ""))
    assert ref["exact"] == pytest.approx(-0.5 * 3.75e-3 * 200e9, rel=1e-12)
    assert abs(ref["relative_error"]) < 1e-8


@pytest.mark.parametrize("edit,words", [
    (("reference: {solution: uniaxial_bar}", "reference: {solution: lame_sphere}"),
     "needs a hollow_sphere geometry"),
    (("  - {type: symmetry, boundary: ymin}\n", ""), "needs symmetry on 'ymin'"),
    (("reference: {solution: uniaxial_bar}", "reference: {solution: cantilever}"),
     "needs fixed on 'xmin'"),
])
def test_reference_that_does_not_fit_is_refused_before_solving(tmp_path, capsys, edit, words):
    case = tmp_path / "case.yaml"
    case.write_text(BAR.replace(*edit))
    assert main(["run", str(case), "-o", str(tmp_path / "out"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "reference.solution" in err and words in err
    assert not (tmp_path / "out").exists()


FREE = """\
mesh:
  geometry: {type: box, lengths: [1.0, 0.05, 0.05]}
  element_size: 0.05
material: {youngs_modulus: 200e9, poissons_ratio: 0.3, density: 7800}
boundary_conditions:
  - {type: fixed, boundary: xmin}
analysis:
  type: dynamic
  dt: 2.5e-6
  t_end: 1.6e-3
  output_every: 100
  initial_velocity: {uniform: [1.0, 0, 0]}
reference: {solution: free_vibration}
"""


def test_free_vibration_period_converges_to_the_bar_wave_period(tmp_path):
    """A fixed-free bar set moving along its axis rings with period 4 L / c. The 3D bar's
    own correction (lateral inertia, Rayleigh-Love) is ~5e-5 here; what is left is the
    dispersion of the discrete wave front (the reaction is a square wave in 1D theory, its
    zero crossings smeared by the mesh), which shrinks with the element size: measured
    -1.2 % at h = 0.05 and -0.27 % at h = 0.025 (P1), so halving h must at least halve it."""
    coarse = run(tmp_path / "a", FREE)
    fine = run(tmp_path / "b", FREE.replace("element_size: 0.05", "element_size: 0.025"))
    assert coarse["quantity"] == "period of the fundamental axial mode"
    assert coarse["exact"] == pytest.approx(4.0 / (200e9 / 7800) ** 0.5, rel=1e-12)
    assert abs(fine["relative_error"]) < 0.5 * abs(coarse["relative_error"])
    assert abs(fine["relative_error"]) < 0.01
