r"""
Friction-bounded force polytopes: what a stance leg can push without slipping.

For a leg with force polytope :math:`\mathcal F` (see :mod:`awp_ros.wrench.force_polytope`),
contact normal ``n`` (unit, world axes) and friction coefficient ``mu``:

.. math::

    (1)\quad \mathcal F_\mu = \mathcal F \cap \mathcal C_N(n, \mu) \cap
        \{f : n \cdot f \ge 0\}

    (2)\quad \mathcal C_N = \{f : (\cos\theta_i t_1 + \sin\theta_i t_2) \cdot f
        \le \mu \cos(\pi / N)\, n \cdot f,\ \theta_i = 2 \pi i / N\}

the N-sided pyramid inscribed in the friction cone (the seed's Fig. 1 "bounded friction
polytopes"); with N = 4 it is :math:`|f \cdot t_1|, |f \cdot t_2| \le \mu / \sqrt 2\,
f \cdot n`. The pyramid's facet normals come from
:func:`awp_ros.wrench.contact_wrench_cone.friction_pyramid`, the same function the contact wrench
cone uses, so FWS and CWC share one pyramid. The set is computed exactly by enumerating the
vertices of the 3D H-representation (1) (all triples of planes, batched); it may be flat
(the pyramid only touches the force polytope) or empty (the leg cannot push at all).
Forces in [N], world axes; the foot is the force's point of application.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np

from awp_ros.geometry import kernels
from awp_ros.geometry.linalg import cross3
from awp_ros.geometry.polytope import Polytope
from awp_ros.wrench.contact_wrench_cone import friction_pyramid, friction_pyramids
from awp_ros.wrench.force_polytope import polytope_from_halfspaces, triples

__all__ = ['FrictionPolytopes', 'friction_halfspaces', 'friction_polytope', 'friction_polytopes',
           'friction_rows', 'inside_force', 'INSIDE_MARGIN']

#: Default distance [N] inside every pyramid plane of :func:`inside_force`'s proof.
INSIDE_MARGIN = 1e-6


def friction_halfspaces(normal: np.ndarray, mu: float, sides: int) -> np.ndarray:
    """
    Return the rows ``[a, 0]`` of the pyramid (2) and of ``-n . f <= 0``.

    :param normal: (3,) unit contact normal, world axes (pointing into the robot).
    :param mu: friction coefficient [-], > 0.
    :param sides: number N of pyramid sides, >= 3.
    :return: array (N + 1, 3) of unit outward normals ``a`` with ``a . f <= 0``.
    """
    n = np.asarray(normal, dtype=float)
    _, facets = friction_pyramid(n, mu, sides)
    facets = np.asarray(facets, dtype=float)
    # Orient outward whatever the convention: the normal direction is inside the pyramid.
    facets = facets * np.where(facets @ n > 0.0, -1.0, 1.0)[:, None]
    facets /= np.linalg.norm(facets, axis=1)[:, None]
    return np.vstack([facets, -n[None, :]])


def friction_rows(normals: np.ndarray, mus: np.ndarray, sides: int) -> np.ndarray:
    """
    Return :func:`friction_halfspaces` of K contacts at once, shape (K, N + 1, 3).

    :param normals: (K, 3) unit contact normals, world axes.
    :param mus: (K,) friction coefficients [-].
    :param sides: pyramid side count N.
    """
    n = np.asarray(normals, dtype=float).reshape(-1, 3)
    _, facets = friction_pyramids(n, np.asarray(mus, dtype=float), sides)
    facets = facets * np.where(np.einsum('kid,kd->ki', facets, n) > 0.0, -1.0, 1.0)[:, :, None]
    return np.concatenate([facets, -n[:, None, :]], axis=1)


def friction_polytope(force: Polytope, normal: np.ndarray, mu: float, sides: int = 4, *,
                      tol: float = 1e-9) -> Polytope:
    """
    Return the friction-bounded force polytope (1) of one leg.

    :param force: the leg's force polytope in R^3 [N] (full or flat, e.g. a singular leg).
    :param normal: (3,) unit contact normal, world axes.
    :param mu: friction coefficient [-].
    :param sides: pyramid side count N.
    :param tol: relative tolerance of the vertex enumeration.
    :return: the polytope in R^3 [N] (``Polytope.empty(3)`` when the leg cannot push),
        with its vertices and a complete H-rep of unit rows (within its affine hull when
        flat).
    """
    rows = friction_halfspaces(normal, mu, sides)
    return _intersect(force, rows, tol)


def friction_polytopes(forces: Sequence[Polytope], rows: np.ndarray, *, tol: float = 1e-9,
                       det_tol: float = 1e-12) -> list[Polytope]:
    """
    Return the friction-bounded polytopes (1) of K legs, batched over the legs.

    Legs whose force polytopes are full-dimensional with the same number of rows (all
    3-joint legs) are solved together: every triple of planes of every leg by Cramer's rule
    at once (``n . f >= 0`` is implied by the pyramid when mu > 0 and then skipped, as are
    triples of opposite parallelepiped facets); a solution is feasible within
    ``tol * max(1, |b|)``; solutions of one leg with the same tight rows are one vertex.
    A leg whose result is not full-dimensional, and any other leg, goes through
    :func:`friction_polytope`'s general path. Same output as :func:`friction_polytope`.

    :param forces: K force polytopes in R^3 [N].
    :param rows: (K, N + 1, 3) unit outward rows ``a . f <= 0`` of each leg's pyramid and
        unilateral constraint (see :func:`friction_halfspaces`).
    :param tol: relative tolerance of the vertex enumeration.
    :param det_tol: triples of unit rows with ``|det|`` at most this are skipped.
    :return: K polytopes, in the order of ``forces``.
    """
    K = len(forces)
    out: list[Polytope | None] = [None] * K
    groups: dict[int, list[int]] = {}
    for k, F in enumerate(forces):
        if F.dimension == 3 and F.A.shape[0] + rows.shape[1] <= _MAX_BATCH_ROWS:
            groups.setdefault(F.A.shape[0], []).append(k)
    for idx in groups.values():
        batch = _batched([forces[k] for k in idx], rows[idx], tol, det_tol)
        for k, P in zip(idx, batch):
            out[k] = P
    for k in range(K):
        if out[k] is None:
            out[k] = _intersect(forces[k], rows[k], tol)
    return out


def inside_force(forces: Sequence[Polytope], rows: np.ndarray, *, margin: float = INSIDE_MARGIN,
                 stacked: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
                 ) -> np.ndarray:
    r"""
    Return, per leg, whether a force of its force polytope is proven strictly in its pyramid.

    .. math:: \exists f \in \mathcal F_k : a \cdot f < -\epsilon \; \forall a \in
              \mathrm{rows}_k, \quad f \in \mathrm{vert}(\mathcal F_k) \cup
              \{t\, n_k : t > 0\}

    A cheap proof that the friction-bounded polytope (1) is not empty, so that the
    per-cycle emptiness warning does not need (1) itself. Two candidates: a vertex of the
    force polytope, then the pyramid's axis ``t n_k`` (``n_k = -rows_k[-1]``), whose
    interval of ``t`` inside ``A f <= b`` is three ratio tests and where every pyramid
    row is ``t (a . n_k) < -margin`` once ``t`` is large enough: a leg carrying load
    pushes near its normal, where a parallelepiped's vertices can all lie outside the
    pyramid. False does not prove emptiness (the pyramid may cut a face off the axis and
    off the vertices): compute (1). With the compiled kernels, legs that are all
    full-dimensional and of one shape (the parallelepipeds of 3-joint legs) take
    :func:`awp_ros.geometry.kernels.inside_forces`, whose reference is the numpy code here.

    :param forces: K force polytopes in R^3 [N] with their vertices and H-reps.
    :param rows: (K, N + 1, 3) unit outward rows of each leg's pyramid (:func:`friction_rows`).
    :param margin: the distance [N] inside every pyramid plane the force must have.
    :param stacked: the polytopes' rows, offsets and vertices stacked, ``(A (K, m, 3),
        b (K, m), V (K, n_v, 3))``, when the caller has them (full-dimensional legs of one
        shape: the kernels' input, not stacked again; the evaluator's ``force_rows``).
    :return: boolean array (K,).
    """
    K = len(forces)
    if kernels.ENABLED and stacked is not None:
        A, b, V = stacked
        return kernels.inside_forces(V, A, b, rows, margin)
    if kernels.ENABLED and K and all(F.dimension == 3 and F.vertices.shape
                                     == forces[0].vertices.shape and F.A.shape
                                     == forces[0].A.shape for F in forces):
        return kernels.inside_forces(np.array([F.vertices for F in forces]),
                                     np.array([F.A for F in forces]),
                                     np.array([F.b for F in forces]), rows, margin)
    if K and all(F.vertices.shape == forces[0].vertices.shape for F in forces):
        V = np.array([F.vertices for F in forces])                     # (K, n_v, 3)
        s = V @ rows.transpose(0, 2, 1)                                 # (K, n_v, N + 1)
        out = (s < -margin).all(axis=2).any(axis=1)
    else:
        out = np.array([bool(np.any(np.all(F.vertices @ rows[k].T < -margin, axis=1)))
                        for k, F in enumerate(forces)], dtype=bool)
    for k in np.flatnonzero(~out).tolist():
        out[k] = _axis_inside(forces[k], rows[k], margin)
    return out


def _axis_inside(force: Polytope, rows: np.ndarray, margin: float) -> bool:
    """Return whether a point ``t n`` of the pyramid's axis proves :func:`inside_force`."""
    n = -rows[-1]
    rn = rows @ n                                   # < 0 for every row of a proper pyramid
    if force.is_empty or force.dimension < 3 or not np.all(rn < 0.0):
        return False
    lo = float(np.max(margin / -rn))                # every pyramid row below -margin
    an = force.A @ n
    up = an > 0.0
    hi = float(np.min(force.b[up] / an[up])) if up.any() else np.inf
    down = an < 0.0
    if down.any():
        lo = max(lo, float(np.max(force.b[down] / an[down])))
    if np.any(force.b[~(up | down)] < 0.0):
        return False
    return lo < hi


