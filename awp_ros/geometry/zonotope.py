r"""
Exact H-representation of a zonotope of any affine dimension (the AWP's engine).

A zonotope with centre ``c`` and generators ``g_1 .. g_m`` (columns of ``G``) is

.. math::

    Z = \{c + G t : \|t\|_\infty \le 1\} = c + \textstyle\sum_j [-g_j, g_j]

Let ``U`` span the generators (``r = rank G``) and work in hull coordinates ``U^T g_j``.
Equations used below:

    (1) every facet of Z is parallel to r - 1 linearly independent generators, so its normal
        is the generalised cross product of such a subset (linalg.subset_normals), both signs;
    (2) the support function of a Minkowski sum is the sum of the supports:
        h_Z(a) = a . c + sum_j |a . g_j|, the offset of the facet with normal a;
    (3) a facet is determined by the generators parallel to it (its incidence set, which
        spans it): subsets with the same set give the same facet pair, kept once (e.g. three
        generators of one lifted leg plus any two of another).

Every row produced by (1) and (2) is a valid supporting halfspace (b = h_Z(a) whatever a is),
and the rows of all rank-(r-1) subsets are complete, so the H-rep is exact. Vertices are
enumerated only on request: a zonotope with m generators in general position has
``2 sum_{i<r} C(m-1, i)`` of them (2048 for 12 generators in R^6).

Units and frames are the caller's (forces [N] in R^3, wrenches [N, N.m] in R^6).
"""

from __future__ import annotations

from functools import lru_cache
from itertools import combinations

import numpy as np

from awp_ros.errors import InputError
from awp_ros.geometry import kernels
from awp_ros.geometry.linalg import (distinct_columns, orthonormal_span, subset_normals,
                                     subset_tree, SubsetTree)
from awp_ros.geometry.polytope import Polytope

__all__ = ['facet_subsets', 'zonotope', 'zonotope_support', 'ZONOTOPE_TOLS']

#: Default tolerances of :func:`zonotope` (its keyword arguments).
ZONOTOPE_TOLS = {'zero_tol': 1e-12, 'rank_tol': 1e-9, 'span_tol': 1e-9, 'incidence_tol': 1e-9}


