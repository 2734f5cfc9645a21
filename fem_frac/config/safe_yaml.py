"""YAML text a hostile or careless hand may have written, read within bounds.

A case file (or a ``--set`` value) is refused with a located message, before it can hang the
parser or reach the schema as something the schema cannot judge, when it is:

- larger than :data:`MAX_FILE_BYTES`, not a regular file, or not UTF-8 text;
- nested deeper than :data:`MAX_DEPTH` (the parser recurses: deep enough, it overflows the
  stack), or aliased so that it refers to itself or expands to more than :data:`MAX_VALUES`
  values ("billion laughs");
- a number YAML cannot read (``!!int 3.5``, 5000 digits, the 13th month);
- a value of no type a case uses: dates and times (quote them for text), binary data, sets,
  values with unknown tags, keys that are not names.

:func:`plain_data` turns ruamel's round-trip containers into plain dicts, lists and scalars,
checking the last two points on the way; its errors are :class:`CaseError` located by key.
"""

from __future__ import annotations

import datetime
import io
import re
from pathlib import Path

from ..errors import CaseError, FemFracError

MAX_FILE_BYTES = 10 * 2**20
MAX_DEPTH = 50
MAX_VALUES = 100_000

_SUSPECTS = (  # what makes ruamel's constructor raise a bare ValueError, most likely first
    re.compile(r"\d{1000,}"),
    re.compile(r"!!\w+"),
    re.compile(r"\b\d{4}-\d\d?-\d\d?"),
)


def read_text(path: Path, what: str = "case file") -> str:
    """The text of ``path``: a regular file of at most :data:`MAX_FILE_BYTES`, UTF-8."""
    try:
        if not path.is_file():
            reason = "no such file" if not path.exists() else "not a regular file"
            raise FemFracError(f"{path}: cannot read {what}: {reason}")
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise FemFracError(f"{path}: the {what} is {size / 2**20:.1f} MB, over the limit of "
                               f"{MAX_FILE_BYTES // 2**20} MB")
        raw = path.read_bytes()
    except OSError as exc:
        raise FemFracError(f"{path}: cannot read {what}: {exc.strerror}") from None
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line, col = _line_col(raw, exc.start)
        raise FemFracError(f"{path}:{line}:{col}: not UTF-8 text (byte 0x{raw[exc.start]:02x}); "
                           "save the file as UTF-8") from None


def shorten(text: str, most: int = 80) -> str:
    """``text`` for a one-line message: cut in the middle when longer than ``most``."""
    if len(text) <= most:
        return text
    return f"{text[: most // 2]}...({len(text) - most + 3} characters)...{text[-most // 2 + 3:]}"


def _line_col(text, offset: int) -> tuple[int, int]:
    """1-based line and column of ``offset`` in ``text`` (str or bytes)."""
    newline = b"\n" if isinstance(text, bytes) else "\n"
    before = text[:offset]
    return before.count(newline) + 1, offset - (before.rfind(newline) + 1) + 1


def yaml_parser():
    from ruamel.yaml import YAML

    y = YAML(typ="rt")  # round-trip keeps line numbers; YAML 1.2: `1e9` is a float
    y.allow_duplicate_keys = False
    return y


def load_yaml(text: str, where: str):
    """Parse ``text``; ``where`` (a file name, or ``--set KEY=VALUE``) heads every message.
    Positions are added as ``:line:col`` after a file name."""
    from ruamel.yaml.error import MarkedYAMLError, YAMLError

    located = not where.startswith("--set")

    def at(line: int, col: int) -> str:
        return f"{where}:{line}:{col}" if located else where

    _check_depth(text, at)
    try:
        return yaml_parser().load(io.StringIO(text))
    except MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        problem = str(exc.problem or exc.context or "invalid YAML")
        if problem.startswith("but ") and exc.context:  # "expected X" "but found Y"
            problem = f"{exc.context}, {problem}"
        problem = " ".join(problem.split())
        raise FemFracError(f"{at(mark.line + 1, mark.column + 1) if mark else where}: "
                           f"YAML: {problem}") from None
    except YAMLError as exc:
        position = getattr(exc, "position", None)
        head = at(*_line_col(text, position)) if isinstance(position, int) else where
        reason = str(getattr(exc, "reason", "") or exc).split("\n")[0]
        raise FemFracError(f"{head}: YAML: {' '.join(reason.split())}") from None
    except RecursionError:
        raise FemFracError(f"{where}: YAML: nested too deeply") from None
    except (ValueError, OverflowError) as exc:  # the constructor's int(), float(), date()
        for pattern in _SUSPECTS:
            found = pattern.search(text)
            if found:
                head = at(*_line_col(text, found.start()))
                break
        else:
            head = where
        raise FemFracError(f"{head}: YAML: cannot read a value: {' '.join(str(exc).split())}"
                           ) from None


