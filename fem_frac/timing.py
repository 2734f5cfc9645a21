"""Wall time per stage, and the process's CPU time before and during a run."""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field


def process_cpu() -> float:
    """CPU seconds (user + system, every thread) this process has spent so far."""
    return time.process_time()


@dataclass
class StageTimer:
    """Accumulates wall seconds per stage name, in the order stages first ran; made when a
    run begins, it also keeps the process's CPU time then (``cpu_start``)."""

    seconds: dict[str, float] = field(default_factory=dict)
    start: float = field(default_factory=time.perf_counter)
    cpu_start: float = field(default_factory=process_cpu)

    @contextmanager
    def __call__(self, stage: str):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[stage] = self.seconds.get(stage, 0.0) + time.perf_counter() - t0

    def total(self) -> float:
        return time.perf_counter() - self.start

    def cpu(self) -> dict[str, float]:
        """``{"before_run": ..., "run": ...}``: the process's CPU seconds before the timer
        was made (for ``fem-frac run``: Python's start, the imports, reading and checking
        the case) and since."""
        return {"before_run": round(self.cpu_start, 3),
                "run": round(process_cpu() - self.cpu_start, 3)}
