"""PETSc linear solves (``linear_solver: petsc``): CG preconditioned by GAMG with the six
rigid-body modes as near-null space by default, or MUMPS's Cholesky factorization, on one
MPI rank or several (fem_frac/solve/ranks.py).

petsc4py is optional and imported only here, when the solver is asked for; its install is
``scripts/petsc-env.sh`` (docs/solvers.md, "PETSc").

The system is kept at full size with block size 3 (one block per node, as the dofs are
numbered ``3 * node + component``): the rows and columns of the constrained dofs are
replaced by the identity, so GAMG aggregates whole nodes and the rigid-body modes are built
from the node coordinates. The solution on the free dofs is that of the condensed system.
The KSP and its preconditioner are set up once per matrix and reused by every solve.
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util
import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import FemFracError, SolverError

INSTALL = "scripts/petsc-env.sh (docs/solvers.md, 'PETSc')"
OPTIONS_PREFIX = "fem_frac_"
_OPTIONS_SET: list[str] = []  # the options of ``analysis.petsc.options`` in PETSc's database


def installed() -> bool:
    """Whether petsc4py can be imported here (without importing it)."""
    return importlib.util.find_spec("petsc4py") is not None


def chosen(method: str, unknowns: int) -> bool:
    """Whether ``linear_solver: method`` solves a system of ``unknowns`` with PETSc:
    ``petsc``, or ``auto`` on several MPI ranks. On one rank ``auto`` stays with the direct
    solvers at every size: PETSc's setup is cheaper past ~50k unknowns, but each of its
    solves costs 5-8 back-solves of PARDISO, so which wins depends on how many solves a run
    makes (docs/solvers.md, "Which solver, how many ranks")."""
    if method == "petsc":
        return True
    if method != "auto":
        return False
    from .ranks import active

    return active() is not None


@functools.cache
def petsc():
    """The ``petsc4py.PETSc`` module (initialised on first use)."""
    try:
        from petsc4py import PETSc
    except ImportError as exc:
        raise FemFracError(f"linear_solver petsc: petsc4py cannot be imported ({exc}); "
                           f"install it with {INSTALL}") from None
    return PETSc


@dataclass(frozen=True)
class Settings:
    """How PETSc solves: Krylov method ``ksp``, preconditioner ``pc`` (``gamg``, ``hypre``
    or ``mumps``, a Cholesky factorization), relative residual ``rtol`` (of the true,
    unpreconditioned residual), ``max_iterations``, and further PETSc options passed as
    they are (``options``: name without the dash, value)."""

    ksp: str = "cg"
    pc: str = "gamg"
    rtol: float = 1e-10
    max_iterations: int = 1000
    options: tuple = ()

    @classmethod
    def of(cls, section) -> Settings:
        """From the case's ``analysis.petsc`` section (None: the defaults)."""
        if section is None:
            return cls()
        ksp = section.ksp or ("preonly" if section.pc == "mumps" else "cg")
        return cls(ksp, section.pc, section.rtol, section.max_iterations,
                   tuple(sorted(section.options.items())))

    def describe(self, ranks: int) -> str:
        where = f", {ranks} MPI ranks" if ranks > 1 else ""
        return f"petsc ({self.ksp} + {self.pc}{where})"


# ---------------------------------------------------------------- the full-size system

def eliminated(matrix: sp.csr_matrix, free: np.ndarray) -> sp.csr_matrix:
    """``matrix`` with the rows and columns of the dofs not in ``free`` replaced by the
    identity (symmetric, same size, block structure kept)."""
    n = matrix.shape[0]
    keep = np.zeros(n, dtype=bool)
    keep[free] = True
    a = sp.csr_matrix(matrix, dtype=np.float64, copy=True)
    rows = np.repeat(np.arange(n), np.diff(a.indptr))
    a.data[~(keep[rows] & keep[a.indices])] = 0.0
    a.eliminate_zeros()
    out = (a + sp.diags((~keep).astype(np.float64))).tocsr()
    out.sort_indices()
    return out


