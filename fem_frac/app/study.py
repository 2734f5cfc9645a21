"""Parameter studies: ``fem-frac study STUDY.yaml``.

A study sweeps a base case over a grid of settings. Every combination of the grid is one
run: its values are applied as ``--set`` overrides and the run goes through exactly the
code path of ``fem-frac run`` (:func:`fem_frac.app.cli.main`), in a fresh process of its own so
that its peak resident memory (``ru_maxrss``) is its own. The study writes

- ``runs/<run id>/``: the output of each run (``summary.json``, ``.pvd``, ...);
- ``study.csv``: one row per run (grid values, method, dofs, wall time total and per stage,
  peak memory, error, status);
- ``study.json``: the fitted convergence rate of each method, the reference values used and
  the Pareto front;
- ``study.png``: error against wall time, log-log, one line per method (needs matplotlib).

A study is resumable: a run whose ``summary.json`` exists is not run again. A failed run is
recorded (exit code and message) and does not stop the study.

The error of a run is either the relative error against the exact solution the case
declares (``error: reference``, from ``summary.json``), or, for ``error: {quantity: NAME}``,
the relative difference of a summary quantity from a reference value estimated per method
by Richardson extrapolation of its three finest runs (:func:`richardson`).
"""

from __future__ import annotations

import contextlib
import csv
import difflib
import hashlib
import io
import itertools
import json
import math
import os
import re
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from ..config.loader import Source, _case_error, parse_override, read_yaml
from ..errors import CaseError, FemFracError

SIZE_KEY = "mesh.element_size"
MATPLOTLIB_HINT = (
    "matplotlib is not installed, so study.png was not written (study.csv was); "
    "install it with: pip install 'fem-frac[study]'  (or: pip install matplotlib)"
)

# --- the study file -------------------------------------------------------------------------


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class ErrorSpec(_Section):
    """``{quantity: NAME}``: a ``summary.json`` value (dotted path), compared with its
    Richardson extrapolation per method."""

    quantity: str = Field(min_length=1)


class StudyFile(_Section):
    """The study file as written (see the module docstring and docs/studies.md)."""

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


def _value_text(value) -> str:
    """A grid value as YAML for ``--set`` (JSON is YAML)."""
    return json.dumps(value)


def run_id(settings: dict) -> str:
    """A stable, file-name-safe id from the run's settings: ``mesh.order=2_mesh.element_size=0.02``.

    Characters outside ``[A-Za-z0-9.=+-]`` become ``-``; a short hash of the exact settings
    is appended when that loses information, so different settings never share an id.
    """
    text = "_".join(f"{k}={_value_text(v).strip(chr(34))}" for k, v in settings.items())
    safe = re.sub(r"[^A-Za-z0-9.=+\-_]", "-", text)
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
        text = _value_text(settings[k]).strip('"')
        parts.append(f"P{text}" if k == "mesh.order" else f"{_short(k)}={text}")
    return ", ".join(parts)


def _study_error(err: dict, data) -> CaseError:
    if err["type"] == "extra_forbidden":
        loc = tuple(err["loc"])
        model = ErrorSpec if loc[:1] == ("error",) else StudyFile
        close = difflib.get_close_matches(str(loc[-1]), list(model.model_fields), n=1)
        hint = (f" (did you mean '{close[0]}'?)" if close
                else f" (allowed: {', '.join(model.model_fields)})")
        return CaseError(loc, "unknown key" + hint)
    return _case_error(err, data)


class StudyErrors(FemFracError):
    def __init__(self, errors: list[CaseError], source: Source):
        super().__init__("; ".join(e.message for e in errors))
        self.errors, self.source = errors, source

    def lines(self) -> list[str]:
        return [self.source.format(e) for e in self.errors]


