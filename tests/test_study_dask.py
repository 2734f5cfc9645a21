"""``fem-frac study --scheduler``: a study on a Dask cluster started from the command line
(a scheduler and two workers, each in a working and temporary directory of its own) writes
the same study.csv as the same study run here; failed runs stay per run; a run's inputs
travel in its task (no filesystem shared); without dask.distributed, one line and exit 2."""

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fem_frac.app.cli import main

distributed = pytest.importorskip("distributed")

from fem_frac.app.study import remote  # noqa: E402
from fem_frac.app.study.inputs import run_inputs  # noqa: E402
from tests.test_study import CASE  # noqa: E402
from tests.test_study import STUDY as LOCAL_STUDY  # noqa: E402

REPO = Path(__file__).resolve().parents[1]

# the study of tests/test_study.py without its thread count (a cluster's are its workers')
STUDY = LOCAL_STUDY.replace("workers: 2\n", "")
assert STUDY != LOCAL_STUDY

# A run that is refused (exit 2: Poisson's ratio over 0.5) and one that fails numerically
# (exit 3: E = 1e-300, its matrix cannot be factorized), beside one that completes.
FAILING = STUDY.replace("mesh.element_size: [0.2, 0.14, 0.098]",
                        "mesh.element_size: [0.25]\n"
                        '  "material.youngs_modulus,material.poissons_ratio": '
                        "[[210e9, 0.3], [210e9, 0.7], [1e-300, 0.3]]")

# The columns that measure this machine at this moment, not the run: wall times (total and
# per stage) and the peak memory of the run's process. Every other column must agree.
TIMING_COLUMNS = ("wall_time_s", "peak_mib")


def _timing(column: str) -> bool:
    return column in TIMING_COLUMNS or (column.startswith("time_") and column.endswith("_s"))


def _rows(path):
    with path.open() as f:
        return list(csv.DictReader(f))


def _without_timing(rows):
    return [{k: v for k, v in r.items() if not _timing(k)} for r in rows]


def _write_study(directory: Path, text: str) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "beam.yaml").write_text(CASE)
    path = directory / "study.yaml"
    path.write_text(text)
    return path


def _start(argv, cwd: Path, env: dict) -> subprocess.Popen:
    return subprocess.Popen(argv, cwd=cwd, env=env, stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)  # its own process group, killed whole


