"""Exact H-representation of a Minkowski sum of lifted 3D polytopes: the FWS (and AWP, any leg).

For stance feet at ``p_k`` [m] relative to the CoM (world-aligned axes) and per-leg force
polytopes ``Q_k`` [N] given by their vertices, the set is

.. math::

    S = \\sum_k L_k Q_k \\subset \\mathbb{R}^6, \\qquad
    L_k = \\begin{bmatrix} I_3 \\\\ [p_k]_\\times \\end{bmatrix}, \\qquad
    h_S(a) = \\sum_k \\max_{v \\in V_k} (L_k^T a) \\cdot v                     \\qquad (1)

With ``Q_k`` the friction-bounded polytopes it is the FWS (feasible wrench set); with the
force polytopes of legs with more than 3 joints it is their AWP. Algorithm (all in the
coordinates ``y = U^T (x - o)`` of the affine hull of ``S``, dimension ``r``, where
``M_k = U^T L_k``):

(2) every facet of ``S`` with unit normal ``a`` is ``sum_k M_k G_k`` for faces ``G_k`` of
    ``Q_k`` whose dimensions ``d_k`` add up to ``r - 1`` and whose lifted direction spaces
    ``M_k dir(G_k)`` are independent (an exchange argument on the faces maximising ``a``);
    so ``a`` is the generalised cross product of the ``r - 1`` lifted face directions,
    ``a . v = det[v, g_1, ..., g_{r-1}]``, computed with exterior products: the wedge
    ``X_k`` of each face's directions is a ``d_k``-vector and ``a = *(X_1 ^ ... ^ X_K)``;
(3) the choice is kept only if ``c_k = M_k^T a`` lies in the normal cone of ``G_k`` for
    every leg, up to one global sign (``m . c_k >= 0`` for the face's check vectors ``m``,
    :mod:`awp_ros.face_lattice`); each check value ``m . c_k = a . (M_k m)`` is a determinant
    too, the pairing of ``(M_k m) ^ X_k`` with the wedge of the other legs' faces, so one
    small matrix product per leg tests every combination at once (no loop over candidates);
(4) ``b = h_S(a)`` by (1) over all the given points, so each kept row is an exact supporting
    halfspace whatever the tolerances (and whatever the face search found); rows are
    deduplicated after rounding.

Every tolerance in (3) only admits extra (redundant but valid) rows: a facet's check values
are exactly >= 0, so it is kept as long as the slack exceeds the rounding error. This is why
(3) may run in float32 (about 2/3 of the work, 4 stance legs): its slack ``cone_tol`` (1e-5
of the bound on the values) is 8x its worst rounding; the survivors' normals are recomputed
in float64 and (4) is float64. Legs with ``d_k = 0`` need no enumeration (their vertex is the
argmax in (4)). An empty leg makes ``S`` empty; no leg gives the point ``{0}``.

Organisation and cost. Choices are grouped by *pattern* (the dimensions ``d_k`` in decreasing
order; reordering legs only flips the sign of ``a``, and both signs are tested), and all leg
assignments of a pattern run as one batch. Parallel edges (and opposite facets) of a leg form
one class: one normal, the union of their cones. Rank-deficient choices (a vanishing partial
wedge) are dropped (``normal_tol``): by the exchange argument of (2) each facet also has an
independent choice. For HyQ-like legs (11-13 vertices, about 14 edge classes, 7 facet
classes) and 4 legs this is about 8e4 choices (three quarters in the pattern (2, 1, 1, 1)),
3-8e3 survivors and 2-4e3 facets, in about 8 ms on one core. Run numpy's BLAS with one thread
(e.g. ``OPENBLAS_NUM_THREADS=1``): with two threads on two shared cores it is 2x slower.
Large temporaries live in per-thread buffers reused across calls: fresh pages cost as much
as the arithmetic.

Without the H-rep, :func:`lp_directional_margins` answers membership and the 12 directional
margins exactly by one warm-started LP (about 1.2 ms for HyQ's 4 legs).
"""

from __future__ import annotations

import threading
from functools import lru_cache
from itertools import combinations, permutations
from math import comb
from typing import Sequence

import numpy as np

