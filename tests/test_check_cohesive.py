"""``fem-frac check`` with a fracture energy: the cohesive law, its length
l_cz = E G_c / sigma_t^2 beside the size of the elements where cracks can run, and the warning
when the mesh is too coarse to resolve it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from report_text import check, line, number

from fem_frac.app.cli import main
from fem_frac.config.loader import load_case
from fem_frac.fracture.stage import protected_vertices
from fem_frac.mesh.build import build_mesh
from solve import write_case

E, STRENGTH, ENERGY = 30e9, 3e6, 3.0
LCZ = E * ENERGY / STRENGTH**2  # 0.01 m


def bar(element_size: float, **fracture) -> dict:
    """A bar pulled along x, its ends protected."""
    return {
        "mesh": {"geometry": {"type": "box", "lengths": [0.04, 0.01, 0.01]},
                 "element_size": element_size},
        "material": {"youngs_modulus": E, "poissons_ratio": 0.2},
        "boundary_conditions": [
            {"type": "fixed", "boundary": "xmin"},
            {"type": "displacement", "boundary": "xmax", "x": 1e-5},
        ],
        "fracture": {"tensile_strength": STRENGTH, "smoothing": {"length": 0.006},
                     "protect": [{"boundary": "xmin"}, {"boundary": "xmax"}], **fracture},
        "analysis": {"type": "quasi_static", "steps": 1},
    }


def free_sizes(tmp_path: Path, case: dict) -> np.ndarray:
    """Mean edge length of each element with a vertex free to split, computed here."""
    loaded, source = load_case(write_case(tmp_path / "sizes.yaml", case))
    mesh = build_mesh(loaded.mesh, source.path.parent)
    free = ~protected_vertices(loaded.fracture, mesh)[mesh.tets].all(axis=1)
    x = mesh.points[mesh.tets[free]]
    pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    return np.mean([np.linalg.norm(x[:, i] - x[:, j], axis=1) for i, j in pairs], axis=0)


def test_coarse_mesh_prints_the_law_the_length_and_the_warning(tmp_path, capsys):
    case = bar(0.008, fracture_energy=ENERGY)
    out = check(tmp_path, capsys, case)
    law = line(out, "cohesive   linear law")
    assert number(law, "G_c =") == pytest.approx(ENERGY)
    assert number(law, "2 G_c / sigma_t =") == pytest.approx(2 * ENERGY / STRENGTH, rel=1e-3)
    assert "shear weight 1," in law and "initial stiffness 20 x E / h" in law
    length = line(out, "cohesive length")
    assert number(length, "l_cz = E G_c / sigma_t^2 =") == pytest.approx(LCZ, rel=1e-3)
    sizes = free_sizes(tmp_path, case)
    where = line(out, "where cracks can run")
    assert f"({len(sizes):,} elements with a vertex free to split)" in where
    assert number(where, "size median") == pytest.approx(np.median(sizes), rel=1e-3)
    assert number(where, "max") == pytest.approx(sizes.max(), rel=1e-3)
    assert np.median(sizes) > LCZ / 2
    warning = line(out, "warning: the mesh cannot resolve the cohesive zone")
    assert "peak load and the crack path will depend on the mesh" in warning
    assert number(warning, "size <=") == pytest.approx(LCZ / 2, rel=1e-3)
    assert number(warning, "better") == pytest.approx(LCZ / 4, rel=1e-3)


def test_fine_mesh_prints_no_warning(tmp_path, capsys):
    case = bar(0.0025, fracture_energy=ENERGY, cohesive={"law": "exponential",
                                                         "shear_weight": 2.0})
    out = check(tmp_path, capsys, case)
    law = line(out, "cohesive   exponential law")
    assert "critical opening lambda_0 + 6 ell =" in law and "shear weight 2," in law
    # the exponential law runs past the linear law's 2 G_c / sigma_t
    assert number(law, "6 ell =") > 2 * ENERGY / STRENGTH
    assert number(line(out, "cohesive length"), "sigma_t^2 =") == pytest.approx(LCZ, rel=1e-3)
    assert np.median(free_sizes(tmp_path, case)) <= LCZ / 2
    assert "warning" not in out
    assert "crack fronts checked against the smoothed stress" in out


def test_front_checked_against_its_own_stress(tmp_path, capsys):
    case = bar(0.0025, fracture_energy=ENERGY, cohesive={"front_stress": "element"})
    out = check(tmp_path, capsys, case)
    assert "crack fronts checked against each element's own stress" in out
    assert "each front element against its own stress" in line(out, "run   fracture")


def test_front_stress_must_be_one_of_its_kinds(tmp_path, capsys):
    case = bar(0.0025, fracture_energy=ENERGY, cohesive={"front_stress": "nodal"})
    path = write_case(tmp_path / "case.yaml", case)
    capsys.readouterr()
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "fracture.cohesive.front_stress" in err and "Traceback" not in err


def test_regions_use_each_elements_own_modulus(tmp_path, capsys):
    """The headline l_cz takes the smallest E; the warning names the soft material that the
    mesh cannot resolve, though the stiff one would pass."""
    case = bar(0.0025, fracture_energy=ENERGY)
    case["regions"] = [{"box": {"min": [0.0, 0.0, 0.0], "max": [0.02, 0.01, 0.01]},
                        "youngs_modulus": E / 4}]
    out = check(tmp_path, capsys, case)
    length = line(out, "cohesive length")
    assert number(length, "sigma_t^2 =") == pytest.approx(LCZ / 4, rel=1e-3)
    assert "smallest E of the regions" in length
    assert number(line(out, f"E {E:.4g}:"), "l_cz") == pytest.approx(LCZ, rel=1e-3)
    assert number(line(out, f"E {E / 4:.4g}:"), "l_cz") == pytest.approx(LCZ / 4, rel=1e-3)
    warning = line(out, "warning: the mesh cannot resolve")
    assert f"E {E / 4:.4g})" in warning
    assert number(warning, "size <=") == pytest.approx(LCZ / 8, rel=1e-3)


def test_without_fracture_energy_no_cohesive_lines(tmp_path, capsys):
    out = check(tmp_path, capsys, bar(0.008))
    assert "tensile strength" in out
    assert "cohesive" not in out and "l_cz" not in out and "warning" not in out


def test_everything_protected_says_no_crack_can_run(tmp_path, capsys):
    case = bar(0.008, fracture_energy=ENERGY)
    case["fracture"]["protect"] = [{"box": {"min": [-1, -1, -1], "max": [1, 1, 1]}}]
    out = check(tmp_path, capsys, case)
    assert number(line(out, "cohesive length"), "sigma_t^2 =") == pytest.approx(LCZ, rel=1e-3)
    assert "every vertex is protected: no crack can run" in out
    assert "warning" not in out


def test_an_absurd_fracture_energy_is_a_located_error(tmp_path, capsys):
    """G_c so small that the faces' least stiffness 2 sigma_t^2 / G_c overflows: one located
    line, exit 2, no traceback."""
    case = bar(0.008, fracture_energy=1e-300)
    path = write_case(tmp_path / "absurd.yaml", case)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "fracture.fracture_energy" in err and "out of range" in err
    assert "Traceback" not in err
