r"""
Exact H-representation of a Minkowski sum of lifted 3D polytopes: the FWS (and AWP, any leg).

For stance feet at ``p_k`` [m] relative to the CoM (world-aligned axes) and per-leg force
polytopes ``Q_k`` [N] given by their vertices, the set is

.. math::

    S = \sum_k L_k Q_k \subset \mathbb{R}^6, \qquad
    L_k = \begin{bmatrix} I_3 \\ [p_k]_\times \end{bmatrix}, \qquad
    h_S(a) = \sum_k \max_{v \in V_k} (L_k^T a) \cdot v                     \qquad (1)

With ``Q_k`` the friction-bounded polytopes it is the FWS (feasible wrench set); with the
force polytopes of legs with more than 3 joints it is their AWP. Algorithm (all in the
coordinates ``y = U^T (x - o)`` of the affine hull of ``S``, dimension ``r``, where
``M_k = U^T L_k``):

(2)-(3) the facet normals, by face combinations of the legs
    (:func:`awp_ros.geometry.minkowski_facets.facet_normal_steps`): each is a generalised
    cross product of ``r - 1`` lifted face directions whose normal cones agree;
(4) rows are deduplicated after rounding their normals (equal normals have equal offsets),
    then ``b = h_S(a)`` by (1) over all the given points, so each kept row is an exact
    supporting halfspace whatever the tolerances (and whatever the face search found).

An empty leg makes ``S`` empty; no leg gives the point ``{0}``. For HyQ-like legs and 4
legs this takes about 3.5 ms on one core (:mod:`awp_ros.geometry.minkowski_facets`).

Without the H-rep, :func:`awp_ros.wrench.fws_queries.lp_directional_margins` answers membership and
the 12 directional margins exactly by warm-started LPs (about 1 ms for HyQ's 4 legs).
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Sequence

import numpy as np

from awp_ros.errors import InputError
from awp_ros.geometry import kernels
from awp_ros.geometry.face_lattice import Faces, polytope_faces
from awp_ros.geometry.linalg import orthonormal_span
from awp_ros.geometry.minkowski_facets import facet_normal_steps, FLOAT32_SLACK, STEP_CHOICES
from awp_ros.geometry.polytope import Polytope
from awp_ros.geometry.steps import run_steps
from awp_ros.wrench.wrench_polytope import lift_matrices

# lift_matrices and lp_directional_margins are re-exported from their modules.
__all__ = ['feasible_wrench_set', 'feasible_wrench_set_steps', 'lifted_hull',
           'minkowski_sum_of_lifts', 'minkowski_sum_steps']


def feasible_wrench_set(positions: np.ndarray, friction_polytopes: Sequence[Polytope],
                        **tolerances: float) -> Polytope:
    r"""
    Return the FWS, the Minkowski sum of the lifted friction-bounded leg polytopes.

    .. math:: \mathrm{FWS} = \sum_k L_k\, (P_k \cap C_k \cap \{n_k \cdot f \ge 0\})

    :param positions: (K, 3) stance feet relative to the CoM [m], world-aligned axes.
    :param friction_polytopes: K 3D polytopes of contact forces [N] (world-aligned axes) with
        their vertices (and complete H-reps, used for their facets); an empty one makes the
        FWS empty.
    :param tolerances: keyword tolerances passed to :func:`minkowski_sum_of_lifts`.
    :return: the FWS as a :class:`Polytope` in R^6 ([N, N.m]), complete H-rep.
    :raises InputError: on mismatched lengths or bad shapes, or a non-empty polytope without
        vertices.
    """
    vertex_sets, halfspaces = _leg_inputs(friction_polytopes)
    return minkowski_sum_of_lifts(positions, vertex_sets, halfspaces=halfspaces, **tolerances)


def feasible_wrench_set_steps(positions: np.ndarray, friction_polytopes: Sequence[Polytope],
                              *, step_choices: int | None = STEP_CHOICES,
                              **tolerances: float) -> Generator[None, None, Polytope]:
    """Compute :func:`feasible_wrench_set` in steps (:func:`minkowski_sum_steps`)."""
    vertex_sets, halfspaces = _leg_inputs(friction_polytopes)
    return (yield from minkowski_sum_steps(positions, vertex_sets, halfspaces=halfspaces,
                                           step_choices=step_choices, **tolerances))


def _leg_inputs(friction_polytopes: Sequence[Polytope]) -> tuple[list, list]:
    """Return the legs' vertex sets and H-reps (or None) for the sum, or raise InputError."""
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
    return vertex_sets, halfspaces


