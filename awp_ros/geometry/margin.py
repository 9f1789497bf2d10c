r"""
Signed Euclidean margins of a point with respect to a polytope, and directional margins.

Every set of awp_ros (force polytopes in R^3, AWP / FWP / FWS in R^6) is a
:class:`~awp_ros.geometry.polytope.Polytope` ``P = {x : A x <= b, x = o + U y}`` of affine
dimension ``r``. For a point ``w`` (a wrench ``[f; tau]`` in [N] and [N.m], world-aligned axes,
origin at the CoM; or a force in [N]) this module reports

.. math::

    \rho = \mathrm{dist}(w, \mathrm{aff}\,P), \qquad
    \bar w = o + U U^T (w - o), \qquad
    m_h = \begin{cases} \mathrm{dist}(\bar w, \partial P) & \bar w \in P \\
                        -\mathrm{dist}(\bar w, P) & \bar w \notin P \end{cases}

    m = \begin{cases} m_h & \rho \le \epsilon_h \\
                      -\sqrt{\rho^2 + \max(0, -m_h)^2} = -\mathrm{dist}(w, P)
                      & \rho > \epsilon_h \end{cases}

where the boundary is relative to the affine hull: ``m_h`` (``margin_in_hull``) is the margin
of the projection inside the hull, and the signed margin ``m`` is negative whenever ``w`` is
not in ``P``: off the hull (farther than the hull tolerance ``eps_h``) it is minus the
Euclidean distance from ``w`` to ``P`` (``P`` lies in its hull, so the distance splits into
the orthogonal parts ``rho`` and ``dist(w_bar, P)``). ``w`` is feasible exactly when
``m >= -eps`` (``feasibility_tol``; ``eps_h >= eps``). Equations used below:

    (1) inside:  m = min_i (b_i - a_i . w) over a complete H-rep with unit rows
                 (redundant valid rows cannot lower the minimum below the true distance);
    (2) outside: m = -min{|x| : G x >= h} (least-distance programming, LDP), solved through
                 the non-negative least squares dual  min{|E u - f| : u >= 0},
                 E = [G^T; h^T], f = e_{r+1}; then x = -(E u - f)_{1..r} / (E u - f)_{r+1}
                 (Lawson & Hanson, *Solving Least Squares Problems*, 1974, ch. 23).

The mixed units of a 6D wrench (N and N.m) are summed as they are: the margin is the
Euclidean distance in these coordinates, as the issue specifies.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from scipy.optimize import nnls

from awp_ros.errors import GeometryError, InputError
from awp_ros.geometry import kernels
from awp_ros.geometry.polytope import Polytope

__all__ = ['least_slack', 'line_interval', 'SetMargin', 'directional_margins', 'polytope_margin']


@dataclass
class SetMargin:
    """
    Signed margin of a point w.r.t. a polytope (see the module docstring).

    :ivar margin: signed Euclidean margin [N, N.m]: the distance to the set's (relative)
        boundary when ``w`` is in the set, minus the distance from ``w`` to the set when it
        is not (off the affine hull included); ``-inf`` for the empty set.
    :ivar margin_in_hull: the margin of ``w``'s projection on the affine hull, measured
        inside the hull (equal to ``margin`` for full-dimensional sets).
    :ivar normal: unit witness normal of shape ``(n,)`` in ambient coordinates: the outward
        normal of the nearest facet (inside) or ``(w - nearest point) / |.|`` (outside),
        restricted to the hull; zeros for a point set, the empty set, or a margin of exactly 0
        outside (ties).
    :ivar dimension: affine dimension of the set (-1 when empty).
    :ivar affine_residual: distance from w to the set's affine hull [N, N.m] (``inf`` if empty).
    :ivar feasible: ``margin >= -feasibility_tol`` (so ``affine_residual <= hull_tol``).
    """

    margin: float
    normal: np.ndarray
    dimension: int
    affine_residual: float
    feasible: bool
    margin_in_hull: float


def polytope_margin(P: Polytope, w: np.ndarray, *, feasibility_tol: float = 1e-6,
                    hull_tol: float | None = None, row_tol: float = 1e-12,
                    working_set: int = 24, slack: tuple[int, float] | None = None
                    ) -> SetMargin:
    r"""
    Return the signed Euclidean margin of ``w`` with respect to ``P``.

    .. math:: m(w) = \pm\, \mathrm{dist}(\bar w, \partial P), \quad
              \bar w = \mathrm{proj}_{\mathrm{aff}\,P}(w)

    Works in hull coordinates ``y = U^T (w - o)``, so full-dimensional and flat sets (1 or 2
    stance legs) are treated alike. Inside: eq. (1) of the module docstring; outside: exact
    nearest point by eq. (2) with :func:`scipy.optimize.nnls`.

    :param P: the polytope (or polyhedral cone with ``b = 0``), complete H-rep required;
        redundant rows are allowed.
    :param w: point of shape ``(n,)``, same units and frame as ``P`` ([N] or [N, N.m]).
    :param feasibility_tol: tolerance on the margin for ``feasible`` [same units as w].
    :param hull_tol: distance from the affine hull up to which ``w`` counts as on it
        (default ``feasibility_tol``; at least ``feasibility_tol``) [same units as w]: with
        1-2 stance legs a measured wrench is on the flat sets' hull only up to its
        estimation error.
    :param row_tol: rows whose projection on the hull's direction space is shorter than this
        are constant constraints and are dropped (a violated one means an empty set).
    :param working_set: initial number of most-violated rows in the least-distance problem;
        violated rows are added until the nearest point satisfies every row (exact).
    :param slack: ``(i, s_i)``, the first row of least slack ``s = b - A w`` as
        :func:`~awp_ros.geometry.kernels.slack_min` returns it, when the caller has it
        (the per-cycle compiled call); computed here otherwise (by that function when the
        kernels are on, so the bits are the same either way).
    :return: a :class:`SetMargin`.
    :raises InputError: when ``w`` has the wrong shape or is not finite.
    :raises GeometryError: when the non-negative least-squares solve fails.
    """
    n = P.ambient_dim
    w = _check_point(w, n)
    if slack is not None and slack[1] >= 0.0 and P.dimension == n:
        # Full-dimensional and inside, from the caller's slack: eq. (1), nothing off the hull.
        return SetMargin(slack[1], P.A[slack[0]].copy(), n, 0.0, True, slack[1])
    hull_tol = feasibility_tol if hull_tol is None else max(hull_tol, feasibility_tol)
    if P.is_empty:
        return SetMargin(-np.inf, np.zeros(n), -1, np.inf, False, -np.inf)
    U = P.hull_basis
    o = P.hull_origin
    d = w - o
    r = U.shape[1]
    if r == n:                      # full-dimensional: y = d, nothing off the hull
        y, off_hull, residual = d, np.zeros(n), 0.0
    else:
        y = U.T @ d
        off_hull = d - U @ y
        residual = float(np.linalg.norm(off_hull))
    if r == 0:
        return _signed(0.0, np.zeros(n), 0, residual, feasibility_tol, hull_tol, d)
    # Eq. (1): the rows lie in the hull's direction space, so A w = A proj(w).
    if P.b.size == 0:
        return _signed(np.inf, np.zeros(n), P.dimension, residual, feasibility_tol, hull_tol,
                       off_hull)
    i, s_i = least_slack(P.A, P.b, w) if slack is None else slack
    if s_i >= 0.0:
        margin = s_i
        normal = P.A[i].copy()
    else:
        s = P.b - P.A @ w
        if r == n:
            # Full-dimensional: eq. (2) directly in ambient coordinates.
            G, h = P.A, s
        else:
            G, h = _hull_rows(P, y, row_tol)
            if G is None:
                return SetMargin(-np.inf, np.zeros(n), -1, np.inf, False, -np.inf)
        x = _least_distance(-G, -h, working_set=working_set)
        dist = float(np.linalg.norm(x))
        margin = -dist
        normal = -x / dist if dist > 0.0 else np.zeros(x.shape[0])
        if r < n:
            normal = U @ normal
    return _signed(margin, normal, P.dimension, residual, feasibility_tol, hull_tol,
                   off_hull)


def _signed(m_hull: float, normal: np.ndarray, dimension: int, residual: float, tol: float,
            hull_tol: float, off_hull: np.ndarray) -> SetMargin:
    """
    Return the SetMargin of a point whose in-hull margin is ``m_hull`` (module docstring).

    :param off_hull: ``w - proj(w)``, the component of ``w`` off the hull (the witness when
        ``w`` is off the hull and its projection inside the set).
    """
    if residual <= hull_tol:
        return SetMargin(m_hull, normal, dimension, residual, m_hull >= -tol, m_hull)
    outside = max(0.0, -m_hull)
    dist = float(np.hypot(residual, outside))
    # The nearest point's direction: the off-hull part plus the in-hull outward part.
    witness = off_hull + (outside * normal if outside > 0.0 else 0.0)
    norm = float(np.linalg.norm(witness))
    witness = witness / norm if norm > 0.0 else witness
    return SetMargin(-dist, witness, dimension, residual, False, m_hull)


def directional_margins(P: Polytope, w: np.ndarray, directions: np.ndarray | None = None, *,
                        feasibility_tol: float = 1e-6,
                        parallel_tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    r"""
    Return how far ``w`` can move along each direction (and its opposite) inside ``P``.

    .. math:: t^+_i = \max\{t : w + t\, d_i \in P\}, \qquad
              t^-_i = \max\{t : w - t\, d_i \in P\}

    i.e. the line ``w + t d_i`` meets ``P`` in the interval ``[-t^-_i, t^+_i]``. For ``w`` in
    ``P`` both are >= 0 (extra force [N] or moment [N.m] admissible along the axis); for ``w``
    outside, the interval may not contain 0 (one of them is negative). Computed exactly by the
    ratio test on the complete H-rep (redundant rows are harmless). For a flat ``P`` the line
    lies in the affine hull only if ``d_i`` is in its direction space and ``w`` within
    ``feasibility_tol`` of it; a transversal line meets the hull in at most one point
    ``t_0`` (then ``t^+ = t_0``, ``t^- = -t_0`` if that point is in ``P``). ``NaN`` when the
    line misses ``P``; ``inf`` along a recession direction of a cone.

    :param P: the polytope (or cone).
    :param w: point of shape ``(n,)`` [N, N.m].
    :param directions: array ``(k, n)`` of directions (not necessarily unit; t is measured in
        multiples of them); default the ``n`` unit axes (fx, fy, fz, mx, my, mz in 6D).
    :param feasibility_tol: tolerance on hull distance and on constraints [same units as w].
    :param parallel_tol: ``|a . d|`` or the transversal component of ``d`` below this counts
        as zero.
    :return: ``(t_plus, t_minus)``, each of shape ``(k,)``.
    :raises InputError: on bad shapes or non-finite values.
    """
    n = P.ambient_dim
    w = _check_point(w, n)
    D = np.eye(n) if directions is None else np.asarray(directions, dtype=float)
    if D.ndim != 2 or D.shape[1] != n or not np.isfinite(D).all():
        msg = f'directions must be a finite array of shape (k, {n}); got shape {D.shape}'
        raise InputError(msg)
    k = D.shape[0]
    nan = np.full(k, np.nan)
    if P.is_empty:
        return nan, nan.copy()
    U, o = P.hull_basis, P.hull_origin
    if U.shape[1] == n and kernels.ENABLED:     # full-dimensional: the ratio test alone
        t_plus, t_minus, empty = kernels.ratio_test(P.A, P.b, w, D, feasibility_tol,
                                                    parallel_tol)
        t_plus[empty] = np.nan
        t_minus[empty] = np.nan
        return t_plus, t_minus
    s = P.b - P.A @ w
    Gt = D @ P.A.T  # (k, m): one row per direction, reductions along the long axis
    t_plus, t_minus, empty = line_interval(s, Gt, feasibility_tol, parallel_tol)
    if U.shape[1] == n:
        t_plus[empty] = np.nan
        t_minus[empty] = np.nan
        return t_plus, t_minus
    # Flat P: components of w - o and of each d orthogonal to the affine hull.
    q = (w - o) - U @ (U.T @ (w - o))
    V = D - (D @ U) @ U.T
    vv = np.einsum('kn,kn->k', V, V)
    transversal = np.sqrt(vv) > parallel_tol
    t0 = np.where(transversal, -(V @ q) / np.where(transversal, vv, 1.0), 0.0)
    miss = np.linalg.norm(q[None, :] + t0[:, None] * V, axis=1) > feasibility_tol
    # Transversal directions: the single hull point w + t0 d must lie in P.
    out = np.any(Gt * t0[:, None] > s[None, :] + feasibility_tol, axis=1)
    t_plus = np.where(transversal, t0, t_plus)
    t_minus = np.where(transversal, -t0, t_minus)
    bad = miss | np.where(transversal, out, empty)
    t_plus[bad] = np.nan
    t_minus[bad] = np.nan
    return t_plus, t_minus


def line_interval(s: np.ndarray, Gt: np.ndarray, feasibility_tol: float,
                  parallel_tol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return ``(t_hi, -t_lo, empty)`` of ``{t : t Gt[j, i] <= s_i for every row i}``.

    The ratio test of the lines ``x + t d_j`` in ``{A x <= b}`` (``s = b - A x``,
    ``Gt[j] = A d_j``); ``empty_j`` when ``t_lo > t_hi + feasibility_tol`` or a row parallel
    to ``d_j`` (``|Gt| <= parallel_tol``) has ``s_i < -feasibility_tol``. Compiled:
    :func:`awp_ros.geometry.kernels.ratio_test`.
    """
    pos = Gt > parallel_tol
    neg = Gt < -parallel_tol
    with np.errstate(divide='ignore', invalid='ignore'):
        ratio = s[None, :] / Gt
    t_hi = np.where(pos, ratio, np.inf).min(axis=1, initial=np.inf)
    t_lo = np.where(neg, ratio, -np.inf).max(axis=1, initial=-np.inf)
    empty = t_lo > t_hi + feasibility_tol
    if s.size and np.min(s) < -feasibility_tol:
        empty |= np.any(~(pos | neg) & (s[None, :] < -feasibility_tol), axis=1)
    return t_hi, -t_lo, empty