def zonotope(center: np.ndarray, generators: np.ndarray, *, with_vertices: bool = False,
             zero_tol: float = ZONOTOPE_TOLS['zero_tol'],
             rank_tol: float = ZONOTOPE_TOLS['rank_tol'],
             span_tol: float = ZONOTOPE_TOLS['span_tol'],
             incidence_tol: float = ZONOTOPE_TOLS['incidence_tol']) -> Polytope:
    r"""
    Return the exact H-representation of the zonotope ``c + G [-1, 1]^m``.

    .. math:: Z = \{x : a_i . x \le a_i . c + \textstyle\sum_j |a_i . g_j|\},
              \quad a_i \perp \{g_j\}_{j \in S_i}, \; |S_i| = r - 1

    :param center: centre ``c`` of shape ``(n,)`` (units of the caller, e.g. [N] or [N, N.m]).
    :param generators: ``G`` of shape ``(n, m)``, one generator per column (half-edges).
    :param with_vertices: also enumerate the vertices (exponential in r; off in the hot path).
    :param zero_tol: generators shorter than ``zero_tol`` times the longest are ignored.
    :param rank_tol: subsets whose unit-scaled volume is at most this are rank-deficient.
    :param span_tol: relative singular-value cut for the affine dimension ``r``.
    :param incidence_tol: ``|a . g_j| / |g_j|`` at most this puts ``g_j`` in the facet
        ``a`` (eq. 3: one row pair per set of such generators; vertices).
    :return: a :class:`Polytope` of dimension ``r`` with unit rows in the hull's direction
        space, ``hull_origin = c``; ``meta['kind'] = 'zonotope'``.
    :raises InputError: on bad shapes or non-finite input.
    """
    c, G = _check(center, generators)
    n = c.shape[0]
    norms = np.sqrt(np.einsum('ij,ij->j', G, G))
    top = float(np.max(norms, initial=0.0))
    keep = norms > zero_tol * top
    if not np.all(keep):
        G, norms = G[:, keep], norms[keep]
    U = orthonormal_span(G.T, rtol=span_tol)
    r = U.shape[1]
    meta = {'kind': 'zonotope', 'generators': G.shape[1]}
    if r == 0:
        return Polytope(0, c[None, :].copy(), np.zeros((0, n)), np.zeros(0), c, U, meta)
    full = r == n
    if full:                                  # hull coordinates are the ambient ones
        U = np.eye(n)
    g = G if full else U.T @ G
    # Eq. (1): a normal per valid subset (either sign), eq. (3): one per incidence set.
    subsets, tree = _combinations(G.shape[1], r - 1)
    if kernels.ENABLED and not with_vertices and 3 <= r <= 6 and G.shape[1] <= kernels.MAX_BITS:
        if r == 6:
            a, h = kernels.zonotope_facets(g, norms, subsets, rank_tol, incidence_tol,
                                           others=facet_complements(G.shape[1], r - 1))
        else:
            a, h = kernels.flat_zonotope_facets(g, norms, subsets, rank_tol, incidence_tol)
    else:
        a, h, subsets = _facets(g, norms, subsets, tree, r, rank_tol, incidence_tol,
                                with_vertices)
    A1 = a if full else a @ U.T
    ac = A1 @ c
    A = np.concatenate([A1, -A1])
    b = np.concatenate([ac + h, h - ac])
    V = np.zeros((0, n))
    if with_vertices:
        A_r = np.concatenate([a, -a])
        in_facet = np.zeros((A_r.shape[0], G.shape[1]), dtype=bool)
        rows = np.arange(subsets.shape[0])[:, None]
        in_facet[rows, subsets] = True
        in_facet[rows + subsets.shape[0], subsets] = True
        V = c + _vertex_signs(A_r @ g, g, in_facet, incidence_tol, A_r,
                              np.concatenate([h, h])) @ G.T
    return Polytope(r, V, A, b, c, U, meta)


