"""
Tests of awp_ros.wrench.feasible_wrench_set against qhull, LPs on the definition, and hand cases.

The sums are checked by methods that do not share its algorithm: brute-force vertex sums
(every row supporting: max over the sums equals b, so S is inside the H-rep's polytope P),
qhull's halfspace intersection of the H-rep (every vertex of P is a vertex sum, so P is inside
S: a missing facet would leave a vertex of P outside), LP supports of P along qhull's facet
normals of the vertex sums and along random directions (equal to the true support), and
scipy.optimize.linprog membership on the definition (f_k in Q_k, sum L_k f_k = w).
"""

from __future__ import annotations


import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, HalfspaceIntersection

from awp_ros.errors import InputError
from awp_ros.geometry.margin import directional_margins, polytope_margin
from awp_ros.geometry.polytope import Polytope
from awp_ros.wrench.feasible_wrench_set import (feasible_wrench_set, minkowski_sum_of_lifts,
                                                minkowski_sum_steps)
from awp_ros.wrench.wrench_polytope import lift_matrices
from cases import hyq_feet, hyq_like_leg, vertex_sums

# -- independent references ------------------------------------------------------------------


def hrep_support(S: Polytope, a: np.ndarray) -> float:
    """Return max a.x over the H-rep's polytope (LP, within the affine hull)."""
    U, o = S.hull_basis, S.hull_origin
    res = linprog(-(U.T @ a), A_ub=S.A @ U, b_ub=S.b - S.A @ o, bounds=(None, None),
                  method='highs')
    assert res.status == 0
    return -res.fun + a @ o


def lp_member(positions, vertex_sets, w) -> bool:
    """Return whether w = sum_k L_k V_k^T lam_k, lam_k in simplices (linprog on the definition)."""
    L = lift_matrices(positions)
    cols = [Lk @ V.T for Lk, V in zip(L, vertex_sets)]
    n = sum(c.shape[1] for c in cols)
    Aeq = [np.hstack(cols)]
    beq = [w]
    start = 0
    for c in cols:
        row = np.zeros(n)
        row[start:start + c.shape[1]] = 1.0
        Aeq.append(row[None, :])
        beq.append([1.0])
        start += c.shape[1]
    res = linprog(np.zeros(n), A_eq=np.vstack(Aeq), b_eq=np.concatenate(beq),
                  bounds=(0, None), method='highs')
    return res.status == 0


def hull_coords(S: Polytope, X: np.ndarray) -> np.ndarray:
    return (X - S.hull_origin) @ S.hull_basis


def hrep_vertices(S: Polytope) -> np.ndarray:
    """
    Vertices of the H-rep's polytope (ambient coordinates), by qhull's halfspace intersection.

    qhull repeats a vertex once per simplicial piece of a non-simple vertex; the repeats are
    kept (each is checked). 'Q12' lets qhull merge the nearly coplanar facets these sums have
    (without it qhull stops with a wide-merge error, the issue's anchor), 'Qx' as default in 6D.
    """
    U, o = S.hull_basis, S.hull_origin
    A_r, b_r = S.A @ U, S.b - S.A @ o
    r = U.shape[1]
    c = np.zeros(r + 1)
    c[-1] = -1.0                                  # Chebyshev centre by LP: an interior point
    res = linprog(c, A_ub=np.hstack([A_r, np.ones((len(A_r), 1))]), b_ub=b_r,
                  bounds=[(None, None)] * r + [(0, None)], method='highs')
    opts = 'Qx Q12' if r >= 5 else 'Q12'
    hs = HalfspaceIntersection(np.hstack([A_r, -b_r[:, None]]), res.x[:r], qhull_options=opts)
    return hs.intersections @ U.T + o


