"""A run of a study on a machine that shares no filesystem with this one: the task a
cluster worker executes (:func:`run_remote`) and the delivery of what it sends back into
the study's runs directory here (:func:`deliver`).

On the worker, the run's inputs (:mod:`.inputs`: the case file and the files it names, as
bytes) are written into a fresh temporary directory, the case is run there by
:func:`.runs.execute` (``fem-frac run`` in a process of its own, so its peak memory and its
failure stay its own), and the plain files of its output directory come back as bytes:
all of them when they hold at most the cap the study passes, else only the files the study
reads (:data:`STUDY_FILES`). The temporary directory is removed afterwards.

Here, the files are written where a local run would have written them, and the worker's
paths in them (and in the run's message) are replaced by the paths a local run is given:
the case file as the study names it, the run's directory, the root of the inputs.
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import stat
import tempfile
from pathlib import Path

from ...errors import FemFracError
from ...writers.directory import MANIFEST, name_problem, prepare_directory, replace_file
from .runs import execute

#: The most a run's output may hold to come back whole (bytes); above it only the files the
#: study reads come back.
RETURN_CAP_BYTES = 256 * 2**20

#: What comes back of a run over the cap: what the study reads, and the list of the run's files.
STUDY_FILES = ("summary.json", "history.csv", "case.resolved.yaml", "study_run.json", MANIFEST)


def run_remote(case: str, files: dict[str, bytes], overrides: tuple[str, ...], run_id: str,
               cap: int, threads: int | None = None) -> dict:
    """Run the case ``case`` (a path relative to the inputs' root, one of ``files``) with
    ``overrides`` in a temporary directory of this machine; returns the run's record
    (:func:`.runs.execute`, ``threads`` its threads), its output files (``{name:
    bytes}``), the names left out over ``cap``, the worker's paths and its host name."""
    work = Path(tempfile.mkdtemp(prefix="fem-frac-run-"))
    try:
        root = work / "inputs"
        for rel, data in files.items():
            path = _inside(root, rel)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
        (work / "runs").mkdir()
        run_dir = work / "runs" / run_id
        record = execute(str(root / case), str(run_dir), tuple(overrides), threads=threads)
        out, left_out = _collect(run_dir, cap)
        return {"record": record, "files": out, "left_out": left_out,
                "paths": {"case": str(root / case), "run_dir": str(run_dir),
                          "root": str(root)},
                "host": socket.gethostname()}
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _inside(root: Path, rel: str) -> Path:
    """``root / rel`` for a relative path that stays inside ``root``."""
    parts = Path(rel).parts
    if Path(rel).is_absolute() or not parts or any(p in ("", ".", "..") for p in parts):
        raise FemFracError(f"{rel!r}: an input of a run must be a relative path inside its "
                           "directory")
    return root.joinpath(*parts)


def _collect(run_dir: Path, cap: int) -> tuple[dict[str, bytes], dict]:
    """The plain files directly inside ``run_dir``; over ``cap`` bytes in all, only
    :data:`STUDY_FILES`, and ``{names, bytes}`` of what was left out."""
    if not run_dir.is_dir():
        return {}, {}
    plain = {}
    for p in sorted(run_dir.iterdir()):
        st = os.lstat(p)
        if stat.S_ISREG(st.st_mode):
            plain[p.name] = st.st_size
    total = sum(plain.values())
    keep = list(plain) if total <= cap else [n for n in plain if n in STUDY_FILES]
    left = [n for n in plain if n not in keep]
    left_out = {"names": left, "bytes": sum(plain[n] for n in left), "cap": cap} if left else {}
    return {n: (run_dir / n).read_bytes() for n in keep}, left_out


def deliver(sent: dict, run_dir: Path, case_path: str, root: Path) -> dict:
    """Write what :func:`run_remote` sent into ``run_dir`` (removing the files of an earlier
    run there, as ``--overwrite`` does) with the worker's paths replaced by ``case_path``,
    ``run_dir`` and ``root``; returns the run's record, which is also ``study_run.json``."""
    paths = sent["paths"]
    swap = [(paths["case"], case_path), (paths["run_dir"], str(run_dir)),
            (paths["root"], str(root))]
    record = dict(sent["record"])
    record["message"] = _swapped(record.get("message", ""), swap)
    record["worker"] = sent.get("host")
    if sent["left_out"]:
        record["not_returned"] = sent["left_out"]
    files = sent["files"]
    if not files:  # the run wrote nothing (refused before its directory was made)
        return record
    for name in files:
        problem = name_problem(name)
        if problem is not None:
            raise FemFracError(f"{run_dir}: a file the worker sent, {name!r}: {problem}")
    prepare_directory(run_dir, Path(case_path).stem, overwrite=True)
    for name, data in files.items():
        if name != "study_run.json":
            replace_file(run_dir / name, _swapped(data, swap))
    replace_file(run_dir / "study_run.json", json.dumps(record, indent=2) + "\n")
    return record


def _swapped(data, swap: list[tuple[str, str]]):
    """``data`` (text or bytes) with each worker path replaced by the path here."""
    raw = isinstance(data, bytes)
    for old, new in swap:
        if raw:
            data = data.replace(os.fsencode(old), os.fsencode(new))
        else:
            data = data.replace(old, new)
    return data
