r"""
Compiled kernels of the per-cycle geometry (numba), with the numpy code as their reference.

Profiling the per-cycle evaluation (``awp_bench``, cProfile) shows its time spread over some
800 Python-level calls per state, most of them numpy calls on arrays of a few hundred
entries, where the call overhead, not the arithmetic, is the cost. The kernels below fuse
the loops of the hottest steps into one compiled call each; the numpy implementations they
replace stay in place, are the reference the tests compare them with, and run when numba is
missing or ``AWP_ROS_KERNELS=numpy`` is set.

Kernels (same equations as the numpy code, see :mod:`awp_ros.geometry.linalg`):

* :func:`cross_products`: the generalised cross products of 5-subsets of one set of
  vectors of R^6, ``(n_s)_i = (-1)^i det V_{-i, S_s}``, the minors of each prefix by Laplace
  expansion along its last vector, reused by the next subset that shares the prefix
  (subsets in lexicographic order share long prefixes);
* :func:`zonotope_facets`: the facet normals and support values of a full-dimensional
  zonotope of R^6 from all its 5-subsets of generators, one normal per incidence set;
* :func:`cone_facets`: the facets of the cone spanned by unit rays, from candidate subsets:
  the side test stops at the first ray on each side, one normal per incidence set;
  :func:`cone_recheck` verifies the last cycle's facets on new rays (the contact wrench
  cone reuses them while they hold);
* :func:`parallelepipeds`: the force parallelepipeds of 3-joint legs (inverse by cofactors).

Measured beside the numpy code in one run (``AWP_ROS_KERNELS=numpy awp_bench`` against
``awp_bench``, the README's speed section): 2.5x on the force polytopes, 1.3x on the AWP, and
the contact wrench cone 6x when its facets are reused.

The kernels work in R^6 (full-dimensional sets: three or more stance legs), with the wedge
tables as constants so that the compiler unrolls them (2-3x over tables passed at run time);
incidence sets are bit masks, so they take at most 63 generators or rays. Callers use the
numpy code for flat sets and beyond. Compiled code is cached on disk (numba ``cache=True``);
``python -m awp_ros.geometry.kernels`` compiles it once (the bootstrap does). The tables are
frozen into the compiled code, whose cache numba keys on this file only: after an edit of
:func:`awp_ros.geometry.exterior.wedge_table`, touch this file (the bootstrap's stamp covers
both).
"""

from __future__ import annotations

from functools import lru_cache
from itertools import combinations
from math import comb
import os

import numpy as np

from awp_ros.geometry.exterior import wedge_table

try:  # numba is a dependency; without it (or AWP_ROS_KERNELS=numpy) the numpy code runs
    import numba
except ImportError:  # pragma: no cover - exercised only on installs without numba
    numba = None

__all__ = ['ENABLED', 'MAX_BITS', 'cone_facets', 'cone_recheck', 'cross_products',
           'parallelepipeds', 'wedge_tables', 'zonotope_facets']

#: Whether the compiled kernels are used (numba importable and not disabled).
ENABLED = numba is not None and os.environ.get('AWP_ROS_KERNELS', '') != 'numpy'
#: Largest number of generators / rays of the incidence bit masks.
MAX_BITS = 63
_COMPILED = False


def _jit(function=None, *, inline: bool = False):
    """
    Compile ``function`` with numba (no Python objects, cached on disk), if available.

    ``inline``: a helper inlined into its callers at numba's IR level (LLVM then sees the
    whole loop: 2-3x faster here than a call per candidate).
    """
    if function is None:
        return lambda f: _jit(f, inline=inline)
    if numba is None:
        return function
    return numba.njit(cache=True, nogil=True, inline='always' if inline else 'never')(function)


