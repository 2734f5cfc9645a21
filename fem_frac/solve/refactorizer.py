"""Factorizations of a sequence of matrices with one sparsity pattern, PARDISO's analysis
made once: full Newton's tangents, the cohesive faces' secant iteration matrices
(:mod:`fem_frac.solve.stepping`)."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .linalg import (
    Factorization,
    _check_matrix,
    _pardiso_check,
    _pardiso_solve,
    _PardisoHandle,
    _probe,
    _resolve,
    factorize,
)


class Refactorizer:
    """Factorizations of a sequence of matrices with one sparsity pattern (full Newton's
    tangents, the cohesive faces' secant matrices): PARDISO's ordering and symbolic
    analysis (phase 11) run once, each matrix then costs only the numerical factorization
    (phase 22). A matrix with another pattern is analysed afresh; other backends factorize
    every matrix from scratch. :meth:`factorize_free` takes the whole matrix and its free
    dofs, and restricts a pattern that comes back without slicing.

    Each :meth:`factorize` replaces the previous factorization made here: a
    :class:`Factorization` it returned earlier must not be used after the next call.
    """

    def __init__(self, method: str = "auto"):
        self.method = _resolve(method)
        self._handle: _PardisoHandle | None = None
        self._seen: _Pattern | None = None  # factorize_free's last pattern
        self._gather: _Gather | None = None  # and its positions, once it came back
        self.analyses = 0

    def factorize(self, a: sp.spmatrix | sp.sparray) -> Factorization:
        if self.method != "pardiso":
            return factorize(a, self.method)
        start = time.perf_counter()
        a = sp.csr_matrix(a, dtype=np.float64)
        _check_matrix(a)
        upper = sp.triu(a, format="csr")
        upper.sort_indices()
        h = self._handle
        if (h is not None and h.n == a.shape[0] and len(h.indices) == len(upper.indices)
                and np.array_equal(h.indptr, upper.indptr)
                and np.array_equal(h.indices, upper.indices)):
            return self._numeric(a, upper.data, start)
        h = self._handle = _PardisoHandle(a)
        self._gather = None  # its positions were for the pattern analysed before
        dummy = np.zeros(a.shape[0])
        _pardiso_check(h.call(12, dummy, dummy), "factorization")
        self.analyses += 1
        return self._made(a, h, start)

    def factorize_free(self, matrix: sp.csr_matrix, free: np.ndarray) -> Factorization:
        """:meth:`factorize` of ``matrix[free][:, free]``. Where ``matrix`` has the pattern
        (and ``free`` the dofs) of the call before, and of one before that, its restricted
        entries and their upper triangle are gathered from ``matrix.data`` at positions
        kept from then: the same values in the same places as slicing, ``triu`` and sorting
        give, without them (about 0.6 ms a refactorization at 2.5k dofs). The positions are
        found only for a pattern that comes back (one slicing more): a pattern seen once,
        such as a new mesh's first matrix, costs nothing more."""
        matrix = sp.csr_matrix(matrix, dtype=np.float64)
        g = self._gather
        if (self.method == "pardiso" and g is not None and self._handle is not None
                and g.pattern.holds(matrix, free)):
            start = time.perf_counter()
            data = matrix.data[g.restricted]
            a = sp.csr_matrix((data, g.indices, g.indptr), shape=g.shape)
            _check_matrix(a)
            return self._numeric(a, data[g.upper], start)
        a = matrix[free][:, free].tocsr()
        out = self.factorize(a)
        if self.method == "pardiso":
            again = self._seen is not None and self._seen.holds(matrix, free)
            if not again:
                self._seen = _Pattern.of(matrix, free)
            self._gather = _Gather.of(self._seen, matrix, a, self._handle) if again else None
        return out

    def _numeric(self, a: sp.csr_matrix, upper: np.ndarray, start: float) -> Factorization:
        """The numerical factorization (phase 22) of ``a``, whose upper triangle's entries
        ``upper`` have the pattern the handle was analysed for."""
        h = self._handle
        h.data[:] = upper
        dummy = np.zeros(a.shape[0])
        _pardiso_check(h.call(22, dummy, dummy), "factorization")
        return self._made(a, h, start)

    @staticmethod
    def _made(a: sp.csr_matrix, h: _PardisoHandle, start: float) -> Factorization:
        solve = _pardiso_solve(h)
        factorization = Factorization("pardiso", a.shape[0], solve)
        factorization.probe_residual = _probe(a, solve, "pardiso")
        factorization.factor_time = time.perf_counter() - start
        return factorization


@dataclass(frozen=True, eq=False)
class _Pattern:
    """A matrix's pattern (CSR ``indptr``, ``indices``, ``shape``; copies) and free dofs."""

    indptr: np.ndarray
    indices: np.ndarray
    shape: tuple
    free: np.ndarray

    @classmethod
    def of(cls, matrix: sp.csr_matrix, free: np.ndarray) -> _Pattern:
        return cls(matrix.indptr.copy(), matrix.indices.copy(), matrix.shape,
                   np.array(free, copy=True))

    def holds(self, matrix: sp.csr_matrix, free: np.ndarray) -> bool:
        return (matrix.shape == self.shape and matrix.indices.size == self.indices.size
                and np.array_equal(matrix.indptr, self.indptr)
                and np.array_equal(matrix.indices, self.indices)
                and np.array_equal(free, self.free))


@dataclass(frozen=True, eq=False)
class _Gather:
    """Positions for :meth:`Refactorizer.factorize_free`: of a matrix of ``pattern``, the
    positions in its ``data`` of the entries of ``matrix[free][:, free]`` (``restricted``,
    whose CSR arrays are ``indptr``, ``indices``, ``shape``) and, among those, of its
    sorted upper triangle (``upper``, the pattern of the PARDISO handle)."""

    pattern: _Pattern
    restricted: np.ndarray
    indptr: np.ndarray
    indices: np.ndarray
    shape: tuple
    upper: np.ndarray

    @classmethod
    def of(cls, pattern: _Pattern, matrix: sp.csr_matrix, a: sp.csr_matrix,
           handle: _PardisoHandle | None) -> _Gather | None:
        """The positions of ``matrix`` (canonical CSR, of ``pattern``) for ``a =
        matrix[free][:, free]`` and ``handle`` (analysed for ``a``'s upper triangle), found
        by putting each entry's position + 1 in its place and slicing as
        ``factorize_free`` and the handle do; ``None`` where that does not reproduce their
        patterns (it always should; an explicit zero a slice dropped would show here)."""
        if handle is None or not matrix.has_canonical_format:
            return None
        where = sp.csr_matrix((np.arange(1.0, matrix.nnz + 1.0), matrix.indices,
                               matrix.indptr), shape=matrix.shape)
        sub = where[pattern.free][:, pattern.free].tocsr()
        if not (np.array_equal(sub.indptr, a.indptr) and np.array_equal(sub.indices, a.indices)):
            return None
        at = sp.csr_matrix((np.arange(1.0, a.nnz + 1.0), a.indices, a.indptr), shape=a.shape)
        upper = sp.triu(at, format="csr")
        upper.sort_indices()
        if not (np.array_equal(upper.indptr, handle.indptr)
                and np.array_equal(upper.indices, handle.indices)):
            return None
        return cls(pattern, sub.data.astype(np.int64) - 1, a.indptr.copy(), a.indices.copy(),
                   a.shape, upper.data.astype(np.int64) - 1)
