"""Running the grid: each run is ``python -m fem_frac run`` in a process of its own."""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ...errors import FemFracError
from ...threads import cores
from ...writers.directory import check_location, name_problem, replace_file
from .analysis import evaluate, summary_value
from .spec import Run, Study

# The directory that holds the fem_frac package, for the runs' PYTHONPATH.
_PACKAGE_ROOT = str(Path(__file__).resolve().parents[3])


@dataclass
class Result:
    run: Run
    status: str  # "ok", "skipped" (done earlier), "failed"
    exit_code: int | None = None
    message: str = ""
    peak_mib: float | None = None
    summary: dict | None = None
    value: float | None = None  # the study quantity of this run
    reference: float | None = None  # the value it is compared with
    error: float | None = None
    partial: dict | None = None  # the summary a run that stopped left (how far it got)

    @property
    def ok(self) -> bool:
        return self.summary is not None

    @property
    def wall_s(self) -> float | None:
        """Wall time of the run (of a failed one: until it stopped), when its summary
        says."""
        return (self.summary or self.partial or {}).get("wall_time_s", {}).get("total")

    @property
    def dofs(self) -> int | None:
        return (self.summary or self.partial or {}).get("counts", {}).get("dofs")

    @property
    def last_step(self) -> int | None:
        """The last step a failed run completed (from its summary), else ``None``."""
        return None if self.ok or self.partial is None else self.partial.get("step")

    @property
    def h(self) -> float | None:
        """Discretization size of the run: the study's ``refinement`` key if swept (default
        ``mesh.element_size``), else dofs^(-1/3)."""
        if self.run.size is not None:
            return self.run.size
        return self.dofs ** (-1 / 3) if self.dofs else None


class _Children:
    """The run processes alive, so that an interrupted study stops them."""

    def __init__(self):
        self.lock = threading.Lock()
        self.procs: set[subprocess.Popen] = set()
        self.stopped = False

    def start(self, argv: list[str], env: dict) -> subprocess.Popen | None:
        with self.lock:
            if self.stopped:
                return None
            proc = subprocess.Popen(argv, env=env, stdin=subprocess.DEVNULL,
                                    stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                    text=True, errors="replace")
            self.procs.add(proc)
            return proc

    def done(self, proc: subprocess.Popen) -> None:
        with self.lock:
            self.procs.discard(proc)

    def stop(self) -> None:
        with self.lock:
            self.stopped = True
            for proc in self.procs:
                if proc.returncode is None:
                    proc.terminate()


def _wait(proc: subprocess.Popen) -> tuple[int, float | None]:
    """Exit code (``-N``: killed by signal N) and peak resident memory (MiB) of ``proc``."""
    if not hasattr(os, "wait4"):
        return proc.wait(), None
    try:
        _, status, usage = os.wait4(proc.pid, 0)
    except ChildProcessError:  # reaped by a concurrent poll() (an interrupted study)
        return proc.wait(), None
    proc.returncode = code = os.waitstatus_to_exitcode(status)
    rss = usage.ru_maxrss
    return code, (rss / (1024 * 1024) if sys.platform == "darwin" else rss / 1024)  # B vs KiB


def run_threads(workers: int) -> int:
    """The threads each of ``workers`` runs at once on this machine may use: its cores
    shared out, at least one."""
    return max(1, cores() // max(1, workers))


def execute(case_path: str, run_dir: str, overrides: tuple[str, ...],
            children: _Children | None = None, threads: int | None = None) -> dict:
    """Run one case as ``fem-frac run`` in a fresh process (so that its peak memory is its
    own). Returns ``{exit_code, message, peak_mib, process_s}`` and writes it to
    ``run_dir/study_run.json``; ``exit_code`` is None for a process killed by a signal.
    ``threads``: the run's ``OMP_NUM_THREADS`` (PARDISO's threads and the element-wise
    work's, :mod:`fem_frac.threads`) where the environment does not set it, so that runs
    side by side do not oversubscribe the cores (:func:`run_threads`)."""
    argv = [sys.executable, "-m", "fem_frac", "run", case_path, "-o", run_dir, "-q",
            "--overwrite"]
    for o in overrides:
        argv += ["--set", o]
    path = os.environ.get("PYTHONPATH")
    env = {**os.environ, "PYTHONPATH": _PACKAGE_ROOT + (os.pathsep + path if path else "")}
    if threads is not None and not os.environ.get("OMP_NUM_THREADS"):
        env["OMP_NUM_THREADS"] = str(threads)
    children = children or _Children()
    t0 = time.perf_counter()
    proc = children.start(argv, env)
    if proc is None:
        return {"exit_code": None, "message": "not run: the study was interrupted"}
    try:
        err = proc.stderr.read()
        code, peak = _wait(proc)
    finally:
        proc.stderr.close()
        children.done(proc)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("error:")]
    message = errors[-1] if errors else (lines[-1] if lines and code else "")
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        code, message = None, f"killed by {name}" + (f": {message}" if message else "")
    record = {"exit_code": code, "message": message.removeprefix("error: "),
              "peak_mib": round(peak, 1) if peak is not None else None,
              "process_s": round(time.perf_counter() - t0, 3)}
    if Path(run_dir).is_dir() and not Path(run_dir).is_symlink():
        replace_file(Path(run_dir) / "study_run.json", json.dumps(record, indent=2) + "\n")
    return record