def load_study(path: str | Path) -> Study:
    """Read and validate a study file, expand its grid. Raises ``StudyErrors`` (located)."""
    from ..config.loader import _plain

    path = Path(path)
    data = read_yaml(path)
    source = Source(path=path, data=data)
    plain = _plain(data)
    try:
        spec = StudyFile.model_validate(plain)
    except ValidationError as exc:
        raise StudyErrors([_study_error(e, plain) for e in exc.errors()], source) from None
    errors: list[CaseError] = []
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
        if len(set(map(_value_text, points))) != len(points):
            errors.append(CaseError(("grid", name), "lists a value twice"))
        axes.append(Axis(name, keys, tuple(points)))
    all_keys = [k for a in axes for k in a.keys]
    by_axis = {a.name: a.keys for a in axes}
    method_keys: list[str] = []
    for i, m in enumerate(spec.method):
        if m in by_axis:  # an axis of several keys, named as in grid
            method_keys += [k for k in by_axis[m] if k not in method_keys]
        elif m in all_keys:
            method_keys += [m] if m not in method_keys else []
        else:
            errors.append(CaseError(("method", i), f"{m!r} is not a key of grid"
                                    + (f" (grid keys: {', '.join(all_keys)})" if all_keys else "")))
    if len(set(all_keys)) != len(all_keys):
        errors.append(CaseError(("grid",), "a key appears in two axes"))
    case_path = path.parent / spec.case
    if not case_path.is_file():
        errors.append(CaseError(("case",), f"no such case file: {case_path}"))
    elif spec.error is None and not any(k.startswith("reference") for k in all_keys):
        from ..config import load_case

        case, _ = load_case(case_path)
        if case.reference is None:
            errors.append(CaseError(
                ("error",), f"the case {spec.case} declares no reference solution; add "
                "reference: {solution: ...} to it or use error: {quantity: NAME}"))
    if errors:
        raise StudyErrors(errors, source)
    runs = []
    for index, combo in enumerate(itertools.product(*(a.values for a in axes))):
        settings = {k: v for a, point in zip(axes, combo, strict=True)
                    for k, v in zip(a.keys, point, strict=True)}
        runs.append(Run(
            index=index,
            run_id=run_id(settings),
            settings=settings,
            overrides=tuple(f"{k}={_value_text(v)}" for k, v in settings.items()),
            method=method_label(settings, method_keys),
            size_key=spec.refinement,
        ))
    return Study(path, spec, axes, runs, source)


# --- running ---------------------------------------------------------------------------------


def _peak_mib() -> float:
    import resource

    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / (1024 * 1024) if sys.platform == "darwin" else rss / 1024  # bytes vs KiB


def execute(case_path: str, run_dir: str, overrides: tuple[str, ...]) -> dict:
    """Run one case as ``fem-frac run`` does; meant for a fresh process of its own.

    Returns ``{exit_code, message, peak_mib, process_s}`` and writes it to
    ``run_dir/study_run.json``.
    """
    from .cli import main

    t0 = time.perf_counter()
    err = io.StringIO()
    argv = ["run", case_path, "-o", run_dir, "-q", "--overwrite"]
    for o in overrides:
        argv += ["--set", o]
    with contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except Exception as exc:  # a bug, not an input error: record it all the same
            code = 1
            print(f"error: {type(exc).__name__}: {exc}", file=sys.stderr)
    lines = [ln for ln in err.getvalue().splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("error:")]
    message = (errors[-1] if errors else (lines[-1] if lines and code else ""))
    record = {"exit_code": code, "message": message.removeprefix("error: "),
              "peak_mib": round(_peak_mib(), 1),
              "process_s": round(time.perf_counter() - t0, 3)}
    if Path(run_dir).is_dir():
        (Path(run_dir) / "study_run.json").write_text(json.dumps(record, indent=2) + "\n")
    return record


def _executor(workers: int):
    import concurrent.futures as cf
    import multiprocessing as mp

    if sys.version_info >= (3, 11):
        # a fresh process per run: its ru_maxrss is its own peak
        return cf.ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn"),
                                      max_tasks_per_child=1)
    return _FreshProcessPool(workers)


class _FreshProcessPool:
    """Python 3.10 (no ``max_tasks_per_child``): threads, each running one run in a
    one-process pool of its own."""

    def __init__(self, workers: int):
        import concurrent.futures as cf

        self.threads = cf.ThreadPoolExecutor(workers)

    def _one(self, fn, *args):
        import concurrent.futures as cf
        import multiprocessing as mp

        with cf.ProcessPoolExecutor(1, mp_context=mp.get_context("spawn")) as pool:
            return pool.submit(fn, *args).result()

    def submit(self, fn, *args):
        return self.threads.submit(self._one, fn, *args)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.threads.shutdown(wait=True, cancel_futures=True)


@dataclass
class Result:
    run: Run
    status: str  # "ok", "skipped" (done earlier), "failed"
    exit_code: int | None = None
    message: str = ""
    peak_mib: float | None = None
    summary: dict | None = None
    value: float | None = None  # the study quantity of this run
    reference: float | None = None  # the value it is compared with
    error: float | None = None

    @property
    def ok(self) -> bool:
        return self.summary is not None

    @property
    def wall_s(self) -> float | None:
        return self.summary["wall_time_s"]["total"] if self.summary else None

    @property
    def dofs(self) -> int | None:
        return self.summary["counts"]["dofs"] if self.summary else None

    @property
    def h(self) -> float | None:
        """Discretization size of the run: the study's ``refinement`` key if swept (default
        ``mesh.element_size``), else dofs^(-1/3)."""
        if self.run.size is not None:
            return self.run.size
        return self.dofs ** (-1 / 3) if self.dofs else None


