"""The committed state of a discretization and the forces that balance it.

One place for the balance of nodal forces, used by the initial state, every implicit step
and every carry-over onto a new mesh:

    M a + C v + f_int(u) = f_ext + r      (r: support reactions, non-zero on fixed dofs)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..cohesive.interface import CohesiveState, Interface
from ..errors import SolverError
from ..plasticity.return_map import PlasticState


@dataclass(frozen=True, eq=False)
class Operators:
    """What one topology provides: the strain operator (``strain``, ``internal_force``,
    ``stiffness``), the elastic stiffness, and the mass and damping matrices when there is
    inertia (``mass`` a sparse matrix, consistent or diagonal); the cohesive crack faces
    (``interface``) when cracks carry a fracture energy; the scalar element masses
    (``element_mass``: ``(n_tets, k, k)`` of a consistent mass, ``(n_tets, k)`` of a
    lumped one on linear tets), which a crack insertion leaves as they are."""

    strain_operator: object
    stiffness: sp.csr_matrix
    mass: sp.csr_matrix | None = None
    damping: sp.csr_matrix | None = None
    interface: Interface | None = None
    element_mass: np.ndarray | None = None
    # the diagonals of a stiffness and of a consistent mass that a crack's reconnection made
    # (fem.reconnect, which reads them at the next one), None where assembled afresh
    stiffness_diagonal: np.ndarray | None = None
    mass_diagonal: np.ndarray | None = None

    @property
    def weights(self) -> np.ndarray:
        """Quadrature weights times Jacobians ``(n_tets, n_qp)``."""
        return self.strain_operator.weights

    @property
    def lumped(self) -> bool:
        """The mass matrix is diagonal."""
        return self.mass is not None and self.mass.nnz == self.mass.shape[0]


@dataclass(frozen=True, eq=False)
class State:
    """Committed state at time ``t``. Vectors are ``(n_dofs,)``; ``stress`` Mandel
    ``(6, n_tets, n_qp)``; ``reaction`` is the support force on the constrained dofs
    ``(k,)``; ``internal_force`` includes the cohesive faces' forces, whose state is
    ``cohesive`` (``None`` without cohesive faces). ``reaction_inertia``: the reaction
    includes the inertia of the constrained dofs (``M a`` and ``C v`` on their rows, as
    every implicit step and every balanced state has it); an explicit step's reaction is
    the force the body transmits, ``f_int + C v - f_ext`` there, the supports' own lumped
    masses moving as prescribed (the ledger books the driver's work on them as the change
    of their kinetic energy, :func:`fem_frac.solve.energy.account`)."""

    t: float
    u: np.ndarray
    v: np.ndarray
    a: np.ndarray
    stress: np.ndarray
    plastic: PlasticState | None
    internal_force: np.ndarray
    reaction: np.ndarray
    cohesive: CohesiveState | None = None
    reaction_inertia: bool = True


@dataclass(frozen=True)
class StepInfo:
    """What one equilibrium step (or its re-solves) cost and reached."""

    iterations: int
    residual: float
    solves: int = 0
    factorizations: int = 0
    cutbacks: int = 0

    def then(self, later: StepInfo) -> StepInfo:
        """This step followed by ``later`` (a re-solve of it): costs add up, the residual
        is the later one's."""
        return StepInfo(self.iterations + later.iterations, later.residual,
                        self.solves + later.solves,
                        self.factorizations + later.factorizations,
                        self.cutbacks + later.cutbacks)


def cohesive_force(ops: Operators, u: np.ndarray, previous: CohesiveState | None):
    """The cohesive faces at ``u`` from the history of ``previous`` (fresh faces when
    ``None``): ``(nodal force (n_dofs,) or 0.0, law response or None, state or None)``."""
    interface = ops.interface
    if interface is None:
        return 0.0, None, None
    kappa = previous.kappa if previous is not None else interface.initial_state().kappa
    response, state = interface.respond(u, kappa)
    return interface.force(response.traction), response, state


def inertial_force(ops: Operators, v: np.ndarray, a: np.ndarray) -> np.ndarray | float:
    """``M a + C v`` (zero without mass)."""
    if ops.mass is None:
        return 0.0
    force = ops.mass @ a
    if ops.damping is not None:
        force = force + ops.damping @ v
    return force