def _read_summary(run_dir: Path) -> dict | None:
    """The run's ``summary.json`` as written, ``None`` when there is none to read."""
    p = run_dir / "summary.json"
    if not p.is_file():
        return None
    try:
        summary = json.loads(p.read_text())
    except (OSError, ValueError):
        return None
    return summary if isinstance(summary, dict) else None


def _load_summary(run_dir: Path) -> dict | None:
    """The summary of a run that completed; ``None`` for one to (re)run: never run, or
    stopped (its summary says how far it got, ``status`` running, failed or interrupted)."""
    summary = _read_summary(run_dir)
    return summary if summary is not None and summary.get("status") == "completed" else None


def _record(run_dir: Path) -> dict:
    try:
        return json.loads((run_dir / "study_run.json").read_text())
    except (OSError, ValueError):
        return {}


def runs_directory(out_dir: Path) -> Path:
    """``out_dir/runs``, made if need be; :class:`FemFracError` when it cannot be, or is a
    symbolic link or no directory (the runs would be written elsewhere)."""
    out_dir = Path(out_dir)
    runs_dir = out_dir / "runs"
    check_location(out_dir)
    if runs_dir.is_symlink() or (os.path.lexists(runs_dir) and not runs_dir.is_dir()):
        raise FemFracError(f"{runs_dir}: is a symbolic link or no directory; a study writes "
                           "its runs only inside its output directory: remove it or use -o DIR")
    try:
        runs_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FemFracError(f"{runs_dir}: cannot create it: {exc.strerror or exc}") from None
    return runs_dir


def run_directory(runs_dir: Path, run: Run) -> Path:
    """The directory of ``run``: ``runs_dir/<run id>``, a plain name directly inside
    ``runs_dir``; :class:`FemFracError` when the id is no plain name or the directory is a
    symbolic link or no directory (the run would be written elsewhere)."""
    problem = name_problem(run.run_id)
    if problem is not None:
        raise FemFracError(f"run id {run.run_id!r}: {problem}")
    path = runs_dir / run.run_id
    if path.is_symlink() or (os.path.lexists(path) and not path.is_dir()):
        raise FemFracError(f"{path}: is a symbolic link or no directory; a run is written only "
                           "inside the study's output directory: remove it")
    return path


