r"""
Exterior algebra of R^r on sorted bases: wedge products and hyperplane normals.

A p-vector of R^r is stored by its ``C(r, p)`` coordinates on the basis
:math:`e_I = e_{i_1} \wedge \dots \wedge e_{i_p}`, ``I`` running over
``itertools.combinations(range(r), p)`` (lexicographic). The wedge of p vectors has the
p x p minors of their coordinate matrix as coordinates. Equations used below:

    (1) (x ^ y)_S = sum_{I + J = S} (-1)^inv(I, J) x_I y_J, inv(I, J) = #{(i, j) in I x J:
        i > j} (the sign that sorts the concatenation I J), a bilinear map with a fixed
        table T (wedge_table);
    (2) the normal of the hyperplane spanned by r - 1 vectors b_1 .. b_{r-1} (their
        generalised cross product) is n_i = (-1)^i det(B without coordinate i)
        = (-1)^i W_{[r] - {i}}, W = b_1 ^ ... ^ b_{r-1}; the (r-1)-subset without i is
        entry r - 1 - i of the lexicographic order (hodge_normal); n . b_l = 0 and |n| is
        the volume spanned by the b_l.

The kernels are batched (one call for many products, no Python loop over them); units are
the caller's. Used by :mod:`awp_ros.geometry.linalg` (facet normals of zonotopes and cones) and
:mod:`awp_ros.wrench.feasible_wrench_set` (facet normals of Minkowski sums of lifted polytopes).
"""

from __future__ import annotations

from functools import lru_cache
from itertools import combinations
from math import comb

import numpy as np

__all__ = ['hodge_normal', 'wedge_all', 'wedge_rows', 'wedge_table']


@lru_cache(maxsize=None)
def wedge_table(r: int, p: int, q: int) -> np.ndarray:
    r"""
    Return the table of eq. (1), shape ``(C(r, p), C(r, q), C(r, p + q))`` (read-only).

    .. math:: (x \wedge y)_S = \textstyle\sum_{I, J} x_I\, y_J\, T_{I J S}
    """
    P = list(combinations(range(r), p))
    Q = list(combinations(range(r), q))
    S = {s: n for n, s in enumerate(combinations(range(r), p + q))}
    T = np.zeros((len(P), len(Q), len(S)))
    for i, I in enumerate(P):
        for j, J in enumerate(Q):
            if set(I) & set(J):
                continue
            inversions = sum(1 for x in I for y in J if x > y)
            T[i, j, S[tuple(sorted(I + J))]] = (-1.0) ** inversions
    T.setflags(write=False)
    return T


def wedge_all(X: np.ndarray, Y: np.ndarray, r: int, p: int, q: int,
              out: np.ndarray | None = None) -> np.ndarray:
    """
    Return every wedge ``x_i ^ y_j`` of each batch entry, eq. (1).

    :param X: p-vectors ``(B, n_x, C(r, p))``.
    :param Y: q-vectors ``(B, n_y, C(r, q))``.
    :param out: optional buffer ``(B, n_x, n_y C(r, p + q))`` for the result.
    :return: ``(B, n_x n_y, C(r, p + q))``, row ``i n_y + j`` holding ``x_i ^ y_j``.
    """
    B, nx, ny = X.shape[0], X.shape[1], Y.shape[1]
    if p == 0 or q == 0:            # a scalar factor: a broadcast product, no table
        cs = comb(r, p + q)
        target = None if out is None else out.reshape(B, nx, ny, cs)
        prod = np.multiply(X[:, :, None, :], Y[:, None, :, :], out=target)
        return prod.reshape(B, nx * ny, cs)
    T = wedge_table(r, p, q)
    cp, cq, cs = T.shape
    # My[b, i_p, j, s] = sum_q Y[b, j, q] T[i_p, q, s], then one product with X.
    My = (Y @ T.transpose(1, 0, 2).reshape(cq, cp * cs)).reshape(B, ny, cp, cs)
    My = My.transpose(0, 2, 1, 3).reshape(B, cp, ny * cs)
    return np.matmul(X, My, out=out).reshape(B, nx * ny, cs)


def wedge_rows(X: np.ndarray, Y: np.ndarray, r: int, p: int, q: int) -> np.ndarray:
    """
    Return the row-wise wedges ``x_i ^ y_i``, shape ``(n, C(r, p + q))``, eq. (1).

    :param X: p-vectors ``(n, C(r, p))``; :param Y: q-vectors ``(n, C(r, q))``.
    """
    T = wedge_table(r, p, q)
    Mx = (X @ T.reshape(T.shape[0], -1)).reshape(X.shape[0], T.shape[1], T.shape[2])
    return np.einsum('nq,nqs->ns', Y, Mx)


def hodge_normal(W: np.ndarray) -> np.ndarray:
    r"""
    Return the hyperplane normals of (r-1)-vectors ``W (..., r)``, eq. (2), same shape.

    .. math:: n_i = (-1)^i\, W_{[r] \setminus \{i\}}
    """
    r = W.shape[-1]
    return W[..., ::-1] * _alternating(r)


@lru_cache(maxsize=16)
def _alternating(r: int) -> np.ndarray:
    """Return ``[1, -1, 1, ...]`` of length ``r`` (read-only)."""
    out = (-1.0) ** np.arange(r)
    out.setflags(write=False)
    return out