def least_slack(A: np.ndarray, b: np.ndarray, w: np.ndarray) -> tuple[int, float]:
    """
    Return ``(i, s_i)``: the first row of least slack ``s = b - A w``; ``(-1, inf)`` without rows.

    :func:`~awp_ros.geometry.kernels.slack_min` when the kernels are on (the per-cycle compiled
    call uses the same code: the same bits), else numpy (the reference).
    """
    if kernels.ENABLED:
        return kernels.slack_min(A, b, w)
    if b.size == 0:
        return -1, np.inf
    s = b - A @ w
    i = int(s.argmin())
    return i, float(s[i])


def _check_point(w: np.ndarray, n: int) -> np.ndarray:
    """Return ``w`` as a finite float vector of shape ``(n,)`` or raise InputError."""
    if type(w) is np.ndarray and w.dtype == np.float64 and w.shape == (n,) \
            and math.isfinite(w.sum()):        # a finite sum: every entry finite (fast path)
        return w
    arr = np.asarray(w, dtype=float)
    if arr.shape != (n,):
        msg = f'point must have shape ({n},); got shape {arr.shape}'
        raise InputError(msg)
    if not np.isfinite(arr).all():
        msg = f'point must be finite; got {arr.tolist()}'
        raise InputError(msg)
    return arr