@lru_cache(maxsize=16)
def wedge_tables(d: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    r"""
    Return the Laplace-expansion tables of k-vectors of R^d, k = 1 .. d - 1.

    .. math:: (W \wedge v)_{S'} = \textstyle\sum_{t} \sigma_{k, S', t}\, W_{src_{k, S', t}}\,
              v_{row_{k, S', t}}

    the wedge of a k-vector ``W`` (components by the lexicographic k-subsets of the
    coordinates) with a vector ``v``: ``(src, row, sign)`` of shape ``(d, C_max, d)`` at
    level ``k`` (``k + 1`` terms per output), built from
    :func:`awp_ros.geometry.exterior.wedge_table` (same signs), and ``size[k] = C(d, k)``.
    """
    width = max(comb(d, k) for k in range(d + 1))
    src = np.zeros((d, width, d), dtype=np.int64)
    row = np.zeros((d, width, d), dtype=np.int64)
    sign = np.zeros((d, width, d))
    size = np.array([comb(d, k) for k in range(d + 1)], dtype=np.int64)
    for k in range(1, d - 1):
        T = wedge_table(d, k, 1)                     # (C(d, k), d, C(d, k + 1))
        for o, S in enumerate(combinations(range(d), k + 1)):
            for t, j in enumerate(S):
                rest = tuple(x for x in S if x != j)
                src[k, o, t] = list(combinations(range(d), k)).index(rest)
                row[k, o, t] = j
                sign[k, o, t] = T[src[k, o, t], j, o]
    for a in (src, row, sign, size):
        a.setflags(write=False)
    return src, row, sign, size


_SRC6, _ROW6, _SIGN6, _ = wedge_tables(6)


@_jit(inline=True)
def _wedge6(W, V, j, k, outputs):
    """Level ``k`` of the R^6 tables into ``W[k]`` (``outputs = C(6, k + 1)``, constant)."""
    for o in range(outputs):
        acc = 0.0
        for t in range(k + 1):
            acc += _SIGN6[k, o, t] * W[k - 1, _SRC6[k, o, t]] * V[_ROW6[k, o, t], j]
        W[k, o] = acc


@_jit(inline=True)
def _subset_normal6(V, subsets, s, prev, W, out):
    """:func:`_subset_normal` in R^6 with constant tables and trip counts (unrolled)."""
    start = 0
    while start < 5 and subsets[s, start] == prev[start]:
        start += 1
    for k in range(start, 5):
        j = subsets[s, k]
        prev[k] = j
        if k == 0:
            for i in range(6):
                W[0, i] = V[i, j]
        elif k == 1:
            _wedge6(W, V, j, 1, 15)
        elif k == 2:
            _wedge6(W, V, j, 2, 20)
        elif k == 3:
            _wedge6(W, V, j, 3, 15)
        else:
            _wedge6(W, V, j, 4, 6)
            for i in range(6):           # n_i = (-1)^i W_{[6] \ {i}}, that subset 5 - i
                out[i] = W[4, 5 - i] if i % 2 == 0 else -W[4, 5 - i]


@_jit(inline=True)
def _scratch():
    """Return the prefix minors (5, 20), the last subset (5,) and a normal (6,) buffers."""
    return np.empty((5, 20)), np.full(5, -1, dtype=np.int64), np.empty(6)


@_jit
def _cross_products(V, subsets):
    m = subsets.shape[0]
    out = np.empty((m, 6))
    W, prev, _ = _scratch()
    for s in range(m):
        _subset_normal6(V, subsets, s, prev, W, out[s])
    return out


def cross_products(V: np.ndarray, subsets: np.ndarray) -> np.ndarray:
    r"""
    Return the generalised cross products of 5-subsets of the columns of ``V`` (6, N).

    .. math:: (n_s)_i = (-1)^i \det V_{-i, S_s}, \quad |S_s| = 5

    :param V: ``(6, N)``, the vectors as columns (not rescaled).
    :param subsets: integer ``(m, 5)`` column indices; rows sharing their first entries with
        the previous row reuse its minors.
    :return: ``(m, 6)``, ``|n_s|`` the volume the subset spans.
    """
    return _cross_products(np.ascontiguousarray(V, dtype=float),
                           np.ascontiguousarray(subsets, dtype=np.int64))


@_jit(inline=True)
def _dot(n, X, j):
    """Return ``n . X[j]`` (unrolled in R^6, the hot case)."""
    if n.shape[0] == 6:
        return (n[0] * X[j, 0] + n[1] * X[j, 1] + n[2] * X[j, 2] + n[3] * X[j, 3]
                + n[4] * X[j, 4] + n[5] * X[j, 5])
    acc = 0.0
    for i in range(n.shape[0]):
        acc += n[i] * X[j, i]
    return acc


@_jit(inline=True)
def _norm2(n):
    """Return ``|n|^2``."""
    acc = 0.0
    for i in range(n.shape[0]):
        acc += n[i] * n[i]
    return acc


@_jit(inline=True)
def _zonotope_row(n, vol, gT, norms, incidence_tol, a, h, masks, multi, kept):
    """Store the facet of cross product ``n`` (length ``vol``) at row ``kept``; the count."""
    m, r = gT.shape
    inv = 1.0 / vol
    total = 0.0
    mask = 0
    count = 0
    for j in range(m):
        dot = abs(_dot(n, gT, j)) * inv
        total += dot
        if dot <= incidence_tol * norms[j]:
            mask |= 1 << j
            count += 1
    for i in range(r):
        a[kept, i] = n[i] * inv
    h[kept] = total
    masks[kept] = mask
    multi[kept] = count > r - 1
    return kept + 1


@_jit
def _zonotope_facets(g, norms, subsets, rank_tol, incidence_tol):
    r, m = g.shape
    n_sub = subsets.shape[0]
    a = np.empty((n_sub, r))
    h = np.empty(n_sub)
    masks = np.empty(n_sub, dtype=np.int64)
    multi = np.zeros(n_sub, dtype=np.bool_)
    U = np.empty((r, m))
    for i in range(r):
        for j in range(m):
            U[i, j] = g[i, j] / norms[j]
    gT = np.ascontiguousarray(g.T)
    normals = _cross_products(U, subsets)            # eq. (1) of every subset, then its row
    kept = 0
    for s in range(n_sub):
        vol = np.sqrt(_norm2(normals[s]))
        if vol > rank_tol:
            kept = _zonotope_row(normals[s], vol, gT, norms, incidence_tol, a, h, masks, multi,
                                 kept)
    keep = _first_of_each(masks[:kept], multi[:kept])
    return a[:kept][keep], h[:kept][keep]


@_jit
def _first_of_each(masks, multi):
    """Return the increasing indices of the first row of each mask (unique ones: all)."""
    n = masks.shape[0]
    keep = np.ones(n, dtype=np.bool_)
    idx = np.flatnonzero(multi)
    if idx.size > 1:
        order = idx[np.argsort(masks[idx], kind='mergesort')]
        for t in range(1, order.size):
            if masks[order[t]] == masks[order[t - 1]]:
                keep[order[t]] = False
    return np.flatnonzero(keep)


def zonotope_facets(g: np.ndarray, norms: np.ndarray, subsets: np.ndarray, rank_tol: float,
                    incidence_tol: float) -> tuple[np.ndarray, np.ndarray]:
    r"""
    Return the unit facet normals ``a`` (k, 6) and ``h(a) = sum_j |a . g_j|`` (k,).

    For a zonotope with generators ``g`` ``(6, m)`` (full-dimensional, ``norms`` their
    lengths), over ``subsets`` (the lexicographic 5-subsets): the cross
    product of each subset's unit-scaled generators, dropped when its length (the volume)
    is at most ``rank_tol``; one row per incidence set ``{j : |a . g_j| <= incidence_tol
    |g_j|}``, the first in subset order. The same rows, in the same order, as
    :func:`awp_ros.geometry.zonotope.zonotope`'s numpy code (both signs: ``a`` and ``-a``
    are the caller's).
    """
    return _zonotope_facets(np.ascontiguousarray(g, dtype=float),
                            np.ascontiguousarray(norms, dtype=float),
                            np.ascontiguousarray(subsets, dtype=np.int64),
                            float(rank_tol), float(incidence_tol))


@_jit(inline=True)
def _cone_row(n, vol, R, side_tol, A, masks, multi, kept, rows, s):
    """Store the facet of cross product ``n`` (length ``vol``) at row ``kept`` if it is one."""
    N, r = R.shape
    slack = side_tol * vol
    above = False
    below = False
    for j in range(N):
        dot = _dot(n, R, j)
        if dot > slack:
            above = True
        elif dot < -slack:
            below = True
        if above and below:
            return kept
    scale = (-1.0 if above else 1.0) / vol
    mask = 0
    count = 0
    for j in range(N):
        if abs(_dot(n, R, j)) <= slack:
            mask |= 1 << j
            count += 1
    for i in range(r):
        A[kept, i] = n[i] * scale
    masks[kept] = mask
    multi[kept] = count > r - 1
    rows[kept] = s
    return kept + 1


@_jit
def _cone_facets(R, subsets, side_tol, rank_tol):
    N, r = R.shape
    n_sub = subsets.shape[0]
    V = np.ascontiguousarray(R.T)
    A = np.empty((n_sub, r))
    masks = np.empty(n_sub, dtype=np.int64)
    multi = np.zeros(n_sub, dtype=np.bool_)
    rows = np.empty(n_sub, dtype=np.int64)
    W, prev, n = _scratch()
    kept = 0
    for s in range(n_sub):
        _subset_normal6(V, subsets, s, prev, W, n)
        vol = np.sqrt(_norm2(n))
        if vol > rank_tol:
            kept = _cone_row(n, vol, R, side_tol, A, masks, multi, kept, rows, s)
    keep = _first_of_each(masks[:kept], multi[:kept])
    return A[:kept][keep], rows[:kept][keep], masks[:kept][keep]


@_jit
def _cone_recheck(R, spans, masks, side_tol, rank_tol):
    N, r = R.shape
    k = spans.shape[0]
    V = np.ascontiguousarray(R.T)
    A = np.empty((k, r))
    W, prev, n = _scratch()
    for s in range(k):
        _subset_normal6(V, spans, s, prev, W, n)
        vol = np.sqrt(_norm2(n))
        if not vol > rank_tol:
            return A, False
        slack = side_tol * vol
        orient = 0.0
        for j in range(N):
            dot = _dot(n, R, j)
            if (masks[s] >> j) & 1:
                if abs(dot) > slack:
                    return A, False
            elif abs(dot) <= slack or (orient != 0.0 and dot * orient >= 0.0):
                return A, False
            elif orient == 0.0:
                orient = -1.0 if dot > 0.0 else 1.0
        if orient == 0.0:
            return A, False
        scale = orient / vol
        for i in range(r):
            A[s, i] = n[i] * scale
    return A, True


def cone_facets(rays: np.ndarray, subsets: np.ndarray, side_tol: float,
                rank_tol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""
    Return the unit outward facet normals ``A`` (k, r) of the cone spanned by unit rays.

    For rays ``(N, 6)`` (rows, unit length, spanning R^6) and candidate ``subsets``
    ``(m, 5)``: the cross product ``a`` of each subset with volume ``|a|`` above
    ``rank_tol``, kept when no ray lies beyond ``side_tol |a|`` on one of its sides
    (oriented so that every ray has ``A . ray <= 0``), one row per incidence set (the rays
    within ``side_tol |a|`` of it), the first in candidate order: the rows, in the order,
    of :func:`awp_ros.wrench.contact_wrench_cone.contact_wrench_cone`'s numpy code.

    :return: ``(A, spans, masks)``: the normals, the candidate subset that spans each
        facet ``(k, r - 1)`` and its incidence mask ``(k,)`` (bit j: ray j on the facet),
        the certificate :func:`cone_recheck` tests on the next rays.
    """
    R = np.ascontiguousarray(rays, dtype=float)
    S = np.ascontiguousarray(subsets, dtype=np.int64)
    A, rows, masks = _cone_facets(R, S, float(side_tol), float(rank_tol))
    return A, S[rows], masks


def cone_recheck(rays: np.ndarray, spans: np.ndarray, masks: np.ndarray, side_tol: float,
                 rank_tol: float) -> np.ndarray | None:
    r"""
    Return the facets of the cone of new rays when it has the facets of the old ones.

    The facets of the cone of unit rays ``(N, r)`` change with the rays only when some ray
    crosses a facet's hyperplane or a facet degenerates. For each old facet (its spanning
    subset and incidence mask from :func:`cone_facets`) the new cross product must have
    volume above ``rank_tol``, exactly the rays of its mask within ``side_tol |a|`` of it
    and every other ray strictly on one side: then every old facet is a facet of the new
    cone with the same rays, the facets' incidences (which ridges they share) are those of
    the old cone, whose facets covered its boundary, and so they cover the new boundary:
    the list is complete. (The caller checks every joint state of the default bag and
    random walks against the full computation.)

    :return: the unit outward normals ``(k, r)`` in the old order, or None when any test
        fails (recompute with :func:`cone_facets`).
    """
    A, ok = _cone_recheck(np.ascontiguousarray(rays, dtype=float), spans, masks,
                          float(side_tol), float(rank_tol))
    return A if ok else None


@_jit
def _parallelepipeds(J, bias, tau_min, tau_max, singular_rtol):
    K = J.shape[0]
    center = np.empty((K, 3))
    G = np.empty((K, 3, 3))
    V = np.empty((K, 8, 3))
    A = np.empty((K, 6, 3))
    b = np.empty((K, 6))
    ratio = np.empty(K)
    for k in range(K):
        sv = np.linalg.svd(np.ascontiguousarray(J[k]))[1]
        ratio[k] = sv[2] / max(sv[0], 2.2250738585072014e-308)
        # J^-T by cofactors: (J^T)^-1 = adj(J^T) / det = cof(J) / det, cof(J)_ij = C_ij
        M = J[k]
        c00 = M[1, 1] * M[2, 2] - M[1, 2] * M[2, 1]
        c01 = M[1, 2] * M[2, 0] - M[1, 0] * M[2, 2]
        c02 = M[1, 0] * M[2, 1] - M[1, 1] * M[2, 0]
        c10 = M[0, 2] * M[2, 1] - M[0, 1] * M[2, 2]
        c11 = M[0, 0] * M[2, 2] - M[0, 2] * M[2, 0]
        c12 = M[0, 1] * M[2, 0] - M[0, 0] * M[2, 1]
        c20 = M[0, 1] * M[1, 2] - M[0, 2] * M[1, 1]
        c21 = M[0, 2] * M[1, 0] - M[0, 0] * M[1, 2]
        c22 = M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0]
        det = M[0, 0] * c00 + M[0, 1] * c01 + M[0, 2] * c02
        ok = ratio[k] > singular_rtol
        inv = 1.0 / det if ok else np.nan
        C = np.array([[c00, c01, c02], [c10, c11, c12], [c20, c21, c22]]) * inv
        for i in range(3):
            acc = 0.0
            for j in range(3):
                half = 0.5 * (tau_max[k, j] - tau_min[k, j])
                G[k, i, j] = C[i, j] * half
                acc += C[i, j] * (bias[k, j] - 0.5 * (tau_max[k, j] + tau_min[k, j]))
            center[k, i] = acc
        for v in range(8):                   # signs of CUBE_SIGNS: itertools.product order
            s0 = 1.0 if v & 4 else -1.0
            s1 = 1.0 if v & 2 else -1.0
            s2 = 1.0 if v & 1 else -1.0
            for i in range(3):
                V[k, v, i] = center[k, i] - (G[k, i, 0] * s0 + G[k, i, 1] * s1
                                             + G[k, i, 2] * s2)
        for j in range(3):                   # rows J^T / |J col j|: the torque bounds
            norm = np.sqrt(M[0, j] * M[0, j] + M[1, j] * M[1, j] + M[2, j] * M[2, j])
            scale = 1.0 / norm if norm > 0.0 else np.nan
            for i in range(3):
                A[k, j, i] = M[i, j] * scale
                A[k, j + 3, i] = -M[i, j] * scale
            b[k, j] = (bias[k, j] - tau_min[k, j]) * scale
            b[k, j + 3] = (tau_max[k, j] - bias[k, j]) * scale
    return center, G, V, A, b, ratio


def parallelepipeds(J: np.ndarray, bias: np.ndarray, tau_min: np.ndarray,
                    tau_max: np.ndarray, singular_rtol: float) -> dict[str, np.ndarray]:
    """
    Return the force parallelepipeds of K 3-joint legs in one call.

    The compiled :func:`awp_ros.wrench.force_polytope.parallelepipeds` (its reference), the
    inverse by cofactors: same keys, values equal to rounding.
    """
    out = _parallelepipeds(np.ascontiguousarray(J, dtype=float),
                           np.ascontiguousarray(bias, dtype=float),
                           np.ascontiguousarray(tau_min, dtype=float),
                           np.ascontiguousarray(tau_max, dtype=float), float(singular_rtol))
    return dict(zip(('center', 'generators', 'vertices', 'A', 'b', 'sigma_ratio'), out))


def compile_all() -> None:
    """
    Compile (or load from the disk cache) every kernel on small inputs, once per process.

    :class:`~awp_ros.evaluation.evaluator.FeasibilityEvaluator` calls it when built, so that
    no control cycle pays for it: loading the cache takes ~0.3 s, compiling (a new install, an
    edited module) ~10 s.
    """
    global _COMPILED
    if _COMPILED or not ENABLED:
        return
    _COMPILED = True
    rng = np.random.default_rng(0)
    g = rng.normal(size=(6, 8))
    subsets = np.array(list(combinations(range(8), 5)), dtype=np.int64)
    cross_products(g, subsets)
    zonotope_facets(g, np.linalg.norm(g, axis=0), subsets, 1e-9, 1e-9)
    rays = g.T / np.linalg.norm(g.T, axis=1)[:, None]
    A, spans, masks = cone_facets(rays, subsets, 1e-9, 1e-9)
    cone_recheck(rays, spans, masks, 1e-9, 1e-9)
    J = rng.normal(size=(2, 3, 3))
    parallelepipeds(J, g[:2, :3], -np.ones((2, 3)), np.ones((2, 3)), 1e-9)


if __name__ == '__main__':
    compile_all()
    print(f'awp_ros.geometry.kernels: compiled ({"numba" if ENABLED else "numpy only"})')
