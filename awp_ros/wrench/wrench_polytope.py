"""
The actuation wrench polytope (AWP) and the feasible wrench polytope (FWP) in R^6.

Frames: world-aligned axes (REP 103), origin at the robot's CoM. Foot positions p_k [m]
relative to the CoM; contact forces f_k [N] exerted by the ground on the robot; wrenches
w = [f; tau] [N, N.m] about the CoM.

Equations (seed eqs. 1-3 and its Sec. on the FWP):

    (1) lift: L_k = [I_3; [p_k]x] (6 x 3), w = L_k f = [f; p_k x f];
    (2) a 3-joint leg's force polytope is a parallelepiped c_k + H_k [-1, 1]^3 (seed eq. 1
        over the torque box), so AWP = sum_k L_k (c_k + H_k [-1, 1]^3) is the zonotope with
        centre sum_k L_k c_k and the 3K generators L_k H_k (zonotope.py);
    (3) FWP = AWP cap CWC: the H-reps are stacked (contact_wrench_cone.py), both expressed in
        the common affine hull. For full-dimensional leg polytopes and pyramids both hulls are
        the subspace sum_k L_k R^3 (dimension 0, 3, 5, 6, 6 for 0..4 legs).
"""

from __future__ import annotations

from functools import lru_cache
import math

import numpy as np

from awp_ros.errors import InputError
from awp_ros.geometry import kernels
from awp_ros.geometry.linalg import cross3, GRAM_CERTIFY, identity
from awp_ros.geometry.lp import chebyshev_ball
from awp_ros.geometry.margin import least_slack
from awp_ros.geometry.polytope import Polytope
from awp_ros.geometry.zonotope import facet_complements, facet_subsets, zonotope, ZONOTOPE_TOLS

__all__ = ['actuation_wrench_polytope', 'feasible_wrench_polytope', 'INTERIOR_TOL', 'lift',
           'lift_matrices', 'lift_points', 'awp_zonotope', 'zonotope_awp']

#: Inscribed-ball radius [N, N.m] under which the FWP is degenerate (touching sets), and
#: the slack its cheap interior tests need (:func:`feasible_wrench_polytope`).
INTERIOR_TOL = 1e-9


def lift(p: np.ndarray) -> np.ndarray:
    r"""
    Return the lift matrix of a foot position, eq. (1).

    .. math:: L = \begin{bmatrix} I_3 \\ [p]_\times \end{bmatrix}, \quad
              L f = [f; p \times f]

    :param p: foot position ``(3,)`` [m] relative to the CoM, world axes.
    :return: array ``(6, 3)``.
    """
    return lift_matrices(np.reshape(p, (1, 3)))[0]


def lift_matrices(positions: np.ndarray) -> np.ndarray:
    """
    Return the lifts ``L_k = [I_3; [p_k]_x]`` of shape (K, 6, 3), eq. (1), batched.

    :param positions: (K, 3) feet relative to the CoM [m], world-aligned axes.
    """
    p = np.asarray(positions, dtype=float)
    K = p.shape[0]
    L = np.zeros((K, 6, 3))
    L[:, 0, 0] = L[:, 1, 1] = L[:, 2, 2] = 1.0
    L[:, 3, 1], L[:, 3, 2] = -p[:, 2], p[:, 1]
    L[:, 4, 0], L[:, 4, 2] = p[:, 2], -p[:, 0]
    L[:, 5, 0], L[:, 5, 1] = -p[:, 1], p[:, 0]
    return L


