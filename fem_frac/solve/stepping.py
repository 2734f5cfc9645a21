"""Steppers: take a discretization's state from one time to the next, in equilibrium.

One implicit form covers static, quasi-static and implicit dynamic steps (see
:mod:`fem_frac.solve.integrators`); explicit central difference has its own update. Each
step evaluates the material law at every quadrature point through a strain operator built
once, and solves with a matrix factorized once per topology (:mod:`fem_frac.solve.bordered`
reuses it across crack insertions) unless full Newton asks for the consistent tangent.
:func:`advance` takes one interval of the time grid (substeps, cutbacks) and keeps the
energy ledger (:mod:`fem_frac.solve.energy`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..config.schema import Equilibrium
from ..errors import SolverError
from . import convergence
from .convergence import ANDERSON_DEPTH, Anderson, contraction, iterations_left, norm
from .energy import Ledger, account
from .integrators import Implicit
from .refactorizer import Refactorizer
from .state import Operators, State, StepInfo, check_finite, cohesive_force, reaction

# A correction below this fraction of the displacement is round-off (a few hundred ulps).
ROUND_OFF = 1e-13
# Halvings of a full Newton correction tried before falling back on the secant stiffness.
LINE_SEARCH_HALVINGS = 4
# Iterations on one secant factorization before the secant of the latest iterate replaces it.
SECANT_REFRESH = 25


class NotConverged(SolverError):
    """Equilibrium iteration of one step stopped at its iteration cap (or was predicted
    to). ``converged`` is ``(state, ledger)`` of the last sub-step a cut-back step
    converged before it stopped (``None`` when it converged none); ``substeps``, what the
    caller that kept them adds (the equilibrium stage: every converged sub-step's world)."""

    converged: tuple | None = None
    substeps: tuple = ()


@dataclass
class _Iterate:
    """The equilibrium iteration of one step, as it goes."""

    u: np.ndarray
    f_int: np.ndarray
    stress: np.ndarray
    plastic: object
    factor: object
    tangent: np.ndarray | None = None
    iterations: int = 0
    relative: float = np.inf
    correction: np.ndarray | None = None
    solves: int = 0
    factorizations: int = 0
    cohesive: object = None  # the cohesive faces' state at the iterate
    cohesive_tangent: np.ndarray | None = None
    cohesive_secant: np.ndarray | None = None
    secant: bool = False  # full Newton fell back on the faces' secant stiffness
    frozen: bool = False  # and iterates on with that factorization (Anderson-accelerated)
    frozen_at: int = -1  # the iteration that factorization was made at
    newton: bool = False  # iterating with the consistent tangent (full Newton)
    switched_at: int = -1  # the iteration modified Newton switched to full Newton at
    residuals: list = field(default_factory=list)  # relative residuals since the switch


@dataclass(frozen=True, eq=False)
class _Target:
    """What a step's iterates are measured against: the load at the new time, the force
    the residual balances (HHT-weighted), and the predictor."""

    load: np.ndarray
    f_ext: np.ndarray
    history: np.ndarray | float
    u_pred: np.ndarray
    v_pred: np.ndarray
    norm: float


class ImplicitStepper:
    """Steps of the implicit form (static, quasi-static, Newmark, HHT-alpha).

    ``modified_newton`` and ``single_pass`` solve with the elastic Jacobian factorized here,
    once (after an insertion, through the old mesh's: :mod:`fem_frac.solve.bordered`);
    ``newton`` refactorizes the consistent tangent every iteration. With cohesive crack
    faces the iteration matrix of the first two also holds the faces' secant
    stiffness at the start of the step (never negative: the iteration contracts while the
    structure is stable), refactorized when damage has changed it. Full Newton iterates
    with the faces' consistent tangent and a backtracking line search (the law's kinks, at
    the peak and from loading to unloading, make full steps cycle); where even the shortest
    step fails to reduce the residual, or where softening faces make the tangent indefinite,
    the step goes on as modified Newton with the secant stiffness of that iterate and
    Anderson acceleration, the secant refactorized every ``SECANT_REFRESH`` iterations.
    """

    def __init__(self, problem, law, ops: Operators, scheme: Implicit,
                 equilibrium: Equilibrium, constrained):
        self.problem, self.law, self.ops = problem, law, ops
        self.scheme, self.equilibrium, self.constrained = scheme, equilibrium, constrained
        self.inertia = ops.mass is not None and scheme.inertia
        # without inertia the step's matrix does not depend on its length, so a step that
        # fails to converge can be split in halves (up to ``cutbacks`` times) at no
        # refactorization; with inertia it would need a new factorization per length
        self.cutbacks = 0 if self.inertia else equilibrium.cutbacks
        self.substeps = 1
        self.elastic_jacobian = self.jacobian(ops.stiffness)
        # K's columns of the constrained dofs: the force of moving prescribed values
        self.fixed_columns = ops.stiffness.tocsr()[:, constrained.dofs].tocsr()
        self.factor = None  # elastic Jacobian's factorization, made on first use
        self.seed = None  # after an insertion: (old factorization, tie) (solve.bordered)
        # full Newton's tangents' and the cohesive secants' refactorizers (made on first
        # use): a secant's pattern stays from step to step as the faces soften
        self.tangents = self.secants = None
        self.secant = None  # the cohesive secant stiffness ``self.factor`` holds
        # the step whose (sub-)steps iterate with full Newton since modified Newton
        # switched to it (the limit-load rule)
        self.newton_step = None

    def jacobian(self, stiffness: sp.csr_matrix) -> sp.csr_matrix:
        s, ops = self.scheme, self.ops
        j = stiffness if s.alpha == 0.0 else (1.0 + s.alpha) * stiffness  # no copy of K
        if self.inertia:
            j = j + s.c_mass * ops.mass
            if ops.damping is not None:
                j = j + (1.0 + s.alpha) * s.c_damping * ops.damping
        return j.tocsr()

    def elastic_factor(self):
        """The elastic Jacobian's factorization (made on the first call): through the
        previous mesh's where :attr:`seed` allows (:mod:`fem_frac.solve.bordered`), else
        afresh."""
        if self.factor is None and self.seed is not None:
            from .bordered import bordered_factor

            (base, tie), self.seed = self.seed, None
            free = self.constrained.free
            self.factor = bordered_factor(base, tie, self.elastic_jacobian, free=free)
        if self.factor is None:
            self.factor = self.constrained.factorize(self.elastic_jacobian)
        return self.factor

    def iteration_factor(self, old: State):
        """The factorization modified Newton iterates with from ``old``: the elastic
        Jacobian, plus the cohesive faces' secant stiffness at ``old``; ``(factor, made)``."""
        interface = self.ops.interface
        if interface is None:
            made = self.factor is None
            return self.elastic_factor(), made
        secant = old.cohesive.secant
        if secant is None:
            secant = interface.respond(old.u, old.cohesive.kappa)[0].secant
        if self.factor is not None and np.allclose(secant, self.secant, rtol=1e-12,
                                                   atol=0.0):
            return self.factor, False
        self.secant = secant
        self.secants = self.secants or Refactorizer(self.constrained.method)
        self.factor = self.constrained.factorize(  # (replaces the last secant's)
            self.jacobian(self.ops.stiffness + interface.matrix(secant)), self.secants)
        return self.factor, True

    def step(self, old: State, t: float, step: int) -> tuple[State, StepInfo]:
        target = self._target(old, t, step)
        it = self._first_iterate(old, t)
        method = self.equilibrium.method
        if method == "newton" or self.newton_step == step:
            it.newton, it.switched_at = True, (0 if method != "newton" else -1)
        accelerate = None
        if (method == "modified_newton" and self.equilibrium.acceleration == "anderson"
                and not it.newton):
            accelerate = Anderson(ANDERSON_DEPTH)
        while True:
            residual, scale = self._residual(it, old, target)
            if it.iterations > 0:
                if self._converged(it, residual, scale, t, step):
                    break
                if self._near_limit(it, old, t, step):
                    accelerate = None  # full Newton's corrections are not mixed
                self._tangent(it, t, step)
            it.correction = it.factor.solve(residual[self.constrained.free])
            it.solves += 1
            free = self.constrained.free
            if it.secant and (accelerate is None or it.frozen_at == it.iterations):
                accelerate = Anderson(ANDERSON_DEPTH)  # on the secant just factorized
            if accelerate is not None:
                it.correction = accelerate(it.u[free], it.correction)
            if self.ops.interface is not None and it.newton and not it.secant:
                self._search(it, old, target)
            else:
                it.u[free] += it.correction
                self._update(it, old)
            it.iterations += 1
        return self._commit(it, old, target, t)

    def _update(self, it: _Iterate, old: State) -> None:
        """The material's response at the iterate's displacement: stresses, plastic state,
        internal force (cohesive faces included) and, for full Newton, the tangents."""
        strain = self.ops.strain_operator.strain(it.u)
        it.stress, it.plastic, it.tangent = self.law.update(strain, old.plastic,
                                                            tangent=it.newton)
        it.f_int = self.ops.strain_operator.internal_force(it.stress)
        if self.ops.interface is not None:
            f_coh, response, it.cohesive = cohesive_force(self.ops, it.u, old.cohesive)
            it.f_int = it.f_int + f_coh
            it.cohesive_tangent, it.cohesive_secant = response.tangent, response.secant

    def _search(self, it: _Iterate, old: State, target: _Target) -> None:
        """Full Newton with cohesive faces: the correction, halved up to
        ``LINE_SEARCH_HALVINGS`` times until the residual decreases (the law's kinks make a
        full step overshoot); without a decrease the smallest step is taken and the step goes
        on with the faces' secant stiffness (:meth:`step`)."""
        free = self.constrained.free
        base, correction = it.u[free].copy(), it.correction
        before = norm(self._residual(it, old, target)[0][free]) if it.iterations else np.inf
        for k in range(LINE_SEARCH_HALVINGS + 1):
            it.u[free] = base + 0.5**k * correction
            self._update(it, old)
            if norm(self._residual(it, old, target)[0][free]) < before:
                break
        else:
            it.secant = True
        it.correction = it.u[free] - base

    def _target(self, old: State, t: float, step: int) -> _Target:
        alpha, s = self.scheme.alpha, self.scheme
        load = self.problem.external_force(t)
        check_finite(load, step, "loads", "external force")
        f_ext = (1.0 + alpha) * load
        damp_old = self.ops.damping @ old.v if (
            self.ops.damping is not None and self.inertia) else 0.0
        if alpha:
            f_ext = f_ext - alpha * self.problem.external_force(old.t)
        history = alpha * (damp_old + old.internal_force) if alpha else 0.0
        u_pred, v_pred = s.predict(old.u, old.v, old.a) if self.inertia else (old.u, old.v)
        return _Target(load, f_ext, history, u_pred, v_pred, norm(f_ext))

    def _first_iterate(self, old: State, t: float) -> _Iterate:
        """Linearize the internal force about the committed state with the elastic
        stiffness (exact when the step stays elastic), so a step that needs no extra
        iteration costs one solve and one return map. Only prescribed dofs have moved, so
        only their columns of K enter."""
        fixed = self.constrained.dofs
        u = old.u.copy()
        u[fixed] = self.problem.prescribed(t)
        moved = u[fixed] - old.u[fixed]
        f_int = old.internal_force
        if np.any(moved):
            f_int = f_int + self.fixed_columns @ moved
        factor, made = self.iteration_factor(old)
        return _Iterate(u, f_int, old.stress, old.plastic, factor,
                        correction=np.zeros(len(self.constrained.free)),
                        factorizations=int(made), cohesive=old.cohesive)

    def _rates(self, u: np.ndarray, old: State, target: _Target):
        if self.inertia:
            return self.scheme.rates(u, target.u_pred, target.v_pred)
        return old.v, old.a

    def _residual(self, it: _Iterate, old: State, target: _Target):
        """The residual force of the iterate and the force scale it is measured against."""
        alpha = self.scheme.alpha
        v, a = self._rates(it.u, old, target)
        inertial = self.ops.mass @ a if self.inertia else 0.0
        damping = self.ops.damping @ v if (self.ops.damping is not None and self.inertia) \
            else 0.0
        residual = target.f_ext - inertial - (1.0 + alpha) * (damping + it.f_int) \
            + target.history
        scale = max(target.norm, (1.0 + alpha) * norm(it.f_int), norm(inertial), 1e-300)
        return residual, scale

    def _converged(self, it: _Iterate, residual: np.ndarray, scale: float, t: float,
                   step: int) -> bool:
        """Whether the iteration stops here (``it.relative`` set, and recorded when it goes
        on); raises when it cannot go on."""
        free, fixed = self.constrained.free, self.constrained.dofs
        method = self.equilibrium.method
        it.relative = norm(residual[free]) / scale
        if not np.isfinite(it.relative):
            _diagnose(step, it.u, it.stress, residual)
        if it.relative <= self.equilibrium.tolerance or method == "single_pass":
            return True
        if norm(it.correction) <= ROUND_OFF * norm(it.u[free]):
            # the last correction moved nothing beyond round-off, so no iteration can
            # reduce the residual: it is round-off too, left relative to forces that are
            # themselves round-off (a body cut free under prescribed displacements carries
            # nothing: f_ext = f_int = 0); reported against the force of the prescribed
            # motion on the free dofs
            prescribed = norm((self.fixed_columns @ it.u[fixed])[free])
            it.relative = norm(residual[free]) / max(scale, prescribed)
            return True
        if it.iterations >= self.equilibrium.max_iterations:
            raise NotConverged(self._not_reached(it, t, step, f"in {it.iterations} "
                                                 "iterations"))
        it.residuals.append(it.relative)
        return False

    def _not_reached(self, it: _Iterate, t: float, step: int, how: str) -> str:
        """The message of a step whose equilibrium iteration stops ``how``."""
        method = self.equilibrium.method
        switched = (f", full Newton from iteration {it.switched_at}"
                    if method == "modified_newton" and it.switched_at >= 0 else "")
        advice = ", or use analysis.equilibrium.method: newton" if not it.newton else ""
        return (f"step {step} (t = {t:.6g}): equilibrium not reached {how} of {method}"
                f"{switched} (relative residual {it.relative:.2e} > tolerance "
                f"{self.equilibrium.tolerance:g}); take smaller steps{advice}")

    def _near_limit(self, it: _Iterate, old: State, t: float, step: int) -> bool:
        """Modified Newton's rule near a limit load (docs/solvers.md): where the residual's
        contraction over the last iterations predicts more iterations than the cap allows,
        the step (and the sub-steps left of it) goes on with full Newton; where full Newton
        too is predicted past the cap, the step gives up at once (for a cut-back). True
        when it switched."""
        eq = self.equilibrium
        if eq.method != "modified_newton":
            return False
        more = iterations_left(it.residuals, eq.tolerance, convergence.RATE_WINDOW)
        if more is None or it.iterations + more <= eq.max_iterations:
            return False
        if it.newton:
            rate = contraction(it.residuals, convergence.RATE_WINDOW)
            raise NotConverged(self._not_reached(
                it, t, step, f"after {it.iterations} iterations (the residual contracted "
                f"by {rate:.3g} an iteration over the last {convergence.RATE_WINDOW}: "
                + (f"{more:.0f} more" if math.isfinite(more) else "no number of")
                + f" iterations would reach the tolerance, {eq.max_iterations} are allowed)"))
        it.newton, it.switched_at, it.residuals = True, it.iterations, []
        self.newton_step = step
        self._update(it, old)  # the consistent tangent at the iterate
        return True

    def _tangent(self, it: _Iterate, t: float, step: int) -> None:
        """Full Newton's matrix for the next correction (modified Newton keeps its own)."""
        if it.frozen and it.iterations - it.frozen_at >= SECANT_REFRESH:
            it.frozen = False  # the secant of an iterate closer to equilibrium
        if it.newton and (self.law.plastic or self.ops.interface is not None) \
                and not it.frozen:
            self._refactorize(it, t, step)

    def _refactorize(self, it: _Iterate, t: float, step: int) -> None:
        """Full Newton: factorize the consistent tangent of the iterate (bulk and cohesive
        faces)."""
        self.tangents = self.tangents or Refactorizer(self.constrained.method)
        # an elastic bulk's tangent is the stiffness assembled once
        stiffness = self.ops.stiffness if it.tangent is None or not self.law.plastic else \
            self.ops.strain_operator.stiffness(it.tangent)
        if it.cohesive_tangent is not None:
            faces = it.cohesive_secant if it.secant else it.cohesive_tangent
            it.frozen = it.secant
            it.frozen_at = it.iterations
            stiffness = stiffness + self.ops.interface.matrix(faces)
        try:
            it.factor = self.constrained.factorize(self.jacobian(stiffness), self.tangents)
        except SolverError:
            if it.cohesive_tangent is not None and not it.secant:
                # softening faces made the tangent indefinite: go on with their secant
                it.secant = True
                self._refactorize(it, t, step)
                return
            how = ("newton" if it.switched_at < 0 else
                   f"modified_newton, full Newton from iteration {it.switched_at}")
            raise NotConverged(
                f"step {step} (t = {t:.6g}): the consistent tangent became singular after "
                f"{it.iterations} iterations of {how} (relative residual "
                f"{it.relative:.2e}): the plastic zone forms a mechanism") from None
        it.factorizations += 1

    def _commit(self, it: _Iterate, old: State, target: _Target,
                t: float) -> tuple[State, StepInfo]:
        u = it.u
        if self.inertia:
            v, a = self.scheme.rates(u, target.u_pred, target.v_pred)
            r = reaction(self.ops, self.constrained.dofs, it.f_int, target.load, v, a)
        else:
            v, a = np.zeros_like(u), np.zeros_like(u)
            r = reaction(self.ops, self.constrained.dofs, it.f_int, target.load)
        new = State(t, u, v, a, it.stress, it.plastic, it.f_int, r, it.cohesive)
        return new, StepInfo(it.iterations, it.relative, it.solves, it.factorizations)


def _diagnose(step: int, u: np.ndarray, stress: np.ndarray, residual: np.ndarray) -> None:
    """Name the first non-finite field of an iterate whose residual norm is not finite."""
    check_finite(u, step, "solve", "displacement")
    check_finite(stress, step, "return map", "stress")
    check_finite(residual, step, "equilibrium", "residual force")
    raise SolverError(f"step {step}, stage equilibrium: the residual norm overflowed")


class ExplicitStepper:
    """Central difference (velocity Verlet) with a lumped (diagonal) mass; no solve.

    Damping uses the half-step velocity. Prescribed dofs follow their curves, with the
    velocity of the last step's prescribed motion and zero acceleration; the reaction is
    the force the body transmits (``State.reaction_inertia`` false: the ledger books the
    driver's work on the supports' own masses as the change of their kinetic energy).
    ``substeps`` stable steps are taken per step of the time grid (see :func:`advance`).
    """

    cutbacks = 0

    def __init__(self, problem, law, ops: Operators, dt: float, substeps: int,
                 constrained):
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
        f_coh, _, cohesive = cohesive_force(ops, u, old.cohesive)
        f_int = ops.strain_operator.internal_force(stress) + f_coh
        damping = ops.damping @ v_half if ops.damping is not None else 0.0
        load = problem.external_force(t)
        check_finite(load, step, "loads", "external force")
        force = load - f_int - damping
        a = force * self.inverse_mass
        a[fixed] = 0.0
        v = v_half + 0.5 * h * a
        return (State(t, u, v, a, stress, plastic, f_int, -force[fixed], cohesive,
                      reaction_inertia=False), StepInfo(1, 0.0))


Stepper = ImplicitStepper | ExplicitStepper


def advance(stepper: Stepper, state: State, end: float, ledger: Ledger, n: int,
            substep=None) -> tuple[State, Ledger, StepInfo]:
    """Step ``state`` to ``end``: the interval ``n`` of the time grid.

    A stepper with ``substeps > 1`` takes that many equal steps, each one accounted in the
    energy ledger. A stepper with ``cutbacks > 0`` halves a step whose equilibrium iteration
    fails, down to ``cutbacks`` levels (a sub-step of 2^-cutbacks of the interval); the
    :class:`StepInfo` counts the halvings. ``substep(state, ledger, info)`` sees every
    sub-step a cut-back interval converged before its end; a :class:`NotConverged` raised
    from a cut-back interval carries the last one (``converged``).
    """
    start = state.t
    substeps, levels = stepper.substeps, stepper.cutbacks
    # targets still to reach, the next one last; a step that does not converge is
    # split in two by pushing its midpoint (cutback), down to 2^-levels of it
    pending = [end if k == substeps else start + (end - start) * k / substeps
               for k in range(substeps, 0, -1)]
    shortest = (end - start) / substeps / 2**levels
    total = StepInfo(0, 0.0)
    cutbacks = tried = 0
    while pending:
        t = pending[-1]
        tried += 1
        try:
            # overflow becomes inf/NaN, which the steppers' finiteness checks stop at once
            with np.errstate(over="ignore", invalid="ignore"):
                new, info = stepper.step(state, t, n)
        except NotConverged as exc:
            if levels == 0:
                raise
            if (t - state.t) / 2 < shortest * (1 - 1e-9):
                raise _cut_back_out(exc, levels, cutbacks, tried, shortest, state, ledger,
                                    start) from None
            pending.append(0.5 * (state.t + t))
            cutbacks += 1
            continue
        pending.pop()
        ledger = account(ledger, state, new, stepper.problem, stepper.law, stepper.ops)
        state = new
        total = total.then(info)
        if substep is not None and cutbacks and pending:
            substep(state, ledger, info)
    return state, ledger, StepInfo(total.iterations, total.residual, total.solves,
                                   total.factorizations, cutbacks)


def _cut_back_out(exc: NotConverged, levels: int, cutbacks: int, tried: int,
                  shortest: float, state: State, ledger: Ledger,
                  start: float) -> NotConverged:
    """The failure of an interval cut back as far as it may: how far, what was tried, the
    last converged sub-step (carried for the output)."""
    done = f"; the last converged at t = {state.t:.6g}" if state.t > start else \
        "; none converged"
    out = NotConverged(
        f"{exc} (after {levels} levels of cut-back: {cutbacks} halvings, {tried} sub-steps "
        f"tried down to dt = {shortest:.3g}{done}; the load may exceed what the structure "
        "carries)")
    out.converged = (state, ledger) if state.t > start else None
    return out