class FrictionPolytopes:
    """
    The friction-bounded polytopes (1) of K legs, computed together on first use.

    ``frictions[k]`` is :func:`friction_polytopes` ``(forces, rows)[k]``; the batch runs once,
    when a leg's polytope is first asked for (the FWS, leg messages, markers), so a control
    cycle that needs none of them does not pay for it.
    """

    def __init__(self, forces: Sequence[Polytope], rows: np.ndarray, **tols: float) -> None:
        self._forces, self._rows, self._tols = list(forces), rows, tols
        self._out: list[Polytope] | None = None

    @property
    def computed(self) -> bool:
        """Return whether the polytopes have been computed."""
        return self._out is not None

    def __len__(self) -> int:
        return len(self._forces)

    def __getitem__(self, k: int) -> Polytope:
        if self._out is None:
            self._out = friction_polytopes(self._forces, self._rows, **self._tols)
        return self._out[k]


def _intersect(force: Polytope, rows: np.ndarray, tol: float) -> Polytope:
    """Return force ∩ {rows . f <= 0} by the general vertex enumeration."""
    if force.is_empty:
        return Polytope.empty(3)
    E, e = force.equalities
    A = np.vstack([force.A, E, -E, rows])
    b = np.concatenate([force.b, e, -e, np.zeros(rows.shape[0])])
    return polytope_from_halfspaces(A, b, tol=tol)


