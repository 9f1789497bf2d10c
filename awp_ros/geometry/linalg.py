"""
Small batched linear-algebra kernels shared by the polytope modules.

All functions are vectorised over a batch axis: the hot path calls each of them once per
control cycle on every candidate at once, never in a Python loop over candidates.

Normals of hyperplanes spanned by d - 1 vectors of R^d are generalised cross products
(closed-form cofactors, no pivoting; :mod:`awp_ros.geometry.exterior`):

    (1) (n)_i = (-1)^i det(B with coordinate i deleted),  n . b_l = 0 for every b_l;
    (2) the k x k minors of the first k vectors (all coordinate sets R, |R| = k, their
        wedge product) follow from the (k-1) x (k-1) ones by Laplace expansion along the
        k-th vector: M_k[R] = sum_p (-1)^(p + k - 1) b_k[R_p] M_{k-1}[R minus R_p];
    (3) candidates that share their first k vectors share M_k (prefix tree, SubsetTree);
    (4) with one set of N vectors, a level of the tree is one matrix product: the minors
        W (n_k, C(d, k)) of the k-prefixes times B = T V (C(d, k), C(d, k + 1) N), T the
        fixed table of eq. (2), give every prefix extended by every vector; the children are
        gathered from it (a few times more products than needed, but in BLAS: numpy's
        call overhead and the products, not the gather, are what cost at these sizes);
    (5) only the vectors lo..hi-1 that end some (k+1)-prefix enter that product (for the
        lexicographic s-subsets of m vectors, m - s + 1 of them at every level).
"""

from __future__ import annotations

from functools import lru_cache
import math
from math import comb
import threading
from typing import NamedTuple

import numpy as np
from scipy.linalg.lapack import dpotrf as _dpotrf

from awp_ros.errors import InputError
from awp_ros.geometry.exterior import hodge_normal, wedge_rows, wedge_table

__all__ = [
    'GRAM_CERTIFY',
    'SubsetTree',
    'quaternion_matrix',
    'cross3',
    'distinct_columns',
    'hyperplane_normals',
    'identity',
    'orthonormal_span',
    'subset_cross_products',
    'subset_normals',
    'subset_tree',
    'workspace',
]


class SubsetTree(NamedTuple):
    """
    Prefix tree of index subsets (rows of an integer array), for :func:`subset_normals`.

    ``levels[k - 1] = (last, parent)`` over the distinct k-prefixes of the rows (sorted):
    ``last`` is the prefix's final index, ``parent`` the position of its (k-1)-prefix in the
    previous level (``None`` at level 1). ``leaf`` maps each input row to its full prefix,
    ``None`` when that map is the identity (rows distinct and sorted). ``size`` is the
    number of input rows, ``width`` the subset size, ``vectors`` one more than the largest
    index. ``windows[k - 1] = (lo, hi)`` is the range of the last indices of level ``k + 1``
    (eq. 5), and ``gathers[k - 1]`` picks that level out of the products of eq. (4): the flat
    positions ``(parent * C + c) * (hi - lo) + last - lo`` of its ``C`` components ``c``.
    """

    levels: tuple[tuple[np.ndarray, np.ndarray | None], ...]
    leaf: np.ndarray | None
    size: int
    width: int
    vectors: int
    gathers: tuple[np.ndarray, ...]
    windows: tuple[tuple[int, int], ...] = ()


