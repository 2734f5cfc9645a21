"""Elastic-perfectly plastic thick sphere under internal pressure against Hill's closed form
(docs/plasticity.md; figures from benchmarks/hill.py).

Octant of a sphere a = 1, b = 2 (mm-N-s: mm, MPa), E = 210e3, sigma_Y = 240, no hardening;
the pressure that drives the plastic zone to c = 1.5 (287.1) is ramped over 10 quasi-static
steps. Two measures of the final state:

- ``u_b``: mean radial displacement u . x / |x| over the nodes of the outer surface. Exact:
  ``sigma_Y (1 - nu) c^3 / (E b^2)``, a property of the elastic shell c..b alone.
- ``c_h``: plastic radius from the yielded volume, ``V_p`` = sum of the quadrature weights of
  the points with equivalent plastic strain > 0, and the octant volume
  ``(pi / 6)(c^3 - a^3)``: ``c_h = (a^3 + 6 V_p / pi)^(1/3)``.

Expected rates (argued in docs/plasticity.md): ``c_h`` converges at O(h) at least (the
yielded set is a union of whole quadrature cells, so the interface is resolved to a cell
layer); ``u_b`` at O(h^2) or better for P2 and P1-averaged. Standard P1 converges too but
locks: under isochoric plastic flow (and near-incompressible elasticity) its error is several
times that of the averaged P1 on the same mesh.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pytest

from fem_frac.fem.loads import surface_nodes
from fem_frac.verify.exact import (
    hill_sphere_outer_displacement,
    hill_sphere_plastic_radius,
    hill_sphere_pressure,
)
from solve import run

A, B, E, SIGMA_Y = 1.0, 2.0, 210e3, 240.0
NU, C = 0.3, 1.5
STEPS = 10


def averaged_available() -> bool:
    """Whether the strain operators offer the averaged (B-bar) P1 formulation."""
    try:
        from fem_frac.fem.operators import FORMULATIONS
    except ImportError:
        return False
    return "averaged" in FORMULATIONS


def hill_case(order: int, size: float, formulation: str = "standard", nu: float = NU,
              c: float = C, steps: int = STEPS) -> dict:
    """The octant under the pressure ``p(c)`` ramped over ``steps`` quasi-static steps."""
    pressure = float(hill_sphere_pressure(c, A, B, SIGMA_Y))
    return {
        "title": f"Hill sphere, plastic radius {c}",
        "units": "mm-N-s",
        "mesh": {"geometry": {"type": "hollow_sphere", "inner_radius": A, "outer_radius": B,
                              "sector": "octant"},
                 "element_size": size, "order": order, "formulation": formulation},
        "material": {"youngs_modulus": E, "poissons_ratio": nu},
        "plasticity": {"yield_stress": SIGMA_Y},
        "boundary_conditions": [
            {"type": "symmetry", "boundary": "symmetry_x"},
            {"type": "symmetry", "boundary": "symmetry_y"},
            {"type": "symmetry", "boundary": "symmetry_z"},
            {"type": "pressure", "boundary": "inner", "pressure": pressure},
        ],
        # modified Newton converges linearly once the wall yields (~30 iterations a step at
        # c = 1.5, ~100 near the limit load): more than the default 200 in a step
        "analysis": {"type": "quasi_static", "steps": steps,
                     "equilibrium": {"method": "modified_newton", "tolerance": 1e-8,
                                     "max_iterations": 2000}},
    }


@dataclass(frozen=True)
class HillResult:
    order: int
    formulation: str
    nu: float
    c: float  # exact plastic radius
    size: float  # element_size asked of gmsh
    h: float  # mean element size (volume / n_tets)^(1/3)
    dofs: int
    c_h: float
    u_b: float
    iterations: int
    wall: float
    # P1: radii of the sphere octants of the same volumes as the polyhedral inner and outer
    # surfaces of the mesh (nan for the isoparametric P2)
    a_facets: float = float("nan")
    b_facets: float = float("nan")

    @property
    def c_error(self) -> float:
        """Relative error of the plastic radius, signed."""
        return (self.c_h - self.c) / self.c

    @property
    def u_b_exact(self) -> float:
        return hill_sphere_outer_displacement(self.c, B, SIGMA_Y, E, self.nu)

    @property
    def u_b_error(self) -> float:
        """Relative error of the outer radial displacement, signed."""
        return (self.u_b - self.u_b_exact) / self.u_b_exact

    @property
    def geometry_u_b_error(self) -> float:
        """Hill's u_b for the sphere of radii ``a_facets, b_facets`` under the same pressure,
        relative to the exact one: the share of the P1 error that the flat facets explain."""
        if np.isnan(self.a_facets):
            return float("nan")
        pressure = float(hill_sphere_pressure(self.c, A, B, SIGMA_Y))
        c = hill_sphere_plastic_radius(pressure, self.a_facets, self.b_facets, SIGMA_Y)
        u_b = hill_sphere_outer_displacement(c, self.b_facets, SIGMA_Y, E, self.nu)
        return u_b / self.u_b_exact - 1.0

    @property
    def limit_load_shift(self) -> float:
        """Relative change of the limit load 2 sigma_Y ln(b/a) for the facets' radii."""
        return float(np.log(self.b_facets / self.a_facets) / np.log(B / A) - 1.0)

    @property
    def element(self) -> str:
        return f"P{self.order}" + (" averaged" if self.formulation == "averaged" else "")