def check_hrep_vertices_are_sums(S: Polytope, positions, vertex_sets, rtol=1e-7):
    """
    Every vertex of the H-rep's polytope is a vertex sum, so that polytope is inside S.

    With :func:`check_rows_support` (S inside it) the two are equal: no facet is missing.
    With 'Q12' qhull may also emit points off the polytope (violating its rows; artefacts of
    the wide merges): those are set aside, at most a quarter of the output.
    """
    pts = vertex_sums(positions, vertex_sets)
    scale = np.abs(pts).max()
    X = hrep_vertices(S)
    inside = np.max(X @ S.A.T - S.b, axis=1) <= rtol * scale
    assert inside.sum() >= 0.75 * len(X)
    X = X[inside]
    d = np.min(np.linalg.norm(X[:, None, :] - pts[None, :, :], axis=2), axis=1)
    assert np.max(d) <= rtol * scale
    return X


def check_supports_along_hull_normals(S: Polytope, positions, vertex_sets, rtol=1e-9):
    """
    Along every facet normal of qhull's hull of the vertex sums, P's support is S's.

    Complete: were a facet of S missing, a point of P would lie beyond it, and P's support
    along its normal would exceed S's. P's support is an LP on the H-rep, S's the max over
    the sums (the other half, S inside P, is :func:`check_rows_support`).
    """
    pts = vertex_sums(positions, vertex_sets)
    hull = ConvexHull(hull_coords(S, pts), qhull_options='Qt Qx')
    normals = np.unique(np.round(hull.equations[:, :-1], 9), axis=0) @ S.hull_basis.T
    scale = np.abs(pts).max()
    for a in normals / np.linalg.norm(normals, axis=1)[:, None]:
        assert hrep_support(S, a) == pytest.approx(np.max(pts @ a), abs=rtol * scale)
    return len(normals)


def check_rows_support(S: Polytope, positions, vertex_sets, rtol=1e-9):
    pts = vertex_sums(positions, vertex_sets)
    np.testing.assert_allclose(np.linalg.norm(S.A, axis=1), 1.0, atol=1e-12)
    # Rows lie in the hull's direction space and the sums lie in the hull.
    np.testing.assert_allclose(S.A - (S.A @ S.hull_basis) @ S.hull_basis.T, 0.0, atol=1e-12)
    scale = np.abs(pts).max()
    assert np.max(np.linalg.norm(hull_coords(S, pts) @ S.hull_basis.T + S.hull_origin - pts,
                                 axis=1)) <= rtol * scale
    h = np.max(pts @ S.A.T, axis=0)
    np.testing.assert_allclose(S.b, h, rtol=0, atol=rtol * scale)


# -- hand cases -------------------------------------------------------------------------------

def box(lo, hi) -> np.ndarray:
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                     for z in (lo[2], hi[2])], dtype=float)


def test_no_leg_is_the_origin():
    S = minkowski_sum_of_lifts(np.zeros((0, 3)), [])
    assert S.dimension == 0 and S.A.shape == (0, 6)
    np.testing.assert_array_equal(S.vertices, np.zeros((1, 6)))
    assert polytope_margin(S, np.zeros(6)).feasible


def test_one_box_at_the_com_is_the_box_times_zero_moment():
    V = box((-100.0, -200.0, 0.0), (100.0, 200.0, 800.0))
    S = minkowski_sum_of_lifts(np.zeros((1, 3)), [V])
    assert S.dimension == 3 and S.A.shape == (6, 6)
    rows = {tuple(np.round(np.append(a, bb), 9)) for a, bb in zip(S.A, S.b)}
    expected = {(1, 0, 0, 0, 0, 0, 100), (-1, 0, 0, 0, 0, 0, 100), (0, 1, 0, 0, 0, 0, 200),
                (0, -1, 0, 0, 0, 0, 200), (0, 0, 1, 0, 0, 0, 800), (0, 0, -1, 0, 0, 0, 0)}
    assert rows == {tuple(float(x) for x in e) for e in expected}
    m = polytope_margin(S, np.array([0.0, 0.0, 300.0, 0.0, 0.0, 0.0]))
    assert m.margin == pytest.approx(100.0) and m.affine_residual == pytest.approx(0.0)
    m = polytope_margin(S, np.array([0.0, 0.0, 300.0, 5.0, 0.0, 0.0]))
    assert m.affine_residual == pytest.approx(5.0) and not m.feasible