from awp_ros.errors import InputError
from awp_ros.face_lattice import Faces, polytope_faces
from awp_ros.linalg import orthonormal_span
from awp_ros.polytope import Polytope

__all__ = ['feasible_wrench_set', 'lift_matrices', 'lp_directional_margins',
           'minkowski_sum_of_lifts']

# Bound on the float32 rounding of a check value (3), relative to ``bound``: with u = 6e-8
# and q <= 20 products per value (inputs rounded, then summed in any order) the error is at
# most (q + 1) u |O| |Y| <= 1.3e-6 bound; twice that is the smallest slack accepted.
_FLOAT32_SLACK = 2.5e-6


def lift_matrices(positions: np.ndarray) -> np.ndarray:
    """Return the lifts ``L_k = [I_3; [p_k]_x]`` of shape (K, 6, 3), ``L_k f = [f; p_k x f]``.

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


def feasible_wrench_set(positions: np.ndarray, friction_polytopes: Sequence[Polytope],
                        **tolerances: float) -> Polytope:
    """Return the FWS, the Minkowski sum of the lifted friction-bounded leg polytopes.

    .. math:: \\mathrm{FWS} = \\sum_k L_k\\, (P_k \\cap C_k \\cap \\{n_k \\cdot f \\ge 0\\})

    :param positions: (K, 3) stance feet relative to the CoM [m], world-aligned axes.
    :param friction_polytopes: K 3D polytopes of contact forces [N] (world-aligned axes) with
        their vertices (and complete H-reps, used for their facets); an empty one makes the
        FWS empty.
    :param tolerances: keyword tolerances passed to :func:`minkowski_sum_of_lifts`.
    :return: the FWS as a :class:`Polytope` in R^6 ([N, N.m]), complete H-rep.
    :raises InputError: on mismatched lengths or bad shapes, or a non-empty polytope without
        vertices.
    """
    vertex_sets = []
    for k, Q in enumerate(friction_polytopes):
        V = np.asarray(Q.vertices, dtype=float).reshape(-1, Q.ambient_dim)
        if Q.ambient_dim != 3:
            msg = f'friction polytope {k} lives in R^{Q.ambient_dim}, not R^3'
            raise InputError(msg)
        if not Q.is_empty and V.shape[0] == 0:
            msg = f'friction polytope {k} (dimension {Q.dimension}) has no vertices'
            raise InputError(msg)
        vertex_sets.append(np.zeros((0, 3)) if Q.is_empty else V)
    halfspaces = [(Q.A, Q.b) if Q.dimension == 3 and Q.A.shape[0] else None
                  for Q in friction_polytopes]
    return minkowski_sum_of_lifts(positions, vertex_sets, halfspaces=halfspaces, **tolerances)


def minkowski_sum_of_lifts(positions: np.ndarray, vertex_sets: Sequence[np.ndarray], *,
                           halfspaces: Sequence[tuple | None] | None = None,
                           rank_tol: float = 1e-7, plane_tol: float = 1e-9,
                           cone_tol: float = 1e-5, normal_tol: float = 1e-8,
                           dedupe_decimals: int = 10) -> Polytope:
    """Return the exact H-rep of ``sum_k L_k conv(V_k)`` in R^6 (module docstring, (1)-(4)).

    .. math:: S = \\sum_k L_k\\, \\mathrm{conv}(V_k), \\quad
              S = \\{x : A x \\le b,\\; x = o + U y\\}

    :param positions: (K, 3) points of application relative to the CoM [m] (world axes).
    :param vertex_sets: K arrays (n_k, 3) of points [N] (duplicates and non-extreme points
        allowed; ``n_k = 0`` is an empty leg).
    :param halfspaces: optional K entries ``(A_k, b_k)`` or None: rows with ``A_k f <= b_k`` on
        ``Q_k`` that include all its facet planes (its H-rep); they spare the search for facets
        among point triples (:func:`~awp_ros.face_lattice.polytope_faces`).
    :param rank_tol: relative rank tolerance for the hull of each ``Q_k`` and of ``S``: a leg
        thinner than about ``rank_tol`` times its size is flattened (projected on its plane or
        line, so S moves by about that much); a barely thicker one has facet normals accurate
        to about ``1e-16 / rank_tol``, which bounds how far the H-rep can overshoot S.
    :param plane_tol: relative tolerance for points on facet planes of each ``Q_k``.
    :param cone_tol: slack of the float32 normal-cone filter (3), relative to the bound on
        the check values; it must exceed float32 rounding (about 2e-6), a larger one only
        adds redundant rows.
    :param normal_tol: a face choice whose unnormalised normal is shorter than this times its
        bound (the product of the lifted unit directions) is rank-deficient and skipped.
    :param dedupe_decimals: rows equal after rounding ``a`` and ``b / scale`` to this many
        decimals are merged.
    :return: a :class:`Polytope` with unit rows ``A`` in the hull's direction space, ``b``,
        ``hull_origin``, ``hull_basis``, ``dimension = r``; ``vertices`` are given for one
        leg (the lifted vertices) and for none ({0}), else (0, 6). ``meta`` holds
        ``candidates`` (face choices examined) and ``kept`` (rows before deduplication).
    :raises InputError: on bad shapes, non-finite values or mismatched lengths, or
        ``cone_tol`` below float32 rounding.
    """
    if not cone_tol >= _FLOAT32_SLACK:
        msg = f'cone_tol={cone_tol!r} must be >= {_FLOAT32_SLACK} (float32 filter rounding)'
        raise InputError(msg)
    P = np.asarray(positions, dtype=float)
    if P.ndim != 2 or P.shape[1] != 3 or not np.all(np.isfinite(P)):
        raise InputError(f'positions must be a finite (K, 3) array; got shape {P.shape}')
    if len(vertex_sets) != P.shape[0]:
        msg = f'{len(vertex_sets)} vertex sets for {P.shape[0]} positions'
        raise InputError(msg)
    if halfspaces is None:
        halfspaces = [None] * len(vertex_sets)
    if len(halfspaces) != len(vertex_sets):
        msg = f'{len(halfspaces)} halfspace sets for {len(vertex_sets)} vertex sets'
        raise InputError(msg)
    faces = [polytope_faces(V, H, rank_tol=rank_tol, plane_tol=plane_tol)
             for V, H in zip(vertex_sets, halfspaces)]
    if any(F.dimension < 0 for F in faces):
        return Polytope.empty(6)
    L = lift_matrices(P)
    origin = np.zeros(6)
    for Lk, F in zip(L, faces):
        origin += Lk @ F.origin
    spans = [Lk @ F.basis for Lk, F in zip(L, faces)]
    U = orthonormal_span(np.hstack(spans + [np.zeros((6, 0))]).T, rtol=rank_tol)
    r = U.shape[1]
    if r == 0:
        return Polytope(0, origin[None, :], np.zeros((0, 6)), np.zeros(0), origin,
                        np.zeros((6, 0)), {'candidates': 0, 'kept': 0})
    M = np.einsum('nr,knd->krd', U, L)            # M_k = U^T L_k, (K, r, 3)
    A_r, count = _facet_normals(faces, M, r, cone_tol, normal_tol)
    # Support (4) over every input point, not only the extreme ones the face search kept;
    # a leg found flat within rank_tol is projected on its plane like its faces (consistent
    # flattening: mixing the two made an ill-conditioned H-rep overshoot S).
    Z = [(np.asarray(V, dtype=float) - F.origin) @ (F.basis @ F.basis.T) @ Mk.T
         for V, F, Mk in zip(vertex_sets, faces, M)]
    b_r = _support(A_r, Z)
    kept = A_r.shape[0]
    scale = sum(float(np.max(np.linalg.norm(z, axis=1))) for z in Z) or 1.0
    first = _unique_rows(np.hstack([A_r, b_r[:, None] / scale]), dedupe_decimals)
    A = A_r[first] @ U.T
    b = b_r[first] + A @ origin
    if len(faces) == 1:
        vertices = faces[0].vertices @ L[0].T
    else:
        vertices = np.zeros((0, 6))
    meta = {'candidates': count, 'kept': kept}
    return Polytope(r, vertices, A, b, origin, U, meta)


def lp_directional_margins(positions: np.ndarray, vertex_sets: Sequence[np.ndarray],
                           w: np.ndarray, *,
                           feasibility_tol: float = 1e-6) -> tuple[bool, np.ndarray, np.ndarray]:
    """Return membership and directional margins of ``w`` in S exactly, without the H-rep.

    .. math:: t^\\pm_i = \\max\\{t : w \\pm t\\, e_i \\in S\\}, \\qquad
              S = \\sum_k L_k\\, \\mathrm{conv}(V_k)

    One LP in the barycentric weights ``lam_k >= 0`` (``sum_k L_k V_k^T lam_k - t_i e_i = w``,
    ``1^T lam_k = 1``) solved 13 times with warm starts (primal simplex, HiGHS): ``t = 0``
    for membership, then ``max`` and ``min`` of each ``t_i``. Same conventions as
    :func:`awp_ros.margin.directional_margins` (``t^+ = t_0, t^- = -t_0`` when the line meets
    a flat S in one point; NaN when it misses S). HiGHS is taken from ``highspy`` when
    installed, else from the copy bundled in scipy; without either, scipy's ``linprog``.

    :param positions: (K, 3) feet relative to the CoM [m], world-aligned axes.
    :param vertex_sets: K arrays (n_k, 3) of points [N].
    :param w: (6,) wrench [N, N.m], same frame.
    :param feasibility_tol: absolute tolerance on the equality rows [N, N.m].
    :return: ``(member, t_plus, t_minus)``, the last two of shape (6,) [N or N.m].
    :raises InputError: on bad shapes or non-finite values.
    """
    P = np.asarray(positions, dtype=float)
    w = np.asarray(w, dtype=float)
    if P.ndim != 2 or P.shape[1] != 3 or len(vertex_sets) != P.shape[0]:
        msg = f'positions {P.shape} and {len(vertex_sets)} vertex sets do not match'
        raise InputError(msg)
    if w.shape != (6,) or not np.all(np.isfinite(w)) or not np.all(np.isfinite(P)):
        raise InputError(f'w must be a finite (6,) wrench; got shape {w.shape}')
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


class _HighsLp:
    """min c t_i over {A [lam; t] = rhs, lam >= 0, t_j = 0 (j != i)}, warm-started HiGHS."""

    def __init__(self, A: np.ndarray, rhs: np.ndarray, n: int, tol: float) -> None:
        self.n = n
        try:
            import highspy as core
        except ImportError:
            try:
                from scipy.optimize._highspy import _core as core
            except ImportError:                   # pragma: no cover - scipy without HiGHS
                core = None
        self.core, self.A, self.rhs = core, A, rhs
        if core is None:
            return
        self.h = core.Highs() if hasattr(core, 'Highs') else core._Highs()
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
        """The same LP with scipy.optimize.linprog (no warm start)."""
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


# -- the enumeration (2)-(3) ------------------------------------------------------------

def _facet_normals(faces: list[Faces], M: np.ndarray, r: int, cone_tol: float,
                   normal_tol: float) -> tuple[np.ndarray, int]:
    """Return unit candidate normals (N, r) that pass the normal-cone tests, and the count.

    The face choices are grouped by *pattern*, the face dimensions sorted in decreasing order
    (reordering the legs only flips the sign of ``a``, and both signs are tested); all leg
    assignments of one pattern run as one batch, padded to the largest class count.
    """
    if r == 1:                                    # a segment: both directions of the line
        return np.array([[1.0], [-1.0]]), 2
    # Per leg and face dimension d: X (m, C(r, d)) wedges, Y (m, k, c, C(r, d + 1)) checks.
    lifted = []
    for F, Mk in zip(faces, M):
        per_dim = {}
        for d, group in enumerate(F.groups, start=1):
            if d > r - 1:
                break
            dirs = group.dirs @ Mk.T               # (m, d, r)
            X = dirs[:, 0, :]
            for i in range(1, d):
                X = _wedge_rows(X, dirs[:, i, :], r, i, 1)
            checks = group.checks @ Mk.T            # (m, k, c, r)
            m, k, c = checks.shape[:3]
            Y = _wedge_rows(checks.reshape(m * k * c, r), np.repeat(X, k * c, axis=0), r, 1, d)
            per_dim[d] = (X, Y.reshape(m, k, c, Y.shape[-1]), group.mask)
        lifted.append(per_dim)
    scale = max(float(np.linalg.norm(Mk, 2)) for Mk in M)
    normals, count = [], 0
    for dims, legs in _patterns(lifted, r - 1):
        sets = [_stack([lifted[k][d] for k in column], r, d)
                for d, column in zip(dims, zip(*legs))]
        a, n = _pattern_normals(sets, dims, r, scale, cone_tol, normal_tol)
        normals.append(a)
        count += n
    if not normals:
        return np.zeros((0, r)), 0
    return np.vstack(normals), count


def _patterns(lifted: list[dict], total: int) -> list[tuple[list[int], list[tuple]]]:
    """Return (dims, leg tuples): face dimensions in decreasing order adding up to ``total``.

    Legs are distinct, and increasing within a run of equal dimensions (each face choice once).
    """
    out = []
    available = sorted({d for per_dim in lifted for d in per_dim}, reverse=True)

    def partitions(rest: int, largest: int) -> list[list[int]]:
        if rest == 0:
            return [[]]
        return [[d] + tail for d in available if d <= min(rest, largest)
                for tail in partitions(rest - d, d)]

    for dims in partitions(total, total):
        if len(dims) > len(lifted):
            continue
        legs = [ks for ks in permutations(range(len(lifted)), len(dims))
                if all(d in lifted[k] for k, d in zip(ks, dims))
                and all(ks[i] < ks[i + 1] for i in range(len(dims) - 1)
                        if dims[i] == dims[i + 1])]
        if legs:
            out.append((dims, legs))
    return out


def _stack(items: list[tuple], r: int, d: int) -> tuple[np.ndarray, ...]:
    """Stack the (X, Y, mask) of several legs into a batch, padding with empty classes."""
    n = max(item[0].shape[0] for item in items)
    k = max(item[1].shape[1] for item in items)
    c = max(item[1].shape[2] for item in items)
    B = len(items)
    Xb = np.zeros((B, n, comb(r, d)))
    Yb = np.zeros((B, n, k, c, comb(r, d + 1)))
    mb = np.zeros((B, n, k), dtype=bool)
    for b, (X, Y, mask) in enumerate(items):
        Xb[b, :X.shape[0]] = X
        Yb[b, :Y.shape[0], :Y.shape[1], :Y.shape[2]] = Y
        mb[b, :mask.shape[0], :mask.shape[1]] = mask
    return Xb, Yb, mb


def _pattern_normals(sets: list, dims: list[int], r: int, scale: float, cone_tol: float,
                     normal_tol: float) -> tuple[np.ndarray, int]:
    """Normals of every face choice of one pattern (a batch of leg tuples) passing (3).

    ``scale`` bounds the norm of every lifted unit vector, so ``bound = scale ** r`` bounds
    ``|a|`` times the norm of a lifted check vector (Hadamard) and ``cone_tol * bound`` is an
    absolute slack. Arrays carry a leading batch axis ``B``; the candidates of one batch entry
    form the grid ``(n_0, ..., n_{J-1})`` of class indices.
    """
    J = len(sets)
    bound = scale ** r
    Xs = [item[0] for item in sets]
    B = Xs[0].shape[0]
    ns = [X.shape[1] for X in Xs]
    N = int(np.prod(ns))
    # Prefix and suffix wedges; O_j = prefix_{<j} ^ suffix_{>j}.
    pre, suf = [np.ones((B, 1, 1))], [np.ones((B, 1, 1))]
    deg_pre, deg_suf = [0], [0]
    for j in range(J - 1):
        pre.append(_wedge_all(pre[-1], Xs[j], r, deg_pre[-1], dims[j], f'pre{j}'))
        deg_pre.append(deg_pre[-1] + dims[j])
    for j in range(J - 1, 0, -1):
        suf.append(_wedge_all(Xs[j], suf[-1], r, dims[j], deg_suf[-1], f'suf{j}'))
        deg_suf.append(deg_suf[-1] + dims[j])
    suf.reverse()
    deg_suf.reverse()
    # Running min and max over all check values (3), in the grid layout (B, n_0, ..., n_J-1),
    # in float32 (a filter whose slack exceeds its rounding; the survivors' normals are
    # recomputed in float64). Buffers are reused across calls (no page faults).
    lo = _WORK.get('lo', (B,) + tuple(ns))
    hi = _WORK.get('hi', (B,) + tuple(ns))
    lo.fill(0.0)
    hi.fill(0.0)
    for j in range(J):
        _, Y, mask = sets[j]                        # Y (B, n_j, k, c, C(r, d_j + 1))
        k, c = Y.shape[2:4]
        if c == 0:
            continue
        other = _wedge_all(pre[j], suf[j], r, deg_pre[j], deg_suf[j], 'O')   # (B, N / n_j, .)
        T = _wedge_table(r, r - 1 - dims[j], dims[j] + 1)[:, :, 0]
        T = T * (-1.0) ** (deg_pre[j] + (dims[j] + 1) * deg_suf[j])
        rows = other.shape[1]
        other32 = _WORK.get('O32', other.shape)
        other32[...] = other
        OT = np.swapaxes(other32, 1, 2)               # (B, ., rows)
        Y = Y @ T.T                                   # pairs with O (not O @ T): smaller
        # Slot i (the i-th parallel face of a class) exists for a prefix of the classes
        # (classes come sorted by size), so slot i > 0 only runs over that prefix.
        vmin = vmax = None
        for i in range(k):
            m = ns[j] if i == 0 else int(mask[:, :, i].sum(axis=1).max())
            if m == 0:
                break
            Yi = Y[:, :m, i].transpose(0, 2, 1, 3).reshape(B, c * m, -1).astype(np.float32)
            vals = np.matmul(Yi, OT, out=_WORK.get(f'vals{min(i, 1)}', (B, c * m, rows)))
            vals = vals.reshape(B, c, m, rows)       # vals[b, check, class, row]
            fmin, fmax = vals[:, 0], _WORK.get(f'fmax{min(i, 1)}', (B, m, rows))
            fmax[...] = fmin
            for ci in range(1, c):
                np.minimum(fmin, vals[:, ci], out=fmin)
                np.maximum(fmax, vals[:, ci], out=fmax)
            # A class passes when one of its faces does (union of their normal cones);
            # empty slots (padding) get -inf / +inf, so an empty class fails both signs.
            empty = ~mask[:, :m, i]
            fmin[empty] = -np.inf
            fmax[empty] = np.inf
            if vmin is None:
                vmin, vmax = fmin, fmax
            else:
                np.maximum(vmin[:, :m], fmin, out=vmin[:, :m])
                np.minimum(vmax[:, :m], fmax, out=vmax[:, :m])
        shape = [B, ns[j]] + ns[:j] + ns[j + 1:]
        np.minimum(lo, np.moveaxis(vmin.reshape(shape), 1, j + 1), out=lo)
        np.maximum(hi, np.moveaxis(vmax.reshape(shape), 1, j + 1), out=hi)
    # Rank-deficient choices (a vanishing partial wedge) fail both signs.
    small = (normal_tol * bound) ** 2
    dead_last = np.einsum('bnp,bnp->bn', pre[J - 1], pre[J - 1]) <= small   # (B, N / n_-1)
    dead_first = np.einsum('bnp,bnp->bn', suf[0], suf[0]) <= small          # (B, N / n_0)
    for grid, fill in ((lo, -np.inf), (hi, np.inf)):
        grid.reshape(B, -1, ns[-1])[dead_last] = fill
        grid.reshape(B, ns[0], -1).transpose(0, 2, 1)[dead_first] = fill
    tol = cone_tol * bound
    pos, neg = np.flatnonzero(lo >= -tol), np.flatnonzero(hi <= tol)
    # Normals of the survivors only: W = prefix_{<J-1} ^ X_{J-1}, a_i = (-1)^i W_{[r] - i}.
    idx = np.concatenate([pos, neg])
    b, rest = idx // N, idx % N
    W = _wedge_rows(pre[J - 1][b, rest // ns[-1]], Xs[-1][b, rest % ns[-1]], r,
                    deg_pre[J - 1], dims[-1])
    a = W[:, ::-1] * ((-1.0) ** np.arange(r))[None, :]
    a[pos.size:] *= -1.0
    norm = np.linalg.norm(a, axis=1)
    keep = norm > normal_tol * bound
    return a[keep] / norm[keep, None], B * N


class _Workspace(threading.local):
    """Per-thread buffers reused across calls, grown on demand (no fresh pages per call)."""

    def __init__(self) -> None:
        self.buffers: dict[str, np.ndarray] = {}

    def get(self, name: str, shape: tuple, dtype: type = np.float32) -> np.ndarray:
        """Return an uninitialised array of ``shape`` backed by buffer ``name``."""
        size = int(np.prod(shape))
        buf = self.buffers.get(name)
        if buf is None or buf.size < size or buf.dtype != dtype:
            grow = 0 if buf is None or buf.dtype != dtype else 2 * buf.size
            buf = np.empty(max(size, grow), dtype=dtype)
            self.buffers[name] = buf
        return buf[:size].reshape(shape)


_WORK = _Workspace()


def _support(A_r: np.ndarray, Z: list[np.ndarray]) -> np.ndarray:
    """Return h(a) = sum_k max_v a . z_v for each row a of A_r (eq. 1, hull coordinates)."""
    stacked = np.vstack(Z)
    starts = np.cumsum([0] + [z.shape[0] for z in Z[:-1]])
    if A_r.shape[0] == 0:
        return np.zeros(0)
    return np.maximum.reduceat(A_r @ stacked.T, starts, axis=1).sum(axis=1)


def _unique_rows(X: np.ndarray, decimals: int) -> np.ndarray:
    """Return the sorted indices of the first of each group of rows equal after rounding.

    Rows are hashed to one integer (a fast 1D unique); a hash collision between different
    rounded rows is detected and then the exact row-wise unique is used.
    """
    if X.shape[0] == 0:
        return np.zeros(0, dtype=int)
    q = np.round(X * 10.0 ** decimals).astype(np.int64)
    weights = np.array([0x9E3779B97F4A7C15 >> (5 * i) for i in range(X.shape[1])],
                       dtype=np.uint64).astype(np.int64)
    with np.errstate(over='ignore'):
        key = q @ weights
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    if not np.array_equal(q, q[first[inverse]]):
        _, first = np.unique(q, axis=0, return_index=True)
    return np.sort(first)


# -- exterior algebra of R^r ------------------------------------------------------------

@lru_cache(maxsize=None)
def _wedge_table(r: int, p: int, q: int) -> np.ndarray:
    """Return T (C(r,p), C(r,q), C(r,p+q)): (x ^ y)_s = sum x_i y_j T_ijs on sorted bases."""
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


def _wedge_all(X: np.ndarray, Y: np.ndarray, r: int, p: int, q: int,
               out: str | None = None) -> np.ndarray:
    """Return every wedge x_i ^ y_j of each batch entry, shape (B, n_x * n_y, C(r, p+q)).

    ``X`` is (B, n_x, C(r, p)), ``Y`` (B, n_y, C(r, q)); row ``i * n_y + j``; the result is
    written to the workspace buffer ``out`` when it is named.
    """
    T = _wedge_table(r, p, q)
    cp, cq, cs = T.shape
    B, nx, ny = X.shape[0], X.shape[1], Y.shape[1]
    # My[b, i_p, j, s] = sum_q Y[b, j, q] T[i_p, q, s], then one product with X.
    My = (Y @ T.transpose(1, 0, 2).reshape(cq, cp * cs)).reshape(B, ny, cp, cs)
    My = My.transpose(0, 2, 1, 3).reshape(B, cp, ny * cs)
    Z = None if out is None else _WORK.get(out, (B, nx, ny * cs), np.float64)
    return np.matmul(X, My, out=Z).reshape(B, nx * ny, cs)


def _wedge_rows(X: np.ndarray, Y: np.ndarray, r: int, p: int, q: int) -> np.ndarray:
    """Return the row-wise wedges x_i ^ y_i, shape (n, C(r, p+q))."""
    T = _wedge_table(r, p, q)
    Mx = (X @ T.reshape(T.shape[0], -1)).reshape(X.shape[0], T.shape[1], T.shape[2])
    return np.einsum('nq,nqs->ns', Y, Mx)
