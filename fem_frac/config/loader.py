"""Read a case file: YAML 1.2 with line numbers -> command-line overrides -> :class:`Case`.

Every problem becomes a :class:`~fem_frac.errors.CaseError` carrying the key path; a
:class:`Source` turns that path back into ``file:line:col`` for the message.
"""

from __future__ import annotations

import difflib
import typing
from dataclasses import dataclass, field
from pathlib import Path

from pydantic import BaseModel, ValidationError

from ..errors import CaseError, FemFracError
from .schema import Case


class CaseErrors(FemFracError):
    """Several located case errors at once (all validation errors of one file)."""

    def __init__(self, errors: list[CaseError], source: Source):
        super().__init__("; ".join(e.message for e in errors))
        self.errors = errors
        self.source = source

    def lines(self) -> list[str]:
        return [self.source.format(e) for e in self.errors]


@dataclass
class Source:
    """Where each key of a case came from: a line of the file, or a ``--set`` override."""

    path: Path
    data: object  # ruamel CommentedMap after overrides
    overrides: dict[tuple, str] = field(default_factory=dict)

    def locate(self, loc: tuple) -> str:
        for key_path, text in self.overrides.items():
            if tuple(loc[: len(key_path)]) == key_path:
                return f"{self.path}: --set {text}"
        line, col = _position(self.data, loc)
        return f"{self.path}:{line}:{col}"

    def format(self, error: CaseError) -> str:
        return f"{self.locate(error.path)}: {format_key(error.path)}: {error.message}"


def format_key(loc: tuple) -> str:
    """``("boundary_conditions", 2, "traction")`` -> ``boundary_conditions[2].traction``."""
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out or "<case>"


def _position(data, loc: tuple) -> tuple[int, int]:
    """1-based (line, column) of the deepest key of ``loc`` present in the YAML tree."""
    node, pos = data, (0, 0)
    for part in loc:
        lc = getattr(node, "lc", None)
        if isinstance(node, dict) and part in node:
            if lc is not None:
                pos = lc.key(part)
            node = node[part]
        elif isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
            if lc is not None:
                pos = lc.item(part)
            node = node[part]
        # otherwise: a union tag inserted by pydantic, or a missing key (stay at the parent)
    return pos[0] + 1, pos[1] + 1


def _yaml():
    from ruamel.yaml import YAML

    y = YAML(typ="rt")  # round-trip keeps line numbers; YAML 1.2: `1e9` is a float
    y.allow_duplicate_keys = False
    return y


def read_yaml(path: Path):
    """Parse ``path`` keeping positions; YAML syntax errors become a located CaseError."""
    from ruamel.yaml.error import MarkedYAMLError, YAMLError

    try:
        text = path.read_text()
    except OSError as exc:
        raise FemFracError(f"{path}: cannot read case file: {exc.strerror}") from None
    try:
        data = _yaml().load(text)
    except MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"{path}:{mark.line + 1}:{mark.column + 1}" if mark else str(path)
        problem = " ".join(str(exc.problem or exc.context or "invalid YAML").split())
        raise FemFracError(f"{where}: YAML: {problem}") from None
    except YAMLError as exc:
        raise FemFracError(f"{path}: YAML: {' '.join(str(exc).split())}") from None
    if not isinstance(data, dict):
        raise FemFracError(f"{path}:1:1: the case file must be a mapping of sections")
    return data


def parse_override(text: str) -> tuple[tuple, object]:
    """``"material.youngs_modulus=3e8"`` -> (("material", "youngs_modulus"), 3e8).

    List items are addressed by index: ``boundary_conditions.1.pressure=2e6`` or
    ``boundary_conditions[1].pressure=2e6``. The value is parsed as YAML.
    """
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise FemFracError(f"--set {text}: expected KEY.PATH=VALUE")
    parts: list = []
    for piece in key.strip().replace("[", ".").replace("]", "").split("."):
        if not piece:
            raise FemFracError(f"--set {text}: empty key in '{key}'")
        parts.append(int(piece) if piece.isdigit() else piece)
    import io

    parsed = _yaml().load(io.StringIO(value)) if value.strip() else None
    return tuple(parts), parsed


def apply_override(data, key_path: tuple, value, text: str) -> None:
    node = data
    for i, part in enumerate(key_path[:-1]):
        nxt = key_path[i + 1]
        if isinstance(node, list):
            if not isinstance(part, int) or not 0 <= part < len(node):
                raise FemFracError(f"--set {text}: no item {part} in {format_key(key_path[:i])}")
            node = node[part]
            continue
        if part not in node or node[part] is None:
            node[part] = [] if isinstance(nxt, int) else {}
        node = node[part]
    last = key_path[-1]
    if isinstance(node, list):
        if not isinstance(last, int) or not 0 <= last < len(node):
            raise FemFracError(f"--set {text}: no item {last} in {format_key(key_path[:-1])}")
    node[last] = value


def plain_data(node):
    """ruamel's round-trip containers and scalar subclasses -> plain Python objects."""
    if isinstance(node, dict):
        return {str(k): plain_data(v) for k, v in node.items()}
    if isinstance(node, list):
        return [plain_data(v) for v in node]
    if isinstance(node, bool) or node is None:
        return node
    for t in (int, float, str):
        if isinstance(node, t):
            return t(node)
    return node


