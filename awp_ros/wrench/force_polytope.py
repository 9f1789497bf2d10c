r"""
Per-leg force polytopes: the contact forces a leg's torque box can produce, in R^3.

For leg k with translational foot Jacobian ``J`` (3 x n, LOCAL_WORLD_ALIGNED, world axes)
and ``bias`` the leg's rows of ``rnea(q, v, a)`` (seed eq. 1):

.. math::

    (1)\quad \mathcal F = \{f : \tau_{min} \le \mathrm{bias} - J^T f \le \tau_{max}\}
    \qquad f\ \text{[N], force of the ground on the foot, world axes}

    (2)\quad n = 3,\ J\ \text{invertible:}\quad
        \mathcal F = \{c - G s : s \in [-1, 1]^3\},\
        c = J^{-T}(\mathrm{bias} - \tau_{mid}),\ G = J^{-T} \mathrm{diag}(h)

    (3)\quad \text{facets:}\quad \pm \hat J_i \cdot f \le \dots,\
        \text{one pair per joint } i, \hat J_i = J_{:,i} / |J_{:,i}|

with ``tau_mid = (tau_max + tau_min) / 2`` and ``h = (tau_max - tau_min) / 2``. Vertex ``i``
of a parallelepiped is ``c - G s_i`` with ``s_i`` row ``i`` of :data:`CUBE_SIGNS`; it is
produced by the torques ``tau_mid + h * s_i``. Legs with more than 3 joints: the exact set
(1) by vertex enumeration. A singular leg (rank J < 3) makes (1) unbounded or empty; it is
replaced by the seed's pseudo-inverse image ``{pinv(J^T)(bias - tau)}`` (a flat zonotope)
and flagged ``singular``. Near-singular legs keep the exact set and are flagged
``near_singular``.

Legs with fewer than 3 joints (a planar 2-joint leg, Solo8's) are flat by design: the
actuators push only within the span of J's columns (the leg's plane), and J^T is one-to-one
there, so the force set is exactly

.. math:: (4)\quad \mathcal F = \{f \in \mathrm{range}(J) : \tau_{min} \le \mathrm{bias}
    - J^T f \le \tau_{max}\} = \{J^{T+} (\mathrm{bias} - \tau) : \tau_{min} \le \tau
    \le \tau_{max}\}

(forces across the plane are held by the structure, not the actuators: they are not in
the set), a parallelogram (n = 2) or a segment (n = 1). Such a leg is singular, and flagged,
only when J is rank-deficient within its own rank ``n``: singularity is judged on the ratio
of J's smallest to largest singular value, of ``min(n, 3)`` values.

The module also holds the small 3D converters used for every per-leg polytope:
:func:`polytope_from_halfspaces` (vertex enumeration, vectorised over all triples of
planes) and :func:`polytope_from_points` (convex hull of a few points, any dimension).
"""

from __future__ import annotations

from functools import lru_cache
import itertools

import numpy as np
from scipy.spatial import ConvexHull

from awp_ros.errors import GeometryError
from awp_ros.geometry import kernels
from awp_ros.geometry.linalg import orthonormal_span
from awp_ros.geometry.polytope import Polytope

__all__ = ['CUBE_SIGNS', 'force_polytope', 'parallelepipeds', 'polytope_from_halfspaces',
           'polytope_from_points', 'triples']

#: Rows s of {-1, 1}^3; vertex i of a parallelepiped is c - G s_i (torques tau_mid + h s_i).
CUBE_SIGNS = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))