def hill(order: int, size: float, formulation: str = "standard", nu: float = NU,
         c: float = C) -> HillResult:
    """Run the case and measure ``u_b`` and ``c_h`` on its final state."""
    start = time.perf_counter()
    setup, state, _, counters = run(hill_case(order, size, formulation, nu, c))
    wall = time.perf_counter() - start
    space, mesh = setup.disc.space, setup.disc.mesh
    nodes = surface_nodes(space, space.facet_indices(mesh.boundaries["outer"]))
    x = space.node_points[nodes]
    u = state.u.reshape(-1, 3)[nodes]
    u_b = float(np.mean(np.einsum("ni,ni->n", u, x) / np.linalg.norm(x, axis=1)))
    dx = space.basis.dx
    yielded = float(dx[state.plastic.equivalent_plastic_strain > 0.0].sum())
    c_h = (A**3 + 6.0 * yielded / np.pi) ** (1.0 / 3.0)
    h = float((dx.sum() / mesh.n_tets) ** (1.0 / 3.0))
    radii = (float("nan"), float("nan"))
    if order == 1:
        radii = tuple(equivalent_radius(mesh.points, mesh.boundaries[k])
                      for k in ("inner", "outer"))
    return HillResult(order, formulation, nu, c, size, h, space.n_dofs, float(c_h), u_b,
                      counters.iterations, wall, *radii)


def equivalent_radius(points: np.ndarray, triangles: np.ndarray) -> float:
    """Radius of the sphere octant whose volume is the cone from the origin over the flat
    ``triangles`` ``(k, 3)`` (a polyhedral approximation of an octant of a sphere about 0)."""
    p = points[triangles]  # (k, 3 corners, 3)
    cone = np.abs(np.einsum("ki,ki->k", p[:, 0], np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])))
    volume = cone.sum() / 6.0
    return float((6.0 * volume / np.pi) ** (1.0 / 3.0))


def slope(results: list[HillResult], error: str) -> float:
    """Least-squares slope of log |error| against log h."""
    hs = [r.h for r in results]
    errors = [abs(getattr(r, error)) for r in results]
    return float(np.polyfit(np.log(hs), np.log(errors), 1)[0])


needs_averaged = pytest.mark.skipif(not averaged_available(),
                                    reason="formulation 'averaged' not available")

COARSE = (0.4, 0.25)  # mean h 0.205, 0.136: a refinement by 1.51


