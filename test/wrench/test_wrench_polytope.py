"""Tests of awp_ros.wrench.wrench_polytope: AWP against qhull and by hand, FWP against LPs."""

from __future__ import annotations

from itertools import product

import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.spatial import ConvexHull

from awp_ros.errors import InputError
from awp_ros.geometry.margin import directional_margins, polytope_margin
from awp_ros.wrench.contact_wrench_cone import contact_wrench_cone, friction_pyramid, lift_rays
from awp_ros.wrench.wrench_polytope import (actuation_wrench_polytope, feasible_wrench_polytope,
                                            lift, lift_points)

FEET = np.array([[0.37, 0.33, -0.55], [0.37, -0.33, -0.55],
                 [-0.37, 0.33, -0.55], [-0.37, -0.33, -0.55]])
UP = np.tile([0.0, 0.0, 1.0], (4, 1))
MU = 0.7
TAU = np.array([150.0, 150.0, 150.0])  # [N.m] half-range of the torque box
WEIGHT = np.array([0.0, 0.0, 85.0 * 9.81, 0.0, 0.0, 0.0])


def leg_jacobian(q: np.ndarray, sign: float) -> np.ndarray:
    """
    Return the translational Jacobian [m/rad] of a HyQ-like leg.

    HAA about x, HFE and KFE about y.
    """
    def fk(q):
        c0, s0 = np.cos(q[0]), np.sin(q[0])
        rx = np.array([[1, 0, 0], [0, c0, -s0], [0, s0, c0]])

        def ry(a):
            return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
        return rx @ (np.array([0, sign * 0.08, 0]) + ry(q[1]) @ (
            np.array([0, 0, -0.35]) + ry(q[2]) @ np.array([0, 0, -0.35])))
    eps = 1e-7
    return np.column_stack([(fk(q + eps * e) - fk(q - eps * e)) / (2 * eps) for e in np.eye(3)])


def hyq_legs(K: int, seed: int = 0):
    """Return (positions, centers, generators) of K HyQ-like legs in random standing postures."""
    rng = np.random.default_rng(seed)
    P, C, H = [], [], []
    for k in range(K):
        q = np.array([rng.uniform(-0.2, 0.2), rng.uniform(0.5, 0.9), rng.uniform(-1.6, -1.0)])
        J = leg_jacobian(q, 1.0 if k % 2 == 0 else -1.0)
        JinvT = np.linalg.inv(J.T)
        bias = rng.normal(size=3) * 5.0  # [N.m] gravity of the leg's links
        P.append(FEET[k] + rng.normal(size=3) * 0.02)
        C.append(JinvT @ bias)
        H.append(JinvT @ np.diag(TAU))
    return np.array(P).reshape(K, 3), np.array(C).reshape(K, 3), np.array(H).reshape(K, 3, 3)


def vertex_sums(P, C, H) -> np.ndarray:
    """All 2^(3K) lifted vertex sums (brute force)."""
    K = P.shape[0]
    c = sum(lift(P[k]) @ C[k] for k in range(K))
    G = np.hstack([lift(P[k]) @ H[k] for k in range(K)])
    return c + np.array(list(product((-1.0, 1.0), repeat=3 * K))) @ G.T


def lp_in_awp(P, C, H, w) -> bool:
    """Return whether w = sum_k L_k (c_k + H_k t_k), |t| <= 1 (LP on the definition)."""
    K = P.shape[0]
    G = np.hstack([lift(P[k]) @ H[k] for k in range(K)])
    c = sum(lift(P[k]) @ C[k] for k in range(K))
    res = linprog(np.zeros(3 * K), A_eq=G, b_eq=w - c, bounds=(-1, 1), method='highs')
    return res.status == 0


def lp_in_cwc(P, w, normals=UP, mu=MU) -> bool:
    R = lift_rays(P, np.stack([friction_pyramid(n, mu)[0] for n in normals[:len(P)]]))
    R = R.reshape(-1, 6)
    res = linprog(np.zeros(R.shape[0]), A_eq=R.T, b_eq=w, bounds=(0, None), method='highs')
    return res.status == 0


def lp_fwp_support(P, C, H, a, normals=UP, mu=MU) -> float:
    """Return max a.w over AWP cap CWC (LP over both definitions at once)."""
    K = P.shape[0]
    G = np.hstack([lift(P[k]) @ H[k] for k in range(K)])
    c = sum(lift(P[k]) @ C[k] for k in range(K))
    R = lift_rays(P, np.stack([friction_pyramid(n, mu)[0] for n in normals[:K]])).reshape(-1, 6)
    nt, nl = 3 * K, R.shape[0]
    # Variables [t, lam]: G t + c = R lam, objective max a.(R lam).
    A_eq = np.hstack([G, -R.T])
    res = linprog(np.concatenate([np.zeros(nt), -(R @ a)]), A_eq=A_eq, b_eq=-c,
                  bounds=[(-1, 1)] * nt + [(0, None)] * nl, method='highs')
    assert res.status == 0
    return -res.fun