def load_case(path: str | Path, overrides: typing.Sequence[str] = ()) -> tuple[Case, Source]:
    """Parse, override and validate a case file. Raises ``CaseErrors`` / ``FemFracError``."""
    path = Path(path)
    data = read_yaml(path)
    source = Source(path=path, data=data)
    for text in overrides:
        key_path, value = parse_override(text)
        apply_override(data, key_path, value, text)
        source.overrides[key_path] = text
    plain = plain_data(data)
    try:
        case = Case.model_validate(plain)
    except ValidationError as exc:
        raise CaseErrors([case_error(e, plain) for e in exc.errors()], source) from None
    return case, source


# --- pydantic errors -> one-line messages -------------------------------------------------


def _strip_tags(loc: tuple, data) -> tuple:
    """Drop the union-member tag pydantic inserts after a discriminated union's position.

    The tag equals the ``type`` value of the mapping there, and comes first under it.
    """
    out: list = []
    node, fresh = data, True
    for part in loc:
        if isinstance(node, dict) and fresh and part == node.get("type"):
            fresh = False
            continue
        out.append(part)
        fresh = True
        if isinstance(node, dict):
            node = node.get(part)
        elif isinstance(node, list) and isinstance(part, int) and part < len(node):
            node = node[part]
        else:
            node = None
    return tuple(out)


def case_error(err: dict, data) -> CaseError:
    """One pydantic error (of validating ``data``) as a located one-line message."""
    loc = _strip_tags(tuple(err["loc"]), data)
    kind, ctx = err["type"], err.get("ctx", {})
    if kind == "missing" and loc and isinstance(loc[-1], int):
        return CaseError(loc[:-1], "must be a list of 3 numbers")
    if kind == "extra_forbidden":
        names = _field_names_at(data, loc[:-1])
        return CaseError(loc, "unknown key" + _did_you_mean(str(loc[-1]), names))
    if kind == "missing":
        return CaseError(loc, "required key is missing")
    if kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        op = {"greater_than": ">", "greater_than_equal": ">=", "less_than": "<"}.get(kind, "<=")
        bound = next(iter(ctx.values()))
        return CaseError(loc, f"must be {op} {bound:g}, got {_show(err['input'])}")
    if kind == "union_tag_invalid":
        expected = [t.strip(" '") for t in str(ctx.get("expected_tags", "")).split(",")]
        tag = ctx.get("tag")
        return CaseError(
            loc, f"unknown type {tag!r}" + _did_you_mean(str(tag), expected, always=True)
        )
    if kind == "union_tag_not_found":
        return CaseError(loc, "missing 'type' key")
    if kind == "literal_error":
        return CaseError(loc, f"must be one of {ctx.get('expected')}, got {err['input']!r}")
    if kind in ("float_parsing", "float_type", "int_parsing", "int_type"):
        return CaseError(loc, f"must be a number, got {err['input']!r}")
    if kind in ("tuple_type", "list_type"):
        return CaseError(loc, f"must be a list, got {err['input']!r}")
    if kind in ("too_short", "too_long"):
        return CaseError(loc, f"must have {_expected_length(ctx)} items, got {err['input']!r}")
    if kind == "model_type" or kind == "dict_type":
        return CaseError(loc, f"must be a mapping of keys, got {err['input']!r}")
    if kind == "value_error":
        return CaseError(loc, str(ctx.get("error", err["msg"])))
    return CaseError(loc, err["msg"][0].lower() + err["msg"][1:])


def _show(value) -> str:
    return f"{value:g}" if isinstance(value, float) else repr(value)


def _expected_length(ctx: dict) -> str:
    return str(ctx.get("max_length") or ctx.get("min_length") or "3")


def _did_you_mean(word: str, names: list[str], always: bool = False) -> str:
    close = difflib.get_close_matches(word, names, n=1, cutoff=0.6)
    if close:
        return f" (did you mean '{close[0]}'?)"
    if names and always:
        return f" (expected one of: {', '.join(names)})"
    return f" (allowed: {', '.join(names)})" if names else ""


def _field_names_at(data, loc: tuple) -> list[str]:
    """Field names of the model that validates the mapping at ``loc`` (union tags skipped)."""
    annotation: object = Case
    node = data
    for part in loc:
        model = _model_of(annotation, node)
        if isinstance(part, int):
            annotation = _list_item(annotation)
            node = node[part] if isinstance(node, list) and part < len(node) else None
        elif model is not None and part in model.model_fields:
            annotation = model.model_fields[part].annotation
            node = node.get(part) if isinstance(node, dict) else None
        # else: a union tag in the loc, which names the member _model_of picks anyway
    model = _model_of(annotation, node)
    return list(model.model_fields) if model is not None else []


def _members(annotation) -> list:
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _members(typing.get_args(annotation)[0])
    if origin is typing.Union or str(origin) == "<class 'types.UnionType'>":
        return [m for a in typing.get_args(annotation) for m in _members(a)]
    return [annotation]


def _list_item(annotation):
    for member in _members(annotation):
        if typing.get_origin(member) in (list, tuple):
            return typing.get_args(member)[0]
    return None


def _model_of(annotation, node) -> type[BaseModel] | None:
    models = [m for m in _members(annotation) if isinstance(m, type) and issubclass(m, BaseModel)]
    if len(models) > 1 and isinstance(node, dict):
        for m in models:
            tag = m.model_fields.get("type")
            if tag is not None and node.get("type") in typing.get_args(tag.annotation):
                return m
    return models[0] if models else None