def parallelepipeds(J: np.ndarray, bias: np.ndarray, tau_min: np.ndarray,
                    tau_max: np.ndarray, *, singular_rtol: float = 1e-9
                    ) -> dict[str, np.ndarray]:
    """
    Return the force parallelepipeds of K 3-joint legs at once (equations 2-3).

    :param J: (K, 3, 3) foot Jacobians [m/rad], world axes.
    :param bias: (K, 3) bias torques [N.m].
    :param tau_min: (K, 3) lower torque limits [N.m].
    :param tau_max: (K, 3) upper torque limits [N.m].
    :return: dict with ``center`` (K, 3) [N], ``generators`` (K, 3, 3) (columns) [N],
        ``vertices`` (K, 8, 3) [N], ``A`` (K, 6, 3) unit rows, ``b`` (K, 6) [N] and
        ``sigma_ratio`` (K,) the smallest over the largest singular value of J. Legs with
        ``sigma_ratio <= singular_rtol`` get NaNs: use :func:`force_polytope` for them.
    """
    if kernels.ENABLED:     # compiled, one call (this code is its reference)
        return kernels.parallelepipeds(J, bias, tau_min, tau_max, singular_rtol)
    J = np.asarray(J, dtype=float)
    h = 0.5 * (tau_max - tau_min)
    mid = 0.5 * (tau_max + tau_min)
    sv = np.linalg.svd(J, compute_uv=False)
    ratio = sv[:, -1] / np.maximum(sv[:, 0], np.finfo(float).tiny)
    JT = np.swapaxes(J, 1, 2)
    ok = ratio > singular_rtol
    if np.all(ok):
        JinvT = np.linalg.inv(JT)
    else:
        JinvT = np.full_like(J, np.nan)
        JinvT[ok] = np.linalg.inv(JT[ok])
    center = (JinvT @ (bias - mid)[:, :, None])[:, :, 0]
    G = JinvT * h[:, None, :]
    vertices = center[:, None, :] - (G @ CUBE_SIGNS.T).transpose(0, 2, 1)
    norms = np.sqrt(np.einsum('kij,kij->kj', J, J))         # (K, 3) column norms
    inv = 1.0 / np.where(norms > 0.0, norms, np.nan)        # NaN rows, no warning
    Jhat = JT * inv[:, :, None]                             # (K, 3, 3) unit rows
    A = np.concatenate([Jhat, -Jhat], axis=1)
    b = np.concatenate([(bias - tau_min) * inv, (tau_max - bias) * inv], axis=1)
    return {'center': center, 'generators': G, 'vertices': vertices, 'A': A, 'b': b,
            'sigma_ratio': ratio}


def force_polytope(J: np.ndarray, bias: np.ndarray, tau_min: np.ndarray,
                   tau_max: np.ndarray, *, singular_rtol: float = 1e-9,
                   near_singular_rtol: float = 1e-2, tol: float = 1e-9) -> Polytope:
    """
    Return the force polytope (1) of one leg with any number of joints.

    :param J: (3, n) foot Jacobian w.r.t. the leg's joints [m/rad], world axes.
    :param bias: (n,) bias torques [N.m] (seed eq. 1 without the contact term).
    :param tau_min: (n,) lower torque limits [N.m].
    :param tau_max: (n,) upper torque limits [N.m].
    :param singular_rtol: J is singular when its smallest singular value is below this
        times its largest (then the pseudo-inverse image is returned).
    :param near_singular_rtol: below this ratio the leg is flagged ``near_singular``.
    :param tol: relative tolerance of the vertex enumeration (n > 3).
    :return: a :class:`Polytope` in R^3 [N]; ``meta`` holds ``singular``,
        ``near_singular``, ``sigma_ratio`` (of J's ``min(n, 3)`` singular values),
        ``planar`` (n < 3: flat by design, eq. 4) and, for parallelepipeds, pseudo-inverse
        images and legs with n < 3, ``center`` (3,) and ``generators`` (3, max(n, 3)) with
        ``F = {c - G s}`` (zero columns beyond n).
    """
    J = np.asarray(J, dtype=float)
    bias = np.asarray(bias, dtype=float)
    n = J.shape[1]
    sv = np.linalg.svd(J, compute_uv=False)          # min(n, 3) values: the leg's own rank
    ratio = float(sv[-1] / sv[0]) if sv.size and sv[0] > 0.0 else 0.0
    meta = {'singular': ratio <= singular_rtol,
            'near_singular': singular_rtol < ratio <= near_singular_rtol,
            'sigma_ratio': ratio, 'planar': n < 3}
    h = 0.5 * (tau_max - tau_min)
    mid = 0.5 * (tau_max + tau_min)
    if meta['singular'] or n < 3:                       # (4) for n < 3: exact, flat
        JinvT = np.linalg.pinv(J.T, rcond=singular_rtol)
        center = JinvT @ (bias - mid)
        G = JinvT * h[None, :]
        signs = np.array(list(itertools.product((-1.0, 1.0), repeat=n)))
        P = polytope_from_points(center[None, :] - signs @ G.T, tol=tol)
        if n < 3:       # zero columns: the same set, the (3, 3) shape of the AWP zonotope
            G = np.concatenate([G, np.zeros((3, 3 - n))], axis=1)
        meta.update(center=center, generators=G)
        return Polytope(P.dimension, P.vertices, P.A, P.b, P.hull_origin, P.hull_basis, meta)
    if n == 3:
        pp = parallelepipeds(J[None], bias[None], tau_min[None], tau_max[None],
                             singular_rtol=singular_rtol)
        meta.update(center=pp['center'][0], generators=pp['generators'][0])
        return Polytope(3, pp['vertices'][0], pp['A'][0], pp['b'][0], np.zeros(3),
                        np.eye(3), meta)
    A = np.vstack([J.T, -J.T])
    b = np.concatenate([bias - tau_min, tau_max - bias])
    P = polytope_from_halfspaces(A, b, tol=tol)
    return Polytope(P.dimension, P.vertices, P.A, P.b, P.hull_origin, P.hull_basis, meta)


