"""Case loading: overrides, defaults, unit sanity checks."""

import pytest
from pydantic import ValidationError
from test_cli_errors import BASE

from fem_frac.app.cli import main
from fem_frac.config import load_case, schema
from fem_frac.config.loader import parse_override
from fem_frac.config.units import magnitude_warnings
from fem_frac.errors import CaseError
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


# --- hostile input: strict values, --set, one error per misspelt key ------------------------


def _first_error(case_file, capsys, *args) -> str:
    assert main(["check", str(case_file), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    errors = [line for line in err if line.startswith("error: ")]
    assert len(errors) == 1 and "Traceback" not in "\n".join(err), err
    return errors[0]


@pytest.mark.parametrize(
    "old,new,line,words",
    [
        ("youngs_modulus: 210e9", "youngs_modulus: '210e9'", 9, "must be a number"),
        ("youngs_modulus: 210e9", "youngs_modulus: .inf", 9, "must be a finite number"),
        ("youngs_modulus: 210e9", "youngs_modulus: 1e400", 9, "must be a finite number"),
        ("youngs_modulus: 210e9", "youngs_modulus: true", 9, "must be a number, got true"),
        ("element_size: 0.5", "element_size: .nan", 6, "must be a finite number"),
        ("traction: [0, 0, -1e5]", "traction: [0, .nan, -1e5]", 17, "finite"),
        ("order: 1", "order: true", 7, "must be a number, got true"),
        ("units: SI", "units: 2001-01-01", 1, "a date"),
        ("density: 7850", "density: 7850\n  poissons_ratio: 0.3", 12, "duplicate"),
    ],
)
def test_strict_values_are_refused_at_their_line(tmp_path, capsys, old, new, line, words):
    case = tmp_path / "case.yaml"
    case.write_text(BASE.replace(old, new, 1))
    error = _first_error(case, capsys)
    assert f"{case}:{line}:" in error and words in error, error


@pytest.mark.parametrize(
    "override,words",
    [
        ("fragments.whole_body=yes", "must be true or false, got 'yes'"),
        ("fragments.whole_body=maybe", "must be true or false"),
        ("analysis={type: quasi_static, steps: 2.5}", "must be a whole number"),
        ("fracture={tensile_strength: 1, smoothing: {rings: 1}, perturbation: "
         "{angle: 5, seed: -1}}", "must be >= 0"),
        ("title=!!binary aGk=", "binary data"),
        ("material=&a [*a]", "refers to itself"),
    ],
)
def test_strict_overrides_are_refused(case_file, capsys, override, words):
    error = _first_error(case_file, capsys, "--set", override)
    assert f"--set {override[:40]}" in error and words in error, error


def test_set_creates_missing_sections(case_file):
    case, source = load_case(case_file, ["analysis.type=quasi_static", "analysis.steps=3",
                                         "plasticity.yield_stress=1e8"])
    assert case.analysis.type == "quasi_static" and case.analysis.steps == 3
    assert case.plasticity.yield_stress == 1e8
    assert ("analysis",) in source.created and ("plasticity",) in source.created


@pytest.mark.parametrize(
    "override,words",
    [
        ("analysis.steps=10", "analysis: missing 'type' key: t_end, dt and steps are for "
         "'type: quasi_static'"),
        ("fracture.tensile_strength=1", "fracture.smoothing: required key is missing"),
        ("material.youngs_modulus.x=3", "material.youngs_modulus holds a number"),
        ("boundary_conditions.7.type=fixed", "boundary_conditions has no item 7 (it has 2)"),
        ("material=[1", "YAML: expected ',' or ']'"),
        ("material.youngs_modulus=" + "9" * 5000, "characters)...999"),
        ("analysis={tpye: dynamic}", "analysis.tpye: unknown key (did you mean 'type'?)"),
    ],
)
def test_bad_overrides_name_the_option_in_one_line(case_file, capsys, override, words):
    error = _first_error(case_file, capsys, "--set", override)
    assert error.startswith(f"error: {case_file}: --set ") and words in error, error
    assert len(error) < 400


def test_a_misspelt_key_is_one_error_at_the_key(tmp_path, capsys):
    case = tmp_path / "case.yaml"
    case.write_text(BASE.replace("mesh:", "mehs:").replace("lengths:", "lenghts:"))
    error = _first_error(case, capsys)
    assert f"{case}:2:1: mehs: unknown key (did you mean 'mesh'?)" in error, error
    assert "required key" not in error
    case.write_text(BASE.replace("lengths:", "lenghts:").replace("    type: box", "    tpye: box"))
    error = _first_error(case, capsys)
    assert f"{case}:4:5: mesh.geometry.tpye: unknown key (did you mean 'type'?)" in error


def test_several_errors_print_the_first_and_count_the_rest(tmp_path, capsys):
    case = tmp_path / "case.yaml"
    case.write_text(BASE.replace("210e9", "-1").replace("0.3", "0.7").replace("7850", "0"))
    error = _first_error(case, capsys)
    assert f"{case}:9:3: material.youngs_modulus" in error and "(and 2 more errors)" in error


@pytest.mark.parametrize(
    "text,words",
    [
        (b"units: SI\n# caf\xe9\n", "case.yaml:2:6: not UTF-8 text (byte 0xe9)"),
        ("a: " + "[" * 60 + "]" * 60 + "\n", "nested deeper than 50 levels"),
        ("a: " + "[" * 5000 + "]" * 5000 + "\n", "nested deeper than 50 levels"),
        ("a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]\n" + "".join(
            f"{c}: &{c} [{', '.join([f'*{p}'] * 10)}]\n"
            for p, c in zip("abcdef", "bcdefg", strict=True)), "more than 100,000 values"),
        ("a: 1\n---\nb: 2\n", "single document"),
        ("a: \x00\n", "case.yaml:1:4: YAML: special characters are not allowed"),
        ("title: 2001-13-45\n", "case.yaml:1:8: YAML: cannot read a value"),
        ("1: x\n", "a key must be a name, got 1"),
    ],
)
def test_hostile_yaml_is_one_located_line(tmp_path, capsys, text, words):
    case = tmp_path / "case.yaml"
    (case.write_bytes if isinstance(text, bytes) else case.write_text)(text)
    error = _first_error(case, capsys)
    assert words in error, error


def test_big_case_files_and_non_files_are_refused_unread(tmp_path, capsys):
    import os

    big = tmp_path / "case.yaml"
    with open(big, "wb") as f:
        f.truncate(11 * 2**20)
    assert "over the limit of 10 MB" in _first_error(big, capsys)
    fifo = tmp_path / "fifo.yaml"
    os.mkfifo(fifo)  # reading it would block for ever
    assert "not a regular file" in _first_error(fifo, capsys)


# --- work bounds -------------------------------------------------------------------------------


def test_work_bounds_refuse_before_meshing_unless_allowed(case_file, capsys):
    from fem_frac.app.budget import BOUNDS, check_budget, estimate

    case, _ = load_case(case_file)
    e = estimate(case, case_file.parent)
    assert e.tets == pytest.approx(5 * 1.0 * 0.5 * 0.5 / 0.5**3) and e.steps == 1
    error = _first_error(case_file, capsys, "--set", "mesh.element_size=1e-4")
    assert "mesh.element_size: about 1.25e+12 tets" in error and "--allow-large" in error
    many = ["--set", "analysis={type: quasi_static, steps: 200000}"]
    assert "2e+05 output frames: over the bound of 100000" in _first_error(
        case_file, capsys, *many)
    assert main(["check", str(case_file), *many, "--allow-large"]) == 0
    wide = ["--set", "fracture={tensile_strength: 1, smoothing: {length: 100}}",
            "--set", "mesh.element_size=0.02"]
    assert "tets in a smoothing neighbourhood" in _first_error(case_file, capsys, *wide)
    heavy, _ = load_case(case_file, ["mesh.element_size=1e-4"])
    check_budget(heavy, case_file.parent, bounds=None)  # no bounds: no refusal
    with pytest.raises(CaseError, match="over the bound"):
        check_budget(heavy, case_file.parent, BOUNDS)


def test_explicit_substeps_count_as_steps(case_file):
    from fem_frac.app.budget import estimate

    case, _ = load_case(case_file, ["analysis={type: dynamic, integrator: central_difference,"
                                    " substeps: true, dt: 1.0, steps: 10}"])
    # steel, h = 0.5: c = 5.8 km/s, stable step about 0.7 h / c = 6e-5 s
    assert 1e5 < estimate(case, case_file.parent).steps < 3e5


def test_tets_estimate_matches_gmsh_and_the_shipped_files():
    from pathlib import Path

    from fem_frac.app.budget import estimate
    from fem_frac.mesh.build import build_mesh

    cases = Path(__file__).resolve().parents[1] / "cases"
    case, _ = load_case(cases / "cantilever.yaml")
    mesh = build_mesh(case.mesh, cases)
    assert 0.8 < estimate(case, cases).tets / mesh.n_tets < 1.6
    for name in ("notched_beam", "plate_with_hole", "block_with_hole"):
        case, _ = load_case(cases / f"{name}.yaml")
        assert 100 < estimate(case, cases).tets < 1e5, name
