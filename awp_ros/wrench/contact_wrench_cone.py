"""
Friction pyramids and the exact H-representation of the contact wrench cone (CWC).

Frames: world-aligned axes (REP 103), origin at the robot's CoM; forces [N], moments [N.m],
foot positions [m] relative to the CoM. Contact force f_k = force of the ground on the robot.

Equations used below:

    (1) pyramid of leg k (N sides, inscribed in the cone of coefficient mu around n):
        t1 = normalised projection of world x on the contact plane (world y if x // n),
        t2 = n x t1, th_i = 2 pi i / N,
        facet i: (cos th_i t1 + sin th_i t2 - mu cos(pi/N) n) . f <= 0,
        ray i:   n + mu (cos ph_i t1 + sin ph_i t2), ph_i = th_i + pi/N
                 (ray i lies on facets i and i+1; rays i, i+1 are adjacent);
    (2) lift: L_k = [I_3; [p_k]x], w = L_k f = [f; p_k x f];
    (3) CWC = sum_k L_k pyramid_k = cone{L_k r_{k,i}} (seed, Sec. AWP/FWP; Hirukawa 2006);
    (4) a facet of a Minkowski sum of cones is a sum of faces F_k of the summands, one per
        leg: {0}, one ray, two adjacent rays (a 2D face) or the whole pyramid. A spanning set
        of the facet with independent vectors can always be chosen face by face (greedy: a
        line in a pyramid's span misses some 2D face plane, a plane misses some ray), so the
        normals of the (r - 1)-subsets built from per-leg choices {none, one ray, an adjacent
        pair, three spanning rays} whose dimensions add up to r - 1 contain every facet
        normal; a candidate is kept iff every lifted ray lies on one side (then it spans an
        (r-1)-face: a facet), oriented so that a . w <= 0 on the cone; candidates with the
        same rays on them are the same facet (kept once). The 2032 candidates of 4 legs
        with 4-sided pyramids cost one matrix product per level of their prefix tree
        (linalg.subset_cross_products) and one for the side test.

The CWC is returned as a :class:`~awp_ros.geometry.polytope.Polytope` although it is an unbounded
cone: ``b = 0``, no vertices, ``hull_origin = 0`` and ``meta['kind'] = 'cone'``;
``meta['rays']`` holds the unit lifted rays (one per row).
"""

from __future__ import annotations

from functools import lru_cache
from itertools import product
import math
import threading

import numpy as np

from awp_ros.errors import InputError
from awp_ros.geometry import kernels
from awp_ros.geometry.linalg import (cross3, distinct_columns, GRAM_CERTIFY, identity,
                                     orthonormal_span, subset_cross_products, subset_tree,
                                     SubsetTree, workspace)
from awp_ros.geometry.polytope import Polytope
from awp_ros.wrench.wrench_polytope import lift_points

#: The lifted wrenches ``[r; p_k x r]`` of per-leg rays, eq. (2) (positions (K, 3) [m],
#: rays (K, N, 3) -> (K, N, 6)); :func:`awp_ros.wrench.wrench_polytope.lift_points`.
lift_rays = lift_points

__all__ = ['cone_polytope', 'contact_wrench_cone', 'contact_wrench_cone_unchecked',
           'facets_key', 'friction_pyramid', 'friction_pyramids', 'last_facets', 'lift_rays',
           'pyramid_rays', 'record_facets', 'reset_reuse', 'reuse_counts', 'CONE_TOL']

#: Default tolerance of the cone's span, facet sides and ranks, and of a frictionless contact.
CONE_TOL = 1e-9


