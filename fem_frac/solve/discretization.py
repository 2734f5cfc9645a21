"""A mesh made ready to step: function space, materials, supports and loads, operators and
the stepper. Built once from the case's recipe and again on every mesh a topology change
makes (a crack, a piece leaving), so the recipe holds the sub-configurations it needs and
nothing else.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..cohesive.interface import InterfaceRecipe, build_interface
from ..config import schema
from ..errors import CaseError
from ..fem.space import Space, build_space
from ..mesh.mesh import Mesh
from ..plasticity.law import MaterialLaw, material_law
from ..plasticity.regions import ElementMaterials, element_materials
from ..timing import StageTimer
from . import integrators
from .constrained import Constrained
from .linalg import Factorization
from .problem import Problem, build_problem, free_rigid_modes
from .stable_step import ExplicitLimit, stable_limit
from .state import Operators
from .stepping import ExplicitStepper, ImplicitStepper, Stepper

Log = Callable[[str], None]


def quiet(_: str) -> None:
    pass


@dataclass(frozen=True, eq=False)
class Recipe:
    """The sections of a case that say how to discretize a mesh."""

    order: int
    formulation: str
    material: schema.Material
    regions: tuple
    plasticity: schema.Plasticity | None
    boundary_conditions: tuple
    body_force: schema.BodyForce | None
    load_curves: dict
    analysis: schema.StaticAnalysis | schema.QuasiStaticAnalysis | schema.DynamicAnalysis
    dt: float
    cohesive: InterfaceRecipe | None = None  # crack faces with a fracture energy

    @property
    def dynamic(self) -> bool:
        return isinstance(self.analysis, schema.DynamicAnalysis)

    @property
    def explicit(self) -> bool:
        return self.dynamic and self.analysis.integrator == "central_difference"


@dataclass(frozen=True, eq=False)
class Discretization:
    """What one mesh provides: space, materials and law, supports and loads, operators,
    the free/constrained split, the stepper and (explicit) the stable step. Rebuilt after
    every topology change, from ``recipe``."""

    recipe: Recipe
    mesh: Mesh
    space: Space
    problem: Problem
    materials: ElementMaterials
    law: MaterialLaw
    ops: Operators
    constrained: Constrained
    stepper: Stepper
    limit: ExplicitLimit | None


def discretize(recipe: Recipe, mesh: Mesh, timer: StageTimer, strict: bool = True,
               log: Log = quiet, previous: tuple | None = None) -> Discretization:
    """The discretization of ``mesh`` (factorization deferred to the first step).
    ``strict=False`` lets a condition whose faces left with a rigid piece act on nothing
    (named groups follow the faces they named through crack insertion). ``previous``:
    ``(discretization, node_map)`` of the mesh a crack insertion made this one from, whose
    operators are then updated rather than rebuilt where that is exact
    (:mod:`fem_frac.fem.reconnect`)."""
    changed = _changed(mesh, previous)
    carried, like = (None, None) if changed is None else (previous[0].problem.selections,
                                                          previous[0].space)
    space, materials, problem = model_on(recipe, mesh, timer, strict, carried, like)
    if strict:
        check_model(recipe, space, materials, problem)
    # per-element properties follow the elements
    law = material_law(materials, recipe.plasticity)
    ops = build_operators(recipe, space, materials, law, timer, previous, changed)
    constrained = Constrained(problem, recipe.analysis.linear_solver,
                              recipe.analysis.petsc)
    limit = None
    if recipe.explicit:
        with timer("time step"):
            limit = stable_limit(space, ops.stiffness, ops.mass.diagonal(), constrained.free,
                                 materials, recipe.analysis.rayleigh,
                                 _initial_cohesive_stiffness(ops))
        substeps = explicit_substeps(limit, recipe.dt, recipe.analysis.substeps)
        log(f"time step  dt {recipe.dt:.4g}, stable limit {limit.dt:.4g} ({limit.method})"
            + (f", {substeps} substeps per step" if substeps > 1 else ""))
        stepper = ExplicitStepper(problem, law, ops, recipe.dt, substeps, constrained)
    else:
        stepper = ImplicitStepper(problem, law, ops, scheme(recipe.analysis, recipe.dt),
                                  recipe.analysis.equilibrium, constrained)
        stepper.seed = _seed(previous, space, ops, constrained)
    return Discretization(recipe, mesh, space, problem, materials, law, ops, constrained,
                          stepper, limit)


def _changed(mesh: Mesh, previous: tuple | None) -> np.ndarray | None:
    """The tets a crack insertion changed, where ``mesh`` is the ``previous``
    discretization's reconnected (:func:`~fem_frac.fem.reconnect.changed_tets`: the same
    tets, at the same places, in the same order), else ``None``."""
    from ..fem.reconnect import changed_tets

    if previous is None:
        return None
    old, node_map = previous
    return changed_tets(old.mesh.tets, mesh.tets, node_map)


def _reconnected(recipe: Recipe, space: Space, tangent: np.ndarray, previous: tuple | None,
                 changed: np.ndarray | None):
    """``(strain operator, stiffness, its diagonal)`` of ``space`` from the ``previous``
    discretization's (:mod:`fem_frac.fem.reconnect`), or ``None`` where that does not
    apply: quadratic tets, the averaged formulation, or a mesh that is not the old one
    reconnected (``changed``: :func:`_changed`)."""
    from ..fem.reconnect import reconnect

    if changed is None or recipe.order != 1 or recipe.formulation != "standard":
        return None
    old, _ = previous
    return reconnect(old.ops.strain_operator, old.ops.stiffness, tangent, space,
                     np.asarray(old.mesh.tets), np.asarray(space.mesh.tets), changed,
                     old.ops.stiffness_diagonal)


def _reconnected_mass(space: Space, element_mass: np.ndarray, previous: tuple | None,
                      changed: np.ndarray | None) -> tuple | None:
    """The consistent mass of ``space`` and its diagonal from the ``previous``
    discretization's (:func:`~fem_frac.fem.reconnect.reconnect_mass`: linear tets, a mesh
    the old one reconnected, ``changed`` as :func:`_changed`), else ``None``."""
    from ..fem.reconnect import reconnect_mass

    if changed is None or space.order != 1:
        return None
    old = previous[0]
    return reconnect_mass(old.ops.mass, element_mass, np.asarray(old.mesh.tets),
                          np.asarray(space.mesh.tets), changed, space.n_nodes,
                          old.ops.mass_diagonal)


def _seed(previous: tuple | None, space: Space, ops: Operators, constrained: Constrained):
    """``(factorization, tie)`` of the ``previous`` discretization for a stepper on a mesh a
    crack insertion made from it (:mod:`fem_frac.solve.bordered`: the elements' stiffness
    and mass matrices, hence those of the Jacobian with inertia, ``K + c M``, the steps'
    length fixed, are the old mesh's scattered to new dofs), or that pieces left
    (:func:`~fem_frac.solve.bordered.restricted`), ``None`` where it does not apply: no
    factorization made there yet, cohesive faces (whose secant stiffness changes the
    iteration matrix anyway), P2 (mid-edge nodes renumbered), or pieces that left sharing
    a vertex with the rest or with a free dof that copies a constrained one."""
    if previous is None or ops.interface is not None or space.order != 1:
        return None
    old, node_map = previous
    factor = old.stepper.factor if isinstance(old.stepper, ImplicitStepper) else None
    if not isinstance(factor, Factorization) or old.ops.interface is not None:
        return None  # none made yet, or PETSc's (which keeps its own)
    # the vector dofs of the node map (fracture.remap.dof_transfer, a layer above this one)
    node_map = np.asarray(node_map, dtype=np.int64)
    dofs = (3 * node_map[:, None] + np.arange(3)).ravel()
    index = np.full(old.space.n_dofs, -1, dtype=np.int64)
    index[old.constrained.free] = np.arange(old.constrained.free.size)
    tie = index[dofs[constrained.free]]
    if space.mesh.n_tets == old.mesh.n_tets:
        # a crack insertion: every tet kept, copies tied to vertices; a free dof whose
        # vertex's dof was constrained (a copy split off a support) tied to none (-1)
        return factor, tie
    if not np.all(tie >= 0):
        return None  # pieces left, and a free dof whose vertex's dof was constrained
    # pieces left (fem_frac.fracture.topology.extract): exact through the old factor where
    # they shared no vertex with the rest and the rest kept its free dofs
    kept = np.zeros(old.mesh.n_points, dtype=bool)
    kept[node_map] = True
    held = kept[np.asarray(old.mesh.tets)]
    if np.any(held.any(axis=1) & ~held.all(axis=1)) \
            or np.count_nonzero(kept[old.constrained.free // 3]) != tie.size:
        return None
    from .bordered import restricted

    rest = restricted(factor, tie)
    return None if rest is None else (rest, np.arange(tie.size))


def _initial_cohesive_stiffness(ops: Operators) -> sp.csr_matrix | None:
    """The stiffness of the cohesive faces undamaged and closed: the largest they have."""
    interface = ops.interface
    if interface is None:
        return None
    response, _ = interface.respond(np.zeros(interface.jump.shape[1]),
                                    interface.initial_state().kappa)
    return interface.matrix(response.secant)


def model_on(recipe: Recipe, mesh: Mesh, timer: StageTimer, strict: bool = True,
             carried: tuple | None = None, like: Space | None = None
             ) -> tuple[Space, ElementMaterials, Problem]:
    """Function space, per-element materials, supports and loads on ``mesh`` (``carried``:
    the selections of the mesh a crack reconnected into this one, whose faces are taken
    at their rows: :func:`~fem_frac.solve.problem.build_problem`; ``like``: that mesh's
    space, whose geometry :func:`~fem_frac.fem.space.build_space` reuses)."""
    with timer("space"):
        space = build_space(mesh, recipe.order, like)
    with timer("loads"):
        materials = element_materials(recipe.material, list(recipe.regions), mesh)
        problem = build_problem(space, list(recipe.boundary_conditions), recipe.body_force,
                                materials.density, recipe.analysis, recipe.load_curves,
                                strict, carried)
    return space, materials, problem


def check_model(recipe: Recipe, space: Space, materials: ElementMaterials,
                problem: Problem) -> None:
    """What the analysis needs of the model: a density for inertia, supports that hold
    every rigid-body motion without it (located errors)."""
    if recipe.dynamic and not materials.has_density():
        raise CaseError(("material", "density"), "a dynamic analysis needs material.density "
                        "(for every element)")
    if not recipe.dynamic:
        free = free_rigid_modes(space, problem.constraints.dofs)
        if free:
            raise CaseError(
                ("boundary_conditions",),
                "the supports leave rigid-body motions free (" + ", ".join(free) + "): "
                "a static solve is singular; add supports (fixed, displacement, symmetry)",
            )


def build_operators(recipe: Recipe, space: Space, materials: ElementMaterials,
                    law: MaterialLaw, timer: StageTimer, previous: tuple | None = None,
                    changed: np.ndarray | None = None) -> Operators:
    """Strain operator and elastic stiffness (updated from ``previous``, see
    :func:`discretize`, where that is exact: ``changed``, the tets the insertion changed,
    :func:`_changed`); mass and damping when the analysis is dynamic; the cohesive crack
    faces when cracks carry a fracture energy."""
    from ..fem.operators import strain_operator

    with timer("assemble"):
        d = law.elastic_tangent
        if d.ndim == 4:  # per element: one value for every quadrature point
            d = np.ascontiguousarray(np.broadcast_to(d, (6, 6) + space.basis.dx.shape))
        reused = _reconnected(recipe, space, d, previous, changed)
        diagonals = [None, None]  # of a stiffness and a mass reconnect made
        if reused is not None:
            op, k, diagonals[0] = reused
        else:
            op = strain_operator(space, recipe.formulation)
            k = op.stiffness(d)
    mass = damping = element_mass = None
    if recipe.dynamic:
        from ..fem.mass import (
            consistent_mass,
            element_scalar_lumped,
            element_scalar_mass,
            lumped_mass,
        )

        analysis = recipe.analysis
        with timer("mass"):
            if analysis.mass_kind == "lumped":
                # a crack moves no tet and changes no material: the element masses of the
                # mesh it reconnected are this one's (kept for linear tets)
                element_mass = None if changed is None else previous[0].ops.element_mass
                if element_mass is None and space.order == 1:
                    element_mass = element_scalar_lumped(space, materials.density)
                mass = sp.diags(lumped_mass(space, materials.density, element_mass)).tocsr()
            else:
                # a crack moves no tet and changes no material: the element masses of
                # the mesh it reconnected are this one's
                element_mass = None if changed is None else previous[0].ops.element_mass
                if element_mass is None:
                    element_mass = element_scalar_mass(space, materials.density)
                reused = _reconnected_mass(space, element_mass, previous, changed)
                if reused is not None:
                    mass, diagonals[1] = reused
                else:
                    mass = consistent_mass(space, materials.density, element_mass)
            if analysis.rayleigh is not None:
                r = analysis.rayleigh
                damping = (r.mass * mass + r.stiffness * k).tocsr()
    interface = None
    if recipe.cohesive is not None:
        with timer("cohesive faces"):
            interface = build_interface(recipe.cohesive, space.mesh, space,
                                        materials.youngs_modulus)
    return Operators(op, k, mass, damping, interface, element_mass, *diagonals)


def scheme(analysis, dt: float) -> integrators.Implicit:
    """The implicit scheme of ``analysis``: Newmark, HHT-alpha, or quasi-static."""
    if isinstance(analysis, schema.DynamicAnalysis):
        if analysis.integrator == "hht":
            return integrators.hht(dt, analysis.alpha)
        return integrators.newmark(dt, analysis.newmark_beta, analysis.newmark_gamma)
    return integrators.quasi_static(dt)


def explicit_substeps(limit: ExplicitLimit, dt: float, allow: bool) -> int:
    """Substeps per step for central difference; refuses ``dt`` above the limit unless
    ``allow``."""
    if dt <= limit.dt:
        return 1
    if not allow:
        raise CaseError(
            ("analysis", "dt"),
            f"time step {dt:.4g} exceeds the stable step of central difference "
            f"{limit.dt:.4g} (2/omega_max, {limit.method}); use dt <= {limit.dt:.4g}, "
            "an implicit integrator, or substeps: true",
        )
    return int(np.ceil(dt / limit.dt))
