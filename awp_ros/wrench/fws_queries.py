r"""
Exact per-cycle queries on the feasible wrench set without its H-representation.

For stance feet at ``p_k`` [m] relative to the CoM (world-aligned axes) and per-leg
friction-bounded force polytopes given by their vertices ``V_k`` [N], the FWS is

.. math::

    S = \sum_k L_k\, \mathrm{conv}(V_k), \qquad
    w \in S \iff \exists \lambda_k \ge 0,\ 1^T \lambda_k = 1:\
    \sum_k L_k V_k^T \lambda_k = w                                       \qquad (1)

so membership and the directional margins ``max {t : w +- t e_i in S}`` are linear programs
in the barycentric weights (1), solved exactly (simplex) with warm starts. This answers the
per-cycle questions (is ``w`` feasible, how much extra force or moment along each axis) in
about a millisecond for HyQ's four legs, while the exact H-rep and Euclidean margin
(:mod:`awp_ros.wrench.feasible_wrench_set`) take several.

The same LPs by the compiled dense simplex of the feasible region take about 0.04 ms
(:func:`directional_margins_of_legs`, README "Speed"): the FWS's directional margins every
cycle.

When ``w`` is outside S, its distance to S and the nearest point are a quadratic program over
(1), solved by Wolfe's minimum-norm-point algorithm on the legs' points (:func:`fws_distance`,
a few microseconds): the FWS's signed margin and witness every cycle when it is negative. (Inside,
the margin is the distance to the nearest facet, which needs the facets: the H-rep.)

With two stance legs membership is a one-dimensional LP (:func:`two_leg_contains`): a force
along the line through both feet is the same wrench from either foot, so the force
distributions of a wrench on the legs' hyperplane form a line, cut by each leg's rows in an
interval (a few microseconds, every cycle).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from awp_ros.errors import InputError
from awp_ros.geometry import kernels
from awp_ros.geometry.linalg import cross3
from awp_ros.geometry.margin import line_interval, SetMargin
from awp_ros.wrench.wrench_polytope import lift_matrices

__all__ = ['directional_margins_of_legs', 'directional_of_points', 'fws_distance',
           'lifted_points', 'lp_directional_margins', 'outside_margin_of_points',
           'two_leg_contains']

#: Feet closer than this [m] span no hyperplane: :func:`two_leg_contains` answers None.
FEET_APART = 1e-6
#: ``|a . u|`` below this (unit rows and line) counts as a row parallel to the line.
PARALLEL_TOL = 1e-12
#: :func:`fws_distance`'s tolerances, relative to the scale ``K max |g|`` of the legs' points:
#: the distance's (``DISTANCE_RTOL``) and, squared, the rounding floor of the gap.
DISTANCE_RTOL = 1e-11
GAP_FLOOR_RTOL = 1e-13
#: Largest number of Wolfe iterations (four HyQ legs take 10-30).
MAX_WOLFE_ITERATIONS = 500


def lp_directional_margins(positions: np.ndarray, vertex_sets: Sequence[np.ndarray],
                           w: np.ndarray, *,
                           feasibility_tol: float = 1e-6) -> tuple[bool, np.ndarray, np.ndarray]:
    r"""
    Return membership and directional margins of ``w`` in S exactly, without the H-rep.

    .. math:: t^\pm_i = \max\{t : w \pm t\, e_i \in S\}, \qquad
              S = \sum_k L_k\, \mathrm{conv}(V_k)

    One LP in the barycentric weights ``lam_k >= 0`` (``sum_k L_k V_k^T lam_k - t_i e_i = w``,
    ``1^T lam_k = 1``) solved 13 times with warm starts (primal simplex, HiGHS): ``t = 0``
    for membership, then ``max`` and ``min`` of each ``t_i``. Same conventions as
    :func:`awp_ros.geometry.margin.directional_margins` (``t^+ = t_0, t^- = -t_0`` when the line
    meets a flat S in one point; NaN when it misses S). HiGHS is taken from the copy bundled in
    scipy (measured faster per solve than ``highspy``'s), else from ``highspy``; without
    either, scipy's ``linprog``.

    :param positions: (K, 3) feet relative to the CoM [m], world-aligned axes.
    :param vertex_sets: K arrays (n_k, 3) of points [N].
    :param w: (6,) wrench [N, N.m], same frame.
    :param feasibility_tol: absolute tolerance on the equality rows [N, N.m].
    :return: ``(member, t_plus, t_minus)``, the last two of shape (6,) [N or N.m].
    :raises InputError: on bad shapes or non-finite values.
    """
    P, w = _checked(positions, vertex_sets, w)
    nan = np.full(6, np.nan)
    V = [np.asarray(v, dtype=float).reshape(-1, 3) for v in vertex_sets]
    if any(v.shape[0] == 0 for v in V):
        return False, nan, nan.copy()
    L = lift_matrices(P)
    G = np.hstack([np.zeros((6, 0))] + [Lk @ v.T for Lk, v in zip(L, V)])
    n, K = G.shape[1], len(V)
    scale = max(float(np.max(np.abs(G), initial=0.0)), float(np.max(np.abs(w))), 1.0)
    E = np.zeros((K, n))
    E[np.repeat(np.arange(K), [v.shape[0] for v in V]), np.arange(n)] = 1.0
    A = np.block([[G / scale, -np.eye(6)], [E, np.zeros((K, 6))]])
    rhs = np.concatenate([w / scale, np.ones(K)])
    t_plus, t_minus = nan.copy(), nan.copy()
    solver = _HighsLp(A, rhs, n, max(feasibility_tol / scale, 1e-10))
    member = solver.solve(None, 0.0) is not None
    for i in range(6):
        hi, lo = solver.solve(i, -1.0), solver.solve(i, 1.0)
        if hi is not None and lo is not None:
            t_plus[i], t_minus[i] = hi * scale, -lo * scale
    return member, t_plus, t_minus


def directional_margins_of_legs(positions: np.ndarray, force_A: np.ndarray,
                                force_b: np.ndarray, pyramid_rows: np.ndarray, w: np.ndarray
                                ) -> tuple[np.ndarray, np.ndarray] | None:
    r"""
    Return the FWS's directional margins at ``w`` from the legs' H-reps, by LPs, every cycle.

    .. math:: t^\pm_i = \max\{t : w \pm t\, e_i \in S\}, \qquad
              S = \sum_k L_k\, \bigl(\{f : A_k f \le b_k,\ R_k f \le 0\}\bigr)

    The LPs of :func:`lp_directional_margins` in the barycentric weights of each leg's
    friction-bounded polytope's vertices, solved by the compiled dense simplex of the
    feasible region (:func:`awp_ros.geometry.kernels.directional_margins_lp`: about 0.04 ms
    for four HyQ legs, against about 1.2 ms for HiGHS), the conventions of
    :func:`awp_ros.geometry.margin.directional_margins`.

    :param positions: (K, 3) the feet relative to the CoM [m], world-aligned axes.
    :param force_A: (K, m, 3) and ``force_b`` (K, m) [N]: the legs' full-dimensional force
        polytopes ``A_k f <= b_k``.
    :param pyramid_rows: (K, N + 1, 3) unit rows ``R_k f <= 0``
        (:func:`~awp_ros.wrench.friction_polytope.friction_rows`).
    :param w: (6,) the wrench ``[f; tau]`` [N, N.m], about the CoM, same axes.
    :return: ``(t_plus, t_minus)`` (6,) each [N x3, N.m x3], or None when an LP failed (or
        without the compiled kernels: the FWS's H-rep answers then).
    """
    if not kernels.ENABLED:
        return None
    plus, minus, status = kernels.directional_margins_lp(force_A, force_b, pyramid_rows,
                                                         positions, w)
    return None if status else (plus, minus)


def directional_of_points(K: int, points: tuple, w: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray] | None:
    """
    Return :func:`directional_margins_of_legs` from the legs' lifted points, or None.

    ``points``: ``(G, leg, status)`` of :func:`awp_ros.geometry.kernels.cycle_regions` (the
    feasible region's points, ``K`` legs); ``w`` [N, N.m] the wrench they were projected at.
    """
    plus, minus, status = kernels.directional_margins_of_points(*points[:2], K, points[2], w)
    return None if status else (plus, minus)


def fws_distance(positions: np.ndarray, vertex_sets: Sequence[np.ndarray], w: np.ndarray
                 ) -> tuple[float, np.ndarray, float, int]:
    r"""
    Return the distance from ``w`` to S and S's nearest point, without the H-rep.

    .. math::

        d(w, S) = \min_{s \in S} |s - w|, \qquad S = \sum_k L_k\, \mathrm{conv}(V_k)

    Wolfe's minimum-norm-point algorithm (P. Wolfe, *Finding the nearest point in a
    polytope*, Math. Programming 11, 1976) over ``S - w``, with the linear minimisation
    oracle of a Minkowski sum, one argmin per leg:

    (1) ``q(x) = argmin_{y in S - w} x . y = sum_k L_k v_k(x) - w``,
        ``v_k(x) = argmin_{v in V_k} (L_k^T x) . v``;
    (2) a *corral*: affinely independent points ``y_i`` of ``S - w`` (sums of one vertex
        per leg; at most 6 when ``w`` is outside) whose affine hull's nearest point to 0,
        ``x = sum_i lam_i y_i``, has weights ``lam_i > 0``; each major step adds ``q(x)``,
        and the minor steps, when the affine hull's nearest point leaves the atoms' hull,
        move to the last point inside it and drop the atoms whose weight vanished;
    (3) it stops when the gap ``eps = x . x - x . q(x)`` is small: every ``y`` in ``S - w``
        has ``x . y >= x . q(x)``, so

        .. math:: |x| - \frac{\epsilon}{|x|} \le d(w, S) \le |x|.

    The nearest point is ``s* = w + x`` (a convex combination of sums of vertices, in S up
    to rounding) and the distance ``|x|``, accurate to the bound (3): ``DISTANCE_RTOL``
    times the scale ``K max |g|`` of the lifted points, unless the gap reaches the rounding
    floor (``eps <= GAP_FLOOR_RTOL scale^2``: for a ``w`` a few micro-newtons outside, the
    direction of ``x`` is known to about the machine epsilon times ``scale / |x|``).
    Compiled (:func:`awp_ros.geometry.kernels.min_norm_point`); its reference in the tests
    is the least-distance program on the FWS's H-rep
    (:func:`~awp_ros.geometry.margin.polytope_margin`), a different method.

    :param positions: (K, 3) feet relative to the CoM [m], world-aligned axes.
    :param vertex_sets: K arrays (n_k, 3) of points [N] (each leg's friction-bounded
        polytope's vertices).
    :param w: (6,) wrench [N, N.m], same frame.
    :return: ``(distance, nearest (6,), bound, status)``: ``distance`` [N, N.m] an upper
        bound of ``d(w, S)`` within ``bound`` of it (0 when ``w`` is in S, to the
        tolerance), status 0 converged, 1 not within :data:`MAX_WOLFE_ITERATIONS`, 2 the
        atoms became numerically dependent first, 3 a leg without points (distance inf).
    :raises InputError: on bad shapes or non-finite values.
    """
    P, w = _checked(positions, vertex_sets, w)
    G, leg, _ = lifted_points(P, vertex_sets)
    return _distance(G, leg, len(vertex_sets), w)


def lifted_points(positions: np.ndarray, vertex_sets: Sequence[np.ndarray]
                  ) -> tuple[np.ndarray, np.ndarray, int]:
    """
    Return the legs' lifted points ``[v; p_k x v]`` as the per-cycle kernels give them.

    ``(G (6, n), leg (n,), status)``, each leg's points contiguous, status 1 when a leg has
    none (:func:`awp_ros.geometry.kernels.cycle_regions`' last entry).
    """
    V = [np.asarray(v, dtype=float).reshape(-1, 3) for v in vertex_sets]
    L = lift_matrices(np.asarray(positions, dtype=float).reshape(-1, 3))
    G = np.hstack([np.zeros((6, 0))] + [Lk @ v.T for Lk, v in zip(L, V)])
    leg = np.repeat(np.arange(len(V)), [v.shape[0] for v in V])
    return G, leg, int(any(v.shape[0] == 0 for v in V))


def outside_margin_of_points(K: int, points: tuple, w: np.ndarray, feasibility_tol: float
                             ) -> tuple[SetMargin | None, str]:
    """
    Return the FWS's signed margin of a wrench outside it, from the legs' lifted points.

    ``points``: ``(G, leg, status)`` of :func:`awp_ros.geometry.kernels.cycle_regions` (the
    feasible region's points, ``K >= 3`` legs: a 6D FWS), ``w`` [N, N.m] a wrench the
    feasible region found outside. The margin is ``-d(w, S)`` (:func:`fws_distance`), the
    witness the unit direction from the nearest point to ``w``, as
    :func:`~awp_ros.geometry.margin.polytope_margin` reports them on the H-rep:
    ``dimension`` 6, ``affine_residual`` 0, ``feasible`` when ``d <= feasibility_tol``.

    :return: ``(margin, problem)``: the margin and ``''``; or None and ``''`` without
        points (a leg without vertices: no region either); or None and the reason when
        Wolfe's algorithm did not converge, or stopped by rounding with a bound above
        ``feasibility_tol`` (the caller reports it as a warning).
    """
    G, leg, status = points
    if status != 0 or G.shape[1] == 0:
        return None, ''
    d, nearest, bound, status = _distance(G, leg, K, w)
    if status != 0 and not (status == 2 and bound <= feasibility_tol):
        return None, (f"FWS distance: Wolfe's algorithm stopped (status {status}) at "
                      f'{d:.6g} with a bound {bound:.3g} [N, N.m]; margin left to the FWS')
    normal = (w - nearest) / d if d > 0.0 else np.zeros(6)
    return SetMargin(margin=-d, normal=normal, dimension=6, affine_residual=0.0,
                     feasible=bool(d <= feasibility_tol), margin_in_hull=-d), ''


def _checked(positions: np.ndarray, vertex_sets: Sequence[np.ndarray], w: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """Return ``positions`` (K, 3) and ``w`` (6,) as float arrays, or raise InputError."""
    P = np.asarray(positions, dtype=float)
    w = np.asarray(w, dtype=float)
    if P.ndim != 2 or P.shape[1] != 3 or len(vertex_sets) != P.shape[0]:
        msg = f'positions {P.shape} and {len(vertex_sets)} vertex sets do not match'
        raise InputError(msg)
    if w.shape != (6,) or not np.isfinite(w).all() or not np.isfinite(P).all():
        raise InputError(f'w must be a finite (6,) wrench; got shape {w.shape}')
    return P, w


def _distance(G: np.ndarray, leg: np.ndarray, K: int, w: np.ndarray
              ) -> tuple[float, np.ndarray, float, int]:
    """Return :func:`fws_distance`'s answer from the lifted points ``G`` (6, n) and ``leg``."""
    scale = K * float(np.max(np.abs(G), initial=0.0)) + float(np.max(np.abs(w)))
    d, nearest, bound, _, status = kernels.min_norm_point(
        G, leg, K, w, DISTANCE_RTOL * scale, GAP_FLOOR_RTOL * scale ** 2, MAX_WOLFE_ITERATIONS)
    return d, nearest, bound, status


def two_leg_contains(positions: np.ndarray, force_A: np.ndarray, force_b: np.ndarray,
                     pyramid_rows: np.ndarray, w: np.ndarray, *, hull_tol: float,
                     feasibility_tol: float = 1e-6) -> bool | None:
    r"""
    Return whether ``w`` is in the FWS of two stance legs, by an LP on the definition.

    .. math::

        \nu = (p_1 \times p_2,\ p_2 - p_1), \qquad
        \bar w = w - \frac{\nu \cdot w}{|\nu|^2}\, \nu = (F, \tau)

        \bar w = L_1 f_1 + L_2 f_2 \iff f_1 = F - f_2,\quad
        f_2 = \frac{g \times d}{|d|^2} + s\, \frac{d}{|d|},\quad
        g = \tau - p_1 \times F,\ d = p_2 - p_1,\ s \in \mathbb{R}

    The FWS of two legs lies in the hyperplane ``nu . x = 0`` of their lifts (a force along
    ``d`` is the same wrench from either foot). As for the FWS's own verdict
    (:func:`~awp_ros.geometry.margin.polytope_margin`), ``w`` is in it when it is within
    ``hull_tol`` of the hyperplane and its projection ``w_bar`` is in the set: when some
    ``s`` puts ``f_k`` in leg k's friction-bounded force polytope, ``A_k f_k <= b_k`` (torque
    limits) and ``R_k f_k <= 0`` (friction pyramid and ``n . f >= 0``). Each of the legs'
    (unit) rows bounds ``s`` on one side (the ratio test), or, parallel to ``d``, holds or
    fails for every ``s``; the rows hold to ``feasibility_tol`` [N].

    :param positions: (2, 3) the feet relative to the CoM [m], world-aligned axes.
    :param force_A: (2, m, 3) the legs' force polytopes' rows, ``force_A[k] f <= force_b[k]``
        (full-dimensional force polytopes: a singular leg's flat one is not of this form).
    :param force_b: (2, m) [N].
    :param pyramid_rows: (2, N + 1, 3) unit rows ``R_k f <= 0``
        (:func:`~awp_ros.wrench.friction_polytope.friction_rows`).
    :param w: (6,) the wrench ``[f; tau]`` [N, N.m], about the CoM, same axes.
    :param hull_tol: distance [N, N.m] of ``w`` from the hyperplane up to which it counts as
        on it (the evaluator's ``hull_tolerance``).
    :param feasibility_tol: tolerance on the legs' rows [N].
    :return: the verdict, or None when the feet are less than :data:`FEET_APART` apart
        (no hyperplane).
    """
    if kernels.ENABLED:                   # one compiled call (the code below is its reference)
        verdict = kernels.two_leg_contains(positions, force_A, force_b, pyramid_rows, w,
                                           hull_tol, feasibility_tol, PARALLEL_TOL, FEET_APART)
        return None if verdict < 0 else bool(verdict)
    p1, p2 = np.asarray(positions, dtype=float)
    w = np.asarray(w, dtype=float)
    d = p2 - p1
    dd = float(d @ d)
    if not dd > FEET_APART ** 2:
        return None
    nu = np.concatenate([cross3(p1, p2), d])
    off = float(nu @ w) / float(nu @ nu)
    if abs(off) * np.sqrt(float(nu @ nu)) > hull_tol:
        return False
    wb = w - off * nu
    F, tau = wb[:3], wb[3:]
    f2 = cross3(tau - cross3(p1, F), d) / dd
    u = d / np.sqrt(dd)
    A = np.concatenate([force_A[1], pyramid_rows[1], -force_A[0], -pyramid_rows[0]])
    b = np.concatenate([force_b[1], np.zeros(len(pyramid_rows[1])),
                        force_b[0] - force_A[0] @ F, -(pyramid_rows[0] @ F)])
    scale = np.sqrt(np.einsum('ij,ij->i', A, A))
    A, b = A / scale[:, None], b / scale
    empty = line_interval(b - A @ f2, (A @ u)[None, :], feasibility_tol, PARALLEL_TOL)[2]
    return not bool(empty[0])


class _HighsLp:
    """min c t_i over {A [lam; t] = rhs, lam >= 0, t_j = 0 (j != i)}, warm-started HiGHS."""

    def __init__(self, A: np.ndarray, rhs: np.ndarray, n: int, tol: float) -> None:
        self.n = n
        core = _highs_core()
        self.core, self.A, self.rhs = core, A, rhs
        if core is None:
            return
        # The raw class: highspy's Highs() prints a banner on stdout when first built.
        self.h = core._Highs() if hasattr(core, '_Highs') else core.Highs()
        for key, value in (('output_flag', False), ('presolve', 'off'), ('solver', 'simplex'),
                           ('simplex_strategy', 4), ('primal_feasibility_tolerance', tol)):
            self.h.setOptionValue(key, value)
        lp = core.HighsLp()
        m, cols = A.shape
        lp.num_col_, lp.num_row_ = cols, m
        lp.col_cost_ = np.zeros(cols)
        lp.col_lower_ = np.zeros(cols)
        lp.col_upper_ = np.concatenate([np.full(n, np.inf), np.zeros(cols - n)])
        lp.row_lower_, lp.row_upper_ = rhs, rhs
        nz = np.nonzero(A.T)
        lp.a_matrix_.format_ = core.MatrixFormat.kColwise
        lp.a_matrix_.start_ = np.searchsorted(nz[0], np.arange(cols + 1))
        lp.a_matrix_.index_ = nz[1]
        lp.a_matrix_.value_ = A.T[nz]
        lp.a_matrix_.num_col_, lp.a_matrix_.num_row_ = cols, m
        self.h.passModel(lp)

    def solve(self, i: int | None, cost: float) -> float | None:
        """Return the optimal ``t_i`` (0 for ``i = None``: feasibility), None if infeasible."""
        if self.core is None:
            return self._linprog(i, cost)
        h, col = self.h, None if i is None else self.n + i
        if col is not None:
            h.changeColBounds(col, -np.inf, np.inf)
            h.changeColCost(col, cost)
        h.run()
        ok = h.getModelStatus() == self.core.HighsModelStatus.kOptimal
        value = h.getSolution().col_value[col] if ok and col is not None else 0.0
        if col is not None:
            h.changeColCost(col, 0.0)
            h.changeColBounds(col, 0.0, 0.0)
        return float(value) if ok else None

    def _linprog(self, i: int | None, cost: float) -> float | None:
        """Solve the same LP with scipy.optimize.linprog (no warm start)."""
        from scipy.optimize import linprog
        cols = self.A.shape[1]
        c = np.zeros(cols)
        bounds = [(0, None)] * self.n + [(0, 0)] * (cols - self.n)
        if i is not None:
            c[self.n + i] = cost
            bounds[self.n + i] = (None, None)
        res = linprog(c, A_eq=self.A, b_eq=self.rhs, bounds=bounds, method='highs')
        if res.status != 0:
            return None
        return float(res.x[self.n + i]) if i is not None else 0.0


def _highs_core():
    """Return a HiGHS binding module (scipy's bundled one first, then highspy) or None."""
    try:
        from scipy.optimize._highspy import _core as core
    except ImportError:
        try:
            import highspy as core
        except ImportError:                       # pragma: no cover - no HiGHS at all
            core = None
    return core