@lru_cache(maxsize=32)
def triples(m: int) -> np.ndarray:
    """Return all index triples of m planes, shape (C(m, 3), 3) (cached, read-only)."""
    out = np.array(list(itertools.combinations(range(m), 3)), dtype=int).reshape(-1, 3)
    out.setflags(write=False)
    return out


def polytope_from_halfspaces(A: np.ndarray, b: np.ndarray, *, tol: float = 1e-9,
                             det_tol: float = 1e-12) -> Polytope:
    r"""
    Return the bounded polytope ``{x : A x <= b}`` in R^3 with its vertices.

    .. math:: P = \{x \in \mathbb R^3 : a_i \cdot x \le b_i\}

    Every triple of planes with ``|det| > det_tol`` is solved at once (batched), the
    solutions satisfying all rows within ``tol * max(1, |b|_inf)`` are the vertices
    (duplicates within that distance merged). The H-rep keeps the rows tight at 3 or more
    vertices (facets), duplicates removed. Flat results (dimension 0-2) are described in
    their affine hull (see :class:`Polytope`). The caller guarantees boundedness (an
    unbounded input yields the hull of its vertices).

    :param A: (m, 3) rows, any norm (normalised here).
    :param b: (m,) right-hand sides, in the units of x times |a|.
    :return: the polytope (``Polytope.empty(3)`` if infeasible).
    """
    A = np.asarray(A, dtype=float)
    b = np.asarray(b, dtype=float)
    norms = np.linalg.norm(A, axis=1)
    if np.any(norms == 0.0):
        if np.any(b[norms == 0.0] < 0.0):
            return Polytope.empty(3)
        A, b, norms = A[norms > 0.0], b[norms > 0.0], norms[norms > 0.0]
    A = A / norms[:, None]
    b = b / norms
    scale = max(1.0, float(np.max(np.abs(b), initial=0.0)))
    eps = tol * scale
    tri = triples(A.shape[0])
    M = A[tri]
    det = np.linalg.det(M)
    good = np.abs(det) > det_tol
    if not np.any(good):
        return Polytope.empty(3)
    X = np.linalg.solve(M[good], b[tri[good]][:, :, None])[:, :, 0]
    feasible = np.all(X @ A.T <= b + eps, axis=1)
    V = _unique_points(X[feasible], eps)
    if V.shape[0] == 0:
        return Polytope.empty(3)
    P = polytope_from_points(V, tol=tol, extreme=True)
    if P.dimension < 3:
        return P
    tight = np.abs(V @ A.T - b) <= eps                      # (nv, m)
    facet = np.sum(tight, axis=0) >= 3
    Af, bf = A[facet], b[facet]
    # Drop duplicated rows (same plane listed twice).
    same = (Af @ Af.T > 1.0 - 1e-12) & (np.abs(bf[:, None] - bf[None, :]) <= eps)
    dup = np.any(np.triu(same, 1), axis=0)
    return Polytope(3, V, Af[~dup], bf[~dup], np.zeros(3), np.eye(3))