def lp_in_fws(P, C, H, w, normals=UP, mu=MU) -> bool:
    """One force distribution: f_k in force polytope and pyramid, sum L_k f_k = w."""
    K = P.shape[0]
    nv = 6 * K  # f_k (3) and t_k (3) per leg
    A_eq, b_eq, A_ub = [], [], []
    L = np.hstack([lift(P[k]) for k in range(K)])
    A_eq.append(np.hstack([L, np.zeros((6, 3 * K))]))
    b_eq.append(w)
    for k in range(K):
        row = np.zeros((3, nv))
        row[:, 3 * k:3 * k + 3] = np.eye(3)
        row[:, 3 * K + 3 * k:3 * K + 3 * k + 3] = -H[k]
        A_eq.append(row)
        b_eq.append(C[k])
        facets = friction_pyramid(normals[k], mu)[1]
        ub = np.zeros((facets.shape[0], nv))
        ub[:, 3 * k:3 * k + 3] = facets
        A_ub.append(ub)
    bounds = [(None, None)] * (3 * K) + [(-1, 1)] * (3 * K)
    res = linprog(np.zeros(nv), A_ub=np.vstack(A_ub), b_ub=np.zeros(sum(len(a) for a in A_ub)),
                  A_eq=np.vstack(A_eq), b_eq=np.concatenate(b_eq), bounds=bounds,
                  method='highs')
    return res.status == 0


def test_lift_is_force_and_moment_about_com():
    p, f = np.array([0.37, -0.33, -0.55]), np.array([10.0, -20.0, 300.0])
    np.testing.assert_allclose(lift(p) @ f, np.concatenate([f, np.cross(p, f)]))
    np.testing.assert_allclose(lift_points(p[None], f[None])[0], lift(p) @ f)


def test_one_leg_with_diagonal_jacobian_by_hand():
    p = np.array([0.37, 0.33, -0.55])
    J = np.diag([0.3, 0.5, 0.4])
    h = TAU / np.diag(J)  # [N] half-widths of the force box
    c = np.array([5.0, -3.0, 40.0])
    awp = actuation_wrench_polytope(p[None], c[None], np.diag(h)[None])
    assert awp.dimension == 3 and awp.A.shape[0] == 6
    m = polytope_margin(awp, lift(p) @ c)
    # Distance from L c to the facet x_i = c_i + h_i inside range(L):
    # h_i / sqrt([(L^T L)^-1]_ii), (L^T L)^-1 = (I + p p^T) / (1 + |p|^2).
    expected = np.min(h * np.sqrt((1 + p @ p) / (1 + p ** 2)))
    assert m.margin == pytest.approx(expected, rel=1e-12)
    assert m.affine_residual == pytest.approx(0.0, abs=1e-9)
    L = lift(p)
    proj = L @ np.linalg.solve(L.T @ L, L.T @ WEIGHT)
    m = polytope_margin(awp, WEIGHT)
    assert m.affine_residual == pytest.approx(np.linalg.norm(WEIGHT - proj))
    assert not m.feasible


@pytest.mark.parametrize('K', [1, 2, 3])
def test_awp_matches_qhull_of_vertex_sums(K):
    P, C, H = hyq_legs(K, seed=K)
    awp = actuation_wrench_polytope(P, C, H, with_vertices=True)
    assert awp.dimension == {1: 3, 2: 5, 3: 6}[K]
    pts = vertex_sums(P, C, H)
    y = (pts - awp.hull_origin) @ awp.hull_basis
    assert np.max(np.linalg.norm(pts - awp.hull_origin - y @ awp.hull_basis.T, axis=1)) < 1e-9
    hull = ConvexHull(y)
    facets = np.hstack([hull.equations[:, :-1], -hull.equations[:, -1:]])
    A_r, b_r = awp.A @ awp.hull_basis, awp.b - awp.A @ awp.hull_origin
    ours = np.hstack([A_r, b_r[:, None] / 1e3])
    theirs = np.unique(np.round(np.hstack([facets[:, :-1], facets[:, -1:] / 1e3]), 7), axis=0)
    d = np.max(np.abs(ours[:, None, :] - theirs[None, :, :]), axis=2)
    assert np.all(d.min(axis=1) < 1e-6) and np.all(d.min(axis=0) < 1e-6)
    V = np.unique(np.round(pts[hull.vertices], 5), axis=0)
    np.testing.assert_allclose(np.unique(np.round(awp.vertices, 5), axis=0), V, atol=1e-4)


def test_four_leg_awp_support_equals_brute_force():
    P, C, H = hyq_legs(4, seed=4)
    awp = actuation_wrench_polytope(P, C, H)
    assert awp.dimension == 6
    # 792 five-subsets of 12 generators; the 6 subsets with 3 + 2 generators of the same two
    # legs all span L_i R^3 + L_j R^3: one normal per pair of legs, 6 * 5 duplicates.
    assert awp.A.shape[0] == 2 * (792 - 30)
    brute = np.max(vertex_sums(P, C, H) @ awp.A.T, axis=0)
    np.testing.assert_allclose(awp.b, brute, rtol=1e-12, atol=1e-8)


