"""Reading what ``fem-frac check`` prints, for the tests of its report."""

from __future__ import annotations

import re
from pathlib import Path

from fem_frac.app.cli import main
from solve import write_case


def check(tmp_path: Path, capsys, case: dict) -> str:
    """The report ``fem-frac check`` prints for ``case`` (written to ``tmp_path``)."""
    path = write_case(tmp_path / "case.yaml", case)
    capsys.readouterr()
    assert main(["check", str(path)]) == 0
    return capsys.readouterr().out


def line(text: str, start: str) -> str:
    """The one line of ``text`` that starts with ``start`` (leading spaces aside)."""
    hits = [x for x in text.splitlines() if x.lstrip().startswith(start)]
    assert len(hits) == 1, (start, text)
    return hits[0]


def number(text: str, before: str) -> float:
    """The number that follows ``before`` in ``text``."""
    return float(re.search(re.escape(before) + r" (\S+?)[;,)]?(?:\s|$)", text).group(1))
