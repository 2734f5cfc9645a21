"""Run a case given as a dict through the driver, without files."""

from __future__ import annotations

from pathlib import Path

from fem_frac.app.driver import prepare, simulate
from fem_frac.config.schema import Case
from fem_frac.timing import StageTimer


def run(case_dict: dict, case_dir: Path = Path("."), observe=None):
    """``(setup, final state, ledger, counters)`` of a case, every step seen by ``observe``."""
    case = Case.model_validate(case_dict)
    timer = StageTimer()
    setup = prepare(case, case_dir, timer)
    state, ledger, counters = simulate(setup, timer, observe or (lambda *a: None))
    return setup, state, ledger, counters


def solve(case_dict: dict, case_dir: Path = Path(".")):
    """(case, model, displacement) of a static case."""
    setup, state, _, _ = run(case_dict, case_dir)
    return setup.case, setup.model, state.u


def run_fracture(case_dict: dict, case_dir: Path = Path("."), observe=None):
    """``(setup, fracture stage, final state, ledger, counters)`` of a case with fracture;
    ``stage.current`` is the final discretization (mesh, space, operators)."""
    from fem_frac.app.driver import fracture_stage

    case = Case.model_validate(case_dict)
    timer = StageTimer()
    setup = prepare(case, case_dir, timer)
    stage = fracture_stage(setup, timer)
    state, ledger, counters = simulate(setup, timer, observe or (lambda *a: None),
                                       fracture=stage)
    return setup, stage, state, ledger, counters


def run_fragments(case_dict: dict, case_dir: Path = Path("."), observe=None):
    """``(setup, fracture stage, rigid stage, final state, ledger)`` of a case with
    fragments."""
    from fem_frac.app.driver import fracture_stage, rigid_stage

    case = Case.model_validate(case_dict)
    timer = StageTimer()
    setup = prepare(case, case_dir, timer)
    fracture = fracture_stage(setup, timer)
    rigid = rigid_stage(setup, fracture)
    state, ledger, _ = simulate(setup, timer, observe or (lambda *a: None),
                                fracture=fracture, rigid=rigid)
    return setup, fracture, rigid, state, ledger


def write_case(path: Path, case_dict: dict) -> Path:
    """Write ``case_dict`` as a YAML case file (block style, one key per line)."""
    from ruamel.yaml import YAML

    yaml = YAML(typ="safe")
    yaml.default_flow_style = False
    with open(path, "w") as f:
        yaml.dump(case_dict, f)
    return path
