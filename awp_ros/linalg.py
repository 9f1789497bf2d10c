"""Small batched linear-algebra kernels shared by the polytope modules.

All functions are vectorised over a batch axis: the hot path calls each of them once per
control cycle on every candidate at once, never in a Python loop over candidates.

Normals of hyperplanes spanned by d - 1 vectors of R^d are generalised cross products
(closed-form cofactors, no pivoting):

    (1) (n)_i = (-1)^i det(B with coordinate i deleted),  n . b_l = 0 for every b_l;
    (2) the k x k minors of the first k vectors (all coordinate sets R, |R| = k) follow from
        the (k-1) x (k-1) ones by Laplace expansion along the k-th vector:
        M_k[R] = sum_p (-1)^(p + k - 1) b_k[R_p] M_{k-1}[R minus R_p];
    (3) candidates that share their first k vectors share M_k (prefix tree, SubsetTree).
"""

from __future__ import annotations

import threading
from functools import lru_cache
from itertools import combinations
from typing import NamedTuple

import numpy as np

__all__ = [
    'SubsetTree',
    'cross3',
    'generic_key',
    'hyperplane_normals',
    'orthonormal_span',
    'subset_normals',
    'subset_normals_t',
    'subset_tree',
    'unique_rows',
    'workspace',
]


class SubsetTree(NamedTuple):
    """Prefix tree of index subsets (rows of an integer array), for :func:`subset_normals`.

    ``levels[k - 1] = (last, parent)`` over the distinct k-prefixes of the rows (sorted):
    ``last`` is the prefix's final index, ``parent`` the position of its (k-1)-prefix in the
    previous level (``None`` at level 1). ``leaf`` maps each input row to its full prefix,
    ``None`` when that map is the identity (rows distinct and sorted). ``size`` is the
    number of input rows, ``width`` the subset size.
    """

    levels: tuple[tuple[np.ndarray, np.ndarray | None], ...]
    leaf: np.ndarray | None
    size: int
    width: int


