"""Exact references a case can declare (``reference: {solution: ...}``): the quantity each
compares, its exact value from :mod:`fem_frac.verify.exact`, and the run's error, reported in
``summary.json``.

- ``cantilever``: a box along x, ``fixed`` on ``xmin``, a uniform z ``traction`` on
  ``xmax``, elastic. Tip deflection (mean of -u_z over the nodes of x = L) against
  Timoshenko beam theory.
- ``lame_sphere``: a ``hollow_sphere`` with a ``pressure`` on ``inner``, elastic. L2 norm of
  the displacement error over the body, relative to the L2 norm of the exact field.
- ``hill_sphere``: a ``hollow_sphere`` octant with a ``pressure`` on ``inner``, perfectly
  plastic. Outer radial displacement (mean of u . x/|x| over the ``outer`` nodes) against
  Hill.
- ``uniaxial_bar``: a box with ``symmetry`` on ``xmin ymin zmin`` and an x ``displacement``
  on ``xmax``. Axial stress (the ``xmax`` reaction over the face's area) against the exact
  1D elastoplastic path along the same steps.
- ``free_vibration``: a dynamic box along x, ``fixed`` on ``xmin``, set moving along x by a
  uniform initial velocity, elastic: the fixed-free bar rings in its axial modes. Period of
  the fundamental, from the zero crossings of the ``xmin`` reaction (a square wave of
  period 4 L / c in 1D theory), against 4 L / sqrt(E / rho). The 3D bar differs from 1D
  theory by the lateral inertia of its Poisson contraction (Rayleigh-Love), a relative
  O((nu pi r / (2 L))^2) for the fundamental, r the section's radius of gyration.

A reference that does not fit the case is a :class:`CaseError` at ``reference.solution``,
raised before the solve.
"""

from __future__ import annotations

import numpy as np

from ..config import schema
from ..errors import CaseError
from ..mesh.mesh import match
from ..verify import exact

KEY = ("reference", "solution")


def _by_type(case: schema.Case, kind, boundary: str):
    found = [(i, bc) for i, bc in enumerate(case.boundary_conditions)
             if isinstance(bc, kind) and bc.boundary == boundary]
    return found[-1][1] if found else None


def _need(condition: bool, solution: str, what: str) -> None:
    if not condition:
        raise CaseError(KEY, f"reference {solution!r} needs {what}")


def check_reference(case: schema.Case) -> None:
    """Raise a located CaseError when the declared reference does not fit the case."""
    if case.reference is None:
        return
    name, geometry = case.reference.solution, case.mesh.geometry
    _need(not case.regions, name, "one material (no regions)")
    if name == "cantilever":
        _need(isinstance(geometry, schema.BoxGeometry), name, "a box geometry")
        _need(_by_type(case, schema.Fixed, "xmin") is not None, name, "fixed on 'xmin'")
        t = _by_type(case, schema.Traction, "xmax")
        _need(t is not None and t.traction[0] == 0 and t.traction[1] == 0, name,
              "a z traction on 'xmax'")
        _need(case.plasticity is None, name, "an elastic material")
    elif name in ("lame_sphere", "hill_sphere"):
        _need(isinstance(geometry, schema.HollowSphereGeometry), name,
              "a hollow_sphere geometry")
        _need(_by_type(case, schema.Pressure, "inner") is not None, name,
              "a pressure on 'inner'")
        if name == "lame_sphere":
            _need(case.plasticity is None, name, "an elastic material")
        else:
            _need(case.plasticity is not None and case.plasticity.hardening == 0
                  and case.plasticity.kinematic_hardening == 0, name,
                  "perfect plasticity (no hardening)")
            _need(geometry.sector == "octant", name, "the octant sector")
            _below_limit_load(case, geometry)
    elif name == "free_vibration":
        _need(isinstance(geometry, schema.BoxGeometry), name, "a box geometry")
        _need(isinstance(case.analysis, schema.DynamicAnalysis), name, "a dynamic analysis")
        _need(_by_type(case, schema.Fixed, "xmin") is not None, name, "fixed on 'xmin'")
        v0 = getattr(case.analysis, "initial_velocity", None)
        _need(v0 is not None and v0.uniform[0] != 0 and v0.uniform[1] == v0.uniform[2] == 0
              and not any(v0.angular_velocity), name, "a uniform initial velocity along x")
        _need(case.plasticity is None, name, "an elastic material")
    elif name == "uniaxial_bar":
        _need(isinstance(geometry, schema.BoxGeometry), name, "a box geometry")
        for face in ("xmin", "ymin", "zmin"):
            _need(_by_type(case, schema.Symmetry, face) is not None, name,
                  f"symmetry on '{face}'")
        d = _by_type(case, schema.Displacement, "xmax")
        _need(d is not None and d.x is not None, name, "an x displacement on 'xmax'")