def test_p2_converges_to_hill():
    """P2 at two coarse sizes, refined by r = 1.51 in h.

    Expected rates: u_b at least 2 (the shell c..b is elastic and smooth, the displacement
    C^1 across the interface; 3.6 is fitted in docs/plasticity.md), so its error must
    shrink by r^2 = 2.3 at least (5.5 measured); c_h at 1 (the cell layer), so by r = 1.51
    (3.3 measured). P2 with two to three tets through the wall is within 2 % of Hill in
    both (0.9 % and 0.8 % measured on the coarse mesh).
    """
    coarse, fine = (hill(2, s) for s in COARSE)
    r = coarse.h / fine.h
    assert abs(coarse.u_b_error) < 0.02 and abs(coarse.c_error) < 0.02
    assert abs(fine.u_b_error) < abs(coarse.u_b_error) / r**2
    assert abs(fine.c_error) < abs(coarse.c_error) / r


def test_p1_converges_but_locks():
    """Standard P1 at three coarse sizes (h 0.205, 0.136, 0.101).

    Both errors shrink at every refinement, and u_b stays > 10 % low (39 %, 18 %, 13 %
    measured): the element is too stiff, its plastic zone too small. The plastic radius is
    within one element layer, |c_h - c| < h: P1 has one quadrature point per tet, the
    interface tets (whose mean stress is below yield) stay elastic, which puts c_h about
    half a layer low (0.5 to 0.65 h measured), plus the O(h) error of the P1 stress.
    The averaged P1 on the finest of these meshes is at least 3x closer in u_b (locking
    removed; 2.7 % against 12.6 % measured) and its c_h within one layer as well.
    """
    results = [hill(1, s) for s in (*COARSE, 0.18)]
    for coarse, fine in zip(results, results[1:], strict=False):
        assert abs(fine.u_b_error) < abs(coarse.u_b_error)
        assert abs(fine.c_error) < abs(coarse.c_error)
    for r in results:
        assert r.u_b_error < -0.1
        assert abs(r.c_h - r.c) < r.h
    if averaged_available():
        averaged = hill(1, 0.18, "averaged")
        assert abs(averaged.u_b_error) < abs(results[-1].u_b_error) / 3
        assert abs(averaged.c_h - averaged.c) < averaged.h


@needs_averaged
def test_locking_grows_with_incompressibility():
    """On the h = 0.136 mesh, from nu = 0.3 to 0.49 standard P1's u_b error more than
    doubles (18 % to 53 % low measured; the exact u_b only scales with 1 - nu, so the growth
    is the element's), and the averaged P1 is at least 4x closer (7.9 % measured)."""
    standard = hill(1, 0.25)
    locked = hill(1, 0.25, nu=0.49)
    averaged = hill(1, 0.25, "averaged", nu=0.49)
    assert locked.u_b_error < 2 * standard.u_b_error < 0
    assert abs(averaged.u_b_error) < abs(locked.u_b_error) / 4


FINE = (0.25, 0.16, 0.1)  # mean h 0.136, 0.093, 0.060: the benchmark's meshes


@pytest.mark.slow
@pytest.mark.parametrize(
    "order,formulation,rates",
    [
        (2, "standard", {"u_b_error": 2.0, "c_error": 0.7}),
        (1, "averaged", {"u_b_error": 1.5, "c_error": 0.7}),
        (1, "standard", {"u_b_error": 1.5, "c_error": 0.7}),
    ],
)
def test_hill_convergence_rates(order, formulation, rates):
    """Slopes fitted over the benchmark's three meshes (docs/plasticity.md), against the
    expected rates less a margin for unstructured meshes (not similar from one size to the
    next; the yielded set jumps by whole cells):

    - c_h: rate 1 (one layer of quadrature cells), asserted > 0.7;
    - u_b, P2: >= 2 (3.6 fitted), asserted > 2;
    - u_b, P1: 2 for a smooth displacement (an L2-like functional of a P1 field), asserted
      > 1.5: the locking error of standard P1 is large and still pre-asymptotic.
    """
    if formulation == "averaged" and not averaged_available():
        pytest.skip("formulation 'averaged' not available")
    results = [hill(order, s, formulation) for s in FINE]
    for error, rate in rates.items():
        assert slope(results, error) > rate, (error, [getattr(r, error) for r in results])
    if order == 1:
        assert all(abs(r.c_h - r.c) < r.h for r in results)