def lift_points(positions: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """
    Return ``L_k v`` for per-leg 3-vectors, batched: ``(K, ..., 3) -> (K, ..., 6)``, eq. (1).

    :param positions: ``(K, 3)`` [m]; :param vectors: ``(K, ..., 3)`` (forces [N]).
    """
    P = np.asarray(positions, dtype=float)
    V = np.asarray(vectors, dtype=float)
    P = P.reshape(P.shape[:1] + (1,) * (V.ndim - 2) + (3,))
    return np.concatenate([V, cross3(P, V)], axis=-1)


def actuation_wrench_polytope(positions: np.ndarray, centers: np.ndarray,
                              generators: np.ndarray, *, with_vertices: bool = False,
                              **zonotope_tols: float) -> Polytope:
    r"""
    Return the AWP of 3-joint legs as an exact zonotope H-rep, eq. (2).

    .. math:: \mathrm{AWP} = \bigoplus_k L_k (c_k + H_k [-1, 1]^3)
              = \textstyle\sum_k L_k c_k + [L_1 H_1, \dots, L_K H_K] [-1, 1]^{3K}

    :param positions: stance foot positions ``(K, 3)`` [m] relative to the CoM, world axes.
    :param centers: force-polytope centres ``(K, 3)`` [N], world axes.
    :param generators: ``(K, 3, 3)`` [N]: ``generators[k][:, j]`` is the j-th half-edge of leg
        k's parallelepiped (``J^{-T} diag((tau_max - tau_min) / 2)``; zero or dependent
        columns allowed for singular legs).
    :param with_vertices: also enumerate the 6D vertices (slow, off in the hot path).
    :param zonotope_tols: tolerances forwarded to :func:`awp_ros.geometry.zonotope.zonotope`.
    :return: the AWP (``{0}`` for K = 0), ``meta['kind'] = 'zonotope'``.
    :raises InputError: on bad shapes or non-finite values.
    """
    P, C, H = _check_legs(positions, centers, generators)
    return awp_zonotope(P, C, H, with_vertices=with_vertices, **zonotope_tols)


def awp_zonotope(P: np.ndarray, C: np.ndarray, H: np.ndarray, *,
                 with_vertices: bool = False, **zonotope_tols: float) -> Polytope:
    """
    Return :func:`actuation_wrench_polytope` of legs already checked (its eq. (2)).

    :param P: feet (K, 3) [m]; :param C: centres (K, 3) [N]; :param H: generators (K, 3, 3)
        [N]: finite float arrays of these shapes (the evaluator's own, per cycle).
    """
    K = P.shape[0]
    if K == 0:
        return zonotope(np.zeros(6), np.zeros((6, 0)), with_vertices=with_vertices)
    tol = {**ZONOTOPE_TOLS, **zonotope_tols} if zonotope_tols else ZONOTOPE_TOLS
    if kernels.ENABLED and 3 <= K <= kernels.MAX_BITS // 3 and not with_vertices:
        fused = kernels.lifted_zonotope(P, C, H, facet_subsets(3 * K), tol['zero_tol'],
                                        max(tol['span_tol'] ** 2, GRAM_CERTIFY),
                                        tol['rank_tol'], tol['incidence_tol'],
                                        others=facet_complements(3 * K))
        if fused is not None:       # full-dimensional (else the general code decides)
            return zonotope_awp(*fused, 3 * K)
    if kernels.ENABLED and K == 2 and not with_vertices:      # a hyperplane of R^6
        fused = kernels.lifted_zonotope_pair(P, C, H, facet_subsets(6, 4), tol['zero_tol'],
                                             max(tol['span_tol'] ** 2, GRAM_CERTIFY),
                                             tol['span_tol'], tol['rank_tol'],
                                             tol['incidence_tol'])
        if fused is not None:       # certified 5-dimensional (else the general code decides)
            A, b, c, n, U = fused
            return Polytope(5, np.zeros((0, 6)), A, b, c, U,
                            {'kind': 'zonotope', 'generators': 6}).with_hyperplane(n)
    # One lift for the centre and the three generators of every leg: (K, 4, 6).
    lifted = lift_points(P, np.concatenate([C[:, None, :], H.transpose(0, 2, 1)], axis=1))
    center = np.sum(lifted[:, 0, :], axis=0)
    G = lifted[:, 1:, :].reshape(3 * K, 6).T
    return zonotope(center, G, with_vertices=with_vertices, **zonotope_tols)


def zonotope_awp(A: np.ndarray, b: np.ndarray, c: np.ndarray, generators: int) -> Polytope:
    """Return the full-dimensional AWP of its zonotope rows ``A``, ``b`` and centre ``c``."""
    return Polytope(6, np.zeros((0, 6)), A, b, c, identity(6),
                    {'kind': 'zonotope', 'generators': generators})


def feasible_wrench_polytope(awp: Polytope, cwc: Polytope, *, hull_tol: float = 1e-9,
                             interior_tol: float = INTERIOR_TOL,
                             stacked: tuple[np.ndarray, np.ndarray] | None = None,
                             interior: bool | None = None) -> Polytope:
    r"""
    Return the FWP = AWP cap CWC as a stacked H-rep in the common affine hull, eq. (3).

    .. math:: \mathrm{FWP} = \{w \in \mathrm{aff}: A_{awp} w \le b_{awp},\;
              A_{cwc} w \le 0\}

    Rows of both sets are projected on the intersection of the two affine hulls (they are
    equal, and nothing is projected, when leg polytopes and pyramids are full-dimensional)
    and re-normalised. When the hulls coincide, the intersection has an interior in the hull
    if the AWP centre (a zonotope's) lies strictly inside the CWC or 0 strictly inside the
    AWP (cheap tests, the usual case); otherwise a Chebyshev-ball LP decides:
    ``meta['degenerate'] = True`` when the largest inscribed ball has radius <=
    ``interior_tol`` (touching sets: the reported dimension is then that of the hull, an
    upper bound), empty when the LP shows the intersection is empty.

    :param awp: the AWP (any Polytope with a complete H-rep).
    :param cwc: the CWC (``b = 0``, a cone).
    :param hull_tol: distance under which the two hulls coincide / a point is in a hull.
    :param interior_tol: inscribed-ball radius [N, N.m] under which the set is degenerate.
    :param stacked: ``([A_awp; A_cwc], [b_awp; b_cwc])`` when the caller has them stacked
        already (:func:`awp_ros.geometry.kernels.cycle_sets`); used when the hulls coincide.
    :param interior: the outcome of the two cheap interior tests when the caller made them
        (:func:`~awp_ros.geometry.kernels.cycle_sets`, with ``interior_tol``), for
        full-dimensional sets; made here when None.
    :return: the FWP; ``meta['source']`` is 0 for rows from the AWP, 1 from the CWC;
        ``meta['kind'] = 'intersection'``. Vertices are not enumerated.
    """
    n = awp.ambient_dim
    if awp.is_empty or cwc.is_empty:
        return Polytope.empty(n)
    if awp.dimension == 0 or cwc.dimension == 0:
        return _point_intersection(awp, cwc, hull_tol)
    origin, U, same = _hull_intersection(awp, cwc, hull_tol)
    if U is None:
        return Polytope.empty(n)
    if same:
        A1, b1, A2, b2 = awp.A, awp.b, cwc.A, cwc.b
    else:
        A1, b1 = _restrict(awp, origin, U, hull_tol)
        A2, b2 = _restrict(cwc, origin, U, hull_tol)
        if A1 is None or A2 is None:
            return Polytope.empty(n)
    A, b = stacked if same and stacked is not None else \
        (np.concatenate((A1, A2)), np.concatenate((b1, b2)))
    meta = {'kind': 'intersection', 'source': _source(A1.shape[0], A2.shape[0]),
            'degenerate': False}
    # A zonotope's centre is in its relative interior; the apex 0 of the CWC is in the CWC.
    center_test = same and awp.meta.get('kind') == 'zonotope'
    if interior is None or not (same and center_test):
        interior = ((center_test and _strictly_inside(A2, b2, awp.hull_origin, interior_tol))
                    or (same and _strictly_inside(A1, b1, np.zeros(n), interior_tol)))
    if not interior:
        ball = chebyshev_ball(A @ U, b - A @ origin, max_radius=1.0)
        radius = None if ball is None else ball[1]
        if radius is None or radius < -interior_tol:
            return Polytope.empty(n)
        meta['degenerate'] = radius <= interior_tol
    fwp = Polytope(U.shape[1], np.zeros((0, n)), A, b, origin, U, meta)
    if same and U is awp.hull_basis and 'equalities' in awp.__dict__:
        fwp.__dict__['equalities'] = awp.equalities          # the same hull, known already
    return fwp


def _check_legs(positions: np.ndarray, centers: np.ndarray,
                generators: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return float arrays ``(K, 3)``, ``(K, 3)``, ``(K, 3, 3)`` or raise InputError."""
    P = np.asarray(positions, dtype=float)
    C = np.asarray(centers, dtype=float)
    H = np.asarray(generators, dtype=float)
    if P.size == 0 and C.size == 0 and H.size == 0:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3, 3))
    K = P.shape[0] if P.ndim == 2 else -1
    if P.shape != (K, 3) or C.shape != (K, 3) or H.shape != (K, 3, 3):
        msg = (f'AWP needs positions (K, 3), centers (K, 3), generators (K, 3, 3); got '
               f'{P.shape}, {C.shape}, {H.shape}')
        raise InputError(msg)
    if not math.isfinite(P.sum() + C.sum() + H.sum()):     # else: which one (or an overflow)
        for name, arr in (('positions', P), ('centers', C), ('generators', H)):
            if not np.isfinite(arr).all():
                msg = f'AWP {name} must be finite; got {arr.tolist()}'
                raise InputError(msg)
    return P, C, H


def _point_intersection(awp: Polytope, cwc: Polytope, tol: float) -> Polytope:
    """Return the intersection when one set is a single point."""
    n = awp.ambient_dim
    point, other = (awp, cwc) if awp.dimension == 0 else (cwc, awp)
    x = point.hull_origin
    scale = max(1.0, float(np.max(np.abs(x))))
    if not other.contains(x, tol=tol * scale):
        return Polytope.empty(n)
    return Polytope(0, x[None, :].copy(), np.zeros((0, n)), np.zeros(0), x.copy(),
                    np.zeros((n, 0)), {'kind': 'intersection', 'source': np.zeros(0, np.int8),
                                       'degenerate': False})


def _hull_intersection(awp: Polytope, cwc: Polytope,
                       tol: float) -> tuple[np.ndarray, np.ndarray | None, bool]:
    """
    Return ``(origin, basis, same)`` of aff(AWP) cap aff(CWC).

    ``basis`` is None when the hulls miss each other; ``same`` when they coincide.
    """
    U1, o1, U2, o2 = awp.hull_basis, awp.hull_origin, cwc.hull_basis, cwc.hull_origin
    if U1.shape[1] == U1.shape[0] and U2.shape[1] == U2.shape[0]:
        return o1, U1, True                       # both full-dimensional: the whole space
    scale = max(1.0, *map(abs, o1.tolist()))
    if U1.shape[1] == U2.shape[1] == U1.shape[0] - 1 and 'equalities' in awp.__dict__ \
            and np.array_equal(U1, U2):
        # One hyperplane's basis (two stance legs: both sets' closed-form basis of the same
        # feet): the same hull when o1 is on o2's hyperplane, |n . (o1 - o2)| its distance.
        n1 = awp.equalities[0][0]
        if abs(float(n1 @ (o1 - o2))) <= tol * scale:
            return o1, U1, True
    if U1.shape[1] == U2.shape[1]:
        d = o1 - o2
        same = (np.linalg.norm(U2 - U1 @ (U1.T @ U2)) <= tol * U2.shape[1]
                and np.linalg.norm(d - U2 @ (U2.T @ d)) <= tol * scale)
        if same:
            return o1, U1, True
    E1, e1 = awp.equalities
    E2, e2 = cwc.equalities
    E = np.vstack([E1, E2])
    e = np.concatenate([e1, e2])
    x, *_ = np.linalg.lstsq(E, e, rcond=None)
    if np.linalg.norm(E @ x - e) > tol * scale:
        return x, None, False
    _, s, vt = np.linalg.svd(E)
    rank = int(np.sum(s > tol * max(1.0, s[0] if s.size else 1.0)))
    return x, vt[rank:].T, False


def _restrict(P: Polytope, origin: np.ndarray, U: np.ndarray,
              tol: float) -> tuple[np.ndarray | None, np.ndarray]:
    """Return P's rows restricted to the hull ``origin + span U``, unit rows in that span."""
    Ar = P.A @ U
    norms = np.linalg.norm(Ar, axis=1)
    rhs = P.b - P.A @ origin
    const = norms <= tol
    if np.any(const & (rhs < -tol * max(1.0, float(np.max(np.abs(P.b), initial=0.0))))):
        return None, np.zeros(0)
    Ar = Ar[~const] / norms[~const, None]
    rhs = rhs[~const] / norms[~const]
    A = Ar @ U.T
    return A, rhs + A @ origin


def _strictly_inside(A: np.ndarray, b: np.ndarray, x: np.ndarray, tol: float) -> bool:
    """
    Return True when ``x`` satisfies every row with slack above ``tol``.

    The least slack by :func:`~awp_ros.geometry.margin.least_slack` (the per-cycle compiled
    call makes the same test with the same code).
    """
    return A.shape[0] == 0 or least_slack(A, b, x)[1] > tol


@lru_cache(maxsize=64)
def _source(m1: int, m2: int) -> np.ndarray:
    """Return the FWP's row sources (read-only): ``m1`` zeros (AWP), ``m2`` ones (CWC)."""
    source = np.ones(m1 + m2, dtype=np.int8)
    source[:m1] = 0
    source.setflags(write=False)
    return source
