"""The study file: its model, its validation (located errors) and the runs of its grid."""

from __future__ import annotations

import difflib
import hashlib
import itertools
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from ...config.loader import Source, case_error, parse_override, plain_data, read_yaml
from ...errors import CaseError, FemFracError

SIZE_KEY = "mesh.element_size"


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class ErrorSpec(_Section):
    """``{quantity: NAME}``: a ``summary.json`` value (dotted path), compared with its
    Richardson extrapolation per method."""

    quantity: str = Field(min_length=1)


class StudyFile(_Section):
    """The study file as written (see :mod:`fem_frac.app.study` and docs/studies.md)."""

    title: str | None = None
    case: str = Field(min_length=1)
    method: list[str] = []
    grid: dict[str, list[Any]]
    error: ErrorSpec | None = None  # None: the case's declared reference
    workers: Annotated[int, Field(gt=0)] | None = None
    refinement: str = Field(
        default=SIZE_KEY,
        description="the grid key that is the discretization size h of rates and Richardson "
        "extrapolation: mesh.element_size (default) or analysis.dt for a time-step study",
    )

    @field_validator("error", mode="before")
    @classmethod
    def _error(cls, v):
        if v == "reference" or v is None:
            return None
        if isinstance(v, str):
            raise ValueError(f"must be 'reference' or {{quantity: NAME}}, got {v!r}")
        return v


@dataclass(frozen=True)
class Axis:
    """One grid axis: one key, or several keys varied together (``"a.b,c.d"``)."""

    name: str
    keys: tuple[str, ...]
    values: tuple[tuple, ...]  # one tuple of len(keys) per point of the axis


@dataclass(frozen=True)
class Run:
    """One combination of the grid."""

    index: int
    run_id: str
    settings: dict  # key -> value, in grid order
    overrides: tuple[str, ...]
    method: str
    size_key: str = SIZE_KEY

    @property
    def size(self) -> float | None:
        v = self.settings.get(self.size_key)
        return float(v) if isinstance(v, int | float) else None


@dataclass
class Study:
    path: Path
    spec: StudyFile
    axes: list[Axis]
    runs: list[Run]
    source: Source

    @property
    def case_path(self) -> Path:
        return self.path.parent / self.spec.case

    @property
    def name(self) -> str:
        return self.path.stem

    @property
    def keys(self) -> list[str]:
        return [k for a in self.axes for k in a.keys]

    @property
    def quantity(self) -> str | None:
        return self.spec.error.quantity if self.spec.error is not None else None


def value_text(value) -> str:
    """A grid value as YAML for ``--set`` (JSON is YAML)."""
    return json.dumps(value)


def run_id(settings: dict) -> str:
    """A stable, file-name-safe id from the run's settings: ``mesh.order=2_mesh.element_size=0.02``.

    It is a plain directory name (the run's directory under ``runs/``): characters outside
    ``[A-Za-z0-9.=+-_]`` (``/`` among them) become ``-``, and an id that would start with
    ``.`` or ``-`` (``..``, a hidden name, an option) starts with ``run_``; a short hash of
    the exact settings is appended when that loses information, so different settings never
    share an id.
    """
    text = "_".join(f"{k}={value_text(v).strip(chr(34))}" for k, v in settings.items())
    safe = re.sub(r"[^A-Za-z0-9.=+\-_]", "-", text)
    if not safe or safe.startswith((".", "-")):
        safe = f"run_{safe}"
    if safe != text or len(safe) > 120:
        digest = hashlib.sha1(json.dumps(settings, sort_keys=True).encode()).hexdigest()[:8]
        safe = f"{safe[:110]}_{digest}"
    return safe


def _short(key: str) -> str:
    return key.replace("[", ".").replace("]", "").split(".")[-1]


def method_label(settings: dict, method_keys: list[str]) -> str:
    if not method_keys:
        return "all runs"
    parts = []
    for k in method_keys:
        text = value_text(settings[k]).strip('"')
        parts.append(f"P{text}" if k == "mesh.order" else f"{_short(k)}={text}")
    return ", ".join(parts)


class StudyErrors(FemFracError):
    def __init__(self, errors: list[CaseError], source: Source):
        super().__init__("; ".join(e.message for e in errors))
        self.errors, self.source = errors, source

    def lines(self) -> list[str]:
        return [self.source.format(e) for e in self.errors]