def _batched(forces: list[Polytope], rows: np.ndarray, tol: float,
             det_tol: float) -> list[Polytope | None]:
    """
    Vertex enumeration of K full-dimensional legs with equal row counts at once.

    For the triple (i, j, l) of unit rows, Cramer's rule gives
    ``x = (b_i a_j x a_l + b_j a_l x a_i + b_l a_i x a_j) / (a_i . a_j x a_l)``; the cross
    products of all row pairs are formed once per leg. Two feasible solutions of one leg are
    the same vertex when the same rows are tight at both (a vertex is the intersection of
    its tight planes), which merges the many triples through a degenerate vertex (the
    pyramid's apex) without pairwise distances.
    """
    K = len(forces)
    AF = np.array([F.A for F in forces])
    m0 = AF.shape[1]
    # n . f >= 0 (the last row, -n) follows from the pyramid when mu > 0 (every facet
    # normal then has a . n < 0): skip it.
    implied = np.all(rows[:, :-1] @ rows[:, -1, :, None] > _IMPLIED_TOL)
    cone = rows[:, :-1] if implied else rows
    A = np.concatenate([AF, cone], axis=1)                                  # (K, m, 3)
    m = A.shape[1]
    b = np.zeros((K, m))
    b[:, :m0] = [F.b for F in forces]
    eps = tol * np.maximum(1.0, np.abs(b).max(axis=1))                      # (K,)
    # Parallelepipeds list each facet pair as rows p and p + m0/2 (opposite normals): the
    # triples holding both are singular and are left out.
    half = m0 // 2 if m0 % 2 == 0 and (AF[:, m0 // 2:] == -AF[:, :m0 // 2]).all() else 0
    tri, pairs, powers = _triple_tables(m, half)
    if kernels.ENABLED and m <= kernels.MAX_BITS:     # the loops below, fused (reference)
        V, starts, facet, full = kernels.batched_vertices(A, b, tri.T, eps, det_tol)
        return _legs(V, starts, A, b, facet, full)
    C = cross3(A[:, :, None, :], A[:, None, :, :]).reshape(K, m * m, 3)       # a_p x a_q
    C = C[:, pairs]                             # (K, 3, T, 3): a_j x a_l, a_l x a_i, a_i x a_j
    det = (A[:, tri[0]] * C[:, 0]) @ np.ones(3)
    good = np.abs(det) > det_tol
    bt = b[:, tri, None]                                                    # (K, 3, T, 1)
    X = bt[:, 0] * C[:, 0] + bt[:, 1] * C[:, 1] + bt[:, 2] * C[:, 2]
    X /= np.where(good, det, 1.0)[:, :, None]                               # (K, T, 3)
    slack = b[:, None, :] - X @ A.transpose(0, 2, 1)                        # (K, T, m)
    # Feasible: no row violated (counted by a product: reductions along m are slow).
    violated = (slack < -eps[:, None, None]) @ np.ones(m)
    leg, cand = np.nonzero(good & (violated == 0.0))
    tight = np.abs(slack[leg, cand]) <= eps[leg][:, None]                   # (n, m)
    key = leg * (1 << m) + (tight @ powers).astype(np.int64)
    _, first = np.unique(key, return_index=True)                # sorted by leg, then rows
    V, tight, leg = X[leg[first], cand[first]], tight[first], leg[first]
    starts = np.searchsorted(leg, np.arange(K + 1))
    onehot = (leg[None, :] == np.arange(K)[:, None]).astype(float)          # (K, n_v)
    count = onehot @ tight                                   # (K, m): vertices on each row
    facet = count >= 3.0
    # Full-dimensional: 4 vertices or more and no row holding them all (a flat set lies on
    # its plane's rows); such a leg goes through the general path.
    nv = np.diff(starts)
    full = (nv >= 4) & (count.max(axis=1) < nv)
    return _legs(V, starts, A, b, facet, full)


