"""Mass matrices and the critical time step of explicit dynamics."""

import numpy as np
import pytest
import scipy.linalg as sla

from fem_frac.fem.elasticity import stiffness
from fem_frac.fem.mass import (
    consistent_mass,
    critical_time_step,
    element_frequencies,
    lumped_mass,
)
from fem_frac.fem.space import build_space
from fem_frac.fem.tensors import isotropic_tangent
from fem_frac.mesh import tet_volumes
from meshes import structured_box

E, NU, RHO = 210e9, 0.3, 7800.0
LENGTHS = (1.0, 0.8, 0.6)
VOLUME = float(np.prod(LENGTHS))


def box(n=(2, 2, 2), distortion=0.2):
    mesh = structured_box(n, LENGTHS, distortion=distortion, seed=3)
    assert np.all(tet_volumes(mesh.points, mesh.tets) > 0)
    return mesh


def x_ones(space):
    e = np.zeros(space.n_dofs)
    e[0::3] = 1.0
    return e


def true_critical_step(space):
    """2 / w_max of the unconstrained ``K u = w^2 M_lumped u``, dense."""
    k = stiffness(space, isotropic_tangent(E, NU)).toarray()
    w2 = sla.eigh(k, np.diag(lumped_mass(space, RHO)), eigvals_only=True)[-1]
    return 2.0 / np.sqrt(w2)


@pytest.mark.parametrize("order", [1, 2])
def test_total_mass(order):
    space = build_space(box(), order)
    expected = RHO * VOLUME
    ones = x_ones(space)
    m = consistent_mass(space, RHO)
    assert m.shape == (space.n_dofs, space.n_dofs)
    assert abs(ones @ (m @ ones) - expected) <= 1e-12 * expected
    ml = lumped_mass(space, RHO)
    assert ml.shape == (space.n_dofs,)
    for c in range(3):
        assert abs(ml[c::3].sum() - expected) <= 1e-12 * expected
    assert np.all(ml > 0)


def test_p1_lumped_is_row_sum():
    space = build_space(box(), 1)
    row_sum = np.asarray(consistent_mass(space, RHO).sum(axis=1)).ravel()
    np.testing.assert_allclose(lumped_mass(space, RHO), row_sum, rtol=1e-12)


def test_p2_row_sum_is_not_positive_hrz_is():
    """Row sums of the P2 consistent mass give vertices a negative mass (-rho V_e / 20 per
    tet), so HRZ lumping is needed for a usable diagonal mass."""
    space = build_space(box(), 2)
    row_sum = np.asarray(consistent_mass(space, RHO).sum(axis=1)).ravel()
    assert row_sum.min() < 0
    assert np.all(lumped_mass(space, RHO) > 0)


@pytest.mark.parametrize("order", [1, 2])
def test_consistent_mass_integrates_exactly(order):
    """``u^T M v = rho int u . v`` for interpolated fields on an undistorted box: linear
    (x, y), and for P2 quadratic (x^2, y z), whose degree-4 product needs intorder 4."""
    space = build_space(box(distortion=0.0), order)
    lx, ly, lz = LENGTHS
    p = space.node_points
    m = consistent_mass(space, RHO)
    cases = [(p[:, 0], p[:, 1], lx**2 * ly**2 * lz / 4)]
    if order == 2:
        cases.append((p[:, 0] ** 2, p[:, 1] * p[:, 2], lx**3 / 3 * ly**2 / 2 * lz**2 / 2))
    for fu, fv, integral in cases:
        u, v = np.zeros(space.n_dofs), np.zeros(space.n_dofs)
        u[0::3], v[0::3] = fu, fv
        assert abs(u @ (m @ v) - RHO * integral) <= 1e-12 * RHO * integral
        u[0::3], v[0::3] = 0.0, 0.0
        u[2::3], v[2::3] = fu, fv  # same in z, no cross-component coupling
        assert abs(u @ (m @ v) - RHO * integral) <= 1e-12 * RHO * integral
        w = np.zeros(space.n_dofs)
        w[1::3] = fv
        assert abs(u @ (m @ w)) <= 1e-14 * RHO * integral


@pytest.mark.parametrize("order", [1, 2])
def test_consistent_mass_is_spd(order):
    space = build_space(box(), order)
    m = consistent_mass(space, RHO).toarray()
    assert np.abs(m - m.T).max() <= 1e-15 * np.abs(m).max()
    assert np.linalg.eigvalsh(m)[0] > 0


@pytest.mark.parametrize(
    ("order", "distortion", "factor"),
    [(1, 0.0, 0.7), (2, 0.0, 0.7), (1, 0.2, 0.5), (2, 0.2, 0.5)],
)
def test_critical_step_is_a_tight_lower_bound(order, distortion, factor):
    """The element bound never exceeds the true step of the assembled lumped system, and
    is not absurdly conservative. Measured bound/true: 0.78 (P1), 0.88 (P2) undistorted,
    0.59 (P1), 0.67 (P2) with distortion 0.2. It loosens with distortion because the
    stiffest element's bound sees only its own nodal mass (rho V_e / 4 per vertex), while
    in the assembly its nodes also carry the neighbours' mass; on larger distorted meshes
    the gap grows with the worst element (0.44 P1, 0.57 P2 on 4x3x3)."""
    space = build_space(box(distortion=distortion), order)
    dt = critical_time_step(space, E, NU, RHO)
    dt_true = true_critical_step(space)
    assert dt <= dt_true * (1 + 1e-12)
    assert dt >= factor * dt_true


