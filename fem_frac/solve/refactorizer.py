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
        self._keys: np.ndarray | None = None  # the analysed pattern's, for _place
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
        place = self._place(upper) if h is not None and h.n == a.shape[0] else None
        if place is not None:
            return self._numeric(a, upper.data, start, place)
        h = self._handle = _PardisoHandle(a)
        self._gather = self._keys = None  # they were for the pattern analysed before
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
            return self._numeric(a, data[g.upper], start, g.place)
        a = matrix[free][:, free].tocsr()
        out = self.factorize(a)
        if self.method == "pardiso":
            again = self._seen is not None and self._seen.holds(matrix, free)
            if not again:
                self._seen = _Pattern.of(matrix, free)
            self._gather = self._gathered(matrix, a) if again else None
        return out

    def _gathered(self, matrix: sp.csr_matrix, a: sp.csr_matrix) -> _Gather | None:
        """The positions of :meth:`factorize_free` for ``matrix`` (of the pattern just seen
        again) and its restriction ``a``, which the handle was just made for."""
        found = _positions(self._seen, matrix, a) if self._handle is not None else None
        place = self._place(found[1]) if found is not None else None
        if place is None:
            return None
        return _Gather(self._seen, found[0], a.indptr.copy(), a.indices.copy(), a.shape,
                       found[1].data.astype(np.int64), place)

    def _place(self, upper: sp.csr_matrix) -> slice | np.ndarray | None:
        """Where the entries of ``upper`` (sorted CSR) go in the pattern the handle was
        analysed for: all of it (the same pattern), the positions of a part of it (entries
        that came out zero, such as a separated cohesive face's, and that a sum or product
        of scipy's left out), or ``None`` (an entry outside it: analyse again)."""
        h = self._handle
        if (len(h.indices) == len(upper.indices) and np.array_equal(h.indptr, upper.indptr)
                and np.array_equal(h.indices, upper.indices)):
            return slice(None)
        if upper.indices.size > h.indices.size:
            return None
        if self._keys is None:
            self._keys = _keys(h.indptr, h.indices, h.n)
        wanted = _keys(upper.indptr, upper.indices, h.n)
        at = np.minimum(np.searchsorted(self._keys, wanted), self._keys.size - 1)
        return at if np.array_equal(self._keys[at], wanted) else None

    def _numeric(self, a: sp.csr_matrix, upper: np.ndarray, start: float,
                 place: slice | np.ndarray = slice(None)) -> Factorization:
        """The numerical factorization (phase 22) of ``a``, whose upper triangle's entries
        ``upper`` go to ``place`` in the pattern the handle was analysed for (the others
        zero)."""
        h = self._handle
        if not isinstance(place, slice):
            h.data[:] = 0.0
        h.data[place] = upper
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
    whose CSR arrays are ``indptr``, ``indices``, ``shape``), among those, of its sorted
    upper triangle (``upper``), and where those go in the pattern of the PARDISO handle
    (``place``: all of it, or positions in a pattern that holds more)."""

    pattern: _Pattern
    restricted: np.ndarray
    indptr: np.ndarray
    indices: np.ndarray
    shape: tuple
    upper: np.ndarray
    place: slice | np.ndarray


def _positions(pattern: _Pattern, matrix: sp.csr_matrix, a: sp.csr_matrix
               ) -> tuple[np.ndarray, sp.csr_matrix] | None:
    """``(restricted, upper)`` of :class:`_Gather` for ``matrix`` (canonical CSR, of
    ``pattern``) and ``a = matrix[free][:, free]``, ``upper`` as a sorted CSR upper
    triangle whose entries are the positions: found by putting each entry's position + 1
    in its place and slicing as ``factorize_free`` does; ``None`` where that does not
    reproduce ``a``'s pattern (it always should; an explicit zero a slice dropped would
    show here)."""
    if not matrix.has_canonical_format:
        return None
    where = sp.csr_matrix((np.arange(1.0, matrix.nnz + 1.0), matrix.indices, matrix.indptr),
                          shape=matrix.shape)
    sub = where[pattern.free][:, pattern.free].tocsr()
    if not (np.array_equal(sub.indptr, a.indptr) and np.array_equal(sub.indices, a.indices)):
        return None
    at = sp.csr_matrix((np.arange(1.0, a.nnz + 1.0), a.indices, a.indptr), shape=a.shape)
    upper = sp.triu(at, format="csr")
    upper.sort_indices()
    upper.data -= 1.0
    return sub.data.astype(np.int64) - 1, upper


def _keys(indptr: np.ndarray, indices: np.ndarray, n: int) -> np.ndarray:
    """``row * n + column`` of each entry of a CSR pattern (ascending where it is sorted)."""
    rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr))
    return rows * n + indices
