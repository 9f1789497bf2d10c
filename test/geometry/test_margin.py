"""Tests of awp_ros.geometry.margin against hand cases, qhull, projection certificates and LPs."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog, nnls
from scipy.spatial import ConvexHull

from awp_ros.errors import InputError
from awp_ros.geometry.margin import directional_margins, polytope_margin
from awp_ros.geometry.polytope import Polytope


def hull_polytope(points: np.ndarray, origin=None, basis=None, redundant: bool = False):
    """Build a Polytope from points (in hull coordinates when a basis is given) with qhull."""
    points = np.asarray(points, dtype=float)
    r = points.shape[1]
    hull = ConvexHull(points)
    A_r, b_r = hull.equations[:, :-1], -hull.equations[:, -1]
    if redundant:
        A_r = np.vstack([A_r, A_r[:3], A_r[:3]])
        b_r = np.concatenate([b_r, b_r[:3], b_r[:3] + 1.0])
    if basis is None:
        origin, basis = np.zeros(r), np.eye(r)
    A = A_r @ basis.T
    b = b_r + A @ origin
    V = origin + points[hull.vertices] @ basis.T
    return Polytope(r, V, A, b, origin, basis)


def unit_cube() -> Polytope:
    V = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float)
    return hull_polytope(V)


def support(P: Polytope, a: np.ndarray) -> float:
    """Support function by LP over the vertices (independent of the H-rep)."""
    return float(np.max(P.vertices @ a))


def lp_contains(P: Polytope, x: np.ndarray, tol: float = 1e-7) -> bool:
    """Membership by LP on the V-rep: x = V^T lam, lam in the simplex."""
    V = P.vertices
    k = V.shape[0]
    res = linprog(np.zeros(k), A_eq=np.vstack([V.T, np.ones((1, k))]),
                  b_eq=np.concatenate([x, [1.0]]), bounds=(0, None), method='highs')
    if res.status == 0:
        return True
    # Tolerant check: minimise the L1 violation.
    n = V.shape[1]
    c = np.concatenate([np.zeros(k), np.ones(2 * n)])
    Aeq = np.vstack([np.hstack([V.T, np.eye(n), -np.eye(n)]),
                     np.concatenate([np.ones(k), np.zeros(2 * n)])[None, :]])
    res = linprog(c, A_eq=Aeq, b_eq=np.concatenate([x, [1.0]]), bounds=(0, None),
                  method='highs')
    return res.status == 0 and res.fun <= tol


def hull_distance(V: np.ndarray, w: np.ndarray) -> float:
    """
    Return the distance from ``w`` to conv(V): NNLS over convex weights.

    ``min |V^T lam - w|`` over ``lam >= 0`` with ``sum(lam) = 1`` enforced by a heavily
    weighted extra row (its error is below 1e-9 of the scale here).
    """
    scale = 1e6 * (1.0 + float(np.max(np.abs(V))))
    E = np.vstack([V.T, np.full(V.shape[0], scale)])
    lam, _ = nnls(E, np.concatenate([w, [scale]]), maxiter=10000)
    return float(np.linalg.norm(V.T @ lam - w))


def test_cube_inside_is_distance_to_nearest_face():
    m = polytope_margin(unit_cube(), [0.5, 0.5, 0.2])
    assert m.margin == pytest.approx(0.2)
    np.testing.assert_allclose(m.normal, [0, 0, -1], atol=1e-12)
    assert m.dimension == 3 and m.affine_residual == 0.0 and m.feasible


def test_cube_outside_is_exact_distance_not_max_violation():
    m = polytope_margin(unit_cube(), [2.0, 2.0, 0.5])
    # max_i(a_i.w - b_i) would give 1, the exact distance is sqrt(2).
    assert m.margin == pytest.approx(-np.sqrt(2))
    np.testing.assert_allclose(m.normal, [1 / np.sqrt(2), 1 / np.sqrt(2), 0], atol=1e-9)
    assert not m.feasible


def test_flat_square_reports_residual_and_margin_in_hull():
    basis = np.array([[1.0, 0], [0, 1], [0, 0]])
    P = hull_polytope(np.array([[0, 0], [1, 0], [0, 1], [1, 1]], float),
                      origin=np.array([0, 0, 1.0]), basis=basis)
    m = polytope_margin(P, [0.5, 0.25, 3.0])
    assert m.dimension == 2
    assert m.affine_residual == pytest.approx(2.0)
    assert m.margin_in_hull == pytest.approx(0.25)
    assert m.margin == pytest.approx(-2.0)            # off the hull: minus the distance
    np.testing.assert_allclose(m.normal, [0, 0, 1], atol=1e-12)
    assert not m.feasible
    # Off the hull and outside the square in it: the distance has both parts (by hand).
    out = polytope_margin(P, [1.3, 0.5, 1.4])
    assert out.margin == pytest.approx(-0.5) and out.margin_in_hull == pytest.approx(-0.3)
    np.testing.assert_allclose(out.normal, [0.6, 0, 0.8], atol=1e-12)
    assert polytope_margin(P, [0.5, 0.25, 1.0 + 1e-8]).feasible
    # A hull tolerance accepts a small residual, keeping the in-hull margin.
    tol = polytope_margin(P, [0.5, 0.25, 1.1], hull_tol=0.2)
    assert tol.feasible and tol.margin == pytest.approx(0.25)
    assert not polytope_margin(P, [0.5, 0.25, 1.3], hull_tol=0.2).feasible


def test_point_set_margin_zero_residual_distance():
    P = Polytope(0, np.array([[1.0, 2, 3]]), np.zeros((0, 3)), np.zeros(0),
                 np.array([1.0, 2, 3]), np.zeros((3, 0)))
    m = polytope_margin(P, [1.0, 2, 7])
    assert m.margin == pytest.approx(-4.0) and m.margin_in_hull == 0.0 and m.dimension == 0
    assert m.affine_residual == pytest.approx(4.0)
    assert not m.feasible
    assert polytope_margin(P, [1.0, 2, 3]).feasible


def test_empty_set_is_infeasible():
    m = polytope_margin(Polytope.empty(6), np.zeros(6))
    assert m.margin == -np.inf and m.dimension == -1 and not m.feasible


def test_bad_point_raises_input_error():
    with pytest.raises(InputError, match='shape'):
        polytope_margin(unit_cube(), np.zeros(4))
    with pytest.raises(InputError, match='finite'):
        polytope_margin(unit_cube(), [0.0, np.nan, 0.0])


@pytest.mark.parametrize('seed', range(6))
def test_random_6d_margin_matches_qhull_and_lp_certificates(seed):
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(30, 6)) * [300, 300, 800, 100, 100, 50]
    P = hull_polytope(pts, redundant=True)
    inner = rng.dirichlet(np.ones(30) * 0.3, size=6) @ pts
    outer = rng.normal(size=(6, 6)) * [300, 300, 800, 100, 100, 50]
    margins = []
    for w in np.vstack([inner, outer]):
        m = polytope_margin(P, w)
        margins.append(m.margin)
        a = m.normal
        assert np.linalg.norm(a) == pytest.approx(1.0)
        # Support function at the witness normal: h(a) = a.w + margin (both cases).
        assert support(P, a) == pytest.approx(a @ w + m.margin, rel=1e-9, abs=1e-7)
        if m.margin >= 0:
            assert m.margin == pytest.approx(np.min(P.b - P.A @ w), abs=1e-9)
            for u in rng.normal(size=(20, 6)):
                u /= np.linalg.norm(u)
                assert lp_contains(P, w + (1 - 1e-9) * m.margin * u)
        else:
            # Nearest point z = w + margin * a is in P and w - z is in its normal cone:
            # (w - z).(v - z) <= 0 for every vertex v (the projection certificate).
            z = w + m.margin * a
            assert np.all(P.A @ z <= P.b + 1e-7)
            assert np.max((P.vertices - z) @ (w - z)) <= 1e-7 * np.linalg.norm(w - z) * 1e3
            assert lp_contains(P, z, tol=1e-6)
    assert min(margins) < 0 < max(margins)


@pytest.mark.parametrize('seed', range(3))
def test_flat_3d_set_in_6d_matches_its_own_coordinates(seed):
    rng = np.random.default_rng(10 + seed)
    pts = rng.normal(size=(12, 3)) * 200
    basis, _ = np.linalg.qr(rng.normal(size=(6, 3)))
    origin = rng.normal(size=6) * 10
    P6 = hull_polytope(pts, origin=origin, basis=basis)
    P3 = hull_polytope(pts)
    N = np.linalg.svd(basis)[0][:, 3:]
    for y in rng.normal(size=(8, 3)) * 150:
        off = N @ rng.normal(size=3) * 5
        w = origin + basis @ y + off
        m6 = polytope_margin(P6, w)
        m3 = polytope_margin(P3, y)
        assert m6.margin_in_hull == pytest.approx(m3.margin, rel=1e-9, abs=1e-9)
        assert m6.affine_residual == pytest.approx(np.linalg.norm(off))
        assert m6.dimension == 3 and not m6.feasible
        # Signed margin: minus the distance from w to the set, by an independent QP.
        assert m6.margin == pytest.approx(-hull_distance(origin + pts @ basis.T, w), rel=1e-6)
        if m3.margin >= 0:
            np.testing.assert_allclose(m6.normal, off / np.linalg.norm(off), atol=1e-9)
        m_on = polytope_margin(P6, origin + basis @ y)
        np.testing.assert_allclose(basis.T @ m_on.normal, m3.normal, atol=1e-9)
        assert m_on.margin == pytest.approx(m3.margin, rel=1e-9, abs=1e-9)


def test_directional_margins_on_cube_by_hand():
    tp, tm = directional_margins(unit_cube(), [0.25, 0.5, 0.9])
    np.testing.assert_allclose(tp, [0.75, 0.5, 0.1])
    np.testing.assert_allclose(tm, [0.25, 0.5, 0.9])
    tp, tm = directional_margins(unit_cube(), [2.0, 0.5, 0.5])
    assert tp[0] == pytest.approx(-1.0) and tm[0] == pytest.approx(2.0)
    assert np.isnan(tp[1]) and np.isnan(tm[2])


@pytest.mark.parametrize('seed', range(3))
def test_directional_margins_match_linprog(seed):
    rng = np.random.default_rng(20 + seed)
    P = hull_polytope(rng.normal(size=(25, 6)) * 100, redundant=True)
    w = rng.normal(size=6) * 20
    D = rng.normal(size=(4, 6))
    tp, tm = directional_margins(P, w, np.vstack([np.eye(6), D]))
    for i, d in enumerate(np.vstack([np.eye(6), D])):
        for sign, got in ((1.0, tp[i]), (-1.0, tm[i])):
            res = linprog([-1.0], A_ub=(P.A @ d * sign)[:, None], b_ub=P.b - P.A @ w,
                          bounds=[(None, None)], method='highs')
            if res.status == 2:
                assert np.isnan(got)
            else:
                assert got == pytest.approx(-res.fun, rel=1e-9, abs=1e-9)


def test_directional_margins_flat_set_transversal_and_parallel():
    basis = np.array([[1.0, 0], [0, 1], [0, 0]])
    P = hull_polytope(np.array([[0, 0], [1, 0], [0, 1], [1, 1]], float),
                      origin=np.array([0, 0, 1.0]), basis=basis)
    tp, tm = directional_margins(P, [0.5, 0.25, 1.0])
    np.testing.assert_allclose(tp, [0.5, 0.75, 0.0])
    np.testing.assert_allclose(tm, [0.5, 0.25, 0.0])
    # Off the hull: parallel lines miss, the transversal one hits at t0 = -2.
    tp, tm = directional_margins(P, [0.5, 0.25, 3.0])
    assert np.all(np.isnan(tp[:2])) and tp[2] == pytest.approx(-2.0)
    assert tm[2] == pytest.approx(2.0)
    tp, _ = directional_margins(P, [5.0, 0.25, 3.0])
    assert np.all(np.isnan(tp))


def test_cone_margins_by_hand():
    # The cone x2 >= |x1| (b = 0): inside, apex and edge projections.
    A = np.array([[1.0, -1.0], [-1.0, -1.0]]) / np.sqrt(2)
    C = Polytope(2, np.zeros((0, 2)), A, np.zeros(2), np.zeros(2), np.eye(2), {'kind': 'cone'})
    assert polytope_margin(C, [0.0, 1.0]).margin == pytest.approx(1 / np.sqrt(2))
    m = polytope_margin(C, [0.0, -1.0])
    assert m.margin == pytest.approx(-1.0)
    np.testing.assert_allclose(m.normal, [0.0, -1.0], atol=1e-12)
    m = polytope_margin(C, [2.0, 1.0])
    assert m.margin == pytest.approx(-np.sqrt(0.5))
    tp, tm = directional_margins(C, [0.0, 1.0])
    assert tp[1] == np.inf and tm[1] == pytest.approx(1.0) and tp[0] == pytest.approx(1.0)


@pytest.mark.parametrize('seed', range(3))
def test_least_distance_working_set_is_exact(seed):
    rng = np.random.default_rng(30 + seed)
    P = hull_polytope(rng.normal(size=(40, 6)) * 100)
    for w in rng.normal(size=(5, 6)) * 300:
        full = polytope_margin(P, w, working_set=10 ** 6)
        tiny = polytope_margin(P, w, working_set=1)
        assert tiny.margin == pytest.approx(full.margin, rel=1e-10, abs=1e-9)
        np.testing.assert_allclose(tiny.normal, full.normal, atol=1e-8)
