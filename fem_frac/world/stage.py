"""The stage protocol and the one step loop.

A stage is a callable ``(step, world) -> (world, event)``: it reads the world it is given,
returns the world after its part of the step, and an event record (a small frozen value, or
``None``) for the history and the console. The loop runs the stages in order for step 0 (the
initial world: stages that move it in time leave it as it is) and for every step of the
time grid, and knows nothing of what any stage does.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any, Protocol, TypeVar

import numpy as np

from .state import World

E = TypeVar("E")


@dataclass(frozen=True, eq=False)
class Step:
    """Step ``n`` of the time grid, from the world ``start`` (committed at the previous
    step) to time ``t``; ``events`` are those of the stages that ran before in this step.
    Step 0 is the initial world (``start.t == t``)."""

    n: int
    t: float
    start: World
    events: tuple = ()

    @property
    def initial(self) -> bool:
        return self.n == 0

    def event(self, kind: type[E]) -> E | None:
        """The event of type ``kind`` reported so far in this step (the last one)."""
        for e in reversed(self.events):
            if isinstance(e, kind):
                return e
        return None


class Stage(Protocol):
    """One stage of the step loop."""

    name: str

    def __call__(self, step: Step, world: World) -> tuple[World, Any]: ...


def march(world: World, stages: Sequence[Stage], times: np.ndarray,
          timer: Callable[[str], Any] | None = None) -> World:
    """Run ``stages`` for step 0 at ``times[0]`` and every step to ``times[1:]``; returns
    the last world. ``timer(name)``, a context manager, times each stage by name."""
    for n in range(len(times)):
        step = Step(n, float(times[n]), world)
        for stage in stages:
            if timer is None:
                world, event = stage(step, world)
            else:
                with timer(stage.name):
                    world, event = stage(step, world)
            step = replace(step, events=step.events + (event,))
    return world
