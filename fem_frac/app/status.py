"""How far a run got, in its ``summary.json`` from the first step on.

The driver writes the summary marked ``running`` before the first step and refreshes it
(at most once a second) as steps are committed, so a run killed outright (``kill -9``, out
of memory) leaves a summary saying which step it reached beside a ``.pvd`` that lists every
frame written. An interrupted run (Ctrl-C, SIGTERM) or a failed one (exit 3) marks it
``interrupted`` or ``failed`` with the last step it completed (``step``, ``time``), where it
stopped (``stopped_at``: step and stage) and the reason (``message``); a failed summary also
carries what a completed one does as far as it is known at the last completed step (counts,
analysis costs, energies, wall times). A finished run replaces it by the full summary
(``completed``).
"""

from __future__ import annotations

import json
import signal
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..errors import Interrupted, SolverError
from ..writers.directory import replace_file

# Exceptions that are numerical failures (exit 3): the solver's own, and those numpy,
# LAPACK and the overflow warning (raised as an error during a run) throw.
NUMERICAL = (SolverError, ArithmeticError, np.linalg.LinAlgError, RuntimeWarning)


def write_json(path: Path, data: dict) -> None:
    """``data`` to ``path`` through a scratch file and a rename (never half written, never
    through a link)."""
    replace_file(path, json.dumps(data, indent=2) + "\n")


def where(exc: BaseException) -> tuple[int | None, str | None]:
    """The step number and stage name of the step loop's frame ``exc`` passed through
    (``(None, None)`` when it was raised outside the loop)."""
    tb, found = exc.__traceback__, (None, None)
    while tb is not None:
        frame = tb.tb_frame
        if frame.f_code.co_name == "march" and "stage" in frame.f_locals:
            name = getattr(frame.f_locals["stage"], "name", None)
            if name:
                found = (frame.f_locals.get("n"), name)
        tb = tb.tb_next
    return found


def stage_of(exc: BaseException) -> str:
    """``step n, stage s: `` of the step loop's frame ``exc`` passed through, unless the
    message says so already (a numerical failure deep in shared code knows neither)."""
    if str(exc).startswith("step "):
        return ""
    n, name = where(exc)
    return "" if name is None else f"step {'?' if n is None else n}, stage {name}: "


def failure_message(exc: BaseException) -> str:
    """What stopped a run, as the command line says it (without the case file)."""
    if isinstance(exc, SolverError):
        return f"{stage_of(exc)}{exc}"
    kind = "numerical failure" if isinstance(exc, NUMERICAL) else "internal error"
    return f"{stage_of(exc)}{kind}: {type(exc).__name__}: {exc}"


class RunStatus:
    """The summary of a run under way: ``(n, world)`` observer of every committed step.

    ``world`` is the last committed world and ``tally`` the run's tally (set by the
    driver once the initial world exists), so that a failed run can say what it had
    reached."""

    def __init__(self, path: Path, case_path: Path, steps: int, every: float = 1.0):
        self.path, self.case_path, self.steps, self.every = path, case_path, steps, every
        self.step, self.t = 0, 0.0
        self.world, self.tally = None, None
        self._last = -float("inf")

    def record(self, status: str, **extra) -> None:
        write_json(self.path, {"case": str(self.case_path), "status": status,
                               "step": self.step, "steps": self.steps, "time": self.t,
                               **extra})

    def fail(self, exc: BaseException, known: dict | None = None) -> None:
        """Mark the run ``failed`` by ``exc``: the last step it completed, where it
        stopped, the message, and ``known`` (the summary's sections as far as known)."""
        n, stage = where(exc)
        started = self.world is not None
        if n is None:  # outside the step loop: setting up (before step 0) or after it
            n, stage = (self.step, "summary") if started else (0, "set-up")
        known = {k: v for k, v in (known or {}).items()
                 if k not in ("case", "status", "step", "steps", "time")}
        write_json(self.path, {
            "case": str(self.case_path), "status": "failed",
            # the last step completed (0 also when the run stopped setting up step 0:
            # stopped_at says so)
            "step": self.step, "steps": self.steps, "time": self.t,
            "stopped_at": {"step": n, "stage": stage}, "message": failure_message(exc),
            **known})

    def __call__(self, n: int, world) -> None:
        self.step, self.t, self.world = n, world.t, world
        now = time.perf_counter()
        if now - self._last >= self.every:
            self._last = now
            self.record("running")


def _raise(signum, _frame):
    raise Interrupted(signum)


@contextmanager
def terminated_as_interrupt() -> Iterator[None]:
    """SIGTERM raises :class:`Interrupted` inside the block (as SIGINT raises
    KeyboardInterrupt), so the run can say how far it got; outside the main thread
    nothing changes."""
    try:
        previous = signal.signal(signal.SIGTERM, _raise)
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