def test_two_boxes_hull_normal_is_the_moment_about_the_foot_line():
    """c_1 = c_2 = 0 iff a = (-d x p_1, d) with d = p_1 - p_2: the one equality of the 5D sum."""
    p = np.array([[0.3, 0.2, -0.5], [-0.3, -0.2, -0.5]])
    V = box((-100.0, -100.0, 0.0), (100.0, 100.0, 600.0))
    S = minkowski_sum_of_lifts(p, [V, V])
    assert S.dimension == 5
    d = p[0] - p[1]
    e = np.concatenate([-np.cross(d, p[0]), d])
    E, _ = S.equalities
    assert abs(abs(E[0] @ e) / np.linalg.norm(e) - 1.0) < 1e-12
    # Support along a pure force axis: both legs at their max, 2 x 600 N.
    assert hrep_support(S, np.array([0.0, 0, 1, 0, 0, 0])) == pytest.approx(1200.0)
    check_rows_support(S, p, [V, V])
    check_hrep_vertices_are_sums(S, p, [V, V])


@pytest.mark.parametrize('K,seed', [(3, 20), (4, 21), (4, 22)])
def test_every_pair_of_feet_gives_two_facets_whose_faces_add_up_to_six(K, seed):
    """
    Along a = (p_i x d, d) / |.|, d = p_j - p_i, c_i = c_j = 0: legs i, j lie whole in the face.

    For any feet (here random, not level, not aligned) the face of S with normal +-a is
    ``L_i Q_i + L_j Q_j`` plus one vertex of each other leg: 5-dimensional (the two lifted
    spaces share the direction ``(d, p_i x d)``), a facet whose legs' face dimensions add up to
    6, not 5. Checked without the engine's algorithm: the vertex sums on the plane
    ``a . x = max a . x`` span a 5-dimensional affine set, and the H-rep has the row.
    """
    rng = np.random.default_rng(seed)
    vertex_sets = [rng.normal(size=(rng.integers(4, 7), 3)) * [300, 300, 900] + [0, 0, 800]
                   for _ in range(K)]
    p = hyq_feet(rng, K) + rng.uniform(-0.1, 0.1, size=(K, 3))
    S = minkowski_sum_of_lifts(p, vertex_sets)
    assert S.dimension == 6
    pts = vertex_sums(p, vertex_sets)
    scale = np.abs(pts).max()
    found = 0
    for i in range(K):
        for j in range(i + 1, K):
            d = p[j] - p[i]
            for sign in (1.0, -1.0):
                a = sign * np.concatenate([np.cross(p[i], d), d])
                a /= np.linalg.norm(a)
                L = lift_matrices(p)
                assert np.abs(L[i].T @ a).max() < 1e-12 and np.abs(L[j].T @ a).max() < 1e-12
                h = np.max(pts @ a)
                face = pts[pts @ a >= h - 1e-9 * scale]
                assert np.linalg.matrix_rank(face[1:] - face[0], tol=1e-6 * scale) == 5
                # The H-rep holds that row, with the support as offset.
                k = int(np.argmax(S.A @ a))
                assert S.A[k] @ a == pytest.approx(1.0, abs=1e-9)
                assert S.b[k] == pytest.approx(h, abs=1e-9 * scale)
                found += 1
    assert found == K * (K - 1)


# -- brute force: qhull on all vertex sums (and on the H-rep's vertices) -----------------------

@pytest.mark.parametrize('K,seed', [(1, 0), (1, 1), (2, 2), (2, 3), (3, 4), (3, 5), (4, 6),
                                    (4, 7)])
