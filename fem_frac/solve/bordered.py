"""Solves with the Jacobian of a mesh a crack insertion made, through the factorization of
the mesh before it (no refactorization per insertion).

A crack insertion gives some vertices copies; elements keep their geometry and material,
so their matrices do not change, only the dofs they are scattered to. Let ``tie`` map every
free dof of the new mesh to the free dof of the *base* mesh it copies (several new dofs may
tie to one base dof: a vertex and its copies), ``E (n', n)`` the matrix of that map
(``E[i, tie[i]] = 1``) and ``F (n', m)`` the unit columns of the ``m`` *copies*: every new
dof tied to a base dof except the first one, and every new dof tied to none (``tie = -1``:
a copy of a vertex split off the support that held it, its dof constrained in the base;
its row of ``E`` is zero). ``T = [E, F]`` is square and invertible, and
because tying the copies together gives back the base mesh,

    T^T A' T = [[A, C], [C^T, D]],    A = E^T A' E (the base Jacobian),
                                      C = E^T A' F (n x m),  D = F^T A' F (m x m).

With the base factorization of ``A``, ``G = A^-1 C`` (``m`` back-solves at once) and the
Cholesky factor of the Schur complement ``S = D - C^T G``, a solve ``A' x = b`` is

    y = A^-1 E^T b,   z = S^-1 (F^T b - C^T y),   w = y - G z,   x = E w + F z

(one back-solve with the base factor and small dense work). Exact, not an iteration: the
answer is the direct solve's to round-off.

Where the base factorization comes in halves, ``A^-1 = R^T R`` (PARDISO's Cholesky
``P A P^T = L L^T``: ``R = L^-1 P``, its forward substitution; ``R^T`` its backward one:
:class:`~fem_frac.solve.linalg.Factorization`), the columns kept are ``Y = R C`` instead of
``G``: ``m`` forward substitutions, half the work of ``m`` back-solves, and ``C^T G = Y^T
Y``. A solve is then

    u = R E^T b,   z = S^-1 (F^T b - Y^T u),   w = R^T (u - Y z),   x = E w + F z

still one back-solve, in its two halves.

The same base serves a sequence of insertions,
``tie`` composed through the meshes between, and ``m`` grows with them. A column of ``C``
that an insertion left alone (the copy's elements unchanged; its entries summed again in
another order where a neighbour split, so equal to ``REUSE`` of its size) keeps its column
of ``G`` and of ``C^T G``: a new mesh back-solves only its new or changed columns. The
columns live in one buffer along the chain (:class:`_Columns`), nothing copied.

Pieces that leave the mesh share no vertex with the rest, so the old Jacobian is block
diagonal and the new one is its block of the rest: :func:`restricted` solves through the
old factorization, exactly, and roots the later insertions' bordered factors.

Policy (:func:`bordered_factor`), deterministic so that a run repeats itself to the bit:
keep the base while ``G`` holds at most ``SHARE`` (1) times the entries of the base's
factor (``m <= SHARE nnz(L) / n``, PARDISO reports ``nnz(L)``): a solve then streams
``G`` once (``Y`` twice) against the factor twice, and ``G`` takes no more memory than
the factor (its buffer, with columns no longer used, up to about twice; chosen among 0.25,
0.5, 1 and 2 on ``cases/notched_beam.yaml``, docs/performance.md). Where
the backend does not report ``nnz(L)``, keep it while ``m <= COPIES n^(1/3)`` (2.5: where
the set-up of all ``m`` columns at once cost half a fresh factorization,
docs/performance.md). Past it (or where the tie does not cover the base's free dofs, or
``S`` is not positive definite: a piece the new faces leave loose),
:func:`bordered_factor` returns ``None`` and the caller factorizes afresh (which reports a
singular matrix properly).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

from .linalg import Factorization

# Keep the base factorization while G (n x m) holds at most this share of the factor's
# entries; where the backend does not report them, for up to COPIES copied dofs per cube
# root of its size.
SHARE = 1.0
COPIES = 2.5
# A Schur complement pivot below this share of the largest diagonal of D: singular.
SINGULAR = 1e-12
# A column of C that moved by at most this share of its largest entry is unchanged: its
# entries are the same element terms, summed in another order where a neighbour split.
REUSE = 1e-13
# Restricted factors (pieces that left) one chain may stack before a fresh factorization.
RESTRICTED = 8


def bordered_factor(base: Factorization, tie: np.ndarray, matrix: sp.csr_matrix,
                    free: np.ndarray | None = None) -> Factorization | None:
    """A factorization of ``matrix`` (the new free-dof Jacobian, ``(n', n')``) through
    ``base`` (a :class:`Factorization` of the base mesh's, or a bordered one, whose base is
    then used with the ties composed and whose columns of ``G`` (or ``Y``) are reused
    where ``C``'s did not change) and ``tie (n',)``: the free dof of ``base``'s matrix
    each new free dof copies. ``None`` where the module's policy says to refactorize.
    ``free``: ``matrix`` is the whole Jacobian and these (ascending) its free dofs; only the
    copies' columns are taken, not the free-dof matrix (the same entries)."""
    local = np.asarray(tie, dtype=np.int64)
    root, prior, tie = base, None, local
    if hasattr(base, "tie"):  # compose with the meshes between (-1 stays -1)
        root, prior = base.root, base
        tie = np.where(local >= 0, base.tie[np.maximum(local, 0)], -1)
    start = time.perf_counter()
    n = root.n
    if tie.size == 0 or tie.max() >= n or np.any(np.bincount(tie[tie >= 0], minlength=n) == 0):
        return None  # not every base dof has a copy left, or one that is not the base's
    copies = _copies(tie)
    m = copies.size
    if m > copies_limit(root):
        return None
    columns, d = _copy_columns(sp.csr_matrix(matrix), copies, free)
    own = np.flatnonzero(tie >= 0)
    tied = sp.csr_matrix((np.ones(own.size), (tie[own], own)), shape=(n, tie.size))  # E^T
    c = sp.csc_matrix(tied @ columns)  # (n, m), a few entries a column
    c.sort_indices()
    new, old = _unchanged_columns(prior, local[copies], c)
    fresh = np.setdiff1d(np.arange(m), new)
    columns, slot = _Columns.for_factor(prior, n, new, old, fresh, 2 * m + 16)
    halves = getattr(root, "halves", None)
    ctg = np.empty((m, m))  # C^T G: that of the reused columns kept
    ctg[np.ix_(new, new)] = prior.ctg[np.ix_(old, old)] if new.size else 0.0
    if fresh.size:
        g = columns.append(fresh.size)  # the new columns, solved into the buffer
        rhs = c[:, fresh].toarray(order="F")  # as PARDISO reads it
        if halves is not None:  # Y = R C: C^T A^-1 C = Y^T Y
            halves[0](rhs, out=g)
            block = (columns.buffer[:, :columns.live].T @ g)[slot]
        else:
            _solve_into(root, rhs, g)
            block = c.T @ np.ascontiguousarray(g)
        ctg[:, fresh], ctg[fresh, :] = block, block.T
    cho = _schur_factor(d - ctg, d) if m else None
    if m and cho is None:
        return None
    live = columns.live
    seconds = time.perf_counter() - start
    solve = _solve(root, tied, tie, copies, c, cho, columns.buffer[:, :live], slot)
    out = Factorization("bordered " + root.method, tie.size, solve)
    out.factor_time = seconds
    out.probe_residual = root.probe_residual
    out.root, out.tie, out.copies = root, tie, m
    # for the next insertion's reuse: the copies, C, G's columns (slots) and C^T G
    out.copy_ids, out.c, out.columns, out.slot, out.ctg = copies, c, columns, slot, ctg
    out.live = live
    out.solved = int(fresh.size)  # columns of G back-solved here (the others reused)
    return out


