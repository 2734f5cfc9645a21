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
from .safe_yaml import MAX_DEPTH, load_yaml, plain_data, read_text, shorten
from .schema import Case


class CaseErrors(FemFracError):
    """Several located case errors at once (all validation errors of one file), in the
    order of their place in the file (``--set`` overrides last)."""

    def __init__(self, errors: list[CaseError], source: Source):
        errors = sorted(errors, key=lambda e: source.order(e.path))
        super().__init__("; ".join(e.message for e in errors))
        self.errors = errors
        self.source = source

    def lines(self) -> list[str]:
        return [self.source.format(e) for e in self.errors]

    def line(self) -> str:
        """The first error, and how many more there are: one line."""
        more = len(self.errors) - 1
        return self.lines()[0] + (f" (and {more} more error{'s' * (more > 1)})" if more
                                  else "")


@dataclass
class Source:
    """Where each key of a case came from: a line of the file, or a ``--set`` override
    (which also owns the mappings and lists it had to create on its way)."""

    path: Path
    data: object  # ruamel CommentedMap after overrides
    overrides: dict[tuple, str] = field(default_factory=dict)
    created: dict[tuple, str] = field(default_factory=dict)

    def _override(self, loc: tuple) -> str | None:
        for table in (self.overrides, self.created):
            for key_path, text in table.items():
                if tuple(loc[: len(key_path)]) == key_path:
                    return text
        return None

    def locate(self, loc: tuple) -> str:
        text = self._override(loc)
        if text is not None:
            return f"{self.path}: --set {shorten(text)}"
        line, col = _position(self.data, loc)
        return f"{self.path}:{line}:{col}"

    def order(self, loc: tuple) -> tuple:
        """A sort key: place in the file, overrides after every line."""
        text = self._override(loc)
        if text is not None:
            return (1, list(self.overrides.values()).index(text)
                    if text in self.overrides.values() else 0, 0)
        return (0, *_position(self.data, loc))

    def format(self, error: CaseError) -> str:
        return f"{self.locate(error.path)}: {format_key(error.path)}: {error.message}"


def format_key(loc: tuple) -> str:
    """``("boundary_conditions", 2, "traction")`` -> ``boundary_conditions[2].traction``."""
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out or "<case>"


def _position(data, loc: tuple) -> tuple[int, int]:
    """1-based (line, column) of the deepest key of ``loc`` present in the YAML tree (keys
    an override added have no position: their parent's is kept)."""
    node, pos = data, (0, 0)
    for part in loc:
        lc = getattr(node, "lc", None)
        if isinstance(node, dict) and part in node:
            try:
                pos = lc.key(part) if lc is not None else pos
            except (KeyError, TypeError):
                pass
            node = node[part]
        elif isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
            try:
                pos = lc.item(part) if lc is not None else pos
            except (KeyError, IndexError, TypeError):
                pass
            node = node[part]
        # otherwise: a union tag inserted by pydantic, or a missing key (stay at the parent)
    return pos[0] + 1, pos[1] + 1


def read_yaml(path: Path):
    """Parse ``path`` keeping positions; every problem (size, encoding, syntax, nesting)
    becomes a located :class:`FemFracError`."""
    data = load_yaml(read_text(path), str(path))
    if not isinstance(data, dict):
        raise FemFracError(f"{path}:1:1: the case file must be a mapping of sections")
    return data


def parse_override(text: str) -> tuple[tuple, object]:
    """``"material.youngs_modulus=3e8"`` -> (("material", "youngs_modulus"), 3e8).

    List items are addressed by index: ``boundary_conditions.1.pressure=2e6`` or
    ``boundary_conditions[1].pressure=2e6``. The value is parsed as YAML. Raises
    :class:`FemFracError` naming the option.
    """
    key, sep, value = text.partition("=")
    option = f"--set {shorten(text)}"
    if not sep or not key.strip():
        raise FemFracError(f"{option}: expected KEY.PATH=VALUE")
    parts: list = []
    for piece in key.strip().replace("[", ".").replace("]", "").split("."):
        if not piece.strip():
            raise FemFracError(f"{option}: empty key in '{shorten(key)}'")
        parts.append(int(piece) if piece.isdigit() and piece.isascii() else piece.strip())
    if len(parts) > MAX_DEPTH:
        raise FemFracError(f"{option}: a key path of more than {MAX_DEPTH} parts")
    parsed = load_yaml(value, option) if value.strip() else None
    return tuple(parts), parsed


