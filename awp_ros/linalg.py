"""Small batched linear-algebra kernels shared by the polytope modules.

All functions are vectorised over a leading batch axis: the hot path calls each of
them once per control cycle on every candidate at once, never in a Python loop.
"""

from __future__ import annotations

import numpy as np

__all__ = ['hyperplane_normals', 'orthonormal_span']


def hyperplane_normals(B: np.ndarray, rank_tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Return unit normals of the hyperplanes spanned by batches of d - 1 vectors.

    .. math:: n_i \\perp b_{i,1}, \\dots, b_{i,d-1}, \\quad \\|n_i\\| = 1

    Modified Gram-Schmidt on the rows of each ``B[i]`` (vectorised over ``i``),
    then the coordinate axis least aligned with the span is projected on its
    orthogonal complement. The sign of each normal is arbitrary.

    :param B: array of shape ``(m, d - 1, d)``, the spanning vectors as rows.
    :param rank_tol: a batch whose Gram-Schmidt step leaves a residual below
        ``rank_tol`` times the input row's norm is rank-deficient (no unique normal).
    :return: ``(normals, valid)``: normals of shape ``(m, d)`` (zero rows where not
        valid) and a boolean mask of shape ``(m,)``.
    """
    B = np.asarray(B, dtype=float)
    m, k, d = B.shape
    Q = np.empty_like(B)
    valid = np.ones(m, dtype=bool)
    for i in range(k):
        v = B[:, i, :].copy()
        scale = np.linalg.norm(v, axis=1)
        for j in range(i):
            v -= np.einsum('md,md->m', Q[:, j, :], v)[:, None] * Q[:, j, :]
        norm = np.linalg.norm(v, axis=1)
        ok = norm > rank_tol * np.maximum(scale, np.finfo(float).tiny)
        valid &= ok
        Q[:, i, :] = v / np.where(ok, norm, 1.0)[:, None]
    # Projector on the orthogonal complement of each span, P = I - Q^T Q.
    P = np.eye(d)[None, :, :] - np.einsum('mkd,mke->mde', Q, Q)
    diag = np.einsum('mdd->md', P)
    j = np.argmax(diag, axis=1)
    rows = np.arange(m)
    n = P[rows, :, j]
    n /= np.sqrt(np.maximum(diag[rows, j], np.finfo(float).tiny))[:, None]
    n[~valid] = 0.0
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