def polytope_from_points(V: np.ndarray, *, tol: float = 1e-9,
                         extreme: bool = False) -> Polytope:
    """
    Return the convex hull of points in R^3, of any affine dimension 0-3.

    :param V: (k, 3) points [N], k >= 1.
    :param tol: relative tolerance (affine rank, duplicate points).
    :param extreme: the caller guarantees every distinct point is a vertex (skips qhull
        in the 2D case; the 3D case then still needs the facets from the caller).
    :return: the polytope with unit facet rows within its affine hull.
    """
    V = np.asarray(V, dtype=float)
    if V.shape[0] == 0:
        return Polytope.empty(3)
    scale = max(1.0, float(np.max(np.abs(V))))
    V = _unique_points(V, tol * scale)
    o = V.mean(axis=0)
    U = orthonormal_span(V - o, rtol=tol) if V.shape[0] > 1 else np.zeros((3, 0))
    r = U.shape[1]
    if r == 0:
        return Polytope(0, V[:1], np.zeros((0, 3)), np.zeros(0), V[0].copy(), U)
    Y = (V - o) @ U
    if r == 1:
        u = U[:, 0]
        i, j = int(np.argmin(Y[:, 0])), int(np.argmax(Y[:, 0]))
        A = np.vstack([-u, u])
        b = np.array([-u @ V[i], u @ V[j]])
        return Polytope(1, V[[i, j]], A, b, o, U)
    if r == 2:
        if extreme:
            order = np.argsort(np.arctan2(Y[:, 1] - Y[:, 1].mean(), Y[:, 0] - Y[:, 0].mean()))
        else:
            order = ConvexHull(Y).vertices                 # counter-clockwise in 2D
        Yc = Y[order]
        edge = np.roll(Yc, -1, axis=0) - Yc
        n2 = np.column_stack([edge[:, 1], -edge[:, 0]])  # outward for CCW order
        ln = np.linalg.norm(n2, axis=1)
        keep = ln > tol * scale
        n2 = n2[keep] / ln[keep, None]
        A = n2 @ U.T
        b = np.einsum('ij,ij->i', A, V[order][keep])
        return Polytope(2, V[order], A, b, o, U)
    if extreme:
        return Polytope(3, V, np.zeros((0, 3)), np.zeros(0), np.zeros(3), np.eye(3))
    try:
        hull = ConvexHull(V)
    except Exception as exc:  # noqa: BLE001 -- qhull raises its own error type
        raise GeometryError(f'convex hull of {V.shape[0]} points failed: {exc}') from exc
    eq = hull.equations
    same = (eq[:, :3] @ eq[:, :3].T > 1.0 - 1e-12) \
        & (np.abs(eq[:, 3][:, None] - eq[:, 3][None, :]) <= tol * scale)
    dup = np.any(np.triu(same, 1), axis=0)
    eq = eq[~dup]
    return Polytope(3, V[hull.vertices], eq[:, :3], -eq[:, 3], np.zeros(3), np.eye(3))


def _unique_points(X: np.ndarray, eps: float) -> np.ndarray:
    """Return the rows of X with no earlier row within distance eps (order kept)."""
    if X.shape[0] <= 1:
        return X
    D = np.linalg.norm(X[:, None, :] - X[None, :, :], axis=2)
    dup = np.any(np.triu(D <= eps, 1), axis=0)
    return X[~dup]
