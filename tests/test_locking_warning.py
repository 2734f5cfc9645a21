"""``check`` and ``run`` warn, with numbers, when the elements will be too stiff: standard
linear tets with plasticity (isochoric flow locks them), with nu >= 0.45, and with fewer
than 4 linear tets across the thinnest extent of the body; not P2, not the averaged
formulation under plastic flow or near-incompressibility, which ``check`` notes where P2
is the better buy."""

from __future__ import annotations

import copy

import pytest
from report_text import check, line, number

from fem_frac.app.cli import main
from fem_frac.app.locking import LOCKING_NU, THIN_ELEMENTS, bulk_to_shear
from solve import write_case

# a chunky block: over 5 elements across its thinnest side, so only the material can lock
BLOCK = {
    "mesh": {"geometry": {"type": "box", "lengths": [0.15, 0.1, 0.1]}, "element_size": 0.015,
             "order": 1},
    "material": {"youngs_modulus": 200e9, "poissons_ratio": 0.3},
    "plasticity": {"yield_stress": 250e6},
    "boundary_conditions": [
        {"type": "fixed", "boundary": "xmin"},
        {"type": "traction", "boundary": "xmax", "traction": [1e8, 0.0, 0.0]},
    ],
    "analysis": {"type": "quasi_static", "steps": 1},
}


def variant(**mesh) -> dict:
    case = copy.deepcopy(BLOCK)
    case["mesh"].update(mesh)
    return case


def test_check_warns_on_a_p1_plastic_case_and_not_on_a_p2_one(tmp_path, capsys):
    p1 = check(tmp_path, capsys, variant())
    warning = line(p1, "warning: linear tets (mesh.order 1, formulation standard) lock "
                       "under plastic flow")
    assert "18 %" in warning and "mesh.order: 2" in warning and "averaged" in warning
    assert "lock" not in check(tmp_path, capsys, variant(order=2))


def test_the_averaged_formulation_is_not_warned_of(tmp_path, capsys):
    assert "lock" not in check(tmp_path, capsys, variant(formulation="averaged"))


def test_check_notes_where_p2_is_the_better_buy_than_the_averaged_formulation(tmp_path,
                                                                             capsys):
    """Averaged linear tets under plastic flow or near incompressibility, static or
    implicit: a note with Hill's sphere's errors and times (docs/plasticity.md); none for
    P2, for a compressible elastic case, or for explicit dynamics (not measured)."""
    note = "note: quadratic tets are the better buy"
    plastic = line(check(tmp_path, capsys, variant(formulation="averaged")), note)
    assert "0.15 %" in plastic and "0.71 %" in plastic and "mesh.order: 2" in plastic
    assert note not in check(tmp_path, capsys, variant(order=2))
    elastic = variant(formulation="averaged")
    del elastic["plasticity"]
    assert note not in check(tmp_path, capsys, elastic)
    elastic["material"]["poissons_ratio"] = 0.49
    nearly = line(check(tmp_path, capsys, elastic), note)
    assert "0.26 %" in nearly and "7.9 %" in nearly
    explicit = variant(formulation="averaged")
    explicit["material"]["density"] = 7800.0
    explicit["analysis"] = {"type": "dynamic", "integrator": "central_difference",
                            "dt": 1e-7, "steps": 1}
    assert note not in check(tmp_path, capsys, explicit)


def test_nu_near_one_half_warns_with_the_bulk_to_shear_ratio(tmp_path, capsys):
    case = variant()
    del case["plasticity"]
    case["material"]["poissons_ratio"] = 0.3
    assert "lock" not in check(tmp_path, capsys, case)
    case["regions"] = [{"box": {"min": [0.075, 0, 0], "max": [0.15, 0.1, 0.1]},
                        "poissons_ratio": 0.49}]
    warning = line(check(tmp_path, capsys, case), "warning: linear tets (mesh.order 1, "
                   "formulation standard) lock as nu")
    assert number(warning, "nu =") == 0.49  # the largest of the regions
    # K / G = 2 (1 + nu) / (3 (1 - 2 nu)) = 2.98 / 0.06
    assert number(warning, "makes the bulk modulus") == pytest.approx(2.98 / 0.06, rel=1e-2)
    assert bulk_to_shear(LOCKING_NU) == pytest.approx(29 / 3)
    case["material"]["poissons_ratio"] = case["regions"][0]["poissons_ratio"] = 0.44
    assert "lock" not in check(tmp_path, capsys, case)


def test_a_thin_plate_of_linear_tets_warns_and_counts_the_elements_across(tmp_path, capsys):
    case = variant()
    del case["plasticity"]
    case["mesh"]["geometry"]["lengths"] = [0.15, 0.15, 0.02]
    # pulled in its plane it does not bend: no warning
    assert "warning: about" not in check(tmp_path, capsys, case)
    case["boundary_conditions"][1]["traction"] = [1e8, 0.0, 1e5]  # and across it
    warning = line(check(tmp_path, capsys, case), "warning: about")
    across = number(warning, "about")
    assert across < THIN_ELEMENTS and "extent in z (0.02 over a median element size" in warning
    # the count is the thickness over the median element size
    size = number(warning, "median element size")
    assert across == pytest.approx(0.02 / size, rel=1e-3)  # printed to 3 and 4 digits
    case["mesh"]["order"] = 2
    assert "warning: about" not in check(tmp_path, capsys, case)


def test_run_warns_on_stderr_before_stepping(tmp_path, capsys):
    path = write_case(tmp_path / "block.yaml", variant())
    assert main(["run", str(path), "-o", str(tmp_path / "out"), "-q"]) == 0
    err = capsys.readouterr().err
    assert "warning: linear tets (mesh.order 1, formulation standard) lock under plastic " \
           "flow" in err
    path = write_case(tmp_path / "block2.yaml", variant(formulation="averaged"))
    assert main(["run", str(path), "-o", str(tmp_path / "out2"), "-q"]) == 0
    assert "lock" not in capsys.readouterr().err
