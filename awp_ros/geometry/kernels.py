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
  :func:`lifted_zonotope` fuses it with the lift and the rank certificate (the AWP);
* :func:`cone_facets`: the facets of the cone spanned by unit rays, from candidate subsets:
  every cross product, then every side value in one matrix product, one normal per
  incidence set; :func:`cone_recheck` verifies the last cycle's facets on new rays (the
  contact wrench cone reuses them while they hold); :func:`lifted_rays` lifts the rays;
* :func:`polar_hull` and :func:`polygon_region`: the CoM regions' polygons (the hull of the
  lines' dual points, the primal vertices, short edges dropped, the margin);
  :func:`segment_slice`: the segment of a wrench set on a hyperplane (two stance legs);
* :func:`leg_vertices`, :func:`projected_polygon` and :func:`feasible_region`: the feasible
  region by exact iterative projection of the contact-force LP (a small dense simplex);
  :func:`directional_margins_lp`: the FWS's directional margins by the same simplex;
* :func:`parallelepipeds`: the force parallelepipeds of 3-joint legs (inverse by cofactors);
* :func:`batched_vertices`: the friction-bounded leg polytopes' vertices, every row triple of
  every leg by Cramer's rule in one pass;
* :func:`solid_faces`: the faces and normal cones of a solid leg polytope from its points and
  H-rep (facet rows, edges, their classes), for the FWS's Minkowski sum;
  :func:`certified_solid_faces` with the centroid, scale and full-rank certificate;
* :func:`survivor_normals`: the unit normals of the FWS's face choices that passed the
  normal-cone filter (a sparse wedge, the Hodge dual, the norm);
* :func:`first_of_equal_rows`: the FWS's rows deduplicated (one hash-table pass);
* :func:`ratio_test`: the directional margins' ratio test over every row in one pass;
  :func:`two_leg_contains`: the FWS's verdict for two stance legs (a ratio test on the line
  of their force distributions);
  :func:`slack_min`: the first row of least slack ``b - A w`` (the margins' inside test);
  :func:`min_norm_point`: the nearest point of the FWS to a wrench outside it, from the legs'
  lifted points (Wolfe's algorithm; its reference is the H-rep's least-distance program);
* :func:`cycle_sets` and :func:`cycle_regions`: a control cycle's sets (with the margins'
  slacks) and its three CoM regions, each in one call of the kernels above;
* :func:`slice_facet_normals`: the FWS's face choices of the patterns (2, 1, 1, 1), (2, 2, 1),
  (3, 1, 1) and (3, 2) searched on the slices of one leg's facet (or of the whole leg), in R^4
  (:mod:`awp_ros.geometry.minkowski_facets`, (5)).
* :func:`flat_pair_facet_normals`: the FWS's face choices of two stance legs in their
  hyperplane (r = 5), the patterns (2, 2) and (3, 1), each normal a generalised cross product
  in R^5 (:mod:`awp_ros.geometry.minkowski_facets`, (6)).

Each is measured beside its numpy code, interleaved in one process, by ``awp_bench
--kernels`` (the README's speed section has the figures).

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
from awp_ros.geometry.linalg import cross3, GRAM_CERTIFY, workspace

try:  # numba is a dependency; without it (or AWP_ROS_KERNELS=numpy) the numpy code runs
    import numba
except ImportError:  # pragma: no cover - exercised only on installs without numba
    numba = None

__all__ = [
    'ENABLED', 'MAX_BITS', 'batched_vertices', 'certified_solid_faces',
    'cone_double_description', 'cone_facets', 'cone_recheck', 'cross_products', 'cycle_regions',
    'cycle_sets', 'directional_margins_lp', 'directional_margins_of_points',
    'first_of_equal_rows', 'flat_cone_facets', 'flat_pair_facet_normals', 'feasible_region',
    'flat_zonotope_facets',
    'leg_vertices', 'lifted_rays', 'lifted_zonotope', 'pair_basis', 'parallelepipeds',
    'polar_hull',
    'polygon_region', 'projected_polygon', 'ratio_test', 'segment_slice', 'solid_faces',
    'slice_facet_normals',
    'slice_facet_normal_parts', 'slack_min',
    'sparse_wedge_table', 'survivor_normals', 'two_leg_contains', 'wedge_tables', 'wrench_slice',
    'zonotope_facets']

#: Whether the compiled kernels are used (numba importable and not disabled).
ENABLED = numba is not None and os.environ.get('AWP_ROS_KERNELS', '') != 'numpy'
#: Largest number of generators / rays of the incidence bit masks.
MAX_BITS = 63
_COMPILED = False


def _jit(function=None, *, inline: bool = False, fastmath: bool = False):
    """
    Compile ``function`` with numba (no Python objects, cached on disk), if available.

    ``inline``: a helper inlined into its callers at numba's IR level (LLVM then sees the
    whole loop: 2-3x faster here than a call per candidate). ``fastmath``: LLVM may
    reassociate and contract sums (it then vectorises the loops of min / max over arrays);
    infinities and NaN keep their meaning.
    """
    if function is None:
        return lambda f: _jit(f, inline=inline, fastmath=fastmath)
    if numba is None:
        return function
    return numba.njit(cache=True, nogil=True, inline='always' if inline else 'never',
                      fastmath=_FASTMATH if fastmath else False)(function)


# LLVM's fast-math flags without 'nnan' and 'ninf': the slot tests below rely on -inf.
_FASTMATH = {'contract', 'reassoc', 'nsz', 'arcp'}


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


@_jit(inline=True)
def _wedge6(W, V, j, k):
    """
    Level ``k`` of :func:`wedge_tables` (6), unrolled: ``W[k] = W[k - 1] ^ V[:, j]``.

    Each line is ``sum_t sign[k, o, t] W[k - 1, src[k, o, t]] V[row[k, o, t], j]`` in the
    tables' term order (the same sums as a loop over the tables, without their lookups);
    ``test_unrolled_wedges_are_the_tables`` regenerates these lines from the tables.
    """
    if k == 1:
        v0, v1, v2, v3, v4, v5 = V[0, j], V[1, j], V[2, j], V[3, j], V[4, j], V[5, j]
        W[1, 0] = -W[0, 1] * v0 + W[0, 0] * v1
        W[1, 1] = -W[0, 2] * v0 + W[0, 0] * v2
        W[1, 2] = -W[0, 3] * v0 + W[0, 0] * v3
        W[1, 3] = -W[0, 4] * v0 + W[0, 0] * v4
        W[1, 4] = -W[0, 5] * v0 + W[0, 0] * v5
        W[1, 5] = -W[0, 2] * v1 + W[0, 1] * v2
        W[1, 6] = -W[0, 3] * v1 + W[0, 1] * v3
        W[1, 7] = -W[0, 4] * v1 + W[0, 1] * v4
        W[1, 8] = -W[0, 5] * v1 + W[0, 1] * v5
        W[1, 9] = -W[0, 3] * v2 + W[0, 2] * v3
        W[1, 10] = -W[0, 4] * v2 + W[0, 2] * v4
        W[1, 11] = -W[0, 5] * v2 + W[0, 2] * v5
        W[1, 12] = -W[0, 4] * v3 + W[0, 3] * v4
        W[1, 13] = -W[0, 5] * v3 + W[0, 3] * v5
        W[1, 14] = -W[0, 5] * v4 + W[0, 4] * v5
    elif k == 2:
        v0, v1, v2, v3, v4, v5 = V[0, j], V[1, j], V[2, j], V[3, j], V[4, j], V[5, j]
        W[2, 0] = W[1, 5] * v0 - W[1, 1] * v1 + W[1, 0] * v2
        W[2, 1] = W[1, 6] * v0 - W[1, 2] * v1 + W[1, 0] * v3
        W[2, 2] = W[1, 7] * v0 - W[1, 3] * v1 + W[1, 0] * v4
        W[2, 3] = W[1, 8] * v0 - W[1, 4] * v1 + W[1, 0] * v5
        W[2, 4] = W[1, 9] * v0 - W[1, 2] * v2 + W[1, 1] * v3
        W[2, 5] = W[1, 10] * v0 - W[1, 3] * v2 + W[1, 1] * v4
        W[2, 6] = W[1, 11] * v0 - W[1, 4] * v2 + W[1, 1] * v5
        W[2, 7] = W[1, 12] * v0 - W[1, 3] * v3 + W[1, 2] * v4
        W[2, 8] = W[1, 13] * v0 - W[1, 4] * v3 + W[1, 2] * v5
        W[2, 9] = W[1, 14] * v0 - W[1, 4] * v4 + W[1, 3] * v5
        W[2, 10] = W[1, 9] * v1 - W[1, 6] * v2 + W[1, 5] * v3
        W[2, 11] = W[1, 10] * v1 - W[1, 7] * v2 + W[1, 5] * v4
        W[2, 12] = W[1, 11] * v1 - W[1, 8] * v2 + W[1, 5] * v5
        W[2, 13] = W[1, 12] * v1 - W[1, 7] * v3 + W[1, 6] * v4
        W[2, 14] = W[1, 13] * v1 - W[1, 8] * v3 + W[1, 6] * v5
        W[2, 15] = W[1, 14] * v1 - W[1, 8] * v4 + W[1, 7] * v5
        W[2, 16] = W[1, 12] * v2 - W[1, 10] * v3 + W[1, 9] * v4
        W[2, 17] = W[1, 13] * v2 - W[1, 11] * v3 + W[1, 9] * v5
        W[2, 18] = W[1, 14] * v2 - W[1, 11] * v4 + W[1, 10] * v5
        W[2, 19] = W[1, 14] * v3 - W[1, 13] * v4 + W[1, 12] * v5
    elif k == 3:
        v0, v1, v2, v3, v4, v5 = V[0, j], V[1, j], V[2, j], V[3, j], V[4, j], V[5, j]
        W[3, 0] = -W[2, 10] * v0 + W[2, 4] * v1 - W[2, 1] * v2 + W[2, 0] * v3
        W[3, 1] = -W[2, 11] * v0 + W[2, 5] * v1 - W[2, 2] * v2 + W[2, 0] * v4
        W[3, 2] = -W[2, 12] * v0 + W[2, 6] * v1 - W[2, 3] * v2 + W[2, 0] * v5
        W[3, 3] = -W[2, 13] * v0 + W[2, 7] * v1 - W[2, 2] * v3 + W[2, 1] * v4
        W[3, 4] = -W[2, 14] * v0 + W[2, 8] * v1 - W[2, 3] * v3 + W[2, 1] * v5
        W[3, 5] = -W[2, 15] * v0 + W[2, 9] * v1 - W[2, 3] * v4 + W[2, 2] * v5
        W[3, 6] = -W[2, 16] * v0 + W[2, 7] * v2 - W[2, 5] * v3 + W[2, 4] * v4
        W[3, 7] = -W[2, 17] * v0 + W[2, 8] * v2 - W[2, 6] * v3 + W[2, 4] * v5
        W[3, 8] = -W[2, 18] * v0 + W[2, 9] * v2 - W[2, 6] * v4 + W[2, 5] * v5
        W[3, 9] = -W[2, 19] * v0 + W[2, 9] * v3 - W[2, 8] * v4 + W[2, 7] * v5
        W[3, 10] = -W[2, 16] * v1 + W[2, 13] * v2 - W[2, 11] * v3 + W[2, 10] * v4
        W[3, 11] = -W[2, 17] * v1 + W[2, 14] * v2 - W[2, 12] * v3 + W[2, 10] * v5
        W[3, 12] = -W[2, 18] * v1 + W[2, 15] * v2 - W[2, 12] * v4 + W[2, 11] * v5
        W[3, 13] = -W[2, 19] * v1 + W[2, 15] * v3 - W[2, 14] * v4 + W[2, 13] * v5
        W[3, 14] = -W[2, 19] * v2 + W[2, 18] * v3 - W[2, 17] * v4 + W[2, 16] * v5
    elif k == 4:
        v0, v1, v2, v3, v4, v5 = V[0, j], V[1, j], V[2, j], V[3, j], V[4, j], V[5, j]
        W[4, 0] = W[3, 10] * v0 - W[3, 6] * v1 + W[3, 3] * v2 - W[3, 1] * v3 + W[3, 0] * v4
        W[4, 1] = W[3, 11] * v0 - W[3, 7] * v1 + W[3, 4] * v2 - W[3, 2] * v3 + W[3, 0] * v5
        W[4, 2] = W[3, 12] * v0 - W[3, 8] * v1 + W[3, 5] * v2 - W[3, 2] * v4 + W[3, 1] * v5
        W[4, 3] = W[3, 13] * v0 - W[3, 9] * v1 + W[3, 5] * v3 - W[3, 4] * v4 + W[3, 3] * v5
        W[4, 4] = W[3, 14] * v0 - W[3, 9] * v2 + W[3, 8] * v3 - W[3, 7] * v4 + W[3, 6] * v5
        W[4, 5] = W[3, 14] * v1 - W[3, 13] * v2 + W[3, 12] * v3 - W[3, 11] * v4 + W[3, 10] * v5


@_jit(inline=True)
def _subset_normal6(V, subsets, s, prev, W, out):
    """:func:`_subset_normal_any` in R^6, its wedge levels unrolled (:func:`_wedge6`)."""
    start = 0
    while start < 5 and subsets[s, start] == prev[start]:
        start += 1
    for k in range(start, 5):
        j = subsets[s, k]
        prev[k] = j
        if k == 0:
            for i in range(6):
                W[0, i] = V[i, j]
        else:
            _wedge6(W, V, j, k)
        if k == 4:
            for i in range(6):           # n_i = (-1)^i W_{[6] \ {i}}, that subset 5 - i
                out[i] = W[4, 5 - i] if i % 2 == 0 else -W[4, 5 - i]


@_jit(inline=True)
def _scratch(r):
    """Return the prefix minors (r - 1, 20), the last subset (r - 1,) and a normal (r,)."""
    return np.empty((r - 1, 20)), np.full(r - 1, -1, dtype=np.int64), np.empty(r)


@_jit
def _cross_products(V, subsets):
    m = subsets.shape[0]
    out = np.empty((m, 6))
    W, prev, _ = _scratch(6)
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
def _row_buffers(n_sub, r):
    """Return per-candidate buffers: rows (n_sub, r), incidence masks, multi flags."""
    return (np.empty((n_sub, r)), np.empty(n_sub, dtype=np.int64),
            np.zeros(n_sub, dtype=np.bool_))


@_jit(inline=True)
def _zonotope_row(h, masks, multi, kept, total, mask, extra):
    """Store row ``kept``'s support, incidence mask and multi flag; return the next row."""
    h[kept] = total
    masks[kept] = mask
    multi[kept] = extra
    return kept + 1


@_jit(inline=True)
def _facet_rows6(g, norms, subsets, others, rank_tol, incidence_tol, out, h, masks, multi):
    """
    Store eqs. (1)-(3) of every 5-subset of the generators ``g`` (6, m) in row buffers.

    Row ``kept`` of ``out`` gets the unit normal, ``h`` its support, ``masks`` its incidence,
    ``multi`` whether more than the subset is incident; returns the number of rows stored.
    ``others[s]`` lists the generators not in subset ``s``: the subset's own are on the facet
    (``|a . g_j|`` is rounding), so the mask starts with them and only the others count.
    """
    r, m = g.shape
    n_sub = subsets.shape[0]
    U = g / norms                                    # unit generators (columns)
    limit = incidence_tol * norms
    W, prev, n = _scratch(r)
    d = np.empty(m)
    kept = 0
    for s in range(n_sub):
        _subset_normal6(U, subsets, s, prev, W, n)           # eq. (1)
        n0, n1, n2, n3, n4, n5 = n[0], n[1], n[2], n[3], n[4], n[5]
        vol = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2 + n3 * n3 + n4 * n4 + n5 * n5)
        if not vol > rank_tol:
            continue
        inv = 1.0 / vol
        n0, n1, n2, n3, n4, n5 = n0 * inv, n1 * inv, n2 * inv, n3 * inv, n4 * inv, n5 * inv
        # |a . g_j| for every generator at once (a loop LLVM vectorises), then the others'
        # in increasing j from the table (no branch on the mask per generator).
        for j in range(m):
            d[j] = abs(n0 * g[0, j] + n1 * g[1, j] + n2 * g[2, j] + n3 * g[3, j]
                       + n4 * g[4, j] + n5 * g[5, j])
        mask = 0
        for t in range(r - 1):
            mask |= np.int64(1) << subsets[s, t]
        total = 0.0
        count = r - 1
        for t in range(others.shape[1]):                  # eqs. (2), (3)
            j = others[s, t]
            total += d[j]
            if d[j] <= limit[j]:
                mask |= np.int64(1) << j
                count += 1
        out[kept, 0], out[kept, 1], out[kept, 2] = n0, n1, n2
        out[kept, 3], out[kept, 4], out[kept, 5] = n3, n4, n5
        kept = _zonotope_row(h, masks, multi, kept, total, mask, count > r - 1)
    return kept


@_jit
def _zonotope_facets(g, norms, subsets, others, rank_tol, incidence_tol):
    n_sub = subsets.shape[0]
    a, masks, multi = _row_buffers(n_sub, 6)
    h = np.empty(n_sub)
    kept = _facet_rows6(g, norms, subsets, others, rank_tol, incidence_tol, a, h, masks, multi)
    keep = _first_of_each(masks[:kept], multi[:kept])
    return a[keep], h[keep]


@_jit(inline=True)
def _full_rank(gram, certify):
    """
    Return whether a Gram matrix (n, n) certifies full rank as ``orthonormal_span`` does.

    ``det(gram) / tr(gram)^n > certify``, the determinant from the Cholesky factor's
    diagonal (False when the factorisation breaks down).
    """
    n = gram.shape[0]
    trace = 0.0
    for i in range(n):
        trace += gram[i, i]
    if not trace > 0.0:
        return False
    L = np.zeros((n, n))
    ratio = 1.0
    for i in range(n):
        for j in range(i + 1):
            acc = gram[i, j]
            for t in range(j):
                acc -= L[i, t] * L[j, t]
            if i == j:
                if not acc > 0.0:
                    return False
                L[i, i] = np.sqrt(acc)
                ratio *= acc / trace
            else:
                L[i, j] = acc / L[j, j]
    return ratio > certify


@_jit(inline=True)
def _lifted_generators(P, C, H):
    """Return ``G`` (6, 3K), ``c`` (6,) and the columns' norms: ``L_k H_k``, ``sum_k L_k c_k``."""
    K = P.shape[0]
    m = 3 * K
    G = np.empty((6, m))
    c = np.zeros(6)
    for k in range(K):                       # L_k = [I; [p_k]x]: the centre, the generators
        px, py, pz = P[k, 0], P[k, 1], P[k, 2]
        fx, fy, fz = C[k, 0], C[k, 1], C[k, 2]
        c[0] += fx
        c[1] += fy
        c[2] += fz
        c[3] += py * fz - pz * fy
        c[4] += pz * fx - px * fz
        c[5] += px * fy - py * fx
        for j in range(3):
            gx, gy, gz = H[k, 0, j], H[k, 1, j], H[k, 2, j]
            col = 3 * k + j
            G[0, col], G[1, col], G[2, col] = gx, gy, gz
            G[3, col] = py * gz - pz * gy
            G[4, col] = pz * gx - px * gz
            G[5, col] = px * gy - py * gx
    norms = np.empty(m)
    for j in range(m):
        acc = 0.0
        for i in range(6):
            acc += G[i, j] * G[i, j]
        norms[j] = np.sqrt(acc)
    return G, c, norms


@_jit(inline=True)
def _short_generator(norms, zero_tol):
    """Return whether a generator is at most ``zero_tol`` times the longest (the general code)."""
    top = 0.0
    for j in range(norms.shape[0]):
        top = max(top, norms[j])
    for j in range(norms.shape[0]):
        if not norms[j] > zero_tol * top:
            return True
    return False


@_jit(inline=True)
def _zonotope_rows(A1, h, c):
    """Return the rows ``[A1; -A1]`` and ``b = [A1 c + h; h - A1 c]`` (the reference's order)."""
    k = A1.shape[0]
    A = np.empty((2 * k, 6))
    b = np.empty(2 * k)
    for s in range(k):
        ac = 0.0
        for i in range(6):
            A[s, i] = A1[s, i]
            A[k + s, i] = -A1[s, i]
            ac += A1[s, i] * c[i]
        b[s] = ac + h[s]
        b[k + s] = h[s] - ac
    return A, b


@_jit
def _lifted_zonotope(P, C, H, subsets, others, zero_tol, certify, rank_tol, incidence_tol,
                     extra):
    G, c, norms = _lifted_generators(P, C, H)
    if _short_generator(norms, zero_tol) or not _full_rank(G @ G.T, certify):
        return np.empty((0, 6)), np.empty(0), c, False
    # The rows [a; -a] built in one buffer: the facets' normals first, compacted in place
    # to the kept ones (keep[t] >= t), then their negatives (the reference's order), then
    # the ``extra`` rows with b = 0 (the CWC's, for the FWP: one buffer, no copy of the
    # AWP's rows; the AWP is its first 2k rows).
    n_sub, m2 = subsets.shape[0], extra.shape[0]
    A, masks, multi = _row_buffers(2 * n_sub + m2, 6)
    h = np.empty(n_sub)
    kept = _facet_rows6(G, norms, subsets, others, rank_tol, incidence_tol, A, h, masks, multi)
    keep = _first_of_each(masks[:kept], multi[:kept])
    k = keep.size
    b = np.zeros(2 * k + m2)
    for t in range(k):
        s = keep[t]
        ac = 0.0
        for i in range(6):
            A[t, i] = A[s, i]
            ac += A[t, i] * c[i]
        b[t] = ac + h[s]
        b[k + t] = h[s] - ac
    for t in range(k):
        for i in range(6):
            A[k + t, i] = -A[t, i]
    for t in range(m2):
        for i in range(6):
            A[2 * k + t, i] = extra[t, i]
    return A[:2 * k + m2], b, c, True


@_jit(inline=True)
def _pair_normal(P):
    """Return ``(p_1 x p_2, p_2 - p_1)``, the normal of two feet's wrenches (not unit)."""
    x1, y1, z1, x2, y2, z2 = P[0, 0], P[0, 1], P[0, 2], P[1, 0], P[1, 1], P[1, 2]
    return np.array((y1 * z2 - z1 * y2, z1 * x2 - x1 * z2, x1 * y2 - y1 * x2,
                     x2 - x1, y2 - y1, z2 - z1))


@_jit(inline=True)
def _pair_hyperplane(P):
    r"""
    Return the unit normal ``n`` of the hyperplane of two feet's wrenches and a basis of it.

    ``L_1 f_1 + L_2 f_2`` spans ``n^\perp``, ``n = (p_1 x p_2, p_2 - p_1) / |.|`` (a force
    along the line through both feet is the same wrench from either); the basis ``U`` (6, 5)
    is the Householder reflection of ``n`` onto a coordinate axis without that axis's column.
    ``n = 0`` (coincident feet) gives ``U`` of zeros, which the caller's certificate refuses.
    """
    n = _pair_normal(P)
    U = np.zeros((6, 5))
    norm = np.sqrt(_norm2(n))
    if not norm > 0.0:
        return n, U
    n /= norm
    j = 0
    for i in range(6):
        if abs(n[i]) > abs(n[j]):
            j = i
    v = n.copy()
    v[j] += 1.0 if n[j] >= 0.0 else -1.0
    scale = 2.0 / _norm2(v)
    col = 0
    for t in range(6):                       # columns e_t - scale v v_t of the reflection
        if t == j:
            continue
        for i in range(6):
            U[i, col] = (1.0 if i == t else 0.0) - scale * v[i] * v[t]
        col += 1
    return n, U


