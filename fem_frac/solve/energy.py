"""The energy ledger: energies at the current step, works accumulated from t = 0.

Trapezoidal work of every force, reactions included, makes the balance

    kinetic + elastic + plastic work + damping work + cohesive work - external work
        - contact work = initial energy

(the cohesive work is the trapezoidal work of the crack faces' tractions on their jumps,
the energy they store plus the energy they dissipate)

exact for Newmark average acceleration at converged equilibrium (any material), and a
measure of numerical dissipation for HHT and of O(dt^2) error for central difference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .state import Operators, State


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
    # of which the energy of their motion about the rigid motion (vibration and strain)
    vibration_removed: float = 0.0
    # cohesive crack faces: the work of their tractions (trapezoidal, from t = 0), and at the
    # current step the energy they store and the energy their law has dissipated
    cohesive_work: float = 0.0
    cohesive_stored: float = 0.0
    cohesive_dissipated: float = 0.0
    # contact with rigid bodies (fem_frac.rigid.deformable): the work of their impulses on
    # the finite elements (the kinetic energy each exchange gave them, from t = 0), and the
    # kinetic energy the exchanges removed from both sides together
    contact_work: float = 0.0
    contact_dissipated: float = 0.0

    @property
    def error(self) -> float:
        """kinetic + elastic + plastic work + damping work + cohesive work + fracture +
        handed off - external work - contact work - initial."""
        return (self.kinetic + self.elastic + self.plastic_work + self.damping_work
                + self.cohesive_work + self.fracture + self.handed_off
                - self.external_work - self.contact_work - self.initial)

    @property
    def relative_error(self) -> float:
        return abs(self.error) / self.scale if self.scale > 0 else 0.0

    @property
    def plastic_dissipation(self) -> float:
        """Plastic work less the energy stored by hardening."""
        return self.plastic_work - self.hardening


def initial_ledger(state: State, law, ops: Operators) -> Ledger:
    kinetic = 0.5 * state.v @ (ops.mass @ state.v) if ops.mass is not None else 0.0
    elastic = law.elastic_energy(state.stress, ops.weights)
    stored = state.cohesive.stored if state.cohesive is not None else 0.0
    total = kinetic + elastic + stored
    return Ledger(kinetic=kinetic, elastic=elastic, initial=total, scale=abs(total),
                  cohesive_stored=stored)


def cohesive_work(old: State, new: State, ops: Operators) -> float:
    """Trapezoidal work of the cohesive tractions on the jumps of the step ``old -> new``."""
    if new.cohesive is None or old.cohesive is None or ops.interface is None:
        return 0.0
    a, b = old.cohesive, new.cohesive
    return 0.5 * float(ops.interface.weights
                       @ np.einsum("pi,pi->p", a.traction + b.traction, b.jump - a.jump))


def _full_force(problem, t: float, reaction: np.ndarray) -> np.ndarray:
    f = problem.external_force(t)
    f[problem.constraints.dofs] += reaction
    return f


def support_kinetic(state: State, ops: Operators, fixed: np.ndarray) -> float:
    """Kinetic energy ``v_c m_c v_c / 2`` of the constrained dofs' own (diagonal) masses."""
    if ops.mass is None:
        return 0.0
    v = state.v[fixed]
    return 0.5 * float(v @ (ops.mass.diagonal()[fixed] * v))


def account(ledger: Ledger, old: State, new: State, problem, law, ops: Operators) -> Ledger:
    """The ledger after the step ``old -> new`` (trapezoidal works).

    When ``new.reaction_inertia`` is false (an explicit step) the reactions are the force
    the body transmits: the supports' own lumped masses move as prescribed, and the work
    the driver does on them is the change of their kinetic energy, booked as such (see
    docs/dynamics.md, Energy).
    """
    du = new.u - old.u
    f_old = _full_force(problem, old.t, old.reaction)
    f_new = _full_force(problem, new.t, new.reaction)
    external = ledger.external_work + 0.5 * (f_old + f_new) @ du
    if not new.reaction_inertia:
        fixed = problem.constraints.dofs
        external += support_kinetic(new, ops, fixed) - support_kinetic(old, ops, fixed)
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
    cohesive = ledger.cohesive_work + cohesive_work(old, new, ops)
    faces = new.cohesive
    stored = kinetic + elastic + plastic_work + abs(damping) + abs(cohesive)
    scale = max(ledger.scale, stored, abs(external))
    return Ledger(kinetic, elastic, hardening, plastic_work, damping, external,
                  ledger.initial, scale, ledger.fracture, ledger.handed_off,
                  ledger.vibration_removed, cohesive,
                  faces.stored if faces is not None else 0.0,
                  faces.dissipated if faces is not None else 0.0,
                  ledger.contact_work, ledger.contact_dissipated)