@pytest.mark.parametrize("order", [1, 2])
def test_critical_step_scaling(order):
    space = build_space(box(), order)
    dt = critical_time_step(space, E, NU, RHO)
    assert abs(critical_time_step(space, 2 * E, NU, RHO) * np.sqrt(2) / dt - 1) <= 1e-12
    omega = element_frequencies(space, E, NU, RHO)
    assert omega.shape == (space.mesh.n_tets,)
    assert np.all(omega > 0)
    coarse = critical_time_step(build_space(box(distortion=0.0), order), E, NU, RHO)
    fine = critical_time_step(build_space(box((4, 4, 4), distortion=0.0), order), E, NU, RHO)
    assert 0.4 <= fine / coarse <= 0.6


def _verlet(k, ml, u0, dt, steps, limit):
    """Velocity Verlet (= central differences) from rest; max |u| seen, stops past limit."""
    u, v = u0.copy(), np.zeros_like(u0)
    a = -(k @ u) / ml
    peak = np.abs(u).max()
    for _ in range(steps):
        v += 0.5 * dt * a
        u += dt * v
        a = -(k @ u) / ml
        v += 0.5 * dt * a
        peak = max(peak, np.abs(u).max())
        if peak > limit:
            break
    return peak


def test_central_differences_stable_below_unstable_above():
    """Free vibration of an unconstrained P1 box from a random displacement: bounded at
    0.95 of the bound and of the true limit, exponential growth just past the true limit."""
    space = build_space(box(), 1)
    k = stiffness(space, isotropic_tangent(E, NU))
    ml = lumped_mass(space, RHO)
    u0 = 1e-3 * np.random.default_rng(4).uniform(-1, 1, space.n_dofs)
    scale = np.abs(u0).max()
    dt = critical_time_step(space, E, NU, RHO)
    assert _verlet(k, ml, u0, 0.95 * dt, 2000, 1e3 * scale) < 10 * scale
    dt_true = true_critical_step(space)
    assert _verlet(k, ml, u0, 0.95 * dt_true, 2000, 1e3 * scale) < 10 * scale
    assert _verlet(k, ml, u0, 1.05 * dt_true, 2000, 1e3 * scale) > 1e3 * scale


@pytest.mark.parametrize("order", [1, 2])
def test_mass_solve_matches_the_factorization(order):
    """Conjugate gradients on the consistent mass, preconditioned by its diagonal, to a
    relative residual of MASS_RTOL: the diagonal-scaled mass has a condition number bounded
    by the element type alone, so the solution agrees with a direct solve to within that
    bound times the residual (1e-11 here), in a few tens of iterations on a distorted mesh."""
    from types import SimpleNamespace

    import scipy.sparse.linalg as spla

    from fem_frac.solve.state import MASS_RTOL, mass_solve

    space = build_space(box((4, 3, 3)), order=order)
    mass = consistent_mass(space, RHO).tocsr()
    held = np.flatnonzero(np.abs(space.node_points[:, 0]) < 1e-12)
    fixed = (3 * held[:, None] + np.arange(3)).ravel()
    free = np.setdiff1d(np.arange(space.n_dofs), fixed)
    constrained = SimpleNamespace(free=free)
    rhs = np.random.default_rng(1).standard_normal(free.size)
    m = mass[free][:, free].tocsc()
    exact = spla.spsolve(m, rhs)
    x = mass_solve(mass, constrained, rhs)
    assert np.linalg.norm(m @ x - rhs) <= MASS_RTOL * np.linalg.norm(rhs)
    assert np.abs(x - exact).max() <= 1e-11 * np.abs(exact).max()


def test_the_mass_solve_benchmark_runs():
    """benchmarks/mass_solve.py still runs against the code it times (a small cube)."""
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).parent.parent / "benchmarks" / "mass_solve.py"
    out = subprocess.run([sys.executable, str(script), "--cells", "4", "--repeats", "1"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    row = out.stdout.strip().splitlines()[-1].split("|")
    assert row[1].strip() == "P1" and row[2].strip() == "384"
    assert float(row[-2]) < 1e-11  # the two solutions agree


@pytest.mark.parametrize("order", [1, 2])
def test_vector_mass_is_the_scalar_kron_identity(order):
    """The vector mass holds the scalar mass's entries once per component: kron(M, I_3),
    entry for entry, with sorted indices."""
    import scipy.sparse as sp

    from fem_frac.fem.mass import _scalar_element_dofs, element_scalar_mass

    space = build_space(box(), order)
    m = consistent_mass(space, RHO)
    me = element_scalar_mass(space, RHO)
    dofs = _scalar_element_dofs(space)
    k = dofs.shape[1]
    scalar = sp.coo_matrix((me.ravel(), (np.repeat(dofs, k, axis=1).ravel(),
                                         np.tile(dofs, k).ravel())),
                           shape=(space.n_nodes,) * 2).tocsr()
    expected = sp.kron(scalar, sp.eye(3), format="csr")
    expected.sort_indices()
    for a in ("indptr", "indices", "data"):
        np.testing.assert_array_equal(getattr(m, a), getattr(expected, a))
    # element masses given (a crack's reconnected mesh keeps them): the same matrix
    again = consistent_mass(space, RHO, me)
    np.testing.assert_array_equal(again.data, m.data)