@pytest.mark.parametrize('K', [3, 4])
def test_fwp_membership_matches_lps_and_contains_fws(K):
    P, C, H = hyq_legs(K, seed=10 + K)
    fwp = feasible_wrench_polytope(actuation_wrench_polytope(P, C, H),
                                   contact_wrench_cone(P, UP[:K], MU))
    assert fwp.dimension == 6 and not fwp.meta['degenerate']
    rng = np.random.default_rng(K)
    W = WEIGHT + rng.normal(size=(30, 6)) * [500, 500, 1200, 200, 200, 150]
    seen = set()
    for w in W:
        m = polytope_margin(fwp, w)
        if abs(m.margin) < 1e-3:
            continue
        inside = m.margin > 0
        assert inside == (lp_in_awp(P, C, H, w) and lp_in_cwc(P, w))
        if lp_in_fws(P, C, H, w):
            assert inside
        seen.add(inside)
    assert seen == {True, False}


def test_fwp_margin_lp_certificates():
    P, C, H = hyq_legs(4, seed=21)
    fwp = feasible_wrench_polytope(actuation_wrench_polytope(P, C, H),
                                   contact_wrench_cone(P, UP, MU))
    rng = np.random.default_rng(5)
    for w in (WEIGHT, WEIGHT + [300, 0, 0, 0, 0, 0], WEIGHT + [0, 0, 0, 0, 400, 0],
              np.array([0.0, 0.0, -100.0, 0.0, 0.0, 0.0])):
        m = polytope_margin(fwp, w)
        a = m.normal
        assert lp_fwp_support(P, C, H, a) == pytest.approx(a @ w + m.margin, rel=1e-7, abs=1e-6)
        if m.margin > 0:
            for u in rng.normal(size=(8, 6)):
                x = w + (1 - 1e-7) * m.margin * u / np.linalg.norm(u)
                assert lp_in_awp(P, C, H, x) and lp_in_cwc(P, x)
            assert not (lp_in_awp(P, C, H, w + 1.01 * m.margin * a)
                        and lp_in_cwc(P, w + 1.01 * m.margin * a))


@pytest.mark.parametrize(('K', 'dim'), [(0, 0), (1, 3), (2, 5), (3, 6), (4, 6)])
def test_stance_sizes_dimensions_and_residuals(K, dim):
    P, C, H = hyq_legs(K, seed=30 + K)
    awp = actuation_wrench_polytope(P, C, H)
    cwc = contact_wrench_cone(P, UP[:K], MU)
    fwp = feasible_wrench_polytope(awp, cwc)
    assert awp.dimension == cwc.dimension == fwp.dimension == dim
    m = polytope_margin(fwp, WEIGHT)
    if K >= 3:
        assert m.affine_residual < 1e-9
    else:
        # Residual by an independent projection on span{L_k e_i}.
        L = np.hstack([lift(p) for p in P]) if K else np.zeros((6, 0))
        if K:
            proj = L @ np.linalg.lstsq(L, WEIGHT, rcond=None)[0]
        else:
            proj = np.zeros(6)
        assert m.affine_residual == pytest.approx(np.linalg.norm(WEIGHT - proj), rel=1e-9)
        assert not m.feasible
    tp, tm = directional_margins(fwp, WEIGHT)
    assert tp.shape == tm.shape == (6,)


def test_fwp_empty_and_touching_cases():
    p = FEET[:1]
    h = np.diag([300.0, 300.0, 300.0])[None]
    cwc = contact_wrench_cone(p, UP[:1], MU)
    far = feasible_wrench_polytope(actuation_wrench_polytope(p, np.array([[0, 0, -900.0]]), h),
                                   cwc)
    assert far.is_empty
    assert polytope_margin(far, WEIGHT).margin == -np.inf
    touch = feasible_wrench_polytope(
        actuation_wrench_polytope(p, np.array([[0, 0, -300.0]]), h), cwc)
    assert not touch.is_empty and touch.meta['degenerate']
    assert polytope_margin(touch, np.zeros(6)).margin == pytest.approx(0.0, abs=1e-9)


def test_frictionless_contact_gives_a_segment():
    p = FEET[:1]
    awp = actuation_wrench_polytope(p, np.array([[0.0, 0.0, 100.0]]),
                                    np.diag([300.0, 300.0, 400.0])[None])
    cwc = contact_wrench_cone(p, UP[:1], 0.0)
    fwp = feasible_wrench_polytope(awp, cwc)
    assert cwc.dimension == 1 and fwp.dimension == 1
    # Normal forces 0 .. 500 N along the lifted normal: the middle is 250 N from both ends.
    n6 = lift(p[0]) @ [0.0, 0.0, 1.0]
    m = polytope_margin(fwp, 250.0 * n6)
    assert m.margin == pytest.approx(250.0 * np.linalg.norm(n6))
    assert m.affine_residual < 1e-9


def test_bad_input_raises():
    with pytest.raises(InputError, match='positions'):
        actuation_wrench_polytope(np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((3, 3, 3)))
    with pytest.raises(InputError, match='finite'):
        actuation_wrench_polytope(np.full((1, 3), np.nan), np.zeros((1, 3)), np.zeros((1, 3, 3)))
