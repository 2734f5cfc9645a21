"""A body's state carried onto the mesh a topology change made (crack insertion, pieces
leaving).

Nodal values are copied to the new nodes, element state stays with its element (elements
are never cut). That keeps the displacement field, the stresses, the elastic and kinetic
energies, the mass and the linear and angular momenta exactly. Cohesive crack faces keep
their history (new faces start closed and undamaged). With inertia the acceleration
is re-balanced on the new mesh (the force on a vertex is now shared by its copies), so the
energy ledger of a re-solved step still balances.
"""

from __future__ import annotations

from ..cohesive.interface import carry_history
from ..fracture.remap import dof_transfer, node_transfer, transfer_plastic
from ..fracture.topology import Transfer
from ..solve.discretization import Discretization
from ..solve.state import State, balanced_acceleration, reaction


def carry(state: State, old: Discretization, new: Discretization, transfer: Transfer,
          inertia: bool) -> State:
    """``state`` of ``old`` onto ``new`` through ``transfer``."""
    dofs = dof_transfer(node_transfer(old.space, new.space, transfer))
    u, v, a = state.u[dofs], state.v[dofs], state.a[dofs]
    stress = transfer.transfer_elemental(state.stress, axis=1)
    plastic = transfer_plastic(state.plastic, transfer)
    ops, fixed = new.ops, new.constrained.dofs
    f_int = ops.strain_operator.internal_force(stress)
    cohesive = carry_history(old.ops.interface, state.cohesive, ops.interface)
    if cohesive is not None:
        f_int = f_int + ops.interface.force(cohesive.traction)
    f_ext = new.problem.external_force(state.t)
    if not (inertia and ops.mass is not None):
        return State(state.t, u, v, a, stress, plastic, f_int,
                     reaction(ops, fixed, f_int, f_ext), cohesive)
    a = balanced_acceleration(ops, new.constrained, f_int, f_ext, v, a)
    return State(state.t, u, v, a, stress, plastic, f_int,
                 reaction(ops, fixed, f_int, f_ext, v, a), cohesive)


def rediscretize(disc: Discretization, mesh, timer, why: str,
                 transfer: Transfer | None = None) -> Discretization:
    """``disc``'s recipe on ``mesh``, a mesh a topology change made (``why``, for the
    message): a support or load whose faces all left acts on nothing there. ``transfer``:
    given for a crack insertion, whose operators are updated from ``disc``'s, or for pieces
    leaving, whose solves go through ``disc``'s factorization."""
    from ..errors import CaseError, SolverError
    from ..solve.discretization import discretize

    previous = (disc, transfer.node_map) if transfer is not None else None
    try:
        return discretize(disc.recipe, mesh, timer, strict=False, previous=previous)
    except CaseError as exc:
        raise SolverError(f"{why}: {exc.message}") from None