def _load_summary(run_dir: Path) -> dict | None:
    p = run_dir / "summary.json"
    if not p.is_file():
        return None
    try:
        return json.loads(p.read_text())
    except (OSError, ValueError):
        return None


def _record(run_dir: Path) -> dict:
    try:
        return json.loads((run_dir / "study_run.json").read_text())
    except (OSError, ValueError):
        return {}


def run_study(study: Study, out_dir: Path, workers: int | None = None,
              log: Callable[[str], None] = lambda _m: None) -> list[Result]:
    """Run every run of the study not finished earlier; returns the results in grid order."""
    runs_dir = out_dir / "runs"
    runs_dir.mkdir(parents=True, exist_ok=True)
    n = len(study.runs)
    results: dict[int, Result] = {}
    todo = []
    done = 0
    for run in study.runs:
        summary = _load_summary(runs_dir / run.run_id)
        if summary is not None:
            rec = _record(runs_dir / run.run_id)
            results[run.index] = Result(run, "skipped", 0, "", rec.get("peak_mib"), summary)
        else:
            todo.append(run)
    if study.quantity is None:
        _evaluate(study, list(results.values()))
    for r in results.values():
        done += 1
        log(_progress(done, n, r))
    workers = workers or study.spec.workers or os.cpu_count() or 1
    workers = max(1, min(workers, len(todo) or 1))
    if todo:
        import concurrent.futures as cf

        case_path = str(study.case_path)
        with _executor(workers) as pool:
            futures = {pool.submit(execute, case_path, str(runs_dir / run.run_id),
                                   run.overrides): run for run in todo}
            for fut in cf.as_completed(futures):
                run = futures[fut]
                try:
                    rec = fut.result()
                except Exception as exc:  # the process died (memory, signal)
                    rec = {"exit_code": None, "message": f"worker died: {exc!r}"}
                summary = _load_summary(runs_dir / run.run_id) if rec["exit_code"] == 0 else None
                res = Result(run, "ok" if summary else "failed", rec["exit_code"],
                             rec.get("message", ""), rec.get("peak_mib"), summary)
                if rec["exit_code"] == 0 and summary is None:
                    res.message = "exit 0 but no summary.json"
                results[run.index] = res
                if study.quantity is None:
                    _evaluate(study, [res])
                elif res.ok:
                    res.value = summary_value(res.summary, study.quantity)
                done += 1
                log(_progress(done, n, res))
    ordered = [results[r.index] for r in study.runs]
    _evaluate(study, ordered)
    return ordered


def _progress(i: int, n: int, r: Result) -> str:
    width = len(str(n))
    head = f"run {i:>{width}}/{n}  {r.run.run_id}"
    if not r.ok:
        code = f"exit {r.exit_code}" if r.exit_code is not None else "crashed"
        return f"{head}  FAILED ({code}): {r.message}"
    if r.error is not None:
        err = f"error {r.error:.3e}"
    else:
        err = f"value {r.value:.6g}" if r.value is not None else ""
    extra = "  (done earlier, kept)" if r.status == "skipped" else ""
    return f"{head}  {r.wall_s:7.2f} s  {err}{extra}"


# --- errors: the declared reference, or Richardson extrapolation ------------------------------


@dataclass(frozen=True)
class Extrapolation:
    """Reference value of a quantity from a sequence of refined runs."""

    value: float
    method: str  # "richardson" or "finest"
    order: float | None = None  # observed order p
    ratio: float | None = None  # refinement ratio r of the three finest runs
    note: str = ""


