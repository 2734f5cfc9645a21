"""The output stage: the history row of every step, the series at the output steps, the
progress display, and the tally of the run for its summary; the console the run's messages
go to.

It reads the world and the step's events and returns the world unchanged.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, TextIO

from ..fracture.stage import Batch, FractureEvent
from ..solve.discretization import Log
from ..solve.state import StepInfo
from ..solve.stepping import ExplicitStepper
from ..timing import StageTimer
from ..world.stage import Step
from ..world.state import Body, World
from ..writers.history import HistoryWriter
from ..writers.series import SeriesWriter
from .results import CrackWriter, Layout, empty, frame, history_row, write_step

if TYPE_CHECKING:
    from tqdm import tqdm


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


class Console:
    """The run's messages on ``stream`` (stderr), one a line: a :data:`Log`. While a
    :class:`Progress` bar is drawn on a terminal, a message prints above the bar, which is
    redrawn below it. ``quiet``: nothing at all, no bar either."""

    def __init__(self, stream: TextIO | None = None, quiet: bool = False):
        self.stream = stream if stream is not None else sys.stderr
        self.quiet = quiet
        self.bar: tqdm | None = None

    @property
    def terminal(self) -> bool:
        """Whether a bar may be drawn: not quiet, and the stream is a terminal."""
        isatty = getattr(self.stream, "isatty", None)
        return not self.quiet and isatty is not None and bool(isatty())

    def __call__(self, message: str) -> None:
        if self.quiet:
            return
        if self.bar is not None:
            self.bar.write(message, file=self.stream)
        else:
            print(message, file=self.stream, flush=True)

    def note(self, message: str) -> None:
        """Work under way inside a step (a fracture batch): shown in the bar's status on a
        terminal until the step is drawn; nowhere else (a log file keeps the stages' own
        lines)."""
        if self.bar is not None:
            self.bar.set_description_str(message, refresh=True)

    def close(self) -> None:
        """Ends a bar left drawn (a run stopped by an error or Ctrl-C), so what follows
        starts on a line of its own."""
        if self.bar is not None:
            bar, self.bar = self.bar, None
            bar.close()


# the bar: steps done, elapsed and estimated time left, then the step's status
BAR_FORMAT = ("step       {n_fmt}/{total_fmt} |{bar:20}| {percentage:3.0f}%  "
              "elapsed {elapsed}  ETA {remaining}  {desc}")


class Progress:
    """What a run shows while it steps: steps done, elapsed, the estimated time left, and
    the last step's time, cost and residual (with fracture and fragments: crack faces,
    fragments, rigid bodies).

    On a :class:`Console` that is a terminal, a bar redrawn in place (tqdm); the messages of
    the stages print above it. Anywhere else (a file or a pipe, or a ``log`` that is a plain
    function), a plain line into ``log`` at most every ``every`` seconds, and the last
    step's line. On a quiet console, nothing."""

    def __init__(self, log: Log, steps: int, every: float = 10.0):
        self.log, self.steps, self.every = log, steps, every
        self.start = self.last = time.perf_counter()
        console = log if isinstance(log, Console) else None
        self.quiet = console is not None and console.quiet
        self.console = console if console is not None and console.terminal else None

    def __call__(self, n: int, t: float, info: StepInfo, row: dict | None = None,
                 explicit: bool = False) -> None:
        """Step ``n`` committed at ``t``; ``row``: its history row; ``explicit``: the step
        counts substeps of central difference, not iterations."""
        if self.quiet:
            return
        status = self.status(t, info, row or {}, explicit)
        if self.console is not None:
            self._draw(self.console, n, ", ".join(status))
            return
        now = time.perf_counter()
        if n == 0 or (n < self.steps and now - self.last < self.every):
            return
        self.last = now
        self.log(f"step       {n}/{self.steps}  elapsed {_interval(now - self.start)}  "
                 f"ETA {self.eta(n, now)}  {', '.join(status)}")

    @staticmethod
    def status(t: float, info: StepInfo, row: dict, explicit: bool = False) -> list[str]:
        """``t = ...``, ``3 iterations`` (an explicit step: its substeps), the crack faces,
        fragments and rigid bodies of ``row`` when it has them, then the residual (none
        for an explicit step)."""
        parts = [f"t = {t:.6g}",
                 _count(info.iterations, "substep" if explicit else "iteration")]
        if info.cutbacks:
            parts.append(_count(info.cutbacks, "cutback"))
        for key, word in (("crack_faces", "crack face"), ("fragments", "fragment")):
            if key in row:
                parts.append(_count(row[key], word))
        if "rigid_bodies" in row:
            parts.append(f"{row['rigid_bodies']} rigid")
        if not explicit:
            parts.append(f"residual {info.residual:.1e}")
        return parts

    def eta(self, n: int, now: float) -> str:
        """The time left at the mean rate of the steps so far (``?`` before the first)."""
        if n <= 0:
            return "?"
        return _interval((now - self.start) * (self.steps - n) / n)

    def _draw(self, console: Console, n: int, status: str) -> None:
        bar = console.bar
        if bar is None:
            # the width is the terminal's; the height is given, as a terminal may report
            # none (tqdm then draws nothing); the rate behind the ETA is an average that
            # follows slower or faster stretches of steps without jumping at each one
            from tqdm import tqdm  # only where a bar is drawn (its import: ~6 ms)

            bar = console.bar = tqdm(total=self.steps, file=console.stream, desc=status,
                                     bar_format=BAR_FORMAT, miniters=1, smoothing=0.1,
                                     nrows=24)
        bar.set_description_str(status, refresh=False)
        bar.update(n - bar.n)
        if n >= self.steps:
            console.close()


def _count(n: int, word: str) -> str:
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


def _interval(seconds: float) -> str:
    from tqdm import tqdm

    return tqdm.format_interval(seconds)


class OutputStage:
    """Writes what the run shows (module docstring). ``observers`` see every committed
    ``(n, world)`` (a declared reference records what it needs)."""

    name = "output"

    def __init__(self, plan: OutputPlan, layout: Layout, series: SeriesWriter,
                 history: HistoryWriter, tally: Tally, timer: StageTimer,
                 cracks: CrackWriter | None = None, progress: Progress | None = None,
                 observers: tuple = ()):
        self.plan, self.layout, self.series, self.history = plan, layout, series, history
        self.tally, self.timer, self.cracks = tally, timer, cracks
        self.progress, self.observers = progress, observers

    def __call__(self, step: Step, world: World) -> tuple[World, None]:
        info = self.tally.add(step, world)
        row = history_row(step.n, world, info, step.event(FractureEvent), self.tally.body,
                          self.timer.total(), self.layout)
        self.history.write(row)
        for observe in self.observers:
            observe(step.n, world)
        if self.cracks is not None:
            self.cracks.record(step.n, world)  # the step every crack face opened in
        if self.plan.due(step.n):
            self._write(world)
        if self.progress is not None:
            explicit = isinstance(self.tally.body.disc.stepper, ExplicitStepper)
            self.progress(step.n, world.t, info, row, explicit)
        return world, None

    def _write(self, world: World) -> None:
        last = self.tally.body
        if world.body is not None:
            data = frame(last.disc, world.body, self.layout)
        else:  # the fields of the last body, empty
            data = empty(frame(last.disc, last, self.layout))
        write_step(self.series, world, data, self.layout)
        if self.cracks is not None:
            self.cracks.write(world, last.mesh)
