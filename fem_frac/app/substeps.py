"""The sub-steps of cut-back steps in the output.

A static or quasi-static step whose equilibrium iteration fails is halved (cut back) and
taken in sub-steps (:func:`~fem_frac.solve.stepping.advance`). Every sub-step that
converged before the end of its step gets a row of ``history.csv`` of its own, before the
step's row: ``step`` n (the step it belongs to), ``substep`` k = 1, 2, ... in order, its
``time``, and its own ``iterations`` and ``residual`` (the step's row, ``substep`` 0, keeps
the costs of all its sub-steps added up, as before). When the step then fails, those rows
are written all the same and the last converged sub-state is written as a frame of the
series, so the last state in equilibrium is never lost.
"""

from __future__ import annotations

from ..solve.state import StepInfo
from ..timing import StageTimer
from ..world.stage import Step
from ..world.state import World
from ..writers.history import HistoryWriter
from ..writers.series import SeriesWriter
from .results import Layout, frame, history_row, write_step


class SubstepRows:
    """A stage placed just before the output: the history rows of the sub-steps of the
    step (the equilibrium stage's event), and :meth:`failed` for a step that stopped."""

    name = "substeps"

    def __init__(self, history: HistoryWriter, layout: Layout, timer: StageTimer,
                 series: SeriesWriter | None = None):
        self.history, self.layout, self.timer, self.series = history, layout, timer, series

    def __call__(self, step: Step, world: World) -> tuple[World, None]:
        info = step.event(StepInfo)
        self._rows(step.n, getattr(info, "substeps", ()))
        return world, None

    def failed(self, exc: BaseException, n: int) -> None:
        """Step ``n`` stopped with ``exc``: the rows of the sub-steps it converged and a
        frame of the last (nothing when it converged none)."""
        substeps = getattr(exc, "substeps", ())
        self._rows(n, substeps)
        if substeps and self.series is not None:
            last = substeps[-1].world
            write_step(self.series, last, frame(last.body.disc, last.body, self.layout),
                       self.layout)

    def _rows(self, n: int, substeps) -> None:
        for k, sub in enumerate(substeps, start=1):
            body = sub.world.body
            self.history.write(history_row(n, sub.world, sub.info, None, body,
                                           self.timer.total(), self.layout, substep=k))
