"""Sparse direct solvers for symmetric positive definite systems, factorized once, solved often.

``factorize(A)`` returns a :class:`Factorization` whose ``solve(b)`` is a back-solve with the
stored factor. Backends (measured in docs/solvers.md, reproduced by benchmarks/solvers.py):

- ``"pardiso"``: MKL PARDISO through pypardiso's library loader, in its symmetric positive
  definite mode (Cholesky of the upper triangle), iterative refinement off, back-solves called
  directly (phase 33). x86-64 only, pip alone.
- ``"cholmod"``: CHOLMOD through scikit-sparse; optional, needs SuiteSparse headers from apt.
- ``"superlu"``: scipy's SuperLU, an LU that ignores symmetry; slow but works everywhere.
- ``"petsc"``: not a factorization but PETSc's CG + GAMG (fem_frac/solve/petsc.py), optional;
  here without the rigid-body modes, which :class:`~fem_frac.solve.constrained.Constrained`
  adds for a stiffness matrix.

``"auto"`` picks the first available of the direct solvers in that order (the measured
order, fastest first); under mpiexec with several ranks it is PETSc (docs/solvers.md).

Singular or indefinite matrices raise :class:`~fem_frac.errors.SolverError`, found in three
ways: a zero, negative or non-finite diagonal before factorizing; the backend's own pivot
failure (PARDISO error -4, CHOLMOD's not-positive-definite error, SuperLU's exact singularity);
and, because roundoff often leaves a tiny positive pivot where a null space is, a probe after
factorizing: two solves (one step of inverse iteration, see ``_probe``) whose residual is of
order one when the matrix has a null space (an unconstrained body) and ~eps * cond otherwise.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import os
import sys
import time
import weakref
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from ..errors import SolverError

# Fastest first, as measured (docs/solvers.md); "auto" takes the first available.
PREFERENCE = ("pardiso", "cholmod", "superlu")
# Probe (see _probe): relative residual of a solve whose right-hand side is rich in the lowest
# modes. Measured on clamped elasticity systems: ~1e-12 on the benchmark boxes, up to 6e-3 on
# a 100 x 1 x 1 nearly incompressible P2 beam two elements thick (condition number > 1e10);
# on singular ones (free, or held at one or two nodes, P1 and P2): 2 to 5e4.
PROBE_TOLERANCE = 0.1
SUPERLU_ORDERING = "COLAMD"
SINGULAR_MESSAGE = (
    "matrix is singular, not positive definite or too ill-conditioned ({detail}); for a "
    "stiffness matrix: the body is not fully constrained (rigid-body motion possible)"
)

Solve = Callable[[np.ndarray], np.ndarray]


class Factorization:
    """A stored factorization of an n x n SPD matrix.

    Attributes: ``method`` (backend name), ``n`` (size), ``factor_time`` (seconds spent in
    :func:`factorize`, checks included), ``probe_residual`` (relative residual of the check),
    ``nonzeros`` (entries of the factor where the backend reports them, PARDISO's; else
    ``None``), ``halves``: where the backend does a back-solve in two halves, ``A^-1 =
    R^T R`` (PARDISO's Cholesky ``P A P^T = L L^T``: ``R b = L^-1 P b``, phase 331, and
    ``R^T u = P^T L^-T u``, phase 333; the two in turn are its back-solve to the bit), the
    pair ``(forward, backward)`` of functions of ``(n,)`` or Fortran ``(n, k)`` arrays
    (``forward`` also takes ``out=``); else ``None``. Since ``b.A^-1 c = (R b).(R c)``,
    :mod:`fem_frac.solve.bordered` forms its Schur complement from forward halves alone.
    """

    def __init__(self, method: str, n: int, solve: Solve):
        self.method = method
        self.n = n
        self._solve = solve
        self.factor_time = 0.0
        self.probe_residual = float("nan")
        self.nonzeros = getattr(solve, "nonzeros", None)
        self.halves = getattr(solve, "halves", None)

    def solve(self, b: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Solve A x = b. ``b``: shape (n,) or (n, k). Returns x of the same shape, float64:
        ``out`` where given (float64, b's shape, Fortran order), written in place by the
        backends that can (PARDISO: no array of the solution's size made and copied)."""
        b = np.asarray(b, dtype=np.float64)
        if b.ndim not in (1, 2) or b.shape[0] != self.n:
            raise ValueError(f"right-hand side of shape {b.shape}; expected ({self.n},) or "
                             f"({self.n}, k)")
        if out is not None and (out.shape != b.shape or out.dtype != np.float64
                                or not out.flags.f_contiguous):
            raise ValueError("out: float64, the right-hand side's shape, Fortran order")
        if b.ndim == 2 and b.shape[1] == 0:
            x = np.zeros_like(b)
        elif out is not None and getattr(self._solve, "writes_into", False):
            return self._solve(b, out)
        else:
            x = self._solve(b)
        if out is None:
            return x
        out[...] = x
        return out

    def __repr__(self) -> str:
        return (f"Factorization(method={self.method!r}, n={self.n}, "
                f"factor_time={self.factor_time:.3g})")


