"""``history.csv``: one row per step, written and flushed as the run goes, so an interrupted
or failed run keeps every step it finished."""

from __future__ import annotations

import csv
from pathlib import Path


class HistoryWriter:
    """CSV with a fixed header taken from the first row's keys."""

    def __init__(self, path: Path):
        self.path = path
        self._file = None
        self._writer = None

    def write(self, row: dict) -> None:
        if self._writer is None:
            self._file = open(self.path, "w", newline="")  # noqa: SIM115 (kept open)
            self._writer = csv.DictWriter(self._file, fieldnames=list(row))
            self._writer.writeheader()
        self._writer.writerow({k: _format(v) for k, v in row.items()})
        self._file.flush()

    def close(self) -> None:
        if self._file is not None:
            self._file.close()

    def __enter__(self) -> HistoryWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _format(value) -> str:
    if isinstance(value, float):
        return f"{value:.10g}"
    return str(value)


def read_history(path: Path) -> dict[str, list[float]]:
    """Columns of a history file as floats (for tests and scripts)."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: [float(r[k]) for r in rows] for k in (rows[0] if rows else [])}
