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
    """Factorizations of a sequence of matrices with one sparsity pattern (the tangents of
    full Newton): PARDISO's ordering and symbolic analysis (phase 11) run once, each matrix
    then costs only the numerical factorization (phase 22). A matrix with another pattern
    is analysed afresh; other backends factorize every matrix from scratch.

    Each :meth:`factorize` replaces the previous factorization made here: a
    :class:`Factorization` it returned earlier must not be used after the next call.
    """

    def __init__(self, method: str = "auto"):
        self.method = _resolve(method)
        self._handle: _PardisoHandle | None = None
        self._gather: _Gather | None = None  # factorize_free's positions (last pattern)
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
        dummy = np.zeros(a.shape[0])
        _pardiso_check(h.call(12, dummy, dummy), "factorization")
        self.analyses += 1
        return self._made(a, h, start)

    def factorize_free(self, matrix: sp.csr_matrix, free: np.ndarray) -> Factorization:
        """:meth:`factorize` of ``matrix[free][:, free]``. Where ``matrix`` has the pattern
        of the previous call's (and ``free`` its dofs), the restricted matrix's entries and
        its upper triangle's are gathered from ``matrix.data`` at positions kept from that
        call: the same values in the same places as slicing, ``triu`` and sorting give,
        without them (about a millisecond at a few thousand dofs, per refactorization)."""
        matrix = sp.csr_matrix(matrix, dtype=np.float64)
        g = self._gather
        if (self.method == "pardiso" and g is not None and self._handle is not None
                and g.holds(matrix, free)):
            start = time.perf_counter()
            data = matrix.data[g.restricted]
            a = sp.csr_matrix((data, g.indices, g.indptr), shape=g.shape)
            _check_matrix(a)
            return self._numeric(a, data[g.upper], start)
        a = matrix[free][:, free].tocsr()
        out = self.factorize(a)
        if self.method == "pardiso":
            self._gather = _Gather.of(matrix, free, a, self._handle)
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
class _Gather:
    """Positions for :meth:`Refactorizer.factorize_free`: of a matrix's pattern
    (``pattern``: its ``indptr``, ``indices``, shape; ``free``), the positions in its
    ``data`` of the entries of ``matrix[free][:, free]`` (``restricted``, whose CSR arrays
    are ``indptr``, ``indices``, ``shape``) and, among those, of its sorted upper triangle
    (``upper``, the pattern of the PARDISO handle)."""

    pattern: tuple
    free: np.ndarray
    restricted: np.ndarray
    indptr: np.ndarray
    indices: np.ndarray
    shape: tuple
    upper: np.ndarray

    def holds(self, matrix: sp.csr_matrix, free: np.ndarray) -> bool:
        indptr, indices, shape = self.pattern
        return (matrix.shape == shape and matrix.indices.size == indices.size
                and np.array_equal(matrix.indptr, indptr)
                and np.array_equal(matrix.indices, indices)
                and np.array_equal(free, self.free))

    @classmethod
    def of(cls, matrix: sp.csr_matrix, free: np.ndarray, a: sp.csr_matrix,
           handle: _PardisoHandle | None) -> _Gather | None:
        """The positions of ``matrix`` (canonical CSR) for ``a = matrix[free][:, free]``
        and ``handle`` (analysed for ``a``'s upper triangle), found by putting each entry's
        position + 1 in its place and slicing as ``factorize_free`` and the handle do;
        ``None`` where that does not reproduce their patterns (it always should; an
        explicit zero a slice dropped would show here)."""
        if handle is None or not matrix.has_canonical_format:
            return None
        where = sp.csr_matrix((np.arange(1.0, matrix.nnz + 1.0), matrix.indices,
                               matrix.indptr), shape=matrix.shape)
        sub = where[free][:, free].tocsr()
        if not (np.array_equal(sub.indptr, a.indptr) and np.array_equal(sub.indices, a.indices)):
            return None
        at = sp.csr_matrix((np.arange(1.0, a.nnz + 1.0), a.indices, a.indptr), shape=a.shape)
        upper = sp.triu(at, format="csr")
        upper.sort_indices()
        if not (np.array_equal(upper.indptr, handle.indptr)
                and np.array_equal(upper.indices, handle.indices)):
            return None
        return cls((matrix.indptr.copy(), matrix.indices.copy(), matrix.shape),
                   np.array(free, copy=True), sub.data.astype(np.int64) - 1,
                   a.indptr.copy(), a.indices.copy(), a.shape,
                   upper.data.astype(np.int64) - 1)