def subset_tree(subsets: np.ndarray) -> SubsetTree:
    """Return the prefix tree of the rows of ``subsets`` (integer array ``(m, k)``).

    Build it once per subset pattern (e.g. per stance size, cached by the caller) and pass it
    to :func:`subset_normals`, which then expands each shared prefix once (eq. 3).
    """
    subsets = np.asarray(subsets, dtype=np.intp)
    m, k = subsets.shape
    levels = []
    prev = None
    inv = np.zeros(m, dtype=np.intp)
    for j in range(1, k + 1):
        uniq, inv = np.unique(subsets[:, :j], axis=0, return_inverse=True)
        inv = inv.reshape(-1)
        parent = None
        if prev is not None:
            parent = np.zeros(uniq.shape[0], dtype=np.intp)
            parent[inv] = prev
        levels.append((np.ascontiguousarray(uniq[:, -1]), parent))
        prev = inv
    leaf = inv if k else np.zeros(m, dtype=np.intp)
    if k and leaf.shape[0] == levels[-1][0].shape[0] and np.array_equal(leaf, np.arange(m)):
        leaf = None
    return SubsetTree(tuple(levels), leaf, m, k)


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Return the cross products ``a x b`` along the last axis (length 3), broadcasting.

    Same result as :func:`numpy.cross`, without its per-call overhead (tens of us).
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def hyperplane_normals(B: np.ndarray, rank_tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Return unit normals of the hyperplanes spanned by batches of d - 1 vectors.

    .. math:: n_i = \\star(\\hat b_{i,1} \\wedge \\dots \\wedge \\hat b_{i,d-1}), \\quad
              (n_i)_j = (-1)^j \\det \\hat B_i^{(j)}

    the generalised cross product (eqs. 1-2 of the module docstring) of the unit-scaled
    vectors ``b / |b|``, so ``n_i . b_{i,l} = 0``. ``|n_i|`` before normalisation is the
    volume spanned by the unit-scaled vectors (the product of the sines of Gram-Schmidt);
    the sign of each normal is arbitrary.

    :param B: array of shape ``(m, d - 1, d)``, the spanning vectors as rows.
    :param rank_tol: a batch whose unit-scaled volume is at most ``rank_tol`` (for ``d = 3``,
        the sine of the angle between the two vectors) is rank-deficient (no unique normal);
        a zero vector makes its batch rank-deficient.
    :return: ``(normals, valid)``: normals of shape ``(m, d)`` (zero rows where not
        valid) and a boolean mask of shape ``(m,)``.
    """
    B = np.asarray(B, dtype=float)
    m, k, d = B.shape
    if k != d - 1:
        msg = f'hyperplane_normals needs (m, d - 1, d) vectors; got shape {B.shape}'
        raise ValueError(msg)
    scale = np.sqrt(np.einsum('mkd,mkd->km', B, B))
    nonzero = np.all(scale > 0.0, axis=0)
    Bt = np.divide(B.transpose(1, 2, 0), np.where(scale > 0.0, scale, 1.0)[:, None, :],
                   out=workspace('hyperplane_vectors', (k, d, m)))
    n, valid = _cofactor_normals(d, m, [(Bt[j], None) for j in range(k)], rank_tol)
    valid &= nonzero
    n[:, ~valid] = 0.0
    return np.ascontiguousarray(n.T), valid


def subset_normals(V: np.ndarray, subsets: np.ndarray | SubsetTree,
                   rank_tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Return unit normals of the hyperplanes spanned by subsets of one set of vectors.

    .. math:: n_s \\perp v_j \\;\\forall j \\in S_s, \\quad |S_s| = d - 1, \\quad
              (n_s)_i = (-1)^i \\det \\hat V_{-i, S_s}

    Generalised cross products of the unit-scaled columns ``v_j / |v_j|``, eqs. (1-3) of the
    module docstring: the minors of each distinct prefix of the :class:`SubsetTree` are
    expanded once, every step one gather, multiply and add over a whole level (index tables
    cached per ``d``). The unit-scaled volume ``|n_s|`` (before normalisation) is the rank
    test. The sign of each normal is arbitrary.

    :param V: array of shape ``(d, N)``: the vectors as columns (zero columns allowed).
    :param subsets: integer array ``(m, d - 1)`` of column indices, or its
        :func:`subset_tree` (cache it when the pattern repeats).
    :param rank_tol: subsets with unit-scaled volume at most ``rank_tol`` are not valid.
    :return: ``(normals, valid)``: normals ``(m, d)`` (zero rows where not valid) and the
        boolean mask ``(m,)``.
    """
    n, valid = subset_normals_t(V, subsets, rank_tol)
    return np.ascontiguousarray(n.T), valid


def subset_normals_t(V: np.ndarray, subsets: np.ndarray | SubsetTree, rank_tol: float = 1e-9,
                     *, unit: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Return :func:`subset_normals` with the normals as columns, shape ``(d, m)``.

    :param unit: the columns of ``V`` are already unit vectors (skips the scaling).
    """
    V = np.asarray(V, dtype=float)
    d = V.shape[0]
    tree = subsets if isinstance(subsets, SubsetTree) else subset_tree(
        np.asarray(subsets, dtype=np.intp).reshape(-1, d - 1))
    if tree.width != d - 1:
        msg = f'subsets of {tree.width} vectors do not span hyperplanes of R^{d}'
        raise ValueError(msg)
    if not tree.levels:
        return np.ones((1, tree.size)), np.ones(tree.size, dtype=bool)
    zero = None
    if not unit:
        norms = np.sqrt(np.einsum('dn,dn->n', V, V))
        zero = norms <= 0.0
        V = V / np.where(zero, 1.0, norms)
    m_leaf = tree.levels[-1][0].shape[0]
    n, valid = _cofactor_normals(d, m_leaf, [(V[:, last], parent)
                                             for last, parent in tree.levels], rank_tol)
    if zero is not None and np.any(zero):
        valid &= ~_zero_in_subset(tree, zero)
    if tree.leaf is not None:
        n, valid = n[:, tree.leaf], valid[tree.leaf]
    if not np.all(valid):
        n[:, ~valid] = 0.0
    return n, valid


def orthonormal_span(V: np.ndarray, rtol: float = 1e-9) -> np.ndarray:
    """Return an orthonormal basis (columns) of the span of the rows of ``V``.

    :param V: array of shape ``(k, n)``.
    :param rtol: singular values below ``rtol`` times the largest are dropped.
    :return: array of shape ``(n, r)`` with ``r`` the numerical rank.
    """
    V = np.asarray(V, dtype=float)
    n = V.shape[1]
    if V.shape[0] == 0:
        return np.zeros((n, 0))
    _, s, vt = np.linalg.svd(V, full_matrices=False)
    if s.size == 0 or s[0] == 0.0:
        return np.zeros((n, 0))
    r = int(np.sum(s > rtol * s[0]))
    return vt[:r].T


def unique_rows(A: np.ndarray, tol: float = 1e-9, key: np.ndarray | None = None) -> np.ndarray:
    """Return the indices of rows of ``A`` kept after dropping near-duplicates.

    .. math:: i \\text{ dropped} \\iff \\exists j < i : \\|a_i - a_j\\|_\\infty \\le tol

    for rows adjacent in the order of a fixed generic projection ``key = A d`` (one sort,
    no pairwise table; only rows whose keys are within ``tol |d|_1`` are compared).
    Near-duplicates that the sort does not make adjacent are kept: the result may still hold
    duplicates, it never loses a distinct row.

    :param A: array of shape ``(m, n)`` (e.g. unit normals).
    :param tol: max-norm distance under which two rows are the same.
    :param key: ``A @ d`` if the caller already has it (see :func:`generic_key`).
    :return: sorted integer indices into the rows of ``A``.
    """
    A = np.asarray(A, dtype=float)
    m, n = A.shape
    if m < 2:
        return np.arange(m)
    direction = _generic_direction(n)
    if key is None:
        key = A @ direction
    order = np.argsort(key)
    ks = key[order]
    close = np.flatnonzero(ks[1:] - ks[:-1] <= tol * float(np.sum(np.abs(direction))))
    keep = np.ones(m, dtype=bool)
    if close.size:
        i, j = order[close], order[close + 1]
        At = A.T  # (n, m): reduce over the short axis 0, vectorised along the pairs
        dup = np.max(np.abs(At[:, i] - At[:, j]), axis=0) <= tol
        keep[j[dup]] = False
    return np.flatnonzero(keep)


def generic_key(A: np.ndarray) -> np.ndarray:
    """Return the sort key of :func:`unique_rows` for the rows of ``A`` (shape ``(m, n)``)."""
    return np.asarray(A, dtype=float) @ _generic_direction(A.shape[-1])


def _zero_in_subset(tree: SubsetTree, zero: np.ndarray) -> np.ndarray:
    """Return, per full prefix of the tree, whether one of its vectors is zero."""
    bad = None
    for last, parent in tree.levels:
        here = zero[last]
        bad = here if bad is None else here | bad[parent]
    return bad


def _cofactor_normals(d: int, m: int, levels: list,
                      rank_tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Return (normals (d, m), valid) from per-level unit vectors ``(d, n_k)`` and parents.

    Eq. (2) one position ``p`` at a time (temporaries ``(C(d, k), n_k)``); the parents'
    minors expanded to the level's prefixes, the largest array, live in a reused workspace.
    """
    if d == 1:
        return np.ones((1, m)), np.ones(m, dtype=bool)
    W = levels[0][0]
    for (b, parent), (T, SUB, SIGN) in zip(levels[1:], _laplace_tables(d)):
        if parent is not None:
            # The largest temporary of the kernel: reuse a per-thread buffer.
            W = np.take(W, parent, axis=1, mode='clip',
                        out=workspace('minors', (W.shape[0], parent.shape[0])))
        Wn = b[T[:, 0]] * W[SUB[:, 0]]
        if SIGN[0] < 0.0:
            np.negative(Wn, out=Wn)
        for p in range(1, T.shape[1]):
            term = b[T[:, p]] * W[SUB[:, p]]
            if SIGN[p] > 0.0:
                Wn += term
            else:
                Wn -= term
        W = Wn
    # Eq. (1): the minor without coordinate j is row d - 1 - j of combinations(d, d - 1).
    n = W[::-1] * _alternating(d)[:, None]
    vol = np.sqrt(np.einsum('dm,dm->m', n, n))
    valid = vol > rank_tol
    n /= np.where(valid, vol, 1.0)
    return n, valid


_WORKSPACE = threading.local()


def workspace(name: str, shape: tuple[int, ...]) -> np.ndarray:
    """Return a per-thread scratch array of ``shape``, reused across calls (contents undefined).

    Large temporaries of the per-cycle kernels (hundreds of kB) would otherwise come from
    fresh pages every cycle when the allocator returns freed memory to the system (glibc
    trims the heap top and serves big blocks by mmap): a page fault per 4 kB. Callers must
    not let the array escape: the next call with the same name overwrites it.
    """
    store = getattr(_WORKSPACE, 'arrays', None)
    if store is None:
        store = _WORKSPACE.arrays = {}
    size = int(np.prod(shape))
    buf = store.get(name)
    if buf is None or buf.size < size:
        buf = store[name] = np.empty(max(size, 1))
    return buf[:size].reshape(shape)


@lru_cache(maxsize=16)
def _laplace_tables(d: int) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]:
    """Index tables of eq. (2), from the k x k minors to the (k+1) x (k+1) ones.

    For each coordinate set ``R`` of size ``k + 1`` (lexicographic) and position ``p``:
    ``T[R, p] = R[p]``, ``SUB[R, p]`` = index of ``R`` without ``R[p]``,
    ``SIGN[p] = (-1)^(p + k)`` (expansion along the last column).
    """
    tables = []
    for k in range(1, d - 1):
        index = {c: i for i, c in enumerate(combinations(range(d), k))}
        rows = list(combinations(range(d), k + 1))
        T = np.array(rows, dtype=np.intp)
        SUB = np.array([[index[r[:p] + r[p + 1:]] for p in range(k + 1)] for r in rows],
                       dtype=np.intp)
        SIGN = np.array([(-1.0) ** (p + k) for p in range(k + 1)])
        tables.append((T, SUB, SIGN))
    return tuple(tables)


@lru_cache(maxsize=16)
def _alternating(d: int) -> np.ndarray:
    """Return ``[1, -1, 1, ...]`` of length ``d``."""
    return (-1.0) ** np.arange(d)


@lru_cache(maxsize=16)
def _generic_direction(n: int) -> np.ndarray:
    """Return a fixed direction with incommensurate components (sort key for unique_rows)."""
    return np.sqrt(np.arange(2, n + 2, dtype=float)) - 0.5 * np.arange(n) / (n + 1)