# ---------------------------------------------------------------- PARDISO (MKL)

# PARDISO error codes (MKL reference, "pardiso"): -4 zero pivot, -7 diagonal matrix singular.
_PARDISO_SINGULAR = {-4, -7}
_PARDISO_ERRORS = {
    -1: "input inconsistent", -2: "not enough memory", -3: "reordering problem",
    -5: "unclassified internal error", -6: "reordering failed", -8: "32-bit integer overflow",
    -9: "not enough memory for out-of-core", -10: "cannot open out-of-core files",
    -11: "out-of-core read/write error", -13: "interrupted", -15: "reordering failed",
}


@functools.cache
def _pardiso_function():
    """MKL's ``pardiso`` C function with its argument types, found by pypardiso's loader.

    Importing pypardiso makes a solver (``pypardiso.ps``), whose loader looks for MKL's
    library; that one is reused (another ``PyPardisoSolver()`` would look again). The
    loader asks ``find_library`` first (which runs ``ldconfig``, ``gcc`` and ``ld`` as
    subprocesses: about 0.05 CPU s for its two names) and then globs the whole Python
    prefix recursively (0.25 CPU s in a 2.5 GB venv): the library the mkl wheel puts
    directly in ``sys.prefix/lib`` is named to it (``PYPARDISO_MKL_RT``) for the import
    instead (:func:`_mkl_rt_in_prefix`)."""
    path = _mkl_rt_in_prefix()
    if path is not None:
        os.environ["PYPARDISO_MKL_RT"] = path
    try:
        from pypardiso import ps
    finally:
        if path is not None:
            del os.environ["PYPARDISO_MKL_RT"]
    return ps._mkl_pardiso


def _mkl_rt_in_prefix() -> str | None:
    """The MKL runtime library of this Python environment, in ``sys.prefix/lib*`` (where
    the mkl wheel pypardiso depends on puts it; shortest name first, the first that loads),
    unless ``PYPARDISO_MKL_RT`` names one. ``None``: leave the search to pypardiso's loader
    (``find_library``, then the prefix's whole tree). The environment's own library comes
    before one the system's linker knows (pypardiso's order puts that first): it is the
    one installed with pypardiso, and finding it costs no subprocess."""
    if os.environ.get("PYPARDISO_MKL_RT"):
        return None
    for path in sorted(glob.glob(f"{sys.prefix}/[Ll]ib*/*mkl_rt*"), key=len):
        try:
            ctypes.CDLL(path)
        except OSError:
            continue
        return path
    return None


def _pardiso_iparm() -> np.ndarray:
    """PARDISO parameters (0-based, MKL numbering minus one) for SPD factor-once use."""
    iparm = np.zeros(64, dtype=np.int32)
    iparm[0] = 1  # use the values below, not MKL's defaults
    iparm[1] = 2  # fill-reducing ordering: METIS nested dissection
    iparm[7] = 0  # iterative refinement: none (SPD Cholesky needs none, no perturbed pivots)
    iparm[9] = 13  # pivot perturbation 1e-13 (unused for SPD, no pivoting)
    iparm[17] = -1  # report the number of nonzeros in the factor (iparm[17] on output)
    iparm[26] = 0  # matrix checker off: the CSR is built here, sorted, upper triangle
    iparm[34] = 1  # zero-based indices, as scipy stores them
    return iparm


class _PardisoHandle:
    """PARDISO's internal state for one matrix: upper-triangle CSR, pointers, parameters."""

    def __init__(self, a: sp.csr_matrix):
        upper = sp.triu(a, format="csr")
        upper.sort_indices()
        self.n = a.shape[0]
        self.data = np.ascontiguousarray(upper.data, dtype=np.float64)
        self.indptr = np.ascontiguousarray(upper.indptr, dtype=np.int32)
        self.indices = np.ascontiguousarray(upper.indices, dtype=np.int32)
        self.pt = np.zeros(64, dtype=np.int64)
        self.iparm = _pardiso_iparm()
        self.perm = np.zeros(0, dtype=np.int32)
        # Frees MKL's memory for this matrix when the handle is collected.
        self._finalizer = weakref.finalize(self, _pardiso_release, self.pt, self.iparm)

    def call(self, phase: int, b: np.ndarray, x: np.ndarray) -> int:
        """One PARDISO call; b and x are (n,) or Fortran-ordered (n, k). Returns the error."""
        error = ctypes.c_int32(0)
        nrhs = 1 if b.ndim == 1 else b.shape[1]
        _call_pardiso(self.pt, self.iparm, phase, self.n, self.data, self.indptr,
                      self.indices, nrhs, b, x, error)
        return error.value