def minkowski_sum_of_lifts(positions: np.ndarray, vertex_sets: Sequence[np.ndarray], *,
                           halfspaces: Sequence[tuple | None] | None = None,
                           rank_tol: float = 1e-7, plane_tol: float = 1e-9,
                           cone_tol: float = 1e-5, normal_tol: float = 1e-8,
                           dedupe_decimals: int = 10) -> Polytope:
    r"""
    Return the exact H-rep of ``sum_k L_k conv(V_k)`` in R^6 (module docstring, (1)-(4)).

    .. math:: S = \sum_k L_k\, \mathrm{conv}(V_k), \quad
              S = \{x : A x \le b,\; x = o + U y\}

    :param positions: (K, 3) points of application relative to the CoM [m] (world axes).
    :param vertex_sets: K arrays (n_k, 3) of points [N] (duplicates and non-extreme points
        allowed; ``n_k = 0`` is an empty leg).
    :param halfspaces: optional K entries ``(A_k, b_k)`` or None: rows with ``A_k f <= b_k`` on
        ``Q_k`` that include all its facet planes (its H-rep); they spare the search for facets
        among point triples (:func:`~awp_ros.geometry.face_lattice.polytope_faces`).
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
    :param dedupe_decimals: rows whose unit normals ``a`` are equal after rounding to this many
        decimals are merged (their offsets ``h_S(a)`` are then equal to about that much).
    :return: a :class:`Polytope` with unit rows ``A`` in the hull's direction space, ``b``,
        ``hull_origin``, ``hull_basis``, ``dimension = r``; ``vertices`` are given for one
        leg (the lifted vertices) and for none ({0}), else (0, 6). ``meta`` holds
        ``candidates`` (face choices examined) and ``kept`` (rows before deduplication).
    :raises InputError: on bad shapes, non-finite values or mismatched lengths, or
        ``cone_tol`` below float32 rounding.
    """
    return run_steps(minkowski_sum_steps(
        positions, vertex_sets, halfspaces=halfspaces, rank_tol=rank_tol, plane_tol=plane_tol,
        cone_tol=cone_tol, normal_tol=normal_tol, dedupe_decimals=dedupe_decimals,
        step_choices=None))


def minkowski_sum_steps(positions: np.ndarray, vertex_sets: Sequence[np.ndarray], *,
                        halfspaces: Sequence[tuple | None] | None = None,
                        rank_tol: float = 1e-7, plane_tol: float = 1e-9,
                        cone_tol: float = 1e-5, normal_tol: float = 1e-8,
                        dedupe_decimals: int = 10, step_choices: int | None = STEP_CHOICES
                        ) -> Generator[None, None, Polytope]:
    """
    Compute :func:`minkowski_sum_of_lifts` in steps (:mod:`awp_ros.geometry.steps`).

    It yields after the legs' faces and within the facet search, ``step_choices`` face
    choices at a time (:func:`~awp_ros.geometry.minkowski_facets.facet_normal_steps`; None:
    each pattern in one piece). The result is the same whatever the steps.
    """
    if not cone_tol >= FLOAT32_SLACK:
        msg = f'cone_tol={cone_tol!r} must be >= {FLOAT32_SLACK} (float32 filter rounding)'
        raise InputError(msg)
    P = np.asarray(positions, dtype=float)
    if P.ndim != 2 or P.shape[1] != 3 or not np.isfinite(P).all():
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
    yield
    L, origin, U, M = lifted_hull(P, faces, rank_tol=rank_tol)
    r = U.shape[1]
    if r == 0:
        return Polytope(0, origin[None, :], np.zeros((0, 6)), np.zeros(0), origin,
                        np.zeros((6, 0)), {'candidates': 0, 'kept': 0})
    A_r, count = yield from facet_normal_steps(faces, M, r, cone_tol, normal_tol, feet=P,
                                               basis=U, step_choices=step_choices)
    yield
    # Support (4) over every input point, not only the extreme ones the face search kept;
    # a leg found flat within rank_tol is projected on its plane like its faces (consistent
    # flattening: mixing the two made an ill-conditioned H-rep overshoot S).
    Z = [(np.asarray(V, dtype=float) - F.origin) @ (F.basis @ F.basis.T) @ Mk.T
         for V, F, Mk in zip(vertex_sets, faces, M)]
    kept = A_r.shape[0]
    A_r = A_r[_unique_rows(A_r, dedupe_decimals)]      # equal normals: equal offsets (4)
    b_r = _support(A_r, Z)
    A = A_r @ U.T
    b = b_r + A @ origin
    if len(faces) == 1:
        vertices = faces[0].vertices @ L[0].T
    else:
        vertices = np.zeros((0, 6))
    meta = {'candidates': count, 'kept': kept}
    return Polytope(r, vertices, A, b, origin, U, meta)