def _facets(g: np.ndarray, norms: np.ndarray, subsets: np.ndarray, tree: SubsetTree, r: int,
            rank_tol: float, incidence_tol: float, with_vertices: bool
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """
    Return the unit normals ``a``, supports ``h`` (minus ``a . c``) and subsets of the facets.

    Eqs. (1-3) in numpy: the reference of :func:`awp_ros.geometry.kernels.zonotope_facets`
    and the code that also keeps each facet's subset (for the vertices).
    """
    subsets = subsets if with_vertices else None
    a, valid = subset_normals(g / norms, tree, rank_tol=rank_tol, unit=True)  # (k, r)
    if not np.all(valid):
        a, subsets = a[valid], subsets if subsets is None else subsets[valid]
    ag = np.abs(g.T @ a.T)                                       # (m, k): |a . g_j|
    h = np.sum(ag, axis=0)                                       # eq. (2), minus a . c
    first = distinct_columns(ag <= incidence_tol * norms[:, None], own=r - 1)
    if first.shape[0] < a.shape[0]:
        a, h, subsets = a[first], h[first], subsets if subsets is None else subsets[first]
    return a, h, subsets


def zonotope_support(center: np.ndarray, generators: np.ndarray,
                     directions: np.ndarray) -> np.ndarray:
    r"""
    Return the support function of the zonotope at each direction (row).

    .. math:: h_Z(a) = a . c + \textstyle\sum_j |a . g_j|

    :param directions: array ``(k, n)``.
    :return: array ``(k,)`` in the units of ``c`` times those of ``a``.
    """
    c, G = _check(center, generators)
    D = np.asarray(directions, dtype=float)
    return D @ c + np.sum(np.abs(D @ G), axis=1)


def _check(center: np.ndarray, generators: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(c, G)`` as float arrays or raise InputError naming the problem."""
    c = np.asarray(center, dtype=float)
    G = np.asarray(generators, dtype=float)
    if c.ndim != 1 or G.ndim != 2 or G.shape[0] != c.shape[0]:
        msg = f'zonotope needs center (n,) and generators (n, m); got {c.shape} and {G.shape}'
        raise InputError(msg)
    if not (np.isfinite(c).all() and np.isfinite(G).all()):
        msg = 'zonotope center and generators must be finite'
        raise InputError(msg)
    return c, G


def facet_subsets(m: int, k: int = 5) -> np.ndarray:
    """Return the lexicographic k-subsets of range(m) (read-only), eq. (1)'s candidates."""
    return _combinations(m, k)[0]


@lru_cache(maxsize=64)
def facet_complements(m: int, k: int = 5) -> np.ndarray:
    """Return, for each of :func:`facet_subsets`, the other indices of range(m) (read-only)."""
    others = kernels.subset_complements(facet_subsets(m, k), m)
    others.setflags(write=False)
    return others


@lru_cache(maxsize=64)
def _combinations(m: int, k: int) -> tuple[np.ndarray, SubsetTree]:
    """Return all k-subsets of range(m) (lexicographic) and their prefix tree."""
    subsets = np.array(list(combinations(range(m), k)), dtype=np.intp).reshape(-1, k) if k \
        else np.zeros((1, 0), dtype=np.intp)
    subsets.setflags(write=False)
    return subsets, subset_tree(subsets)


def _vertex_signs(proj: np.ndarray, g: np.ndarray, in_facet: np.ndarray, vertex_tol: float,
                  A_r: np.ndarray, b_r: np.ndarray) -> np.ndarray:
    """
    Return the sign vectors ``(v, m)`` of the vertices, from the facets' sign patterns.

    A vertex lies on a facet ``a``; there ``t_j = sign(a . g_j)`` except on the generators
    ``Z`` parallel to the facet, where the vertices of the facet zonotope take every sign
    pattern that is realisable. With ``|Z| = r - 1`` (general position) all ``2^(r-1)`` are;
    otherwise candidates are kept when the facets tight at them have rank r.
    """
    r, m = g.shape
    gn = np.linalg.norm(g, axis=0)
    rel = proj / gn
    Z = in_facet | (np.abs(rel) <= vertex_tol)
    base = np.where(Z, 0, np.where(rel > 0, 1, -1))
    signs = []
    for z in np.unique(np.sum(Z, axis=1)):
        rows = np.flatnonzero(np.sum(Z, axis=1) == z)
        pos = np.argsort(~Z[rows], axis=1, kind='stable')[:, :z]
        pattern = 1 - 2 * ((np.arange(2 ** z)[:, None] >> np.arange(z)) & 1)
        S = np.repeat(base[rows][:, None, :], 2 ** z, axis=1)
        S[np.arange(rows.size)[:, None, None], np.arange(2 ** z)[None, :, None],
          pos[:, None, :]] = pattern[None, :, :]
        S = np.unique(S.reshape(-1, m), axis=0)
        if z > r - 1:
            S = S[_is_vertex(S @ g.T, A_r, b_r, r, vertex_tol)]
        signs.append(S)
    return np.unique(np.vstack(signs), axis=0).astype(float)


def _is_vertex(Y: np.ndarray, A_r: np.ndarray, b_r: np.ndarray, r: int,
               tol: float) -> np.ndarray:
    """Return which points (rows of Y, hull coordinates) have r independent tight facets."""
    scale = max(float(np.max(np.abs(b_r), initial=0.0)), 1.0)
    tight = (b_r[None, :] - Y @ A_r.T) <= tol * scale
    outer = np.einsum('ki,kj->kij', A_r, A_r).reshape(A_r.shape[0], -1)
    gram = (tight.astype(float) @ outer).reshape(-1, r, r)
    return np.linalg.eigvalsh(gram)[:, 0] > _GRAM_TOL


_GRAM_TOL = 1e-10  # smallest eigenvalue of a sum of unit outer products that counts as rank