def friction_pyramid(normal: np.ndarray, mu: float, sides: int = 4, *,
                     parallel_tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    r"""
    Return the unit rays and the unit outward facet normals of a friction pyramid, eq. (1).

    .. math:: \{f : (\cos\theta_i t_1 + \sin\theta_i t_2) \cdot f \le
              \mu \cos(\pi/N)\, n \cdot f,\; i = 0..N-1\}

    inscribed in the friction cone of coefficient ``mu`` around the unit contact normal
    ``n`` (world frame), with ``t1`` the normalised projection of world x on the contact
    plane (world y when x is parallel to n) and ``t2 = n x t1``. For ``N = 4`` this is
    ``|f.t1|, |f.t2| <= mu/sqrt(2) f.n``. ``n . f >= 0`` follows from the facets.
    Ray ``i`` lies on facets ``i`` and ``i + 1`` (mod N); with ``mu = 0`` every ray is ``n``.

    :param normal: contact normal ``(3,)`` pointing into the robot (world frame), any length.
    :param mu: friction coefficient (>= 0).
    :param sides: number of sides N >= 3.
    :param parallel_tol: world x counts as parallel to n when ``|n x x|`` is below this.
    :return: ``(rays (N, 3), facet_normals (N, 3))``, unit rows.
    :raises InputError: for a zero or non-finite normal, negative or non-finite mu, N < 3.
    """
    rays, facets = friction_pyramids(np.reshape(normal, (1, -1)) if np.size(normal) == 3
                                     else np.asarray(normal), np.asarray([mu]), sides,
                                     parallel_tol=parallel_tol)
    return rays[0], facets[0]


def friction_pyramids(normals: np.ndarray, mu: np.ndarray, sides: int = 4, *,
                      parallel_tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """
    Return :func:`friction_pyramid` for K contacts at once, eq. (1).

    :param normals: contact normals ``(K, 3)`` (world frame, into the robot), any length.
    :param mu: friction coefficients ``(K,)``, each >= 0.
    :param sides: number of sides N >= 3.
    :return: ``(rays (K, N, 3), facet_normals (K, N, 3))``, unit vectors.
    :raises InputError: as :func:`friction_pyramid`, naming the contact index.
    """
    n = np.asarray(normals, dtype=float)
    mu = np.asarray(mu, dtype=float)
    if n.ndim != 2 or n.shape[1] != 3 or mu.shape != (n.shape[0],):
        msg = (f'friction pyramids need normals (K, 3) and mu (K,); got {n.shape} and '
               f'{mu.shape}')
        raise InputError(msg)
    norm = np.linalg.norm(n, axis=1)
    bad = ~np.isfinite(norm) | (norm == 0.0)
    if np.any(bad):
        k = int(np.argmax(bad))
        msg = f'contact normal {k} must be a finite non-zero 3-vector; got {n[k].tolist()}'
        raise InputError(msg)
    bad = ~(np.isfinite(mu) & (mu >= 0.0))
    if np.any(bad):
        k = int(np.argmax(bad))
        msg = f'friction coefficient {k} must be finite and >= 0; got {mu[k]!r}'
        raise InputError(msg)
    if int(sides) != sides or sides < 3:
        msg = f'friction pyramid needs an integer number of sides >= 3; got {sides!r}'
        raise InputError(msg)
    n = n / norm[:, None]
    t1 = np.eye(3)[0] - n[:, :1] * n
    t1_norm = np.linalg.norm(t1, axis=1)
    along_x = t1_norm <= parallel_tol
    if np.any(along_x):
        t1[along_x] = np.eye(3)[1] - n[along_x, 1:2] * n[along_x]
        t1_norm = np.linalg.norm(t1, axis=1)
    t1 /= t1_norm[:, None]
    t2 = cross3(n, t1)
    c_th, s_th, c_ph, s_ph = _angles(int(sides))
    facets = (c_th[None, :, None] * t1[:, None, :] + s_th[None, :, None] * t2[:, None, :]
              - (mu * np.cos(np.pi / sides))[:, None, None] * n[:, None, :])
    facets /= np.linalg.norm(facets, axis=2)[:, :, None]
    rays = n[:, None, :] + mu[:, None, None] * (c_ph[None, :, None] * t1[:, None, :]
                                                + s_ph[None, :, None] * t2[:, None, :])
    rays /= np.linalg.norm(rays, axis=2)[:, :, None]
    return rays, facets


@lru_cache(maxsize=16)
def _angles(sides: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return cos/sin of the facet angles th_i and of the ray angles ph_i of eq. (1)."""
    th = 2.0 * np.pi * np.arange(sides) / sides
    ph = th + np.pi / sides
    return np.cos(th), np.sin(th), np.cos(ph), np.sin(ph)


def contact_wrench_cone(positions: np.ndarray, normals: np.ndarray,
                        friction_coefficients: np.ndarray | float, sides: int = 4, *,
                        span_tol: float = CONE_TOL, rank_tol: float = CONE_TOL,
                        side_tol: float = CONE_TOL,
                        frictionless_tol: float = CONE_TOL) -> Polytope:
    r"""
    Return the exact H-representation of the contact wrench cone, eqs. (3-4).

    .. math:: \mathrm{CWC} = \{\textstyle\sum_k L_k f_k : f_k \in \mathcal{P}_k\}
              = \{w \in \mathrm{span} : a_i \cdot w \le 0\}

    :param positions: foot positions ``(K, 3)`` [m] relative to the CoM, world axes.
    :param normals: contact normals ``(K, 3)`` (world frame, into the robot).
    :param friction_coefficients: ``(K,)`` or a scalar, each >= 0.
    :param sides: pyramid sides N >= 3.
    :param span_tol: relative singular-value cut for the dimension r of the cone's span.
    :param rank_tol: candidate subsets with unit-scaled volume at most this are skipped.
    :param side_tol: a lifted unit ray with ``a . r`` above this is on the wrong side, and
        with ``|a . r|`` at most this it lies on the facet ``a`` (candidates with the same
        rays on them are one facet).
    :param frictionless_tol: a friction coefficient at most this is 0 (the contact's pyramid
        is its normal ray; a pyramid of width ~mu would make rank-deficient candidates).
    :return: the cone as a :class:`Polytope` (``b = 0``, no vertices, ``meta['kind'] =
        'cone'``, ``meta['rays']`` the unit lifted rays ``(K N, 6)``); ``{0}`` for K = 0.
    :raises InputError: on bad shapes, non-finite values, negative mu or N < 3.
    """
    P = np.asarray(positions, dtype=float).reshape(-1, 3) if np.size(positions) else \
        np.zeros((0, 3))
    N_ = np.asarray(normals, dtype=float).reshape(-1, 3) if np.size(normals) else \
        np.zeros((0, 3))
    K = P.shape[0]
    # (A finite sum: all finite, the usual case; else the exact test decides.)
    if N_.shape[0] != K or not (math.isfinite(P.sum()) or np.isfinite(P).all()):
        msg = (f'contact_wrench_cone needs finite positions (K, 3) and normals (K, 3); '
               f'got {np.shape(positions)} and {np.shape(normals)}')
        raise InputError(msg)
    try:
        mu = np.asarray(friction_coefficients, dtype=float)
        mu = np.ascontiguousarray(mu if mu.shape == (K,) else np.broadcast_to(mu, (K,)))
    except ValueError as exc:
        msg = f'friction coefficients must be a scalar or ({K},); got {friction_coefficients!r}'
        raise InputError(msg) from exc
    if int(sides) != sides or sides < 3:
        msg = f'friction pyramid needs an integer number of sides >= 3; got {sides!r}'
        raise InputError(msg)
    return contact_wrench_cone_unchecked(P, N_, mu, int(sides), span_tol=span_tol,
                                         rank_tol=rank_tol, side_tol=side_tol,
                                         frictionless_tol=frictionless_tol)


def contact_wrench_cone_unchecked(P: np.ndarray, N_: np.ndarray, mu: np.ndarray, sides: int,
                                  *, span_tol: float = CONE_TOL, rank_tol: float = CONE_TOL,
                                  side_tol: float = CONE_TOL,
                                  frictionless_tol: float = CONE_TOL) -> Polytope:
    """
    Return :func:`contact_wrench_cone` of inputs it has checked already (eqs. (3-4)).

    :param P: feet (K, 3) [m] and :param N_: normals (K, 3), finite float arrays;
        :param mu: (K,) contiguous float array, each >= 0; :param sides: an int >= 3 (the
        evaluator's own, per cycle). Tolerances as :func:`contact_wrench_cone`.
    """
    K = P.shape[0]
    if K and float(mu.min()) > frictionless_tol:
        frictionless = (False,) * K
    else:
        frictionless = tuple(abs(m) <= frictionless_tol for m in mu.tolist())
        if any(frictionless):
            mu = np.where(frictionless, 0.0, mu)
    origin = np.zeros(6)
    if K == 0:
        return Polytope(0, np.zeros((1, 6)), np.zeros((0, 6)), np.zeros(0), origin,
                        np.zeros((6, 0)), {'kind': 'cone', 'rays': np.zeros((0, 6))})
    rays = pyramid_rays(N_, mu, sides)
    full = False
    if kernels.ENABLED and K >= 2 and K * sides <= kernels.MAX_BITS:
        lifted, full = kernels.lifted_rays(P, rays, max(span_tol ** 2, GRAM_CERTIFY))
    else:
        lifted = lift_rays(P, rays).reshape(K * sides, 6)
        lifted /= np.sqrt(np.einsum('ij,ij->i', lifted, lifted))[:, None]
    # Full rank certified as orthonormal_span would (the kernel), else its SVD decides.
    U = identity(6) if full else None
    pair = _pair_basis(P, lifted, span_tol) if K == 2 and kernels.ENABLED else None
    if pair is not None:
        normal, U = pair
    elif U is None:
        U = orthonormal_span(lifted, rtol=span_tol)
    r = U.shape[1]
    rh = lifted if r == 6 else lifted @ U                               # (K N, r)
    subsets, tree = _candidates(K, sides, r, frictionless)
    if kernels.ENABLED and r == 6 and rh.shape[0] <= kernels.MAX_BITS:
        A = _kernel_facets(rh, subsets, facets_key(rays, r), side_tol, rank_tol)
    elif kernels.ENABLED and 3 <= r < 6 and rh.shape[0] <= kernels.MAX_BITS:
        A = kernels.flat_cone_facets(rh, subsets, side_tol, rank_tol)
    else:
        A = _facets(rh, tree, r, side_tol, rank_tol)
    if r < 6:
        A = A @ U.T
    cone = cone_polytope(A, lifted, U)
    return cone if pair is None else cone.with_hyperplane(normal)


def cone_polytope(A: np.ndarray, lifted: np.ndarray, U: np.ndarray) -> Polytope:
    """Return the CWC of facet rows ``A`` (k, 6), unit ``lifted`` rays and hull basis ``U``."""
    return Polytope(U.shape[1], np.zeros((0, 6)), A, np.zeros(A.shape[0]), np.zeros(6), U,
                    {'kind': 'cone', 'rays': lifted})


def pyramid_rays(normals: np.ndarray, mu: np.ndarray, sides: int) -> np.ndarray:
    """Return the pyramids' rays ``(K, sides, 3)`` of unit ``normals`` (K, 3), ``mu`` (K,)."""
    return _cached_rays(np.ascontiguousarray(normals).tobytes(), mu.tobytes(), sides)


def facets_key(rays: np.ndarray, r: int) -> tuple:
    """Return what fixes a cone's candidates and pyramids: stance, sides, rank, the rays."""
    return rays.shape[0], rays.shape[1], r, rays.tobytes()


def _pair_basis(P: np.ndarray, lifted: np.ndarray,
                span_tol: float) -> tuple[np.ndarray, np.ndarray] | None:
    r"""
    Return ``(n, U)`` of two feet's wrench hyperplane when it spans their lifted rays, else None.

    The closed-form ``(n, U)`` of :func:`awp_ros.geometry.kernels.pair_hyperplane` replaces
    :func:`~awp_ros.geometry.linalg.orthonormal_span`'s SVD when it decides the same rank 5:
    the unit rays' component along ``n`` (rounding) is at most ``span_tol`` (so the sixth
    singular value is below ``span_tol`` times the first, which is >= 1), and the rays in
    hull coordinates pass ``orthonormal_span``'s own full-rank certificate (both tests
    compiled in :func:`~awp_ros.geometry.kernels.pair_basis`; when the certificate does not
    hold, ``orthonormal_span``'s SVD decides).
    """
    n, U, status = kernels.pair_basis(P, lifted, span_tol, max(span_tol ** 2, GRAM_CERTIFY))
    if status == 1:
        return None
    # Status 2: the Gram test did not certify the rank; orthonormal_span's SVD decides.
    return (n, U) if status == 0 or orthonormal_span(lifted @ U, rtol=span_tol).shape == (5, 5) \
        else None


def _kernel_facets(rh: np.ndarray, subsets: np.ndarray, key: tuple, side_tol: float,
                   rank_tol: float) -> np.ndarray:
    """
    Return the facets by the compiled kernels, reusing the last cycle's when still valid.

    Between control cycles the feet move little relative to the CoM and the facets keep
    their rays: :func:`awp_ros.geometry.kernels.cone_recheck` verifies the previous facets
    on the new rays (same incidences, every other ray strictly inside) and only when that
    fails are they searched again: by the double description method
    (:func:`~awp_ros.geometry.kernels.cone_double_description`, ~3x faster than the
    candidates on four legs), and by all candidates when that fails. ``key``: what fixes
    the candidates and the pyramids (stance count, sides, dimension, the unlifted rays).
    One entry per thread.
    """
    last = last_facets(key)
    if last is not None:
        A = kernels.cone_recheck(rh, *last, side_tol, rank_tol)
        if A is not None:
            record_facets(key, *last, reused=True)
            return A
    found = kernels.cone_double_description(rh, side_tol, rank_tol)
    A, spans, masks = found if found is not None else \
        kernels.cone_facets(rh, subsets, side_tol, rank_tol)
    record_facets(key, spans, masks, reused=False)
    return A


_LAST = threading.local()


def last_facets(key: tuple) -> tuple[np.ndarray, np.ndarray] | None:
    """Return this thread's last cone's ``(spans, masks)`` when found for ``key``, else None."""
    last = getattr(_LAST, 'facets', None)
    return (last[1], last[2]) if last is not None and last[0] == key else None


def record_facets(key: tuple, spans: np.ndarray, masks: np.ndarray, *, reused: bool) -> None:
    """Count a reuse of the last facets, or keep new ones (``spans``, ``masks``) for ``key``."""
    if reused:
        _LAST.reused = getattr(_LAST, 'reused', 0) + 1
    else:
        _LAST.facets = (key, spans, masks)
        _LAST.searched = getattr(_LAST, 'searched', 0) + 1


def reset_reuse() -> None:
    """Forget this thread's last facets (the next cone is searched in full)."""
    _LAST.facets = None


def reuse_counts() -> tuple[int, int]:
    """Return this thread's ``(reused, searched)``: cones from the last facets, and in full."""
    return getattr(_LAST, 'reused', 0), getattr(_LAST, 'searched', 0)


def _facets(rh: np.ndarray, tree: SubsetTree, r: int, side_tol: float,
            rank_tol: float) -> np.ndarray:
    """
    Return the unit outward facet normals (hull coordinates) from the candidate subsets.

    Eq. (4) in numpy, the reference of :func:`awp_ros.geometry.kernels.cone_facets`.
    """
    a = subset_cross_products(rh.T, tree, unit=True)           # (m, r), |a| = volume
    vol = np.sqrt(np.square(a) @ np.ones(r))
    # Side test of the unit normal a / |a|, done on a with the tolerance scaled by the
    # volume. Reduce along the long axis (numpy is slow along a short inner one).
    s = np.matmul(rh, a.T, out=workspace('cwc_sides', (rh.shape[0], a.shape[0])))
    slack = side_tol * vol
    below = np.max(s, axis=0) <= slack
    keep = np.flatnonzero((below | (np.min(s, axis=0) >= -slack)) & (vol > rank_tol))
    A = a[keep] * (np.where(below[keep], 1.0, -1.0) / vol[keep])[:, None]
    # One row per facet: a facet is determined by the rays on it (its incidence).
    tight = np.abs(s[:, keep]) <= slack[keep]
    return A[distinct_columns(tight, own=r - 1)]


@lru_cache(maxsize=256)
def _cached_rays(normals: bytes, mu: bytes, sides: int) -> np.ndarray:
    """
    Return the pyramid rays ``(K, N, 3)`` of :func:`friction_pyramids`, memoised.

    Contact normals and friction coefficients rarely change between control cycles; the
    key is their exact bytes, so a hit returns exactly what the computation would.
    """
    rays, _ = friction_pyramids(np.frombuffer(normals).reshape(-1, 3), np.frombuffer(mu),
                                sides)
    rays.setflags(write=False)
    return rays


@lru_cache(maxsize=64)
def _candidates(K: int, sides: int, r: int,
                frictionless: tuple[bool, ...]) -> tuple[np.ndarray, SubsetTree]:
    """
    Return the candidate ray subsets of eq. (4), ``(m, r - 1)``, and their prefix tree.

    Within a subset the larger faces come first (whole pyramids, then 2D faces, then rays),
    so that many candidates share their first vectors (fewer distinct tree prefixes).
    """
    faces = [_leg_faces(sides, flat, k * sides) for k, flat in enumerate(frictionless)]
    rows = {}
    for dims in product(*(range(len(f)) for f in faces)):
        if sum(dims) != r - 1:
            continue
        order = sorted(range(K), key=lambda k: (-dims[k], k))
        for choice in product(*(faces[k][dims[k]] for k in order)):
            row = tuple(i for face in choice for i in face)
            rows.setdefault(tuple(sorted(row)), row)
    subsets = np.array(sorted(rows.values()), dtype=np.intp).reshape(len(rows), r - 1)
    subsets.setflags(write=False)
    return subsets, subset_tree(subsets)


def _leg_faces(sides: int, frictionless: bool, offset: int) -> list[list[tuple[int, ...]]]:
    """Return, per face dimension 0..3, the ray-index tuples spanning the pyramid's faces."""
    if frictionless:
        return [[()], [(offset,)]]
    ray = [(offset + i,) for i in range(sides)]
    pair = [tuple(sorted((offset + i, offset + (i + 1) % sides))) for i in range(sides)]
    whole = [(offset, offset + sides // 3, offset + (2 * sides) // 3)]
    return [[()], ray, pair, whole]