def apply_override(data, key_path: tuple, value, text: str) -> list[tuple]:
    """Set ``key_path`` of ``data`` to ``value``, creating the mappings (or lists) on the
    way that are absent; returns the paths of those it created."""
    node, created, option = data, [], f"--set {shorten(text)}"
    for i, part in enumerate(key_path):
        here = format_key(key_path[:i]) if i else "the case"
        if isinstance(node, list):
            if not isinstance(part, int) or not 0 <= part < len(node):
                raise FemFracError(f"{option}: {here} has no item {part} "
                                   f"(it has {len(node)})")
        elif isinstance(node, dict):
            part = str(part)
        else:
            raise FemFracError(f"{option}: {here} holds {_what(node)}, not a mapping of "
                               f"keys or a list")
        if i == len(key_path) - 1:
            node[part] = value
        else:
            if isinstance(node, dict) and node.get(part) is None:
                node[part] = [] if isinstance(key_path[i + 1], int) else {}
                created.append(key_path[: i + 1])
            node = node[part]
    return created


def _what(node) -> str:
    if isinstance(node, bool):
        return f"{str(node).lower()}"
    if isinstance(node, (int, float)):
        return f"a number ({node})"
    if isinstance(node, str):
        return f"a string ({node[:40]!r})"
    return f"a value of type {type(node).__name__}"


def load_case(path: str | Path, overrides: typing.Sequence[str] = ()) -> tuple[Case, Source]:
    """Parse, override and validate a case file. Raises ``CaseErrors`` / ``FemFracError``
    (and a located ``CaseError`` for a value no case holds: ``Source`` places it)."""
    path = Path(path)
    data = read_yaml(path)
    source = Source(path=path, data=data)
    for text in overrides:
        try:
            key_path, value = parse_override(text)
            created = apply_override(data, key_path, value, text)
        except FemFracError as exc:
            raise FemFracError(f"{path}: {exc}") from None
        source.overrides[key_path] = text
        source.created.update({p: text for p in created})
    try:
        plain = plain_data(data)
    except CaseError as exc:
        raise CaseErrors([exc], source) from None
    try:
        case = Case.model_validate(plain)
    except ValidationError as exc:
        errors = _without_misspelt_missing(exc.errors(), plain)
        raise CaseErrors([case_error(e, plain) for e in errors], source) from None
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


def _without_misspelt_missing(errors: list[dict], data) -> list[dict]:
    """A misspelt key is one error, at the key: drop the "missing" error of the key it
    resembles, next to it (``mehs:`` is not also ``mesh: required key is missing``)."""
    extras: dict[tuple, list[str]] = {}
    for e in errors:
        if e["type"] == "extra_forbidden":
            loc = _strip_tags(tuple(e["loc"]), data)
            extras.setdefault(loc[:-1], []).append(str(loc[-1]))
    out = []
    for e in errors:
        loc = _strip_tags(tuple(e["loc"]), data)
        if (e["type"] == "missing" and loc and isinstance(loc[-1], str)
                and difflib.get_close_matches(loc[-1], extras.get(loc[:-1], []), n=1,
                                              cutoff=0.6)):
            continue
        out.append(e)
    return out


_BOUNDS = {"greater_than": ">", "greater_than_equal": ">=", "less_than": "<",
           "less_than_equal": "<="}


def case_error(err: dict, data) -> CaseError:
    """One pydantic error (of validating ``data``) as a located one-line message."""
    loc = _strip_tags(tuple(err["loc"]), data)
    kind, ctx, got = err["type"], err.get("ctx", {}), _show(err.get("input"))
    if kind == "missing" and loc and isinstance(loc[-1], int):
        return CaseError(loc[:-1], "must be a list of 3 numbers")
    if kind == "extra_forbidden":
        names = _field_names_at(data, loc[:-1])
        return CaseError(loc, "unknown key" + _did_you_mean(str(loc[-1]), names))
    if kind == "missing":
        return CaseError(loc, "required key is missing")
    if kind in _BOUNDS:
        bound = next(iter(ctx.values()))
        return CaseError(loc, f"must be {_BOUNDS[kind]} {_show(bound)}, got {got}")
    if kind == "union_tag_invalid":
        expected = [t.strip(" '") for t in str(ctx.get("expected_tags", "")).split(",")]
        tag = ctx.get("tag")
        return CaseError(
            loc, f"unknown type {_show(tag)}" + _did_you_mean(str(tag), expected, always=True)
        )
    if kind == "union_tag_not_found":
        return _missing_type(data, loc)
    messages = {
        "literal_error": f"must be one of {ctx.get('expected')}, got {got}",
        "finite_number": f"must be a finite number, got {got}",
        "bool_type": f"must be true or false, got {got}",
        "string_type": f"must be text, got {got}",
        "tuple_type": f"must be a list, got {got}",
        "list_type": f"must be a list, got {got}",
        "too_short": f"must have {_expected_length(ctx)} items, got {got}",
        "too_long": f"must have {_expected_length(ctx)} items, got {got}",
        "model_type": f"must be a mapping of keys, got {got}",
        "model_attributes_type": f"must be a mapping of keys, got {got}",
        "dict_type": f"must be a mapping of keys, got {got}",
        "int_type": f"must be a whole number, got {got}",
        "int_from_float": f"must be a whole number, got {got}",
    }
    if kind in messages:
        return CaseError(loc, messages[kind])
    if kind in ("float_parsing", "float_type", "int_parsing"):
        return CaseError(loc, f"must be a number, got {got}")
    if kind == "value_error":
        return CaseError(loc, str(ctx.get("error", err["msg"])))
    return CaseError(loc, err["msg"][0].lower() + err["msg"][1:])