def reaction(ops: Operators, fixed: np.ndarray, f_int: np.ndarray, f_ext: np.ndarray,
             v: np.ndarray | None = None, a: np.ndarray | None = None) -> np.ndarray:
    """Support reactions ``(k,)`` on the ``fixed`` dofs: ``f_int - f_ext`` plus, when the
    rates are given, the inertial and damping forces."""
    r = f_int - f_ext
    if a is not None:
        r = r + inertial_force(ops, v, a)
    return r[fixed]


def balanced_acceleration(ops: Operators, constrained, f_int: np.ndarray, f_ext: np.ndarray,
                          v: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``a`` corrected on the free dofs so that ``M a + C v + f_int = f_ext`` there (a
    diagonal mass by division, a consistent one by :func:`mass_solve`)."""
    free = constrained.free
    unbalanced = f_ext - f_int - inertial_force(ops, v, a)
    if not np.any(unbalanced[free]):
        return a
    a = a.copy()
    if ops.lumped:
        a[free] += unbalanced[free] / ops.mass.diagonal()[free]
    else:
        a[free] += mass_solve(ops.mass, constrained, unbalanced[free])
    return a


# Relative residual of the consistent-mass solves of mass_solve: round-off of the
# factorization it replaces is about 1e-15.
MASS_RTOL = 1e-13


def mass_solve(mass, constrained, rhs: np.ndarray) -> np.ndarray:
    """``M_ff^-1 rhs`` for the consistent mass on the free dofs, by conjugate gradients with
    its diagonal as preconditioner. A consistent mass is spectrally equivalent to its
    diagonal on any mesh (the element mass matrices are, with bounds that depend on the
    element type only), so this converges in a few tens of products, whatever the mesh size,
    where a factorization (what this replaced: one per crack insertion with Newmark) costs as
    much as the stiffness's. Falls back on the factorization if it does not converge."""
    import scipy.sparse.linalg as sla

    free = constrained.free
    m = mass[free][:, free].tocsr()
    inverse = 1.0 / m.diagonal()
    x, info = sla.cg(m, rhs, rtol=MASS_RTOL, atol=0.0, maxiter=500,
                     M=sla.LinearOperator(m.shape, matvec=lambda r: inverse * r))
    if info != 0:
        return constrained.factorize(mass).solve(rhs)
    return x


def check_finite(array: np.ndarray, step: int, stage: str, name: str) -> None:
    """Stop at once when ``array`` holds NaN or Inf, naming step, stage and field."""
    bad = ~np.isfinite(array)
    if np.any(bad):
        raise SolverError(
            f"step {step}, stage {stage}: {name} is not finite in {np.count_nonzero(bad)} "
            f"of {array.size} entries; stopped before writing it"
        )


def initial_state(problem, law, ops: Operators, v0: np.ndarray | None,
                  constrained) -> State:
    """State at t = 0: at rest in the reference configuration (or moving with ``v0``), with
    the acceleration that balances the loads at t = 0 when there is mass."""
    n = problem.space.n_dofs
    u = np.zeros(n)
    u[constrained.dofs] = problem.prescribed(0.0)
    strain = ops.strain_operator.strain(u)
    stress, plastic, _ = law.update(strain, law.initial_state(ops.weights.shape))
    f_coh, _, cohesive = cohesive_force(ops, u, None)
    f_int = ops.strain_operator.internal_force(stress) + f_coh
    return starting_state(problem, ops, constrained, u, v0, (stress, plastic, cohesive), f_int)


def starting_state(problem, ops: Operators, constrained, u: np.ndarray,
                   v0: np.ndarray | None, material: tuple, f_int: np.ndarray) -> State:
    """The state at t = 0 at ``u`` (supports already at their values), moving with ``v0``
    (supports at rest), with ``material = (stress, plastic, cohesive)`` and its internal
    force ``f_int``: with mass, the acceleration that balances the loads at t = 0."""
    stress, plastic, cohesive = material
    v = np.zeros(problem.space.n_dofs) if v0 is None else np.array(v0, dtype=float)
    v[constrained.dofs] = 0.0  # supports start at rest
    a = np.zeros(problem.space.n_dofs)
    f_ext = problem.external_force(0.0)
    if ops.mass is None:
        return State(0.0, u, v, a, stress, plastic, f_int,
                     reaction(ops, constrained.dofs, f_int, f_ext), cohesive)
    a = balanced_acceleration(ops, constrained, f_int, f_ext, v, a)
    return State(0.0, u, v, a, stress, plastic, f_int,
                 reaction(ops, constrained.dofs, f_int, f_ext, v, a), cohesive)
