"""The output directory: never overwrite earlier results unless asked."""

from __future__ import annotations

from pathlib import Path

from ..errors import FemFracError

# What a run writes; ``--overwrite`` removes exactly these, nothing else.
OWNED = (
    "{name}.pvd", "{name}.pvd.tmp", "{name}_*.vtu", "summary.json", "case.resolved.yaml",
    "history.csv",
)


def prepare_directory(directory: Path, name: str, overwrite: bool) -> Path:
    """Create ``directory`` for a run named ``name``.

    Refuses when it already holds results of a run unless ``overwrite``; then removes only
    the files a run writes (see ``OWNED``).
    """
    owned = [p for pattern in OWNED for p in directory.glob(pattern.format(name=name))]
    if directory.exists() and not directory.is_dir():
        raise FemFracError(f"{directory}: exists and is not a directory")
    if owned and not overwrite:
        raise FemFracError(
            f"{directory}: holds results of an earlier run ({owned[0].name}); "
            "pass --overwrite to replace them or -o DIR to write elsewhere"
        )
    for p in owned:
        p.unlink()
    directory.mkdir(parents=True, exist_ok=True)
    return directory
