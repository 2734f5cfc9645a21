"""The matched faces of a tet table (two tets holding one vertex triple), kept per table.

Face row ``r`` is face ``r % 4`` (opposite corner ``r % 4``) of tet ``r // 4``. Matching
every face of a table is a sort of ``4 m`` triples; a crack-insertion batch asks for the
matched faces of its tables several times (debris check, smoothing update, site lookups,
the separation), so they are kept for the last few tables, keyed by a hash of the table's
contents, and :func:`~fem_frac.fracture.topology.cut_tets` derives a new table's from the
old one's (:func:`_kept_pairs`) instead of sorting again.
"""

from __future__ import annotations

import hashlib
import itertools
import weakref
from collections import OrderedDict

import numpy as np
import scipy.sparse as sp

from ..mesh.mesh import TET_FACES

# The matched faces of the last few connectivities asked for: a crack-insertion batch asks
# for those of its new mesh four times (debris check, smoothing update, site lookups), each
# a sort of every face of every tet; open_crack derives the new tables' from the old one's
# (the old, the split and the separated table: kept together, the old one asked again by
# each debris retry and by the new mesh's boundary groups).
_PAIRS: OrderedDict[tuple, tuple] = OrderedDict()
_PAIRS_KEPT = 4
# and their face adjacency, asked three times a batch (smoothing update, debris check,
# site lookups); dropped with the pairs
_ADJACENCY: dict[tuple, sp.csr_matrix] = {}
# The first rows (r1) of matched faces known to hold each face row in one pair at most (a
# manifold table's, and what _kept_pairs keeps of them), by identity: no count of the rows
# per cut. Read-only arrays (_seed_pairs), dropped with them.
_SINGLE: dict[int, tuple] = {}
# Numbers for the keys of the tables cut_tets makes (_new_key)
_MADE = itertools.count()
# The keys (hashes) of the tables cut_tets made, by identity: a batch asks for the matched
# faces of its tables about ten times, each a hash of the whole table otherwise.
_KEYS: dict[int, tuple] = {}


def _face_pairs(tets: np.ndarray):
    """Matched faces of ``tets``: rows ``r1, r2`` (face row ``r`` is face ``r % 4`` of tet
    ``r // 4``) that hold the same vertex set, and the local corners ``(k, 3)`` of each,
    listed in increasing global vertex id so that column ``j`` is the same vertex in both.

    A face held by more than two tets (non-manifold input) yields a chain of pairs, which
    is enough for connectivity. Kept for the last connectivities asked (by content: a
    hash of the tets), read-only.
    """
    tets = np.ascontiguousarray(tets, dtype=np.int64)
    return _pairs_keyed(tets, _key(tets))


def _pairs_keyed(tets: np.ndarray, key: tuple):
    """:func:`_face_pairs` of ``tets`` whose :func:`_key` is ``key`` (the least recently
    asked table goes first: a batch whose debris retries make tables keeps its mesh's)."""
    if key not in _PAIRS:
        _seed_pairs(tets, _match_faces(tets), key)
    _PAIRS.move_to_end(key)
    return _PAIRS[key]


def _key(tets: np.ndarray) -> tuple:
    """The caches' key of a connectivity: its shape and a hash of its contents (kept for
    the tables :func:`cut_tets` made, which no one edits: :data:`_KEYS`)."""
    known = recalled(_KEYS, tets)
    if known is not None:
        return known
    tets = np.ascontiguousarray(tets, dtype=np.int64)
    return tets.shape, hashlib.blake2b(tets.data, digest_size=16).digest()


def _remember_key(tets: np.ndarray) -> tuple:
    """:func:`_key` of ``tets``, kept while ``tets`` lives (a mesh's table, which no one
    edits in place)."""
    key = _key(tets)
    remember(_KEYS, tets, key)
    return key


def _new_key(tets: np.ndarray) -> tuple:
    """A key of its own for a table :func:`~fem_frac.fracture.topology.cut_tets` just made
    (and seeds the matched faces of), kept while ``tets`` lives: no hash of its contents,
    which only another array of the same contents would need (it would match afresh)."""
    key = (tets.shape, next(_MADE))
    remember(_KEYS, tets, key)
    return key


def remember(registry: dict, array: np.ndarray, value) -> None:
    """Keep ``value`` for ``array`` in ``registry``, by identity, while ``array`` lives
    (for arrays no one edits in place)."""
    ident = id(array)
    registry[ident] = (weakref.ref(array, lambda _: registry.pop(ident, None)), value)


def recalled(registry: dict, array: np.ndarray):
    """The value :func:`remember` kept for ``array`` itself, else ``None``."""
    known = registry.get(id(array))
    return known[1] if known is not None and known[0]() is array else None


def _seed_pairs(tets: np.ndarray, pairs, key: tuple | None = None) -> None:
    """Keep ``pairs`` as the matched faces of ``tets`` (made without a sort, by
    :func:`_kept_pairs`); ``key``: its :func:`_key` where known."""
    key = _key(tets) if key is None else key
    if key in _PAIRS:
        _PAIRS.move_to_end(key)
    while key not in _PAIRS and len(_PAIRS) >= _PAIRS_KEPT:
        _ADJACENCY.pop(_PAIRS.popitem(last=False)[0], None)
    for array in pairs:
        array.flags.writeable = False
    _PAIRS[key] = pairs