def subset_tree(subsets: np.ndarray) -> SubsetTree:
    """
    Return the prefix tree of the rows of ``subsets`` (integer array ``(m, k)``).

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
    n_vec = int(subsets.max(initial=-1)) + 1
    gathers, windows = [], []
    for j, (last, parent) in enumerate(levels[1:], start=2):
        width = comb(k + 1, j) if j < k else k + 1
        lo, hi = int(last.min()), int(last.max()) + 1
        pos = (parent[:, None] * width + np.arange(width)) * (hi - lo) + (last - lo)[:, None]
        gathers.append(pos)
        windows.append((lo, hi))
    return SubsetTree(tuple(levels), leaf, m, k, n_vec, tuple(gathers), tuple(windows))


@lru_cache(maxsize=8)
def identity(n: int) -> np.ndarray:
    """
    Return the ``n x n`` identity, one shared read-only array per ``n``.

    For the hull bases and frames the per-cycle code passes on unchanged (``np.eye`` costs
    ~1-2.5 us a call, five calls a cycle); writing into it raises instead of corrupting it.
    """
    eye = np.eye(n)
    eye.setflags(write=False)
    return eye


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """
    Return the cross products ``a x b`` along the last axis (length 3), broadcasting.

    Same result as :func:`numpy.cross`, without its per-call overhead (tens of us): a
    contraction with the Levi-Civita tensor for a few vectors, index shuffles for more.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    n = max(a.size, b.size)
    if n <= 72:
        return np.einsum('ijk,...j,...k->...i', _LEVI_CIVITA, a, b)
    return a[..., _NEXT] * b[..., _PREV] - a[..., _PREV] * b[..., _NEXT]