def _stop(procs: list[subprocess.Popen]) -> None:
    for proc in procs:
        with _gone():
            os.killpg(proc.pid, signal.SIGTERM)
    deadline = time.monotonic() + 10
    for proc in procs:
        try:
            proc.wait(max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            with _gone():
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(5)


class _gone:  # noqa: N801 (a context manager, used as a statement)
    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        return kind is not None and issubclass(kind, ProcessLookupError)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """A scheduler and two workers started with the ``dask`` command, each in a working
    directory, a ``--local-directory`` and a TMPDIR of its own (none of them the client's);
    torn down (process groups terminated, then killed) whatever the tests did."""
    base = tmp_path_factory.mktemp("cluster")
    procs: list[subprocess.Popen] = []
    scheduler_file = base / "scheduler.json"
    try:
        (base / "scheduler").mkdir()
        env = {**os.environ, "PYTHONPATH": str(REPO)}
        procs.append(_start([sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1",
                             "--port", "0", "--no-dashboard", "--scheduler-file",
                             str(scheduler_file)], base / "scheduler", env))
        workers = []
        for i in (1, 2):
            w = base / f"worker{i}"
            for sub in ("cwd", "local", "tmp"):
                (w / sub).mkdir(parents=True)
            workers.append(w)
            procs.append(_start([sys.executable, "-m", "dask", "worker", "--scheduler-file",
                                 str(scheduler_file), "--nworkers", "1", "--nthreads", "1",
                                 "--no-dashboard", "--local-directory", str(w / "local")],
                                w / "cwd", {**env, "TMPDIR": str(w / "tmp")}))
        address = _address(scheduler_file, procs)
        with distributed.Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
        yield address, workers, procs
    finally:
        _stop(procs)


def _address(scheduler_file: Path, procs) -> str:
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if any(p.poll() is not None for p in procs):
            raise RuntimeError("a dask process of the test cluster exited")
        try:
            return json.loads(scheduler_file.read_text())["address"]
        except (OSError, ValueError, KeyError):
            time.sleep(0.2)
    raise RuntimeError("the test scheduler wrote no scheduler file in 60 s")


@pytest.fixture(scope="module")
def local_run(tmp_path_factory):
    """The tiny study run here (threads, no cluster)."""
    path = _write_study(tmp_path_factory.mktemp("local"), STUDY)
    out = path.parent / "out"
    assert main(["study", str(path), "-o", str(out), "-q", "--workers", "2"]) == 0
    return path, out


def test_a_study_on_the_cluster_writes_the_same_study_csv(cluster, local_run, tmp_path):
    address, workers, _ = cluster
    _, local_out = local_run
    path = _write_study(tmp_path / "client", STUDY)
    out = tmp_path / "client" / "out"
    assert main(["study", str(path), "-o", str(out), "-q", "--scheduler", address]) == 0
    here, there = _rows(local_out / "study.csv"), _rows(out / "study.csv")
    assert list(there[0]) == list(here[0])  # the same columns, in the same order
    assert _without_timing(there) == _without_timing(here)
    assert [r["status"] for r in there] == ["ok"] * 3
    assert all(float(r["wall_time_s"]) > 0 and float(r["peak_mib"]) > 10 for r in there)
    for r in there:  # the whole run directory came back, where a local run writes it
        run, local = out / "runs" / r["run_id"], local_out / "runs" / r["run_id"]
        assert sorted(p.name for p in run.iterdir()) == sorted(p.name for p in local.iterdir())
        record = json.loads((run / "study_run.json").read_text())
        assert record["exit_code"] == 0 and record["worker"]
        for p in run.iterdir():  # no path of the worker's is left in what came back
            assert b"fem-frac-run-" not in p.read_bytes(), p
    for w in workers:  # each run's temporary directory on its worker was removed
        assert not list((w / "tmp").glob("fem-frac-run-*"))
    info_here = json.loads((local_out / "study.json").read_text())
    info_there = json.loads((out / "study.json").read_text())
    assert info_there["rates"] == info_here["rates"]


def test_failed_runs_on_the_cluster_are_the_same_rows(cluster, tmp_path, capsys):
    address, _, _ = cluster
    path = _write_study(tmp_path, FAILING)
    outcomes = {}
    for where, options in (("here", ["--workers", "2"]), ("there", ["--scheduler", address])):
        out = tmp_path / f"out_{where}"
        code = main(["study", str(path), "-o", str(out), "-q", *options])
        err = capsys.readouterr().err
        outcomes[where] = code, _without_timing(_rows(out / "study.csv")), err
    assert outcomes["there"] == outcomes["here"]
    code, rows, err = outcomes["there"]
    assert code == 1
    assert [r["exit_code"] for r in rows] == ["0", "2", "3"]
    assert [r["last_step"] for r in rows if r["exit_code"] == "3"] == ["0"]
    assert err.count("error: run ") == 2


def test_output_over_the_cap_brings_back_only_what_the_study_reads(cluster, local_run,
                                                                    tmp_path, monkeypatch):
    address, _, _ = cluster
    _, local_out = local_run
    monkeypatch.setattr(remote, "RETURN_CAP_BYTES", 1000)  # below any run's output
    path = _write_study(tmp_path / "client", STUDY.replace("[0.2, 0.14, 0.098]", "[0.14]"))
    out = tmp_path / "client" / "out"
    assert main(["study", str(path), "-o", str(out), "-q", "--scheduler", address]) == 0
    assert _without_timing(_rows(out / "study.csv")) == \
        _without_timing(_rows(local_out / "study.csv"))[1:2]
    for run in (out / "runs").iterdir():
        assert {p.name for p in run.iterdir()} <= set(remote.STUDY_FILES)
        left = json.loads((run / "study_run.json").read_text())["not_returned"]
        assert left["cap"] == 1000 and any(n.endswith(".vtu") for n in left["names"])


def test_a_local_cluster_writes_the_same_study_csv(local_run, tmp_path):
    _, local_out = local_run
    path = _write_study(tmp_path, STUDY)
    out = tmp_path / "out"
    assert main(["study", str(path), "-o", str(out), "-q", "--scheduler", "local",
                 "--workers", "2"]) == 0
    assert _without_timing(_rows(out / "study.csv")) == \
        _without_timing(_rows(local_out / "study.csv"))


def test_a_run_needs_no_file_of_the_client(tmp_path, monkeypatch):
    """A case that reads a mesh file by a relative path (``../meshes``): its inputs are
    gathered, the client's files removed, and the task run in another directory."""
    (tmp_path / "cases").mkdir()
    (tmp_path / "meshes").mkdir()
    shutil.copy(REPO / "meshes" / "block_with_hole.msh", tmp_path / "meshes")
    case = tmp_path / "cases" / "block.yaml"
    case.write_text((REPO / "cases" / "block_with_hole.yaml").read_text())
    inputs = run_inputs(case, ("material.youngs_modulus=7e10",))
    assert inputs.root == tmp_path
    assert (inputs.case, inputs.files) == ("cases/block.yaml", ("meshes/block_with_hole.msh",))
    files = inputs.read()
    shutil.rmtree(tmp_path / "cases")
    shutil.rmtree(tmp_path / "meshes")
    elsewhere = tmp_path / "worker"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    monkeypatch.setenv("TMPDIR", str(elsewhere))
    sent = remote.run_remote(inputs.case, files, ("material.youngs_modulus=7e10",), "r",
                             remote.RETURN_CAP_BYTES)
    assert sent["record"]["exit_code"] == 0, sent["record"]
    assert json.loads(sent["files"]["summary.json"])["status"] == "completed"
    assert list(elsewhere.iterdir()) == []  # its temporary directory removed


def test_a_geo_file_travels_with_what_it_includes(tmp_path):
    (tmp_path / "geo").mkdir()
    (tmp_path / "geo" / "body.geo").write_text('Include "size.geo";\nMerge "../extra.stl";\n')
    (tmp_path / "geo" / "size.geo").write_text("h = 0.1;\n")
    (tmp_path / "extra.stl").write_text("solid x\nendsolid x\n")
    case = tmp_path / "case" / "c.yaml"
    case.parent.mkdir()
    case.write_text(CASE.replace("  geometry: {type: box, lengths: [1.0, 0.25, 0.25]}\n",
                                 "  file: ../geo/body.geo\n"))
    inputs = run_inputs(case)
    assert inputs.case == "case/c.yaml"
    assert set(inputs.files) == {"geo/body.geo", "geo/size.geo", "extra.stl"}


def test_a_file_named_by_an_absolute_path_is_refused(tmp_path, capsys):
    mesh = (REPO / "meshes" / "block_with_hole.msh").resolve()
    path = _write_study(tmp_path, STUDY)
    (tmp_path / "beam.yaml").write_text(CASE.replace(
        "  geometry: {type: box, lengths: [1.0, 0.25, 0.25]}\n", f"  file: {mesh}\n"))
    code = main(["study", str(path), "-o", str(tmp_path / "out"), "-q", "--scheduler",
                 "tcp://127.0.0.1:9"])  # refused before it connects
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith(f"error: mesh.file: {mesh} is an absolute path"), err


def test_without_dask_one_line_and_exit_2(tmp_path, monkeypatch, capsys):
    path = _write_study(tmp_path, STUDY)
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    assert main(["study", str(path), "-o", str(tmp_path / "out"), "--scheduler",
                 "tcp://127.0.0.1:8786"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["error: --scheduler needs dask.distributed, which is not installed: "
                   "pip install 'fem-frac[cluster]'"], err
    assert not (tmp_path / "out").exists()


def test_workers_with_a_scheduler_address_is_refused(tmp_path, capsys):
    path = _write_study(tmp_path, STUDY)
    assert main(["study", str(path), "--scheduler", "tcp://127.0.0.1:8786",
                 "--workers", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --workers 2: "), err


def test_an_unreachable_scheduler_is_one_line(tmp_path, capsys, monkeypatch):
    from fem_frac.app.study import cluster as cluster_module

    monkeypatch.setattr(cluster_module, "CONNECT_TIMEOUT", "2s")
    path = _write_study(tmp_path, STUDY)
    assert main(["study", str(path), "-o", str(tmp_path / "out"), "-q", "--scheduler",
                 "tcp://127.0.0.1:9"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --scheduler tcp://127.0.0.1:9: cannot "
                                               "connect"), err


def test_a_worker_that_dies_loses_only_its_run(cluster, tmp_path):
    """The worker process of a run under way is killed (SIGKILL): the scheduler starts the
    run again on a worker and the study completes, every row ok."""
    import threading

    import psutil

    address, workers, _ = cluster
    path = _write_study(tmp_path, STUDY.replace("[0.2, 0.14, 0.098]", "[0.07, 0.06]"))
    outcome = {}
    study = threading.Thread(target=lambda: outcome.setdefault("code", main(
        ["study", str(path), "-o", str(tmp_path / "out"), "-q", "--scheduler", address])))
    study.start()
    killed = None
    deadline = time.monotonic() + 60
    while killed is None and study.is_alive() and time.monotonic() < deadline:
        for proc in psutil.process_iter(["cmdline"]):
            cmd = " ".join(proc.info["cmdline"] or [])
            if "fem_frac run" in cmd and any(str(w / "tmp") in cmd for w in workers):
                with _gone():
                    proc.parent().kill()  # the worker process (its nanny starts a new one)
                    proc.kill()  # the run it left
                    killed = cmd
                break
        time.sleep(0.05)
    study.join(120)
    assert killed is not None, "no run was seen under way on the cluster"
    assert outcome.get("code") == 0
    assert [r["status"] for r in _rows(tmp_path / "out" / "study.csv")] == ["ok", "ok"]
    with distributed.Client(address, timeout="30s") as client:  # whole again for others
        client.wait_for_workers(2, timeout=60)