def _kept_pairs(pairs, old: np.ndarray, tets: np.ndarray,
                changed: np.ndarray | None = None):
    """The matched faces of ``tets`` from ``pairs``, those of the table ``old`` that
    ``tets`` was made from by giving some corners new ids (splits, copies): the pairs
    whose faces still hold one vertex set, with their local corners ordered by the new ids
    (recomputed for the tets whose ids changed). A split never makes two faces equal that
    were not, so no pair is missed; the pairs' order is the old one (every user of the
    pairs is indifferent to it). ``None`` where a face had more than two tets (a chain of
    pairs, which a split may re-link): then the faces are matched afresh. ``changed
    (m,)``: the tets whose ids differ from ``old``'s, where the caller knows them.
    """
    r1, r2, l1, l2 = pairs
    if recalled(_SINGLE, r1) is None:
        if np.bincount(np.concatenate([r1, r2]), minlength=4 * tets.shape[0]).max(initial=0) > 1:
            return None
        remember(_SINGLE, r1, True)
    if changed is None:
        changed = np.any(np.asarray(old) != tets, axis=1)
    # (a face row's tet is its row // 4: a shift, the rows being >= 0)
    touched = np.flatnonzero(changed[r1 >> 2] | changed[r2 >> 2])
    n1, g1 = _sorted_face(tets, r1[touched])
    n2, g2 = _sorted_face(tets, r2[touched])
    apart = np.any(g1 != g2, axis=1)
    out = tuple(_without(a, touched[apart]) for a in pairs)
    # the touched pairs kept, at their places among the kept ones: new local corners
    stay = touched[~apart]
    at = stay - np.searchsorted(touched[apart], stay)
    out[2][at], out[3][at] = n1[~apart], n2[~apart]
    remember(_SINGLE, out[0], True)  # a subset of pairs whose rows are each in one
    return out


def _without(a: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """A copy of ``a`` without its rows ``rows`` (sorted, unique; a few): the stretches
    between them joined (a boolean mask would be a pass over every row)."""
    ends = rows.tolist()
    starts = [0] + [r + 1 for r in ends]
    return np.concatenate([a[s:e] for s, e in zip(starts, ends + [a.shape[0]], strict=True)])


def _sorted_face(tets: np.ndarray, rows: np.ndarray):
    """Local corners ``(k, 3)`` and global ids of the face rows ``rows``, in increasing
    global id (as :func:`_match_faces` lists them)."""
    local = TET_FACES[rows % 4]
    glob = np.take_along_axis(tets[rows // 4], local, axis=1)
    order = np.argsort(glob, axis=1, kind="stable")
    return np.take_along_axis(local, order, axis=1), np.take_along_axis(glob, order, axis=1)


def _held(tets: np.ndarray) -> np.ndarray:
    """Mask ``(4 m,)`` over the face rows of ``tets``: the faces another tet also holds."""
    r1, r2, _, _ = _face_pairs(tets)
    held = np.zeros(4 * np.asarray(tets).shape[0], dtype=bool)
    held[r1] = held[r2] = True
    return held


def _match_faces(tets: np.ndarray):
    """:func:`_face_pairs`, computed."""
    m = tets.shape[0]
    glob = tets[:, TET_FACES].reshape(-1, 3)
    local = np.broadcast_to(TET_FACES, (m, 4, 3)).reshape(-1, 3)
    order = np.argsort(glob, axis=1, kind="stable")
    glob = np.take_along_axis(glob, order, axis=1)
    local = np.take_along_axis(local, order, axis=1)
    rows = np.lexsort((glob[:, 2], glob[:, 1], glob[:, 0]))
    s = glob[rows]
    same = np.all(s[1:] == s[:-1], axis=1)
    r1, r2 = rows[:-1][same], rows[1:][same]
    return r1, r2, local[r1], local[r2]


def face_adjacency(tets: np.ndarray) -> sp.csr_matrix:
    """Symmetric ``(m, m)`` 0/1 CSR matrix: entry ``(a, b)`` is 1 when tets a and b share a
    face. Kept with the matched faces: a copy is returned (callers may change theirs)."""
    key = _key(tets)
    r1, r2, _, _ = _pairs_keyed(np.ascontiguousarray(tets, dtype=np.int64), key)
    if key not in _ADJACENCY:
        _ADJACENCY[key] = _adjacency(np.asarray(tets).shape[0], r1, r2)
    return _ADJACENCY[key].copy()


def face_neighbours(tets: np.ndarray) -> np.ndarray:
    """``(m, 4)`` int64: the tet across each face of each tet (face ``j`` opposite corner
    ``j``), the tet itself where no other holds the face (the boundary, a crack)."""
    r1, r2, _, _ = _face_pairs(tets)
    m = np.asarray(tets).shape[0]
    out = np.repeat(np.arange(m, dtype=np.int64), 4)
    out[r1], out[r2] = r2 // 4, r1 // 4
    return out.reshape(m, 4)


def _adjacency(m: int, r1: np.ndarray, r2: np.ndarray) -> sp.csr_matrix:
    a, b = r1 // 4, r2 // 4
    rows = np.concatenate([a, b])
    cols = np.concatenate([b, a])
    adj = sp.coo_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(m, m)).tocsr()
    adj.data[:] = 1  # a (degenerate) double sharing counts once
    return adj