def _call_pardiso(pt, iparm, phase, n, data, indptr, indices, nrhs, b, x, error) -> None:
    int_p, double_p = ctypes.POINTER(ctypes.c_int32), ctypes.POINTER(ctypes.c_double)
    one = ctypes.c_int32(1)
    _pardiso_function()(
        pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(one), ctypes.byref(one),
        ctypes.byref(ctypes.c_int32(2)),  # mtype 2: real symmetric positive definite
        ctypes.byref(ctypes.c_int32(phase)), ctypes.byref(ctypes.c_int32(n)),
        data.ctypes.data_as(double_p), indptr.ctypes.data_as(int_p),
        indices.ctypes.data_as(int_p), None, ctypes.byref(ctypes.c_int32(nrhs)),
        iparm.ctypes.data_as(int_p), ctypes.byref(ctypes.c_int32(0)),
        b.ctypes.data_as(double_p), x.ctypes.data_as(double_p), ctypes.byref(error),
    )


def _pardiso_release(pt: np.ndarray, iparm: np.ndarray) -> None:
    """Phase -1: release all of MKL's memory held under ``pt``."""
    if not pt.any():
        return
    empty = np.zeros(0, dtype=np.float64)
    index = np.zeros(1, dtype=np.int32)
    _call_pardiso(pt, iparm, -1, 0, empty, index, index, 1, empty, empty, ctypes.c_int32(0))
    pt[:] = 0


def _pardiso_check(error: int, stage: str) -> None:
    if error in _PARDISO_SINGULAR:
        raise SolverError(SINGULAR_MESSAGE.format(detail=f"PARDISO {stage}: zero or negative "
                                                  f"pivot, error {error}"))
    if error != 0:
        reason = _PARDISO_ERRORS.get(error, "unknown error")
        raise SolverError(f"PARDISO {stage} failed: {reason} (error {error})")


def _factorize_pardiso(a: sp.csr_matrix) -> Solve:
    handle = _PardisoHandle(a)
    dummy = np.zeros(handle.n)
    _pardiso_check(handle.call(12, dummy, dummy), "factorization")  # analysis + factor
    return _pardiso_solve(handle)


