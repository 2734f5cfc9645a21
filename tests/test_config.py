"""Case loading: overrides, defaults, unit sanity checks."""

import pytest
from test_cli_errors import BASE

from fem_frac.app.cli import main
from fem_frac.config import load_case
from fem_frac.config.loader import parse_override
from fem_frac.config.units import magnitude_warnings


@pytest.fixture
def case_file(tmp_path):
    path = tmp_path / "case.yaml"
    path.write_text(BASE)
    return path


def test_yaml_12_reads_exponents_as_numbers(case_file):
    case, _ = load_case(case_file)
    assert case.material.youngs_modulus == 210e9
    assert case.boundary_conditions[1].traction == (0.0, 0.0, -1e5)


def test_defaults_fill_absent_sections(case_file):
    case, _ = load_case(case_file)
    assert case.analysis.type == "static" and case.analysis.linear_solver == "auto"
    assert case.body_force is None and case.output.directory is None


@pytest.mark.parametrize(
    "text,path,value",
    [
        ("material.youngs_modulus=7e10", ("material", "youngs_modulus"), 7e10),
        ("boundary_conditions[1].traction=[1, 2, 3]",
         ("boundary_conditions", 1, "traction"), [1, 2, 3]),
        ("boundary_conditions.0.type=symmetry", ("boundary_conditions", 0, "type"), "symmetry"),
    ],
)
def test_parse_override(text, path, value):
    assert parse_override(text) == (path, value)


def test_overrides_apply_to_nested_keys_and_list_items(case_file):
    case, source = load_case(
        case_file,
        ["material.poissons_ratio=0.25", "boundary_conditions[1].traction=[0, 1e3, 0]",
         "body_force.gravity=[0, 0, -9.81]"],
    )
    assert case.material.poissons_ratio == 0.25
    assert case.boundary_conditions[1].traction == (0.0, 1e3, 0.0)
    assert case.body_force.gravity == (0.0, 0.0, -9.81)
    assert ("material", "poissons_ratio") in source.overrides


def test_units_mismatch_warns_but_runs_check(case_file, capsys):
    # 210 looks like GPa in an SI case
    assert main(["check", str(case_file), "--set", "material.youngs_modulus=210"]) == 0
    err = capsys.readouterr().err
    assert "warning:" in err and "youngs_modulus" in err and "units" in err


def test_consistent_si_case_has_no_warnings(case_file):
    case, _ = load_case(case_file)
    assert magnitude_warnings(case) == []
    mm, _ = load_case(case_file, ["units=mm-N-s", "material.youngs_modulus=210e3",
                                  "material.density=7.85e-9"])
    assert magnitude_warnings(mm) == []