def _check_depth(text: str, at) -> None:
    """Refuse nesting deeper than :data:`MAX_DEPTH` before the parser recurses into it.

    Counts indentation levels of block collections (and the ``- `` of nested sequences
    written on one line) plus open flow brackets; quoted text and comments are skipped. An
    overestimate for odd layouts, far from the few levels a case uses."""
    indents: list[int] = []
    flow, quote = 0, ""
    for lineno, line in enumerate(text.split("\n"), 1):
        body = line.lstrip(" ")
        if not quote and flow == 0:
            if not body or body.startswith("#"):
                continue
            indent = len(line) - len(body)
            while indents and indents[-1] >= indent:
                indents.pop()
            indents.append(indent)
            dashes = len(re.match(r"(?:-\s+)*", body).group(0).split("-")) - 1
        else:
            dashes = 0
        depth = len(indents) + max(dashes - 1, 0)
        col = len(line) - len(body)
        for i, ch in enumerate(line[col:], col):
            if quote:
                if ch == quote and not (quote == '"' and line[i - 1] == "\\"):
                    quote = ""
            elif ch in "'\"":
                quote = ch
            elif ch == "#" and (i == 0 or line[i - 1] in " \t"):
                break
            elif ch in "[{":
                flow += 1
            elif ch in "]}":
                flow = max(flow - 1, 0)
            if depth + flow > MAX_DEPTH:
                raise FemFracError(f"{at(lineno, i + 1)}: YAML: nested deeper than "
                                   f"{MAX_DEPTH} levels")
        if depth + flow > MAX_DEPTH:
            raise FemFracError(f"{at(lineno, col + 1)}: YAML: nested deeper than "
                               f"{MAX_DEPTH} levels")


def plain_data(node):
    """ruamel's round-trip containers and scalar subclasses -> plain Python objects.

    Raises a :class:`CaseError` at the key path of the first value no case can hold (see
    the module's description), of nesting beyond :data:`MAX_DEPTH` (an alias that refers to
    itself nests without end) or of the value past :data:`MAX_VALUES`."""
    return _plain(node, (), [0], set())


def _plain(node, path: tuple, count: list[int], open_: set[int]):
    count[0] += 1
    if count[0] > MAX_VALUES:
        raise CaseError(path, f"more than {MAX_VALUES:,} values (aliases expanding?)")
    if len(path) > MAX_DEPTH:
        raise CaseError(path[:MAX_DEPTH], f"nested deeper than {MAX_DEPTH} levels")
    if isinstance(node, (dict, list)):
        if id(node) in open_:
            raise CaseError(path, "an alias that refers to itself (it would nest without end)")
        open_.add(id(node))
        try:
            if isinstance(node, list):
                return [_plain(v, path + (i,), count, open_) for i, v in enumerate(node)]
            out = {}
            for k, v in node.items():
                if not isinstance(k, str):
                    raise CaseError(path + (k,), f"a key must be a name, got {_kind(k)}")
                out[str(k)] = _plain(v, path + (k,), count, open_)
            return out
        finally:
            open_.discard(id(node))
    if isinstance(node, bool) or node is None:
        return node
    for t in (int, float, str):
        if isinstance(node, t):
            return t(node)
    raise CaseError(path, f"{_kind(node)} is not a value a case holds")


def _kind(value) -> str:
    if isinstance(value, (datetime.date, datetime.datetime)):
        return f"a date ({value}; quote it for text)"
    if isinstance(value, (bytes, bytearray)):
        return "binary data"
    tag = getattr(value, "tag", None)
    tag = getattr(tag, "value", tag)
    if tag:
        return f"a value tagged {tag}"
    if isinstance(value, (str, int, float, bool)) or value is None:
        return repr(value)
    return f"a {type(value).__name__.removeprefix('Commented').lower()}"