def run_study(study: Study, out_dir: Path, workers: int | None = None,
              log: Callable[[str], None] = lambda _m: None,
              scheduler: str | None = None) -> list[Result]:
    """Run every run of the study not finished earlier; returns the results in grid order.

    Every run is written in its own directory directly inside ``out_dir/runs``; a run whose
    directory is a symbolic link (or no directory) is not run and fails with that message.
    With ``scheduler`` (an address, or ``"local"``) the runs go to a Dask cluster
    (:mod:`.cluster`), else to ``workers`` threads here, each waiting on its run's process.
    Raises :class:`FemFracError` when ``out_dir/runs`` cannot be made inside ``out_dir``."""
    runs_dir = runs_directory(out_dir)
    n = len(study.runs)
    results: dict[int, Result] = {}
    todo = []
    for run in study.runs:
        try:
            run_directory(runs_dir, run)
        except FemFracError as exc:
            results[run.index] = Result(run, "failed", None, str(exc))
            continue
        summary = _load_summary(runs_dir / run.run_id)
        if summary is None:
            todo.append(run)
            continue
        peak = _record(runs_dir / run.run_id).get("peak_mib")
        results[run.index] = Result(run, "skipped", 0, "", peak, summary)
    if study.quantity is None:
        evaluate(study, list(results.values()))
    for done, r in enumerate(results.values(), start=1):
        log(_progress(done, n, r))
    workers = workers or study.spec.workers or os.cpu_count() or 1
    workers = max(1, min(workers, len(todo) or 1))
    finished = (_run_all(study, todo, runs_dir, workers) if scheduler is None else
                _run_on_cluster(study, todo, runs_dir, scheduler, workers, log))
    with contextlib.closing(finished):
        for res in finished:
            results[res.run.index] = res
            if study.quantity is None:
                evaluate(study, [res])
            elif res.ok:
                res.value = summary_value(res.summary, study.quantity)
            log(_progress(len(results), n, res))
    ordered = [results[r.index] for r in study.runs]
    evaluate(study, ordered)
    return ordered


def _run_all(study: Study, todo: list[Run], runs_dir: Path, workers: int):
    """Yield the result of each run of ``todo`` as it finishes, ``workers`` at a time."""
    if not todo:
        return
    case_path = str(study.case_path)
    children = _Children()
    pool = cf.ThreadPoolExecutor(workers)
    threads = run_threads(workers)
    try:
        futures = {pool.submit(execute, case_path, str(runs_dir / run.run_id), run.overrides,
                               children, threads): run for run in todo}
        for fut in cf.as_completed(futures):
            try:
                rec = fut.result()
            except Exception as exc:  # the run could not be started (or waited for)
                rec = {"exit_code": None, "message": f"run failed to start: {exc!r}"}
            yield _result(futures[fut], rec, runs_dir)
    finally:  # also on an interrupt: stop the runs under way, start no more
        children.stop()
        pool.shutdown(wait=True, cancel_futures=True)


def _run_on_cluster(study: Study, todo: list[Run], runs_dir: Path, scheduler: str,
                    workers: int, log: Callable[[str], None]):
    """Yield the result of each run of ``todo`` as it finishes on a Dask cluster."""
    from .cluster import cluster_runs

    with contextlib.closing(cluster_runs(study, todo, runs_dir, scheduler, workers,
                                         log)) as sent:
        for run, rec in sent:
            yield _result(run, rec, runs_dir)


def _result(run: Run, rec: dict, runs_dir: Path) -> Result:
    """The result of ``run`` from its record (:func:`execute`) and its directory."""
    summary = _load_summary(runs_dir / run.run_id) if rec["exit_code"] == 0 else None
    res = Result(run, "ok" if summary else "failed", rec["exit_code"],
                 rec.get("message", ""), rec.get("peak_mib"), summary)
    if summary is None:  # what the run's own summary says of how far it got
        res.partial = _read_summary(runs_dir / run.run_id)
        if res.partial is not None and res.partial.get("status") == "completed":
            res.partial = None  # an earlier run's summary, not this one's
    if rec["exit_code"] == 0 and summary is None:
        res.message = "exit 0 but no summary.json"
    return res


def failure_line(r: Result) -> str:
    """One line naming a failed run: id, exit code, how far it got, the message."""
    code = f"exit {r.exit_code}" if r.exit_code is not None else "crashed"
    step = r.last_step
    where = (f", stopped after step {step} of {r.partial.get('steps')}"
             if step is not None else "")
    return f"run {r.run.run_id} failed ({code}{where}): {r.message}"


def _progress(i: int, n: int, r: Result) -> str:
    width = len(str(n))
    head = f"run {i:>{width}}/{n}  {r.run.run_id}"
    if not r.ok:
        code = f"exit {r.exit_code}" if r.exit_code is not None else "crashed"
        return f"{head}  FAILED ({code}): {r.message}"
    if r.error is not None:
        err = f"error {r.error:.3e}"
    else:
        err = f"value {r.value:.6g}" if r.value is not None else ""
    extra = "  (done earlier, kept)" if r.status == "skipped" else ""
    return f"{head}  {r.wall_s:7.2f} s  {err}{extra}"