def _below_limit_load(case: schema.Case, geometry) -> None:
    """Hill's solution exists below the limit pressure of the sphere, 2 sigma_Y ln(b/a)
    (the whole wall flows at it: no equilibrium, the solve cannot converge)."""
    from ..solve.loading import make_curve, resolve_curves, time_grid

    i = max(i for i, bc in enumerate(case.boundary_conditions)
            if isinstance(bc, schema.Pressure) and bc.boundary == "inner")
    p = case.boundary_conditions[i]
    names, _, _ = resolve_curves([(("boundary_conditions", i, "curve"), p.curve)],
                                 case.load_curves, case.analysis)
    t_end = time_grid(case.analysis).t_end
    table = {"ramp": schema.RampCurve(type="ramp"),
             "constant": schema.ConstantCurve(type="constant"), **case.load_curves}
    curve = table[names[0]]
    times = [0.0, t_end]
    if isinstance(curve, schema.RampCurve):
        times += [curve.t_start, curve.t_end or t_end]
    elif isinstance(curve, schema.TableCurve):
        times += [t for t, _ in curve.points]
    factor = make_curve(curve, t_end)
    peak = max(abs(p.pressure * factor(t)) for t in times if 0.0 <= t <= t_end)
    sy = case.plasticity.yield_stress
    limit = 2.0 * sy * np.log(geometry.outer_radius / geometry.inner_radius)
    if peak >= limit:
        raise CaseError(("boundary_conditions", i, "pressure"),
                        f"reference 'hill_sphere' needs a pressure below the limit load "
                        f"2 sigma_Y ln(b/a) = {limit:.4g} (the whole wall flows there: no "
                        f"equilibrium); the pressure reaches {peak:.4g}")


class Recorder:
    """What ``free_vibration`` needs from every step: the x reaction of ``xmin``; call it
    with each committed ``(n, world)``."""

    def __init__(self, problem):
        self.times: list[float] = []
        self.signal: list[float] = []
        group = problem.reaction_groups["xmin"]
        # every dof of the group is constrained (a fixed support)
        self._rows = match(problem.constraints.dofs, group[0::3])

    def __call__(self, n: int, world) -> None:
        self.times.append(world.t)
        self.signal.append(float(world.body.state.reaction[self._rows].sum()))


def recorder(case: schema.Case, problem) -> Recorder | None:
    """The recorder the case's reference needs (``None``: it needs none)."""
    if case.reference is not None and case.reference.solution == "free_vibration":
        return Recorder(problem)
    return None


def reference_error(case: schema.Case, grid, disc, state,
                    recorder: Recorder | None = None) -> dict:
    """``{solution, quantity, computed, exact, relative_error}`` of the run: its final
    ``state`` on ``disc`` (or the steps ``recorder`` kept)."""
    name = case.reference.solution
    quantity, computed, value = _COMPARE[name](case, grid, disc, state, recorder)
    if name == "lame_sphere":  # an error norm already: exact value 0
        return _row(name, quantity, computed, 0.0, computed)
    return _row(name, quantity, computed, value, (computed - value) / abs(value))


