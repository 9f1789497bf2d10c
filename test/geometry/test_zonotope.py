"""Tests of awp_ros.geometry.zonotope (and its linalg kernels) against qhull and brute force."""

from __future__ import annotations

from itertools import combinations, product

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from awp_ros.errors import InputError
from awp_ros.geometry.linalg import (distinct_columns, hyperplane_normals, orthonormal_span,
                                     subset_normals)
from awp_ros.geometry.zonotope import zonotope, zonotope_support


def vertex_sums(c: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Return all 2^m points c + G s, s in {-1, 1}^m (brute force)."""
    S = np.array(list(product((-1.0, 1.0), repeat=G.shape[1])))
    return c + S @ G.T


def qhull_facets(points: np.ndarray, decimals: int = 7) -> np.ndarray:
    """Return the distinct facet rows [a, b] (unit a, a.x <= b) of qhull's hull of points."""
    hull = ConvexHull(points)
    rows = np.hstack([hull.equations[:, :-1], -hull.equations[:, -1:]])
    return np.unique(np.round(rows, decimals), axis=0)


def assert_same_facets(A: np.ndarray, b: np.ndarray, facets: np.ndarray, scale: float = 1.0):
    """Every qhull facet is one of our rows and every row of ours is a qhull facet."""
    ours = np.hstack([A, b[:, None] / scale])
    theirs = np.hstack([facets[:, :-1], facets[:, -1:] / scale])
    d = np.max(np.abs(ours[:, None, :] - theirs[None, :, :]), axis=2)
    assert np.all(np.min(d, axis=1) < 1e-6), 'a row is not a facet'
    assert np.all(np.min(d, axis=0) < 1e-6), 'a facet is missing'


def in_hull_coordinates(P, points: np.ndarray) -> np.ndarray:
    return (points - P.hull_origin) @ P.hull_basis


def test_box_by_hand():
    Z = zonotope(np.array([1.0, 2.0, 3.0]), np.diag([0.5, 1.0, 2.0]), with_vertices=True)
    assert Z.dimension == 3 and Z.A.shape == (6, 3)
    for a, b in zip(Z.A, Z.b):
        i = int(np.argmax(np.abs(a)))
        assert abs(a[i]) == pytest.approx(1.0)
        expected = a[i] * [1.0, 2.0, 3.0][i] + [0.5, 1.0, 2.0][i]
        assert b == pytest.approx(expected)
    assert Z.vertices.shape == (8, 3)
    assert Z.contains([1.5, 3.0, 5.0]) and not Z.contains([1.6, 2.0, 3.0])


@pytest.mark.parametrize(('n', 'm', 'seed'), [(2, 4, 0), (3, 3, 1), (3, 6, 2), (4, 6, 3),
                                              (5, 7, 4), (6, 8, 5), (6, 9, 6)])
def test_random_full_dimensional_matches_qhull(n, m, seed):
    rng = np.random.default_rng(seed)
    c = rng.normal(size=n) * 100
    G = rng.normal(size=(n, m)) * 300
    Z = zonotope(c, G, with_vertices=True)
    pts = vertex_sums(c, G)
    assert Z.dimension == n
    assert_same_facets(Z.A, Z.b, qhull_facets(pts), scale=1000.0)
    hull = ConvexHull(pts)
    V = np.unique(np.round(pts[hull.vertices], 6), axis=0)
    np.testing.assert_allclose(np.unique(np.round(Z.vertices, 6), axis=0), V, atol=1e-5)
    # General position: 2 sum_{i<n} C(m-1, i) vertices.
    from math import comb
    assert Z.vertices.shape[0] == 2 * sum(comb(m - 1, i) for i in range(n))


def test_flat_zonotope_in_6d_matches_qhull_in_hull_coordinates():
    rng = np.random.default_rng(7)
    basis, _ = np.linalg.qr(rng.normal(size=(6, 3)))
    G = basis @ rng.normal(size=(3, 5)) * 200
    c = rng.normal(size=6) * 50
    Z = zonotope(c, G, with_vertices=True)
    assert Z.dimension == 3
    np.testing.assert_allclose(Z.hull_basis @ Z.hull_basis.T, basis @ basis.T, atol=1e-12)
    pts = in_hull_coordinates(Z, vertex_sums(c, G))
    A_r = Z.A @ Z.hull_basis
    b_r = Z.b - Z.A @ Z.hull_origin
    np.testing.assert_allclose(np.linalg.norm(Z.A, axis=1), 1.0)
    assert_same_facets(A_r, b_r, qhull_facets(pts), scale=1000.0)
    assert Z.vertices.shape[0] == len(ConvexHull(pts).vertices)


def test_degenerate_generators_parallel_zero_and_coplanar():
    rng = np.random.default_rng(8)
    g = rng.normal(size=(3, 3))
    G = np.column_stack([g[:, 0], 2.0 * g[:, 0], np.zeros(3), g[:, 1], g[:, 1] + g[:, 2],
                         g[:, 2], 0.5 * g[:, 1] - g[:, 2]])
    c = rng.normal(size=3)
    Z = zonotope(c, G, with_vertices=True)
    pts = vertex_sums(c, G)
    assert_same_facets(Z.A, Z.b, qhull_facets(pts))
    hull = ConvexHull(pts)
    V = np.unique(np.round(pts[hull.vertices], 8), axis=0)
    np.testing.assert_allclose(np.unique(np.round(Z.vertices, 8), axis=0), V, atol=1e-7)
    # Parallel generators make duplicate normals: they are removed.
    key = np.round(np.hstack([Z.A, Z.b[:, None]]), 8)
    assert np.unique(key, axis=0).shape[0] == key.shape[0]


def test_point_and_segment():
    P = zonotope(np.array([1.0, 2.0]), np.zeros((2, 3)), with_vertices=True)
    assert P.dimension == 0 and P.A.shape == (0, 2)
    np.testing.assert_allclose(P.vertices, [[1.0, 2.0]])
    S = zonotope(np.zeros(3), np.array([[1.0, 2.0], [0.0, 0.0], [1.0, 2.0]]),
                 with_vertices=True)
    assert S.dimension == 1 and S.A.shape[0] == 2
    np.testing.assert_allclose(np.sort(S.b), [3 * np.sqrt(2)] * 2)
    np.testing.assert_allclose(np.sort(S.vertices[:, 0]), [-3.0, 3.0])


def test_support_function_of_every_row_is_its_offset():
    rng = np.random.default_rng(9)
    c, G = rng.normal(size=6) * 10, rng.normal(size=(6, 10)) * 300
    Z = zonotope(c, G)
    brute = np.max(vertex_sums(c, G) @ Z.A.T, axis=0)
    np.testing.assert_allclose(Z.b, brute, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(zonotope_support(c, G, Z.A), Z.b, rtol=1e-12)
    assert Z.A.shape[0] == 2 * 252  # C(10, 5) facet pairs in general position


def test_bad_input_raises():
    with pytest.raises(InputError, match='center'):
        zonotope(np.zeros(3), np.zeros((4, 2)))
    with pytest.raises(InputError, match='finite'):
        zonotope(np.zeros(2), np.array([[np.nan], [1.0]]))


@pytest.mark.parametrize('d', [2, 3, 4, 5, 6])
def test_hyperplane_normals_are_orthogonal_unit_and_flag_rank(d):
    rng = np.random.default_rng(d)
    B = rng.normal(size=(50, d - 1, d)) * rng.uniform(0.01, 1000, size=(50, d - 1, 1))
    if d > 2:
        B[3, 1] = 3.0 * B[3, 0]
    B[5, 0] = 0.0
    n, valid = hyperplane_normals(B)
    bad = [5] + ([3] if d > 2 else [])
    assert not valid[bad].any() and valid.sum() == 50 - len(bad)
    np.testing.assert_allclose(np.linalg.norm(n[valid], axis=1), 1.0)
    Bu = B / np.linalg.norm(B, axis=2, keepdims=True).clip(1e-300)
    assert np.max(np.abs(np.einsum('mkd,md->mk', Bu, n)[valid])) < 1e-12
    # Against the SVD null vector.
    for i in np.flatnonzero(valid)[:10]:
        null = np.linalg.svd(B[i])[2][-1]
        assert abs(abs(null @ n[i]) - 1.0) < 1e-10


def test_subset_normals_match_hyperplane_normals_in_any_order():
    rng = np.random.default_rng(11)
    V = rng.normal(size=(5, 9))
    V[:, 4] = 0.0
    S = np.array(list(combinations(range(9), 4)))[rng.permutation(126)]
    n1, v1 = subset_normals(V, S)
    n2, v2 = hyperplane_normals(V.T[S])
    assert np.array_equal(v1, v2) and (~v1).sum() == 56  # C(8, 3) contain the zero one
    np.testing.assert_allclose(n1, n2, atol=1e-13)


def test_distinct_columns_keeps_the_first_of_each_column_pattern():
    rng = np.random.default_rng(12)
    for n in (16, 70):                          # exact float keys, then row-wise compare
        M = rng.random((n, 20)) < 0.5
        cols = np.hstack([M, M[:, [3, 7, 7]], M[:, :2]])
        first = distinct_columns(cols)
        assert first.tolist() == list(range(20))
        brute = [j for j in range(cols.shape[1])
                 if not any(np.array_equal(cols[:, i], cols[:, j]) for i in range(j))]
        assert first.tolist() == brute
    # Columns with exactly `own` entries are distinct by the caller's promise (not compared).
    cols = np.zeros((6, 7), dtype=bool)
    for j, s in enumerate([(0, 1), (0, 2), (0, 1, 2), (1, 2), (0, 1, 2), (3, 4), (0, 1, 2)]):
        cols[list(s), j] = True
    assert distinct_columns(cols, own=2).tolist() == [0, 1, 2, 3, 5]
    assert distinct_columns(cols).tolist() == [0, 1, 2, 3, 5]


@pytest.mark.parametrize('ratio', [1e-12, 1e-10, 1e-8, 1e-6, 1e-3, 1.0])
@pytest.mark.parametrize('rows', [6, 16])
def test_orthonormal_span_rank_matches_the_singular_values(ratio, rows):
    # Singular values 1 .. ratio (the smallest set by hand): the rank is that of the SVD
    # cut s > 1e-9 s_max, whether the Gram certificate or the SVD decides.
    rng = np.random.default_rng(int(-np.log10(ratio)) + rows)
    Q1, _ = np.linalg.qr(rng.normal(size=(rows, 6)))
    Q2, _ = np.linalg.qr(rng.normal(size=(6, 6)))
    s = np.array([1.0, 0.7, 0.5, 0.3, 0.2, ratio])
    V = 1e3 * (Q1 * s) @ Q2.T
    U = orthonormal_span(V)
    expected = 6 if ratio > 1e-9 else 5
    assert U.shape == (6, expected)
    assert np.allclose(U.T @ U, np.eye(expected), atol=1e-12)
    if expected < 6:                       # the dropped direction is the smallest one
        assert np.linalg.norm(U.T @ Q2[:, 5]) < 1e-6
