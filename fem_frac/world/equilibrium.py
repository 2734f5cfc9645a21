"""The equilibrium stage: the finite elements from the start of a step to its end."""

from __future__ import annotations

from dataclasses import dataclass, replace

from ..errors import SolverError
from ..solve.state import StepInfo
from ..solve.stepping import advance
from .stage import Step
from .state import World


@dataclass(frozen=True, eq=False)
class SubStep:
    """A sub-step a cut-back step converged before its end: the world at its time (the
    body's state and the ledger there) and what it cost."""

    world: World
    info: StepInfo


@dataclass(frozen=True)
class Equilibrated(StepInfo):
    """The equilibrium stage's event: the step's :class:`StepInfo` (every sub-step's costs
    added up, its halvings in ``cutbacks``) and the sub-steps a cut-back step converged
    before its end, in order (none when the step was taken whole)."""

    substeps: tuple[SubStep, ...] = ()


class EquilibriumStage:
    """Steps the deformable body over the interval (substeps and cutbacks as its stepper
    says), keeping the energy ledger; the event is :class:`Equilibrated`. Without a
    deformable body (every piece rigid) only the time moves. A step that fails after
    converging sub-steps raises its :class:`~fem_frac.errors.SolverError` with those
    sub-steps (``substeps``), so the last converged state is not lost."""

    name = "equilibrium"

    def __call__(self, step: Step, world: World) -> tuple[World, StepInfo | None]:
        if step.initial:
            return world, None
        body = world.body
        if body is None:
            return replace(world, t=step.t), StepInfo(0, 0.0)
        kept: list[SubStep] = []

        def keep(state, ledger, info: StepInfo) -> None:
            kept.append(SubStep(replace(world, t=state.t, body=body.with_state(state),
                                        ledger=ledger), info))

        try:
            state, ledger, info = advance(body.disc.stepper, body.state, step.t,
                                          world.ledger, step.n, keep)
        except SolverError as exc:  # no convergence, a non-finite state: what converged stays
            exc.substeps = tuple(kept)
            raise
        event = Equilibrated(info.iterations, info.residual, info.solves,
                             info.factorizations, info.cutbacks, tuple(kept))
        return replace(world, t=step.t, body=body.with_state(state), ledger=ledger), event
