"""
Triangle meshes and slices of polytopes, for drawing them (RViz / Foxglove markers, PNGs).

- :func:`hull_triangles`: the boundary of a 3D (or flat) convex hull as triangles;
- :func:`force_slice`: the 3D force slice ``{f : [f; tau] in P}`` of a 6D wrench polytope.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, HalfspaceIntersection, QhullError

from awp_ros.geometry.lp import chebyshev_ball
from awp_ros.geometry.polytope import Polytope

__all__ = ['force_slice', 'hull_triangles']


def hull_triangles(points: np.ndarray, *, flat_tol: float = 1e-9) -> np.ndarray:
    """
    Return a triangulation ``(T, 3, 3)`` of the boundary of the convex hull of points.

    3D hulls: qhull facets (outward winding). Flat (2D) hulls: the polygon fanned from its
    first vertex, both windings so that it shows from either side. Lower dimensions and
    fewer than 3 points give no triangle.

    :param points: ``(k, 3)`` points (any unit).
    :param flat_tol: singular values below ``flat_tol`` times the largest count as zero.
    """
    P = np.asarray(points, dtype=float).reshape(-1, 3)
    if P.shape[0] < 3:
        return np.zeros((0, 3, 3))
    c = P.mean(axis=0)
    _, s, vt = np.linalg.svd(P - c, full_matrices=False)
    if s[0] == 0.0:
        return np.zeros((0, 3, 3))
    rank = int(np.sum(s > flat_tol * s[0]))
    try:
        if rank == 3:
            hull = ConvexHull(P)
            tri = P[hull.simplices]
            normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            flip = np.einsum('ij,ij->i', normal, tri[:, 0] - c) < 0.0
            tri[flip] = tri[flip][:, ::-1]
            return tri
        if rank == 2:
            Y = (P - c) @ vt[:2].T
            ring = P[ConvexHull(Y).vertices]
            fan = np.stack([np.repeat(ring[:1], len(ring) - 2, axis=0), ring[1:-1], ring[2:]],
                           axis=1)
            return np.concatenate([fan, fan[:, ::-1]])
    except QhullError:
        pass
    return np.zeros((0, 3, 3))


def force_slice(P: Polytope, tau: np.ndarray, *, interior: np.ndarray | None = None,
                tol: float = 1e-9) -> np.ndarray:
    r"""
    Return the vertices ``(k, 3)`` of the force slice of a 6D wrench polytope.

    .. math:: S(\tau) = \{f \in \mathbb{R}^3 : [f; \tau] \in P\}

    with ``P = {w : A w <= b, w = o + U y}``. Writing ``w = o + U (y_0 + N z)`` with
    ``y_0`` solving the moment rows ``U_\tau y = \tau - o_\tau`` and ``N`` a basis of
    their null space, ``S`` is the polytope ``{z : A U N z <= b - A (o + U y_0)}`` mapped to
    forces; its vertices come from qhull's halfspace intersection (dimension of ``z`` >= 2),
    a ratio test (1) or a membership test (0).

    :param P: the wrench polytope [N, N.m], world-aligned axes about the CoM.
    :param tau: the moment ``(3,)`` [N.m].
    :param interior: optional wrench ``(6,)`` known to be strictly inside ``P`` with moment
        ``tau`` (saves the Chebyshev-centre LP).
    :param tol: residual and slack tolerance [N, N.m].
    :return: the vertices [N]; ``(0, 3)`` when the slice is empty or qhull fails.
    """
    empty = np.zeros((0, 3))
    if P.is_empty:
        return empty
    tau = np.asarray(tau, dtype=float)
    o, U = P.hull_origin, P.hull_basis
    Ut = U[3:]
    y0, *_ = np.linalg.lstsq(Ut, tau - o[3:], rcond=None)
    if np.linalg.norm(Ut @ y0 - (tau - o[3:])) > tol * max(1.0, np.linalg.norm(tau)):
        return empty
    _, s, vt = np.linalg.svd(Ut) if Ut.size else (None, np.zeros(0), np.zeros((0, 0)))
    rank = int(np.sum(s > 1e-12 * max(1.0, s[0] if s.size else 1.0)))
    N = vt[rank:].T if Ut.size else np.eye(U.shape[1])
    base = o + U @ y0
    G = P.A @ (U @ N)
    h = P.b - P.A @ base
    norms = np.linalg.norm(G, axis=1)
    keep = norms > 1e-12
    if np.any(h[~keep] < -tol):
        return empty
    G, h = G[keep] / norms[keep, None], h[keep] / norms[keep]
    Uf = (U @ N)[:3]
    d = N.shape[1]
    if d == 0:
        return base[None, :3] if np.all(h >= -tol) else empty
    if d == 1:
        g = G[:, 0]
        hi = np.min(h[g > 0] / g[g > 0]) if np.any(g > 0) else np.inf
        lo = np.max(h[g < 0] / g[g < 0]) if np.any(g < 0) else -np.inf
        if not (np.isfinite(hi) and np.isfinite(lo)) or lo > hi + tol:
            return empty
        return base[:3] + np.outer([lo, hi], Uf[:, 0])
    z0 = None
    if interior is not None:
        z0 = N.T @ (U.T @ (np.asarray(interior, dtype=float) - base))
        if not np.all(G @ z0 < h - tol):
            z0 = None
    if z0 is None:
        ball = chebyshev_ball(G, h, min_radius=0.0)
        z0 = ball[0] if ball is not None and ball[1] > tol else None
        if z0 is None:
            return empty
    try:
        hs = HalfspaceIntersection(np.hstack([G, -h[:, None]]), z0)
    except (QhullError, ValueError):
        return empty
    Z = hs.intersections
    Z = Z[np.all(np.isfinite(Z), axis=1)]
    return base[:3] + Z @ Uf.T