def richardson(h, q, rtol: float = 1e-3) -> Extrapolation:
    """Richardson extrapolation of ``q(h)`` from the three finest of the runs ``(h, q)``.

    With h1 > h2 > h3 (coarse to fine) in a constant ratio r = h1/h2 = h2/h3 and
    q = q* + C h^p: observed order p = log((q1 - q2)/(q2 - q3)) / log r and
    q* = q3 - (q2 - q3)/(r^p - 1). When the ratio is not constant (to ``rtol``), or the
    differences do not shrink monotonically, the finest run is the reference.
    """
    h = np.asarray(h, dtype=float)
    q = np.asarray(q, dtype=float)
    keep = np.isfinite(h) & np.isfinite(q)
    h, q = h[keep], q[keep]
    if len(h) == 0:
        return Extrapolation(math.nan, "finest", note="no runs")
    order = np.argsort(-h, kind="stable")
    h, q = h[order], q[order]
    finest = float(q[-1])
    if len(h) < 3:
        return Extrapolation(finest, "finest", note="fewer than three runs")
    (h1, h2, h3), (q1, q2, q3) = h[-3:], q[-3:]
    r1, r2 = h1 / h2, h2 / h3
    if not (r1 > 1 and r2 > 1) or abs(r1 / r2 - 1) > rtol:
        return Extrapolation(finest, "finest",
                             note=f"refinement ratios {r1:.4g}, {r2:.4g} are not equal")
    d1, d2 = q1 - q2, q2 - q3
    if d2 == 0 or d1 / d2 <= 1:
        return Extrapolation(finest, "finest",
                             note="differences do not shrink monotonically")
    r = math.sqrt(r1 * r2)
    p = math.log(d1 / d2) / math.log(r)
    return Extrapolation(q3 - d2 / (r**p - 1), "richardson", order=p, ratio=r)


def summary_value(summary: dict, quantity: str) -> float | None:
    """``summary.json`` value at a dotted path (``max_displacement``,
    ``reference.computed``, ``reaction_force.inner.0``)."""
    node: Any = summary
    for part in quantity.split("."):
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        else:
            return None
    return float(node) if isinstance(node, int | float) and not isinstance(node, bool) else None


def _evaluate(study: Study, results: list[Result]) -> dict[str, Extrapolation]:
    """Fill ``value``, ``reference`` and ``error`` of the successful results."""
    ok = [r for r in results if r.ok]
    if study.quantity is None:
        for r in ok:
            ref = r.summary.get("reference")
            if ref is not None:
                r.value, r.reference = ref["computed"], ref["exact"]
                r.error = abs(float(ref["relative_error"]))
        return {}
    refs: dict[str, Extrapolation] = {}
    for r in ok:
        r.value = summary_value(r.summary, study.quantity)
    for method in dict.fromkeys(r.run.method for r in ok):
        group = [r for r in ok if r.run.method == method and r.value is not None]
        if not group:
            continue
        ex = richardson([r.h for r in group], [r.value for r in group])
        refs[method] = ex
        for r in group:
            r.reference = ex.value
            if ex.value != 0 and math.isfinite(ex.value):
                r.error = abs(r.value - ex.value) / abs(ex.value)
    return refs


# --- rates, Pareto front ----------------------------------------------------------------------


def convergence_rate(h, error) -> float | None:
    """Slope of log(error) against log(h) (least squares); None below two usable points."""
    h, e = np.asarray(h, dtype=float), np.asarray(error, dtype=float)
    keep = np.isfinite(h) & np.isfinite(e) & (h > 0) & (e > 0)
    if np.count_nonzero(keep) < 2 or len(np.unique(h[keep])) < 2:
        return None
    return float(np.polyfit(np.log(h[keep]), np.log(e[keep]), 1)[0])


def _plottable(r: Result) -> bool:
    return r.ok and r.error is not None and r.error > 0 and r.wall_s is not None


def pareto_front(results: list[Result]) -> list[Result]:
    """Runs no other run beats on both error and wall time, fastest first."""
    pts = sorted((r for r in results if _plottable(r)), key=lambda r: (r.wall_s, r.error))
    front, best = [], math.inf
    for r in pts:
        if r.error < best:
            front.append(r)
            best = r.error
    return front


def methods(results: list[Result]) -> list[str]:
    return list(dict.fromkeys(r.run.method for r in results))


def rates(results: list[Result]) -> dict[str, float | None]:
    out = {}
    for m in methods(results):
        group = [r for r in results if r.run.method == m and _plottable(r)]
        out[m] = convergence_rate([r.h for r in group], [r.error for r in group])
    return out


# --- output -----------------------------------------------------------------------------------


