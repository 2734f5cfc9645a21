"""How far a run got, in its ``summary.json`` from the first step on.

The driver writes the summary marked ``running`` before the first step and refreshes it
(at most once a second) as steps are committed, so a run killed outright (``kill -9``, out
of memory) leaves a summary saying which step it reached beside a ``.pvd`` that lists every
frame written. An interrupted run (Ctrl-C, SIGTERM) or a failed one (exit 3) marks it
``interrupted`` or ``failed`` with the step and the reason; a finished run replaces it by
the full summary (``completed``).
"""

from __future__ import annotations

import json
import signal
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ..errors import Interrupted
from ..writers.directory import replace_file


def write_json(path: Path, data: dict) -> None:
    """``data`` to ``path`` through a scratch file and a rename (never half written, never
    through a link)."""
    replace_file(path, json.dumps(data, indent=2) + "\n")


class RunStatus:
    """The summary of a run under way: ``(n, world)`` observer of every committed step."""

    def __init__(self, path: Path, case_path: Path, steps: int, every: float = 1.0):
        self.path, self.case_path, self.steps, self.every = path, case_path, steps, every
        self.step, self.t = 0, 0.0
        self._last = -float("inf")

    def record(self, status: str, **extra) -> None:
        write_json(self.path, {"case": str(self.case_path), "status": status,
                               "step": self.step, "steps": self.steps, "time": self.t,
                               **extra})

    def __call__(self, n: int, world) -> None:
        self.step, self.t = n, world.t
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
