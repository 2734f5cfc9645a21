"""``fem-frac study --scheduler``: the runs of a study on a Dask distributed cluster.

Each run is one task, :func:`.remote.run_remote`, which runs the case as ``fem-frac run`` in
a process of its own on a worker, in a temporary directory of the worker's machine; its
inputs travel with the task (:func:`_submit`) and its output comes back as bytes
(:mod:`.remote`), so no filesystem is assumed shared. ``--scheduler local`` starts a
:class:`distributed.LocalCluster` of ``workers`` processes of one thread each (one run at a
time per worker).

A task whose worker dies is started again on another worker by the scheduler, up to
``distributed.scheduler.allowed-failures`` times (3 by default), then its run fails
("crashed"); a run's own failure (exit 2, 3, a crashed process) is its record, as here.

dask.distributed is optional (``pip install 'fem-frac[cluster]'``) and imported only here.
"""

from __future__ import annotations

import contextlib
import logging
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

from ...errors import FemFracError
from . import remote
from .inputs import run_inputs
from .runs import run_threads
from .spec import Run, Study

HINT = "pip install 'fem-frac[cluster]'"

#: Input files up to this size (bytes) travel inside each task; larger ones are scattered.
EMBED_BYTES = 2**20

#: How long to wait for the scheduler to answer.
CONNECT_TIMEOUT = "20s"


def require_distributed() -> None:
    """:class:`FemFracError` (one line, how to install it) without dask.distributed."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise FemFracError("--scheduler needs dask.distributed, which is not installed: "
                           f"{HINT}") from None


@contextlib.contextmanager
def connect(scheduler: str, workers: int):
    """A client of the scheduler at ``scheduler``, or of a new local cluster of ``workers``
    one-thread processes for ``"local"``; closed (the local cluster stopped) on leaving."""
    require_distributed()
    from distributed import Client, LocalCluster

    cluster = None
    try:
        if scheduler == "local":
            cluster = LocalCluster(  # no dashboard; its HTTP server on a free local port
                n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                silence_logs=logging.ERROR)
            client = Client(cluster)
        else:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        if cluster is not None:
            cluster.close()
        raise FemFracError(f"--scheduler {scheduler}: cannot connect: "
                           f"{' '.join(str(exc).split()) or type(exc).__name__}") from None
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def cluster_runs(study: Study, todo: list[Run], runs_dir: Path, scheduler: str, workers: int,
                 log: Callable[[str], None] = lambda _m: None) -> Iterator[tuple[Run, dict]]:
    """Yield ``(run, record)`` for each run of ``todo`` as it finishes on the cluster, its
    output written into ``runs_dir/<run id>``. Raises :class:`FemFracError` before anything
    runs when a run's inputs cannot be sent (:func:`.inputs.run_inputs`) or the scheduler
    cannot be reached."""
    if not todo:
        return
    inputs = {run.run_id: run_inputs(study.case_path, run.overrides) for run in todo}
    with connect(scheduler, workers) as client:
        # a local cluster's workers share this machine's cores; a remote worker's run keeps
        # its machine's settings (one worker a core, as the docs advise)
        threads = run_threads(workers) if scheduler == "local" else None
        futures = _submit(client, todo, inputs, threads)
        try:
            yield from _gathered(futures, study, inputs, runs_dir, log)
        finally:  # also on an interrupt: start no more runs (those under way finish there)
            client.cancel([f for f in futures if not f.done()])


def _submit(client, todo: list[Run], inputs: dict, threads: int | None = None) -> dict:
    """Submit one task per run, in grid order. An input file up to :data:`EMBED_BYTES` is
    an argument of the task itself (the scheduler holds it, so a task started again after
    its worker died has it); a larger one is sent once to every worker (``broadcast``: it
    survives the death of any one of them) and shared by the runs that read it.
    ``threads``: each run's ``OMP_NUM_THREADS`` (:func:`.runs.execute`)."""
    scattered: dict[Path, object] = {}
    futures = {}
    tag = uuid.uuid4().hex[:8]
    for run in todo:
        ri = inputs[run.run_id]
        files = {}
        for rel in (ri.case, *ri.files):
            path = ri.root / rel
            if path not in scattered:
                data = path.read_bytes()
                scattered[path] = data if len(data) <= EMBED_BYTES else \
                    client.scatter(data, hash=False, broadcast=True)
            files[rel] = scattered[path]
        fut = client.submit(remote.run_remote, ri.case, files, run.overrides, run.run_id,
                            remote.RETURN_CAP_BYTES, threads,
                            key=f"fem-frac-run-{tag}-{run.index}",
                            pure=False)
        futures[fut] = run
    return futures


def _gathered(futures: dict, study: Study, inputs: dict, runs_dir: Path,
              log: Callable[[str], None]) -> Iterator[tuple[Run, dict]]:
    from distributed import as_completed

    for fut in as_completed(list(futures)):
        run = futures[fut]
        try:
            sent = fut.result()
        except Exception as exc:  # the task failed, not the run: its worker died, no fem_frac
            text = " ".join(str(exc).split())
            yield run, {"exit_code": None, "message": "the run's task failed on the cluster: "
                        f"{type(exc).__name__}" + (f": {text}" if text else "")}
            continue
        finally:
            fut.release()
        run_dir = runs_dir / run.run_id
        try:
            record = remote.deliver(sent, run_dir, str(study.case_path),
                                    inputs[run.run_id].root)
        except (FemFracError, OSError) as exc:
            record = {**sent["record"], "exit_code": None,
                      "message": f"its output could not be written here: {exc}"}
        if "not_returned" in record:
            left = record["not_returned"]
            log(f"warning: run {run.run_id}: its output ({left['bytes'] / 2**20:.0f} MiB "
                f"besides the study's files) is over the {left['cap'] / 2**20:.0f} MiB that "
                f"come back from a worker: only {', '.join(remote.STUDY_FILES[:3])} came back")
        yield run, record