def _copy_columns(a: sp.csr_matrix, copies: np.ndarray, free: np.ndarray | None
                  ) -> tuple[sp.csr_matrix, np.ndarray]:
    """``(A'[:, copies] (n', m), A'[copies][:, copies] dense)`` of the free-dof matrix
    ``A'``: ``a`` itself, or ``a[free][:, free]`` where ``free`` is given, whose columns
    ``free[copies]`` are taken first (the same entries in the same order)."""
    if free is None:
        return a[:, copies], a[copies][:, copies].toarray()
    cols = np.asarray(free)[copies]
    return a[:, cols][free], a[cols][:, cols].toarray()


def restricted(base: Factorization, keep: np.ndarray) -> Factorization | None:
    """A factorization of ``A[keep][:, keep]`` through ``base``'s of ``A``, where ``A``
    couples no row of ``keep`` to a row outside it (block diagonal: a piece that left the
    mesh shared no vertex with the rest), so that ``A^-1 [b; 0] = [A_kk^-1 b; 0]``: one
    solve of ``base`` on ``b`` placed at ``keep`` (in exact arithmetic the other rows are
    zero). It serves as the root of later bordered factors (its copies' limit that of
    ``base``'s factor). ``None`` past ``RESTRICTED`` such factors in a chain (each adds a
    pass over the old dofs to every solve): then the caller factorizes afresh."""
    root = getattr(base, "root", base)
    depth = getattr(root, "depth", 0) + 1
    if depth > RESTRICTED:
        return None
    keep = np.asarray(keep, dtype=np.int64)

    def solve(b: np.ndarray) -> np.ndarray:
        full = np.zeros((base.n,) + b.shape[1:], order="F")
        full[keep] = b
        return base.solve(full)[keep]

    out = Factorization("restricted " + base.method, keep.size, solve)
    out.probe_residual = base.probe_residual
    out.nonzeros, out.depth = root.nonzeros, depth
    return out


