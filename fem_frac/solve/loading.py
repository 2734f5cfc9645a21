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

# The bounds of a time grid arithmetic can step through (see time_grid).
MAX_STEPS = float(2**31 - 1)
MIN_DT, MAX_DT = 1e-150, 1e150


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
    the step is shortened (never lengthened) to divide ``t_end`` exactly.

    Raises a :class:`CaseError` for a grid no arithmetic can step through: more than
    :data:`MAX_STEPS` steps, or a step outside [:data:`MIN_DT`, :data:`MAX_DT`] (its square,
    which the integrators divide by, would underflow to zero or overflow)."""
    if isinstance(analysis, schema.StaticAnalysis):
        return TimeGrid(1.0, 1.0, 1)
    t_end, dt, steps = analysis.t_end, analysis.dt, analysis.steps
    if t_end is None and isinstance(analysis, schema.QuasiStaticAnalysis) and (
        dt is None or steps is None
    ):
        t_end = 1.0
    if steps is None:
        ratio = t_end / dt * (1.0 - 1e-12)
        if not ratio <= MAX_STEPS:
            raise CaseError(("analysis", "dt"), f"t_end / dt = {t_end:g} / {dt:g} is more "
                            f"than {MAX_STEPS:g} steps")
        steps = max(1, int(np.ceil(ratio)))
    if t_end is None:
        t_end = dt * steps
    grid = TimeGrid(float(t_end), float(t_end) / steps, int(steps))
    if not MIN_DT <= grid.dt <= MAX_DT:
        key = "dt" if analysis.dt is not None else ("t_end" if analysis.t_end is not None
                                                     else "steps")
        raise CaseError(("analysis", key), f"a time step of {grid.dt:g} (t_end {grid.t_end:g}"
                        f" in {grid.steps} steps) is outside [{MIN_DT:g}, {MAX_DT:g}]: its "
                        "square under- or overflows; change the unit of time")
    return grid


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
        if not t1 > t0:  # starts at or after its end: a step at t0
            return lambda t: value * float(t >= t0)
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
            _check_ramp(name, table[name], t_end)
        index[i] = used.index(name)
    return used, [make_curve(table[n], t_end) for n in used], index


def _check_ramp(name: str, curve, t_end: float) -> None:
    """A ramp that would start at or after the end of the analysis (its own default end)
    never acts: a located error at its ``t_start``."""
    if isinstance(curve, schema.RampCurve) and curve.t_end is None and curve.t_start >= t_end:
        raise CaseError(("load_curves", name, "t_start"),
                        f"the ramp starts at {curve.t_start:g}, at or after the end of the "
                        f"analysis ({t_end:g}): it would never act; give an earlier t_start")