def _pardiso_solve(handle: _PardisoHandle) -> Solve:
    def phase(number: int, stage: str) -> Solve:
        def run(b: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
            b = np.asfortranarray(b, dtype=np.float64)
            x = np.empty_like(b, order="F") if out is None else out
            _pardiso_check(handle.call(number, b, x), stage)
            return x

        return run

    solve = phase(33, "back-solve")
    solve.nonzeros = int(handle.iparm[17])  # the factor's, as PARDISO reports them
    solve.writes_into = True  # takes ``out``: PARDISO writes x there (Fortran order)
    # forward and backward substitution (Factorization.halves), without the diagonal
    # phase 332: a Cholesky factor (mtype 2) has none
    solve.halves = (phase(331, "forward substitution"), phase(333, "backward substitution"))
    return solve


# ---------------------------------------------------------------- CHOLMOD (scikit-sparse)

def _factorize_cholmod(a: sp.csr_matrix) -> Solve:
    from sksparse.cholmod import CholmodNotPositiveDefiniteError, cholesky

    try:
        # CHOLMOD reads the lower triangle of a CSC matrix: that of A^T = A as CSR is free.
        factor = cholesky(a.T.tocsc() if not sp.isspmatrix_csc(a) else a)
    except CholmodNotPositiveDefiniteError:
        detail = "CHOLMOD: zero or negative pivot"
        raise SolverError(SINGULAR_MESSAGE.format(detail=detail)) from None
    return factor.solve_A


# ---------------------------------------------------------------- SuperLU (scipy)

def _factorize_superlu(a: sp.csr_matrix) -> Solve:
    from scipy.sparse.linalg import splu

    try:
        # COLAMD (scipy's default) measured fastest of SuperLU's orderings on these matrices
        # (docs/solvers.md); the "symmetric mode" orderings fill more.
        lu = splu(a.tocsc(), permc_spec=SUPERLU_ORDERING)
    except RuntimeError as err:  # "Factor is exactly singular"
        raise SolverError(SINGULAR_MESSAGE.format(detail=f"SuperLU: {err}")) from None
    return lu.solve


# ---------------------------------------------------------------- selection and checks

_BACKENDS: dict[str, Callable[[sp.csr_matrix], Solve]] = {
    "pardiso": _factorize_pardiso,
    "cholmod": _factorize_cholmod,
    "superlu": _factorize_superlu,
}


@functools.cache
def _importable(method: str) -> bool:
    try:
        if method == "pardiso":
            _pardiso_function()
        elif method == "cholmod":
            import sksparse.cholmod  # noqa: F401
        elif method == "petsc":
            from .petsc import installed

            return installed()
    except (ImportError, OSError):
        return False
    return True


def available_methods() -> list[str]:
    """Names of the backends usable here, fastest first (``"superlu"`` is always there)."""
    return [m for m in PREFERENCE if _importable(m)]


def _resolve(method: str) -> str:
    available = available_methods()
    if method == "auto":
        return available[0]
    if method == "petsc" and _importable("petsc"):
        return method
    if method not in available:
        known = "" if method in (*_BACKENDS, "petsc") else "unknown "
        raise ValueError(f"{known}linear solver {method!r}; available here: "
                         f"{', '.join(['auto', *available])}")
    return method


def _check_matrix(a: sp.csr_matrix) -> None:
    """Cheap necessary conditions for SPD: square, finite, positive diagonal."""
    if a.ndim != 2 or a.shape[0] != a.shape[1]:
        raise ValueError(f"matrix must be square, got shape {a.shape}")
    if not np.all(np.isfinite(a.data)):
        raise SolverError("matrix has non-finite entries")
    diagonal = a.diagonal()
    bad = np.flatnonzero(~(diagonal > 0))
    if bad.size:
        raise SolverError(SINGULAR_MESSAGE.format(
            detail=f"{bad.size} zero or negative diagonal entries, first at row {bad[0]}"))


def _probe(a: sp.csr_matrix, solve: Solve, method: str) -> float:
    """Relative residual of a solve with a right-hand side rich in A's lowest modes.

    One step of inverse iteration: x = A^-1 b for a random b is dominated by the eigenvectors
    of the smallest eigenvalues, and by a null vector (amplified ~1/eps) if A is singular. The
    residual of solving again with b1 = x / |x| is then ~eps * cond(A) for an SPD matrix, but
    of order one for a singular one: b1's part in the null space cannot be matched (this part is
    only ~sqrt(k / n) of a random b, which is why b itself is not the probe). Raises
    SolverError past PROBE_TOLERANCE or on non-finite values.
    """
    x = solve(np.random.default_rng(0).standard_normal(a.shape[0]))
    with np.errstate(over="ignore", invalid="ignore"):
        norm = float(np.sqrt(np.einsum("i,i->", x, x)))
        residual = float("inf")
        if np.isfinite(norm) and norm > 0:
            b1 = x / norm
            r = a @ solve(b1) - b1
            residual = float(np.sqrt(np.einsum("i,i->", r, r)))
    if not np.isfinite(residual):
        raise SolverError(
            f"{method}: a probe solve overflowed or gave NaN: the matrix's entries span more "
            "orders of magnitude than double precision holds (check the units and the "
            "material constants)")
    if not residual <= PROBE_TOLERANCE:
        raise SolverError(SINGULAR_MESSAGE.format(
            detail=f"{method}: a probe solve has relative residual {residual:.1e} > "
                   f"{PROBE_TOLERANCE:g}"))
    return residual


def factorize(a: sp.spmatrix | sp.sparray, method: str = "auto") -> Factorization:
    """Factorize a symmetric positive definite matrix once, for many back-solves.

    ``a``: sparse (n, n), symmetric positive definite (both triangles stored; a backend may
    read only one). ``method``: ``"auto"`` or one of :func:`available_methods`.
    Raises ``ValueError`` for an unknown or unavailable method and
    :class:`~fem_frac.errors.SolverError` for a singular or indefinite matrix.
    """
    name = _resolve(method)
    start = time.perf_counter()
    a = sp.csr_matrix(a, dtype=np.float64)
    _check_matrix(a)
    if name == "petsc":
        from .petsc import PetscFactorization, Settings
        from .ranks import active

        return PetscFactorization(a, np.arange(a.shape[0]), None, Settings(), active())
    solve = _BACKENDS[name](a)
    factorization = Factorization(name, a.shape[0], solve)
    factorization.probe_residual = _probe(a, solve, name)
    factorization.factor_time = time.perf_counter() - start
    return factorization


