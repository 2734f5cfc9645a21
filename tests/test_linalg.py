"""Sparse direct solver layer: every available backend on a small clamped elasticity system."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from skfem import Basis, ElementTetP1, ElementVector, MeshTet, asm, condense
from skfem.models.elasticity import lame_parameters, linear_elasticity

from fem_frac.errors import SolverError
from fem_frac.solve.linalg import available_methods, factorize

METHODS = available_methods()
N_RHS = 3


@pytest.fixture(scope="module")
def system() -> tuple[sp.csr_matrix, np.ndarray]:
    """P1 stiffness of a 2 x 1 x 1 box of 8 x 4 x 4 cubes (768 tets, 675 dofs), unconstrained,
    and the dofs of its face x = 0."""
    mesh = MeshTet.init_tensor(np.linspace(0, 2, 9), np.linspace(0, 1, 5), np.linspace(0, 1, 5))
    basis = Basis(mesh, ElementVector(ElementTetP1()), intorder=0)
    k = asm(linear_elasticity(*lame_parameters(210e9, 0.3)), basis).tocsr()
    return k, basis.get_dofs(lambda x: x[0] < 1e-12).all()


@pytest.fixture(scope="module")
def stiffness(system) -> sp.csr_matrix:
    """The unconstrained stiffness: singular, six rigid-body modes."""
    return system[0]


@pytest.fixture(scope="module")
def clamped(system) -> sp.csr_matrix:
    """The stiffness with the face x = 0 clamped: symmetric positive definite."""
    return condense(system[0], D=system[1], expand=False).tocsr()


def relative_residual(a, x, b) -> float:
    return float(np.linalg.norm(a @ x - b) / np.linalg.norm(b))


def test_superlu_is_always_available():
    assert "superlu" in METHODS


@pytest.mark.parametrize("method", METHODS)
def test_solves_vector_and_columns(clamped, method):
    rng = np.random.default_rng(0)
    fact = factorize(clamped, method)
    assert fact.method == method and fact.n == clamped.shape[0] and fact.factor_time >= 0
    b = rng.standard_normal(clamped.shape[0])
    x = fact.solve(b)
    assert x.shape == b.shape
    assert relative_residual(clamped, x, b) < 1e-10
    bb = rng.standard_normal((clamped.shape[0], N_RHS))
    xx = fact.solve(bb)
    assert xx.shape == bb.shape
    assert relative_residual(clamped, xx, bb) < 1e-10


@pytest.mark.parametrize("method", METHODS)
def test_factorization_is_reused(clamped, method):
    fact = factorize(clamped, method)
    b = np.random.default_rng(1).standard_normal((clamped.shape[0], N_RHS))
    first = fact.solve(b)
    for column in range(N_RHS):
        again = fact.solve(b[:, column])
        np.testing.assert_allclose(again, first[:, column], rtol=1e-12, atol=0)
    np.testing.assert_allclose(fact.solve(b), first, rtol=0, atol=0)


@pytest.mark.parametrize("method", METHODS)
def test_solves_into_a_given_array(clamped, method):
    """``out``: the solution written there (in place where the backend can), the same bits
    as without it; a column block of a larger Fortran buffer serves."""
    fact = factorize(clamped, method)
    b = np.asfortranarray(np.random.default_rng(3).standard_normal((clamped.shape[0], 3)))
    buffer = np.full((clamped.shape[0], 7), np.nan, order="F")
    out = fact.solve(b, out=buffer[:, 2:5])
    assert np.shares_memory(out, buffer)
    np.testing.assert_array_equal(buffer[:, 2:5], fact.solve(b))
    assert np.isnan(buffer[:, :2]).all() and np.isnan(buffer[:, 5:]).all()
    with pytest.raises(ValueError, match="out"):
        fact.solve(b, out=np.empty((clamped.shape[0], 3)))  # C order


@pytest.mark.skipif("pardiso" not in METHODS, reason="PARDISO is not installed here")
def test_pardiso_halves_are_its_back_solve_and_a_gram_factor(clamped):
    """Forward then backward substitution is the back-solve to the bit, and the forward
    half R (A^-1 = R^T R) gives the products b.A^-1.c as R b . R c."""
    fact = factorize(clamped, "pardiso")
    forward, backward = fact.halves
    rng = np.random.default_rng(4)
    b = np.asfortranarray(rng.standard_normal((clamped.shape[0], 3)))
    np.testing.assert_array_equal(backward(forward(b)), fact.solve(b))
    np.testing.assert_array_equal(backward(forward(b[:, 0])), fact.solve(b[:, 0]))
    gram, exact = forward(b).T @ forward(b), b.T @ fact.solve(b)
    # both are b.A^-1.b to round-off: eps cond(A) (cond ~1e4 here) of the largest entry
    np.testing.assert_allclose(gram, exact, rtol=0, atol=1e-9 * np.abs(exact).max())
    out = np.full((clamped.shape[0], 5), np.nan, order="F")
    forward(b, out=out[:, 1:4])
    np.testing.assert_array_equal(out[:, 1:4], forward(b))
    assert factorize(clamped, "superlu").halves is None


@pytest.mark.parametrize("method", METHODS)
def test_backends_agree(clamped, method):
    b = np.random.default_rng(2).standard_normal(clamped.shape[0])
    reference = factorize(clamped, "superlu").solve(b)
    np.testing.assert_allclose(factorize(clamped, method).solve(b), reference, rtol=1e-8)


@pytest.mark.parametrize("method", METHODS)
def test_unconstrained_stiffness_is_singular(stiffness, method):
    with pytest.raises(SolverError, match="singular"):
        factorize(stiffness, method)


@pytest.mark.parametrize("method", METHODS)
def test_partly_constrained_stiffness_is_singular(stiffness, method):
    # One node fixed: the three rotations about it stay free.
    partly = condense(stiffness, D=np.arange(3), expand=False)
    with pytest.raises(SolverError, match="singular"):
        factorize(partly, method)


def test_zero_diagonal_is_rejected(clamped):
    a = clamped.tolil()
    a[0, :] = 0.0
    a[:, 0] = 0.0
    with pytest.raises(SolverError, match="diagonal"):
        factorize(a.tocsr())


def test_unknown_method_names_available():
    with pytest.raises(ValueError, match="superlu") as info:
        factorize(sp.identity(3, format="csr"), "mumps")
    assert "auto" in str(info.value)


def test_auto_picks_first_available(clamped):
    fact = factorize(clamped)
    assert fact.method == METHODS[0]
    b = np.ones(clamped.shape[0])
    assert relative_residual(clamped, fact.solve(b), b) < 1e-10


def test_wrong_rhs_shape(clamped):
    with pytest.raises(ValueError, match="right-hand side"):
        factorize(clamped, "superlu").solve(np.ones(clamped.shape[0] + 1))


@pytest.mark.parametrize("method", METHODS)
def test_refactorizer_reuses_the_analysis_of_one_pattern(clamped, method):
    """Matrices with the pattern of the first, or with part of it (entries that came out
    zero), are factorized numerically only (PARDISO: one analysis); one with an entry
    outside it is analysed afresh; every factorization solves its own matrix to
    round-off."""
    from fem_frac.solve.refactorizer import Refactorizer

    refactorizer = Refactorizer(method)
    rng = np.random.default_rng(3)
    b = rng.standard_normal(clamped.shape[0])
    for scale in (1.0, 2.0, 0.5):
        a = clamped * scale + sp.diags(np.full(clamped.shape[0], scale * 1e3))
        x = refactorizer.factorize(a).solve(b)
        assert np.linalg.norm(a @ x - b) <= 1e-10 * np.linalg.norm(b)
    if method == "pardiso":
        assert refactorizer.analyses == 1
        # part of the pattern (a diagonal): on the same analysis, its other entries zero
        d = sp.diags(np.arange(1.0, clamped.shape[0] + 1.0)).tocsr()
        np.testing.assert_allclose(refactorizer.factorize(d).solve(b), b / d.diagonal())
        assert refactorizer.analyses == 1
        # an entry outside the pattern (the two ends of the bar coupled): analysed afresh
        n = clamped.shape[0]
        a = (clamped + sp.diags(np.full(n, 1e3))
             + sp.csr_matrix(([1.0, 1.0], ([0, n - 1], [n - 1, 0])), shape=(n, n))).tocsr()
        x = refactorizer.factorize(a).solve(b)
        assert np.linalg.norm(a @ x - b) <= 1e-10 * np.linalg.norm(b)
        assert refactorizer.analyses == 2


def test_a_numerical_refactorization_is_the_fresh_factorization_to_the_bit(clamped):
    """PARDISO's ordering and symbolic analysis depend on the pattern alone, so a matrix
    factorized numerically after another of its pattern (phase 22) solves to the same bits
    as its own fresh factorization (phase 12): on this ground a cohesive step's secant
    matrix goes through a Refactorizer (fem_frac.solve.stepping), not afresh."""
    from fem_frac.solve.refactorizer import Refactorizer

    if "pardiso" not in METHODS:
        pytest.skip("PARDISO is not installed here")
    refactorizer = Refactorizer("pardiso")
    b = np.random.default_rng(4).standard_normal((clamped.shape[0], 2))
    refactorizer.factorize(clamped + sp.diags(np.full(clamped.shape[0], 1e3)))
    a = 2.0 * clamped + sp.diags(np.linspace(1e2, 1e4, clamped.shape[0]))
    x = refactorizer.factorize(a).solve(b)
    assert refactorizer.analyses == 1
    assert np.array_equal(x, factorize(a, "pardiso").solve(b))


def test_a_kept_pattern_is_restricted_by_gathering_its_entries(system, monkeypatch):
    """Refactorizer.factorize_free: a matrix with the pattern (and free dofs) of the two
    calls before goes to PARDISO without slicing or ``triu`` (its entries gathered at
    positions kept from them), and solves to the same bits as the restricted matrix
    factorized afresh; a pattern with more entries is sliced and analysed again, one with
    fewer factorized on that analysis."""
    import scipy.sparse

    from fem_frac.solve.refactorizer import Refactorizer

    if "pardiso" not in METHODS:
        pytest.skip("PARDISO is not installed here")
    k, clamped_dofs = system
    n = k.shape[0]
    free = np.setdiff1d(np.arange(n), clamped_dofs)
    b = np.random.default_rng(5).standard_normal(free.size)
    refactorizer = Refactorizer("pardiso")
    for scale in (1.0, 3.0):  # the pattern seen, then seen again: its positions kept
        refactorizer.factorize_free((scale * k + sp.identity(n)).tocsr(), free)
    matrix = (1.5 * k + sp.diags(np.linspace(1.0, 2.0, n))).tocsr()

    def no_triu(*args, **kwargs):
        raise AssertionError("the kept pattern was sliced again")

    with monkeypatch.context() as m:
        m.setattr(scipy.sparse, "triu", no_triu)
        x = refactorizer.factorize_free(matrix, free).solve(b)
    assert refactorizer.analyses == 1
    assert np.array_equal(x, factorize(matrix[free][:, free].tocsr(), "pardiso").solve(b))
    # one more coupling: another pattern, analysed again, still right
    extra = sp.csr_matrix(([1.0, 1.0], ([free[0], free[-1]], [free[-1], free[0]])), shape=(n, n))
    other = (matrix + extra).tocsr()
    x = refactorizer.factorize_free(other, free).solve(b)
    assert refactorizer.analyses == 2
    assert np.array_equal(x, factorize(other[free][:, free].tocsr(), "pardiso").solve(b))
    # the first pattern again: part of the one analysed now, so factorized on that
    # analysis with the coupling's entries zero (the same matrix, another elimination
    # order: the same solution to round-off, here a few 1e-14); from the third call on,
    # gathered and placed in that pattern
    sub = matrix[free][:, free].tocsr()
    fresh = factorize(sub, "pardiso").solve(b)
    for call in range(3):
        with monkeypatch.context() as m:
            if call == 2:
                m.setattr(scipy.sparse, "triu", no_triu)
            x = refactorizer.factorize_free(matrix, free).solve(b)
        assert np.linalg.norm(x - fresh) <= 1e-10 * np.linalg.norm(fresh)
    assert refactorizer.analyses == 2
    # another pattern analysed through factorize (a coupling neither has): the positions
    # kept are dropped, and the first pattern is sliced and analysed again
    size = free.size
    far = sp.csr_matrix(([1.0, 1.0], ([1, size - 2], [size - 2, 1])), shape=(size, size))
    refactorizer.factorize((far + 2.0 * sp.identity(size)).tocsr())
    assert refactorizer.analyses == 3
    x = refactorizer.factorize_free(matrix, free).solve(b)
    assert refactorizer.analyses == 4
    assert np.array_equal(x, factorize(sub, "pardiso").solve(b))


def test_mkl_is_taken_from_the_environment_without_a_subprocess(monkeypatch, tmp_path):
    """The MKL runtime in ``sys.prefix/lib*`` is named to pypardiso's loader without asking
    ``find_library`` (which runs ldconfig, gcc and ld as subprocesses); a path the
    environment names, or a prefix without the library, leaves the search to the loader."""
    import ctypes
    import glob
    import subprocess
    import sys

    from fem_frac.solve import linalg

    def no_subprocess(*args, **kwargs):
        raise AssertionError("a subprocess was started")

    monkeypatch.setattr(subprocess, "Popen", no_subprocess)
    monkeypatch.delenv("PYPARDISO_MKL_RT", raising=False)
    path = linalg._mkl_rt_in_prefix()
    if glob.glob(f"{sys.prefix}/[Ll]ib*/*mkl_rt*"):
        assert path is not None and path.startswith(sys.prefix)
        ctypes.CDLL(path)
    monkeypatch.setenv("PYPARDISO_MKL_RT", "/some/libmkl_rt.so")
    assert linalg._mkl_rt_in_prefix() is None
    monkeypatch.delenv("PYPARDISO_MKL_RT")
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "libmkl_rt.so.2").write_text("not a library")
    monkeypatch.setattr(sys, "prefix", str(tmp_path))
    assert linalg._mkl_rt_in_prefix() is None  # none that loads