def _solve(root, tied, tie, copies, c, cho, g, slot):
    """``A' x = b`` (module docstring) with ``g`` the live columns of G (of Y where the root
    has halves), ``slot`` each copy's column of it."""
    halves = getattr(root, "halves", None)

    def solve(b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=np.float64)
        one = b.ndim == 1
        b2 = b[:, None] if one else b
        rhs = np.asarray(tied @ b2)
        if not copies.size:
            x = root.solve(rhs)[tie]  # (no copies: every dof tied)
        elif halves is not None:  # y = R^T u, C^T y = Y^T u, w = R^T (u - Y z)
            forward, backward = halves
            u = forward(rhs)
            z = la.cho_solve(cho, b2[copies] - (g.T @ u)[slot])
            x = _tied(backward(u - g @ _spread(z, slot, g.shape[1])), tie)
            x[copies] += z
        else:
            y = root.solve(rhs)
            z = la.cho_solve(cho, b2[copies] - c.T @ y)
            x = _tied(y - g @ _spread(z, slot, g.shape[1]), tie)
            x[copies] += z
        return x[:, 0] if one else x

    return solve


def _tied(w: np.ndarray, tie: np.ndarray) -> np.ndarray:
    """``E w``: each new dof's base value, zero for the dofs tied to none."""
    x = w[np.maximum(tie, 0)]
    x[tie < 0] = 0.0
    return x


def _spread(z: np.ndarray, slot: np.ndarray, live: int) -> np.ndarray:
    """``z (m, k)`` on the slots of the buffer's ``live`` columns, zero elsewhere."""
    out = np.zeros((live, z.shape[1]))
    out[slot] = z
    return out