def write_csv(study: Study, results: list[Result], path: Path) -> None:
    stages = list(dict.fromkeys(
        s for r in results if r.ok for s in r.summary["wall_time_s"] if s != "total"))
    cols = (["run_id", *study.keys, "method", "status", "exit_code", "dofs", "elements", "h",
             "wall_time_s", *(f"time_{s.replace(' ', '_')}_s" for s in stages), "peak_mib",
             "quantity", "value", "reference_value", "error", "message"])
    quantity = study.quantity or "reference"
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols)
        for r in results:
            s = r.summary or {}
            wt = s.get("wall_time_s", {})
            if r.ok and study.quantity is None and "reference" in s:
                quantity = s["reference"]["quantity"]
            w.writerow([
                r.run.run_id, *(_value_text(r.run.settings[k]).strip('"') for k in study.keys),
                r.run.method, "ok" if r.ok else "failed", r.exit_code,
                r.dofs, s.get("counts", {}).get("elements"), _fmt(r.h),
                _fmt(wt.get("total")), *(_fmt(wt.get(st)) for st in stages), _fmt(r.peak_mib),
                quantity if r.ok else "", _fmt(r.value), _fmt(r.reference), _fmt(r.error),
                r.message,
            ])


def _fmt(x) -> str:
    if x is None:
        return ""
    return f"{x:.10g}" if isinstance(x, float) else str(x)


def study_json(study: Study, results: list[Result]) -> dict:
    refs = _evaluate(study, results)
    return {
        "title": study.spec.title,
        "case": os.path.normpath(study.case_path),
        "error": study.quantity or "reference",
        "runs": len(results),
        "failed": [r.run.run_id for r in results if not r.ok],
        "rates": rates(results),
        "rate_against": (study.spec.refinement if study.spec.refinement in study.keys
                         else "dofs^(-1/3)"),
        "extrapolation": {m: {"value": e.value, "method": e.method, "order": e.order,
                              "ratio": e.ratio, "note": e.note} for m, e in refs.items()},
        "pareto_front": [r.run.run_id for r in pareto_front(results)],
    }


def plot(study: Study, results: list[Result], path: Path) -> None:
    """Log-log error against wall time, one line per method; raises ImportError without
    matplotlib."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n_lines = len(methods(results)) + 1
    fig, ax = plt.subplots(figsize=(7.5, 5.0 + 0.2 * n_lines), dpi=120)
    rate = rates(results)
    markers = itertools.cycle("osD^v<>ph*")
    against = (("dt" if study.spec.refinement == "analysis.dt" else "h")
               if study.spec.refinement in study.keys else "dofs^(-1/3)")
    for m in methods(results):
        group = sorted((r for r in results if r.run.method == m and _plottable(r)),
                       key=lambda r: -r.h)
        if not group:
            continue
        k = rate.get(m)
        label = f"{m}: rate {k:.2f}" if k is not None else f"{m}: rate -"
        ax.plot([r.wall_s for r in group], [r.error for r in group], marker=next(markers),
                label=label)
        for r in group:
            text = f"{against}={r.run.size:g}" if r.run.size is not None else f"{r.dofs:,} dofs"
            ax.annotate(text, (r.wall_s, r.error), textcoords="offset points", xytext=(5, 4),
                        fontsize=7, color="0.3")
    front = pareto_front(results)
    if front:
        ax.plot([r.wall_s for r in front], [r.error for r in front], ls="none", marker="o",
                ms=13, mfc="none", mec="k", mew=1.2, label="Pareto front (nothing faster "
                "and more accurate)", drawstyle="steps-post")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time of the run (s)")
    quantity = study.quantity
    if quantity is None:
        q = next((r.summary["reference"]["quantity"] for r in results
                  if r.ok and "reference" in r.summary), "reference")
        ax.set_ylabel(f"error against the exact solution\n({q})")
    else:
        ax.set_ylabel(f"relative error of {quantity}\n(against Richardson extrapolation)")
    ax.set_title(study.spec.title or study.name, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7.5, loc="upper center", bbox_to_anchor=(0.5, -0.13), frameon=False,
              title=f"fitted rate: slope of log error against log {against}",
              title_fontsize=7.5)
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)


@dataclass
class Outcome:
    results: list[Result]
    csv: Path
    json: Path
    png: Path | None
    warnings: list[str] = field(default_factory=list)


def write_outputs(study: Study, results: list[Result], out_dir: Path) -> Outcome:
    csv_path, json_path = out_dir / "study.csv", out_dir / "study.json"
    write_csv(study, results, csv_path)
    json_path.write_text(json.dumps(study_json(study, results), indent=2) + "\n")
    png: Path | None = out_dir / "study.png"
    warnings = []
    try:
        plot(study, results, png)
    except ImportError:
        png = None
        warnings.append(MATPLOTLIB_HINT)
    return Outcome(results, csv_path, json_path, png, warnings)
