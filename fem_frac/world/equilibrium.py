"""The equilibrium stage: the finite elements from the start of a step to its end."""

from __future__ import annotations

from dataclasses import replace

from ..solve.state import StepInfo
from ..solve.stepping import advance
from .stage import Step
from .state import World


class EquilibriumStage:
    """Steps the deformable body over the interval (substeps and cutbacks as its stepper
    says), keeping the energy ledger; the event is the step's :class:`StepInfo`. Without a
    deformable body (every piece rigid) only the time moves."""

    name = "equilibrium"

    def __call__(self, step: Step, world: World) -> tuple[World, StepInfo | None]:
        if step.initial:
            return world, None
        body = world.body
        if body is None:
            return replace(world, t=step.t), StepInfo(0, 0.0)
        state, ledger, info = advance(body.disc.stepper, body.state, step.t, world.ledger,
                                      step.n)
        return replace(world, t=step.t, body=body.with_state(state), ledger=ledger), info