def hyperplane_normals(B: np.ndarray, rank_tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    r"""
    Return unit normals of the hyperplanes spanned by batches of d - 1 vectors.

    .. math:: n_i = \star(\hat b_{i,1} \wedge \dots \wedge \hat b_{i,d-1}), \quad
              (n_i)_j = (-1)^j \det \hat B_i^{(j)}

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
        raise InputError(msg)
    scale = np.sqrt(np.einsum('mkd,mkd->km', B, B))
    nonzero = np.all(scale > 0.0, axis=0)
    if d == 1:
        return np.ones((m, 1)), np.ones(m, dtype=bool)
    U = B / np.where(scale > 0.0, scale, 1.0).T[:, :, None]
    W = U[:, 0]
    for j in range(1, k):
        W = wedge_rows(W, U[:, j], d, j, 1)
    n = hodge_normal(W)
    vol = np.sqrt(np.einsum('md,md->m', n, n))
    valid = (vol > rank_tol) & nonzero
    n /= np.where(valid, vol, 1.0)[:, None]
    n[~valid] = 0.0
    return n, valid


def subset_normals(V: np.ndarray, subsets: np.ndarray | SubsetTree, rank_tol: float = 1e-9,
                   *, unit: bool = False) -> tuple[np.ndarray, np.ndarray]:
    r"""
    Return unit normals of the hyperplanes spanned by subsets of one set of vectors.

    .. math:: n_s \perp v_j \;\forall j \in S_s, \quad |S_s| = d - 1, \quad
              (n_s)_i = (-1)^i \det \hat V_{-i, S_s}

    The :func:`subset_cross_products` of the unit-scaled columns ``v_j / |v_j|``, normalised:
    their length, the unit-scaled volume, is the rank test (a subset holding a zero vector
    has volume 0). The sign of each normal is arbitrary.

    :param V: array of shape ``(d, N)``: the vectors as columns (zero columns allowed).
    :param subsets: integer array ``(m, d - 1)`` of column indices, or its
        :func:`subset_tree` (cache it when the pattern repeats).
    :param rank_tol: subsets with unit-scaled volume at most ``rank_tol`` are not valid.
    :param unit: the columns of ``V`` are already unit vectors (skips the scaling).
    :return: ``(normals, valid)``: normals ``(m, d)`` (zero rows where not valid) and the
        boolean mask ``(m,)``.
    """
    n = subset_cross_products(V, subsets, unit=unit)
    vol = np.sqrt(np.square(n) @ np.ones(n.shape[1]))   # (a product: short-axis sums are slow)
    valid = vol > rank_tol
    n *= (1.0 / np.where(valid, vol, 1.0))[:, None]
    if not np.all(valid):
        n[~valid] = 0.0
    return n, valid


def subset_cross_products(V: np.ndarray, subsets: np.ndarray | SubsetTree, *,
                          unit: bool = False) -> np.ndarray:
    r"""
    Return the generalised cross products of subsets of one set of vectors, eq. (1).

    .. math:: (n_s)_i = (-1)^i \det \hat V_{-i, S_s}, \quad |S_s| = d - 1

    of the unit-scaled columns ``v_j / |v_j|`` (``|n_s|`` is the volume they span), by
    eqs. (1-4) of the module docstring: each level of the :class:`SubsetTree` is one matrix
    product of the previous level's minors with a table built from ``V`` (eq. 4) and one
    gather.

    :param V: array of shape ``(d, N)``: the vectors as columns (zero columns allowed).
    :param subsets: integer array ``(m, d - 1)`` of column indices, or its
        :func:`subset_tree`.
    :param unit: the columns of ``V`` are already unit vectors (skips the scaling).
    :return: array ``(m, d)``.
    """
    V = np.asarray(V, dtype=float)
    d = V.shape[0]
    tree = subsets if isinstance(subsets, SubsetTree) else subset_tree(
        np.asarray(subsets, dtype=np.intp).reshape(-1, d - 1))
    if tree.width != d - 1:
        msg = f'subsets of {tree.width} vectors do not span hyperplanes of R^{d}'
        raise InputError(msg)
    if not tree.levels:
        return np.ones((tree.size, 1))
    V = V[:, :tree.vectors]
    if not unit:
        norms = np.sqrt(np.einsum('dn,dn->n', V, V))
        V = V / np.where(norms > 0.0, norms, 1.0)
    W = V.T[tree.levels[0][0]]
    windows = tree.windows or ((0, tree.vectors),) * len(tree.gathers)
    for k, (pos, (lo, hi)) in enumerate(zip(tree.gathers, windows), start=1):
        # Eq. (4-5): all products of the level's minors with the vectors that end a child
        # at this level, then the children.
        B = (_wedge_step(d, k) @ V[:, lo:hi]).reshape(W.shape[1], -1)
        Y = np.matmul(W, B, out=workspace('minors', (W.shape[0], B.shape[1])))
        W = Y.take(pos)
    if d == 2:
        W = hodge_normal(W)
    return W if tree.leaf is None else W[tree.leaf]


def orthonormal_span(V: np.ndarray, rtol: float = 1e-9) -> np.ndarray:
    r"""
    Return an orthonormal basis (columns) of the span of the rows of ``V``.

    Full rank is first certified without an SVD, from the Cholesky factor ``R`` of the
    Gram matrix ``G = V^T V`` (eigenvalues ``s_i^2``, the squared singular values of V):

    .. math:: \frac{s_{min}^2}{s_{max}^2} \ge \frac{\lambda_{min}(G)}{\operatorname{tr} G}
              \ge \frac{\det G}{(\operatorname{tr} G)^n}
              = \frac{\prod_i R_{ii}^2}{(\operatorname{tr} G)^n}

    (``lambda_max <= tr G`` and ``det G <= lambda_min lambda_max^(n-1)``). When the right
    side exceeds ``max(rtol^2, GRAM_CERTIFY)`` every singular value is above ``rtol`` times
    the largest, so the rank is n, exactly what the SVD test would find; the floor
    ``GRAM_CERTIFY`` keeps the certificate to well-conditioned ``G``, whose Cholesky
    factor is accurate. Otherwise (flat or ill-conditioned sets) the SVD decides.

    :param V: array of shape ``(k, n)``.
    :param rtol: singular values below ``rtol`` times the largest are dropped.
    :return: array of shape ``(n, r)`` with ``r`` the numerical rank (the identity when
        ``r = n``).
    """
    V = np.asarray(V, dtype=float)
    k, n = V.shape
    if k == 0:
        return np.zeros((n, 0))
    if k >= n:
        G = V.T @ V
        trace = float(G.trace())
        R, info = _dpotrf(G)
        if info == 0 and trace > 0.0:        # det G / (tr G)^n, without over/underflow
            ratio = math.prod([x * x / trace for x in R.diagonal().tolist()])
            if ratio > max(rtol * rtol, GRAM_CERTIFY):
                return identity(n)
    _, s, vt = np.linalg.svd(V, full_matrices=False)
    if s.size == 0 or s[0] == 0.0:
        return np.zeros((n, 0))
    r = int(np.sum(s > rtol * s[0]))
    if r == n:
        return identity(n)
    return vt[:r].T


def distinct_columns(mask: np.ndarray, own: int = 0) -> np.ndarray:
    """
    Return the sorted index of the first of each group of equal columns of a boolean mask.

    Used to keep one facet per incidence set (the generators or rays lying on it). With
    ``own > 0`` the caller guarantees that each column holds its own candidate's ``own``
    elements and that candidates differ in them: a column with exactly ``own`` True entries
    then equals no other column, and only the others are compared (packed into one exact
    float key each up to 52 rows, else row-wise).

    :param mask: boolean array ``(n, m)``.
    :param own: see above; 0 compares every column.
    :return: integer indices into the ``m`` columns, increasing.
    """
    n, m = mask.shape
    if own:
        multi = np.flatnonzero(np.ones(n) @ mask > own)
        if multi.size < 2:
            return np.arange(m)
        if 2 * multi.size < m:
            keep = np.ones(m, dtype=bool)
            keep[multi] = False
            keep[multi[distinct_columns(mask[:, multi])]] = True
            return np.flatnonzero(keep)
    if n <= 52:
        key = _bit_weights(n) @ mask
        first = np.unique(key, return_index=True)[1]
    else:
        first = np.unique(mask.T, axis=0, return_index=True)[1]
    return np.sort(first)


_WORKSPACE = threading.local()
GRAM_CERTIFY = 1e-10  # det G / (tr G)^n above this certifies full rank (orthonormal_span)
_NEXT, _PREV = np.array([1, 2, 0]), np.array([2, 0, 1])
_LEVI_CIVITA = np.zeros((3, 3, 3))
_LEVI_CIVITA[0, 1, 2] = _LEVI_CIVITA[1, 2, 0] = _LEVI_CIVITA[2, 0, 1] = 1.0
_LEVI_CIVITA[0, 2, 1] = _LEVI_CIVITA[2, 1, 0] = _LEVI_CIVITA[1, 0, 2] = -1.0


def workspace(name: str, shape: tuple[int, ...], dtype: type = np.float64) -> np.ndarray:
    """
    Return a per-thread scratch array of ``shape``, reused across calls (contents undefined).

    Large temporaries of the per-cycle kernels (hundreds of kB) would otherwise come from
    fresh pages every cycle when the allocator returns freed memory to the system (glibc
    trims the heap top and serves big blocks by mmap): a page fault per 4 kB. A buffer grows
    to at least twice its size when too small. Callers must not let the array escape: the
    next call with the same name overwrites it.
    """
    store = getattr(_WORKSPACE, 'arrays', None)
    if store is None:
        store = _WORKSPACE.arrays = {}
    size = math.prod(shape)
    buf = store.get(name)
    if buf is None or buf.size < size or buf.dtype != dtype:
        grow = 2 * buf.size if buf is not None and buf.dtype == dtype else 1
        buf = store[name] = np.empty(max(size, grow), dtype=dtype)
    return buf[:size].reshape(shape)


@lru_cache(maxsize=32)
def _wedge_step(d: int, k: int) -> np.ndarray:
    """
    Table of eq. (4) from k-vectors to (k+1)-vectors of R^d, shape ``(C(d, k) * C, d)``.

    ``(w ^ v)_s = sum_t sum_j w_t v_j T[t, s, j]`` (:func:`awp_ros.geometry.exterior.wedge_table`
    with the vector's index last), ``C = C(d, k + 1)``. At the last step (``k = d - 2``) the
    output is the normal of eq. (1) instead (:func:`awp_ros.geometry.exterior.hodge_normal`), ``C =
    d``.
    """
    T = wedge_table(d, k, 1).transpose(0, 2, 1)
    if k == d - 2:
        T = hodge_normal(T.transpose(0, 2, 1)).transpose(0, 2, 1)
    out = np.ascontiguousarray(T.reshape(-1, d))
    out.setflags(write=False)
    return out


@lru_cache(maxsize=16)
def _bit_weights(n: int) -> np.ndarray:
    """Return ``2^i`` for ``i < n`` as floats (exact integer keys for ``n <= 52``)."""
    out = 2.0 ** np.arange(n)
    out.setflags(write=False)
    return out


def quaternion_matrix(q: np.ndarray) -> np.ndarray:
    """Return the rotation matrix (3, 3) of a unit quaternion ``[x, y, z, w]``."""
    x, y, z, w = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
