"""Initial states displaced from the reference configuration: a static preload released at
t = 0+, a field given by expressions of the coordinates, or nodal values from elsewhere.

Whatever the source, the state at t = 0 is completed the same way: the stresses (and plastic
state) of the displacement, the case's supports at their values at t = 0, and the
acceleration that balances it, ``M a0 = f_ext(0) - f_int(u0) - C v0`` on the free dofs, so the
integrator starts from the motion the initial state actually has (an acceleration left at
zero would inject every mode the initial force excites).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..config.expression import evaluate, parse
from ..config.schema import StaticAnalysis
from ..errors import CaseError
from .constrained import Constrained
from .energy import initial_ledger
from .integrators import quasi_static
from .problem import Constraints, Problem, build_problem
from .state import Operators, State, cohesive_force, starting_state
from .stepping import ImplicitStepper, advance

AXES = "xyz"
# A field value on a supported dof differs from the support's value when it exceeds this
# fraction of the field's largest value (coordinates read from a mesh file carry round-off).
SUPPORT_TOLERANCE = 1e-9


def field_displacement(space, spec, key: tuple) -> np.ndarray:
    """Nodal displacement ``(n_dofs,)`` of a ``DisplacementField`` evaluated at every node
    of ``space`` (mid-side nodes of P2 included); a value that is not finite is an error at
    ``key + (component,)``."""
    x = space.node_points
    values = {"x": x[:, 0], "y": x[:, 1], "z": x[:, 2], **spec.constants}
    u = np.zeros((space.n_nodes, 3))
    for k, axis in enumerate(AXES):
        tree = parse(getattr(spec, axis), set(AXES) | set(spec.constants))
        u[:, k] = np.broadcast_to(evaluate(tree, values), (space.n_nodes,))
        bad = ~np.isfinite(u[:, k])
        if np.any(bad):
            i = int(np.argmax(bad))
            raise CaseError(key + (axis,), f"not finite at {np.count_nonzero(bad)} of "
                            f"{space.n_nodes} nodes (first at {_point(x[i])}): "
                            f"{getattr(spec, axis)!r}")
    return u.ravel()


def check_supports(u0: np.ndarray, problem: Problem, key: tuple) -> None:
    """An initial displacement must meet the supports at t = 0: a located error naming the
    first dof where it does not (the supports would otherwise cut a kink into it)."""
    dofs = problem.constraints.dofs
    if len(dofs) == 0:
        return
    gap = np.abs(u0[dofs] - problem.prescribed(0.0))
    scale = max(float(np.abs(u0).max(initial=0.0)), float(np.abs(
        problem.prescribed(0.0)).max(initial=0.0)))
    bad = gap > SUPPORT_TOLERANCE * scale
    if np.any(bad):
        i = int(np.argmax(gap))
        dof = int(dofs[i])
        where = _point(problem.space.node_points[dof // 3])
        raise CaseError(key, f"the initial displacement does not meet the supports: "
                        f"u{AXES[dof % 3]} = {u0[dof]:.6g} at {where}, where a support "
                        f"prescribes {problem.prescribed(0.0)[i]:.6g} at t = 0 "
                        f"({np.count_nonzero(bad)} supported dofs differ)")


def _point(x) -> str:
    return "(" + ", ".join(f"{c:.6g}" for c in x) + ")"


def preload_problem(space, conditions: list, density, problem: Problem,
                    case_loads: bool) -> Problem:
    """The static problem of a preload: its ``conditions`` at full value plus, with
    ``case_loads``, the case's external force at t = 0, all ramped over [0, 1]; held by the
    preload's supports and by the case's at their values at t = 0 (the case's win where
    both prescribe a dof)."""
    own = build_problem(space, conditions, None, density, StaticAnalysis())
    force = own.external_force(1.0)  # every preload condition ramps to 1 at t = 1
    if case_loads:
        force = force + problem.external_force(0.0)
    dofs = np.concatenate([own.constraints.dofs, problem.constraints.dofs])
    values = np.concatenate([own.prescribed(1.0), problem.prescribed(0.0)])
    # the last occurrence of a dof wins: the case's supports
    dofs, first = np.unique(dofs[::-1], return_index=True)
    constraints = Constraints(dofs, values[::-1][first], np.zeros(len(dofs), dtype=np.int64))
    return Problem(space, constraints, force[None, :], [lambda t: t], ["preload"],
                   {}, list(own.descriptions))


def preloaded(problem: Problem, law, ops: Operators, linear_solver: str, equilibrium,
              steps: int) -> State:
    """The static equilibrium of a preload problem at t = 1, reached in ``steps`` load
    steps (the equilibrium iteration and cutbacks of the case's analysis); no inertia."""
    static = dataclasses.replace(ops, mass=None, damping=None)
    constrained = Constrained(problem, linear_solver)
    stepper = ImplicitStepper(problem, law, static, quasi_static(1.0 / steps), equilibrium,
                              constrained)
    state = at_rest(problem, law, static, constrained)
    ledger = initial_ledger(state, law, static)
    for n in range(1, steps + 1):
        state, ledger, _ = advance(stepper, state, n / steps, ledger, n)
    return state


def at_rest(problem: Problem, law, ops: Operators, constrained) -> State:
    """The undeformed state at t = 0 of a problem without inertia."""
    return displaced_state(problem, law, ops, constrained, np.zeros(problem.space.n_dofs))


def displaced_state(problem: Problem, law, ops: Operators, constrained, u0: np.ndarray,
                    v0: np.ndarray | None = None, start: State | None = None) -> State:
    """The state at t = 0 displaced by ``u0`` (moving with ``v0``): the supports at their
    values at t = 0, the stresses of ``start`` (a preload's equilibrium, whose plastic
    state and forces it keeps) or else of the material loaded from its virgin state to
    ``u0``, and with mass the acceleration that balances the loads at t = 0."""
    u = np.array(u0, dtype=float)
    u[constrained.dofs] = problem.prescribed(0.0)
    if start is not None:
        stress, plastic, cohesive = start.stress, start.plastic, start.cohesive
        f_int = start.internal_force
    else:
        stress, plastic, _ = law.update(ops.strain_operator.strain(u),
                                        law.initial_state(ops.weights.shape))
        f_coh, _, cohesive = cohesive_force(ops, u, None)
        f_int = ops.strain_operator.internal_force(stress) + f_coh
    return starting_state(problem, ops, constrained, u, v0, (stress, plastic, cohesive), f_int)
