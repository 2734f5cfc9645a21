"""Element-wise work of a large mesh over the machine's cores.

numpy's batched LAPACK calls (``eigh``) and scipy's sparse products release the GIL while
they run, so a large mesh's elements, split into one contiguous range per core, are done in
threads at once. Each element's result is the same bits as in one call: no sum crosses an
element, and every element goes through the same code.

Below :data:`MIN_ITEMS` items it is one call. Splitting shortens the wall time only: a
thread's CPU time is still counted, and handing ranges over costs 0.08 ms a call (measured on
2 cores), so a small mesh keeps one thread and its CPU time (every case of ``cases/`` is
below the threshold). Threads: the CPUs this process may run on, at most
:data:`MAX_THREADS`, and at most ``OMP_NUM_THREADS`` where that is set (MKL's PARDISO
threads follow it too).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")

# Items (elements, tensors, rows) from which the work is split over the threads: at 94k
# tets the split took the eigh from 85 to 47-73 ms and the smoothing product from 36 to
# 14-20 ms of wall time on two cores (benchmarks/fracture.py; docs/performance.md,
# "Insertions, seventh pass"). The threshold lies above every shipped case (the largest has
# 14,638 tets), whose figures are CPU time, which splitting does not lower.
MIN_ITEMS = 32_768
MAX_THREADS = 8

_pool: tuple[int, int, object] | None = None  # (pid, workers, executor); a forked child
# has no threads of its parent's pool and makes its own


def cores() -> int:
    """The CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def threads() -> int:
    """The threads element-wise work may use (module docstring)."""
    n = cores()
    limit = os.environ.get("OMP_NUM_THREADS", "").strip()
    if limit.isdigit() and int(limit) > 0:
        n = min(n, int(limit))
    return max(1, min(n, MAX_THREADS))


def _executor(workers: int):
    global _pool
    if _pool is None or _pool[0] != os.getpid() or _pool[1] < workers:
        from concurrent.futures import ThreadPoolExecutor

        if _pool is not None and _pool[0] == os.getpid():
            _pool[2].shutdown(wait=False)  # a smaller one (OMP_NUM_THREADS rose)
        _pool = (os.getpid(), workers,
                 ThreadPoolExecutor(workers, thread_name_prefix="fem-frac"))
    return _pool[2]


def map_ranges(fn: Callable[[int, int], T], n: int) -> list[T]:
    """``[fn(start, stop), ...]`` over contiguous ranges that cover ``range(n)`` in order:
    one call ``fn(0, n)`` below :data:`MIN_ITEMS` or with one thread, else one range per
    thread, run at once (the first in the calling thread). An exception in any range is
    raised here, after all ranges have finished."""
    k = threads() if n >= MIN_ITEMS else 1
    if k == 1:
        return [fn(0, n)]
    bounds = [n * i // k for i in range(k + 1)]
    futures = [_executor(k - 1).submit(fn, bounds[i], bounds[i + 1]) for i in range(1, k)]
    try:
        first = fn(bounds[0], bounds[1])
    finally:
        from concurrent.futures import wait

        wait(futures)
    return [first] + [f.result() for f in futures]