def row_ranges(n: int, size: int, bs: int) -> np.ndarray:
    """Start of each rank's rows (whole blocks of ``bs``), and the end: ``(size + 1,)``."""
    blocks = n // bs
    counts = np.full(size, blocks // size)
    counts[: blocks % size] += 1
    return bs * np.concatenate(([0], np.cumsum(counts)))


def row_block(a: sp.csr_matrix, start: int, stop: int) -> tuple:
    """CSR arrays ``(indptr, indices, data)`` of rows ``start:stop`` (PETSc's int32)."""
    lo, hi = a.indptr[start], a.indptr[stop]
    indptr = (a.indptr[start: stop + 1] - lo).astype(np.int32)
    return indptr, a.indices[lo:hi].astype(np.int32), a.data[lo:hi]


# ---------------------------------------------------------------- one rank's part

class LocalSystem:
    """The part of one MPI rank (all of it on one rank): its rows of the matrix, the KSP
    set up on them, and the solve of its rows of ``A x = b``. ``points``: the coordinates
    of the nodes of these rows, one per block of 3 (None: block size 1, no rigid-body
    modes)."""

    def __init__(self, comm, n: int, rows: tuple, csr: tuple, points: np.ndarray | None,
                 settings: Settings):
        PETSc = petsc()
        self.settings = settings
        start, stop = rows
        local = stop - start
        self.matrix = PETSc.Mat().createAIJ(size=((local, n), (local, n)),
                                            bsize=1 if points is None else 3, csr=csr,
                                            comm=comm)
        self.matrix.setOption(PETSc.Mat.Option.SPD, True)
        self.matrix.assemble()
        self.near_null = None
        if settings.pc == "gamg" and points is not None:
            coords = PETSc.Vec().createWithArray(np.ascontiguousarray(points.ravel()),
                                                 size=(local, n), bsize=3, comm=comm)
            self.near_null = PETSc.NullSpace().createRigidBody(coords)
            self.matrix.setNearNullSpace(self.near_null)
            coords.destroy()
        self.ksp = self._ksp(comm, settings)
        self.x, self.b = self.matrix.createVecs()

    def _ksp(self, comm, s: Settings):
        PETSc = petsc()
        options = PETSc.Options()
        # this solver's options only (those of the one before are taken out); they stay
        # until the next setup, as some are read at every solve (ksp_converged_reason)
        for name in _OPTIONS_SET:
            options.delValue(OPTIONS_PREFIX + name)
        _OPTIONS_SET.clear()
        for name, value in s.options:
            # true: the option given bare (-ksp_converged_reason), as on a command line
            options[OPTIONS_PREFIX + name] = (None if value is True else "false"
                                              if value is False else value)
            _OPTIONS_SET.append(name)
        ksp = PETSc.KSP().create(comm=comm)
        ksp.setOptionsPrefix(OPTIONS_PREFIX)
        ksp.setOperators(self.matrix)
        ksp.setType(s.ksp)
        pc = ksp.getPC()
        if s.pc == "mumps":
            pc.setType("cholesky")
            pc.setFactorSolverType("mumps")
        else:
            pc.setType(s.pc)
        if s.ksp != "preonly":
            ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
        ksp.setTolerances(rtol=s.rtol, atol=0.0, max_it=s.max_iterations)
        ksp.setFromOptions()
        ksp.setUp()  # the preconditioner (and a factorization) is made here, once
        return ksp

    def solve(self, b_local: np.ndarray) -> tuple[np.ndarray, int, int, float]:
        """This rank's rows of x; the iterations, PETSc's converged reason and the final
        residual norm (the same on every rank)."""
        self.b.getArray()[:] = b_local
        self.ksp.solve(self.b, self.x)
        return (self.x.getArray().copy(), self.ksp.getIterationNumber(),
                int(self.ksp.getConvergedReason()), self.ksp.getResidualNorm())

    def destroy(self) -> None:
        for obj in (self.ksp, self.x, self.b, self.near_null, self.matrix):
            if obj is not None:
                obj.destroy()


@contextlib.contextmanager
def refused(settings: Settings):
    """PETSc's errors (an unknown type, a bad option value, a missing package) as one line
    naming ``analysis.petsc``: PETSc's last message and its error code."""
    PETSc = petsc()
    try:
        yield
    except PETSc.Error as exc:
        lines = [line.removeprefix("[0] ") for line in str(exc).splitlines()]
        options = f", options {dict(settings.options)}" if settings.options else ""
        raise FemFracError(f"analysis.petsc ({settings.ksp} + {settings.pc}{options}): PETSc "
                           f"refused it: {lines[-1]} ({lines[0]})") from None


def reason_name(reason: int) -> str:
    names = {v: k for k, v in vars(petsc().KSP.ConvergedReason).items()
             if isinstance(v, int) and not k.startswith("_")}
    return names.get(reason, str(reason))


# ---------------------------------------------------------------- the solver rank 0 holds

class PetscFactorization:
    """The :class:`~fem_frac.solve.linalg.Factorization` interface on PETSc: ``solve(b)``
    on the free dofs, ``method``, ``n``, ``factor_time`` (setup), and ``iterations`` (of
    every solve so far, a list)."""

    def __init__(self, matrix: sp.csr_matrix, free: np.ndarray, points: np.ndarray,
                 settings: Settings, ranks=None):
        start = time.perf_counter()
        self.free = free
        self.n = len(free)
        self.full = matrix.shape[0]
        self.settings = settings
        self.ranks = ranks
        self.method = settings.describe(1 if ranks is None else ranks.size)
        self.iterations: list[int] = []
        self.probe_residual = float("nan")
        a = eliminated(matrix, free)
        with refused(settings):
            if ranks is None:
                self.local = LocalSystem(petsc().COMM_SELF, self.full, (0, self.full),
                                         row_block(a, 0, self.full), points, settings)
            else:
                self.local = ranks.setup(a, points, settings)
        self.factor_time = time.perf_counter() - start

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=np.float64)
        if b.ndim == 2:
            return np.stack([self.solve(column) for column in b.T], axis=1)
        if b.shape != (self.n,):
            raise ValueError(f"right-hand side of shape {b.shape}; expected ({self.n},)")
        full = np.zeros(self.full)
        full[self.free] = b
        with refused(self.settings):
            if self.ranks is None:
                x, its, reason, residual = self.local.solve(full)
            else:
                x, its, reason, residual = self.ranks.solve(self.local, full)
        self.iterations.append(its)
        if reason < 0 or not np.all(np.isfinite(x)):
            s = self.settings
            norm = float(np.linalg.norm(b))
            raise SolverError(
                f"PETSc {s.ksp} + {s.pc} did not converge: {reason_name(reason)} after {its} "
                f"iterations (relative residual {residual / norm if norm else residual:.1e}, "
                f"rtol {s.rtol:g}); raise analysis.petsc.max_iterations, or check that the "
                "body is fully constrained")
        return x[self.free]

    def __del__(self):
        local = getattr(self, "local", None)
        if local is None:
            return
        if self.ranks is None:
            local.destroy()
        else:
            self.ranks.release(local)

    def __repr__(self) -> str:
        return f"PetscFactorization(method={self.method!r}, n={self.n})"
