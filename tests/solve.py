"""Run a case given as a dict through the driver, without files."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from fem_frac.app.driver import prepare, simulate
from fem_frac.app.output import step_info
from fem_frac.config.schema import Case
from fem_frac.fracture.stage import FractureEvent
from fem_frac.timing import StageTimer


@dataclass(frozen=True)
class Seen:
    """What a test sees of a step: its equilibrium cost (re-solves included), and the
    crack sites opened in it."""

    iterations: int
    residual: float
    solves: int
    factorizations: int
    cutbacks: int
    insertions: int
    passes: int


class Observe:
    """A stage that shows ``observe(n, state, ledger, seen)`` every committed step (the
    state ``None`` once no finite element is left)."""

    name = "observe"

    def __init__(self, observe):
        self.observe = observe

    def __call__(self, step, world):
        info, fracture = step_info(step), step.event(FractureEvent)
        seen = Seen(info.iterations, info.residual, info.solves, info.factorizations,
                    info.cutbacks, fracture.insertions if fracture else 0,
                    fracture.passes if fracture else 0)
        state = world.body.state if world.body is not None else None
        self.observe(step.n, state, world.ledger, seen)
        return world, None


def simulate_dict(case_dict: dict, case_dir: Path = Path("."), observe=None):
    """``(setup, last world, tally)`` of a case, every step seen by ``observe``."""
    case = Case.model_validate(case_dict)
    timer = StageTimer()
    setup = prepare(case, case_dir, timer)
    observers = (Observe(observe),) if observe is not None else ()
    world, tally = simulate(setup, timer, observers=observers)
    return setup, world, tally


def run(case_dict: dict, case_dir: Path = Path("."), observe=None):
    """``(setup, final state, ledger, tally)`` of a case, every step seen by ``observe``."""
    setup, world, tally = simulate_dict(case_dict, case_dir, observe)
    return setup, world.body.state, world.ledger, tally


def solve(case_dict: dict, case_dir: Path = Path(".")):
    """(case, discretization, displacement) of a static case."""
    setup, state, _, _ = run(case_dict, case_dir)
    return setup.case, setup.disc, state.u


def run_fracture(case_dict: dict, case_dir: Path = Path("."), observe=None):
    """``(setup, last world, final state, ledger, tally)`` of a case with fracture;
    ``world.body.disc`` is the final discretization (mesh, space, operators)."""
    setup, world, tally = simulate_dict(case_dict, case_dir, observe)
    return setup, world, world.body.state, world.ledger, tally


# a 2-step quasi-static cantilever on a coarse mesh (a history of three rows, in a second)
SMALL_CASE = {
    "mesh": {"geometry": {"type": "box", "lengths": [1.0, 0.2, 0.2]}, "element_size": 0.2,
             "order": 1},
    "material": {"youngs_modulus": 210e9, "poissons_ratio": 0.3},
    "boundary_conditions": [
        {"type": "fixed", "boundary": "xmin"},
        {"type": "traction", "boundary": "xmax", "traction": [0.0, 0.0, -1e5]},
    ],
    "analysis": {"type": "quasi_static", "steps": 2},
}


def write_case(path: Path, case_dict: dict) -> Path:
    """Write ``case_dict`` as a YAML case file (block style, one key per line)."""
    from ruamel.yaml import YAML

    yaml = YAML(typ="safe")
    yaml.default_flow_style = False
    with open(path, "w") as f:
        yaml.dump(case_dict, f)
    return path