def _show(value) -> str:
    """A value for a one-line message: YAML spelling, long ones cut."""
    if isinstance(value, bool) or value is None:
        return {True: "true", False: "false", None: "null"}[value]
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, int):
        if abs(value) < 10**20:
            return str(value)
        return f"an integer of {value.bit_length() * 0.30103:.0f} digits"
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _missing_type(data, loc: tuple) -> CaseError:
    """What to write as ``type:`` where a section says none (at a misspelt ``type`` key,
    if there is one)."""
    node = data
    for part in loc:
        node = node.get(part) if isinstance(node, dict) else (
            node[part] if isinstance(node, list) and isinstance(part, int)
            and 0 <= part < len(node) else None)
    keys = [str(k) for k in node] if isinstance(node, dict) else []
    close = difflib.get_close_matches("type", keys, n=1, cutoff=0.6)
    if close:
        return CaseError(loc + (close[0],), "unknown key (did you mean 'type'?)")
    if loc == ("analysis",) and {"t_end", "dt", "steps"} & set(keys):
        return CaseError(loc, "missing 'type' key: t_end, dt and steps are for 'type: "
                         "quasi_static' (load steps) or 'type: dynamic' (with inertia); "
                         "without a type the analysis is one static step")
    tags = [t for m in _members(_annotation_at(data, loc)[0]) if isinstance(m, type)
            and issubclass(m, BaseModel) and "type" in m.model_fields
            for t in typing.get_args(m.model_fields["type"].annotation)]
    return CaseError(loc, "missing 'type' key" + (f" (one of: {', '.join(tags)})" if tags
                                                   else ""))


def _expected_length(ctx: dict) -> str:
    return str(ctx.get("max_length") or ctx.get("min_length") or "3")


def _did_you_mean(word: str, names: list[str], always: bool = False) -> str:
    close = difflib.get_close_matches(word, names, n=1, cutoff=0.6)
    if close:
        return f" (did you mean '{close[0]}'?)"
    if names and always:
        return f" (expected one of: {', '.join(names)})"
    return f" (allowed: {', '.join(names)})" if names else ""


def _annotation_at(data, loc: tuple) -> tuple[object, object]:
    """The annotation that validates the value at ``loc`` (union tags skipped), and the
    value."""
    annotation: object = Case
    node = data
    for part in loc:
        model = _model_of(annotation, node)
        if isinstance(part, int):
            annotation = _list_item(annotation)
            node = node[part] if isinstance(node, list) and 0 <= part < len(node) else None
        elif model is not None and part in model.model_fields:
            annotation = model.model_fields[part].annotation
            node = node.get(part) if isinstance(node, dict) else None
        elif model is None and _dict_value(annotation) is not None:
            annotation = _dict_value(annotation)
            node = node.get(part) if isinstance(node, dict) else None
        # else: a union tag in the loc, which names the member _model_of picks anyway
    return annotation, node


def _field_names_at(data, loc: tuple) -> list[str]:
    """Field names of the model that validates the mapping at ``loc`` (union tags skipped)."""
    model = _model_of(*_annotation_at(data, loc))
    return list(model.model_fields) if model is not None else []


def _dict_value(annotation):
    for member in _members(annotation):
        if typing.get_origin(member) is dict:
            return typing.get_args(member)[1]
    return None


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