def _cantilever(case, grid, disc, state, recorder):
    x, problem = disc.space.node_points, disc.problem
    length, width, height = case.mesh.geometry.lengths
    origin = np.asarray(case.mesh.geometry.origin)
    t = _by_type(case, schema.Traction, "xmax")
    force = -t.traction[2] * width * height * _factor(problem, case.analysis, state.t, t)
    tip = np.isclose(x[:, 0], origin[0] + length)
    computed = -float(np.mean(state.u[3 * np.flatnonzero(tip) + 2]))
    m = case.material
    value = exact.cantilever_tip_deflection(force, length, width, height, m.youngs_modulus,
                                            m.poissons_ratio)
    return "tip deflection", computed, value


def _lame_sphere(case, grid, disc, state, recorder):
    from ..fem.norms import l2_error

    g, m = case.mesh.geometry, case.material
    p = _by_type(case, schema.Pressure, "inner")
    pressure = p.pressure * _factor(disc.problem, case.analysis, state.t, p)

    def field(points):
        return exact.lame_sphere_displacement(points, g.center, g.inner_radius,
                                              g.outer_radius, pressure, m.youngs_modulus,
                                              m.poissons_ratio)

    err, norm = l2_error(disc.space, state.u, field)
    return "L2 displacement error / L2 norm", err / norm, 0.0


def _hill_sphere(case, grid, disc, state, recorder):
    g, m = case.mesh.geometry, case.material
    p = _by_type(case, schema.Pressure, "inner")
    pressure = p.pressure * _factor(disc.problem, case.analysis, state.t, p)
    sy = case.plasticity.yield_stress
    c = exact.hill_sphere_plastic_radius(pressure, g.inner_radius, g.outer_radius, sy)
    value = exact.hill_sphere_outer_displacement(c, g.outer_radius, sy, m.youngs_modulus,
                                                 m.poissons_ratio)
    d = disc.space.node_points - np.asarray(g.center)
    r = np.linalg.norm(d, axis=1)
    outer = np.isclose(r, g.outer_radius, rtol=1e-6)
    u = state.u.reshape(-1, 3)[outer]
    computed = float(np.mean(np.sum(u * d[outer], axis=1) / r[outer]))
    return "outer radial displacement", computed, value


def _free_vibration(case, grid, disc, state, recorder):
    length = case.mesh.geometry.lengths[0]
    value = 4.0 * length / np.sqrt(case.material.youngs_modulus / case.material.density)
    computed = exact.fundamental_period(recorder.times, recorder.signal)
    if not np.isfinite(computed):
        raise CaseError(("analysis", "t_end"), "reference 'free_vibration' needs at least "
                        f"1.5 periods (4 L / c = {value:.4g}) in the run")
    return "period of the fundamental axial mode", computed, value


def _uniaxial_bar(case, grid, disc, state, recorder):
    from .results import reaction_forces

    problem = disc.problem
    lengths = case.mesh.geometry.lengths
    area = lengths[1] * lengths[2]
    computed = float(reaction_forces(disc, state)["xmax"][0] / area)
    d = _by_type(case, schema.Displacement, "xmax")
    strains = [d.x * _factor(problem, case.analysis, grid.time(n), d) / lengths[0]
               for n in range(1, grid.steps + 1)]
    value = exact.uniaxial_stress(strains, case.material.youngs_modulus, case.plasticity)
    return "axial stress", computed, value


_COMPARE = {"cantilever": _cantilever, "lame_sphere": _lame_sphere,
            "hill_sphere": _hill_sphere, "free_vibration": _free_vibration,
            "uniaxial_bar": _uniaxial_bar}


def _factor(problem, analysis, t: float, condition) -> float:
    """The curve factor of ``condition`` at time ``t``."""
    from ..solve.loading import default_curve

    name = condition.curve if condition.curve is not None else default_curve(analysis)
    return float(problem.curves[problem.curve_names.index(name)](t))


def _row(name, quantity, computed, value, error) -> dict:
    return {"solution": name, "quantity": quantity, "computed": float(computed),
            "exact": float(value), "relative_error": float(error)}
