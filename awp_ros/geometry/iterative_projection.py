r"""
Iterative projection of a CoM region with LPs (Bretl & Lall, T-RO 2008), the baseline.

This is how planners compute the support region and the feasible region today (the
jet-leg library of Orsolino et al., T-RO 2020); :mod:`awp_ros.wrench.com_region` slices an
exact wrench-set H-rep instead, and this module is kept to compare against it.

Frames and units: world-aligned axes (REP 103, z up), origin at the current CoM; CoM offsets
``delta = (x, y)`` [m], contact forces ``f_k`` [N] (ground on robot), foot positions
``p_k`` [m] relative to the current CoM. With the posture frozen (each leg's force set
``{f : H_k f <= g_k}``: friction pyramid rows, torque-limit rows, or both) the region is the
projection on ``delta`` of

.. math::

    \mathcal Q = \{(\delta, f_1, \dots, f_K) :
        \textstyle\sum_k f_k = f,\;
        \sum_k p_k \times f_k - \delta \times f = \dot L,\;
        H_k f_k \le g_k\}                                                       \qquad (1)

(``sum_k (p_k - delta) x f_k = L'`` about the moved CoM; ``f = m (c'' - g)``), a convex
polygon. Algorithm (Bretl & Lall, Sec. IV):

(2) the support point ``v(c) = argmax {c . delta : (delta, f) in Q}`` is one LP;
(3) start from ``initial_directions`` evenly spaced directions; the support points span an
    inner polygon, the support lines ``c_j . delta <= c_j . v_j`` bound an outer one;
(4) the gap between consecutive support points j, j + 1 is the triangle (``v_j``, outer
    vertex, ``v_{j+1}``); the LP along the outward normal of the inner edge with the largest
    gap inserts a new support point; repeat until the summed gaps (outer area - inner area)
    are at most ``area_tol`` [m^2] or ``max_lps`` LPs were solved.

Each LP is solved from scratch by ``scipy.optimize.linprog(method='highs')``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import math

import numpy as np
from scipy.optimize import linprog

from awp_ros.errors import GeometryError, InputError

__all__ = ['ProjectedRegion', 'iterative_projection', 'torque_halfspaces']


@dataclass(frozen=True)
class ProjectedRegion:
    """
    A CoM region found by iterative projection (see the module docstring).

    :ivar vertices: ``(k, 2)`` [m] the inner polygon (support points, ccw, consecutive
        duplicates removed), relative to the current CoM, world-aligned x/y; empty when the
        region is empty.
    :ivar outer: ``(k', 2)`` [m] the outer polygon (intersections of consecutive support
        lines, ccw); the region lies between the two.
    :ivar area_gap: outer area minus inner area [m^2] at the stop (0 when empty).
    :ivar lps: number of LPs solved.
    :ivar converged: ``area_gap <= area_tol`` (or empty).
    """

    vertices: np.ndarray
    outer: np.ndarray
    area_gap: float
    lps: int
    converged: bool

    @property
    def is_empty(self) -> bool:
        """Return True when the first LP was infeasible."""
        return self.vertices.shape[0] == 0


def torque_halfspaces(J: np.ndarray, bias: np.ndarray, tau_min: np.ndarray,
                      tau_max: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r"""
    Return ``(H, g)`` of a leg's torque limits on its contact force: ``H f <= g``.

    .. math:: \tau_{min} \le b - J^T f \le \tau_{max} \iff
              \begin{bmatrix} -J^T \\ J^T \end{bmatrix} f \le
              \begin{bmatrix} \tau_{max} - b \\ b - \tau_{min} \end{bmatrix}

    :param J: ``(3, n)`` translational foot Jacobian (LOCAL_WORLD_ALIGNED) [m/rad].
    :param bias: ``(n,)`` bias torques ``rnea(q, v, a)`` of the leg's joints [N.m].
    :param tau_min: ``(n,)`` lower torque limits [N.m]; :param tau_max: upper ones.
    :return: ``H`` (2n, 3) [m], ``g`` (2n,) [N.m].
    """
    J = np.asarray(J, dtype=float)
    b = np.asarray(bias, dtype=float)
    return (np.vstack([-J.T, J.T]),
            np.concatenate([np.asarray(tau_max, dtype=float) - b,
                            b - np.asarray(tau_min, dtype=float)]))


def iterative_projection(positions: np.ndarray,
                         halfspaces: Sequence[tuple[np.ndarray, np.ndarray]],
                         force: np.ndarray, moment: np.ndarray, *, area_tol: float = 1e-6,
                         max_lps: int = 500, initial_directions: int = 4) -> ProjectedRegion:
    r"""
    Return the CoM region of (1) by Bretl & Lall's iterative projection.

    .. math:: R = \{\delta : \exists f_k,\ H_k f_k \le g_k,\ \sum_k f_k = f,\
              \sum_k (p_k - \delta) \times f_k = \dot L\}

    :param positions: ``(K, 3)`` feet relative to the current CoM [m], world axes.
    :param halfspaces: K pairs ``(H_k (r_k, 3), g_k (r_k,))``: each leg's force set.
    :param force: ``f = m (c'' - g)`` (3,) [N]; :param moment: ``L'`` (3,) [N.m].
    :param area_tol: stop when outer area - inner area is at most this [m^2].
    :param max_lps: stop after this many LPs (``converged`` is then False).
    :param initial_directions: number of evenly spaced first directions (>= 3).
    :return: the :class:`ProjectedRegion`.
    :raises InputError: on bad shapes or values, or an unbounded region.
    :raises GeometryError: when an LP fails other than by infeasibility.
    """
    P = np.asarray(positions, dtype=float).reshape(-1, 3)
    f = np.asarray(force, dtype=float)
    L = np.asarray(moment, dtype=float)
    K = P.shape[0]
    if len(halfspaces) != K or f.shape != (3,) or L.shape != (3,) or initial_directions < 3:
        msg = (f'iterative_projection needs K positions and K halfspace pairs, a 3-vector force '
               f'and moment and >= 3 directions; got {K}, {len(halfspaces)}, {f.shape}, '
               f'{L.shape}, {initial_directions}')
        raise InputError(msg)
    lp = _BalanceLp(P, halfspaces, f, L)
    if K == 0:
        return ProjectedRegion(np.zeros((0, 2)), np.zeros((0, 2)), 0.0, 0, True)
    th = 2.0 * np.pi * np.arange(initial_directions) / initial_directions
    angles = th.tolist()
    points: list[np.ndarray] = []
    for a in angles:
        v = lp.support(math.cos(a), math.sin(a))
        if v is None:
            return ProjectedRegion(np.zeros((0, 2)), np.zeros((0, 2)), 0.0, lp.count, True)
        points.append(v)
    gaps = [_gap(angles, points, j) for j in range(len(angles))]
    while sum(gaps) > area_tol and lp.count < max_lps:
        j = int(np.argmax(gaps))
        k = (j + 1) % len(angles)
        e = points[k] - points[j]
        length = float(np.hypot(*e))
        if length == 0.0:
            gaps[j] = 0.0
            continue
        a = math.atan2(-e[0], e[1])                      # outward normal (e_y, -e_x)
        v = lp.support(math.cos(a), math.sin(a))
        if v is None:
            raise GeometryError('an LP of the iterative projection became infeasible')
        c = np.array([math.cos(a), math.sin(a)])
        if c @ v <= c @ points[j] + _SAME * max(1.0, length):
            gaps[j] = 0.0                                # the inner edge is a true edge
            continue
        # Insert between j and k (the angle of c lies between theirs, modulo 2 pi).
        angles.insert(j + 1, a)
        points.insert(j + 1, v)
        gaps[j:j + 1] = [0.0, 0.0]
        n = len(angles)
        for i in (j, (j + 1) % n):
            gaps[i] = _gap(angles, points, i)
    inner = _dedupe(np.array(points))
    outer = np.array([_outer_vertex(angles, points, j) for j in range(len(angles))])
    gap = float(sum(gaps))
    return ProjectedRegion(inner, outer, gap, lp.count, gap <= area_tol)


_SAME = 1e-12  # [m] a new support point no farther than this along c is an old one


class _BalanceLp:
    """The LP (2) over ``z = (delta, f_1, ..., f_K)``, matrices built once."""

    def __init__(self, P: np.ndarray, halfspaces: Sequence, f: np.ndarray,
                 L: np.ndarray) -> None:
        K = P.shape[0]
        n = 2 + 3 * K
        A_eq = np.zeros((6, n))
        # sum_k f_k = f; sum_k p_k x f_k - delta x f = L'. delta x f = Dt delta.
        A_eq[3:, :2] = -np.array([[0.0, f[2]], [-f[2], 0.0], [f[1], -f[0]]])
        rows, rhs = [], []
        for k, (H, g) in enumerate(halfspaces):
            H = np.asarray(H, dtype=float).reshape(-1, 3)
            g = np.asarray(g, dtype=float).reshape(-1)
            finite = bool(np.isfinite(H).all() and np.isfinite(g).all())
            if H.shape[0] != g.shape[0] or not finite:
                raise InputError(f'halfspaces[{k}] must be finite (r, 3) and (r,) arrays')
            c = 2 + 3 * k
            A_eq[:3, c:c + 3] = np.eye(3)
            p = P[k]
            A_eq[3:, c:c + 3] = [[0.0, -p[2], p[1]], [p[2], 0.0, -p[0]], [-p[1], p[0], 0.0]]
            block = np.zeros((H.shape[0], n))
            block[:, c:c + 3] = H
            rows.append(block)
            rhs.append(g)
        self.A_eq = A_eq
        self.b_eq = np.concatenate([f, L])
        self.A_ub = np.vstack(rows) if rows else np.zeros((0, n))
        self.b_ub = np.concatenate(rhs) if rhs else np.zeros(0)
        self.n = n
        self.count = 0

    def support(self, cx: float, cy: float) -> np.ndarray | None:
        """Return ``argmax c . delta`` over (1) (None when infeasible)."""
        c = np.zeros(self.n)
        c[0], c[1] = -cx, -cy
        self.count += 1
        kw = {'A_ub': self.A_ub, 'b_ub': self.b_ub, 'A_eq': self.A_eq, 'b_eq': self.b_eq,
              'bounds': (None, None), 'method': 'highs'}
        res = linprog(c, **kw)
        if res.status == 4:
            # HiGHS's presolve sometimes ends in a "solve error" on these LPs (seen with the
            # friction-only one, scipy 1.17): solved again without it.
            res = linprog(c, options={'presolve': False}, **kw)
        if res.status == 2:
            return None
        if res.status == 3:
            raise InputError('the CoM region is unbounded (the balance LP is unbounded)')
        if res.status != 0:
            raise GeometryError(f'iterative projection LP failed: {res.message}')
        return res.x[:2].copy()


def _outer_vertex(angles: list[float], points: list[np.ndarray], j: int) -> np.ndarray:
    """Return the intersection of the support lines j and j + 1 (their angle gap < pi)."""
    k = (j + 1) % len(angles)
    c1 = np.array([math.cos(angles[j]), math.sin(angles[j])])
    c2 = np.array([math.cos(angles[k]), math.sin(angles[k])])
    det = c1[0] * c2[1] - c1[1] * c2[0]
    h1, h2 = float(c1 @ points[j]), float(c2 @ points[k])
    if det <= 1e-15:
        raise InputError('the CoM region is unbounded (support directions span >= pi)')
    return np.array([(h1 * c2[1] - c1[1] * h2) / det, (c1[0] * h2 - c2[0] * h1) / det])


def _gap(angles: list[float], points: list[np.ndarray], j: int) -> float:
    """Return the area [m^2] of the triangle (v_j, outer vertex j, v_{j+1})."""
    k = (j + 1) % len(angles)
    a, b = points[j], points[k]
    o = _outer_vertex(angles, points, j)
    return 0.5 * abs(float((o[0] - a[0]) * (b[1] - a[1]) - (o[1] - a[1]) * (b[0] - a[0])))


def _dedupe(V: np.ndarray, tol: float = 1e-12) -> np.ndarray:
    """Return the closed chain ``V`` without consecutive (cyclic) duplicates."""
    if V.shape[0] < 2:
        return V
    step = np.linalg.norm(V - np.roll(V, 1, axis=0), axis=1)
    keep = step > tol
    return V[keep] if keep.any() else V[:1]
