r"""
CoM regions: the horizontal CoM positions at which a wrench set still balances the robot.

Frames and units: world-aligned axes (REP 103, z up), origin at the current whole-robot CoM;
CoM offsets ``delta`` [m], forces [N], moments [N.m]. Every wrench set of awp_ros (AWP, CWC,
FWP, FWS) is a :class:`~awp_ros.geometry.polytope.Polytope` of wrenches ``[f; tau]`` about the
current CoM, built from the lifts ``L_k f = [f; p_k x f]`` with ``p_k`` the foot positions
relative to the current CoM.

Moving the CoM by ``delta = (x, y, 0)`` with the feet, the posture (Jacobians, bias torques)
and the motion (``c''``, ``L'``) unchanged, the feet are at ``p_k - delta`` from the new CoM
and balance asks ``sum_k f_k = f`` and ``sum_k (p_k - delta) x f_k = L'``, i.e.
``sum_k p_k x f_k = L' + delta x sum_k f_k``. About the *current* CoM the contacts must
therefore supply

.. math::

    W(\delta) = \begin{bmatrix} f \\ \dot L + \delta \times f \end{bmatrix}
              = w_0 + D \delta, \quad
    w_0 = \begin{bmatrix} f \\ \dot L \end{bmatrix}, \quad
    D = \begin{bmatrix} 0 & 0 \\ 0 & 0 \\ 0 & 0 \\
        0 & f_z \\ -f_z & 0 \\ f_y & -f_x \end{bmatrix}
    \qquad (1)

with ``f = m (c'' - g)`` (quasi-static: ``[0, 0, m g]``; then ``tau_x = m g y`` and
``tau_y = -m g x``: a CoM moved forward needs a nose-down moment from the feet, as the
weight then acts ahead of them). The CoM region of a set ``S`` is the slice

.. math::

    R(S) = \{\delta \in \mathbb{R}^2 : W(\delta) \in S\}
         = \{\delta : A (w_0 + D \delta) \le b,\; E (w_0 + D \delta) = e\}      \qquad (2)

(``E x = e`` the affine hull of a flat ``S``, :attr:`Polytope.equalities`; the rows ``A``
are ambient, in the hull's direction space). With the FWS it is the *feasible region*
(Orsolino et al., T-RO 2020: torque limits and friction with one force distribution), with
the CWC the *support region* (Bretl & Lall, T-RO 2008: friction only), with the seed's FWP
= AWP cap CWC the *FWP region*. ``R`` is bounded when ``f_z != 0`` and ``S`` is bounded
(``D`` then has rank 2); the CWC is a cone but its slice at a fixed force is bounded for
contacts on (nearly) level ground.

Algorithm (exact: every vertex is the intersection of two of the slice's lines, nothing is
sampled; vectorised, no Python loop over rows):

(3) the equalities ``G delta = g`` (``G = E D``) give ``delta = d_0 + N t``: ``N`` spans
    the null space of ``G`` (rank 0 for full sets; 1 for two stance legs, a line; 2 for one
    leg, a point); an inconsistent system means an empty region;
(4) the rows become ``n_i . delta <= h_i`` (``n_i = D^T a_i``, ``h_i = b_i - a_i . W(d_0)``);
    rows with ``n_i ~ 0`` are constants (a violated one empties the region); the others are
    scaled to unit ``n_i`` (``h_i`` is then the signed distance [m] from the current CoM to
    the line, positive on the feasible side);
(5) an interior point ``x_0``: the current CoM when every ``h_i > 0`` (and its margin
    comes out above ``1000 distance_tol``), else the Chebyshev centre ``max_x min_i (h_i -
    n_i . x)``, an LP in (x, y, r) solved exactly by a dual simplex (3 basic rows, the most
    violated row enters): each basis is optimal for a relaxation, so a negative radius
    proves emptiness, and a basis that no row violates is the global optimum;
(6) polar duality about ``x_0``: line ``i`` maps to ``d_i = n_i / (h_i - n_i . x_0)``, and
    the polygon's edges are the lines whose dual points are the vertices of ``conv(d)``
    (``0`` strictly inside it iff the polygon is bounded). A ccw convex chain of dual
    points with "primal" vertices ``v_j`` (``a . v_j = b . v_j = 1`` on its edge (a, b):
    the intersection of the two lines) contains ``c`` iff ``c . v_j <= 1`` for all ``j``.
    The extreme points along 8 directions make a first chain; the points inside it are
    redundant lines and are dropped (one matrix product over all rows);
(7) the extreme points of the rest along 128 directions (support points are hull
    vertices) make the chain; it is the hull iff no point lies beyond an edge, i.e. iff
    every ``v_j`` satisfies every remaining line within ``distance_tol`` [m]; each violated
    ``v_j`` adds ``argmax_c c . v_j`` (a hull vertex between the two) and the test is
    repeated (usually 0 to 2 rounds). The vertices are the ``v_j``: intersections of
    consecutive edge lines, counter-clockwise; a line whose edge is shorter than
    ``distance_tol`` (it touches the polygon at a vertex) is dropped.

Representation of :class:`ComRegion` (all relative to the current CoM, world-aligned x/y):

- polygon (``dimension = 2``): ``k >= 3`` vertices counter-clockwise, ``A`` the ``k`` unit
  outward edge normals (edge ``i`` joins vertices ``i - 1`` and ``i``), ``A delta <= b``;
- segment (``1``; two stance legs): its 2 end points, ``A`` holds ``+-nu`` (the unit
  normal of its line, so the equality ``nu . delta = c`` is two rows) and ``+-u`` (its
  direction, the end caps);
- point (``0``; one stance leg, or a segment shorter than ``distance_tol``): 1 vertex,
  ``A = [e_x; -e_x; e_y; -e_y]``;
- empty (``-1``; no stance leg, unbalanceable wrench): no vertex and no row.

``margin`` [m] is the signed distance of the current CoM (``delta = 0``) to the region's
boundary in the plane: positive inside a polygon, minus the distance to the region outside
(so at most 0 for a segment or a point, which have no interior), NaN when empty.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
import math
from typing import Sequence

import numpy as np
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, QhullError

from awp_ros.errors import GeometryError, InputError
from awp_ros.geometry import kernels
from awp_ros.geometry.polytope import Polytope

__all__ = ['ComRegion', 'com_region', 'com_wrench_map', 'feasible_region',
           'feasible_region_of_rows', 'feasible_region_of_kernel', 'EDGE_PARALLEL_TOL',
           'region_of_slice', 'slice_floor', 'DISTANCE_TOL', 'VERTICAL_FORCE_TOL']

#: Default geometric tolerance of the CoM regions [m] (``distance_tol``).
DISTANCE_TOL = 1e-9
#: Default least ``|f_z|`` [N] for which a CoM region is computed (``vertical_force_tol``).
VERTICAL_FORCE_TOL = 1e-6


@dataclass(frozen=True)
class ComRegion:
    """
    A CoM region in the horizontal plane (see the module docstring for each dimension).

    :ivar dimension: 2 polygon, 1 segment, 0 point, -1 empty.
    :ivar vertices: ``(k, 2)`` [m], counter-clockwise for a polygon, relative to the current
        CoM, world-aligned x/y.
    :ivar A: ``(m, 2)`` unit rows of ``A delta <= b``.
    :ivar b: ``(m,)`` [m]: ``b_i`` is the signed distance from the current CoM to line i.
    :ivar margin: signed distance [m] of the current CoM to the region's boundary, positive
        inside, minus the distance to the region outside, NaN when empty.
    :ivar meta: diagnostics: ``rows`` (rows of the sliced set) and, for a polygon,
        ``interior_point`` (``x_0`` of step 5 [m], zero when the current CoM was used).
    """

    dimension: int
    vertices: np.ndarray
    A: np.ndarray
    b: np.ndarray
    margin: float
    meta: dict = field(default_factory=dict, compare=False)

    @property
    def is_empty(self) -> bool:
        """Return True for the empty region."""
        return self.dimension < 0

    @property
    def area(self) -> float:
        """Return the area [m^2] (0 unless a polygon)."""
        if self.dimension < 2:
            return 0.0
        x, y = self.vertices[:, 0], self.vertices[:, 1]
        return 0.5 * float(x @ np.roll(y, -1) - y @ np.roll(x, -1))

    def contains(self, delta: np.ndarray, tol: float = 1e-9) -> bool:
        """Return True if the CoM offset ``delta`` (2,) [m] is in the region, up to ``tol``."""
        if self.is_empty:
            return False
        d = np.asarray(delta, dtype=float).reshape(2)
        return bool(np.all(self.A @ d <= self.b + tol))

    def contains_origin(self, tol: float = 1e-9) -> bool:
        """Return :meth:`contains` of the current CoM, ``delta = 0`` (``A 0 = 0 <= b + tol``)."""
        if self.is_empty:
            return False
        return self.b.size == 0 or float((self.b + tol).min()) >= 0.0


def com_wrench_map(force: np.ndarray, moment: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r"""
    Return ``(w_0, D)`` of eq. (1): the wrench needed about the current CoM is ``w_0 + D delta``.

    .. math:: W(\delta) = [f;\ \dot L + \delta \times f], \quad \delta = (x, y, 0)

    :param force: ``f = m (c'' - g)`` (3,) [N], world axes.
    :param moment: ``L'`` (3,) [N.m], the rate of the centroidal angular momentum.
    :return: ``w_0`` (6,) [N, N.m] and ``D`` (6, 2) [N] (columns ``e_x x f``, ``e_y x f``).
    :raises InputError: on bad shapes or non-finite values.
    """
    fx, fy, fz, *L = _wrench(force, moment)
    w0 = np.array([fx, fy, fz, *L])
    D = np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, fz], [-fz, 0.0], [fy, -fx]])
    return w0, D


def com_region(polytope: Polytope, force: np.ndarray, moment: np.ndarray, *,
               distance_tol: float = DISTANCE_TOL, wrench_tol: float = 1e-6,
               row_tol: float = 1e-9, vertical_force_tol: float = VERTICAL_FORCE_TOL,
               search_radius: float = 100.0) -> ComRegion:
    r"""
    Return the exact CoM region of a wrench set, eq. (2).

    .. math:: R = \{\delta \in \mathbb{R}^2 :
              [f;\ \dot L + \delta \times f] \in S\}

    The feasible region is ``com_region(fws, ...)``, the support region
    ``com_region(cwc, ...)``, the FWP region ``com_region(fwp, ...)``.

    :param polytope: the wrench set ``S`` in R^6 (complete H-rep, flat or full, a cone
        allowed), about the current CoM, world-aligned axes.
    :param force: ``f = m (c'' - g)`` (3,) [N] (quasi-static ``[0, 0, m g]``).
    :param moment: ``L'`` (3,) [N.m].
    :param distance_tol: geometric tolerance [m] in the CoM plane: a line cutting at most
        this off the polygon is redundant, a region thinner than this is a segment or a
        point, an interval empty by at most this is a point.
    :param wrench_tol: tolerance [N, N.m] on the equality residuals and on constant rows.
    :param row_tol: a row (or an equality direction) whose CoM coefficients ``|n_i|`` are
        at most ``row_tol |f|`` is constant in ``delta`` (relative, [-]).
    :param vertical_force_tol: ``|f_z|`` at most this [N] is refused (the region is then a
        strip, unbounded, or empty).
    :param search_radius: half-side [m] of the square around the current CoM in which an
        interior point is searched when the current CoM is not inside (step 5); regions
        are assumed to lie within it.
    :return: the :class:`ComRegion`.
    :raises InputError: on bad shapes or values, ``|f_z| <= vertical_force_tol``, or an
        unbounded region (a cone whose slice is not bounded, e.g. opposing contacts).
    :raises GeometryError: when an internal LP fails.
    """
    if not isinstance(polytope, Polytope) or polytope.ambient_dim != 6:
        raise InputError(f'com_region needs a Polytope in R^6; got {polytope!r:.80}')
    fx, fy, fz, Lx, Ly, Lz = _wrench(force, moment)
    if not abs(fz) > vertical_force_tol:
        msg = (f'the CoM region needs a vertical force component: |f_z| = {abs(fz):.3g} N '
               f'<= {vertical_force_tol:.3g} N (the region would be unbounded or empty)')
        raise InputError(msg)
    P = polytope
    rows = int(P.A.shape[0])
    if P.is_empty:
        return _empty(rows)
    const_tol = row_tol * math.sqrt(fx * fx + fy * fy + fz * fz)
    # (3) equalities of a flat set: delta = d0 + N t.
    x, y = 0.0, 0.0
    rank = 0
    r = P.hull_basis.shape[1]
    if r == 6 and kernels.ENABLED:       # steps (4)-(7) compiled, when (5)'s fast path holds
        sliced = kernels.wrench_slice(
            P.A, P.b, np.array((fx, fy, fz, Lx, Ly, Lz)), distance_tol, EDGE_PARALLEL_TOL,
            slice_floor(fx, fy, fz, row_tol=row_tol, wrench_tol=wrench_tol,
                        search_radius=search_radius))
        if sliced[4] == 2:
            raise InputError(_UNBOUNDED)
        region = region_of_slice(P, sliced, distance_tol=distance_tol)
        if region is not None:
            return region
    if r == 5 and kernels.ENABLED:       # two stance legs: steps (3)-(4) compiled
        E, e = P.equalities
        status, x, y, ux, uy, lo, hi = kernels.segment_slice(
            P.A, P.b, E[0], float(e[0]), np.array((fx, fy, fz, Lx, Ly, Lz)), const_tol,
            wrench_tol, distance_tol)
        if status == 1:
            return _empty(rows)
        if status == 2:
            raise InputError(_UNBOUNDED)
        if status == 0:
            return _segment(np.array([x, y]), np.array([ux, uy]), lo, hi, distance_tol, rows)
    if r == 5:                           # two stance legs: one equality, in scalars
        (E0, E1, E2, E3, E4, E5), = P.equalities[0].tolist()
        gx, gy = fy * E5 - fz * E4, fz * E3 - fx * E5          # G = E D
        g = float(P.equalities[1][0]) - (E0 * fx + E1 * fy + E2 * fz + E3 * Lx + E4 * Ly
                                         + E5 * Lz)
        norm = math.hypot(gx, gy)
        if not norm > const_tol:
            if abs(g) > wrench_tol:
                return _empty(rows)
        else:
            rank = 1
            x, y = g * gx / (norm * norm), g * gy / (norm * norm)
            null = np.array([[-gy / norm], [gx / norm]])
    elif r < 6:
        E, e = P.equalities
        Em = E[:, 3:]                    # G = E D: only D's moment rows are non-zero
        G = np.column_stack((fy * Em[:, 2] - fz * Em[:, 1], fz * Em[:, 0] - fx * Em[:, 2]))
        g = e - E @ np.array((fx, fy, fz, Lx, Ly, Lz))
        u, s, vt = np.linalg.svd(G, full_matrices=True)
        rank = int(np.count_nonzero(s > const_tol))
        d0 = vt[:rank].T @ ((u[:, :rank].T @ g) / s[:rank]) if rank else np.zeros(2)
        if np.linalg.norm(G @ d0 - g) > wrench_tol:
            return _empty(rows)
        null = vt[rank:].T
        x, y = d0.tolist()
    # (4) the rows in delta: n_i . (delta - d0) <= h_i. MT = [a_i . W(d0); n_i^T], (3, m),
    # from the rows [W(d0)^T; D^T] of eq. (1).
    X = np.array(((fx, fy, fz, Lx + y * fz, Ly - x * fz, Lz + x * fy - y * fx),
                  (0.0, 0.0, 0.0, 0.0, -fz, fy), (0.0, 0.0, 0.0, fz, 0.0, -fx)))
    MT = X @ P.A.T
    h = P.b - MT[0]
    N2 = MT[1:]
    if rank == 2:
        if rows and np.min(h) < -wrench_tol:
            return _empty(rows)
        return _point(np.array([x, y]), rows)
    if rank == 1:
        u = null[:, 0]
        interval = _interval(u @ N2, h, const_tol, wrench_tol, distance_tol)
        if interval is None:
            return _empty(rows)
        return _segment(np.array([x, y]), u, *interval, distance_tol, rows)
    # (5) fast path: the current CoM strictly inside, by at least _CENTRED tolerances
    # (checked on the result; closer, the general path). Constant rows need no test here:
    # |n_i| <= const_tol and h_i > const_tol * search_radius put their dual points inside
    # the disc of radius 1 / search_radius, itself inside conv(d) for a region within the
    # search radius (they are redundant).
    if rows >= 3 and float(h.min()) > max(wrench_tol, const_tol * search_radius):
        region = _slice_polygon(N2, h, None, distance_tol, rows)
        if region.margin >= _CENTRED * distance_tol:
            return region
    return _general(N2, h, rows, const_tol=const_tol, wrench_tol=wrench_tol,
                    distance_tol=distance_tol, search_radius=search_radius)


def slice_floor(fx: float, fy: float, fz: float, *, row_tol: float = 1e-9,
                wrench_tol: float = 1e-6, search_radius: float = 100.0) -> float:
    """
    Return the least slack [N, N.m] of every row at the current CoM for step (5)'s fast path.

    ``max(wrench_tol, row_tol |f| search_radius)`` (:func:`com_region`'s tolerances, defaults
    included): above it, constant rows are redundant and the current CoM is inside.
    """
    return max(wrench_tol, row_tol * math.sqrt(fx * fx + fy * fy + fz * fz) * search_radius)


def region_of_slice(P: Polytope, sliced: tuple, *, distance_tol: float = DISTANCE_TOL
                    ) -> ComRegion | None:
    """
    Return the polygon of :func:`awp_ros.geometry.kernels.wrench_slice`'s result on ``P``.

    None when the kernel's fast path does not hold (status not 0, or the current CoM closer
    to an edge than ``_CENTRED`` tolerances): :func:`com_region` then decides (its general
    steps, or the unbounded region's error).
    """
    A, b, V, margin, status = sliced
    if status == 0 and margin >= _CENTRED * distance_tol:
        return ComRegion(2, V, A, b, margin, {'rows': int(P.A.shape[0]),
                                              'interior_point': np.zeros(2)})
    return None


# -- the feasible region by projection (every cycle, no FWS H-rep) --------------------------


def feasible_region(positions: np.ndarray, force_polytopes: Sequence[Polytope],
                    friction_rows: np.ndarray, force: np.ndarray, moment: np.ndarray, *,
                    distance_tol: float = DISTANCE_TOL) -> ComRegion | None:
    r"""
    Return the exact feasible region without the FWS's H-rep, by iterative projection.

    .. math::

        R = \{\delta : \exists f_k \in \mathcal F_k \cap \mathcal C_k,\;
              \textstyle\sum_k L_k f_k = w_0 + D \delta\}
          = \{\delta : W(\delta) \in \mathrm{FWS}\}

    the same set as ``com_region(fws, force, moment)`` (eq. 2 with the FWS), computed as the
    projection on ``delta`` of the LP of the contact forces: each leg's friction-bounded
    polytope by its vertices (all triples of its torque and pyramid rows), the forces as
    convex combinations of them, and :func:`awp_ros.geometry.kernels.projected_polygon`'s
    exact iterative projection (Bretl & Lall's, every edge certified by an LP in its
    normal, no area tolerance). About 2 LPs per vertex of a small dense simplex: cheap
    enough for every control cycle, where the FWS's H-rep is not.

    :param positions: (K, 3) stance feet relative to the CoM [m], world-aligned axes.
    :param force_polytopes: K full-dimensional force polytopes [N] (H-rep ``A f <= b``).
    :param friction_rows: (K, N + 1, 3) unit rows ``a . f <= 0`` of each leg's pyramid and
        ``n . f >= 0`` (:func:`awp_ros.wrench.friction_polytope.friction_rows`).
    :param force: ``f = m (c'' - g)`` (3,) [N]; ``moment``: ``L'`` (3,) [N.m].
    :param distance_tol: [m] an edge is certified when no support point lies more than
        this beyond it; shorter edges and collinear vertices are merged.
    :return: the :class:`ComRegion` (same representation as :func:`com_region`), or None
        when it cannot be computed this way (kernels off, a leg polytope not
        full-dimensional, no leg, ``|f_z|`` too small, an LP failing): use
        :func:`com_region` on the FWS then.
    """
    K = len(force_polytopes)
    w = np.concatenate((np.asarray(force, dtype=float).ravel(),
                        np.asarray(moment, dtype=float).ravel()))
    if w.shape != (6,) or not np.isfinite(w).all():
        _wrench(force, moment)                      # raises InputError naming the bad vector
    if K == 0 or any(F.dimension != 3 or F.A.shape != force_polytopes[0].A.shape
                     for F in force_polytopes):
        return None
    return feasible_region_of_rows(positions, np.array([F.A for F in force_polytopes]),
                                   np.array([F.b for F in force_polytopes]), friction_rows, w,
                                   distance_tol=distance_tol)


def feasible_region_of_rows(positions: np.ndarray, force_A: np.ndarray, force_b: np.ndarray,
                            friction_rows: np.ndarray, wrench: np.ndarray, *,
                            distance_tol: float = DISTANCE_TOL) -> ComRegion | None:
    """
    Return :func:`feasible_region` from the legs' stacked H-reps, unchecked (a hot path).

    :param force_A: (K, m, 3) and ``force_b`` (K, m): the K full-dimensional force
        polytopes ``A f <= b`` [N]; ``wrench``: ``[f; L']`` (6,) finite;
        the rest as :func:`feasible_region`, whose None cases the caller has excluded
        but these two: kernels off, ``|f_z| <= 1e-6`` N.
    """
    if not kernels.ENABLED or abs(wrench[2]) <= VERTICAL_FORCE_TOL:
        return None
    return feasible_region_of_kernel(kernels.feasible_region(
        force_A, force_b, friction_rows, positions, wrench, distance_tol), distance_tol)


def feasible_region_of_kernel(out: tuple, distance_tol: float = DISTANCE_TOL
                              ) -> ComRegion | None:
    """
    Return the region of :func:`awp_ros.geometry.kernels.feasible_region`'s ``out``.

    ``(V, A, b, margin, status)``: empty (status 1), None (it failed), a point, a segment or
    the polygon, as :func:`feasible_region_of_rows` returns them.
    """
    V, A, b, margin, status = out
    if status == 1:
        return _empty(0)
    if status != 0:
        return None
    k = V.shape[0]
    if k == 1:
        return _point(V[0], 0)
    if k == 2:
        u = V[1] - V[0]
        length = math.hypot(u[0], u[1])
        return _segment(V[0], u / length, 0.0, length, distance_tol, 0)
    return ComRegion(2, V, A, b, margin, {'rows': 0, 'interior_point': np.zeros(2)})


# -- the polygon (full-dimensional slices) ---------------------------------------------------


#: The current CoM is the interior point of step (5) when every line is farther than this
#: many distance tolerances (closer, the dual points would be badly scaled).
_CENTRED = 1e3

_UNBOUNDED = ('the CoM region is unbounded (the slice of the wrench set is not bounded: a '
              'cone with opposing contacts, or too few rows)')


def _general(N2: np.ndarray, h: np.ndarray, rows: int, *, const_tol: float,
             wrench_tol: float, distance_tol: float, search_radius: float) -> ComRegion:
    """Return the region ``{delta : N2^T delta <= h}`` when 0 is not well inside (4-7)."""
    nn = np.hypot(N2[0], N2[1])
    const = nn <= const_tol
    if const.any():
        if np.min(h[const]) < -wrench_tol:
            return _empty(rows)
        keep = ~const
        N2, h, nn = N2[:, keep], h[keep], nn[keep]
    if h.size < 3:
        raise InputError(_UNBOUNDED)
    nh = (N2 / nn).T
    hh = h / nn
    x0, radius = _chebyshev(nh, hh, search_radius, distance_tol)
    if radius < -distance_tol:
        return _empty(rows)
    if radius <= distance_tol:
        return _thin(nh, hh, x0, distance_tol, rows)
    return _slice_polygon(N2, h, x0, distance_tol, rows)


def _slice_polygon(N2: np.ndarray, h: np.ndarray, x0: np.ndarray | None, tol: float,
                   rows: int) -> ComRegion:
    """
    Return the polygon of the lines ``N2^T delta <= h`` about the interior point ``x0``.

    Steps (6-7): compiled (:func:`awp_ros.geometry.kernels.polygon_region`) when the
    kernels are enabled, else :func:`_polar` and :func:`_polygon` (the numpy reference).
    """
    if kernels.ENABLED:
        out = kernels.polygon_region(N2, h, x0, tol, EDGE_PARALLEL_TOL)
        if out is None:
            raise InputError(_UNBOUNDED)
        A, b, V, margin = out
        return ComRegion(2, V, A, b, margin,
                         {'rows': rows, 'interior_point': np.zeros(2) if x0 is None else x0})
    shifted = N2 / h if x0 is None else N2 / (h - x0 @ N2)
    chain, V = _polar(shifted, tol)
    return _polygon(N2, h, chain, V, x0, tol, rows)


@lru_cache(maxsize=128)
def _shift(k: int, step: int) -> np.ndarray:
    """Return the cyclic index map ``i -> (i + step) mod k`` (read-only, cached)."""
    out = (np.arange(k) + step) % max(k, 1)
    out.setflags(write=False)
    return out


def _directions(k: int) -> np.ndarray:
    """Return ``k`` unit directions at angles ``2 pi j / k``, shape (k, 2)."""
    th = 2.0 * np.pi * np.arange(k) / k
    out = np.column_stack([np.cos(th), np.sin(th)])
    out.setflags(write=False)
    return out


_CHAIN_DIRECTIONS = 128
_U8 = _directions(8)
_U_CHAIN = _directions(_CHAIN_DIRECTIONS)
_SHIFT_CHAIN = (np.arange(_CHAIN_DIRECTIONS) - 1) % _CHAIN_DIRECTIONS
_FILTER_ROWS = 160     # up to this many rows, no first filter
_FILTER_SLACK = 1e-9   # relative: points this close to the first chain are kept
_MAX_ROUNDS = 20


def _polar(Dm: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the hull vertices of the dual points, ccw, and the primal vertices (steps 6-7).

    ``Dm`` (2, m) are the dual points ``d_i = n_i / s_i`` about an interior point (every
    ``s_i > 0``). A ccw convex chain of dual points containing 0, with the primal vertices
    ``v_j`` (``a . v_j = b . v_j = 1`` for its edge (a, b)), contains ``c`` iff
    ``c . v_j <= 1`` for every ``j``. (6) The extreme points along 8 directions make a first
    chain; the points inside it are dropped. (7) The extreme points of the rest along
    ``_CHAIN_DIRECTIONS`` directions make the chain; an edge is a hull edge iff no point
    lies beyond it, i.e. iff ``v_j`` satisfies every line within ``tol`` [m]:
    ``c . v_j <= 1 + tol |c|``; a violated vertex adds ``argmax_c c . v_j`` to the chain,
    until none is.

    :return: ``(chain, V)``: indices of the columns of ``Dm`` on the hull, ccw, and the
        primal vertices ``V`` (2, k) relative to the interior point, ``V[:, j]`` on the
        lines ``chain[j]`` and ``chain[j + 1]``.
    :raises InputError: when 0 is not strictly inside the hull (an unbounded region).
    """
    index = None
    if Dm.shape[1] > _FILTER_ROWS:
        V8 = _chain_vertices(Dm[:, (_U8 @ Dm).argmax(axis=1)].T.tolist())
        if V8 is not None:
            index = np.flatnonzero((V8 @ Dm).max(axis=0) > 1.0 - _FILTER_SLACK)
            Dm = Dm[:, index]
    # Sorted by polar angle, the hull's vertices are in ccw order whatever their indices.
    order = np.arctan2(Dm[1], Dm[0]).argsort()
    Dm = Dm[:, order]
    index = order if index is None else index[order]
    # An unbounded region (0 not strictly inside conv(d)) shows as det <= 0 below: the
    # chain's points then lie in a closed half-plane through 0.
    # Support points along directions swept ccw are cyclically non-decreasing in that order.
    top = (_U_CHAIN @ Dm).argmax(axis=1)
    chain = top[top != top[_SHIFT_CHAIN]]
    chain.sort()
    limit = np.hypot(Dm[0], Dm[1])
    limit *= tol
    limit += 1.0
    for _ in range(_MAX_ROUNDS):
        V = _edge_vertices(Dm, chain)
        excess = V.T @ Dm                                # (k, m): c . v_j
        excess -= limit
        worst = excess.max(axis=1)
        if float(worst.max()) <= 0.0:
            return index[chain], V
        chain = np.union1d(chain, excess[worst > 0.0].argmax(axis=1))
    # Rare: the sampled chain keeps missing hull vertices; take the exact 2D hull (qhull).
    try:
        hull = ConvexHull(Dm.T)
    except QhullError as exc:
        raise GeometryError(f'the CoM polygon: qhull failed on the dual points: {exc}') from exc
    chain = np.sort(hull.vertices)        # Dm is sorted by angle: index order is ccw
    return index[chain], _edge_vertices(Dm, chain)


def _edge_vertices(Dm: np.ndarray, chain: np.ndarray) -> np.ndarray:
    """
    Return the primal vertices (2, k) of the ccw chain ``Dm[:, chain]`` of dual points.

    ``V[:, j]`` solves ``a . v = b . v = 1`` for the chain's edge (a, b) = (j, j + 1).

    :raises InputError: 0 is not strictly inside the chain (an unbounded region).
    """
    C = Dm[:, chain]
    Cn = C[:, _shift(chain.size, 1)]
    det = C[0] * Cn[1] - C[1] * Cn[0]
    if chain.size < 3 or float(det.min()) <= 0.0:
        raise InputError(_UNBOUNDED)
    V = (Cn - C)[::-1] / det
    V[1] *= -1.0                                         # ((b_y - a_y), (a_x - b_x)) / det
    return V


def _chain_vertices(points: list[list[float]]) -> np.ndarray | None:
    """
    Return the primal vertices ``v`` (k, 2) of a ccw closed chain of dual points, or None.

    ``v`` solves ``a . v = b . v = 1`` for each edge (a, b) (repeated points skipped); None
    when 0 is not strictly inside the chain (an edge with ``a x b <= 0``) or fewer than 3
    distinct points. Pure Python: a few points.
    """
    out = []
    ax, ay = points[-1]
    for bx, by in points:
        if bx != ax or by != ay:
            det = ax * by - ay * bx
            if not det > 0.0:
                return None
            out.append(((by - ay) / det, (ax - bx) / det))
            ax, ay = bx, by
    return np.array(out) if len(out) >= 3 else None


def _polygon(N2: np.ndarray, h: np.ndarray, chain: np.ndarray, V: np.ndarray,
             x0: np.ndarray | None, tol: float, rows: int) -> ComRegion:
    """
    Return the polygon whose edges are the lines ``chain`` (unit rows, ccw vertices).

    ``V`` (2, k): the vertices relative to ``x0`` (None: the current CoM), ``V[:, j]`` the
    end of edge ``j``.
    """
    interior = np.zeros(2) if x0 is None else x0
    while True:
        k = chain.size
        a = N2[:, chain]
        nn = np.hypot(a[0], a[1])
        A = (a / nn).T
        b = h[chain] / nn
        # Edge i joins vertices i - 1 and i; a line touching the polygon at one vertex
        # (its dual point on a hull edge) has a zero-length edge and is dropped (when its
        # neighbours meet: their normals are not parallel).
        e = V - V[:, _shift(k, -1)]
        length = np.hypot(e[0], e[1])
        if k <= 3 or float(length.min()) > tol:
            break
        short = length <= tol
        Ap, An = A[_shift(k, -1)], A[_shift(k, 1)]
        short &= Ap[:, 0] * An[:, 1] - Ap[:, 1] * An[:, 0] > EDGE_PARALLEL_TOL
        drop = short & ~short[_shift(k, -1)] if not short.all() else np.arange(k) == 0
        if not drop.any():
            break
        chain = chain[~drop]
        A, b = A[~drop], b[~drop]
        An, bn = A[_shift(A.shape[0], 1)], b[_shift(A.shape[0], 1)]
        det = A[:, 0] * An[:, 1] - A[:, 1] * An[:, 0]
        V = np.vstack(((b * An[:, 1] - A[:, 1] * bn) / det,
                       (A[:, 0] * bn - An[:, 0] * b) / det))
        x0 = None
    V = V.T if x0 is None else V.T + x0
    inside = float(b.min())
    margin = inside if inside >= 0.0 else -_distance_to_polygon(V)
    return ComRegion(2, np.ascontiguousarray(V), A, b, margin,
                     {'rows': rows, 'interior_point': interior})


#: sin of the angle under which two edge normals of a region count as parallel.
EDGE_PARALLEL_TOL = 1e-12


def _distance_to_polygon(V: np.ndarray) -> float:
    """Return the distance of 0 to the closed chain of vertices ``V`` (point to segments)."""
    e = V[_shift(V.shape[0], 1)] - V
    ee = (e * e).sum(axis=1)
    t = np.clip(-(V * e).sum(axis=1) / np.where(ee > 0.0, ee, 1.0), 0.0, 1.0)
    q = V + t[:, None] * e
    return float(np.sqrt((q * q).sum(axis=1).min()))


# -- interior point: the Chebyshev centre by constraint generation ---------------------------


def _chebyshev(nh: np.ndarray, hh: np.ndarray, box: float,
               tol: float) -> tuple[np.ndarray, float]:
    r"""
    Return the Chebyshev centre and radius of ``{x : nh x <= hh, |x|_inf <= box}`` (step 5).

    .. math:: \max_{x, r}\ r \quad \text{s.t.}\ n_i \cdot x + r \le h_i

    The radius is negative for an empty set. Dual simplex on this 3-variable LP: a basis of
    3 rows with multipliers ``lam >= 0``, ``sum_j lam_j (n_j, 1) = (0, 0, 1)``, is optimal
    for those rows (a relaxation: its ``r`` bounds the full radius from above); the most
    violated row ``k`` enters, the ratio test ``min lam_j / mu_j`` (``mu = B^{-T} (n_k, 1)``,
    ``mu_j > 0``) picks the row that leaves, until no row is violated (the exact optimum).
    The first basis is the tightest row at 0 and the two box rows facing it. Once
    ``r < -tol`` the loop stops (empty); after ``_MAX_PIVOTS`` pivots (cycling on a
    degenerate vertex) one HiGHS LP decides.
    """
    m = hh.size
    G = np.empty((m + 4, 3))
    G[:m, :2] = nh
    G[m:, :2] = [[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]]
    G[:, 2] = 1.0
    g = np.concatenate((hh, np.full(4, float(box))))
    k = int(hh.argmin())
    basis = [k, m + (1 if nh[k, 0] >= 0.0 else 0), m + (3 if nh[k, 1] >= 0.0 else 2)]
    check = max(tol, 1e-12 * float(box))
    for _ in range(_MAX_PIVOTS):
        inv = _inverse3(G[basis].tolist())
        if inv is None:
            break
        gb = g[basis].tolist()
        z = np.array([sum(a * c for a, c in zip(row, gb)) for row in inv])
        if z[2] < -tol:
            return z[:2], float(z[2])
        viol = G @ z
        viol -= g
        k = int(viol.argmax())
        if viol[k] <= check:
            return z[:2], float(z[2])
        gk = G[k].tolist()
        lam = inv[2]                                       # B^{-T} (0, 0, 1)
        mu = [sum(inv[i][j] * gk[i] for i in range(3)) for j in range(3)]
        ratios = [(max(lam[j], 0.0) / mu[j], j) for j in range(3) if mu[j] > 1e-12]
        if not ratios:
            break                                          # cannot happen: LP feasible
        basis[min(ratios)[1]] = k
    return _chebyshev_lp(nh, hh, box)


_MAX_PIVOTS = 100


def _inverse3(B: list[list[float]]) -> list[list[float]] | None:
    """Return the inverse of a 3 x 3 matrix (rows as lists), None when singular."""
    (a, b, c), (d, e, f), (g, h, i) = B
    A, D, G = e * i - f * h, c * h - b * i, b * f - c * e
    det = a * A + b * (f * g - d * i) + c * (d * h - e * g)
    if abs(det) <= 1e-14:
        return None
    return [[A / det, D / det, G / det],
            [(f * g - d * i) / det, (a * i - c * g) / det, (c * d - a * f) / det],
            [(d * h - e * g) / det, (b * g - a * h) / det, (a * e - b * d) / det]]


def _chebyshev_lp(nh: np.ndarray, hh: np.ndarray, box: float) -> tuple[np.ndarray, float]:
    """Return the Chebyshev centre and radius by one HiGHS LP over every row."""
    A = np.column_stack((nh, np.ones(hh.size)))
    res = linprog([0.0, 0.0, -1.0], A_ub=A, b_ub=hh,
                  bounds=[(-box, box), (-box, box), (None, None)], method='highs')
    if res.status != 0:
        raise GeometryError(f'the Chebyshev LP of the CoM region failed: {res.message}')
    return res.x[:2].copy(), float(res.x[2])


# -- degenerate regions -----------------------------------------------------------------------


def _interval(alpha: np.ndarray, beta: np.ndarray, const_tol: float, beta_tol: float,
              tol: float) -> tuple[float, float] | None:
    """Return ``[lo, hi]`` of ``{t : alpha t <= beta}``, None when empty (within ``tol``)."""
    pos, neg = alpha > const_tol, alpha < -const_tol
    const = ~(pos | neg)
    if const.any() and float(beta[const].min()) < -beta_tol:
        return None
    if not (pos.any() and neg.any()):
        raise InputError(_UNBOUNDED)
    hi = float((beta[pos] / alpha[pos]).min())
    lo = float((beta[neg] / alpha[neg]).max())
    if lo > hi + tol:
        return None
    return lo, hi


def _thin(nh: np.ndarray, hh: np.ndarray, x: np.ndarray, tol: float,
          rows: int) -> ComRegion:
    """
    Return a full-dimensional slice whose inscribed radius is within ``tol`` of 0.

    The set lies within ``tol`` of a segment through the Chebyshev centre ``x``, along one of
    the tightest lines there; each candidate direction is searched by a ratio test with the
    slacks relaxed by ``tol`` and the longest interval is kept.
    """
    slack = hh - nh @ x
    best = None
    for i in np.argsort(slack)[:3].tolist():
        u = np.array([-nh[i, 1], nh[i, 0]])
        got = _interval(nh @ u, slack + tol, 1e-12, 0.0, tol)
        if got is not None and (best is None or got[1] - got[0] > best[1][1] - best[1][0]):
            best = (u, got)
    if best is None:
        return _empty(rows)
    u, (lo, hi) = best
    return _segment(x, u, lo, hi, tol, rows)


def _segment(origin: np.ndarray, u: np.ndarray, lo: float, hi: float, tol: float,
             rows: int) -> ComRegion:
    """Return the segment ``origin + t u``, ``t in [lo, hi]`` (a point when shorter than tol)."""
    ox, oy = np.asarray(origin, dtype=float).tolist()
    ux, uy = np.asarray(u, dtype=float).tolist()
    norm = math.hypot(ux, uy)
    ux, uy = ux / norm, uy / norm
    if hi - lo <= tol:
        t = 0.5 * (lo + hi)
        return _point(np.array([ox + t * ux, oy + t * uy]), rows)
    p = (ox + lo * ux, oy + lo * uy)
    q = (ox + hi * ux, oy + hi * uy)
    c = uy * -ox + ux * oy                           # nu = (-u_y, u_x): nu . origin
    s = ux * ox + uy * oy
    A = np.array([[-uy, ux], [uy, -ux], [ux, uy], [-ux, -uy]])
    b = np.array([c, -c, s + hi, -(s + lo)])
    return ComRegion(1, np.array([p, q]), A, b, -_distance_to_segment(p, q), {'rows': rows})


def _distance_to_segment(p: tuple[float, float], q: tuple[float, float]) -> float:
    """Return the distance of 0 to the segment ``[p, q]`` (points as pairs of floats)."""
    ex, ey = q[0] - p[0], q[1] - p[1]
    t = min(1.0, max(0.0, -(p[0] * ex + p[1] * ey) / (ex * ex + ey * ey)))
    return math.hypot(p[0] + t * ex, p[1] + t * ey)


def _point(x: np.ndarray, rows: int) -> ComRegion:
    """Return the region ``{x}``."""
    x = np.asarray(x, dtype=float)
    A = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    b = np.array([x[0], -x[0], x[1], -x[1]])
    return ComRegion(0, x[None, :].copy(), A, b, -float(np.linalg.norm(x)), {'rows': rows})


def _empty(rows: int) -> ComRegion:
    """Return the empty region."""
    return ComRegion(-1, np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), float('nan'),
                     {'rows': rows})


def _wrench(force: np.ndarray, moment: np.ndarray) -> list[float]:
    """Return ``[f; L']`` as 6 Python floats, or raise InputError naming the bad vector."""
    if type(force) is np.ndarray and type(moment) is np.ndarray and force.shape == (3,) \
            and moment.shape == (3,) and force.dtype == moment.dtype == np.float64:
        out = force.tolist() + moment.tolist()      # the hot path: checked in one step
        if all(map(math.isfinite, out)):
            return out
    out = []
    for name, x in (('force', force), ('moment', moment)):
        try:
            arr = np.asarray(x, dtype=float)
        except (TypeError, ValueError):
            arr = np.zeros(0)
        values = arr.tolist() if arr.shape == (3,) else None
        if values is None or not all(map(math.isfinite, values)):
            raise InputError(f'{name} must be a finite 3-vector; got {x!r:.80}')
        out += values
    return out
