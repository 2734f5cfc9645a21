"""The step loop: march a model through time, reaching equilibrium in every step.

One implicit form covers static, quasi-static and implicit dynamic steps (see
:mod:`fem_frac.solve.integrators`); explicit central difference has its own update. Each step
evaluates the material law at every quadrature point through a strain operator built once,
and solves with a matrix factorized once per topology unless full Newton asks for the
consistent tangent.

Energy bookkeeping (trapezoidal work of every force, reactions included) makes the balance

    kinetic + elastic + plastic work + damping work - external work = initial energy

exact for Newmark average acceleration at converged equilibrium (any material), and a
measure of numerical dissipation for HHT and of O(dt^2) error for central difference.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp

from ..errors import SolverError
from ..plasticity.law import MaterialLaw
from ..plasticity.return_map import PlasticState
from .integrators import Implicit
from .linalg import Refactorizer, factorize
from .problem import Problem


@dataclass(frozen=True, eq=False)
class Operators:
    """What one topology provides: the strain operator (``strain``, ``internal_force``,
    ``stiffness``), the elastic stiffness, and the mass and damping matrices when there is
    inertia (``mass`` a sparse matrix, consistent or diagonal)."""

    strain_operator: object
    stiffness: sp.csr_matrix
    mass: sp.csr_matrix | None = None
    damping: sp.csr_matrix | None = None

    @property
    def weights(self) -> np.ndarray:
        return self.strain_operator.weights


@dataclass(frozen=True, eq=False)
class State:
    """Committed state at time ``t``. Vectors are ``(n_dofs,)``; ``stress`` Mandel
    ``(6, n_tets, n_qp)``; ``reaction`` is the support force on the constrained dofs
    ``(k,)``."""

    t: float
    u: np.ndarray
    v: np.ndarray
    a: np.ndarray
    stress: np.ndarray
    plastic: PlasticState | None
    internal_force: np.ndarray
    reaction: np.ndarray


@dataclass(frozen=True)
class Ledger:
    """Energies at the current step; works accumulated from t = 0."""

    kinetic: float = 0.0
    elastic: float = 0.0
    hardening: float = 0.0
    plastic_work: float = 0.0
    damping_work: float = 0.0
    external_work: float = 0.0
    initial: float = 0.0
    scale: float = 0.0
    # energy released by crack insertion where nothing else can take it (no inertia): the
    # imbalance of the steps retaken on a cracked mesh, see fem_frac.fracture.stage
    fracture: float = 0.0
    # kinetic and strain energy of pieces that left the finite elements as rigid bodies
    handed_off: float = 0.0

    @property
    def error(self) -> float:
        """kinetic + elastic + plastic work + damping work + fracture + handed off -
        external work - initial."""
        return (self.kinetic + self.elastic + self.plastic_work + self.damping_work
                + self.fracture + self.handed_off - self.external_work - self.initial)

    @property
    def relative_error(self) -> float:
        return abs(self.error) / self.scale if self.scale > 0 else 0.0

    @property
    def plastic_dissipation(self) -> float:
        """Plastic work less the energy stored by hardening."""
        return self.plastic_work - self.hardening


@dataclass(frozen=True)
class StepInfo:
    iterations: int
    residual: float
    solves: int = 0
    factorizations: int = 0
    cutbacks: int = 0
    insertions: int = 0  # crack sites opened in the step
    passes: int = 0  # re-solves of the step on a cracked mesh


@dataclass(frozen=True)
class Equilibrium:
    method: str = "modified_newton"
    tolerance: float = 1e-8
    max_iterations: int = 500
    acceleration: str = "anderson"
    cutbacks: int = 4


class NotConverged(SolverError):
    """Equilibrium iteration of one step stopped at its iteration cap."""


# A correction below this fraction of the displacement is round-off (a few hundred ulps).
ROUND_OFF = 1e-13
# Past corrections Anderson mixing keeps (Walker & Ni 2011 use 1 to 10; 5 is a common choice).
ANDERSON_DEPTH = 5


class Anderson:
    """Anderson acceleration of the fixed-point iteration u <- u + J0^-1 R(u) of modified
    Newton (Walker & Ni, SIAM J. Numer. Anal. 49, 2011): the next iterate combines the last
    ``depth`` iterates so as to minimize the linearized correction. The corrections are
    J0-preconditioned residuals already computed by the back-solve, so it costs a few dot
    products per iteration; a converged iteration is unchanged (the correction vanishes).
    """

    def __init__(self, depth: int):
        self.depth = depth
        self.u: list[np.ndarray] = []
        self.f: list[np.ndarray] = []

    def __call__(self, u: np.ndarray, f: np.ndarray) -> np.ndarray:
        """The step to take from ``u`` given the plain correction ``f``."""
        self.u.append(u.copy())
        self.f.append(f)
        if len(self.u) > self.depth + 1:
            self.u.pop(0)
            self.f.pop(0)
        if len(self.u) < 2:
            return f
        df = np.stack([b - a for a, b in zip(self.f[:-1], self.f[1:], strict=True)], axis=1)
        du = np.stack([b - a for a, b in zip(self.u[:-1], self.u[1:], strict=True)], axis=1)
        gamma, *_ = np.linalg.lstsq(df, f, rcond=1e-10)
        if not np.all(np.isfinite(gamma)):
            self.u, self.f = self.u[-1:], self.f[-1:]
            return f
        return f - (du + df) @ gamma


@dataclass
class Counters:
    steps: int = 0
    iterations: int = 0
    solves: int = 0
    factorizations: int = 0
    cutbacks: int = 0
    max_residual: float = 0.0
    solver: str = ""
    seconds: dict = field(default_factory=dict)


def _norm(x) -> float:
    """Euclidean norm without BLAS: ``np.linalg.norm`` goes through a threaded BLAS dot
    that costs milliseconds under contention for a vector that einsum sums in microseconds."""
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.einsum("i,i->", x, x))) if x.ndim else abs(float(x))


def check_finite(array: np.ndarray, step: int, stage: str, name: str) -> None:
    """Stop at once when ``array`` holds NaN or Inf, naming step, stage and field."""
    bad = ~np.isfinite(array)
    if np.any(bad):
        raise SolverError(
            f"step {step}, stage {stage}: {name} is not finite in {np.count_nonzero(bad)} "
            f"of {array.size} entries; stopped before writing it"
        )


class Constrained:
    """Free/constrained split of the dofs and factorizations of matrices restricted to the
    free dofs."""

    def __init__(self, problem: Problem, method: str):
        n = problem.space.n_dofs
        self.dofs = problem.constraints.dofs
        mask = np.ones(n, dtype=bool)
        mask[self.dofs] = False
        self.free = np.flatnonzero(mask)
        self.method = method

    def factorize(self, matrix: sp.csr_matrix, refactorizer: Refactorizer | None = None):
        """Factorization of ``matrix`` on the free dofs (through ``refactorizer`` when given,
        which reuses the symbolic analysis of its previous matrix)."""
        sub = matrix[self.free][:, self.free].tocsr()
        if refactorizer is not None:
            return refactorizer.factorize(sub)
        return factorize(sub, self.method)


def initial_state(problem: Problem, law: MaterialLaw, ops: Operators, v0: np.ndarray | None,
                  constrained: Constrained, method: str) -> State:
    """State at t = 0: at rest in the reference configuration (or moving with ``v0``), with
    the acceleration that balances the loads at t = 0 when there is mass."""
    n = problem.space.n_dofs
    u = np.zeros(n)
    u[problem.constraints.dofs] = problem.prescribed(0.0)
    shape = ops.weights.shape
    strain = ops.strain_operator.strain(u)
    stress, plastic, _ = law.update(strain, law.initial_state(shape))
    f_int = ops.strain_operator.internal_force(stress)
    v = np.zeros(n) if v0 is None else v0.copy()
    v[constrained.dofs] = 0.0  # supports start at rest
    a = np.zeros(n)
    f_ext = problem.external_force(0.0)
    unbalanced = f_ext - f_int - (ops.damping @ v if ops.damping is not None else 0.0)
    if ops.mass is not None and np.any(unbalanced[constrained.free]):
        solver = constrained.factorize(ops.mass)
        a[constrained.free] = solver.solve(unbalanced[constrained.free])
    reaction = (f_int - f_ext)[constrained.dofs]
    if ops.mass is not None:
        reaction = reaction + (ops.mass @ a + (ops.damping @ v if ops.damping is not None
                                               else 0.0))[constrained.dofs]
    return State(0.0, u, v, a, stress, plastic, f_int, reaction)


def initial_ledger(state: State, law: MaterialLaw, ops: Operators) -> Ledger:
    kinetic = 0.5 * state.v @ (ops.mass @ state.v) if ops.mass is not None else 0.0
    elastic = law.elastic_energy(state.stress, ops.weights)
    total = kinetic + elastic
    return Ledger(kinetic=kinetic, elastic=elastic, initial=total, scale=abs(total))


def _full_force(problem: Problem, t: float, reaction: np.ndarray) -> np.ndarray:
    f = problem.external_force(t)
    f[problem.constraints.dofs] += reaction
    return f


def account(ledger: Ledger, old: State, new: State, problem: Problem, law: MaterialLaw,
            ops: Operators) -> Ledger:
    """The ledger after the step ``old -> new`` (trapezoidal works)."""
    du = new.u - old.u
    f_old = _full_force(problem, old.t, old.reaction)
    f_new = _full_force(problem, new.t, new.reaction)
    external = ledger.external_work + 0.5 * (f_old + f_new) @ du
    damping = ledger.damping_work
    if ops.damping is not None:
        damping += 0.5 * (ops.damping @ (old.v + new.v)) @ du
    plastic_work = ledger.plastic_work
    if new.plastic is not None:
        dep = new.plastic.plastic_strain - old.plastic.plastic_strain
        plastic_work += 0.5 * float(np.sum(np.sum((old.stress + new.stress) * dep, axis=0)
                                           * ops.weights))
    kinetic = 0.5 * new.v @ (ops.mass @ new.v) if ops.mass is not None else 0.0
    elastic = law.elastic_energy(new.stress, ops.weights)
    hardening = law.hardening_energy(new.plastic, ops.weights)
    stored = kinetic + elastic + plastic_work + abs(damping)
    scale = max(ledger.scale, stored, abs(external))
    return Ledger(kinetic, elastic, hardening, plastic_work, damping, external,
                  ledger.initial, scale, ledger.fracture, ledger.handed_off)


class ImplicitStepper:
    """Steps of the implicit form (static, quasi-static, Newmark, HHT-alpha).

    ``modified_newton`` and ``single_pass`` solve with the elastic Jacobian factorized here,
    once; ``newton`` refactorizes the consistent tangent every iteration.
    """

    def __init__(self, problem: Problem, law: MaterialLaw, ops: Operators, scheme: Implicit,
                 equilibrium: Equilibrium, constrained: Constrained):
        self.problem, self.law, self.ops = problem, law, ops
        self.scheme, self.equilibrium, self.constrained = scheme, equilibrium, constrained
        # without inertia the step's matrix does not depend on its length, so a step that
        # fails to converge can be split in halves (up to ``cutbacks`` times) at no
        # refactorization; with inertia it would need a new factorization per length
        self.cutbacks = 0 if (ops.mass is not None and scheme.inertia) else equilibrium.cutbacks
        self.elastic_jacobian = self.jacobian(ops.stiffness)
        # K's columns of the constrained dofs: the force of moving prescribed values
        self.fixed_columns = ops.stiffness.tocsc()[:, constrained.dofs].tocsr()
        self.factor = None  # elastic Jacobian's factorization, made on first use
        self.tangents = None  # full Newton's refactorizer, made on first use
        self.factorizations = 0

    def jacobian(self, stiffness: sp.csr_matrix) -> sp.csr_matrix:
        s, ops = self.scheme, self.ops
        j = (1.0 + s.alpha) * stiffness
        if ops.mass is not None and s.inertia:
            j = j + s.c_mass * ops.mass
            if ops.damping is not None:
                j = j + (1.0 + s.alpha) * s.c_damping * ops.damping
        return j.tocsr()

    def elastic_factor(self):
        if self.factor is None:
            self.factor = self.constrained.factorize(self.elastic_jacobian)
            self.factorizations += 1
        return self.factor

    def step(self, old: State, t: float, step: int) -> tuple[State, StepInfo]:
        problem, law, ops, s = self.problem, self.law, self.ops, self.scheme
        free, fixed = self.constrained.free, self.constrained.dofs
        method = self.equilibrium.method
        inertia = ops.mass is not None and s.inertia
        alpha = s.alpha
        load = problem.external_force(t)
        check_finite(load, step, "loads", "external force")
        f_ext = (1.0 + alpha) * load
        damp_old = ops.damping @ old.v if (ops.damping is not None and inertia) else 0.0
        if alpha:
            f_ext = f_ext - alpha * problem.external_force(old.t)
        history = alpha * (damp_old + old.internal_force) if alpha else 0.0
        u_pred, v_pred = s.predict(old.u, old.v, old.a) if inertia else (old.u, old.v)
        f_ext_norm = _norm(f_ext)

        u = old.u.copy()
        u[fixed] = problem.prescribed(t)
        factor = self.elastic_factor()
        solves = factorizations = 0
        # First iterate: linearize the internal force about the committed state with the
        # elastic stiffness (exact when the step stays elastic), so a step that needs no
        # extra iteration costs one solve and one return map. Only prescribed dofs have
        # moved, so only their columns of K enter.
        moved = u[fixed] - old.u[fixed]
        f_int = old.internal_force
        if np.any(moved):
            f_int = f_int + self.fixed_columns @ moved
        stress, plastic, tangent = old.stress, old.plastic, None
        iterations, relative = 0, np.inf
        correction = np.zeros(len(free))
        accelerate = None
        if method == "modified_newton" and self.equilibrium.acceleration == "anderson":
            accelerate = Anderson(ANDERSON_DEPTH)
        while True:
            v, a = s.rates(u, u_pred, v_pred) if inertia else (old.v, old.a)
            inertial = ops.mass @ a if inertia else 0.0
            damping = ops.damping @ v if (ops.damping is not None and inertia) else 0.0
            residual = f_ext - inertial - (1.0 + alpha) * (damping + f_int) + history
            if iterations > 0:
                scale = max(f_ext_norm, (1.0 + alpha) * _norm(f_int), _norm(inertial), 1e-300)
                relative = _norm(residual[free]) / scale
                if not np.isfinite(relative):
                    _diagnose(step, u, stress, residual)
                if relative <= self.equilibrium.tolerance or method == "single_pass":
                    break
                if _norm(correction) <= ROUND_OFF * _norm(u[free]):
                    # the last correction moved nothing beyond round-off, so no iteration
                    # can reduce the residual: it is round-off too, left relative to forces
                    # that are themselves round-off (a body cut free under prescribed
                    # displacements carries nothing: f_ext = f_int = 0); reported against
                    # the force of the prescribed motion on the free dofs
                    prescribed = _norm((self.fixed_columns @ u[fixed])[free])
                    relative = _norm(residual[free]) / max(scale, prescribed)
                    break
                if iterations >= self.equilibrium.max_iterations:
                    raise NotConverged(
                        f"step {step} (t = {t:.6g}): equilibrium not reached in {iterations} "
                        f"iterations of {method} (relative residual {relative:.2e} > "
                        f"tolerance {self.equilibrium.tolerance:g}); take smaller steps"
                        + (", or use analysis.equilibrium.method: newton"
                           if method != "newton" else "")
                    )
                if method == "newton" and law.plastic:
                    # refactorize only when the iterate is not yet converged
                    if self.tangents is None:
                        self.tangents = Refactorizer(self.constrained.method)
                    try:
                        factor = self.constrained.factorize(
                            self.jacobian(ops.strain_operator.stiffness(tangent)),
                            self.tangents)
                    except SolverError:
                        raise NotConverged(
                            f"step {step} (t = {t:.6g}): the consistent tangent became "
                            f"singular after {iterations} iterations of newton (relative "
                            f"residual {relative:.2e}): the plastic zone forms a mechanism"
                        ) from None
                    factorizations += 1
            correction = factor.solve(residual[free])
            solves += 1
            if accelerate is not None:
                correction = accelerate(u[free], correction)
            u[free] += correction
            strain = ops.strain_operator.strain(u)
            stress, plastic, tangent = law.update(strain, old.plastic,
                                                  tangent=(method == "newton"))
            f_int = ops.strain_operator.internal_force(stress)
            iterations += 1
        v, a = s.rates(u, u_pred, v_pred) if inertia else (np.zeros_like(u), np.zeros_like(u))
        reaction = (f_int - load)[fixed]
        if inertia:
            reaction = reaction + (ops.mass @ a)[fixed]
            if ops.damping is not None:
                reaction = reaction + (ops.damping @ v)[fixed]
        new = State(t, u, v, a, stress, plastic, f_int, reaction)
        return new, StepInfo(iterations, relative, solves, factorizations)


def _diagnose(step: int, u: np.ndarray, stress: np.ndarray, residual: np.ndarray) -> None:
    """Name the first non-finite field of an iterate whose residual norm is not finite."""
    check_finite(u, step, "solve", "displacement")
    check_finite(stress, step, "return map", "stress")
    check_finite(residual, step, "equilibrium", "residual force")
    raise SolverError(f"step {step}, stage equilibrium: the residual norm overflowed")


class ExplicitStepper:
    """Central difference (velocity Verlet) with a lumped (diagonal) mass; no solve.

    Damping uses the half-step velocity. Prescribed dofs follow their curves, with the
    velocity of the prescribed motion and zero acceleration. ``substeps`` stable steps are
    taken per step of the time grid (see :func:`march`).
    """

    def __init__(self, problem: Problem, law: MaterialLaw, ops: Operators, dt: float,
                 substeps: int, constrained: Constrained):
        self.problem, self.law, self.ops = problem, law, ops
        self.dt, self.substeps, self.constrained = dt, substeps, constrained
        self.inverse_mass = 1.0 / ops.mass.diagonal()

    def step(self, old: State, t: float, step: int) -> tuple[State, StepInfo]:
        """One step of central difference from ``old.t`` to ``t`` (a substep of the loop)."""
        problem, ops, law = self.problem, self.ops, self.law
        fixed = self.constrained.dofs
        h = t - old.t
        v_half = old.v + 0.5 * h * old.a
        u = old.u + h * v_half
        u[fixed] = problem.prescribed(t)
        v_half[fixed] = (u[fixed] - old.u[fixed]) / h
        check_finite(u, step, "explicit update", "displacement")
        stress, plastic, _ = law.update(ops.strain_operator.strain(u), old.plastic)
        check_finite(stress, step, "return map", "stress")
        f_int = ops.strain_operator.internal_force(stress)
        damping = ops.damping @ v_half if ops.damping is not None else 0.0
        load = problem.external_force(t)
        check_finite(load, step, "loads", "external force")
        force = load - f_int - damping
        a = force * self.inverse_mass
        a[fixed] = 0.0
        v = v_half + 0.5 * h * a
        return State(t, u, v, a, stress, plastic, f_int, -force[fixed]), StepInfo(1, 0.0)


Observer = Callable[[int, State, Ledger, StepInfo], None]


def advance(stepper, state: State, start: float, end: float, ledger: Ledger, problem: Problem,
            law: MaterialLaw, ops: Operators, n: int) -> tuple[State, Ledger, StepInfo]:
    """Step ``state`` (at ``start``) to ``end``: the interval ``n`` of the time grid.

    A stepper with ``substeps > 1`` takes that many equal steps, each one accounted in the
    energy ledger. A stepper with ``cutbacks > 0`` halves a step whose equilibrium iteration
    fails, up to that many times.
    """
    substeps = getattr(stepper, "substeps", 1)
    max_cutbacks = getattr(stepper, "cutbacks", 0)
    iterations = cutbacks = solves = factorizations = 0
    # targets still to reach, the next one last; a step that does not converge is
    # split in two by pushing its midpoint (cutback), down to 2^-max_cutbacks of it
    pending = [end if k == substeps else start + (end - start) * k / substeps
               for k in range(substeps, 0, -1)]
    shortest = (end - start) / substeps / 2**max_cutbacks
    info = StepInfo(0, 0.0)
    while pending:
        t = pending[-1]
        try:
            # overflow becomes inf/NaN, which the steppers' finiteness checks stop at once
            with np.errstate(over="ignore", invalid="ignore"):
                new, info = stepper.step(state, t, n)
        except NotConverged as exc:
            if max_cutbacks == 0:
                raise
            if (t - state.t) / 2 < shortest * (1 - 1e-9):
                raise NotConverged(
                    f"{exc} (after {cutbacks} cutbacks, down to a step of "
                    f"{t - state.t:.3g}; the load may exceed what the structure carries)"
                ) from None
            pending.append(0.5 * (state.t + t))
            cutbacks += 1
            continue
        pending.pop()
        ledger = account(ledger, state, new, problem, law, ops)
        state = new
        iterations += info.iterations
        solves += info.solves
        factorizations += info.factorizations
    info = replace(info, iterations=iterations, solves=solves,
                   factorizations=factorizations, cutbacks=cutbacks)
    return state, ledger, info


@dataclass(frozen=True, eq=False)
class System:
    """What a topology change replaces: the problem, operators and stepper on a new mesh."""

    problem: Problem
    ops: Operators
    stepper: object
    law: MaterialLaw


# ``after_step(n, start, start_ledger, end, ledger, info)``: a stage run between steps (crack
# insertion) that may retake the step on a new topology; returns ``(end, ledger, info,
# system)``, ``system`` None when the topology is unchanged.
AfterStep = Callable[..., tuple]


def march(stepper, state: State, times: np.ndarray, problem: Problem, law: MaterialLaw,
          ops: Operators, observe: Observer, counters: Counters,
          after_step: AfterStep | None = None) -> tuple[State, Ledger]:
    """Take the steps to ``times[1:]``; ``observe`` sees every committed step (and step 0).

    Each interval is taken by :func:`advance` (substeps, cutbacks); ``after_step`` then
    sees it and may replace the system (see :data:`AfterStep`) for the steps that follow.
    """
    ledger = initial_ledger(state, law, ops)
    observe(0, state, ledger, StepInfo(0, 0.0))
    for n in range(1, len(times)):
        t0 = time.perf_counter()
        start, end = float(times[n - 1]), float(times[n])
        first, first_ledger = state, ledger
        state, ledger, info = advance(stepper, state, start, end, ledger, problem, law, ops, n)
        if after_step is not None:
            state, ledger, info, system = after_step(n, first, first_ledger, state, ledger,
                                                     info)
            if system is not None:
                stepper, problem, ops, law = system.stepper, system.problem, system.ops, \
                    system.law
        counters.steps += 1
        counters.iterations += info.iterations
        counters.solves += info.solves
        counters.factorizations += info.factorizations
        counters.cutbacks += info.cutbacks
        counters.max_residual = max(counters.max_residual, info.residual)
        counters.seconds["steps"] = counters.seconds.get("steps", 0.0) + time.perf_counter() - t0
        observe(n, state, ledger, info)
    return state, ledger
