"""The output stage: the history row of every step, the series at the output steps, the
progress line, and the tally of the run for its summary.

It reads the world and the step's events and returns the world unchanged.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from ..fracture.stage import Batch, FractureEvent
from ..solve.discretization import Log
from ..solve.state import StepInfo
from ..timing import StageTimer
from ..world.stage import Step
from ..world.state import Body, World
from ..writers.history import HistoryWriter
from ..writers.series import SeriesWriter
from .results import Layout, empty, frame, history_row, write_crack_surface, write_step


def step_info(step: Step) -> StepInfo:
    """The step's equilibrium cost and residual: the regular step, then its re-solves on
    cracked meshes."""
    info = step.event(StepInfo) or StepInfo(0, 0.0)
    fracture = step.event(FractureEvent)
    if fracture is not None and fracture.resolve is not None:
        info = info.then(fracture.resolve)
    return info


@dataclass
class Tally:
    """What the run did, step by step: counts for the summary, the insertion batches, and
    the last deformable body (what the summary describes once no finite element is left).
    ``factorizations`` starts with those made before the first step."""

    body: Body
    solver: str = ""
    factorizations: int = 0
    steps: int = 0
    iterations: int = 0
    solves: int = 0
    cutbacks: int = 0
    max_residual: float = 0.0
    batches: list[Batch] = field(default_factory=list)

    def add(self, step: Step, world: World) -> StepInfo:
        info = step_info(step)
        if world.body is not None:
            self.body = world.body
        if step.initial:
            return info
        self.steps += 1
        self.iterations += info.iterations
        self.solves += info.solves
        self.factorizations += info.factorizations
        self.cutbacks += info.cutbacks
        self.max_residual = max(self.max_residual, info.residual)
        fracture = step.event(FractureEvent)
        if fracture is not None:
            self.batches.extend(fracture.batches)
        return info


class TallyStage:
    """A stage that adds every step to ``tally`` (a run without output)."""

    name = "tally"

    def __init__(self, tally: Tally):
        self.tally = tally

    def __call__(self, step: Step, world: World) -> tuple[World, None]:
        self.tally.add(step, world)
        return world, None


@dataclass(frozen=True)
class OutputPlan:
    """Which steps are written: step 0 and every ``every``-th, always the last of
    ``steps``; ``every`` None: the last only (a static analysis writes its one solution)."""

    steps: int
    every: int | None

    def due(self, n: int) -> bool:
        if self.every is None:
            return n == self.steps
        return n == self.steps or n % self.every == 0


class Progress:
    """A line every ~2 s of wall time, and at the end (into ``log``)."""

    def __init__(self, log: Log, steps: int, every: float = 2.0):
        self.log, self.steps, self.every = log, steps, every
        self.last = time.perf_counter()

    def __call__(self, n: int, t: float, info: StepInfo) -> None:
        now = time.perf_counter()
        if n == 0 or (n < self.steps and now - self.last < self.every):
            return
        self.last = now
        self.log(f"step       {n}/{self.steps}  t = {t:.6g}  "
                 f"iterations {info.iterations}  residual {info.residual:.1e}")


class OutputStage:
    """Writes what the run shows (module docstring). ``observers`` see every committed
    ``(n, world)`` (a declared reference records what it needs)."""

    name = "output"

    def __init__(self, plan: OutputPlan, layout: Layout, series: SeriesWriter,
                 history: HistoryWriter, tally: Tally, timer: StageTimer,
                 cracks: SeriesWriter | None = None, progress: Progress | None = None,
                 observers: tuple = ()):
        self.plan, self.layout, self.series, self.history = plan, layout, series, history
        self.tally, self.timer, self.cracks = tally, timer, cracks
        self.progress, self.observers = progress, observers

    def __call__(self, step: Step, world: World) -> tuple[World, None]:
        info = self.tally.add(step, world)
        self.history.write(history_row(step.n, world, info, step.event(FractureEvent),
                                       self.tally.body, self.timer.total(), self.layout))
        for observe in self.observers:
            observe(step.n, world)
        if self.plan.due(step.n):
            self._write(world)
        if self.progress is not None:
            self.progress(step.n, world.t, info)
        return world, None

    def _write(self, world: World) -> None:
        last = self.tally.body
        if world.body is not None:
            data = frame(last.disc, world.body, self.layout)
        else:  # the fields of the last body, empty
            data = empty(frame(last.disc, last, self.layout))
        write_step(self.series, world, data, self.layout)
        if self.cracks is not None:
            write_crack_surface(self.cracks, world, last.mesh)