@_jit
def _pair_hyperplane_of(P):
    return _pair_hyperplane(P)


def pair_hyperplane(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(n, U)`` of two feet ``positions`` (2, 3) [m] (see :func:`_pair_hyperplane`)."""
    return _pair_hyperplane_of(np.ascontiguousarray(positions, dtype=float))


@_jit
def _pair_basis(P, R, span_tol, certify):
    n, U = _pair_hyperplane(P)
    N = R.shape[0]
    along = 0.0
    for i in range(N):
        a = 0.0
        for t in range(6):
            a += R[i, t] * n[t]
        along += a * a
    if not along <= span_tol * span_tol:
        return n, U, 1
    G = np.zeros((5, 5))                     # the Gram matrix of the rays in hull coordinates
    h = np.empty(5)
    for i in range(N):
        for c in range(5):
            acc = 0.0
            for t in range(6):
                acc += R[i, t] * U[t, c]
            h[c] = acc
        for c in range(5):
            for d in range(5):
                G[c, d] += h[c] * h[d]
    return n, U, 0 if _full_rank(G, certify) else 2


def pair_basis(positions: np.ndarray, rays: np.ndarray, span_tol: float,
               certify: float) -> tuple[np.ndarray, np.ndarray, int]:
    r"""
    Return ``(n, U, status)``: two feet's wrench hyperplane when it spans their lifted rays.

    :func:`pair_hyperplane` of the feet ``positions`` (2, 3) [m], then the unit lifted
    ``rays`` (N, 6): status 1 when their components along ``n`` (rounding) exceed
    ``span_tol`` (``sum (r_i . n)^2 > span_tol^2``), 2 when the rays in hull coordinates
    ``R U`` are not certified of rank 5 by the Gram test of
    :func:`awp_ros.geometry.linalg.orthonormal_span` (``det G / tr(G)^5 > certify``; the
    caller's SVD then decides), else 0.
    """
    return _pair_basis(np.ascontiguousarray(positions, dtype=float),
                       np.ascontiguousarray(rays, dtype=float), float(span_tol),
                       float(certify))


@_jit
def _lifted_zonotope_pair(P, C, H, subsets, src, row, sign, size, zero_tol, certify,
                          span_tol, rank_tol, incidence_tol):
    G, c, norms = _lifted_generators(P, C, H)
    n, U = _pair_hyperplane(P)
    if _short_generator(norms, zero_tol):
        return np.empty((0, 6)), np.empty(0), c, n, U, False
    top = 0.0
    residual = 0.0
    for j in range(6):
        top = max(top, norms[j])
        dot = 0.0
        for i in range(6):
            dot += n[i] * G[i, j]
        residual += dot * dot
    g = U.T @ G                                  # (5, 6) hull coordinates
    if not np.sqrt(residual) <= span_tol * top or not _full_rank(g @ g.T, certify):
        return np.empty((0, 6)), np.empty(0), c, n, U, False
    a, h = _flat_zonotope_facets(g, norms, subsets, src, row, sign, size, rank_tol,
                                 incidence_tol)
    A, b = _zonotope_rows(a @ U.T, h, c)
    return A, b, c, n, U, True


def lifted_zonotope(positions: np.ndarray, centers: np.ndarray, generators: np.ndarray,
                    subsets: np.ndarray, zero_tol: float, certify: float, rank_tol: float,
                    incidence_tol: float, *, others: np.ndarray | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    r"""
    Return the AWP of K >= 3 parallelepiped legs, ``(A, b, c)``, in one compiled call.

    (Two legs: :func:`lifted_zonotope_pair`.)

    :func:`awp_ros.wrench.wrench_polytope.actuation_wrench_polytope` and
    :func:`awp_ros.geometry.zonotope.zonotope` fused for the full-dimensional case: the lifted
    centre ``c = sum_k L_k c_k`` and generators ``L_k H_k``, the full rank certified as
    :func:`awp_ros.geometry.linalg.orthonormal_span` does (``det(G G^T) / tr^6 >
    certify``, from a Cholesky factor), :func:`zonotope_facets`, and the rows ``[a; -a]``,
    ``b = [a . c + h; h - a . c]`` in the reference's order.

    :param others: :func:`subset_complements` of ``subsets`` (computed when None; the hot
        caller passes a cached table).
    :return: ``(A, b, c)``, or None when a generator is shorter than ``zero_tol`` times the
        longest or the certificate fails (the caller takes the general code).
    """
    S = np.ascontiguousarray(subsets, dtype=np.int64)
    A, b, c, ok = _lifted_zonotope(np.ascontiguousarray(positions, dtype=float),
                                   np.ascontiguousarray(centers, dtype=float),
                                   np.ascontiguousarray(generators, dtype=float), S,
                                   _complements(S, 3 * len(positions), others),
                                   float(zero_tol), float(certify), float(rank_tol),
                                   float(incidence_tol), np.empty((0, 6)))
    return (A, b, c) if ok else None


def lifted_zonotope_pair(positions: np.ndarray, centers: np.ndarray, generators: np.ndarray,
                         subsets: np.ndarray, zero_tol: float, certify: float, span_tol: float,
                         rank_tol: float, incidence_tol: float
                         ) -> tuple[np.ndarray, ...] | None:
    r"""
    Return the AWP of two parallelepiped legs, ``(A, b, c, n, U)``, in one compiled call.

    :func:`lifted_zonotope` for K = 2, whose sum is flat: it spans the hyperplane
    ``n^\perp``, ``n = (p_1 x p_2, p_2 - p_1)``, with the basis ``U`` (6, 5) taken from ``n``
    in closed form instead of an SVD. The rank is decided as
    :func:`awp_ros.geometry.linalg.orthonormal_span` would: the generators' component along
    ``n`` (rounding) at most ``span_tol`` times the longest, and ``det(g g^T) / tr^5 >
    certify`` for the hull coordinates ``g = U^T G``; then :func:`flat_zonotope_facets` over
    ``subsets`` (the lexicographic 4-subsets of the 6 generators) and the rows
    ``[a U^T; -a U^T]``, ``b = [A_1 c + h; h - A_1 c]``.

    :return: ``(A, b, c, n, U)`` (``n`` the hull's unit normal), or None when a generator is
        short or the rank is not certified (the caller takes the general code).
    """
    src, row, sign, size = wedge_tables(5)
    A, b, c, n, U, ok = _lifted_zonotope_pair(
        np.ascontiguousarray(positions, dtype=float), np.ascontiguousarray(centers, dtype=float),
        np.ascontiguousarray(generators, dtype=float),
        np.ascontiguousarray(subsets, dtype=np.int64), src, row, sign, size, float(zero_tol),
        float(certify), float(span_tol), float(rank_tol), float(incidence_tol))
    return (A, b, c, n, U) if ok else None


@_jit(inline=True)
def _subset_normal_any(V, subsets, s, prev, W, out, src, row, sign, size):
    """:func:`_subset_normal6` in R^d, d = ``V.shape[0]``, with the tables passed in."""
    d = V.shape[0]
    start = 0
    while start < d - 1 and subsets[s, start] == prev[start]:
        start += 1
    for k in range(start, d - 1):
        j = subsets[s, k]
        prev[k] = j
        if k == 0:
            for i in range(d):
                W[0, i] = V[i, j]
        else:
            for o in range(size[k + 1]):
                acc = 0.0
                for t in range(k + 1):
                    acc += sign[k, o, t] * W[k - 1, src[k, o, t]] * V[row[k, o, t], j]
                W[k, o] = acc
    for i in range(d):                   # n_i = (-1)^i W_{[d] \ {i}}, that subset d - 1 - i
        out[i] = W[d - 2, d - 1 - i] if i % 2 == 0 else -W[d - 2, d - 1 - i]


@_jit
def _flat_zonotope_facets(g, norms, subsets, src, row, sign, size, rank_tol, incidence_tol):
    r, m = g.shape
    n_sub = subsets.shape[0]
    a, masks, multi = _row_buffers(n_sub, r)
    h = np.empty(n_sub)
    U = g / norms                                    # unit generators (columns)
    W, prev, n = _scratch(r)
    kept = 0
    for s in range(n_sub):
        _subset_normal_any(U, subsets, s, prev, W, n, src, row, sign, size)
        vol = np.sqrt(_norm2(n))
        if not vol > rank_tol:
            continue
        total = 0.0
        mask = 0
        count = 0
        for j in range(m):
            dot = 0.0
            for i in range(r):
                dot += n[i] * g[i, j]
            dot = abs(dot) / vol
            total += dot
            if dot <= incidence_tol * norms[j]:
                mask |= np.int64(1) << j
                count += 1
        for i in range(r):
            a[kept, i] = n[i] / vol
        kept = _zonotope_row(h, masks, multi, kept, total, mask, count > r - 1)
    keep = _first_of_each(masks[:kept], multi[:kept])
    return a[keep], h[keep]


def flat_zonotope_facets(g: np.ndarray, norms: np.ndarray, subsets: np.ndarray,
                         rank_tol: float, incidence_tol: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Return :func:`zonotope_facets` of a zonotope of R^r, 3 <= r <= 5 (hull coordinates).

    The flat AWP of two stance legs (r = 5) and the like: the same equations and rows with
    the wedge tables of R^r passed at run time (few subsets: the call overhead counts).
    """
    r = g.shape[0]
    src, row, sign, size = wedge_tables(r)
    return _flat_zonotope_facets(np.ascontiguousarray(g, dtype=float),
                                 np.ascontiguousarray(norms, dtype=float),
                                 np.ascontiguousarray(subsets, dtype=np.int64), src, row, sign,
                                 size, float(rank_tol), float(incidence_tol))


@_jit
def _flat_cone_facets(R, subsets, src, row, sign, size, side_tol, rank_tol):
    N, r = R.shape
    n_sub = subsets.shape[0]
    V = np.ascontiguousarray(R.T)
    A, masks, multi = _row_buffers(n_sub, r)
    rows = np.empty(n_sub, dtype=np.int64)
    W, prev, n = _scratch(r)
    dots = np.empty(N)
    kept = 0
    for s in range(n_sub):
        _subset_normal_any(V, subsets, s, prev, W, n, src, row, sign, size)
        vol = np.sqrt(_norm2(n))
        if not vol > rank_tol:
            continue
        slack = side_tol * vol
        top, low = -np.inf, np.inf
        for j in range(N):
            acc = 0.0
            for i in range(r):
                acc += n[i] * R[j, i]
            dots[j] = acc
            top = max(top, acc)
            low = min(low, acc)
        if top > slack and low < -slack:
            continue
        scale = (-1.0 if top > slack else 1.0) / vol
        mask = 0
        count = 0
        for j in range(N):
            if abs(dots[j]) <= slack:
                mask |= np.int64(1) << j
                count += 1
        for i in range(r):
            A[kept, i] = n[i] * scale
        masks[kept] = mask
        multi[kept] = count > r - 1
        rows[kept] = s
        kept += 1
    keep = _first_of_each(masks[:kept], multi[:kept])
    return A[:kept][keep]


def flat_cone_facets(rays: np.ndarray, subsets: np.ndarray, side_tol: float,
                     rank_tol: float) -> np.ndarray:
    """
    Return :func:`cone_facets`' normals for unit rays of R^r, 3 <= r <= 5 (hull coordinates).

    The flat contact wrench cone of two stance legs (r = 5): the same equations and rows,
    the wedge tables of R^r passed at run time.
    """
    R = np.ascontiguousarray(rays, dtype=float)
    src, row, sign, size = wedge_tables(R.shape[1])
    return _flat_cone_facets(R, np.ascontiguousarray(subsets, dtype=np.int64), src, row, sign,
                             size, float(side_tol), float(rank_tol))


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
                    incidence_tol: float, *, others: np.ndarray | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    r"""
    Return the unit facet normals ``a`` (k, 6) and ``h(a) = sum_j |a . g_j|`` (k,).

    For a zonotope with generators ``g`` ``(6, m)`` (full-dimensional, ``norms`` their
    lengths), over ``subsets`` (the lexicographic 5-subsets): the cross
    product of each subset's unit-scaled generators, dropped when its length (the volume)
    is at most ``rank_tol``; one row per incidence set ``{j : |a . g_j| <= incidence_tol
    |g_j|}``, the first in subset order. The same rows, in the same order, as
    :func:`awp_ros.geometry.zonotope.zonotope`'s numpy code (both signs: ``a`` and ``-a``
    are the caller's). ``others``: :func:`subset_complements` of ``subsets`` (computed when
    None).
    """
    g = np.ascontiguousarray(g, dtype=float)
    S = np.ascontiguousarray(subsets, dtype=np.int64)
    return _zonotope_facets(g, np.ascontiguousarray(norms, dtype=float), S,
                            _complements(S, g.shape[1], others), float(rank_tol),
                            float(incidence_tol))


def subset_complements(subsets: np.ndarray, m: int) -> np.ndarray:
    """
    Return, row by row, the increasing indices of ``range(m)`` not in ``subsets`` (n, k).

    As int8 (``m <= MAX_BITS``): the table is read every cycle, a small one stays in cache.
    """
    S = np.asarray(subsets, dtype=np.int64)
    member = np.zeros((S.shape[0], m), dtype=bool)
    member[np.arange(S.shape[0])[:, None], S] = True
    return np.nonzero(~member)[1].reshape(S.shape[0], m - S.shape[1]).astype(np.int8)


def _complements(S: np.ndarray, m: int, others: np.ndarray | None) -> np.ndarray:
    """Return ``others`` as the kernels take it, or :func:`subset_complements` of ``S``."""
    if others is None:
        return subset_complements(S, m)
    return np.ascontiguousarray(others, dtype=np.int8)


@_jit
def _cone_facets(R, subsets, side_tol, rank_tol):
    N, r = R.shape
    n_sub = subsets.shape[0]
    V = np.ascontiguousarray(R.T)
    # Every candidate's cross product, then every side value in one product: the early
    # exit of a side test per candidate mispredicts its branches (2.5x slower, measured).
    normals = _cross_products(V, subsets)
    sides = normals @ V                                  # (n_sub, N): a_s . ray_j
    A, masks, multi = _row_buffers(n_sub, r)
    rows = np.empty(n_sub, dtype=np.int64)
    kept = 0
    for s in range(n_sub):
        vol = np.sqrt(_norm2(normals[s]))
        if not vol > rank_tol:
            continue
        slack = side_tol * vol
        top, low = -np.inf, np.inf
        for j in range(N):
            top = max(top, sides[s, j])
            low = min(low, sides[s, j])
        if top > slack and low < -slack:
            continue                                     # rays on both sides: no facet
        scale = (-1.0 if top > slack else 1.0) / vol
        mask = 0
        count = 0
        for j in range(N):
            if abs(sides[s, j]) <= slack:
                mask |= np.int64(1) << j
                count += 1
        for i in range(r):
            A[kept, i] = normals[s, i] * scale
        masks[kept] = mask
        multi[kept] = count > r - 1
        rows[kept] = s
        kept += 1
    keep = _first_of_each(masks[:kept], multi[:kept])
    return A[:kept][keep], rows[:kept][keep], masks[:kept][keep]


@_jit
def _cone_recheck(R, spans, masks, side_tol, rank_tol):
    N, r = R.shape
    k = spans.shape[0]
    V = np.ascontiguousarray(R.T)
    A = np.empty((k, r))
    W, prev, n = _scratch(6)
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


@_jit
def _lifted_rays(P, rays, certify):
    K, N = rays.shape[0], rays.shape[1]
    R = np.empty((K * N, 6))
    for k in range(K):
        px, py, pz = P[k, 0], P[k, 1], P[k, 2]
        for i in range(N):
            x, y, z = rays[k, i, 0], rays[k, i, 1], rays[k, i, 2]
            row = k * N + i
            R[row, 0], R[row, 1], R[row, 2] = x, y, z
            R[row, 3] = py * z - pz * y
            R[row, 4] = pz * x - px * z
            R[row, 5] = px * y - py * x
            acc = 0.0
            for t in range(6):
                acc += R[row, t] * R[row, t]
            inv = 1.0 / np.sqrt(acc)
            for t in range(6):
                R[row, t] *= inv
    return R, _full_rank(R.T @ R, certify)


def lifted_rays(positions: np.ndarray, rays: np.ndarray,
                certify: float) -> tuple[np.ndarray, bool]:
    r"""
    Return the unit lifted rays ``L_k r / |L_k r|`` (K N, 6) and whether they span R^6.

    The lift of :mod:`awp_ros.wrench.contact_wrench_cone` eq. (3) (``[r; p_k x r]``,
    normalised) and the full-rank certificate of
    :func:`awp_ros.geometry.linalg.orthonormal_span` (``det(R^T R) / tr^6 > certify``) in
    one compiled call; False means "not certified" (the caller's SVD decides).

    :param positions: (K, 3) feet [m]; :param rays: (K, N, 3) pyramid rays (unit).
    """
    return _lifted_rays(np.ascontiguousarray(positions, dtype=float),
                        np.ascontiguousarray(rays, dtype=float), float(certify))


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


@_jit(inline=True)
def _popcount(x):
    """Return the number of set bits of a non-negative int64."""
    count = 0
    while x:
        x &= x - 1
        count += 1
    return count


@_jit(inline=True)
def _unit_rows(X, n, r):
    """Scale rows ``0 .. n - 1`` of ``X`` to unit length."""
    for i in range(n):
        acc = 0.0
        for t in range(r):
            acc += X[i, t] * X[i, t]
        inv = 1.0 / np.sqrt(acc)
        for t in range(r):
            X[i, t] *= inv


@_jit
def _cone_dd(R, side_tol, rank_tol, cap):
    N, r = R.shape
    V = np.ascontiguousarray(R.T)
    fail = (np.empty((0, r)), np.empty((0, r - 1), dtype=np.int64),
            np.empty(0, dtype=np.int64), False)
    # (1) r independent rays (Gram-Schmidt, in index order): their polar is simplicial.
    Q = np.zeros((r, r))
    basis = np.empty(r, dtype=np.int64)
    nb = 0
    v = np.empty(r)
    for j in range(N):
        for t in range(r):
            v[t] = R[j, t]
        for i in range(nb):
            d = 0.0
            for t in range(r):
                d += Q[i, t] * v[t]
            for t in range(r):
                v[t] -= d * Q[i, t]
        nv = np.sqrt(_norm2(v))
        if nv > 1e-6:
            for t in range(r):
                Q[nb, t] = v[t] / nv
            basis[nb] = j
            nb += 1
            if nb == r:
                break
    if nb < r:
        return fail
    X = np.empty((cap, r))
    Z = np.empty(cap, dtype=np.int64)
    X2 = np.empty((cap, r))
    Z2 = np.empty(cap, dtype=np.int64)
    s = np.empty(cap)
    pos = np.empty(cap, dtype=np.int64)
    neg = np.empty(cap, dtype=np.int64)
    W, prev, nrm = _scratch(6)
    sub = np.empty((1, r - 1), dtype=np.int64)
    done = np.int64(0)
    for i in range(r):
        done |= np.int64(1) << basis[i]
    # Ray i of the simplicial polar: normal to the other r - 1 basis rays, inside ray i.
    for i in range(r):
        c = 0
        for k in range(r):
            if k != i:
                sub[0, c] = basis[k]
                c += 1
        prev[:] = -1
        _subset_normal6(V, sub, 0, prev, W, nrm)
        sign = -1.0 if _dot(nrm, R, basis[i]) > 0.0 else 1.0
        for t in range(r):
            X[i, t] = sign * nrm[t]
        Z[i] = done & ~(np.int64(1) << basis[i])
    n = r
    _unit_rows(X, n, r)
    # (2) one ray at a time: keep the polar's rays on its side, join adjacent pairs across.
    for j in range(N):
        if (done >> j) & 1:
            continue
        bit = np.int64(1) << j
        m = 0
        n_pos = n_neg = 0
        for i in range(n):
            s[i] = _dot(X[i], R, j)
            if s[i] <= side_tol:
                for t in range(r):
                    X2[m, t] = X[i, t]
                Z2[m] = Z[i] | bit if s[i] >= -side_tol else Z[i]
                m += 1
            else:
                pos[n_pos] = i
                n_pos += 1
            if not s[i] >= -side_tol:
                neg[n_neg] = i
                n_neg += 1
        for ip in range(n_pos):                # the pairs across: (positive, negative)
            p = pos[ip]
            for iq in range(n_neg):
                q = neg[iq]
                common = Z[p] & Z[q]
                if _popcount(common) < r - 2:
                    continue
                adjacent = True
                for k in range(n):
                    if k != p and k != q and (Z[k] & common) == common:
                        adjacent = False
                        break
                if not adjacent:
                    continue
                if m >= cap:
                    return fail
                for t in range(r):
                    X2[m, t] = s[p] * X[q, t] - s[q] * X[p, t]
                Z2[m] = common | bit
                m += 1
        _unit_rows(X2, m, r)
        X, X2 = X2, X
        Z, Z2 = Z2, Z
        n = m
        done |= bit
    # (3) each extreme ray a facet: the rays on it and r - 1 independent ones among them
    # (its span: the rays on it in general position, else picked in index order).
    A = np.empty((n, r))
    spans = np.empty((n, r - 1), dtype=np.int64)
    masks = np.empty(n, dtype=np.int64)
    for i in range(n):
        mask = np.int64(0)
        for j in range(N):
            dot = _dot(X[i], R, j)
            if dot > side_tol:
                return fail
            if dot >= -side_tol:
                mask |= np.int64(1) << j
        nb = 0
        if _popcount(mask) == r - 1:
            for j in range(N):
                if (mask >> j) & 1:
                    spans[i, nb] = j
                    nb += 1
        else:
            for j in range(N):
                if nb == r - 1:
                    break
                if not (mask >> j) & 1:
                    continue
                for t in range(r):
                    v[t] = R[j, t]
                for k in range(nb):
                    d = 0.0
                    for t in range(r):
                        d += Q[k, t] * v[t]
                    for t in range(r):
                        v[t] -= d * Q[k, t]
                nv = np.sqrt(_norm2(v))
                if nv > 1e-6:
                    for t in range(r):
                        Q[nb, t] = v[t] / nv
                    spans[i, nb] = j
                    nb += 1
        if nb < r - 1:
            return fail
    # The normals as cone_facets computes them: the cross product of the span (exact to
    # rounding on its rays; the extreme rays carry the error of their combinations), the
    # side test and the mask of that normal.
    prev[:] = -1
    for i in range(n):
        _subset_normal6(V, spans, i, prev, W, nrm)
        vol = np.sqrt(_norm2(nrm))
        if not vol > rank_tol:
            return fail
        scale = (1.0 if _dot(nrm, X, i) > 0.0 else -1.0) / vol
        for t in range(r):
            A[i, t] = nrm[t] * scale
        mask = np.int64(0)
        for j in range(N):
            dot = _dot(A[i], R, j)
            if dot > side_tol:
                return fail
            if dot >= -side_tol:
                mask |= np.int64(1) << j
        masks[i] = mask
    keep = _first_of_each(masks, np.ones(n, dtype=np.bool_))
    return A[keep], spans[keep], masks[keep], True


def cone_double_description(rays: np.ndarray, side_tol: float, rank_tol: float,
                            cap: int = 1024
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    r"""
    Return :func:`cone_facets`' ``(A, spans, masks)`` by the double description method.

    The facets of ``C = cone{rays}`` (unit rows ``(N, 6)`` spanning R^6, ``C`` pointed) are
    the extreme rays of its polar ``C* = {a : rays a <= 0}``. Starting from ``r``
    independent rays, whose polar is simplicial (its extreme rays: the cross products of
    each ``r - 1`` of them), the rays are added one at a time: ``a . ray <= side_tol`` keeps
    an extreme ray of the polar, and each pair of adjacent extreme rays ``a_p``, ``a_q`` on
    both sides of the new hyperplane (``s_p > 0 > s_q``) gives the new one
    ``s_p a_q - s_q a_p`` on it (Motzkin et al. 1953; Fukuda & Prodon 1996). Adjacency is
    combinatorial: the rays both are on number at least ``r - 2`` and no third extreme ray
    is on all of them. The cost follows the output (a contact wrench cone of four legs has
    tens of facets: ~48 for HyQ's stance), where :func:`cone_facets` tests every candidate
    subset (2032 for four legs).

    Each extreme ray is then re-derived as :func:`cone_facets` derives a facet: ``r - 1``
    independent rays on it (within ``side_tol``; the rays on it in general position, else
    picked in index order) are its span, whose cross product (volume above ``rank_tol``)
    oriented outward is the unit normal ``a`` (exact to rounding on the span, where the
    extreme ray carries the error of its combinations), no ray beyond ``side_tol`` of it,
    the mask the rays within ``side_tol``; rows with the same mask are kept once. So the
    output is :func:`cone_facets`' for the same rays and tolerances, up to the order of the
    rows (the tests compare them). None (search the candidates instead) when the rays do not
    span R^6, a step fails its test, or the extreme rays outgrow ``cap``.
    """
    R = np.ascontiguousarray(rays, dtype=float)
    if R.ndim != 2 or R.shape[1] != 6 or R.shape[0] > MAX_BITS:
        return None
    A, spans, masks, ok = _cone_dd(R, float(side_tol), float(rank_tol), int(cap))
    return (A, spans, masks) if ok else None


@_jit(inline=True)
def _largest_gram_eigenvalue(a00, a01, a02, a10, a11, a12, a20, a21, a22):
    """
    Return the largest eigenvalue of ``A^T A`` (``sigma_max(A)^2``) of a 3x3 matrix.

    The trigonometric solution of the symmetric 3x3 eigenproblem (Smith 1961): accurate
    to rounding relative to itself whatever the other eigenvalues.
    """
    g00 = a00 * a00 + a10 * a10 + a20 * a20
    g11 = a01 * a01 + a11 * a11 + a21 * a21
    g22 = a02 * a02 + a12 * a12 + a22 * a22
    g01 = a00 * a01 + a10 * a11 + a20 * a21
    g02 = a00 * a02 + a10 * a12 + a20 * a22
    g12 = a01 * a02 + a11 * a12 + a21 * a22
    q = (g00 + g11 + g22) / 3.0
    p2 = ((g00 - q) ** 2 + (g11 - q) ** 2 + (g22 - q) ** 2
          + 2.0 * (g01 * g01 + g02 * g02 + g12 * g12))
    if not p2 > 0.0:
        return q                        # G = q I
    p = np.sqrt(p2 / 6.0)
    b00, b11, b22 = (g00 - q) / p, (g11 - q) / p, (g22 - q) / p
    b01, b02, b12 = g01 / p, g02 / p, g12 / p
    half_det = 0.5 * (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02)
                      + b02 * (b01 * b12 - b11 * b02))
    return q + 2.0 * p * np.cos(np.arccos(min(1.0, max(-1.0, half_det))) / 3.0)


@_jit(inline=True)
def _sigma_ratio3(M):
    r"""
    Return ``sigma_min / sigma_max`` of a 3x3 matrix ``M`` in closed form (no SVD call).

    .. math:: \frac{\sigma_3}{\sigma_1} = \frac{|\det M|}{\sigma_1(M)\, \sigma_1(\mathrm{cof} M)}

    since ``cof M = det(M) M^{-T}`` has the singular values ``sigma_i sigma_j`` (largest
    ``sigma_1 sigma_2``). The two largest singular values come from
    :func:`_largest_gram_eigenvalue`, ``det`` from the cofactors. Against LAPACK's SVD (a
    call per leg cost ~10 us a cycle for four legs; the tests compare them): relative error
    below 1e-8 for ratios above 1e-3 unless ``sigma_2 ~ sigma_3`` (up to 5e-6 there: the
    cofactors' rounding meets a double top eigenvalue), absolute error below 2e-9, and the
    same side of ``singular_rtol`` (1e-9) on 40000 matrices with ratios 1e-14 .. 1e-6.
    """
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
    big = _largest_gram_eigenvalue(M[0, 0], M[0, 1], M[0, 2], M[1, 0], M[1, 1], M[1, 2],
                                   M[2, 0], M[2, 1], M[2, 2])
    cof = _largest_gram_eigenvalue(c00, c01, c02, c10, c11, c12, c20, c21, c22)
    if not (big > 0.0 and cof > 0.0):
        return 0.0
    return min(1.0, abs(det) / np.sqrt(big * cof))


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
        M = J[k]
        ratio[k] = _sigma_ratio3(M)
        # J^-T by cofactors: (J^T)^-1 = adj(J^T) / det = cof(J) / det, cof(J)_ij = C_ij
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


_COLLINEAR = 1e-12  # relative cross product under which three points count as collinear


@_jit(inline=True)
def _extremes(v, i, high, at_high, low, at_low):
    """Return the largest and smallest value so far with their first indices, ``v`` at ``i``."""
    if v > high:
        high, at_high = v, i
    if v < low:
        low, at_low = v, i
    return high, at_high, low, at_low


@_jit
def _polar_hull(D, slack):
    m = D.shape[1]
    x, y = D[0], D[1]
    # Akl-Toussaint: the extreme points along 8 directions make an octagon (ccw); points
    # strictly inside it are not hull vertices. Directions k pi / 4: the largest and the
    # smallest x, x + y, y and y - x, found in one pass (the first index on ties).
    e0 = e1 = e2 = e3 = e4 = e5 = e6 = e7 = 0
    h0 = h1 = h2 = h3 = -np.inf
    l0 = l1 = l2 = l3 = np.inf
    for i in range(m):
        v0, v2 = x[i], y[i]
        h0, e0, l0, e4 = _extremes(v0, i, h0, e0, l0, e4)
        h1, e1, l1, e5 = _extremes(v0 + v2, i, h1, e1, l1, e5)
        h2, e2, l2, e6 = _extremes(v2, i, h2, e2, l2, e6)
        h3, e3, l3, e7 = _extremes(v2 - v0, i, h3, e3, l3, e7)
    ext = np.array((e0, e1, e2, e3, e4, e5, e6, e7))
    # The disc inscribed in the octagon about the origin (when inside it) is a cheaper
    # first test: dual points of far lines cluster about the origin.
    r2 = np.inf
    for k in range(8):
        p, q = ext[k], ext[(k + 1) % 8]
        ex, ey = x[q] - x[p], y[q] - y[p]
        ee = ex * ex + ey * ey
        if ee > 0.0:
            cross = ex * (0.0 - y[p]) - ey * (0.0 - x[p])
            r2 = min(r2, cross * abs(cross) / ee)
    r2 = r2 * (1.0 - 1e-9) if r2 > 0.0 else 0.0
    keep = np.empty(m, dtype=np.int64)
    n_keep = 0
    for i in range(m):
        if x[i] * x[i] + y[i] * y[i] < r2:
            continue
        inside = True
        for k in range(8):
            p, q = ext[k], ext[(k + 1) % 8]
            if p == q:
                continue
            ex, ey = x[q] - x[p], y[q] - y[p]
            cross = ex * (y[i] - y[p]) - ey * (x[i] - x[p])
            if cross <= slack * (abs(ex) + abs(ey)):
                inside = False
                break
        if not inside:
            keep[n_keep] = i
            n_keep += 1
    idx = keep[:n_keep]
    # Andrew's monotone chain on the rest (sorted by x, then y), strictly convex turns.
    order = idx[np.argsort(x[idx] + 0.0 * y[idx], kind='mergesort')]
    t = 1
    while t < order.size:                # ties in x: by y (insertion, runs are short)
        u = t
        while u > 0 and x[order[u]] == x[order[u - 1]] and y[order[u]] < y[order[u - 1]]:
            order[u], order[u - 1] = order[u - 1], order[u]
            u -= 1
        t += 1
    n = order.size
    hull = np.empty(2 * n + 1, dtype=np.int64)
    k = 0
    for pass_ in range(2):
        start = k
        for t in range(n):
            i = order[t] if pass_ == 0 else order[n - 1 - t]
            while k >= start + 2:
                a, b = hull[k - 2], hull[k - 1]
                ux, uy, vx, vy = x[b] - x[a], y[b] - y[a], x[i] - x[a], y[i] - y[a]
                cross = ux * vy - uy * vx
                if cross > _COLLINEAR * (abs(ux) + abs(uy)) * (abs(vx) + abs(vy)):
                    break
                k -= 1
            hull[k] = i
            k += 1
        k -= 1                            # the last point starts the other chain
    return hull[:max(k, 0)].copy()


def polar_hull(D: np.ndarray, slack: float = 0.0) -> np.ndarray:
    r"""
    Return the vertices of the convex hull of 2D points ``D`` (2, m), counter-clockwise.

    The dual points of a CoM region's lines (:mod:`awp_ros.wrench.com_region`, step 6).
    Points strictly inside the octagon of the extreme points along 8 directions (by more
    than ``slack`` times the edge's 1-norm) are dropped first (Akl-Toussaint), then
    Andrew's monotone chain keeps the strictly convex turns of the rest: points on a hull
    edge (a cross product within ``_COLLINEAR`` relative of 0) are not vertices. The
    reference is qhull (the tests).

    :return: integer indices into the columns of ``D``, ccw, starting at the point of
        smallest ``x`` (then ``y``); fewer than 3 for degenerate input.
    """
    return _polar_hull(np.ascontiguousarray(D, dtype=float), float(slack))


@_jit(inline=True)
def _signed_margin(V, b):
    """
    Return the signed distance [m] of 0 to the polygon ``V`` with unit edge offsets ``b``.

    ``min b`` inside, minus the distance to the nearest edge of the closed chain outside.
    """
    k = V.shape[0]
    inside = np.inf
    for i in range(k):
        inside = min(inside, b[i])
    if inside >= 0.0:
        return inside
    best = np.inf                        # outside: the distance of 0 to the edges
    for i in range(k):
        q = (i + 1) % k
        ex, ey = V[q, 0] - V[i, 0], V[q, 1] - V[i, 1]
        ee = ex * ex + ey * ey
        t = -(V[i, 0] * ex + V[i, 1] * ey) / ee if ee > 0.0 else 0.0
        t = min(1.0, max(0.0, t))
        qx, qy = V[i, 0] + t * ex, V[i, 1] + t * ey
        best = min(best, qx * qx + qy * qy)
    return -np.sqrt(best)


@_jit
def _polygon_region(N2, h, x0, tol, parallel):
    m = h.shape[0]
    D = np.empty((2, m))
    for i in range(m):
        s = h[i] - (N2[0, i] * x0[0] + N2[1, i] * x0[1])
        D[0, i] = N2[0, i] / s
        D[1, i] = N2[1, i] / s
    chain = _polar_hull(D, 0.0)
    k = chain.size
    A = np.empty((k, 2))
    b = np.empty(k)
    V = np.empty((k, 2))
    if k < 3:
        return chain, A, b, V, np.nan, False
    for j in range(k):                   # the primal vertices, relative to x0
        a, c = chain[j], chain[(j + 1) % k]
        det = D[0, a] * D[1, c] - D[1, a] * D[0, c]
        if not det > 0.0:
            return chain, A, b, V, np.nan, False
        V[j, 0] = (D[1, c] - D[1, a]) / det
        V[j, 1] = (D[0, a] - D[0, c]) / det
    for j in range(k):                   # unit rows and offsets about the current CoM
        ax, ay = N2[0, chain[j]], N2[1, chain[j]]
        nn = np.sqrt(ax * ax + ay * ay)
        A[j, 0], A[j, 1], b[j] = ax / nn, ay / nn, h[chain[j]] / nn
    shifted = True                       # V is relative to x0 until recomputed from A, b
    while True:
        # Edge i joins vertices i - 1 and i; a line touching the polygon at one vertex has
        # a zero-length edge and is dropped when its neighbours are not parallel.
        short = np.zeros(k, dtype=np.bool_)
        n_short = 0
        for i in range(k):
            ex, ey = V[i, 0] - V[i - 1, 0], V[i, 1] - V[i - 1, 1]
            if np.sqrt(ex * ex + ey * ey) <= tol:
                p, q = (i - 1) % k, (i + 1) % k
                if A[p, 0] * A[q, 1] - A[p, 1] * A[q, 0] > parallel:
                    short[i] = True
                    n_short += 1
        if k <= 3 or n_short == 0:
            break
        drop = np.zeros(k, dtype=np.bool_)
        if n_short == k:
            drop[0] = True
        else:
            for i in range(k):
                drop[i] = short[i] and not short[i - 1]
        keep = np.flatnonzero(~drop)
        chain, A, b = chain[keep], A[keep], b[keep]
        k = chain.size
        V = np.empty((k, 2))
        for i in range(k):
            q = (i + 1) % k
            det = A[i, 0] * A[q, 1] - A[i, 1] * A[q, 0]
            V[i, 0] = (b[i] * A[q, 1] - A[i, 1] * b[q]) / det
            V[i, 1] = (A[i, 0] * b[q] - A[q, 0] * b[i]) / det
        shifted = False
    if shifted:
        for i in range(k):
            V[i, 0] += x0[0]
            V[i, 1] += x0[1]
    return chain, A, b, V, _signed_margin(V, b), True


def polygon_region(N2: np.ndarray, h: np.ndarray, x0: np.ndarray | None, tol: float,
                   parallel: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float] | None:
    r"""
    Return the polygon ``{delta : N2^T delta <= h}`` of a CoM region (steps 6-7, compiled).

    The compiled :func:`awp_ros.wrench.com_region._polar` and ``_polygon`` (their numpy
    code is the reference): the dual points ``n_i / (h_i - n_i . x_0)`` about the interior
    point ``x0`` (None: the current CoM), their hull (:func:`polar_hull`), the primal
    vertices, then the lines whose edges are at most ``tol`` [m] long dropped (their
    neighbours' normals not ``parallel``), and the signed margin of the current CoM.

    :return: ``(A, b, V, margin)`` (unit edge normals (k, 2), offsets [m], ccw vertices
        (k, 2) [m] relative to the current CoM, edge ``i`` joining vertices ``i - 1`` and
        ``i``), or None when 0 is not strictly inside the dual hull (unbounded region).
    """
    x = np.zeros(2) if x0 is None else np.ascontiguousarray(x0, dtype=float)
    _, A, b, V, margin, ok = _polygon_region(np.ascontiguousarray(N2, dtype=float),
                                             np.ascontiguousarray(h, dtype=float), x,
                                             float(tol), float(parallel))
    return (A, b, V, float(margin)) if ok else None


@_jit
def _wrench_slice(PA, Pb, w, tol, parallel, h_min):
    m = PA.shape[0]
    fx, fy, fz, Lx, Ly, Lz = w[0], w[1], w[2], w[3], w[4], w[5]
    N2 = np.empty((2, m))
    h = np.empty(m)
    lowest = np.inf
    for i in range(m):
        h[i] = Pb[i] - (PA[i, 0] * fx + PA[i, 1] * fy + PA[i, 2] * fz + PA[i, 3] * Lx
                        + PA[i, 4] * Ly + PA[i, 5] * Lz)
        N2[0, i] = fy * PA[i, 5] - fz * PA[i, 4]
        N2[1, i] = fz * PA[i, 3] - fx * PA[i, 5]
        lowest = min(lowest, h[i])
    A, b, V = np.empty((0, 2)), np.empty(0), np.empty((0, 2))
    if m < 3 or not lowest > h_min:
        return A, b, V, np.nan, 1
    _, A, b, V, margin, ok = _polygon_region(N2, h, np.zeros(2), tol, parallel)
    return A, b, V, margin, 0 if ok else 2


def wrench_slice(A: np.ndarray, b: np.ndarray, wrench: np.ndarray, tol: float,
                 parallel: float, h_min: float) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                         float, int]:
    r"""
    Return the CoM region of a full-dimensional wrench set when the CoM is well inside.

    The fast path of :func:`awp_ros.wrench.com_region.com_region` (steps 4-7, compiled): the
    rows ``A w <= b`` (R^6) in ``delta``, ``n_i . delta <= h_i`` with ``h = b - A w`` and
    ``n_i = (f_y a_{i,5} - f_z a_{i,4}, f_z a_{i,3} - f_x a_{i,5})`` (``w = [f; L']``),
    then :func:`polygon_region` about the current CoM.

    :return: ``(A, b, V, margin, status)`` as :func:`polygon_region`; status 0 the polygon,
        1 not this path (fewer than 3 rows, or some ``h_i <= h_min``: the current CoM not
        well inside), 2 unbounded.
    """
    return _wrench_slice(np.ascontiguousarray(A, dtype=float),
                         np.ascontiguousarray(b, dtype=float),
                         np.ascontiguousarray(wrench, dtype=float), float(tol),
                         float(parallel), float(h_min))


@_jit
def _segment_slice(PA, Pb, E, e, w, const_tol, wrench_tol, tol):
    fx, fy, fz, Lx, Ly, Lz = w[0], w[1], w[2], w[3], w[4], w[5]
    gx, gy = fy * E[5] - fz * E[4], fz * E[3] - fx * E[5]          # G = E D
    g = e - (E[0] * fx + E[1] * fy + E[2] * fz + E[3] * Lx + E[4] * Ly + E[5] * Lz)
    norm = np.hypot(gx, gy)
    if not norm > const_tol:
        return (1 if abs(g) > wrench_tol else 3), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    x, y = g * gx / (norm * norm), g * gy / (norm * norm)
    ux, uy = -gy / norm, gx / norm
    # The rows in t along delta = (x, y) + t u: alpha t <= beta (com_region's (4), _interval).
    X0 = (fx, fy, fz, Lx + y * fz, Ly - x * fz, Lz + x * fy - y * fx)
    hi, lo = np.inf, -np.inf
    n_pos = n_neg = 0
    const_min = np.inf
    for i in range(PA.shape[0]):
        a0, a1, a2, a3, a4, a5 = PA[i, 0], PA[i, 1], PA[i, 2], PA[i, 3], PA[i, 4], PA[i, 5]
        m0 = X0[0] * a0 + X0[1] * a1 + X0[2] * a2 + X0[3] * a3 + X0[4] * a4 + X0[5] * a5
        n0 = -fz * a4 + fy * a5
        n1 = fz * a3 - fx * a5
        beta = Pb[i] - m0
        alpha = ux * n0 + uy * n1
        if alpha > const_tol:
            hi = min(hi, beta / alpha)
            n_pos += 1
        elif alpha < -const_tol:
            lo = max(lo, beta / alpha)
            n_neg += 1
        else:
            const_min = min(const_min, beta)
    if const_min < -wrench_tol:
        return 1, x, y, ux, uy, 0.0, 0.0
    if n_pos == 0 or n_neg == 0:
        return 2, x, y, ux, uy, 0.0, 0.0
    if lo > hi + tol:
        return 1, x, y, ux, uy, lo, hi
    return 0, x, y, ux, uy, lo, hi


def segment_slice(A: np.ndarray, b: np.ndarray, normal: np.ndarray, offset: float,
                  wrench: np.ndarray, const_tol: float, wrench_tol: float,
                  tol: float) -> tuple:
    r"""
    Return the CoM region of a wrench set on a hyperplane of R^6 (two stance legs) as a segment.

    Steps (3)-(4) of :func:`awp_ros.wrench.com_region.com_region` for ``r = 5``, compiled:
    the hull's equality ``normal . W(delta) = offset`` is the line ``delta = (x, y) + t u``
    (``g = offset - normal . w``, ``G = normal D``, ``(x, y) = g G / |G|^2``, ``u`` along
    ``G``'s null space), and each row ``a_i . W(delta) <= b_i`` (``A`` (m, 6), ``b``) the
    bound ``alpha_i t <= beta_i``; rows with ``|alpha_i| <= const_tol`` are constant (their
    least ``beta`` below ``-wrench_tol``: empty).

    :return: ``(status, x, y, u_x, u_y, lo, hi)``: status 0 the interval ``[lo, hi]`` of
        ``t``, 1 empty (``lo > hi + tol``, a violated constant row, or ``|g| > wrench_tol``
        with ``|G| <= const_tol``), 2 unbounded (no bound on one side), 3 ``|G| <=
        const_tol`` with the equality met (not a line: the caller's general steps).
    """
    out = _segment_slice(np.ascontiguousarray(A, dtype=float),
                         np.ascontiguousarray(b, dtype=float),
                         np.ascontiguousarray(normal, dtype=float), float(offset),
                         np.ascontiguousarray(wrench, dtype=float), float(const_tol),
                         float(wrench_tol), float(tol))
    return (int(out[0]),) + tuple(float(v) for v in out[1:])


# -- the feasible region by exact iterative projection (a small simplex) ---------------------

@_jit
def _leg_vertices(A, b, tol):
    """Return the vertices of ``{f : A f <= b}`` (R^3) by all plane triples, merged."""
    m = A.shape[0]
    out = np.empty((m * (m - 1) * (m - 2) // 6, 3))
    bmax = 1.0
    for i in range(m):
        bmax = max(bmax, abs(b[i]))
    slack = tol * bmax
    C = np.empty((m, m, 3))                          # C[j, k] = a_j x a_k, once per pair
    for j in range(m):
        for k in range(j + 1, m):
            C[j, k, 0] = A[j, 1] * A[k, 2] - A[j, 2] * A[k, 1]
            C[j, k, 1] = A[j, 2] * A[k, 0] - A[j, 0] * A[k, 2]
            C[j, k, 2] = A[j, 0] * A[k, 1] - A[j, 1] * A[k, 0]
    n = 0
    x = np.empty(3)
    for i in range(m):
        for j in range(i + 1, m):
            cx, cy, cz = -C[i, j, 0], -C[i, j, 1], -C[i, j, 2]
            for k in range(j + 1, m):
                # Cramer's rule: x = (b_i a_j x a_k + b_j a_k x a_i + b_k a_i x a_j) / det
                jk0, jk1, jk2 = C[j, k, 0], C[j, k, 1], C[j, k, 2]
                det = A[i, 0] * jk0 + A[i, 1] * jk1 + A[i, 2] * jk2
                if abs(det) <= 1e-12:
                    continue
                ki0, ki1, ki2 = -C[i, k, 0], -C[i, k, 1], -C[i, k, 2]
                x[0] = (b[i] * jk0 + b[j] * ki0 - b[k] * cx) / det
                x[1] = (b[i] * jk1 + b[j] * ki1 - b[k] * cy) / det
                x[2] = (b[i] * jk2 + b[j] * ki2 - b[k] * cz) / det
                ok = True
                for r in range(m):
                    if A[r, 0] * x[0] + A[r, 1] * x[1] + A[r, 2] * x[2] > b[r] + slack:
                        ok = False
                        break
                if not ok:
                    continue
                for q in range(n):
                    d = abs(out[q, 0] - x[0]) + abs(out[q, 1] - x[1]) + abs(out[q, 2] - x[2])
                    if d <= slack:
                        ok = False
                        break
                if ok:
                    out[n, 0], out[n, 1], out[n, 2] = x[0], x[1], x[2]
                    n += 1
    return out[:n]


@_jit(inline=True)
def _reduced_costs(T, basis, cost, d, live):
    """Write the reduced costs ``d = cost - cost_B B^-1 A`` of the first ``live`` columns."""
    m = T.shape[0]
    for j in range(live):
        d[j] = cost[j]
    for i in range(m):
        cb = cost[basis[i]]
        if cb != 0.0:
            for j in range(live):
                d[j] -= cb * T[i, j]
    for i in range(m):
        if basis[i] < live:
            d[basis[i]] = 0.0


@_jit(inline=True)
def _simplex(T, basis, cost, kind, d, row, max_iter, live):
    """
    Minimise ``cost . z`` from the feasible basis of the tableau ``T = B^-1 [A | rhs]``.

    Nonbasic variables are at 0, so the last column holds the basic values; ``kind[j]``: 0
    ``z_j >= 0``, 1 free, 2 fixed at 0 (never enters; leaves when it would move). Dantzig's
    rule, then Bland's (smallest index: no cycling) after ``max_iter / 4`` pivots. The
    reduced costs ``d`` are updated with each pivot like a row of the tableau, and
    recomputed from ``cost`` every 16 pivots and before optimality is declared. Only the
    first ``live`` columns (and the last) are kept up to date: the others are fixed
    variables that can never enter again (phase 1's artificials, once it is over), and no
    step reads their columns. ``row`` (a buffer of ``T``'s row length) holds the pivot row.
    Returns 0 optimal, 1 unbounded, 2 iteration limit.
    """
    m = T.shape[0]
    N = T.shape[1] - 1
    _reduced_costs(T, basis, cost, d, live)
    fresh = True
    for it in range(max_iter):
        bland = it > max_iter // 4
        enter, best, direction = -1, 0.0, 1.0
        for j in range(live):
            if kind[j] == 2:
                continue
            score = abs(d[j]) if kind[j] == 1 else -d[j]
            if score > 1e-11:
                if bland:
                    enter, direction = j, (1.0 if d[j] < 0.0 else -1.0)
                    break
                if score > best:
                    enter, best, direction = j, score, (1.0 if d[j] < 0.0 else -1.0)
        if enter < 0:
            if fresh:
                return 0
            _reduced_costs(T, basis, cost, d, live)  # no drift in the optimality test
            fresh = True
            continue
        leave, step = -1, np.inf
        for i in range(m):
            alpha = direction * T[i, enter]
            k = kind[basis[i]]
            if k == 1:
                continue
            if alpha > 1e-12:
                t = max(T[i, N], 0.0) / alpha
            elif k == 2 and alpha < -1e-12:
                t = 0.0
            else:
                continue
            if t < step or (t == step and basis[i] < basis[leave]):
                leave, step = i, t
        if leave < 0:
            return 1
        piv = T[leave, enter]
        for j in range(live):                        # the pivot row, apart: no aliasing
            row[j] = T[leave, j] / piv
        row[N] = T[leave, N] / piv
        for j in range(live):
            T[leave, j] = row[j]
        T[leave, N] = row[N]
        for i in range(m):
            if i != leave:
                f = T[i, enter]
                if f != 0.0:
                    Ti = T[i]
                    for j in range(live):
                        Ti[j] -= f * row[j]
                    Ti[N] -= f * row[N]
        basis[leave] = enter
        if it % 16 == 15:
            _reduced_costs(T, basis, cost, d, live)
            fresh = True
        else:
            f = d[enter]
            for j in range(live):
                d[j] -= f * row[j]
            d[enter] = 0.0
            fresh = False
    return 2


@_jit(inline=True)
def _support_point(T, basis, cost, kind, d, row, u, n, out):
    """Solve ``max u . delta`` from the current basis; write delta to ``out``; status."""
    for j in range(cost.shape[0]):
        cost[j] = 0.0
    cost[n], cost[n + 1] = -u[0], -u[1]
    status = _simplex(T, basis, cost, kind, d, row, 4000, n + 2)
    out[0] = out[1] = 0.0
    N = T.shape[1] - 1
    for i in range(T.shape[0]):
        if basis[i] == n:
            out[0] = T[i, N]
        elif basis[i] == n + 1:
            out[1] = T[i, N]
    return status


@_jit(inline=True)
def _basis_bound(T, basis, kind, leg, n, K, u, a0, a1, gap):
    r"""
    Bound ``max u . delta - u . a`` [m] over the LP's feasible set, from the current basis.

    With the cost ``-u . delta`` the reduced cost of a weight is ``d_j = u . (T[r_x, j],
    T[r_y, j])`` (rows ``r_x, r_y`` where ``delta`` is basic), and every feasible point has
    ``u . delta = u . delta_B - \sum_j d_j lam_j`` with ``lam_j`` in [0, 1], one unit of
    weight per leg: so ``u . delta <= u . delta_B + \sum_legs max_j max(0, -d_j)``. Any
    feasible basis gives this bound; inf when ``delta`` is not basic.
    """
    rx = ry = -1
    for i in range(T.shape[0]):
        if basis[i] == n:
            rx = i
        elif basis[i] == n + 1:
            ry = i
    if rx < 0 or ry < 0:
        return np.inf
    for k in range(K):
        gap[k] = 0.0
    for j in range(n):
        if kind[j] == 0:
            dj = u[0] * T[rx, j] + u[1] * T[ry, j]
            if -dj > gap[leg[j]]:
                gap[leg[j]] = -dj
    N = T.shape[1] - 1
    total = u[0] * (T[rx, N] - a0) + u[1] * (T[ry, N] - a1)
    for k in range(K):
        total += gap[k]
    return total


@_jit(inline=True)
def _crash_basis(T, basis, kind, cost, first, K, a0, flipped):
    """
    Write phase 1's crash basis of a tableau in the legs' barycentric weights.

    Rows 0-5 are the wrench, row ``6 + k`` leg k's unit of weight, the artificials' columns
    start at ``a0`` (one per row). Each leg's row starts with its point ``first[k]`` basic
    (weight 1, eliminated from the wrench rows; its artificial fixed at 0, ``kind`` 2), or
    with its artificial when it has none (``first[k] < 0``); the wrench rows with their
    artificials, after negating those whose right-hand side is negative (``flipped``). The
    artificials' sum is added to ``cost``.
    """
    N = T.shape[1] - 1
    for k in range(K):
        r, c = 6 + k, first[k]
        if c < 0:
            T[r, a0 + r] = 1.0
            basis[r] = a0 + r
            cost[a0 + r] = 1.0
            continue
        for i in range(6):                           # T[r, c] == 1: pivot on it
            f = T[i, c]
            if f != 0.0:
                for j in range(N + 1):
                    T[i, j] -= f * T[r, j]
        basis[r] = c
        kind[a0 + r] = 2
    for i in range(6):
        flipped[i] = T[i, N] < 0.0
        if flipped[i]:
            for j in range(N + 1):
                T[i, j] = -T[i, j]
        T[i, a0 + i] = 1.0
        basis[i] = a0 + i
        cost[a0 + i] = 1.0


@_jit
def _projected_polygon(G, leg, K, w0, D, tol, max_lps):
    """See :func:`projected_polygon`."""
    n = G.shape[1]
    m = 6 + K
    N = n + 2 + m
    scale = 1.0
    for i in range(6):
        scale = max(scale, abs(w0[i]), abs(D[i, 0]), abs(D[i, 1]))
        for j in range(n):
            scale = max(scale, abs(G[i, j]))
    T = np.zeros((m, N + 1))
    for i in range(6):
        for j in range(n):
            T[i, j] = G[i, j] / scale
        T[i, n] = -D[i, 0] / scale
        T[i, n + 1] = -D[i, 1] / scale
        T[i, N] = w0[i] / scale
    for j in range(n):
        T[6 + leg[j], j] = 1.0
    for k in range(K):
        T[6 + k, N] = 1.0
    # Phase 1 from a crash basis: each leg's convexity row starts with its point of largest
    # vertical force basic (weight 1, eliminated from the wrench rows); the wrench rows (and
    # the convexity row of a leg without points) start with an artificial z_{n+2+i} =
    # |rhs_i| basic; their sum is minimised. A leg's artificial with its point basic is
    # fixed at 0 from the start.
    basis = np.empty(m, dtype=np.int64)
    kind = np.zeros(N, dtype=np.int64)
    kind[n] = kind[n + 1] = 1
    cost = np.zeros(N)
    d = np.empty(N)
    row = np.empty(N + 1)                            # the pivot row, one buffer for all LPs
    first = np.full(K, -1, dtype=np.int64)
    for j in range(n):
        if first[leg[j]] < 0 or T[2, j] > T[2, first[leg[j]]]:
            first[leg[j]] = j
    _crash_basis(T, basis, kind, cost, first, K, n + 2, np.empty(6, dtype=np.bool_))
    status = _simplex(T, basis, cost, kind, d, row, 4000, N)
    vertices = np.empty((max_lps + 3, 2))
    if status != 0:
        return vertices[:0], 2
    infeasibility = 0.0
    for i in range(m):
        if basis[i] >= n + 2:
            infeasibility += T[i, N]
    if infeasibility > 1e-9:
        return vertices[:0], 1
    for i in range(m):
        kind[n + 2 + i] = 2
    u = np.empty(2)
    p = np.empty(2)
    gap = np.empty(K)
    # Support points in three directions, then every edge of the hull of the points found
    # is tested by its outward normal until each is certified (Bretl & Lall, exact): by the
    # bound of the current basis when it suffices (_basis_bound, no pivot), else by an LP.
    k = 0
    lps = 0
    for t in range(3):
        angle = 2.0 * np.pi * t / 3.0
        u[0], u[1] = np.cos(angle), np.sin(angle)
        if _support_point(T, basis, cost, kind, d, row, u, n, p) != 0:
            return vertices[:0], 2
        lps += 1
        if k > 0 and abs(p[0] - vertices[k - 1, 0]) + abs(p[1] - vertices[k - 1, 1]) <= tol:
            continue
        if k > 1 and abs(p[0] - vertices[0, 0]) + abs(p[1] - vertices[0, 1]) <= tol:
            continue
        vertices[k, 0], vertices[k, 1] = p[0], p[1]
        k += 1
    if k == 1:
        return vertices[:1], 0
    e = 0
    while e < k:
        a0, a1 = vertices[e, 0], vertices[e, 1]
        b0, b1 = vertices[(e + 1) % k, 0], vertices[(e + 1) % k, 1]
        length = np.hypot(b0 - a0, b1 - a1)
        u[0], u[1] = (b1 - a1) / length, -(b0 - a0) / length
        if _basis_bound(T, basis, kind, leg, n, K, u, a0, a1, gap) <= tol:
            e += 1                                   # certified by the current basis
            continue
        if lps >= max_lps:
            return vertices[:0], 2
        if _support_point(T, basis, cost, kind, d, row, u, n, p) != 0:
            return vertices[:0], 2
        lps += 1
        if u[0] * (p[0] - a0) + u[1] * (p[1] - a1) <= tol:
            e += 1                                   # a certified edge
            continue
        # A support point at a vertex already found is on the inner side of every edge in
        # exact arithmetic: beyond this one only by the rounding of a short edge's normal
        # (two points found on one edge, ~1e-8 m apart). Certified; inserting it would
        # break the chain's convexity.
        known = False
        for q in range(k):
            if abs(p[0] - vertices[q, 0]) + abs(p[1] - vertices[q, 1]) <= tol:
                known = True
                break
        if known:
            e += 1
            continue
        for q in range(k, e + 1, -1):                # insert p after vertex e
            vertices[q, 0], vertices[q, 1] = vertices[q - 1, 0], vertices[q - 1, 1]
        vertices[e + 1, 0], vertices[e + 1, 1] = p[0], p[1]
        k += 1
    return vertices[:k], 0


@_jit(inline=True)
def _needed_rows(R):
    """
    Return how many of the rows ``R`` (pyramid sides, then ``-n . f <= 0``) are needed.

    The last row is implied by the others, and dropped (fewer plane triples), when their
    sum is a positive multiple of it (``mu > 0``: the pyramid lies above its apex).
    """
    c = R.shape[0]
    if c < 2:
        return c
    s0 = s1 = s2 = 0.0
    for i in range(c - 1):
        s0, s1, s2 = s0 + R[i, 0], s1 + R[i, 1], s2 + R[i, 2]
    u0, u1, u2 = R[c - 1, 0], R[c - 1, 1], R[c - 1, 2]
    uu = u0 * u0 + u1 * u1 + u2 * u2
    su = s0 * u0 + s1 * u1 + s2 * u2
    if not (uu > 0.0 and su > 0.0):
        return c
    t = su / uu
    e0, e1, e2 = s0 - t * u0, s1 - t * u1, s2 - t * u2
    if e0 * e0 + e1 * e1 + e2 * e2 <= 1e-24 * (s0 * s0 + s1 * s1 + s2 * s2):
        return c - 1
    return c


@_jit
def _lifted_leg_points(FA, Fb, R, P):
    """
    Return the legs' lifted vertices ``[v; p_k x v]`` (6, n), their legs (n,) and a status.

    Leg ``k``'s friction-bounded polytope ``{f : FA[k] f <= Fb[k], R[k] f <= 0}`` by its
    vertices (:func:`leg_vertices`); status 1 (and no points) when a leg has none.
    """
    K, m0 = FA.shape[0], FA.shape[1]
    m = m0 + R.shape[1]
    A = np.empty((m, 3))
    b = np.zeros(m)
    columns = np.empty((6, K * m * (m - 1) * (m - 2) // 6))
    leg = np.empty(columns.shape[1], dtype=np.int64)
    n = 0
    for k in range(K):
        A[:m0] = FA[k]
        b[:m0] = Fb[k]
        A[m0:] = R[k]
        b[m0:] = 0.0
        mk = m0 + _needed_rows(R[k])
        V = _leg_vertices(A[:mk], b[:mk], 1e-9)
        if V.shape[0] == 0:
            return columns[:, :0].copy(), leg[:0].copy(), 1
        for v in range(V.shape[0]):
            x, y, z = V[v, 0], V[v, 1], V[v, 2]
            columns[0, n], columns[1, n], columns[2, n] = x, y, z
            columns[3, n] = P[k, 1] * z - P[k, 2] * y
            columns[4, n] = P[k, 2] * x - P[k, 0] * z
            columns[5, n] = P[k, 0] * y - P[k, 1] * x
            leg[n] = k
            n += 1
    return columns[:, :n].copy(), leg[:n].copy(), 0


@_jit
def _feasible_polygon(G, leg, K, points_status, w0, D, tol, max_lps):
    """
    Return the vertices and status of :func:`feasible_region` (``W = w0 + D delta``).

    From the legs' lifted points ``G``, ``leg`` and their status (:func:`_lifted_leg_points`).
    """
    if points_status != 0:
        return np.empty((0, 2)), 1
    V, status = _projected_polygon(G, leg, K, w0, D, tol, max_lps)
    if status != 0:
        return V, status
    # Merge vertices closer than tol and vertices inside an edge (collinear neighbours).
    k = V.shape[0]
    keep = np.ones(k, dtype=np.bool_)
    changed = True
    while changed and k >= 2:
        changed = False
        idx = np.flatnonzero(keep)
        c = idx.size
        if c < 2:
            break
        for t in range(c):
            i, j = idx[t - 1], idx[t]
            if abs(V[i, 0] - V[j, 0]) + abs(V[i, 1] - V[j, 1]) <= tol:
                keep[j] = False
                changed = True
                break
            if c >= 3:
                h = idx[(t + 1) % c]
                e0x, e0y = V[j, 0] - V[i, 0], V[j, 1] - V[i, 1]
                e1x, e1y = V[h, 0] - V[j, 0], V[h, 1] - V[j, 1]
                turn = e0x * e1y - e0y * e1x
                if turn <= 1e-12 * np.hypot(e0x, e0y) * np.hypot(e1x, e1y):
                    keep[j] = False
                    changed = True
                    break
    return V[keep].copy(), 0


@_jit
def _feasible_region(FA, Fb, R, P, w, tol, max_lps):
    """See :func:`feasible_region`."""
    G, leg, status = _lifted_leg_points(FA, Fb, R, P)
    return _feasible_region_of_points(G, leg, FA.shape[0], status, w, tol, max_lps)


@_jit
def _feasible_region_of_points(G, leg, K, points_status, w, tol, max_lps):
    """:func:`feasible_region` from the legs' lifted points (:func:`_lifted_leg_points`)."""
    D = np.zeros((6, 2))             # W(delta) = w + D delta: the moment of f at the offset
    D[3, 1], D[4, 0], D[5, 0], D[5, 1] = w[2], -w[2], w[1], -w[0]
    V, status = _feasible_polygon(G, leg, K, points_status, w, D, tol, max_lps)
    k = V.shape[0]
    A = np.zeros((k, 2))
    b = np.zeros(k)
    if status != 0 or k < 3:
        return V, A, b, np.nan, status
    for j in range(k):                               # edge j joins vertices j - 1 and j
        ex, ey = V[j, 0] - V[j - 1, 0], V[j, 1] - V[j - 1, 1]
        length = np.hypot(ex, ey)
        A[j, 0], A[j, 1] = ey / length, -ex / length
        b[j] = A[j, 0] * V[j, 0] + A[j, 1] * V[j, 1]
    return V, A, b, _signed_margin(V, b), status


@_jit(inline=True)
def _directional_phase1(G, leg, K, first, w, scale, axis, T, basis, kind, cost, d, row,
                        flipped):
    """
    Write a feasible basis of ``[G | -e_axis] (lam, t) = w`` to ``T`` (phase 1); status.

    One unit of weight per leg; from :func:`_crash_basis` (each leg's point ``first[k]``,
    artificials on the wrench rows, ``flipped`` where their right-hand side was negated),
    their sum minimised. ``axis < 0``: no ``t`` (its column zero and fixed).
    Returns 0 feasible (the artificials then fixed at 0), 1 infeasible (the line misses S),
    2 failed.
    """
    n, m = G.shape[1], T.shape[0]
    N = T.shape[1] - 1
    T[:, :] = 0.0
    for i in range(6):
        for j in range(n):
            T[i, j] = G[i, j] / scale
        T[i, N] = w[i] / scale
    for j in range(n):
        T[6 + leg[j], j] = 1.0
    for k in range(K):
        T[6 + k, N] = 1.0
    kind[:] = 0
    kind[n] = 2
    if axis >= 0:
        T[axis, n] = -1.0
        kind[n] = 1
    cost[:] = 0.0
    _crash_basis(T, basis, kind, cost, first, K, n + 1, flipped)
    if _simplex(T, basis, cost, kind, d, row, 4000, N) != 0:
        return 2
    infeasibility = 0.0
    for i in range(m):
        if basis[i] > n:
            infeasibility += T[i, N]
    if infeasibility > 1e-9:
        return 1
    for i in range(m):
        kind[n + 1 + i] = 2
    return 0


@_jit
def _directional_margins(G, leg, K, points_status, w):
    """See :func:`directional_margins_lp`; from the legs' lifted points."""
    out = np.full((6, 2), np.nan)
    if points_status != 0:
        return out, 0                                 # a leg without points: S is empty
    n = G.shape[1]
    m = 6 + K
    N = n + 1 + m                                     # weights, t, artificials
    scale = 1.0
    for i in range(6):
        scale = max(scale, abs(w[i]))
        for j in range(n):
            scale = max(scale, abs(G[i, j]))
    T, Ta = np.empty((m, N + 1)), np.empty((m, N + 1))
    basis, basis_a = np.empty(m, dtype=np.int64), np.empty(m, dtype=np.int64)
    kind, kind_a = np.empty(N, dtype=np.int64), np.empty(N, dtype=np.int64)
    cost = np.empty(N)
    d = np.empty(N)
    row = np.empty(N + 1)
    flipped = np.empty(6, dtype=np.bool_)
    first = np.full(K, -1, dtype=np.int64)           # each leg's point of largest f_z
    for j in range(n):
        if first[leg[j]] < 0 or G[2, j] > G[2, first[leg[j]]]:
            first[leg[j]] = j
    # One phase 1 of G lam = w for the six axes when w is in S: t's column is then that
    # basis' image of -e_axis, +-(its wrench row's artificial column, kept up to date), and
    # t = 0 is feasible. Else each axis' line has a phase 1 of its own.
    inside = _directional_phase1(G, leg, K, first, w, scale, -1, T, basis, kind, cost, d, row,
                                 flipped)
    if inside == 2:
        return np.full((6, 2), np.nan), 2
    for axis in range(6):
        if inside == 0:
            Ta[:, :] = T
            basis_a[:] = basis
            kind_a[:] = kind
            sign = 1.0 if flipped[axis] else -1.0
            for i in range(m):
                Ta[i, n] = sign * T[i, n + 1 + axis]
            kind_a[n] = 1
        else:
            status = _directional_phase1(G, leg, K, first, w, scale, axis, Ta, basis_a,
                                         kind_a, cost, d, row, flipped)
            if status == 2:
                return np.full((6, 2), np.nan), 2
            if status == 1:                           # the line misses S: NaN
                continue
        for side in range(2):                         # max t, then min t, from that basis
            cost[:] = 0.0
            cost[n] = -1.0 if side == 0 else 1.0
            if _simplex(Ta, basis_a, cost, kind_a, d, row, 4000, n + 1) != 0:
                return np.full((6, 2), np.nan), 2
            t = 0.0
            for i in range(m):
                if basis_a[i] == n:
                    t = Ta[i, N]
            out[axis, side] = t * scale if side == 0 else -t * scale
    return out, 0


def directional_margins_lp(force_A: np.ndarray, force_b: np.ndarray, rows: np.ndarray,
                           positions: np.ndarray, wrench: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray, int]:
    r"""
    Return the FWS's directional margins at ``wrench`` exactly, by LPs, without its H-rep.

    .. math:: t^+_i = \max\{t : w + t e_i \in S\}, \qquad
              t^-_i = -\min\{t : w + t e_i \in S\}, \qquad
              S = \sum_k L_k\, \mathrm{conv}(V_k)

    ``V_k`` the vertices of leg ``k``'s friction-bounded polytope ``{f : force_A[k] f <=
    force_b[k], rows[k] f <= 0}`` (:func:`leg_vertices`), lifted to ``[v; p_k x v]`` at the
    feet ``positions`` (K, 3) [m]. Per axis one LP in the legs' barycentric weights and
    ``t``: a dense two-phase simplex (:func:`projected_polygon`'s, rows scaled by the
    largest entry; phase 1 leaves at most 1e-9 of that scale), then ``max t`` and ``min t``
    from the same basis. The conventions of
    :func:`awp_ros.geometry.margin.directional_margins` (the interval need not contain 0
    when ``w`` is outside; both NaN when the line misses S; for a flat S, ``t^+ = t_0``,
    ``t^- = -t_0`` where the line crosses it).

    :return: ``(t_plus (6,), t_minus (6,), status)`` [N x3, N.m x3]: status 0, or 2 when an
        LP failed (unbounded or over its iteration limit; all NaN).
    """
    G, leg, status = _lifted_leg_points(
        np.ascontiguousarray(force_A, dtype=float), np.ascontiguousarray(force_b, dtype=float),
        np.ascontiguousarray(rows, dtype=float), np.ascontiguousarray(positions, dtype=float))
    return directional_margins_of_points(G, leg, len(force_A), status, wrench)


def directional_margins_of_points(G: np.ndarray, leg: np.ndarray, K: int, points_status: int,
                                  wrench: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """
    Return :func:`directional_margins_lp`'s margins from the legs' lifted points.

    ``(G, leg, points_status)`` as :func:`cycle_regions` returns them (the feasible region's
    points: the per-cycle evaluation projects and takes the margins from one enumeration).
    """
    out, status = _directional_margins(G, leg, int(K), int(points_status),
                                       np.ascontiguousarray(wrench, dtype=float))
    return out[:, 0].copy(), out[:, 1].copy(), int(status)


def feasible_region(force_A: np.ndarray, force_b: np.ndarray, rows: np.ndarray,
                    positions: np.ndarray, wrench: np.ndarray, tol: float,
                    max_lps: int = 400) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, int]:
    r"""
    Return the feasible region's polygon by :func:`projected_polygon` on the legs' points.

    Leg ``k``'s friction-bounded polytope ``{f : force_A[k] f <= force_b[k], rows[k] f <=
    0}`` (torque and pyramid rows, R^3) by its vertices (:func:`leg_vertices`), lifted to
    ``[v; p_k x v]`` (``positions`` (K, 3) [m] from the CoM); the wrench needed with the CoM
    at ``delta`` is ``W(delta) = wrench + [0; delta x f]``. The polygon's vertices closer
    than ``tol`` or inside an edge are merged.

    :return: ``(V (k, 2) counter-clockwise, A (k, 2), b (k,), margin, status)``: for a
        polygon (``k >= 3``) the unit edge rows ``A delta <= b`` (edge ``j`` joins vertices
        ``j - 1`` and ``j``) and the signed distance [m] of 0 to its boundary (positive
        inside); else ``A``, ``b`` empty and ``margin`` NaN. Status as
        :func:`projected_polygon` (1 also for a leg that cannot push).
    """
    V, A, b, margin, status = _feasible_region(
        np.ascontiguousarray(force_A, dtype=float), np.ascontiguousarray(force_b, dtype=float),
        np.ascontiguousarray(rows, dtype=float), np.ascontiguousarray(positions, dtype=float),
        np.ascontiguousarray(wrench, dtype=float), float(tol), int(max_lps))
    return V, A, b, float(margin), int(status)


def projected_polygon(G: np.ndarray, leg: np.ndarray, K: int, w0: np.ndarray, D: np.ndarray,
                      tol: float, max_lps: int = 400) -> tuple[np.ndarray, int]:
    r"""
    Return the exact polygon ``{delta : exists lam, G lam = w0 + D delta, lam in simplices}``.

    ``G`` (6, n): the lifted points ``[v; p_k x v]`` of K legs (``leg`` (n,) their leg),
    ``lam >= 0`` with ``sum lam = 1`` per leg; ``w0 + D delta`` the wrench needed with the
    CoM moved by ``delta`` (:func:`awp_ros.wrench.com_region.com_wrench_map`). A dense
    two-phase simplex (the rows scaled by the largest entry) finds a feasible basis, then
    the support points ``argmax u . delta`` in three directions, then for every edge of the
    points found its outward normal: a support point beyond the edge by more than ``tol``
    [m] is a new vertex, else the edge is an edge of the polygon (the test of Bretl & Lall's
    iterative projection, run until every edge is certified: no area tolerance). Each LP
    starts from the last one's basis.

    :return: ``(vertices (k, 2) counter-clockwise [m], status)``: status 0 (``k = 1`` a
        point, ``k = 2`` a segment), 1 empty (phase 1 leaves infeasibility), 2 failed (an LP
        unbounded or over its iteration limit, or more than ``max_lps`` LPs).
    """
    V, status = _projected_polygon(np.ascontiguousarray(G, dtype=float),
                                   np.ascontiguousarray(leg, dtype=np.int64), int(K),
                                   np.ascontiguousarray(w0, dtype=float),
                                   np.ascontiguousarray(D, dtype=float), float(tol),
                                   int(max_lps))
    return V, int(status)


def leg_vertices(A: np.ndarray, b: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Return the vertices (k, 3) of ``{f : A f <= b}`` by all triples of rows (merged)."""
    return _leg_vertices(np.ascontiguousarray(A, dtype=float),
                         np.ascontiguousarray(b, dtype=float), float(tol))


# -- Faces of a solid leg polytope (the numpy reference: awp_ros.geometry.face_lattice) ----

@_jit(inline=True)
def _stable_argsort(keys):
    """Return a stable argsort of a short int64 array (insertion sort)."""
    n = keys.shape[0]
    order = np.arange(n)
    for i in range(1, n):
        j, item = i, order[i]
        while j > 0 and keys[order[j - 1]] > keys[item]:
            order[j] = order[j - 1]
            j -= 1
        order[j] = item
    return order


@_jit(inline=True)
def _face_classes(dirs, checks):
    """
    Group faces by direction space as ``FaceGroup.from_faces`` does (same classes and order).

    ``dirs`` (n, d, 3), d = 1 (edges) or 2 (facets); ``checks`` (n, c, 3). Returns the
    class directions (m, d, 3), checks (m, k, c, 3), mask (m, k), and False on a hash
    collision of two different rounded keys (the caller then runs the numpy code).
    """
    n, d, c = dirs.shape[0], dirs.shape[1], checks.shape[1]
    q = np.empty((n, 3), dtype=np.int64)
    key = np.empty(3)
    for i in range(n):
        if d == 1:
            key[:] = dirs[i, 0]
        else:
            a, e = dirs[i, 0], dirs[i, 1]
            key[0] = a[1] * e[2] - a[2] * e[1]
            key[1] = a[2] * e[0] - a[0] * e[2]
            key[2] = a[0] * e[1] - a[1] * e[0]
        key /= np.sqrt(key[0] ** 2 + key[1] ** 2 + key[2] ** 2)
        lead = 0
        for t in range(1, 3):
            if abs(key[t]) > abs(key[lead]):
                lead = t
        s = np.sign(key[lead])
        for t in range(3):
            q[i, t] = np.int64(np.rint(key[t] * s * 1e10))
    h = q[:, 0] + q[:, 1] * np.int64(1000003) + q[:, 2] * np.int64(998244353)
    order = _stable_argsort(h)
    inverse = np.empty(n, dtype=np.int64)
    first = np.empty(n, dtype=np.int64)
    m = 0
    for t in range(n):
        i = order[t]
        if t == 0 or h[i] != h[order[t - 1]]:
            first[m] = i
            m += 1
        inverse[i] = m - 1
    ok = True
    for i in range(n):
        f = first[inverse[i]]
        if q[i, 0] != q[f, 0] or q[i, 1] != q[f, 1] or q[i, 2] != q[f, 2]:
            ok = False
    counts = np.zeros(m, dtype=np.int64)
    for i in range(n):
        counts[inverse[i]] += 1
    by_size = _stable_argsort(-counts)
    rank = np.empty(m, dtype=np.int64)
    for t in range(m):
        rank[by_size[t]] = t
    k = counts.max() if m else 0
    out_dirs = np.empty((m, d, 3))
    out_checks = np.zeros((m, k, c, 3))
    mask = np.zeros((m, k), dtype=np.bool_)
    filled = np.zeros(m, dtype=np.int64)
    for t in range(m):
        out_dirs[rank[t]] = dirs[first[t]]
    for i in range(n):                                # slots in input order within a class
        g = rank[inverse[i]]
        out_checks[g, filled[g]] = checks[i]
        mask[g, filled[g]] = True
        filled[g] += 1
    return out_dirs, out_checks, mask, ok


@_jit
def _solid_faces(V, A, b, origin, scale, tol):
    # Points closer than tol are merged (the first of each cluster stays).
    n0 = V.shape[0]
    keep = np.ones(n0, dtype=np.bool_)
    for i in range(n0):
        for j in range(i):
            s = 0.0
            for t in range(3):
                s += ((V[i, t] - origin[t]) - (V[j, t] - origin[t])) ** 2
            if np.sqrt(s) <= tol:
                keep[i] = False
                break
    V = V[keep]
    n = V.shape[0]
    # Facets: unit rows whose points span a plane, one per incidence set (in key order).
    R = A.shape[0]
    rows = np.empty((R, 3))
    inc_all = np.zeros((R, n), dtype=np.bool_)
    keys = np.empty(R, dtype=np.int64)
    m = 0
    S = np.empty((3, 3))
    mean = np.empty(3)
    for r in range(R):
        norm = np.sqrt(A[r, 0] ** 2 + A[r, 1] ** 2 + A[r, 2] ** 2)
        if not norm > 0.0:
            continue
        a = A[r] / norm
        br = b[r] / norm
        count = 0
        key = np.int64(0)
        mean[:] = 0.0
        S[:, :] = 0.0
        for i in range(n):
            if abs(V[i, 0] * a[0] + V[i, 1] * a[1] + V[i, 2] * a[2] - br) <= tol:
                inc_all[m, i] = True
                key += np.int64(1) << i
                count += 1
                for u in range(3):
                    mean[u] += V[i, u]
                    for v in range(3):
                        S[u, v] += V[i, u] * V[i, v]
        c = max(count, 1)
        for u in range(3):
            for v in range(3):
                S[u, v] = S[u, v] / c - (mean[u] / c) * (mean[v] / c)
        if np.linalg.eigvalsh(S)[1] > tol * tol:
            rows[m] = a
            keys[m] = key
            m += 1
    order = _stable_argsort(keys[:m])
    F = 0
    pick = np.empty(m, dtype=np.int64)
    for t in range(m):
        if t == 0 or keys[order[t]] != keys[order[t - 1]]:
            pick[F] = order[t]
            F += 1
    N = np.empty((F, 3))
    inc = np.zeros((F, n), dtype=np.bool_)
    offsets = np.empty(F)
    for f in range(F):
        N[f] = rows[pick[f]]
        inc[f] = inc_all[pick[f]]
        best = -np.inf
        for i in range(n):
            best = max(best, V[i, 0] * N[f, 0] + V[i, 1] * N[f, 1] + V[i, 2] * N[f, 2])
        offsets[f] = best
    extreme = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        extreme[i] = inc[:, i].sum() >= 3
    # Edges: facet pairs sharing two points, direction n_f x n_g or the chord.
    E = 0
    pairs = np.empty((F * (F - 1) // 2, 2), dtype=np.int64)
    for f in range(F):
        for g in range(f + 1, F):
            if (inc[f] & inc[g]).sum() >= 2:
                pairs[E, 0], pairs[E, 1] = f, g
                E += 1
    edirs = np.empty((E, 1, 3))
    echecks = np.empty((E, 2, 3))
    for t in range(E):
        nf, ng = N[pairs[t, 0]], N[pairs[t, 1]]
        e = np.empty(3)
        e[0] = nf[1] * ng[2] - nf[2] * ng[1]
        e[1] = nf[2] * ng[0] - nf[0] * ng[2]
        e[2] = nf[0] * ng[1] - nf[1] * ng[0]
        sin = np.sqrt(e[0] ** 2 + e[1] ** 2 + e[2] ** 2)
        if sin > 0.0:
            e /= sin
        lo, hi = np.inf, -np.inf
        i0, i1 = 0, 0
        for i in range(n):
            if inc[pairs[t, 0], i] and inc[pairs[t, 1], i]:
                s = V[i, 0] * e[0] + V[i, 1] * e[1] + V[i, 2] * e[2]
                if s < lo:
                    lo, i0 = s, i
                if s > hi:
                    hi, i1 = s, i
        chord = V[i1] - V[i0]
        length = np.sqrt(chord[0] ** 2 + chord[1] ** 2 + chord[2] ** 2)
        if length * sin < scale:
            e = chord / length
        pf = nf - (nf[0] * e[0] + nf[1] * e[1] + nf[2] * e[2]) * e
        pg = ng - (ng[0] * e[0] + ng[1] * e[1] + ng[2] * e[2]) * e
        fg = pf[0] * pg[0] + pf[1] * pg[1] + pf[2] * pg[2]
        mf = pf - fg * pg / (pg[0] ** 2 + pg[1] ** 2 + pg[2] ** 2)
        mg = pg - fg * pf / (pf[0] ** 2 + pf[1] ** 2 + pf[2] ** 2)
        edirs[t, 0] = e
        echecks[t, 0] = mf / np.sqrt(mf[0] ** 2 + mf[1] ** 2 + mf[2] ** 2)
        echecks[t, 1] = mg / np.sqrt(mg[0] ** 2 + mg[1] ** 2 + mg[2] ** 2)
    # Facet planes: u = n x (the axis of n's smallest component), w = n x u.
    fdirs = np.empty((F, 2, 3))
    fchecks = np.empty((F, 1, 3))
    for f in range(F):
        nv = N[f]
        ax = 0
        for t in range(1, 3):
            if abs(nv[t]) < abs(nv[ax]):
                ax = t
        axis = np.zeros(3)
        axis[ax] = 1.0
        u = np.empty(3)
        u[0] = nv[1] * axis[2] - nv[2] * axis[1]
        u[1] = nv[2] * axis[0] - nv[0] * axis[2]
        u[2] = nv[0] * axis[1] - nv[1] * axis[0]
        u /= np.sqrt(u[0] ** 2 + u[1] ** 2 + u[2] ** 2)
        fdirs[f, 0] = u
        fdirs[f, 1, 0] = nv[1] * u[2] - nv[2] * u[1]
        fdirs[f, 1, 1] = nv[2] * u[0] - nv[0] * u[2]
        fdirs[f, 1, 2] = nv[0] * u[1] - nv[1] * u[0]
        fchecks[f, 0] = nv
    ed, ec, em, ok_e = _face_classes(edirs, echecks)
    fd, fc, fm, ok_f = _face_classes(fdirs, fchecks)
    return V[extreme], N, offsets, ed, ec, em, fd, fc, fm, ok_e and ok_f and E > 1 and F > 1


def solid_faces(V: np.ndarray, A: np.ndarray, b: np.ndarray, origin: np.ndarray,
                scale: float, tol: float) -> tuple | None:
    """
    Return the faces of a solid (3D) polytope from its points and supporting rows, or None.

    The compiled form of ``awp_ros.geometry.face_lattice`` for a 3D point set with its
    H-rep (close points merged, facet rows, edges, their classes): the extreme points, unit
    facet normals, offsets, and the (dirs, checks, mask) of the edge and facet classes.
    None when the numpy code must decide (more than :data:`MAX_BITS` points, a hash
    collision of two class keys, fewer than two edges or facets).
    """
    if V.shape[0] > MAX_BITS - 1:               # the reference's bit keys take 62 bits
        return None
    out = _solid_faces(np.ascontiguousarray(V, dtype=float),
                       np.ascontiguousarray(A, dtype=float).reshape(-1, 3),
                       np.ascontiguousarray(b, dtype=float).reshape(-1),
                       np.ascontiguousarray(origin, dtype=float), float(scale), float(tol))
    return out[:-1] if out[-1] else None


@_jit
def _solid_faces_of(V, A, b, certify, plane_tol):
    n = V.shape[0]
    origin = np.zeros(3)
    for i in range(n):
        for t in range(3):
            origin[t] += V[i, t]
    for t in range(3):
        origin[t] /= n
    gram = np.zeros((3, 3))
    scale2 = 0.0
    for i in range(n):
        x0, x1, x2 = V[i, 0] - origin[0], V[i, 1] - origin[1], V[i, 2] - origin[2]
        scale2 = max(scale2, x0 * x0 + x1 * x1 + x2 * x2)
        gram[0, 0] += x0 * x0
        gram[0, 1] += x0 * x1
        gram[0, 2] += x0 * x2
        gram[1, 1] += x1 * x1
        gram[1, 2] += x1 * x2
        gram[2, 2] += x2 * x2
    gram[1, 0], gram[2, 0], gram[2, 1] = gram[0, 1], gram[0, 2], gram[1, 2]
    scale = np.sqrt(scale2)
    if not _full_rank(gram, certify):
        return (V[:0], np.zeros((0, 3)), np.zeros(0), np.zeros((0, 1, 3)),
                np.zeros((0, 1, 1, 3)), np.zeros((0, 1), dtype=np.bool_),
                np.zeros((0, 2, 3)), np.zeros((0, 1, 1, 3)), np.zeros((0, 1), dtype=np.bool_),
                False, origin)
    out = _solid_faces(V, A, b, origin, scale, plane_tol * scale)
    return out + (origin,)


def certified_solid_faces(V: np.ndarray, A: np.ndarray, b: np.ndarray, rank_tol: float,
                          plane_tol: float) -> tuple | None:
    """
    Return ``(origin, solid_faces(...))`` of points certified full-dimensional, or None.

    :func:`solid_faces` with its inputs computed in the same call: the centroid
    ``origin``, ``scale`` (the largest distance from it), and the full rank of the centred
    points certified as :func:`awp_ros.geometry.linalg.orthonormal_span` does
    (``det G / tr(G)^3 > max(rank_tol^2, GRAM_CERTIFY)`` from the Cholesky factor of the
    Gram matrix; a set it does not certify, or that :func:`solid_faces` declines, gives
    None and the numpy code decides).
    """
    if V.shape[0] > MAX_BITS - 1 or V.shape[0] < 4:
        return None
    out = _solid_faces_of(np.ascontiguousarray(V, dtype=float),
                          np.ascontiguousarray(A, dtype=float).reshape(-1, 3),
                          np.ascontiguousarray(b, dtype=float).reshape(-1),
                          max(float(rank_tol) ** 2, GRAM_CERTIFY), float(plane_tol))
    return (out[-1], out[:-2]) if out[-2] else None


# -- Facet normals of the FWS's face choices (awp_ros.geometry.minkowski_facets) -------------

@lru_cache(maxsize=32)
def sparse_wedge_table(r: int, p: int, q: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return the nonzero entries ``(I, J, sign)`` of the wedge table, grouped by output.

    Entry ``t`` adds ``sign[t] x_{I[t]} y_{J[t]}`` to output coordinate ``t // C(p + q, p)``
    (each has ``C(p + q, p)`` terms): eq. (1) of :mod:`awp_ros.geometry.exterior`.
    """
    T = wedge_table(r, p, q)
    i, j, s = np.nonzero(T)
    order = np.argsort(s, kind='stable')
    return i[order].astype(np.int64), j[order].astype(np.int64), T[i, j, s][order]


@_jit(inline=True)
def _survivor_normals_into(P, X, batch, row, col, first, second, sign, r, flip_from, min_norm):
    n = batch.shape[0]
    per = first.shape[0] // r
    out = np.empty((n, r))
    kept = 0
    W = np.empty(r)
    for t in range(n):
        p, x = P[batch[t], row[t]], X[batch[t], col[t]]
        e = 0
        for s in range(r):
            acc = 0.0
            for _ in range(per):
                acc += sign[e] * p[first[e]] * x[second[e]]
                e += 1
            W[s] = acc
        norm = 0.0
        for s in range(r):
            norm += W[s] * W[s]
        norm = np.sqrt(norm)
        if not norm > min_norm:
            continue
        scale = (-1.0 if t >= flip_from else 1.0) / norm
        for i in range(r):                            # n_i = (-1)^i W_{[r] - i}
            out[kept, i] = W[r - 1 - i] * scale * (1.0 - 2.0 * (i % 2))
        kept += 1
    return out[:kept].copy()


@_jit
def _survivor_normals(P, X, batch, row, col, first, second, sign, r, flip_from, min_norm):
    return _survivor_normals_into(P, X, batch, row, col, first, second, sign, r, flip_from,
                                  min_norm)


# The FWS's most frequent case, (r, p, q) = (6, 4, 1) (all four-leg patterns but (3, 2)): the
# same body with its table and r as compile-time constants, so that its loops run over fixed
# indices (about 4x faster than with the table passed at run time; the same arithmetic in the
# same order).
_FIRST_641, _SECOND_641, _SIGN_641 = sparse_wedge_table(6, 4, 1)


@_jit
def _survivor_normals_641(P, X, batch, row, col, flip_from, min_norm):
    return _survivor_normals_into(P, X, batch, row, col, _FIRST_641, _SECOND_641, _SIGN_641, 6,
                                  flip_from, min_norm)


def survivor_normals(P: np.ndarray, X: np.ndarray, batch: np.ndarray, row: np.ndarray,
                     col: np.ndarray, p: int, q: int, flip_from: int,
                     min_norm: float) -> np.ndarray:
    r"""
    Return the unit normals of chosen face combinations: ``a = *(P_{b,i} ^ X_{b,j})``.

    ``P`` (B, n_p, C(r, p)) holds wedges of all legs' face directions but the last,
    ``X`` (B, n_x, C(r, q)) the last leg's, ``p + q = r - 1``; choice ``t`` pairs
    ``P[batch[t], row[t]]`` with ``X[batch[t], col[t]]``. Choices from ``flip_from`` on get
    the opposite sign; those whose normal is not longer than ``min_norm`` (rank-deficient)
    are dropped. The numpy form: ``hodge_normal(wedge_rows(P[batch, row], X[batch, col]))``.
    """
    r = p + q + 1
    P, X = np.ascontiguousarray(P, dtype=float), np.ascontiguousarray(X, dtype=float)
    batch, row, col = batch.astype(np.int64), row.astype(np.int64), col.astype(np.int64)
    if (r, p, q) == (6, 4, 1):
        return _survivor_normals_641(P, X, batch, row, col, int(flip_from), float(min_norm))
    first, second, sign = sparse_wedge_table(r, p, q)
    return _survivor_normals(P, X, batch, row, col, first, second, sign, r, int(flip_from),
                             float(min_norm))


# -- The slice search of the FWS's facet normals (minkowski_facets, (5)) ----------------------
#
# On the slice of leg A's facet with unit normal n, c_A = lambda n, so a = (lambda n + p_A x t, t)
# and c_k = lambda n + t x d_k with d_k = p_k - p_A, x = (lambda, t) in R^4 (world axes); on the
# slice of all of Q_A (its face of dimension 3) c_A = 0, the same with lambda = 0 and n = 0.
# An edge direction e of leg k is the wall r . x = 0, r = (n . e, d_k x e); a check vector m
# the value s . x, s = (n . m, d_k x m). Three walls give x, their generalised cross product.


@_jit(inline=True, fastmath=True)
def _slice_lift(n, dk, v, out):
    """Write ``(n . v, dk x v)``, ``c_k . v`` as a linear form of x = (lambda, t), to out."""
    out[0] = n[0] * v[0] + n[1] * v[1] + n[2] * v[2]
    out[1] = dk[1] * v[2] - dk[2] * v[1]
    out[2] = dk[2] * v[0] - dk[0] * v[2]
    out[3] = dk[0] * v[1] - dk[1] * v[0]


@_jit(inline=True, fastmath=True)
def _norm4(v):
    return np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3])


@_jit(inline=True, fastmath=True)
def _plucker4(r1, r2, out):
    """Write r1 ^ r2 in R^4 (components 01, 02, 03, 12, 13, 23) to out; return its norm."""
    out[0] = r1[0] * r2[1] - r1[1] * r2[0]
    out[1] = r1[0] * r2[2] - r1[2] * r2[0]
    out[2] = r1[0] * r2[3] - r1[3] * r2[0]
    out[3] = r1[1] * r2[2] - r1[2] * r2[1]
    out[4] = r1[1] * r2[3] - r1[3] * r2[1]
    out[5] = r1[2] * r2[3] - r1[3] * r2[2]
    acc = 0.0
    for i in range(6):
        acc += out[i] * out[i]
    return np.sqrt(acc)


@_jit(inline=True, fastmath=True)
def _cross4(P, c, out):
    """Write x with ``x . y = det[r1; r2; c; y]`` for ``P = r1 ^ r2`` to out (minors along c)."""
    d123 = c[1] * P[5] - c[2] * P[4] + c[3] * P[3]
    d023 = c[0] * P[5] - c[2] * P[2] + c[3] * P[1]
    d013 = c[0] * P[4] - c[1] * P[2] + c[3] * P[0]
    d012 = c[0] * P[3] - c[1] * P[1] + c[2] * P[0]
    out[0] = -d123
    out[1] = d023
    out[2] = -d013
    out[3] = d012


@_jit(inline=True, fastmath=True)
def _slot_signs(S, tol, k, c, x, nx):
    """
    Return (pos, neg) for one leg at x.

    pos: some slot has every ``S . x >= -tol |x|``; neg: some slot has every
    ``S . x <= tol |x|``. A missing slot has ``tol = -inf`` (fails both).
    """
    f = -np.inf
    h = np.inf
    for s in range(k):
        mn = np.inf
        mx = -np.inf
        for j in range(c):
            v = S[s, j, 0] * x[0] + S[s, j, 1] * x[1] + S[s, j, 2] * x[2] + S[s, j, 3] * x[3]
            w = tol[s, j] * nx
            mn = min(mn, v + w)
            mx = max(mx, v - w)
        f = max(f, mn)
        h = min(h, mx)
    return f >= 0.0, h <= 0.0


@_jit(inline=True, fastmath=True)
def _slot_bounds(G, g, k, c, R, Rn, nR, f, h, mn, mx):
    """
    Write one leg's slot bounds for every candidate wall ``R[:, d]`` to ``f`` and ``h``.

    ``f[d] = max_slot min_check (G . R_d + g |R_d|)``,
    ``h[d] = min_slot max_check (G . R_d - g |R_d|)`` (pos: ``f >= 0``, neg: ``h <= 0``), one
    loop over the candidates per check (vectorised). A slot without checks passes both.
    """
    R0, R1, R2, R3 = R[0], R[1], R[2], R[3]
    for s in range(k):
        for j in range(c):
            g0, g1, g2, g3 = G[s, j, 0], G[s, j, 1], G[s, j, 2], G[s, j, 3]
            sl = g[s, j]
            if j == 0:
                for d in range(nR):
                    v = g0 * R0[d] + g1 * R1[d] + g2 * R2[d] + g3 * R3[d]
                    w = sl * Rn[d]
                    mn[d] = v + w
                    mx[d] = v - w
            else:
                for d in range(nR):
                    v = g0 * R0[d] + g1 * R1[d] + g2 * R2[d] + g3 * R3[d]
                    w = sl * Rn[d]
                    lo = v + w
                    hi = v - w
                    mn[d] = lo if lo < mn[d] else mn[d]
                    mx[d] = hi if hi > mx[d] else mx[d]
        if c == 0:
            for d in range(nR):
                mn[d] = np.inf
                mx[d] = -np.inf
        if s == 0:
            for d in range(nR):
                f[d] = mn[d]
                h[d] = mx[d]
        else:
            for d in range(nR):
                f[d] = mn[d] if mn[d] > f[d] else f[d]
                h[d] = mx[d] if mx[d] < h[d] else h[d]


@_jit(inline=True, fastmath=True)
def _slice_normal(x, n, pA, U, out, row, a):
    """Write ``U^T a / |a|`` to out[row], ``a = (lambda n + p_A x t, t)``, x = (lambda, t)."""
    a[0] = x[0] * n[0] + pA[1] * x[3] - pA[2] * x[2]
    a[1] = x[0] * n[1] + pA[2] * x[1] - pA[0] * x[3]
    a[2] = x[0] * n[2] + pA[0] * x[2] - pA[1] * x[1]
    a[3] = x[1]
    a[4] = x[2]
    a[5] = x[3]
    acc = 0.0
    for i in range(6):
        acc += a[i] * a[i]
    scale = 1.0 / np.sqrt(acc)
    for j in range(U.shape[1]):
        acc = 0.0
        for i in range(6):
            acc += U[i, j] * a[i]
        out[row, j] = acc * scale


@_jit(inline=True, fastmath=True)
def _slice_checks(n, dk, checks, mask, cone_tol, S, tol):
    """Write the check forms ``S`` (k, c, 4) of a face class and their slack (-inf: no slot)."""
    for s in range(S.shape[0]):
        for j in range(S.shape[1]):
            _slice_lift(n, dk, checks[s, j], S[s, j])
            tol[s, j] = cone_tol * _norm4(S[s, j]) if mask[s] else -np.inf


@_jit(fastmath=True)
def _slice_search(positions, An, Ac, Am, nA, whole, Bd, Bc, Bm, nB, pair, Cd, Cc, Cm, nC,
                  Dd, Dc, Dm, nD, legs, U, cone_tol, normal_tol, out_pos, out_neg):
    """
    Search the face choices of one pattern on slices (:func:`slice_facet_normals`).

    Leg tuples ``legs`` (T, 3 or 4): A (its facet classes, or all of Q_A when ``whole``),
    then the node legs and the candidate leg.

    ``pair``: the node is one facet class of leg B (its two directions, pattern (2, 2, 1)),
    or with ``whole`` one edge class of B with the wall lambda = 0 (3, 1, 1); else the node
    is an edge class of B and one of C (2, 1, 1, 1). The candidates are the edge classes of
    the last leg (D). Returns (pos rows, neg rows, choices), rows -1 when an output is full.
    """
    kA, cA = Ac.shape[2], Ac.shape[3]
    kB, cB = Bc.shape[2], Bc.shape[3]
    kC, cC = Cc.shape[2], Cc.shape[3]
    kD, cD = Dc.shape[2], Dc.shape[3]
    mD = Dd.shape[1]
    npos = 0
    nneg = 0
    choices = 0
    r1, r2, r3, x = np.empty(4), np.empty(4), np.empty(4), np.empty(4)
    P, a = np.empty(6), np.empty(6)
    dB, dC, dD = np.empty(3), np.empty(3), np.empty(3)
    zero, n = np.zeros(3), np.zeros(3)
    # Candidate columns padded to a multiple of 4 (zeros: whole vector iterations in
    # _slot_bounds; the padding is computed and never read).
    mP = (mD + 3) // 4 * 4
    R, Rn = np.zeros((4, mP)), np.zeros(mP)
    SA, tA = np.empty((kA, cA, 4)), np.empty((kA, cA))
    SB, tB = np.empty((Bd.shape[1], kB, cB, 4)), np.empty((Bd.shape[1], kB, cB))
    SC, tC = np.empty((Cd.shape[1], kC, cC, 4)), np.empty((Cd.shape[1], kC, cC))
    SD, tD = np.empty((mD, kD, cD, 4)), np.empty((mD, kD, cD))
    GB, gB = np.empty((kB, cB, 4)), np.empty((kB, cB))
    GC, gC = np.empty((kC, cC, 4)), np.empty((kC, cC))
    f1, h1, f2, h2 = np.empty(mP), np.empty(mP), np.empty(mP), np.empty(mP)
    mn, mx = np.empty(mP), np.empty(mP)
    for t in range(legs.shape[0]):
        A, B, C, D = legs[t, 0], legs[t, 1], legs[t, 2], legs[t, -1]
        pA = positions[A]
        for i in range(3):
            dB[i] = positions[B, i] - pA[i]
            dC[i] = positions[C, i] - pA[i]
            dD[i] = positions[D, i] - pA[i]
        for fa in range(nA[A]):
            if not whole:
                for i in range(3):
                    n[i] = An[A, fa, i]
            _slice_checks(n, zero, Ac[A, fa], Am[A, fa], cone_tol, SA, tA)
            for e in range(nD[D]):
                _slice_lift(n, dD, Dd[D, e, 0], r3)
                for i in range(4):
                    R[i, e] = r3[i]
                Rn[e] = _norm4(r3)
                _slice_checks(n, dD, Dc[D, e], Dm[D, e], cone_tol, SD[e], tD[e])
            for e in range(nB[B]):
                _slice_checks(n, dB, Bc[B, e], Bm[B, e], cone_tol, SB[e], tB[e])
            if not pair:
                for e in range(nC[C]):
                    _slice_checks(n, dC, Cc[C, e], Cm[C, e], cone_tol, SC[e], tC[e])
            for b in range(nB[B]):
                if pair and whole:
                    r1[0], r1[1], r1[2], r1[3] = 1.0, 0.0, 0.0, 0.0
                    _slice_lift(n, dB, Bd[B, b, 0], r2)
                elif pair:
                    _slice_lift(n, dB, Bd[B, b, 0], r1)
                    _slice_lift(n, dB, Bd[B, b, 1], r2)
                else:
                    _slice_lift(n, dB, Bd[B, b, 0], r1)
                for c in range(1 if pair else nC[C]):
                    choices += nD[D]
                    if not pair:
                        _slice_lift(n, dC, Cd[C, c, 0], r2)
                    nP = _plucker4(r1, r2, P)
                    if not nP > normal_tol * _norm4(r1) * _norm4(r2):
                        continue
                    # A check S of a node leg at x(r3): S . x = det[r1; r2; r3; S]
                    # = -cross4(P, S) . r3, a linear form G of the candidate wall r3.
                    for s in range(kB):
                        for j in range(cB):
                            _cross4(P, SB[b, s, j], GB[s, j])
                            for i in range(4):
                                GB[s, j, i] = -GB[s, j, i]
                            gB[s, j] = tB[b, s, j] * nP
                    if not pair:
                        for s in range(kC):
                            for j in range(cC):
                                _cross4(P, SC[c, s, j], GC[s, j])
                                for i in range(4):
                                    GC[s, j, i] = -GC[s, j, i]
                                gC[s, j] = tC[c, s, j] * nP
                    # The candidates: the node legs' checks first, as linear forms of the
                    # candidate wall, then leg A's and the candidate leg's at x.
                    nR = (nD[D] + 3) // 4 * 4
                    _slot_bounds(GB, gB, kB, cB, R, Rn, nR, f1, h1, mn, mx)
                    if not pair:
                        _slot_bounds(GC, gC, kC, cC, R, Rn, nR, f2, h2, mn, mx)
                    for d in range(nD[D]):
                        pos = f1[d] >= 0.0
                        neg = h1[d] <= 0.0
                        if not pair:
                            pos = pos and f2[d] >= 0.0
                            neg = neg and h2[d] <= 0.0
                        if not (pos or neg):
                            continue
                        for i in range(4):
                            r3[i] = R[i, d]
                        _cross4(P, r3, x)
                        nx = _norm4(x)
                        if not nx > normal_tol * nP * Rn[d]:       # rank-deficient choice
                            continue
                        pa, na = _slot_signs(SA, tA, kA, cA, x, nx)
                        pos = pos and pa
                        neg = neg and na
                        if not (pos or neg):
                            continue
                        pd, nd = _slot_signs(SD[d], tD[d], kD, cD, x, nx)
                        if pos and pd:
                            if npos == out_pos.shape[0]:
                                return -1, -1, choices
                            _slice_normal(x, n, pA, U, out_pos, npos, a)
                            npos += 1
                        if neg and nd:
                            if nneg == out_neg.shape[0]:
                                return -1, -1, choices
                            for i in range(4):
                                x[i] = -x[i]
                            _slice_normal(x, n, pA, U, out_neg, nneg, a)
                            nneg += 1
    return npos, nneg, choices


@_jit(fastmath=True)
def _slice_whole_facet(positions, Bd, Bc, Bm, nB, legs, U, cone_tol, normal_tol, out_pos,
                       out_neg):
    """
    Search the pattern (3, 2) on its slice (:func:`slice_facet_normals`).

    Leg A gives all of Q_A (the slice lambda = 0, no checks), leg B a facet class, whose two
    directions are the walls beside lambda = 0. Returns (pos rows, neg rows, choices), rows
    -1 when an output is full.
    """
    kB, cB = Bc.shape[2], Bc.shape[3]
    npos = 0
    nneg = 0
    choices = 0
    r1, r2, r3, x = np.empty(4), np.empty(4), np.empty(4), np.empty(4)
    P, a = np.empty(6), np.empty(6)
    dB, n = np.empty(3), np.zeros(3)
    SB, tB = np.empty((kB, cB, 4)), np.empty((kB, cB))
    r1[0], r1[1], r1[2], r1[3] = 1.0, 0.0, 0.0, 0.0
    for t in range(legs.shape[0]):
        A, B = legs[t, 0], legs[t, 1]
        pA = positions[A]
        for i in range(3):
            dB[i] = positions[B, i] - pA[i]
        for b in range(nB[B]):
            choices += 1
            _slice_lift(n, dB, Bd[B, b, 0], r2)
            _slice_lift(n, dB, Bd[B, b, 1], r3)
            nP = _plucker4(r1, r2, P)
            if not nP > normal_tol * _norm4(r2):
                continue
            _cross4(P, r3, x)
            nx = _norm4(x)
            if not nx > normal_tol * nP * _norm4(r3):
                continue
            _slice_checks(n, dB, Bc[B, b], Bm[B, b], cone_tol, SB, tB)
            pos, neg = _slot_signs(SB, tB, kB, cB, x, nx)
            if pos:
                if npos == out_pos.shape[0]:
                    return -1, -1, choices
                _slice_normal(x, n, pA, U, out_pos, npos, a)
                npos += 1
            if neg:
                if nneg == out_neg.shape[0]:
                    return -1, -1, choices
                for i in range(4):
                    x[i] = -x[i]
                _slice_normal(x, n, pA, U, out_neg, nneg, a)
                nneg += 1
    return npos, nneg, choices


#: The patterns :func:`slice_facet_normals` searches (r = 6).
SLICE_PATTERNS = ((2, 1, 1, 1), (2, 2, 1), (3, 1, 1), (3, 2))


def slice_facet_normals(positions: np.ndarray, U: np.ndarray, groups: dict, dims: tuple,
                        legs: np.ndarray, cone_tol: float,
                        normal_tol: float) -> tuple[np.ndarray, int]:
    """
    Return :func:`slice_facet_normal_parts`'s rows stacked (+ then -) and the choices.

    Over consecutive runs of ``legs``, stacking every run's + rows, then every run's - rows,
    gives the same array as one call (the facet search in steps).
    """
    plus, minus, choices = slice_facet_normal_parts(positions, U, groups, dims, legs,
                                                    cone_tol, normal_tol)
    return np.vstack([plus, minus]), choices


def slice_facet_normal_parts(positions: np.ndarray, U: np.ndarray, groups: dict, dims: tuple,
                             legs: np.ndarray, cone_tol: float, normal_tol: float
                             ) -> tuple[np.ndarray, np.ndarray, int]:
    r"""
    Return the unit normals (hull coordinates) of one pattern's face choices that pass (3).

    :mod:`awp_ros.geometry.minkowski_facets`, (5): the choices of leg A's face (a facet
    class, or all of Q_A) are searched on its slice, ``x = (lambda, t)`` in R^4; the node's
    two walls give ``P = r1 ^ r2``, every candidate wall ``r3`` the normal
    ``x = *(r1 ^ r2 ^ r3)``, and a check of a node leg is the linear form
    ``-*(r1 ^ r2 ^ s)`` of ``r3`` (one pass over the candidates per check). Check values
    pass within ``cone_tol`` times ``|s| |x|`` (the node legs': ``|s| |r1 ^ r2| |r3|``,
    a bound of it), in float64; choices with ``|x| <= normal_tol |r1 ^ r2| |r3|`` (or a
    node with ``|r1 ^ r2| <= normal_tol |r1| |r2|``) are rank-deficient and skipped.

    :param positions: (K, 3) feet relative to the CoM [m].
    :param U: (6, 6) orthonormal basis of the sum's hull (r = 6).
    :param groups: ``d -> (dirs (K, m, d, 3), checks (K, m, k, c, 3), mask (K, m, k),
        counts (K,))``, every leg's face classes of dimension ``d`` padded (counts 0: none).
    :param dims: the pattern, one of :data:`SLICE_PATTERNS`.
    :param legs: (T, len(dims)) leg tuples of the pattern.
    :return: ``(plus (N+, 6), minus (N-, 6), choices examined)``: the rows passing with the
        + sign and those passing with the - sign (negated), each in search order
        (:func:`slice_facet_normals` stacks them).
    """
    dims = tuple(dims)
    positions = np.ascontiguousarray(positions, dtype=float)
    U = np.ascontiguousarray(U, dtype=float)
    legs = np.ascontiguousarray(legs, dtype=np.int64)
    if dims == (3, 2):
        B = groups[2]
        cap = 256
        while True:
            out_pos = workspace('fws_slice_pos', (cap, 6))
            out_neg = workspace('fws_slice_neg', (cap, 6))
            npos, nneg, choices = _slice_whole_facet(positions, B[0], B[1], B[2], B[3], legs,
                                                     U, float(cone_tol), float(normal_tol),
                                                     out_pos, out_neg)
            if npos >= 0:
                return out_pos[:npos].copy(), out_neg[:nneg].copy(), int(choices)
            cap *= 4
    whole = dims[0] == 3
    A = groups[dims[0]]
    An = np.zeros(A[0].shape[:2] + (3,)) if whole else \
        np.ascontiguousarray(cross3(A[0][:, :, 0], A[0][:, :, 1]))
    B, C, D = groups[dims[1]], groups[dims[2]], groups[dims[-1]]
    pair = len(dims) == 3
    cap = 4096
    while True:
        out_pos = workspace('fws_slice_pos', (cap, 6))
        out_neg = workspace('fws_slice_neg', (cap, 6))
        npos, nneg, choices = _slice_search(
            positions, An, A[1], A[2], A[3], whole, B[0], B[1], B[2], B[3], pair,
            C[0], C[1], C[2], C[3], D[0], D[1], D[2], D[3], legs, U, float(cone_tol),
            float(normal_tol), out_pos, out_neg)
        if npos >= 0:
            return out_pos[:npos].copy(), out_neg[:nneg].copy(), int(choices)
        cap *= 4


# -- The FWS of two stance legs: a flat sum (minkowski_facets, (6)) ----------------------------
#
# Two legs' lifted polytopes span a hyperplane of R^6 (a force along the line through both feet
# is the same wrench from either); in its coordinates (r = 5) a facet takes faces whose
# dimensions add up to 4: a facet class of each leg (2, 2), or all of one leg and an edge class
# of the other (3, 1). Its normal a is the generalised cross product of the four lifted
# directions, a . y = det[v_1; v_2; v_3; v_4; y].

#: The columns left when column i of a (4, 5) matrix is dropped.
_COLS5 = np.array([[1, 2, 3, 4], [0, 2, 3, 4], [0, 1, 3, 4], [0, 1, 2, 4], [0, 1, 2, 3]])


@_jit(inline=True, fastmath=True)
def _row_pair_minors(V, r, c0, c1, c2, c3):
    """Return the 2x2 minors of rows r, r + 1 of V on columns (01, 02, 03, 12, 13, 23)."""
    return (V[r, c0] * V[r + 1, c1] - V[r, c1] * V[r + 1, c0],
            V[r, c0] * V[r + 1, c2] - V[r, c2] * V[r + 1, c0],
            V[r, c0] * V[r + 1, c3] - V[r, c3] * V[r + 1, c0],
            V[r, c1] * V[r + 1, c2] - V[r, c2] * V[r + 1, c1],
            V[r, c1] * V[r + 1, c3] - V[r, c3] * V[r + 1, c1],
            V[r, c2] * V[r + 1, c3] - V[r, c3] * V[r + 1, c2])


@_jit(inline=True, fastmath=True)
def _cross5(V, out):
    """Write a with ``a . y = det[V_0; V_1; V_2; V_3; y]`` (V (4, 5)) to out; return |a|."""
    acc = 0.0
    for i in range(5):
        c0, c1, c2, c3 = _COLS5[i, 0], _COLS5[i, 1], _COLS5[i, 2], _COLS5[i, 3]
        m01, m02, m03, m12, m13, m23 = _row_pair_minors(V, 0, c0, c1, c2, c3)
        n01, n02, n03, n12, n13, n23 = _row_pair_minors(V, 2, c0, c1, c2, c3)
        # Laplace along rows (0, 1): det = sum of signed products of complementary minors.
        d = m01 * n23 - m02 * n13 + m03 * n12 + m12 * n03 - m13 * n02 + m23 * n01
        out[i] = d if i % 2 == 0 else -d
        acc += d * d
    return np.sqrt(acc)


@_jit(inline=True, fastmath=True)
def _lift5(Mk, v, out):
    """Write ``M_k v`` (M_k (5, 3)) to out; return its norm."""
    acc = 0.0
    for i in range(5):
        out[i] = Mk[i, 0] * v[0] + Mk[i, 1] * v[1] + Mk[i, 2] * v[2]
        acc += out[i] * out[i]
    return np.sqrt(acc)


@_jit(inline=True, fastmath=True)
def _lifted_checks5(Mk, checks, mask, cone_tol, S, tol):
    """Write a class's lifted check vectors ``M_k m`` (k, c, 5) and slacks (-inf: no slot)."""
    for s in range(S.shape[0]):
        for j in range(S.shape[1]):
            norm = _lift5(Mk, checks[s, j], S[s, j])
            tol[s, j] = cone_tol * norm if mask[s] else -np.inf


@_jit(inline=True, fastmath=True)
def _slot_signs5(S, tol, a, na):
    """
    :func:`_slot_signs` in R^5: (pos, neg) of one leg's face class at a.

    A copy of its loops, not a call: the R^4 one keeps its dot product unrolled by hand in
    the slice search's innermost loop (10^4 candidates per FWS), left as it is; this one runs
    for about 100 choices per FWS.
    """
    f = -np.inf
    h = np.inf
    for s in range(S.shape[0]):
        mn = np.inf
        mx = -np.inf
        for j in range(S.shape[1]):
            v = 0.0
            for i in range(5):
                v += S[s, j, i] * a[i]
            w = tol[s, j] * na
            mn = min(mn, v + w)
            mx = max(mx, v - w)
        f = max(f, mn)
        h = min(h, mx)
    return f >= 0.0, h <= 0.0


@_jit(fastmath=True)
def _flat_pair_search(M, Ed, Ec, Em, nE, Fd, Fc, Fm, nF, cone_tol, normal_tol, out):
    """
    Search the face choices of two legs in their hyperplane (:func:`flat_pair_facet_normals`).

    Writes the passing unit normals to ``out`` (the + rows of each choice, then its - row)
    and returns ``(rows, choices)``.
    """
    V = np.empty((4, 5))
    a = np.empty(5)
    kE, cE = Ec.shape[2], Ec.shape[3]
    kF, cF = Fc.shape[2], Fc.shape[3]
    SE = np.empty((2, Ed.shape[1], kE, cE, 5))
    tE = np.empty((2, Ed.shape[1], kE, cE))
    SF = np.empty((2, Fd.shape[1], kF, cF, 5))
    tF = np.empty((2, Fd.shape[1], kF, cF))
    EV = np.empty((2, Ed.shape[1], 5))
    nEV = np.empty((2, Ed.shape[1]))
    FV = np.empty((2, Fd.shape[1], 2, 5))
    nFV = np.empty((2, Fd.shape[1], 2))
    WV = np.empty((2, 3, 5))
    nWV = np.empty((2, 3))
    e = np.zeros(3)
    for k in range(2):
        for i in range(nE[k]):
            nEV[k, i] = _lift5(M[k], Ed[k, i, 0], EV[k, i])
            _lifted_checks5(M[k], Ec[k, i], Em[k, i], cone_tol, SE[k, i], tE[k, i])
        for i in range(nF[k]):
            for j in range(2):
                nFV[k, i, j] = _lift5(M[k], Fd[k, i, j], FV[k, i, j])
            _lifted_checks5(M[k], Fc[k, i], Fm[k, i], cone_tol, SF[k, i], tF[k, i])
        for j in range(3):
            e[0], e[1], e[2] = 0.0, 0.0, 0.0
            e[j] = 1.0
            nWV[k, j] = _lift5(M[k], e, WV[k, j])
    rows = 0
    choices = 0
    # (2, 2): a facet class of each leg, both legs checked.
    for i in range(nF[0]):
        for j in range(nF[1]):
            choices += 1
            for q in range(5):
                V[0, q], V[1, q] = FV[0, i, 0, q], FV[0, i, 1, q]
                V[2, q], V[3, q] = FV[1, j, 0, q], FV[1, j, 1, q]
            na = _cross5(V, a)
            if not na > normal_tol * nFV[0, i, 0] * nFV[0, i, 1] * nFV[1, j, 0] * nFV[1, j, 1]:
                continue
            p0, m0 = _slot_signs5(SF[0, i], tF[0, i], a, na)
            if not (p0 or m0):
                continue
            p1, m1 = _slot_signs5(SF[1, j], tF[1, j], a, na)
            for sign, ok in ((1.0, p0 and p1), (-1.0, m0 and m1)):
                if ok:
                    for q in range(5):
                        out[rows, q] = sign * a[q] / na
                    rows += 1
    # (3, 1): all of leg w (no check: its normal cone is {0}), an edge class of the other.
    for w in range(2):
        o = 1 - w
        for i in range(nE[o]):
            choices += 1
            for q in range(5):
                V[0, q], V[1, q], V[2, q] = WV[w, 0, q], WV[w, 1, q], WV[w, 2, q]
                V[3, q] = EV[o, i, q]
            na = _cross5(V, a)
            if not na > normal_tol * nWV[w, 0] * nWV[w, 1] * nWV[w, 2] * nEV[o, i]:
                continue
            p1, m1 = _slot_signs5(SE[o, i], tE[o, i], a, na)
            for sign, ok in ((1.0, p1), (-1.0, m1)):
                if ok:
                    for q in range(5):
                        out[rows, q] = sign * a[q] / na
                    rows += 1
    return rows, choices


def flat_pair_facet_normals(M: np.ndarray, edges: tuple, facets: tuple, cone_tol: float,
                            normal_tol: float) -> tuple[np.ndarray, int]:
    r"""
    Return the unit facet normal candidates of the sum of two solid lifted legs, and the count.

    :mod:`awp_ros.geometry.minkowski_facets`, (6): in the coordinates ``y = U^T x`` of the two
    legs' hyperplane (r = 5, ``M`` (2, 5, 3) = ``U^T L_k``) the face choices are the patterns
    (2, 2) (a facet class of each leg) and (3, 1) (all of one leg, an edge class of the other);
    each choice's normal is the generalised cross product of its four lifted directions,
    ``a . y = det[v_1; v_2; v_3; v_4; y]``, kept with the sign + (-) when every check value
    ``(M_k m) . a`` of its faces is ``>= -`` (``<=``) ``cone_tol |M_k m| |a|`` for some slot
    of the class, in float64; ``|a| <= normal_tol`` times the product of the ``|v_i|`` is
    rank-deficient and skipped. Every tolerance only admits extra rows that are valid
    supporting halfspaces once the caller sets their offsets (the support function).

    :param edges: ``(dirs (2, m, 1, 3), checks (2, m, k, c, 3), mask (2, m, k), counts (2,))``,
        the legs' edge classes padded (``minkowski_facets._padded_groups``); ``facets``
        likewise with ``dirs (2, m, 2, 3)``.
    :return: ``(rows (N, 5), choices examined)``.
    """
    M = np.ascontiguousarray(M, dtype=float)
    Ed, Ec, Em, nE = edges
    Fd, Fc, Fm, nF = facets
    cap = 2 * (int(nF[0]) * int(nF[1]) + int(nE[0]) + int(nE[1]))
    out = np.empty((max(cap, 1), 5))
    rows, choices = _flat_pair_search(
        M, np.ascontiguousarray(Ed, dtype=float), np.ascontiguousarray(Ec, dtype=float),
        np.ascontiguousarray(Em), np.ascontiguousarray(nE, dtype=np.int64),
        np.ascontiguousarray(Fd, dtype=float), np.ascontiguousarray(Fc, dtype=float),
        np.ascontiguousarray(Fm), np.ascontiguousarray(nF, dtype=np.int64), float(cone_tol),
        float(normal_tol), out)
    return out[:rows].copy(), int(choices)


@_jit
def _first_of_equal_rows(X, scale):
    """Open addressing on the rows rounded to integers (:func:`first_of_equal_rows`)."""
    n, m = X.shape
    q = np.empty((n, m), dtype=np.int64)
    for i in range(n):
        for j in range(m):
            q[i, j] = np.int64(np.rint(X[i, j] * scale))
    size = 16
    while size < 2 * n:
        size *= 2
    table = np.full(size, -1, dtype=np.int64)
    first = np.empty(n, dtype=np.int64)
    count = 0
    for i in range(n):
        h = np.uint64(1469598103934665603)
        for j in range(m):
            h = (h ^ np.uint64(q[i, j])) * np.uint64(1099511628211)
        slot = np.int64(h & np.uint64(size - 1))
        while True:
            k = table[slot]
            if k < 0:
                table[slot] = i
                first[count] = i
                count += 1
                break
            same = True
            for j in range(m):
                if q[k, j] != q[i, j]:
                    same = False
                    break
            if same:
                break
            slot = (slot + 1) & (size - 1)
    return first[:count].copy()


def first_of_equal_rows(X: np.ndarray, decimals: int) -> np.ndarray:
    """
    Return the indices (increasing) of the first of each group of rows equal after rounding.

    Rows equal after ``np.rint(X * 10**decimals)`` form a group; one pass with a hash table
    of the rounded rows (open addressing, whole rows compared on a hash match). The numpy
    form: ``np.sort(np.unique(np.rint(X * 10**decimals), axis=0, return_index=True)[1])``.
    """
    X = np.ascontiguousarray(X, dtype=float)
    if X.ndim != 2 or X.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    return _first_of_equal_rows(X, float(10.0 ** decimals))


@_jit
def _batched_vertices(A, b, tri, eps, det_tol, V, starts, facet, full):
    """Cramer's rule on every row triple of every leg (:func:`batched_vertices`)."""
    K, m = A.shape[0], A.shape[1]
    T = tri.shape[0]
    X = np.empty((T, 3))
    keys = np.empty(T, dtype=np.int64)
    x = np.empty(3)
    n = 0
    for k in range(K):
        starts[k] = n
        count = 0
        for t in range(T):
            i, j, q = tri[t, 0], tri[t, 1], tri[t, 2]
            # a_j x a_q, a_q x a_i, a_i x a_j
            c00 = A[k, j, 1] * A[k, q, 2] - A[k, j, 2] * A[k, q, 1]
            c01 = A[k, j, 2] * A[k, q, 0] - A[k, j, 0] * A[k, q, 2]
            c02 = A[k, j, 0] * A[k, q, 1] - A[k, j, 1] * A[k, q, 0]
            det = A[k, i, 0] * c00 + A[k, i, 1] * c01 + A[k, i, 2] * c02
            if not abs(det) > det_tol:
                continue
            c10 = A[k, q, 1] * A[k, i, 2] - A[k, q, 2] * A[k, i, 1]
            c11 = A[k, q, 2] * A[k, i, 0] - A[k, q, 0] * A[k, i, 2]
            c12 = A[k, q, 0] * A[k, i, 1] - A[k, q, 1] * A[k, i, 0]
            c20 = A[k, i, 1] * A[k, j, 2] - A[k, i, 2] * A[k, j, 1]
            c21 = A[k, i, 2] * A[k, j, 0] - A[k, i, 0] * A[k, j, 2]
            c22 = A[k, i, 0] * A[k, j, 1] - A[k, i, 1] * A[k, j, 0]
            bi, bj, bq = b[k, i], b[k, j], b[k, q]
            x[0] = (bi * c00 + bj * c10 + bq * c20) / det
            x[1] = (bi * c01 + bj * c11 + bq * c21) / det
            x[2] = (bi * c02 + bj * c12 + bq * c22) / det
            key = np.int64(0)
            feasible = True
            for r in range(m):
                slack = b[k, r] - (A[k, r, 0] * x[0] + A[k, r, 1] * x[1] + A[k, r, 2] * x[2])
                if slack < -eps[k]:
                    feasible = False
                    break
                if slack <= eps[k]:
                    key |= np.int64(1) << r
            if not feasible:
                continue
            X[count] = x
            keys[count] = key
            count += 1
        # One vertex per tight-row set, the first candidate of each, in increasing key order.
        order = np.argsort(keys[:count], kind='mergesort')
        for r in range(m):
            facet[k, r] = False
        rows = np.zeros(m, dtype=np.int64)
        nv = 0
        for u in range(count):
            o = order[u]
            if u > 0 and keys[o] == keys[order[u - 1]]:
                continue
            V[n + nv] = X[o]
            for r in range(m):
                if (keys[o] >> r) & 1:
                    rows[r] += 1
            nv += 1
        most = 0
        for r in range(m):
            facet[k, r] = rows[r] >= 3
            most = max(most, rows[r])
        full[k] = nv >= 4 and most < nv
        n += nv
    starts[K] = n


def batched_vertices(A: np.ndarray, b: np.ndarray, tri: np.ndarray, eps: np.ndarray,
                     det_tol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """
    Return the vertices of K polytopes ``{f : A_k f <= b_k}`` of R^3 by Cramer's rule.

    The batched vertex enumeration of the friction-bounded polytopes
    (:func:`awp_ros.wrench.friction_polytope.friction_polytopes`, whose numpy code is the
    reference): for every row triple ``(i, j, q)`` of ``tri`` with ``|det| > det_tol``,
    ``x = (b_i a_j x a_q + b_j a_q x a_i + b_q a_i x a_j) / (a_i . a_j x a_q)`` is a vertex
    when no slack is below ``-eps_k``; the rows with ``|slack| <= eps_k`` are tight, and one
    vertex is kept per set of tight rows (the first triple's, sets in increasing bit order).

    :param A: (K, m, 3) unit rows, ``m <= 63``; :param b: (K, m); :param tri: (T, 3) row
        triples; :param eps: (K,) feasibility tolerances.
    :return: ``(V (n, 3), starts (K + 1,), facet (K, m), full (K,))``: leg k's vertices are
        ``V[starts[k]:starts[k + 1]]``, ``facet`` its rows tight at 3 vertices or more,
        ``full`` whether it has 4 vertices or more and no row tight at all of them.
    """
    A = np.ascontiguousarray(A, dtype=float)
    K = A.shape[0]
    V = np.empty((K * max(tri.shape[0], 1), 3))
    starts = np.empty(K + 1, dtype=np.int64)
    facet = np.empty((K, A.shape[1]), dtype=np.bool_)
    full = np.empty(K, dtype=np.bool_)
    _batched_vertices(A, np.ascontiguousarray(b, dtype=float),
                      np.ascontiguousarray(tri, dtype=np.int64),
                      np.ascontiguousarray(eps, dtype=float), float(det_tol), V, starts,
                      facet, full)
    return V[:starts[K]], starts, facet, full


@_jit
def _inside_forces(V, A, b, rows, margin):
    K, nv = V.shape[0], V.shape[1]
    m, nr = A.shape[1], rows.shape[1]
    out = np.zeros(K, dtype=np.bool_)
    for k in range(K):
        for i in range(nv):                  # a vertex strictly inside every pyramid plane
            inside = True
            for r in range(nr):
                s = V[k, i, 0] * rows[k, r, 0] + V[k, i, 1] * rows[k, r, 1] \
                    + V[k, i, 2] * rows[k, r, 2]
                if not s < -margin:
                    inside = False
                    break
            if inside:
                out[k] = True
                break
        if out[k]:
            continue
        n0, n1, n2 = -rows[k, nr - 1, 0], -rows[k, nr - 1, 1], -rows[k, nr - 1, 2]
        lo = -np.inf                         # the axis t n: every pyramid row below -margin
        proper = True
        for r in range(nr):
            rn = rows[k, r, 0] * n0 + rows[k, r, 1] * n1 + rows[k, r, 2] * n2
            if not rn < 0.0:
                proper = False
                break
            lo = max(lo, margin / -rn)
        if not proper:
            continue
        hi = np.inf                          # ... and inside A f <= b (three ratio tests)
        for r in range(m):
            an = A[k, r, 0] * n0 + A[k, r, 1] * n1 + A[k, r, 2] * n2
            if an > 0.0:
                hi = min(hi, b[k, r] / an)
            elif an < 0.0:
                lo = max(lo, b[k, r] / an)
            elif b[k, r] < 0.0:
                proper = False
        out[k] = proper and lo < hi
    return out


def inside_forces(V: np.ndarray, A: np.ndarray, b: np.ndarray, rows: np.ndarray,
                  margin: float) -> np.ndarray:
    """
    Return :func:`awp_ros.wrench.friction_polytope.inside_force` of K full-dimensional legs.

    The same two tests, in the same order, on the legs' stacked vertices ``V`` (K, n_v, 3)
    and H-reps ``A`` (K, m, 3), ``b`` (K, m) [N] (the batched parallelepipeds), with the
    pyramid ``rows`` (K, N + 1, 3): a vertex with every row ``< -margin``, else the axis
    ``t n_k`` (``n_k = -rows_k[-1]``), whose interval of ``t`` is three ratio tests.
    """
    return _inside_forces(np.ascontiguousarray(V, dtype=float),
                          np.ascontiguousarray(A, dtype=float),
                          np.ascontiguousarray(b, dtype=float),
                          np.ascontiguousarray(rows, dtype=float), float(margin))


# -- one control cycle's sets and regions, each in one call -----------------------------------


@_jit
def _cycle_sets(J, bias, tau_min, tau_max, singular_rtol, P, rays, ray_certify, subsets,
                others, zero_tol, certify, rank_tol, incidence_tol, spans, masks, reuse,
                side_tol, cone_rank_tol, cap, rows, inside_margin, w, interior_tol):
    """See :func:`cycle_sets`."""
    center, G, V, FA, Fb, ratio = _parallelepipeds(J, bias, tau_min, tau_max, singular_rtol)
    proven = _inside_forces(V, FA, Fb, rows, inside_margin)
    e6 = np.empty((0, 6))
    singular = False
    for k in range(P.shape[0]):
        if not ratio[k] > singular_rtol:
            singular = True
    # The cone first: its rows follow the AWP's in the zonotope's buffer (the FWP's rows).
    lifted, full = _lifted_rays(P, rays, ray_certify)
    Ac, reused, cone_ok = e6, False, True
    if not singular and full and reuse:
        Ac, reused = _cone_recheck(lifted, spans, masks, side_tol, cone_rank_tol)
    if not singular and full and not reused:
        Ac, spans, masks, cone_ok = _cone_dd(lifted, side_tol, cone_rank_tol, cap)
        if not cone_ok:
            Ac = e6
    Af, bf, c, ok = _lifted_zonotope(P, center, G, subsets, others, zero_tol, certify,
                                     rank_tol, incidence_tol, Ac)
    status = 1 if singular else 2 if not ok else 3 if not full else 4 if not cone_ok else 0
    m2 = Ac.shape[0]
    m1 = Af.shape[0] - m2 if ok else 0
    # The margins' slack ``b - A w`` at its first smallest row (:func:`slack_min`), AWP
    # and FWP; and the FWP's interior test of
    # :func:`awp_ros.wrench.wrench_polytope.feasible_wrench_polytope` (the AWP's centre
    # strictly inside the CWC, else 0 strictly inside the AWP).
    i_awp, s_awp, i_fwp, s_fwp, interior = -1, np.inf, -1, np.inf, False
    if status == 0:
        i_awp, s_awp = _slack_min(Af, bf, w, 0, m1)
        i_cwc, s_cwc = _slack_min(Af, bf, w, m1, m1 + m2)
        i_fwp, s_fwp = (i_awp, s_awp) if not s_cwc < s_awp else (i_cwc, s_cwc)
        # (b - A 0 = b: the least slack of 0 is the least offset.)
        interior = _slack_min(Af, bf, c, m1, m1 + m2)[1] > interior_tol \
            or (m1 == 0 or bf[:m1].min() > interior_tol)
    return (status, (center, G, V, FA, Fb, ratio), proven, (Af[:m1], bf[:m1], c),
            (lifted, Ac, spans, masks, reused), (Af, bf),
            (i_awp, s_awp, i_fwp, s_fwp, interior))


def cycle_sets(J: np.ndarray, bias: np.ndarray, tau_min: np.ndarray, tau_max: np.ndarray,
               singular_rtol: float, positions: np.ndarray, rays: np.ndarray,
               ray_certify: float, subsets: np.ndarray, others: np.ndarray, zero_tol: float,
               certify: float, rank_tol: float, incidence_tol: float,
               last: tuple[np.ndarray, np.ndarray] | None, side_tol: float,
               cone_rank_tol: float, rows: np.ndarray, inside_margin: float,
               wrench: np.ndarray, interior_tol: float) -> tuple:
    r"""
    Return a control cycle's wrench sets of K >= 3 three-joint legs in one compiled call.

    The kernels of the per-cycle stages, called in their order without Python between them:
    :func:`parallelepipeds` (``J`` (K, 3, 3), ``bias``, ``tau_min``, ``tau_max`` (K, 3)),
    :func:`inside_forces` (the pyramid ``rows`` (K, N + 1, 3), ``inside_margin`` [N]),
    :func:`lifted_zonotope` (the AWP: feet ``positions`` (K, 3) [m], ``subsets`` and
    ``others`` of the 3K generators as :func:`lifted_zonotope` takes them, the zonotope
    tolerances), :func:`lifted_rays` (the
    pyramids' ``rays`` (K, N, 3), ``ray_certify``), then the CWC's facets by
    :func:`cone_recheck` of the ``last`` cone's ``(spans, masks)`` when given, else (or when
    it fails) by :func:`cone_double_description`; and the FWP's rows ``[A_awp; A_cwc]``,
    ``[b_awp; 0]`` (:func:`awp_ros.wrench.wrench_polytope.feasible_wrench_polytope`'s order),
    written by :func:`lifted_zonotope` after the AWP's in one buffer (the AWP's rows are a
    view of the FWP's: no copy). Then the margins' inside test at ``wrench`` [N, N.m]:
    :func:`slack_min` of the AWP and of the FWP; and the FWP's interior test (the AWP's
    centre ``c`` with slack above ``interior_tol`` in the CWC, else 0 in the AWP). Each
    result is the kernel's own, bit for bit.

    :return: ``(status, legs, proven, awp, cwc, fwp, slacks)``: ``legs`` the
        parallelepipeds' ``(center, generators, vertices, A, b, sigma_ratio)``; ``proven``
        (K,) bool; ``awp`` ``(A, b, c)``; ``cwc`` ``(lifted rays, A, spans, masks,
        reused)``; ``fwp`` ``(A, b)``; ``slacks`` ``(i_awp, s_awp, i_fwp, s_fwp,
        interior)``. ``status`` 0 when all hold, else the first that failed: 1 a leg at or
        below ``singular_rtol``, 2 the AWP not certified full-dimensional, 3 the rays not
        full rank, 4 the double description failed (the later results are then empty or
        partial: the caller takes the general code).
    """
    spans, masks = last if last is not None else (np.zeros((0, 5), dtype=np.int64),
                                                  np.zeros(0, dtype=np.int64))
    return _cycle_sets(np.ascontiguousarray(J, dtype=float),
                       np.ascontiguousarray(bias, dtype=float),
                       np.ascontiguousarray(tau_min, dtype=float),
                       np.ascontiguousarray(tau_max, dtype=float), float(singular_rtol),
                       np.ascontiguousarray(positions, dtype=float),
                       np.ascontiguousarray(rays, dtype=float), float(ray_certify),
                       np.ascontiguousarray(subsets, dtype=np.int64),
                       _complements(subsets, 3 * len(positions), others), float(zero_tol),
                       float(certify), float(rank_tol), float(incidence_tol),
                       np.ascontiguousarray(spans, dtype=np.int64),
                       np.ascontiguousarray(masks, dtype=np.int64), last is not None,
                       float(side_tol), float(cone_rank_tol), 1024,
                       np.ascontiguousarray(rows, dtype=float), float(inside_margin),
                       np.ascontiguousarray(wrench, dtype=float), float(interior_tol))


@_jit
def _cycle_regions(cwc_A, fwp_A, fwp_b, force_A, force_b, rows, P, w, tol, parallel, h_min,
                   max_lps):
    """See :func:`cycle_regions`."""
    support = _wrench_slice(cwc_A, np.zeros(cwc_A.shape[0]), w, tol, parallel, h_min)
    G, leg, status = _lifted_leg_points(force_A, force_b, rows, P)
    feasible = _feasible_region_of_points(G, leg, force_A.shape[0], status, w, tol, max_lps)
    fwp = _wrench_slice(fwp_A, fwp_b, w, tol, parallel, h_min)
    return support, feasible, fwp, (G, leg, status)


def cycle_regions(cwc_A: np.ndarray, fwp_A: np.ndarray, fwp_b: np.ndarray,
                  force_A: np.ndarray, force_b: np.ndarray, rows: np.ndarray,
                  positions: np.ndarray, wrench: np.ndarray, tol: float, parallel: float,
                  h_min: float, max_lps: int = 400) -> tuple:
    """
    Return a control cycle's three CoM regions' kernels in one compiled call.

    :func:`wrench_slice` of the CWC (``cwc_A``, ``b = 0``), :func:`feasible_region` of the
    legs (``force_A`` (K, 6, 3), ``force_b``, the pyramid ``rows``, the feet ``positions``)
    and :func:`wrench_slice` of the FWP (``fwp_A``, ``fwp_b``), at ``wrench`` [N, N.m], in
    this order, each the kernel's own result, and last the legs' lifted points the feasible
    region was projected from, ``(G (6, n), leg (n,), status)``
    (:func:`directional_margins_of_points` takes them): ``(support, feasible, fwp, points)``.
    """
    return _cycle_regions(np.ascontiguousarray(cwc_A, dtype=float),
                          np.ascontiguousarray(fwp_A, dtype=float),
                          np.ascontiguousarray(fwp_b, dtype=float),
                          np.ascontiguousarray(force_A, dtype=float),
                          np.ascontiguousarray(force_b, dtype=float),
                          np.ascontiguousarray(rows, dtype=float),
                          np.ascontiguousarray(positions, dtype=float),
                          np.ascontiguousarray(wrench, dtype=float), float(tol),
                          float(parallel), float(h_min), int(max_lps))


@_jit(inline=True)
def _slack_min(A, b, w, start, stop):
    """Return the first row ``i`` in ``[start, stop)`` of least ``b_i - A_i . w``, and it."""
    best, at = np.inf, -1
    if A.shape[1] == 6:                  # unrolled: the same sums, in the same order
        w0, w1, w2, w3, w4, w5 = w[0], w[1], w[2], w[3], w[4], w[5]
        for i in range(start, stop):
            acc = b[i] - A[i, 0] * w0 - A[i, 1] * w1 - A[i, 2] * w2 - A[i, 3] * w3 \
                - A[i, 4] * w4 - A[i, 5] * w5
            if acc < best:
                best, at = acc, i
    else:
        for i in range(start, stop):
            acc = b[i]
            for c in range(A.shape[1]):
                acc -= A[i, c] * w[c]
            if acc < best:
                best, at = acc, i
    if at < 0 and stop > start:          # every slack +inf or NaN: the first row's
        at = start
        best = b[start]
        for c in range(A.shape[1]):
            best -= A[start, c] * w[c]
    return at, best


@_jit
def _slack_min_of(A, b, w):
    return _slack_min(A, b, w, 0, A.shape[0])


def slack_min(A: np.ndarray, b: np.ndarray, w: np.ndarray) -> tuple[int, float]:
    r"""
    Return ``(i, s_i)``: the first row of least slack ``s = b - A w`` of ``A x <= b``.

    ``s_i = b_i - sum_c A_ic w_c``, summed in this order (the per-cycle path computes its
    margins' slacks with the same code, so both give the same bits); ``(-1, inf)`` without
    rows. The inside test of :func:`awp_ros.geometry.margin.polytope_margin` and of the
    FWP's interior (:func:`awp_ros.wrench.wrench_polytope.feasible_wrench_polytope`).
    """
    i, s = _slack_min_of(np.ascontiguousarray(A, dtype=float),
                         np.ascontiguousarray(b, dtype=float),
                         np.ascontiguousarray(w, dtype=float))
    return int(i), float(s)


@_jit(fastmath=True)
def _ratio_test(A, b, w, D, feasibility_tol, parallel_tol, t_hi, t_lo, empty):
    """Run the ratio test, a branch-free pass over the rows per direction (:func:`ratio_test`)."""
    m, n = A.shape
    s = np.empty(m)
    for i in range(m):
        acc = b[i]
        for c in range(n):
            acc -= A[i, c] * w[c]
        s[i] = acc
    for j in range(D.shape[0]):
        d = D[j]
        hi = np.inf
        lo = -np.inf
        bad = 0.0
        for i in range(m):
            g = 0.0
            for c in range(n):
                g += d[c] * A[i, c]
            r = s[i] / (g if g != 0.0 else 1.0)
            hi = min(hi, r if g > parallel_tol else np.inf)
            lo = max(lo, r if g < -parallel_tol else -np.inf)
            flat = abs(g) <= parallel_tol and s[i] < -feasibility_tol
            bad = max(bad, 1.0 if flat else 0.0)
        t_hi[j] = hi
        t_lo[j] = -lo
        empty[j] = bad > 0.0 or lo > hi + feasibility_tol


def ratio_test(A: np.ndarray, b: np.ndarray, w: np.ndarray, D: np.ndarray,
               feasibility_tol: float, parallel_tol: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return ``(t_plus, t_minus, empty)`` of the lines ``w + t D_j`` in ``{x : A x <= b}``.

    The ratio test of :func:`~awp_ros.geometry.margin.directional_margins` in one pass over
    the rows: with ``s = b - A w`` and ``g = A_i . D_j``, ``t_plus_j = min s_i / g`` over the
    rows with ``g > parallel_tol``, ``-t_minus_j = max s_i / g`` over those with
    ``g < -parallel_tol``; ``empty_j`` when ``-t_minus_j > t_plus_j + feasibility_tol`` or
    a row parallel to ``D_j`` has ``s_i < -feasibility_tol``. The numpy form is
    :func:`awp_ros.geometry.margin.line_interval` on ``s`` and ``D A^T``.
    """
    A = np.ascontiguousarray(A, dtype=float)
    D = np.ascontiguousarray(D, dtype=float)
    k = D.shape[0]
    t_hi, t_lo, empty = np.empty(k), np.empty(k), np.empty(k, dtype=np.bool_)
    _ratio_test(A, np.ascontiguousarray(b, dtype=float), np.ascontiguousarray(w, dtype=float),
                D, float(feasibility_tol), float(parallel_tol), t_hi, t_lo, empty)
    return t_hi, t_lo, empty


@_jit(inline=True)
def _line_rows(a, beta, sign, f0, u, tol, parallel_tol, bounds):
    """
    Cut ``bounds = [lo, hi]`` by the row ``sign a . (f0 + s u) <= beta`` (unit in ``a``).

    Returns False when the row is parallel to ``u`` (``|a . u| <= parallel_tol |a|``) and
    fails by more than ``tol`` (every ``s`` fails it).
    """
    na = np.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    g = sign * (a[0] * u[0] + a[1] * u[1] + a[2] * u[2]) / na
    r = (beta - sign * (a[0] * f0[0] + a[1] * f0[1] + a[2] * f0[2])) / na
    if abs(g) <= parallel_tol:
        return r >= -tol
    if g > 0.0:
        bounds[1] = min(bounds[1], r / g)
    else:
        bounds[0] = max(bounds[0], r / g)
    return True


@_jit
def _two_leg_contains(P, A, b, R, w, hull_tol, tol, parallel_tol, feet_apart):
    """Return 1 / 0 (in / not in the FWS of two legs), -1 without a hyperplane."""
    p1, p2 = P[0], P[1]
    d = p2 - p1
    dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    if not dd > feet_apart * feet_apart:
        return -1
    nu = _pair_normal(P)
    nn = 0.0
    nw = 0.0
    for i in range(6):
        nn += nu[i] * nu[i]
        nw += nu[i] * w[i]
    off = nw / nn
    if abs(off) * np.sqrt(nn) > hull_tol:
        return 0
    F = w[:3] - off * nu[:3]
    tau = w[3:] - off * nu[3:]
    g = np.empty(3)
    g[0] = tau[0] - (p1[1] * F[2] - p1[2] * F[1])
    g[1] = tau[1] - (p1[2] * F[0] - p1[0] * F[2])
    g[2] = tau[2] - (p1[0] * F[1] - p1[1] * F[0])
    f2 = np.empty(3)                       # (g x d) / |d|^2: d x f2 = g
    f2[0] = (g[1] * d[2] - g[2] * d[1]) / dd
    f2[1] = (g[2] * d[0] - g[0] * d[2]) / dd
    f2[2] = (g[0] * d[1] - g[1] * d[0]) / dd
    u = d / np.sqrt(dd)
    f1 = F - f2                            # leg 1 takes F - f2 - s u: its rows with sign -1
    bounds = np.array([-np.inf, np.inf])
    for i in range(A.shape[1]):
        if not (_line_rows(A[1, i], b[1, i], 1.0, f2, u, tol, parallel_tol, bounds)
                and _line_rows(A[0, i], b[0, i], -1.0, -f1, u, tol, parallel_tol, bounds)):
            return 0
    for i in range(R.shape[1]):
        if not (_line_rows(R[1, i], 0.0, 1.0, f2, u, tol, parallel_tol, bounds)
                and _line_rows(R[0, i], 0.0, -1.0, -f1, u, tol, parallel_tol, bounds)):
            return 0
    return 1 if bounds[0] <= bounds[1] + tol else 0


def two_leg_contains(positions: np.ndarray, force_A: np.ndarray, force_b: np.ndarray,
                     pyramid_rows: np.ndarray, w: np.ndarray, hull_tol: float, tol: float,
                     parallel_tol: float, feet_apart: float) -> int:
    """
    Return :func:`awp_ros.wrench.fws_queries.two_leg_contains` in one call: 1, 0, -1 (None).

    The same one-dimensional LP, its ratio test over the legs' rows normalised on the fly
    (its numpy form there is the reference).
    """
    return int(_two_leg_contains(
        np.ascontiguousarray(positions, dtype=float), np.ascontiguousarray(force_A, dtype=float),
        np.ascontiguousarray(force_b, dtype=float),
        np.ascontiguousarray(pyramid_rows, dtype=float), np.ascontiguousarray(w, dtype=float),
        float(hull_tol), float(tol), float(parallel_tol), float(feet_apart)))


# -- The nearest point of the FWS to a wrench outside it (Wolfe's algorithm) -------------------
#
# S = sum_k conv{g_kj}, the legs' lifted points; y = s - w ranges over S - w. The oracle
# q(x) = argmin_{y in S - w} x . y is one argmin per leg; a corral of affinely independent
# atoms (points of S - w) carries x, the nearest point to 0 of their affine hull, with weights
# lam > 0 (Wolfe 1976; awp_ros.wrench.fws_queries.fws_distance has the equations).


@_jit(inline=True)
def _sum_oracle(G, starts, K, x, w, out):
    """Write ``q = argmin_{y in S - w} x . y`` (each leg's argmin, summed, minus w) to out."""
    for i in range(6):
        out[i] = -w[i]
    for k in range(K):
        best, at = np.inf, starts[k]
        for j in range(starts[k], starts[k + 1]):
            v = x[0] * G[0, j] + x[1] * G[1, j] + x[2] * G[2, j] + x[3] * G[3, j] \
                + x[4] * G[4, j] + x[5] * G[5, j]
            if v < best:
                best, at = v, j
        for i in range(6):
            out[i] += G[i, at]


@_jit(inline=True)
def _affine_minimiser(Y, m, alpha, Q, R, rank_tol):
    r"""
    Write the affine weights ``alpha`` of the nearest point to 0 of ``aff(Y[:m])``.

    .. math:: d_j = y_j - y_0 = Q R, \quad R \beta = -Q^T y_0, \quad
              \alpha = (1 - 1^T \beta,\ \beta)

    (Gram-Schmidt twice on the ``m - 1 <= 6`` columns ``d_j``). Return False when the atoms
    are affinely dependent: a column's residual at most ``rank_tol`` times its length.
    """
    n = m - 1
    for j in range(n):
        norm0 = 0.0
        for i in range(6):
            Q[i, j] = Y[j + 1, i] - Y[0, i]
            norm0 += Q[i, j] * Q[i, j]
        norm0 = np.sqrt(norm0)
        for c in range(j):
            R[c, j] = 0.0
        for _ in range(2):                 # twice is enough (Kahan-Parlett)
            for c in range(j):
                dot = 0.0
                for i in range(6):
                    dot += Q[i, c] * Q[i, j]
                R[c, j] += dot
                for i in range(6):
                    Q[i, j] -= dot * Q[i, c]
        norm = 0.0
        for i in range(6):
            norm += Q[i, j] * Q[i, j]
        norm = np.sqrt(norm)
        if norm == 0.0 or norm <= rank_tol * norm0:
            return False
        R[j, j] = norm
        for i in range(6):
            Q[i, j] /= norm
    total = 0.0
    for j in range(n - 1, -1, -1):         # back substitution
        acc = 0.0
        for i in range(6):
            acc -= Q[i, j] * Y[0, i]
        for c in range(j + 1, n):
            acc -= R[j, c] * alpha[c + 1]
        alpha[j + 1] = acc / R[j, j]
        total += alpha[j + 1]
    alpha[0] = 1.0 - total
    return True


@_jit(inline=True)
def _corral_point(Y, lam, m, x):
    """Write ``x = sum_i lam_i Y[i]`` and return ``|x|^2``."""
    xx = 0.0
    for i in range(6):
        acc = 0.0
        for c in range(m):
            acc += lam[c] * Y[c, i]
        x[i] = acc
        xx += acc * acc
    return xx


@_jit
def _min_norm_point(G, leg, K, w, tol, floor, max_iter):
    """See :func:`min_norm_point`."""
    nearest = np.full(6, np.nan)
    starts = np.zeros(K + 1, dtype=np.int64)
    for j in range(G.shape[1]):
        starts[leg[j] + 1] += 1
    for k in range(K):
        if starts[k + 1] == 0:
            return np.inf, nearest, np.inf, 0, 3
        starts[k + 1] += starts[k]
    Y, lam, alpha = np.empty((7, 6)), np.empty(7), np.empty(7)
    Q, R = np.empty((6, 6)), np.zeros((6, 6))
    x, q = np.zeros(6), np.empty(6)
    # The first atom: the point of S - w farthest towards w from the legs' mean points' sum.
    for j in range(G.shape[1]):
        size = starts[leg[j] + 1] - starts[leg[j]]
        for i in range(6):
            x[i] += G[i, j] / size
    for i in range(6):
        x[i] -= w[i]
    _sum_oracle(G, starts, K, x, w, q)
    Y[0] = q
    lam[0] = 1.0
    m = 1
    xx = _corral_point(Y, lam, m, x)
    bound = np.inf
    status, iterations = 1, 0
    while iterations < max_iter:
        iterations += 1
        norm = np.sqrt(xx)
        if norm <= tol:                   # w is in S, to tol
            bound, status = norm, 0
            break
        _sum_oracle(G, starts, K, x, w, q)
        gap = xx
        for i in range(6):
            gap -= x[i] * q[i]
        bound = min(gap / norm, norm)
        if gap / norm <= tol or gap <= floor:
            status = 0
            break
        if m == 7:                        # seven atoms span R^6: x = 0 unless rounding
            status = 2
            break
        Y[m] = q
        lam[m] = 0.0
        m += 1
        dependent = False
        while True:                       # the minor cycle
            if not _affine_minimiser(Y, m, alpha, Q, R, 1e-12):
                dependent = True
                break
            positive = True
            for i in range(m):
                positive = positive and alpha[i] > 1e-14
            if positive:
                for i in range(m):
                    lam[i] = alpha[i]
                break
            # Move from lam towards alpha until a weight vanishes; drop those atoms.
            theta = 1.0
            for i in range(m):
                if alpha[i] <= 1e-14 and lam[i] - alpha[i] > 0.0:
                    theta = min(theta, lam[i] / (lam[i] - alpha[i]))
            smallest = 0
            for i in range(m):
                lam[i] = (1.0 - theta) * lam[i] + theta * alpha[i]
                if lam[i] < lam[smallest]:
                    smallest = i
            kept, total = 0, 0.0
            for i in range(m):
                if lam[i] > 1e-14 and i != smallest:
                    Y[kept] = Y[i]
                    lam[kept] = lam[i]
                    total += lam[i]
                    kept += 1
            m = kept
            for i in range(m):
                lam[i] /= total
        if dependent:                     # the new atom: no progress in floating point
            status = 2
            break
        xx = _corral_point(Y, lam, m, x)
    for i in range(6):
        nearest[i] = w[i] + x[i]
    return np.sqrt(xx), nearest, bound, iterations, status


def min_norm_point(G: np.ndarray, leg: np.ndarray, K: int, w: np.ndarray, tol: float,
                   floor: float, max_iter: int = 200) -> tuple[float, np.ndarray, float, int, int]:
    r"""
    Return the nearest point to ``w`` of ``S = sum_k conv{G[:, leg == k]}``, by Wolfe's algorithm.

    :func:`awp_ros.wrench.fws_queries.fws_distance` has the equations. ``G`` (6, n) the legs'
    lifted points, contiguous per leg; ``leg`` (n,) their legs ``0 .. K - 1``; ``w`` (6,).
    It stops when the gap ``eps = x . x - x . q`` of the iterate ``x = s - w`` and the
    oracle's point ``q`` gives ``eps / |x| <= tol``, or ``eps <= floor`` (rounding: the
    direction of a tiny ``x`` is only known to about the points' size times the machine
    epsilon over ``|x|``).

    :return: ``(distance, nearest (6,), bound, iterations, status)``: ``distance = |x|``,
        an upper bound of ``dist(w, S)`` within ``bound`` of it (``min(eps / |x|, |x|)``);
        status 0 converged, 1 ``max_iter`` reached, 2 the atoms became affinely dependent
        before convergence, 3 a leg without points (distance inf).
    """
    d, nearest, bound, iterations, status = _min_norm_point(
        np.ascontiguousarray(G, dtype=float), np.ascontiguousarray(leg, dtype=np.int64),
        int(K), np.ascontiguousarray(w, dtype=float), float(tol), float(floor), int(max_iter))
    return float(d), nearest, float(bound), int(iterations), int(status)


def compile_all() -> None:
    """
    Compile (or load from the disk cache) every kernel on small inputs, once per process.

    :class:`~awp_ros.evaluation.evaluator.FeasibilityEvaluator` calls it when built, so that
    no control cycle pays for it: loading the cache takes ~0.3 s, compiling (a new install, an
    edited module) ~30 s.
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
    cone_double_description(rays, 1e-9, 1e-9)
    polar_hull(g[:2])
    g5 = g[:5]
    subsets4 = np.array(list(combinations(range(8), 4)), dtype=np.int64)
    flat_zonotope_facets(g5, np.linalg.norm(g5, axis=0), subsets4, 1e-9, 1e-9)
    flat_cone_facets(g5.T / np.linalg.norm(g5.T, axis=1)[:, None], subsets4, 1e-9, 1e-9)
    lifted_rays(g[:3, :3], rng.normal(size=(3, 4, 3)), 1e-10)
    lifted_zonotope(g[:3, :3], g[3:6, :3], rng.normal(size=(3, 3, 3)),
                    np.array(list(combinations(range(9), 5)), dtype=np.int64), 1e-12, 1e-10,
                    1e-9, 1e-9)
    pair_hyperplane(g[:2, :3])
    pair_basis(g[:2, :3], rng.normal(size=(8, 6)), 1e-9, 1e-10)
    lifted_zonotope_pair(g[:2, :3], g[3:5, :3], rng.normal(size=(2, 3, 3)),
                         np.array(list(combinations(range(6), 4)), dtype=np.int64), 1e-12,
                         1e-10, 1e-9, 1e-9, 1e-9)
    polygon_region(g[:2], np.ones(8), None, 1e-9, 1e-12)
    wrench_slice(g.T, np.ones(8), np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0]), 1e-9, 1e-12, 0.0)
    segment_slice(g.T, np.ones(8), g[:, 0], 0.0, np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0]), 1e-9,
                  1e-6, 1e-9)
    box = np.vstack([np.eye(3), -np.eye(3)])
    cube = leg_vertices(box, np.ones(6))
    lifted = np.vstack([np.hstack([cube.T, cube.T]), np.zeros((3, 2 * cube.shape[0]))])
    projected_polygon(lifted, np.repeat(np.arange(2), cube.shape[0]), 2, np.zeros(6),
                      np.zeros((6, 2)), 1e-9)
    feasible_region(box[None], np.ones((1, 6)), -box[None, :1], np.zeros((1, 3)),
                    np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0]), 1e-9)
    J = rng.normal(size=(2, 3, 3))
    parallelepipeds(J, g[:2, :3], -np.ones((2, 3)), np.ones((2, 3)), 1e-9)
    solid_faces(cube, box, np.ones(6), np.zeros(3), float(np.sqrt(3.0)), 1e-9)
    certified_solid_faces(cube, box, np.ones(6), 1e-9, 1e-9)
    index = np.zeros(1, dtype=np.int64)
    survivor_normals(rng.normal(size=(1, 1, 15)), g.T[None, :1], index, index, index, 4, 1, 1,
                     0.0)
    survivor_normals(rng.normal(size=(1, 1, 20)), rng.normal(size=(1, 1, 15)), index, index,
                     index, 3, 2, 1, 0.0)                   # the general kernel
    first_of_equal_rows(g, 10)
    min_norm_point(lifted, np.repeat(np.arange(2), cube.shape[0]), 2,
                   np.array([9.0, 0.0, 0.0, 0.0, 0.0, 0.0]), 1e-9, 1e-13)
    ratio_test(g.T, np.ones(8), np.zeros(6), np.eye(6), 1e-6, 1e-9)
    two_leg_contains(g[:2, :3], box[None].repeat(2, 0), np.ones((2, 6)),
                     -box[None, :4].repeat(2, 0), np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0]), 1.0,
                     1e-6, 1e-12, 1e-6)
    slack_min(g.T, np.ones(8), np.zeros(6))
    inside_forces(cube[None], box[None], np.ones((1, 6)), -box[None, :3], 1e-6)
    # The per-cycle calls, with read-only tables and rays as the evaluator passes them.
    S9 = np.array(list(combinations(range(9), 5)), dtype=np.int64)
    O9 = subset_complements(S9, 9)
    rays3 = rng.normal(size=(3, 4, 3))
    for table in (S9, O9, rays3):
        table.setflags(write=False)
    J3, P3 = rng.normal(size=(3, 3, 3)), rng.normal(size=(3, 3))
    rows3 = -box[None, :4].repeat(3, 0)
    for last in (None, (np.zeros((1, 5), dtype=np.int64), np.zeros(1, dtype=np.int64))):
        sets = cycle_sets(J3, g[:3, :3], -np.ones((3, 3)), np.ones((3, 3)), 1e-9, P3, rays3,
                          1e-10, S9, O9, 1e-12, 1e-10, 1e-9, 1e-9, last, 1e-9, 1e-9, rows3, 1e-6,
                          np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0]), 1e-9)
    cycle_regions(sets[4][1], sets[5][0], sets[5][1], sets[1][3], sets[1][4], rows3, P3,
                  np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0]), 1e-9, 1e-12, 0.0)
    directional_margins_lp(box[None], np.ones((1, 6)), -box[None, :1], np.zeros((1, 3)),
                           np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0]))
    batched_vertices(box[None], np.ones((1, 6)), np.array([[0, 1, 2]]), np.ones(1), 1e-12)
    groups = {d: (rng.normal(size=(2, 2, d, 3)), rng.normal(size=(2, 2, 2, 2, 3)),
                  np.ones((2, 2, 2), dtype=bool), np.full(2, 2)) for d in (1, 2, 3)}
    for dims, legs in (((2, 1, 1, 1), [[0, 1, 1, 1]]), ((2, 2, 1), [[0, 1, 1]]),
                       ((3, 1, 1), [[0, 1, 1]]), ((3, 2), [[0, 1]])):
        slice_facet_normals(g[:2, :3], np.eye(6), groups, dims, np.array(legs), 1e-5, 1e-8)
    flat_pair_facet_normals(rng.normal(size=(2, 5, 3)), groups[1], groups[2], 1e-5, 1e-8)


if __name__ == '__main__':
    compile_all()
    print(f'awp_ros.geometry.kernels: compiled ({"numba" if ENABLED else "numpy only"})')