def _study_error(err: dict, data) -> CaseError:
    if err["type"] == "extra_forbidden":
        loc = tuple(err["loc"])
        model = ErrorSpec if loc[:1] == ("error",) else StudyFile
        close = difflib.get_close_matches(str(loc[-1]), list(model.model_fields), n=1)
        hint = (f" (did you mean '{close[0]}'?)" if close
                else f" (allowed: {', '.join(model.model_fields)})")
        return CaseError(loc, "unknown key" + hint)
    return case_error(err, data)


def load_study(path: str | Path) -> Study:
    """Read and validate a study file, expand its grid. Raises ``StudyErrors`` (located)."""
    path = Path(path)
    data = read_yaml(path)
    source = Source(path=path, data=data)
    plain = plain_data(data)
    try:
        spec = StudyFile.model_validate(plain)
    except ValidationError as exc:
        raise StudyErrors([_study_error(e, plain) for e in exc.errors()], source) from None
    errors: list[CaseError] = []
    axes = _axes(spec, errors)
    method_keys = _method_keys(spec, axes, errors)
    _check_case(spec, path.parent / spec.case, [k for a in axes for k in a.keys], errors)
    if errors:
        raise StudyErrors(errors, source)
    return Study(path, spec, axes, _expand(spec, axes, method_keys), source)


def _axes(spec: StudyFile, errors: list[CaseError]) -> list[Axis]:
    """The axes of ``grid``; problems are appended to ``errors``."""
    axes: list[Axis] = []
    if not spec.grid:
        errors.append(CaseError(("grid",), "must name at least one key to vary"))
    for name, values in spec.grid.items():
        keys = tuple(k.strip() for k in name.split(","))
        try:
            for k in keys:
                parse_override(f"{k}=0")
        except FemFracError:
            errors.append(CaseError(("grid", name), "not a key path like mesh.element_size"))
            continue
        if not values:
            errors.append(CaseError(("grid", name), "must list at least one value"))
            axes.append(Axis(name, keys, ()))
            continue
        points = []
        for i, v in enumerate(values):
            if len(keys) == 1:
                points.append((v,))
            elif isinstance(v, list) and len(v) == len(keys):
                points.append(tuple(v))
            else:
                errors.append(CaseError(("grid", name, i),
                                        f"must be a list of {len(keys)} values, one per key"))
        if len(set(map(value_text, points))) != len(points):
            errors.append(CaseError(("grid", name), "lists a value twice"))
        axes.append(Axis(name, keys, tuple(points)))
    all_keys = [k for a in axes for k in a.keys]
    if len(set(all_keys)) != len(all_keys):
        errors.append(CaseError(("grid",), "a key appears in two axes"))
    return axes


def _method_keys(spec: StudyFile, axes: list[Axis], errors: list[CaseError]) -> list[str]:
    """The grid keys named by ``method`` (an axis of several keys by its grid name)."""
    all_keys = [k for a in axes for k in a.keys]
    by_axis = {a.name: a.keys for a in axes}
    method_keys: list[str] = []
    for i, m in enumerate(spec.method):
        if m in by_axis:
            method_keys += [k for k in by_axis[m] if k not in method_keys]
        elif m in all_keys:
            method_keys += [m] if m not in method_keys else []
        else:
            errors.append(CaseError(("method", i), f"{m!r} is not a key of grid"
                                    + (f" (grid keys: {', '.join(all_keys)})" if all_keys else "")))
    return method_keys


def _check_case(spec: StudyFile, case_path: Path, all_keys: list[str],
                errors: list[CaseError]) -> None:
    """The case file exists and, for ``error: reference``, declares a reference solution."""
    if not case_path.is_file():
        errors.append(CaseError(("case",), f"no such case file: {case_path}"))
    elif spec.error is None and not any(k.startswith("reference") for k in all_keys):
        from ...config import load_case

        case, _ = load_case(case_path)
        if case.reference is None:
            errors.append(CaseError(
                ("error",), f"the case {spec.case} declares no reference solution; add "
                "reference: {solution: ...} to it or use error: {quantity: NAME}"))


def _expand(spec: StudyFile, axes: list[Axis], method_keys: list[str]) -> list[Run]:
    """Every combination of the axes, in grid order."""
    runs = []
    for index, combo in enumerate(itertools.product(*(a.values for a in axes))):
        settings = {k: v for a, point in zip(axes, combo, strict=True)
                    for k, v in zip(a.keys, point, strict=True)}
        runs.append(Run(
            index=index,
            run_id=run_id(settings),
            settings=settings,
            overrides=tuple(f"{k}={value_text(v)}" for k, v in settings.items()),
            method=method_label(settings, method_keys),
            size_key=spec.refinement,
        ))
    return runs
