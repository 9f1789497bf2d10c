"""Tests of awp_ros.geometry.exterior against determinants (numpy.linalg.det), cross products."""

from __future__ import annotations

from itertools import combinations

import numpy as np
import pytest

from awp_ros.geometry.exterior import hodge_normal, wedge_all, wedge_rows, wedge_table


def minors(B: np.ndarray) -> np.ndarray:
    """All k x k minors of the k vectors (rows of B) on sorted coordinate sets, by det."""
    k, r = B.shape
    return np.array([np.linalg.det(B[:, list(S)]) for S in combinations(range(r), k)])


def wedge_of(B: np.ndarray) -> np.ndarray:
    """Wedge of the rows of B by repeated wedge_rows (one vector at a time)."""
    r = B.shape[1]
    W = B[:1]
    for j in range(1, B.shape[0]):
        W = wedge_rows(W, B[j:j + 1], r, j, 1)
    return W[0]


@pytest.mark.parametrize('r', [3, 4, 6])
def test_wedge_of_vectors_is_the_vector_of_minors(r):
    rng = np.random.default_rng(r)
    for k in range(1, r + 1):
        B = rng.normal(size=(k, r))
        np.testing.assert_allclose(wedge_of(B), minors(B), atol=1e-12)


def test_wedge_is_associative_and_graded_antisymmetric():
    rng = np.random.default_rng(1)
    r = 6
    x, y = rng.normal(size=(2, r))
    X = wedge_of(rng.normal(size=(2, r)))[None]                 # a 2-vector
    xy = wedge_rows(x[None], y[None], r, 1, 1)
    yx = wedge_rows(y[None], x[None], r, 1, 1)
    np.testing.assert_allclose(xy, -yx, atol=1e-14)
    left = wedge_rows(wedge_rows(X, x[None], r, 2, 1), y[None], r, 3, 1)
    right = wedge_rows(X, xy, r, 2, 2)
    np.testing.assert_allclose(left, right, atol=1e-12)
    # A 2-vector commutes with a 1-vector: (-1)^(2 * 1) = 1.
    np.testing.assert_allclose(wedge_rows(X, x[None], r, 2, 1),
                               wedge_rows(x[None], X, r, 1, 2), atol=1e-12)


def test_wedge_all_is_every_pair_of_wedge_rows():
    rng = np.random.default_rng(2)
    r, p, q = 5, 2, 2
    X = rng.normal(size=(3, 4, 10))                             # 3 batches, 4 p-vectors
    Y = rng.normal(size=(3, 5, 10))                             # 5 q-vectors
    out = np.empty((3, 4, 5 * 5))                               # C(5, 4) = 5 coordinates
    Z = wedge_all(X, Y, r, p, q, out=out)
    assert Z.shape == (3, 20, 5) and np.shares_memory(Z, out)
    for b in range(3):
        for i in range(4):
            for j in range(5):
                np.testing.assert_allclose(Z[b, i * 5 + j],
                                           wedge_rows(X[b, i:i + 1], Y[b, j:j + 1], r, p, q)[0],
                                           atol=1e-12)


def test_hodge_normal_is_the_cross_product_and_is_orthogonal():
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(2, 3))
    np.testing.assert_allclose(hodge_normal(wedge_of(np.stack([a, b]))), np.cross(a, b),
                               atol=1e-14)
    B = rng.normal(size=(5, 6))
    n = hodge_normal(wedge_of(B))
    np.testing.assert_allclose(B @ n, 0.0, atol=1e-12)
    # |n| is the 5-volume: sqrt(det(B B^T)).
    assert np.linalg.norm(n) == pytest.approx(np.sqrt(np.linalg.det(B @ B.T)), rel=1e-12)


def test_wedge_table_is_read_only_and_cached():
    T = wedge_table(6, 2, 3)
    assert T.shape == (15, 20, 6) and not T.flags.writeable
    assert wedge_table(6, 2, 3) is T
    # A p-set and a disjoint q-set meet in exactly one (p+q)-set, overlapping ones in none.
    assert np.all(np.abs(T).sum(axis=2) <= 1.0)