class _Columns:
    """The columns of ``G`` that a chain of bordered factors on one root holds: ``buffer
    (n, capacity)`` (Fortran order: a column is contiguous, ``G z`` reads the first
    ``live``), filled in order. A factor's columns are slots of it; a later factor keeps
    the slots of the columns it reuses and appends its new ones after the ``live`` ones,
    so nothing is copied. Columns no factor uses any more stay as dead slots until the
    buffer is full; then the live ones are copied into a new buffer."""

    def __init__(self, n: int, capacity: int):
        self.buffer = np.empty((n, capacity), order="F")
        self.live = 0

    @classmethod
    def for_factor(cls, prior, n: int, new: np.ndarray, old: np.ndarray, fresh: np.ndarray,
                   capacity: int) -> tuple[_Columns, np.ndarray]:
        """The buffer for a factor whose copies ``new`` reuse ``prior``'s columns ``old``
        and whose copies ``fresh`` add columns, and its slots ``(len(new) + len(fresh),)``
        (the added columns in order, after the buffer's live ones)."""
        k = fresh.size
        slot = np.empty(new.size + k, dtype=np.int64)
        shared = prior is not None and hasattr(prior, "columns")
        if shared and prior.columns.live == prior.live \
                and prior.live + k <= prior.columns.buffer.shape[1]:
            columns = prior.columns  # prior is its latest factor: append after its columns
            slot[new] = prior.slot[old]
        else:  # a fresh buffer, the reused columns copied to its front
            columns = cls(n, max(capacity, slot.size))
            if new.size:
                columns.buffer[:, : new.size] = prior.columns.buffer[:, prior.slot[old]]
            columns.live = new.size
            slot[new] = np.arange(new.size)
        slot[fresh] = columns.live + np.arange(k)
        return columns, slot

    def append(self, k: int) -> np.ndarray:
        """The next ``k`` columns of the buffer, now live, to be filled (a view)."""
        self.live += k
        return self.buffer[:, self.live - k: self.live]


def _solve_into(root, b: np.ndarray, out: np.ndarray) -> None:
    """``out[...] = A^-1 b`` through ``root``, in place where its backend can."""
    if isinstance(root, Factorization):
        root.solve(b, out=out)
    else:
        out[...] = root.solve(b)


def _copies(tie: np.ndarray) -> np.ndarray:
    """Sorted new dofs that are copies: the first new dof tied to each base dof represents
    it, the others copy it; a dof tied to none (-1: a vertex's copy off the support that
    holds the vertex) is bordered too."""
    order = np.argsort(tie, kind="stable")
    first = np.r_[True, tie[order][1:] != tie[order][:-1]] & (tie[order] >= 0)
    return np.sort(order[~first])


def _schur_factor(s: np.ndarray, d: np.ndarray):
    """Cholesky factor of the Schur complement ``s``; ``None`` where it is not positive
    definite, or a pivot was lost to round-off against ``d``'s diagonal (a singular S, as
    the direct solve's probe finds)."""
    try:
        cho = la.cho_factor(s, lower=True)
    except la.LinAlgError:
        return None
    if np.min(np.diag(cho[0])) ** 2 <= SINGULAR * np.max(np.abs(np.diag(d))):
        return None
    return cho


def copies_limit(root: Factorization) -> float:
    """The most copied dofs ``root`` serves (module docstring): ``SHARE`` times the factor's
    entries per dof where the backend reports them, else ``COPIES n^(1/3)``."""
    if root.nonzeros:
        return SHARE * root.nonzeros / root.n
    return COPIES * root.n ** (1.0 / 3.0)


def _unchanged_columns(prior: Factorization | None, copied: np.ndarray, c: sp.csc_matrix
                       ) -> tuple[np.ndarray, np.ndarray]:
    """``(j, k)``: the columns ``j`` of the new ``C`` equal, to round-off (``REUSE`` of the
    column's largest entry), to the columns ``k`` of ``prior``'s (a bordered factor on the
    same root), whose ``G`` columns therefore serve unchanged. ``copied``: the prior mesh's
    dof each new copy copies; a copy of a prior copy whose elements the insertion left
    alone has the same column (its entries summed again where a neighbour split)."""
    none = np.zeros(0, dtype=np.int64)
    if prior is None or prior.copies == 0 or c.shape[1] == 0:
        return none, none
    pos = np.minimum(np.searchsorted(prior.copy_ids, copied), prior.copies - 1)
    j = np.flatnonzero(prior.copy_ids[pos] == copied)
    if j.size == 0:
        return none, none
    k = pos[j]
    new, old = c[:, j], prior.c[:, k]
    diff = abs(new - old).max(axis=0).toarray().ravel()
    scale = np.maximum(abs(new).max(axis=0).toarray().ravel(),
                       abs(old).max(axis=0).toarray().ravel())
    same = diff <= REUSE * scale
    return j[same], k[same]
