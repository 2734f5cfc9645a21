"""The error of each run (declared reference or Richardson extrapolation), convergence rates
and the Pareto front of error against wall time."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from .runs import Result
    from .spec import Study


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


def evaluate(study: Study, results: list[Result]) -> dict[str, Extrapolation]:
    """Fill ``value``, ``reference`` and ``error`` of the successful results; returns the
    extrapolation of each method (none for the declared reference)."""
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


def convergence_rate(h, error) -> float | None:
    """Slope of log(error) against log(h) (least squares); None below two usable points."""
    h, e = np.asarray(h, dtype=float), np.asarray(error, dtype=float)
    keep = np.isfinite(h) & np.isfinite(e) & (h > 0) & (e > 0)
    if np.count_nonzero(keep) < 2 or len(np.unique(h[keep])) < 2:
        return None
    return float(np.polyfit(np.log(h[keep]), np.log(e[keep]), 1)[0])


def plottable(r: Result) -> bool:
    return r.ok and r.error is not None and r.error > 0 and r.wall_s is not None


def pareto_front(results: list[Result]) -> list[Result]:
    """Runs no other run beats on both error and wall time, fastest first."""
    pts = sorted((r for r in results if plottable(r)), key=lambda r: (r.wall_s, r.error))
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
        group = [r for r in results if r.run.method == m and plottable(r)]
        out[m] = convergence_rate([r.h for r in group], [r.error for r in group])
    return out
