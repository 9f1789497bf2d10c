"""Tests of awp_ros.wrench.force_polytope: per-leg force polytopes and the 3D H/V converters."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.spatial import ConvexHull

from awp_ros.wrench.force_polytope import (CUBE_SIGNS, force_polytope, parallelepipeds,
                                           polytope_from_halfspaces, polytope_from_points)

RNG_SEED = 7


def _same_rows(X, Y, atol):
    """Return True if the row sets of X and Y match up to atol (any order)."""
    if X.shape != Y.shape:
        return False
    D = np.linalg.norm(X[:, None, :] - Y[None, :, :], axis=2)
    return bool(np.all(D.min(axis=1) <= atol) and np.all(D.min(axis=0) <= atol))


def _support_lp(J, bias, lo, hi, c):
    """Return max c.f over {lo <= bias - J^T f <= hi} by linprog (the definition)."""
    A = np.vstack([J.T, -J.T])
    b = np.concatenate([bias - lo, hi - bias])
    res = linprog(-c, A_ub=A, b_ub=b, bounds=[(None, None)] * 3, method='highs')
    assert res.status == 0
    return -res.fun


def test_diagonal_jacobian_gives_the_hand_computed_box():
    # tau = bias - J^T f with J = diag(0.5, 0.4, 0.3): f_i = (bias_i - tau_i) / J_ii.
    J = np.diag([0.5, 0.4, 0.3])
    bias = np.array([0.0, 0.0, 2.943])
    lo, hi = -np.array([10.0, 20.0, 30.0]), np.array([10.0, 20.0, 30.0])
    P = force_polytope(J, bias, lo, hi)
    assert P.dimension == 3 and not P.meta['singular']
    fx, fy = (-20.0, 20.0), (-50.0, 50.0)
    fz = ((2.943 - 30.0) / 0.3, (2.943 + 30.0) / 0.3)
    box = np.array([[x, y, z] for x in fx for y in fy for z in fz])
    assert _same_rows(P.vertices, box, 1e-9)
    np.testing.assert_allclose(P.meta['center'], [0.0, 0.0, 2.943 / 0.3], atol=1e-12)
    # The facet normals are the columns of J, normalised: here the axes.
    assert _same_rows(P.A, np.vstack([np.eye(3), -np.eye(3)]), 1e-12)
    np.testing.assert_allclose(np.sort(P.b), np.sort([20, 20, 50, 50, -fz[0], fz[1]]))


def test_parallelepiped_vertices_meet_the_torque_box_at_their_corners():
    rng = np.random.default_rng(RNG_SEED)
    K = 5
    J = rng.normal(size=(K, 3, 3))
    bias = rng.normal(size=(K, 3)) * 10
    lo = -rng.uniform(5, 50, size=(K, 3))
    hi = rng.uniform(5, 50, size=(K, 3))
    pp = parallelepipeds(J, bias, lo, hi)
    for k in range(K):
        tau = bias[k] - pp['vertices'][k] @ J[k]        # rows: tau = bias - J^T f
        expected = 0.5 * (hi[k] + lo[k]) + 0.5 * (hi[k] - lo[k]) * CUBE_SIGNS
        np.testing.assert_allclose(tau, expected, atol=1e-8)
        # H-rep: every vertex on exactly 3 facets, inside all others; facets match qhull.
        slack = pp['b'][k] - pp['vertices'][k] @ pp['A'][k].T
        assert np.all(slack >= -1e-8)
        assert np.all(np.sum(np.abs(slack) < 1e-8, axis=1) == 3)
        hull = ConvexHull(pp['vertices'][k])
        eq = np.unique(np.round(hull.equations, 8), axis=0)
        assert _same_rows(np.hstack([pp['A'][k], -pp['b'][k][:, None]]), eq, 1e-6)


def test_four_joint_leg_is_the_exact_set_checked_by_linear_programs():
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(5):
        J = rng.normal(size=(3, 4))
        bias = rng.normal(size=4) * 5
        lo, hi = -rng.uniform(5, 30, 4), rng.uniform(5, 30, 4)
        P = force_polytope(J, bias, lo, hi)
        assert P.dimension == 3 and not P.meta['singular']
        tau = bias - P.vertices @ J
        assert np.all(tau >= lo - 1e-8) and np.all(tau <= hi + 1e-8)
        hull = ConvexHull(P.vertices)
        assert len(hull.vertices) == len(P.vertices)       # all reported points extreme
        for c in rng.normal(size=(20, 3)):
            assert np.max(P.vertices @ c) == pytest.approx(_support_lp(J, bias, lo, hi, c),
                                                           rel=1e-9, abs=1e-9)
        # The H-rep is exactly the facets (qhull's, merged).
        eq = np.unique(np.round(hull.equations, 7), axis=0)
        assert _same_rows(np.unique(np.round(np.hstack([P.A, -P.b[:, None]]), 7), axis=0),
                          eq, 1e-5)


def test_singular_leg_is_flagged_and_flat_pseudo_inverse_image():
    # Fully stretched leg: the columns of J are coplanar (rank 2).
    J = np.array([[0.0, 0.5, 0.2], [0.3, 0.0, 0.0], [0.0, 0.0, 0.0]])
    bias = np.array([1.0, 2.0, 3.0])
    lo, hi = -np.full(3, 10.0), np.full(3, 10.0)
    P = force_polytope(J, bias, lo, hi)
    assert P.meta['singular'] and P.dimension == 2
    pinv = np.linalg.pinv(J.T)
    pts = (bias[None, :] - (0.0 + 10.0 * CUBE_SIGNS)) @ pinv.T
    Y = (pts - P.hull_origin) @ P.hull_basis
    hull = ConvexHull(Y)
    assert _same_rows(P.vertices, pts[hull.vertices], 1e-9)
    assert np.all(P.A @ pts.T <= P.b[:, None] + 1e-9)     # the image is inside the H-rep
    assert np.all(np.abs(P.vertices[:, 2]) < 1e-12)       # flat in the rows' plane


def test_near_singular_leg_is_exact_but_flagged():
    J = np.diag([0.5, 0.4, 1e-3])
    P = force_polytope(J, np.zeros(3), -np.ones(3), np.ones(3))
    assert P.meta['near_singular'] and not P.meta['singular'] and P.dimension == 3
    assert np.max(P.vertices[:, 2]) == pytest.approx(1e3)


def test_halfspaces_to_vertices_edge_cases():
    cube = np.vstack([np.eye(3), -np.eye(3)])
    P = polytope_from_halfspaces(cube, np.ones(6))
    assert P.dimension == 3 and len(P.vertices) == 8 and len(P.b) == 6
    # A redundant row is dropped from the H-rep, a duplicate too.
    P = polytope_from_halfspaces(np.vstack([cube, [[1, 1, 1]], cube[:1]]),
                                 np.concatenate([np.ones(6), [10.0, 1.0]]))
    assert len(P.b) == 6
    assert polytope_from_halfspaces(cube, np.array([1, 1, 1, -2, 1, 1.0])).is_empty
    flat = polytope_from_halfspaces(cube, np.array([1, 1, 0, 1, 1, 0.0]))
    assert flat.dimension == 2 and len(flat.vertices) == 4
    np.testing.assert_allclose(np.abs(flat.hull_basis[2]), 0.0, atol=1e-12)
    seg = polytope_from_halfspaces(cube, np.array([1, 0, 0, 1, 0, 0.0]))
    assert seg.dimension == 1 and len(seg.vertices) == 2
    pt = polytope_from_halfspaces(cube, np.zeros(6))
    assert pt.dimension == 0 and np.allclose(pt.vertices, 0.0)


def test_points_to_polytope_any_dimension():
    rng = np.random.default_rng(RNG_SEED)
    X = rng.normal(size=(30, 3))
    P = polytope_from_points(X)
    hull = ConvexHull(X)
    assert _same_rows(P.vertices, X[hull.vertices], 1e-12)
    assert np.all(P.A @ X.T <= P.b[:, None] + 1e-9)
    square = np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1], [0.5, 0.5, 1.0]])
    P = polytope_from_points(square)
    assert P.dimension == 2 and len(P.vertices) == 4 and len(P.b) == 4
    assert P.contains(np.array([0.5, 0.2, 1.0])) and not P.contains(np.array([0.5, 0.2, 1.1]))
    P = polytope_from_points(np.array([[0, 0, 0], [1, 1, 1], [2, 2, 2.0]]))
    assert P.dimension == 1 and _same_rows(P.vertices, np.array([[0, 0, 0], [2, 2, 2.0]]), 0)
    assert polytope_from_points(np.ones((3, 3))).dimension == 0


def test_exactly_singular_jacobians_do_not_raise():
    J = np.stack([np.diag([0.5, 0.4, 0.3]), np.array([[1.0, 2, 3], [2, 4, 6], [0, 0, 1]]),
                  np.zeros((3, 3))])
    pp = parallelepipeds(J, np.zeros((3, 3)), -np.ones((3, 3)), np.ones((3, 3)))
    assert np.all(np.isfinite(pp['vertices'][0]))
    assert np.all(np.isnan(pp['vertices'][1:]))
    np.testing.assert_array_equal(pp['sigma_ratio'][2], 0.0)
    P = force_polytope(J[1], np.ones(3), -np.ones(3), np.ones(3))
    assert P.meta['singular'] and P.dimension == 2
    P = force_polytope(J[2], np.ones(3), -np.ones(3), np.ones(3))
    assert P.meta['singular'] and P.dimension == 0      # no Jacobian: only f = 0
    np.testing.assert_allclose(P.vertices, np.zeros((1, 3)))


def _support_lp_in_span(J, bias, lo, hi, c):
    """Return max c.f over {f = J y : lo <= bias - J^T J y <= hi} (the definition, eq. 4)."""
    n = J.shape[1]
    JTJ = J.T @ J
    A = np.vstack([JTJ, -JTJ])
    b = np.concatenate([bias - lo, hi - bias])
    res = linprog(-(J.T @ c), A_ub=A, b_ub=b, bounds=[(None, None)] * n, method='highs')
    assert res.status == 0
    return -res.fun


@pytest.mark.parametrize('n', [1, 2])
def test_legs_with_fewer_than_three_joints_are_exact_flat_and_not_singular(n):
    rng = np.random.default_rng(RNG_SEED + n)
    J = rng.normal(size=(3, n)) * 0.3
    bias = rng.normal(size=n)
    lo, hi = -rng.uniform(5, 15, n), rng.uniform(5, 15, n)
    P = force_polytope(J, bias, lo, hi)
    assert not P.meta['singular'] and not P.meta['near_singular'] and P.meta['planar']
    assert P.dimension == n
    # Within the leg's span: the support function equals the LP on the definition.
    for _ in range(20):
        c = rng.normal(size=3)
        assert np.max(P.vertices @ c) == pytest.approx(_support_lp_in_span(J, bias, lo, hi, c),
                                                       rel=1e-9, abs=1e-9)
    # Every vertex is a force in range(J) whose torques are at a corner of the box.
    tau = bias - P.vertices @ J
    assert np.all(np.isclose(tau, lo[None], atol=1e-9) | np.isclose(tau, hi[None], atol=1e-9))
    resid = P.vertices - P.vertices @ J @ np.linalg.pinv(J)
    assert np.max(np.abs(resid)) < 1e-9
    # The generators cover the set with zero columns up to 3 (one AWP zonotope).
    G, cen = P.meta['generators'], P.meta['center']
    assert G.shape == (3, 3) and np.all(G[:, n:] == 0.0)
    corners = cen - CUBE_SIGNS @ G.T
    for c in rng.normal(size=(20, 3)):
        assert np.max(corners @ c) == pytest.approx(np.max(P.vertices @ c), abs=1e-9)


def test_a_two_joint_leg_singular_within_its_rank_is_flagged():
    J = np.array([[0.2, 0.4], [0.0, 0.0], [0.1, 0.2]])        # parallel columns: rank 1
    P = force_polytope(J, np.zeros(2), -np.ones(2), np.ones(2))
    assert P.meta['singular'] and P.dimension == 1
