"""Load curves and the time grid: when each load and prescribed displacement acts, how much.

A curve is a scalar factor of time multiplying a condition's value. Conditions without a
``curve`` follow the analysis default: ``constant`` for dynamic analyses (the load is on from
the start), ``ramp`` for static and quasi-static ones (0 to full over the analysis; a static
analysis is one step to t = 1, so its loads do the work of a slowly applied load).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..config import schema
from ..errors import CaseError

Curve = Callable[[float], float]


@dataclass(frozen=True)
class TimeGrid:
    """``steps`` equal steps of ``dt`` from 0 to ``t_end``."""

    t_end: float
    dt: float
    steps: int

    def time(self, step: int) -> float:
        return self.t_end if step == self.steps else step * self.dt


def time_grid(analysis) -> TimeGrid:
    """The steps an analysis takes. Static: one step to t = 1. Given ``t_end`` and ``dt``,
    the step is shortened (never lengthened) to divide ``t_end`` exactly."""
    if isinstance(analysis, schema.StaticAnalysis):
        return TimeGrid(1.0, 1.0, 1)
    t_end, dt, steps = analysis.t_end, analysis.dt, analysis.steps
    if t_end is None and isinstance(analysis, schema.QuasiStaticAnalysis) and (
        dt is None or steps is None
    ):
        t_end = 1.0
    if steps is None:
        steps = max(1, int(np.ceil(t_end / dt * (1.0 - 1e-12))))
    if t_end is None:
        t_end = dt * steps
    return TimeGrid(float(t_end), float(t_end) / steps, int(steps))


def default_curve(analysis) -> str:
    return "constant" if isinstance(analysis, schema.DynamicAnalysis) else "ramp"


def make_curve(curve: schema.RampCurve | schema.ConstantCurve | schema.TableCurve,
               t_end: float) -> Curve:
    """A vectorizable function of time for one curve of the case."""
    if isinstance(curve, schema.ConstantCurve):
        value = curve.value
        return lambda t: value
    if isinstance(curve, schema.RampCurve):
        t0, t1, value = curve.t_start, curve.t_end or t_end, curve.value
        return lambda t: value * float(np.clip((t - t0) / (t1 - t0), 0.0, 1.0))
    times = np.array([p[0] for p in curve.points])
    factors = np.array([p[1] for p in curve.points])
    return lambda t: float(np.interp(t, times, factors))


def resolve_curves(
    names: list[tuple[tuple, str | None]], load_curves: dict, analysis
) -> tuple[list[str], list[Curve], np.ndarray]:
    """Map each condition's curve name (or None for the default) to a curve index.

    ``names`` holds ``(case key of the curve, name)``. Returns the distinct curve names, their
    functions and, per condition, the index into them. An unknown name is a
    :class:`CaseError` at that key.
    """
    t_end = time_grid(analysis).t_end
    builtin = {
        "ramp": schema.RampCurve(type="ramp"),
        "constant": schema.ConstantCurve(type="constant"),
    }
    table = {**builtin, **load_curves}
    used: list[str] = []
    index = np.zeros(len(names), dtype=np.int64)
    for i, (key, name) in enumerate(names):
        name = name if name is not None else default_curve(analysis)
        if name not in table:
            known = ", ".join(sorted(table))
            raise CaseError(key, f"unknown load curve {name!r}; known: {known}")
        if name not in used:
            used.append(name)
        index[i] = used.index(name)
    return used, [make_curve(table[n], t_end) for n in used], index
