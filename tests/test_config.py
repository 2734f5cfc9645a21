"""Case loading: overrides, defaults, unit sanity checks."""

import pytest
from pydantic import ValidationError
from test_cli_errors import BASE

from fem_frac.app.cli import main
from fem_frac.config import load_case, schema
from fem_frac.config.loader import parse_override
from fem_frac.config.units import magnitude_warnings
from fem_frac.solve import integrators


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


def _dynamic(**kw):
    return schema.DynamicAnalysis(type="dynamic", dt=1e-3, steps=2, **kw)


def test_dynamic_defaults_resolved_by_the_schema():
    assert _dynamic().mass_kind == "consistent" and _dynamic(integrator="hht").mass_kind == (
        "consistent")
    assert _dynamic(integrator="central_difference").mass_kind == "lumped"
    assert _dynamic(mass="lumped").mass_kind == "lumped"
    newmark = _dynamic()
    assert newmark.beta is None and newmark.gamma is None  # as written: absent
    assert (newmark.newmark_beta, newmark.newmark_gamma) == (0.25, 0.5)
    given = _dynamic(beta=0.3025, gamma=0.6)
    assert (given.newmark_beta, given.newmark_gamma) == (0.3025, 0.6)
    scheme = integrators.newmark(1e-3, given.newmark_beta, given.newmark_gamma)
    assert (scheme.beta, scheme.gamma) == (0.3025, 0.6)
    assert integrators.quasi_static(1e-3).beta == newmark.newmark_beta  # one default
    with pytest.raises(ValidationError, match="beta and gamma are for newmark"):
        _dynamic(integrator="hht", beta=0.25)
    with pytest.raises(ValidationError, match="central_difference needs the lumped mass"):
        _dynamic(integrator="central_difference", mass="consistent")


def test_resolved_defaults_stay_out_of_the_dumped_case(case_file):
    case, _ = load_case(case_file, ["analysis={type: dynamic, dt: 1.0e-3, steps: 2}"])
    dumped = case.model_dump(exclude_none=True)["analysis"]
    assert not {"mass", "beta", "gamma", "mass_kind", "newmark_beta"} & set(dumped)


def test_equilibrium_is_frozen_with_the_stepper_attributes():
    eq = schema.StaticAnalysis().equilibrium
    assert (eq.method, eq.tolerance, eq.max_iterations, eq.acceleration, eq.cutbacks) == (
        "modified_newton", 1e-8, 500, "anderson", 4)
    with pytest.raises(ValidationError, match="frozen"):
        eq.tolerance = 1e-6
    assert eq.model_copy(update={"method": "newton"}).method == "newton"


def test_every_schema_name_importable_from_the_package():
    from fem_frac.config.schema import Case, Equilibrium, MeshSection  # noqa: F401

    for name in schema.__all__:
        assert getattr(schema, name) is not None, name
