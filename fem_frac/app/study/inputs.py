"""The files a run of a study reads, gathered so that it can run on a machine that does not
share this one's filesystem (``fem-frac study --scheduler``).

A case names files relative to its own directory: ``mesh.file`` (a ``.geo`` with the files
it ``Include``\\ s or ``Merge``\\ s by a literal name), the ``file`` of every obstacle of
``type: mesh``, and ``analysis.initial_displacement.from_run.directory`` (of which the run
reads the ``.pvd`` and its last frame). Those files and the case file are the run's inputs,
named by their paths relative to a common root, so that the same tree rebuilt anywhere
resolves the same relative names. An absolute path (or ``~``) cannot be rebuilt there and
is refused, as are inputs above :data:`INPUT_CAP_BYTES` in all.

Files named but missing are not gathered: the run then fails on the worker as it would
here (same exit code and message).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

from ...errors import FemFracError

#: The most a run's input files may hold, together (bytes).
INPUT_CAP_BYTES = 256 * 2**20

# ``Include "name"`` / ``Merge "name"`` of a .geo file (a literal name; gmsh takes it from
# the including file's directory). A computed name is refused by the .geo check itself.
_GEO_INCLUDE = re.compile(rb'\b(?:Include|Merge|MergeWithBoundingBox)\s*"([^"\n]*)"')


@dataclass(frozen=True)
class RunInputs:
    """The case file and the files it names: ``root`` (here) and, relative to it, the case
    (``case``) and every other file (``files``)."""

    root: Path
    case: str
    files: tuple[str, ...]

    def read(self) -> dict[str, bytes]:
        """``{relative path: content}`` of the case and its files."""
        return {rel: (self.root / rel).read_bytes() for rel in (self.case, *self.files)}


def run_inputs(case_path: Path, overrides: tuple[str, ...] = ()) -> RunInputs:
    """The inputs of the run of ``case_path`` with ``overrides``; :class:`FemFracError` when
    one is named by an absolute path or they are over :data:`INPUT_CAP_BYTES`."""
    case_path = Path(os.path.abspath(case_path))
    case = _case(case_path, overrides)
    named = _named_files(case, case_path.parent) if case is not None else []
    paths = [case_path, *named]
    root = Path(os.path.commonpath([str(p.parent) for p in paths]))
    total = sum(p.stat().st_size for p in paths)
    if total > INPUT_CAP_BYTES:
        raise FemFracError(f"{case_path}: the case and its files hold {total / 2**20:.0f} MiB, "
                           f"over the {INPUT_CAP_BYTES / 2**20:.0f} MiB a run sends to a "
                           "cluster; run this study without --scheduler")
    rel = [os.path.relpath(p, root) for p in paths]
    return RunInputs(root, rel[0], tuple(dict.fromkeys(rel[1:])))


def _case(case_path: Path, overrides: tuple[str, ...]):
    """The case with ``overrides`` (else without them, else ``None``): a case that does not
    load fails on the worker just as it would here."""
    from ...config import load_case

    for o in (overrides, ()):
        try:
            return load_case(case_path, o)[0]
        except (FemFracError, OSError):
            continue
    return None


def _named_files(case, case_dir: Path) -> list[Path]:
    """The plain files ``case`` names that exist, relative names taken from ``case_dir``."""
    found: list[Path] = []
    if case.mesh.file is not None:
        mesh = _relative(case_dir, case.mesh.file, "mesh.file")
        found += _geo_tree(mesh) if mesh.suffix == ".geo" else [mesh]
    for i, obstacle in enumerate(case.obstacles):
        if obstacle.type == "mesh":
            found.append(_relative(case_dir, obstacle.file, f"obstacles[{i}].file"))
    start = getattr(case.analysis, "initial_displacement", None)
    if start is not None and start.from_run is not None:
        found += _earlier_run(case_dir, start.from_run)
    return [p for p in found if p.is_file()]


def _relative(case_dir: Path, name: str, key: str) -> Path:
    if name.startswith("~") or Path(name).is_absolute():
        raise FemFracError(f"{key}: {name} is an absolute path; a run on a cluster takes only "
                           "files named relative to the case file (no filesystem is assumed "
                           "shared with the workers)")
    return Path(os.path.normpath(case_dir / name))


def _geo_tree(path: Path, seen: set | None = None) -> list[Path]:
    """``path`` and the files it includes by a literal name, recursively."""
    seen = set() if seen is None else seen
    if path in seen or not path.is_file():
        return []
    seen.add(path)
    found = [path]
    for m in _GEO_INCLUDE.finditer(path.read_bytes()):
        name = os.fsdecode(m.group(1))
        target = _relative(path.parent, name, f"mesh.file: {path.name}: Include/Merge")
        found += _geo_tree(target, seen) if target.suffix == ".geo" else [target]
    return found


def _earlier_run(case_dir: Path, spec) -> list[Path]:
    """The ``.pvd`` of ``from_run.directory`` and the last frame it lists (what the run
    reads); nothing when the directory holds no readable series (the run says why)."""
    from ...errors import CaseError
    from ..initial import run_series

    _relative(case_dir, spec.directory, "analysis.initial_displacement.from_run.directory")
    try:
        frame = run_series(case_dir, spec)
    except (CaseError, OSError):
        return []
    directory = Path(os.path.normpath(case_dir / spec.directory))
    series = [p for p in directory.glob("*.pvd") if not p.stem.endswith("_crack")]
    return [*series, Path(os.path.normpath(frame))]