def _legs(V: np.ndarray, starts: np.ndarray, A: np.ndarray, b: np.ndarray,
          facet: np.ndarray, full: np.ndarray) -> list[Polytope | None]:
    """Return the full-dimensional legs' polytopes (vertices ``V[starts[k]:starts[k+1]]``)."""
    # Facet rows of every leg at once, then sliced (views) per leg.
    Af, bf = A[facet], b[facet]
    ends = np.cumsum(facet @ np.ones(A.shape[1])).tolist()
    bounds = starts.tolist()
    out: list[Polytope | None] = [None] * A.shape[0]
    eye, zero = np.eye(3), np.zeros(3)
    for k, solid in enumerate(full.tolist()):
        if solid:
            r0, r1 = int(ends[k - 1]) if k else 0, int(ends[k])
            out[k] = Polytope(3, V[bounds[k]:bounds[k + 1]], Af[r0:r1], bf[r0:r1], zero, eye)
    return out


_MAX_BATCH_ROWS = 48  # the tight-row pattern of a vertex is packed into one int64 key
_IMPLIED_TOL = 1e-12  # min (-a_i . n) of the pyramid facets for n . f >= 0 to be implied


@lru_cache(maxsize=16)
def _triple_tables(m: int, half: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return the row triples, their pair indices and the row bit weights.

    The row triples ``(3, T)``, the flat indices ``(3, T)`` of the pairs (j, k), (k, i), (i, j)
    into an (m, m) table, and the bit weights 2^p of the rows (as floats).

    With ``half > 0`` the triples holding rows p and p + half (p < half) are left out.
    """
    tri = triples(m)
    if half:
        opposite = np.zeros((m, m), dtype=bool)
        opposite[np.arange(half), np.arange(half) + half] = True
        clash = opposite[tri[:, 0], tri[:, 1]] | opposite[tri[:, 0], tri[:, 2]] \
            | opposite[tri[:, 1], tri[:, 2]]
        tri = tri[~clash]
    i, j, k = tri[:, 0], tri[:, 1], tri[:, 2]
    pairs = np.stack([j * m + k, k * m + i, i * m + j])
    return np.ascontiguousarray(tri.T), pairs, 2.0 ** np.arange(m)