def _hull_rows(P: Polytope, y: np.ndarray,
               row_tol: float) -> tuple[np.ndarray | None, np.ndarray]:
    """
    Return the unit rows in hull coordinates and the slacks ``b_r - A_r y``.

    ``(None, _)`` when a constant row is violated (the set is empty).
    """
    A_r = P.A @ P.hull_basis
    b_r = P.b - P.A @ P.hull_origin
    norms = np.sqrt(np.einsum('mr,mr->m', A_r, A_r))
    keep = norms > row_tol
    if np.any(~keep & (b_r < 0.0)):
        return None, np.zeros(0)
    A_r = A_r[keep] / norms[keep, None]
    b_r = b_r[keep] / norms[keep]
    return A_r, b_r - A_r @ y


def _least_distance(G: np.ndarray, h: np.ndarray, *, working_set: int = 24,
                    violation_tol: float = 1e-12) -> np.ndarray:
    """
    Return the minimum-norm ``x`` with ``G x >= h`` (eq. 2), by constraint generation.

    The LDP is solved on a working set of rows (the most violated at ``x = 0`` first); its
    solution is a lower bound, and optimal for all rows once it satisfies them all, else the
    violated rows join the set. Each sub-problem is Lawson-Hanson's NNLS dual.
    """
    m = G.shape[0]
    scale = float(np.max(np.abs(h), initial=0.0))
    tol = violation_tol * max(scale, 1.0)
    active = np.zeros(m, dtype=bool)
    k = min(m, max(working_set, 1))
    active[np.argpartition(-h, k - 1)[:k]] = True
    while True:
        x = _ldp(G[active], h[active])
        violated = (G @ x < h - tol) & ~active
        if not np.any(violated):
            return x
        active |= violated


def _ldp(G: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Return the minimum-norm ``x`` with ``G x >= h`` (Lawson-Hanson LDP via NNLS)."""
    m, r = G.shape
    scale = float(np.max(h, initial=0.0))
    if scale <= 0.0:
        return np.zeros(r)
    E = np.empty((r + 1, m))
    E[:r] = G.T
    np.divide(h, scale, out=E[r])
    f = np.zeros(r + 1)
    f[r] = 1.0
    try:
        u, _ = nnls(E, f, maxiter=max(50, 5 * m))
    except RuntimeError as exc:
        msg = f'least-distance NNLS failed on {m} constraints in dimension {r}: {exc}'
        raise GeometryError(msg) from exc
    res = E @ u
    res[r] -= 1.0
    if -res[r] <= np.finfo(float).eps:
        msg = f'least-distance problem infeasible ({m} constraints in dimension {r})'
        raise GeometryError(msg)
    return res[:r] * (-scale / res[r])