def lifted_hull(positions: np.ndarray, faces: Sequence[Faces], *, rank_tol: float = 1e-7
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """
    Return ``(L, o, U, M)``: the lifts, the sum's affine hull and each leg's map into it.

    ``L`` (K, 6, 3) the lift matrices of the feet ``positions`` [m], ``o = sum_k L_k o_k``
    (the legs' face origins), ``U`` (6, r) an orthonormal basis of the span of the lifted
    legs' directions (``rank_tol`` as :func:`minkowski_sum_of_lifts`), ``M_k = U^T L_k``
    (K, r, 3).
    """
    L = lift_matrices(positions)
    origin = np.zeros(6)
    for Lk, F in zip(L, faces):
        origin += Lk @ F.origin
    spans = [Lk @ F.basis for Lk, F in zip(L, faces)]
    U = orthonormal_span(np.hstack(spans + [np.zeros((6, 0))]).T, rtol=rank_tol)
    return L, origin, U, np.einsum('nr,knd->krd', U, L)


def _support(A_r: np.ndarray, Z: list[np.ndarray]) -> np.ndarray:
    """Return h(a) = sum_k max_v a . z_v for each row a of A_r (eq. 1, hull coordinates)."""
    h = np.zeros(A_r.shape[0])
    if A_r.shape[0] == 0:
        return h
    values = np.vstack(Z) @ A_r.T                 # (points, rows): each leg's block contiguous
    start = 0
    for z in Z:
        if z.shape[0]:
            h += values[start:start + z.shape[0]].max(axis=0)
        start += z.shape[0]
    return h


def _unique_rows(X: np.ndarray, decimals: int) -> np.ndarray:
    """
    Return the sorted indices of the first of each group of rows equal after rounding.

    Rows are hashed to one integer (a fast 1D sort); a hash collision between different
    rounded rows is detected and then the exact row-wise unique is used.
    """
    if X.shape[0] == 0:
        return np.zeros(0, dtype=int)
    if kernels.ENABLED:        # one hash-table pass, compiled (the code below is its reference)
        return kernels.first_of_equal_rows(X, decimals)
    q = np.rint(X * 10.0 ** decimals).astype(np.int64)
    weights = np.array([0x9E3779B97F4A7C15 >> (5 * i) for i in range(X.shape[1])],
                       dtype=np.uint64).astype(np.int64)
    with np.errstate(over='ignore'):
        key = q @ weights
    order = np.argsort(key)
    new = np.empty(key.size, dtype=bool)
    new[0] = True
    np.not_equal(key[order[1:]], key[order[:-1]], out=new[1:])
    first = np.minimum.reduceat(order, np.flatnonzero(new))     # first index of each group
    if not np.array_equal(q[order], q[first[np.cumsum(new) - 1]]):
        _, first = np.unique(q, axis=0, return_index=True)
    return np.sort(first)