def test_random_small_sums_match_qhull(K, seed):
    rng = np.random.default_rng(seed)
    vertex_sets = [rng.normal(size=(rng.integers(4, 8), 3)) * [300, 300, 900] + [0, 0, 800]
                   for _ in range(K)]
    p = hyq_feet(rng, K)
    S = minkowski_sum_of_lifts(p, vertex_sets)
    assert S.dimension == {1: 3, 2: 5, 3: 6, 4: 6}[K]
    check_rows_support(S, p, vertex_sets)
    pts = vertex_sums(p, vertex_sets)
    check_hrep_vertices_are_sums(S, p, vertex_sets)
    hull = ConvexHull(hull_coords(S, pts))
    for eq in hull.equations[:: max(1, len(hull.equations) // 40)]:
        a = S.hull_basis @ eq[:-1]
        assert hrep_support(S, a) == pytest.approx(np.max(pts @ a), rel=1e-9, abs=1e-6)


@pytest.mark.parametrize('K,seed', [(1, 10), (2, 11), (3, 12)])
def test_hyq_like_sums_rows_support_and_vertices_are_sums(K, seed):
    rng = np.random.default_rng(seed)
    vertex_sets = [hyq_like_leg(rng) for _ in range(K)]
    p = hyq_feet(rng, K)
    S = minkowski_sum_of_lifts(p, vertex_sets)
    check_rows_support(S, p, vertex_sets)
    check_hrep_vertices_are_sums(S, p, vertex_sets)


def test_five_small_legs_rows_support_and_vertices_are_sums():
    """More legs than a quadruped (a hexapod minus one): patterns with five parts."""
    rng = np.random.default_rng(13)
    vertex_sets = [rng.normal(size=(4, 3)) * [300, 300, 900] + [0, 0, 800] for _ in range(5)]
    p = hyq_feet(rng, 5)
    S = minkowski_sum_of_lifts(p, vertex_sets)
    assert S.dimension == 6
    check_rows_support(S, p, vertex_sets)
    # qhull's halfspace intersection of this H-rep is chaotic (a precision error, a twisted
    # facet, on rows an ulp away from an earlier run's): the complete check along every facet
    # normal of the sums' hull instead.
    assert check_supports_along_hull_normals(S, p, vertex_sets) >= S.A.shape[0] // 2
    # The check can fail: without the row of S's largest facet offset it does.
    i = int(np.argmax(S.b))
    keep = np.arange(S.A.shape[0]) != i
    cut = Polytope(S.dimension, S.vertices, S.A[keep], S.b[keep], S.hull_origin, S.hull_basis)
    with pytest.raises(AssertionError):
        check_supports_along_hull_normals(cut, p, vertex_sets)


# -- four legs: LP supports and LP membership ------------------------------------------------

@pytest.fixture(scope='module')
def four_legs():
    rng = np.random.default_rng(42)
    vertex_sets = [hyq_like_leg(rng) for _ in range(4)]
    p = hyq_feet(rng, 4)
    return p, vertex_sets, minkowski_sum_of_lifts(p, vertex_sets)


def test_four_legs_rows_support_and_random_supports_agree(four_legs):
    p, vertex_sets, S = four_legs
    assert S.dimension == 6
    check_rows_support(S, p, vertex_sets)
    check_hrep_vertices_are_sums(S, p, vertex_sets)
    L = lift_matrices(p)
    rng = np.random.default_rng(0)
    for _ in range(60):
        a = rng.normal(size=6)
        a /= np.linalg.norm(a)
        h = sum(np.max(V @ (Lk.T @ a)) for Lk, V in zip(L, vertex_sets))
        assert hrep_support(S, a) == pytest.approx(h, rel=1e-9, abs=1e-6)


def test_the_sum_in_steps_interleaved_with_another_is_the_sum_in_one_piece(four_legs):
    """Steps (the node's FWS between joint states) change nothing, even when two alternate."""
    p, vertex_sets, S = four_legs
    rng = np.random.default_rng(7)
    q = hyq_feet(rng, 4)
    other_sets = [hyq_like_leg(rng) for _ in range(4)]
    T = minkowski_sum_of_lifts(q, other_sets)
    first = minkowski_sum_steps(p, vertex_sets)
    second = minkowski_sum_steps(q, other_sets)
    answers, steps = {}, 0
    while len(answers) < 2:                  # alternate: each step of one, then of the other
        for name, g in (('first', first), ('second', second)):
            if name in answers:
                continue
            try:
                next(g)
                steps += 1
            except StopIteration as stop:
                answers[name] = stop.value
    assert steps >= 10                       # four legs: the facet search in several pieces
    for got, want in ((answers['first'], S), (answers['second'], T)):
        assert np.array_equal(got.A, want.A) and np.array_equal(got.b, want.b)
    check_rows_support(answers['second'], q, other_sets)
    check_hrep_vertices_are_sums(answers['second'], q, other_sets)


def test_checkers_detect_a_missing_facet(four_legs):
    """The oracles can fail: without one facet the H-rep's polytope has a vertex outside S."""
    p, vertex_sets, S = four_legs
    pts = vertex_sums(p, vertex_sets)
    w = np.array([0.0, 0.0, 85.0 * 9.81, 0.0, 0.0, 0.0])
    i = int(np.argmin(S.b - S.A @ w))               # the facet nearest to a standing wrench
    keep = np.arange(len(S.b)) != i
    T = Polytope(6, S.vertices, S.A[keep], S.b[keep], S.hull_origin, S.hull_basis)
    with pytest.raises(AssertionError):
        check_hrep_vertices_are_sums(T, p, vertex_sets)
    assert hrep_support(T, S.A[i]) > np.max(pts @ S.A[i]) + 1e-6


def test_four_legs_directional_margins_match_linprog(four_legs):
    """Max t with w + t e_i in S, by linprog on the definition, equals the H-rep ratio test."""
    p, vertex_sets, S = four_legs
    L = lift_matrices(p)
    cols = np.hstack([Lk @ V.T for Lk, V in zip(L, vertex_sets)])
    n = cols.shape[1]
    E = np.zeros((4, n))
    start = 0
    for k, V in enumerate(vertex_sets):
        E[k, start:start + len(V)] = 1.0
        start += len(V)
    w = np.array([10.0, -20.0, 85.0 * 9.81, 5.0, -3.0, 1.0])
    t_plus, t_minus = directional_margins(S, w)
    for i in range(6):
        for sign, t in ((1.0, t_plus[i]), (-1.0, t_minus[i])):
            e = sign * np.eye(6)[i]
            c = np.zeros(n + 1)
            c[-1] = -1.0
            A_eq = np.vstack([np.hstack([cols, -e[:, None]]), np.hstack([E, np.zeros((4, 1))])])
            res = linprog(c, A_eq=A_eq, b_eq=np.concatenate([w, np.ones(4)]),
                          bounds=[(0, None)] * n + [(None, None)], method='highs')
            assert res.status == 0
            assert t == pytest.approx(-res.fun, rel=1e-7, abs=1e-6)


def test_tiny_leg_facet_regression():
    """
    Seed 65, a leg with a 0.01 N facet: every row supports the sums, supports near rows agree.

    The face search once lost that facet, and then gave rows cutting S by 600 N.
    """
    rng = np.random.default_rng(65)
    vertex_sets = [hyq_like_leg(rng) for _ in range(4)]
    p = hyq_feet(rng, 4)
    S = minkowski_sum_of_lifts(p, vertex_sets)
    check_rows_support(S, p, vertex_sets)
    L = lift_matrices(p)
    rng = np.random.default_rng(0)
    for i in rng.choice(len(S.b), 20, replace=False):
        a = S.A[i] + 0.05 * rng.normal(size=6)
        a /= np.linalg.norm(a)
        h = sum(np.max(V @ (Lk.T @ a)) for Lk, V in zip(L, vertex_sets))
        assert hrep_support(S, a) == pytest.approx(h, rel=1e-9, abs=1e-6)


def test_four_legs_membership_agrees_with_linprog(four_legs):
    p, vertex_sets, S = four_legs
    rng = np.random.default_rng(1)
    pts = vertex_sums(p, vertex_sets)
    centre = pts.mean(axis=0)
    tested = {True: 0, False: 0}
    for _ in range(60):
        lam = rng.dirichlet(np.ones(4))
        w = centre + rng.uniform(0.5, 2.0) * (lam @ pts[rng.choice(len(pts), 4)] - centre)
        m = polytope_margin(S, w)
        if abs(m.margin) < 1e-6 * np.abs(pts).max():
            continue
        assert lp_member(p, vertex_sets, w) == (m.margin > 0)
        tested[bool(m.margin > 0)] += 1
    assert tested[True] > 5 and tested[False] > 5


def test_four_legs_margin_ball_inside_and_witness_support(four_legs):
    p, vertex_sets, S = four_legs
    L = lift_matrices(p)
    w = np.array([0.0, 0.0, 85.0 * 9.81, 0.0, 0.0, 0.0])
    m = polytope_margin(S, w)
    assert m.feasible and m.margin > 0
    h = sum(np.max(V @ (Lk.T @ m.normal)) for Lk, V in zip(L, vertex_sets))
    assert h - m.normal @ w == pytest.approx(m.margin, rel=1e-9)
    rng = np.random.default_rng(2)
    for _ in range(10):
        u = rng.normal(size=6)
        u /= np.linalg.norm(u)
        assert lp_member(p, vertex_sets, w + 0.999 * m.margin * u)
    t_plus, t_minus = directional_margins(S, w)
    for i in range(6):
        e = np.eye(6)[i]
        assert lp_member(p, vertex_sets, w + 0.999 * t_plus[i] * e)
        assert not lp_member(p, vertex_sets, w + 1.001 * t_plus[i] * e + 1e-6 * e)
        assert lp_member(p, vertex_sets, w - 0.999 * t_minus[i] * e)


# -- degenerate inputs ------------------------------------------------------------------------

def test_empty_leg_makes_the_sum_empty():
    rng = np.random.default_rng(3)
    S = minkowski_sum_of_lifts(hyq_feet(rng, 2), [hyq_like_leg(rng), np.zeros((0, 3))])
    assert S.is_empty and S.dimension == -1


def test_segment_point_and_flat_legs_in_hull_coordinates():
    rng = np.random.default_rng(4)
    seg = np.array([[0.0, 0.0, 100.0], [150.0, -50.0, 700.0]])
    pt = np.array([[20.0, 30.0, 400.0]])
    tri = np.array([[0.0, 0.0, 0.0], [300.0, 0.0, 500.0], [-200.0, 250.0, 500.0]])
    p = hyq_feet(rng, 4)
    cases = {(0,): ([seg], 1), (1,): ([pt], 0), (2,): ([tri], 2),
             (0, 1): ([seg, pt], 1), (0, 2): ([seg, seg + 10.0], 2),
             (0, 1, 2): ([seg, pt, tri], 3),
             (0, 1, 2, 3): ([seg, seg, seg, seg], 3),   # (u, p_k x u) span 3 dimensions
             (1, 2, 3): ([tri, tri, tri], 5)}           # 2 force + 3 moment dimensions
    for legs, (vertex_sets, dim) in cases.items():
        S = minkowski_sum_of_lifts(p[list(legs)], vertex_sets)
        assert S.dimension == dim, legs
        check_rows_support(S, p[list(legs)], vertex_sets)
        if dim >= 2:
            check_hrep_vertices_are_sums(S, p[list(legs)], vertex_sets)
        if dim == 1:
            y = hull_coords(S, vertex_sums(p[list(legs)], vertex_sets))[:, 0]
            assert sorted(S.b - S.A @ S.hull_origin) == pytest.approx(
                sorted([y.max(), -y.min()]), abs=1e-9)


@pytest.mark.parametrize('seed', [0, 44, 139])
def test_nearly_flat_thin_and_clustered_legs(seed):
    """
    Nearly flat, thin and clustered legs: the H-rep's supports stay close to the true ones.

    Legs flat to 1e-12..1e-4, nearly segments, or with 1e-3 N clusters: the supports of the
    H-rep's polytope along random and near-facet directions stay within 1e-6 (relative) of the
    true ones (seeds that once overshot by 1e-2 or gave an unbounded H-rep).
    """
    rng = np.random.default_rng(seed)
    K = int(rng.integers(2, 4))
    vertex_sets = []
    for _ in range(K):
        kind, n = rng.integers(0, 4), int(rng.integers(3, 9))
        X = rng.normal(size=(n, 3)) * [300, 300, 900] + [0, 0, 800]
        if kind == 1:
            X[:, 2] = 800 + rng.normal(size=n) * 10.0 ** rng.uniform(-12, -4)
        if kind == 2:
            X = X[:2] + rng.normal(size=(2, 3)) * 1e-9
        if kind == 3:
            X = np.vstack([X, X[0] + rng.normal(size=(3, 3)) * 1e-3])
        vertex_sets.append(X)
    p = hyq_feet(rng, K)
    S = minkowski_sum_of_lifts(p, vertex_sets)
    pts = vertex_sums(p, vertex_sets)
    scale = np.abs(pts).max()
    np.testing.assert_allclose(S.b, np.max(pts @ S.A.T, axis=0), atol=1e-6 * scale)
    rng = np.random.default_rng(seed)
    for _ in range(40):
        a = S.hull_basis @ rng.normal(size=S.dimension)
        if rng.random() < 0.5:
            a = S.A[rng.integers(len(S.b))] + 0.05 * a / np.linalg.norm(a)
            a = S.hull_basis @ (S.hull_basis.T @ a)
        a /= np.linalg.norm(a)
        assert hrep_support(S, a) == pytest.approx(np.max(pts @ a), abs=1e-6 * scale)


@pytest.mark.parametrize('feet,dim', [
    ([[0.3, 0.3, -0.5], [0.3, -0.3, -0.5], [-0.3, 0.3, -0.5]], 6),     # coplanar (always)
    ([[0.3, 0.0, -0.5], [0.0, 0.0, -0.5], [-0.3, 0.0, -0.5]], 5),      # collinear feet
    ([[0.3, 0.1, -0.5], [0.3, 0.1, -0.5]], 3),                          # the same foot twice
])
def test_degenerate_feet(feet, dim):
    rng = np.random.default_rng(5)
    p = np.array(feet)
    vertex_sets = [hyq_like_leg(rng) for _ in range(len(p))]
    S = minkowski_sum_of_lifts(p, vertex_sets)
    assert S.dimension == dim
    check_rows_support(S, p, vertex_sets)
    check_hrep_vertices_are_sums(S, p, vertex_sets)


def test_feasible_wrench_set_takes_polytopes_and_empty_ones():
    rng = np.random.default_rng(6)
    V = [hyq_like_leg(rng) for _ in range(2)]
    p = hyq_feet(rng, 2)
    polys = [Polytope(3, v, np.zeros((0, 3)), np.zeros(0), v.mean(0), np.eye(3)) for v in V]
    S = feasible_wrench_set(p, polys)
    T = minkowski_sum_of_lifts(p, V)
    np.testing.assert_array_equal(S.A, T.A)
    assert feasible_wrench_set(p, [polys[0], Polytope.empty(3)]).is_empty


def test_bad_input_raises():
    with pytest.raises(InputError, match='positions'):
        minkowski_sum_of_lifts(np.zeros((2, 2)), [np.zeros((1, 3))] * 2)
    with pytest.raises(InputError, match='2 vertex sets for 3 positions'):
        minkowski_sum_of_lifts(np.zeros((3, 3)), [np.zeros((1, 3))] * 2)
    with pytest.raises(InputError, match='finite'):
        minkowski_sum_of_lifts(np.zeros((1, 3)), [np.array([[np.nan, 0.0, 0.0]])])
    with pytest.raises(InputError, match='cone_tol'):
        minkowski_sum_of_lifts(np.zeros((1, 3)), [np.eye(3)], cone_tol=1e-9)
    no_vertices = Polytope(3, np.zeros((0, 3)), np.eye(3), np.ones(3), np.zeros(3), np.eye(3))
    with pytest.raises(InputError, match='no vertices'):
        feasible_wrench_set(np.zeros((1, 3)), [no_vertices])


def test_fws_with_kernels_on_the_default_bag_equals_numpy_and_the_lp(repo, tmp_path):
    """
    Every FWS the node computes over the default bag, and every 25th joint state's.

    With the compiled kernels (faces, slice search, ratio test, ...) the signed margin and the
    directional margins equal those of the numpy reference, recomputed from scratch, and the
    directional margins and membership those of exact LPs on the legs' vertices (no H-rep;
    three and four legs, where the FWS is solid).
    """
    from awp_ros.bags.replay import replay_bag
    from awp_ros.evaluation.evaluator import compute_fws
    from awp_ros.geometry import kernels
    from awp_ros.robot.config import load_parameters
    from awp_ros.ros.pipeline import Pipeline
    from awp_ros.wrench.fws_queries import lp_directional_margins
    values, base_dir = load_parameters('hyq')
    pipe = Pipeline.from_parameters(values, base_dir=base_dir)
    jobs = []
    evaluate = pipe.on_joint_state

    def keep(msg, **kw):
        cycle = evaluate(msg, **kw)
        r = cycle.result
        if r is not None and r.legs and (r.fws is not None or len(jobs) % 25 == 0):
            jobs.append(pipe.evaluator.fws_job(r))
        elif r is not None and r.legs:
            jobs.append(None)
        return cycle
    pipe.on_joint_state = keep
    replay_bag(repo / 'config' / 'hyq_gait.mcap', tmp_path / 'out.mcap', pipeline=pipe,
               outputs=['report'], progress=False, copy_inputs=False)
    jobs = [job for job in jobs if job is not None]
    legs = {len(job[1]) for job in jobs}
    assert len(jobs) > 250 and legs == {2, 3, 4}
    solid = 0
    for positions, frictions, w, ftol, htol, _ in jobs:
        S, margin, plus, minus, _ = compute_fws(positions, frictions, w, ftol, htol)
        kernels.ENABLED = False
        try:
            S0, margin0, plus0, minus0, _ = compute_fws(positions, frictions, w, ftol, htol)
        finally:
            kernels.ENABLED = True
        scale = 1.0 + np.abs(w).max()
        assert S.dimension == S0.dimension
        assert margin.feasible == margin0.feasible
        assert margin.margin == pytest.approx(margin0.margin, abs=1e-6 * scale)
        np.testing.assert_allclose(plus, plus0, atol=1e-6 * scale, rtol=1e-9)
        np.testing.assert_allclose(minus, minus0, atol=1e-6 * scale, rtol=1e-9)
        if S.dimension < 6:     # flat (two legs): feasible within hull_tol of the hull
            continue
        solid += 1
        member, lp_plus, lp_minus = lp_directional_margins(
            positions, [Q.vertices for Q in frictions], w, feasibility_tol=ftol)
        assert member == margin.feasible
        np.testing.assert_allclose(plus, lp_plus, atol=1e-5 * scale, rtol=1e-7)
        np.testing.assert_allclose(minus, lp_minus, atol=1e-5 * scale, rtol=1e-7)
    assert solid > 150
