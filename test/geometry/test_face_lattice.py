"""Tests of awp_ros.geometry.face_lattice against hand cases, qhull and normal-cone definition."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from awp_ros.errors import InputError
from awp_ros.geometry.face_lattice import polytope_faces


def box(lo=(0.0, 0.0, 0.0), hi=(1.0, 1.0, 1.0)) -> np.ndarray:
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                     for z in (lo[2], hi[2])], dtype=float)


def class_members(group) -> list[tuple[np.ndarray, np.ndarray]]:
    """Return (dirs, checks) of every face of a group, ungrouped."""
    out = []
    for dirs, checks, mask in zip(group.dirs, group.checks, group.mask):
        out += [(dirs, checks[i]) for i in np.flatnonzero(mask)]
    return out


def maximisers(V: np.ndarray, c: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    s = V @ c
    return V[s >= s.max() - tol * np.abs(V).max() * np.linalg.norm(c)]


def test_cube_has_six_facets_twelve_edges_in_three_classes():
    F = polytope_faces(box())
    assert F.dimension == 3
    assert len(F.vertices) == 8
    edges, facets, whole = F.groups
    assert edges.count == 12 and edges.dirs.shape[0] == 3    # 3 classes of 4 parallel edges
    assert facets.count == 6 and facets.dirs.shape[0] == 3   # opposite facets share a class
    assert whole.count == 1
    sizes = F.groups[0].mask.sum(axis=1)
    assert np.all(np.diff(sizes) <= 0)                       # classes sorted by size
    normals = np.round(F.facet_normals, 12)
    expected = np.vstack([np.eye(3), -np.eye(3)])
    assert {tuple(n) for n in normals} == {tuple(n) for n in expected}
    np.testing.assert_allclose(np.sort(F.facet_offsets), [0, 0, 0, 1, 1, 1], atol=1e-12)


def test_duplicate_and_non_extreme_points_are_dropped():
    V = np.vstack([box(), box()[:3], [[0.5, 0.5, 0.5], [0.5, 0.5, 1.0], [0.5, 0.0, 0.0]]])
    F = polytope_faces(V)
    assert len(F.vertices) == 8
    assert F.groups[1].count == 6


@pytest.mark.parametrize('seed', range(5))
def test_random_polytope_facets_match_qhull(seed):
    rng = np.random.default_rng(seed)
    V = rng.normal(size=(14, 3)) * [300.0, 200.0, 800.0]
    F = polytope_faces(V)
    hull = ConvexHull(V)
    assert F.groups[1].count == len(hull.equations)          # generic: triangles
    assert F.groups[0].count == 3 * len(hull.equations) // 2
    assert len(F.vertices) == len(hull.vertices)
    for eq in hull.equations:
        assert np.max(F.facet_normals @ eq[:3]) == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize('seed', range(4))
def test_edge_checks_are_the_normal_cone(seed):
    """Any c perpendicular to an edge passes its checks iff c is maximised on a parallel edge."""
    rng = np.random.default_rng(seed)
    V = rng.normal(size=(12, 3)) * [300.0, 200.0, 800.0]
    F = polytope_faces(V)
    for dirs, checks, mask in zip(F.groups[0].dirs, F.groups[0].checks, F.groups[0].mask):
        e = dirs[0]
        for _ in range(40):
            c = rng.normal(size=3)
            c -= (c @ e) * e
            passes = any(np.all(checks[i] @ c >= 0.0) for i in np.flatnonzero(mask))
            M = maximisers(V, c)
            spans_edge = len(M) >= 2 and np.linalg.norm(np.cross(M[-1] - M[0], e)) < 1e-6 * \
                np.linalg.norm(M[-1] - M[0])
            assert passes == spans_edge


def test_facet_checks_select_the_outward_normal():
    V = box(hi=(2.0, 3.0, 5.0))
    F = polytope_faces(V)
    for dirs, checks, mask in zip(F.groups[1].dirs, F.groups[1].checks, F.groups[1].mask):
        n = np.cross(dirs[0], dirs[1])
        for sign in (1.0, -1.0):
            ok = [bool(checks[i, 0] @ (sign * n) >= 0.0) for i in np.flatnonzero(mask)]
            assert sum(ok) == 1          # exactly one of the two opposite facets
            assert len(maximisers(V, sign * n)) == 4


def test_clipped_polytope_with_nearly_coplanar_facets():
    """A pyramid plane almost through a box vertex makes a very short edge; Euler holds."""
    V = box(lo=(-1.0, -1.0, 0.0), hi=(1.0, 1.0, 2.0))
    cut = V[:, 0] + V[:, 2] <= 3.0 - 1e-7
    V = np.vstack([V[cut], [[1.0, -1.0, 2.0 - 1e-7], [1.0, 1.0, 2.0 - 1e-7],
                            [1.0 - 1e-7, -1.0, 2.0], [1.0 - 1e-7, 1.0, 2.0]]])
    F = polytope_faces(V)
    nv, ne, nf = len(F.vertices), F.groups[0].count, F.groups[1].count
    assert (nv, nf) == (10, 7)
    assert nv - ne + nf == 2


def test_tiny_facet_far_from_the_rest_is_kept():
    """A corner cut 0.01 N wide on a 2000 N polytope: its three vertices and facet survive."""
    V = box(lo=(-1000.0, -1000.0, 0.0), hi=(1000.0, 1000.0, 2000.0))
    corner = np.array([1000.0, 1000.0, 2000.0])
    V = np.vstack([V[np.any(V != corner, axis=1)],
                   corner - [[0.01, 0, 0], [0, 0.012, 0], [0, 0, 0.011]]])
    F = polytope_faces(V)
    hull = ConvexHull(V)
    assert len(F.vertices) == len(hull.vertices) == 10
    assert F.groups[1].count == 7
    assert len(F.vertices) - F.groups[0].count + F.groups[1].count == 2


def test_facets_from_halfspaces_match_the_point_search():
    """The H-rep path (redundant and repeated rows included) finds the same faces."""
    lo, hi = np.array([-300.0, -200.0, 0.0]), np.array([300.0, 200.0, 900.0])
    cut = np.array([0.3, 0.4, 0.866])
    cut /= np.linalg.norm(cut)
    A = np.vstack([np.eye(3), -np.eye(3), cut, cut, [[0.0, 0.0, 1.0]]])
    b = np.concatenate([hi, -lo, [700.0, 700.0, 5000.0]])   # a repeat, a redundant row
    V = box(lo, hi)
    V = V[V @ cut <= 700.0]
    for e in np.array([[x, y] for x in range(3) for y in range(3) if x < y]):
        for s0 in (lo, hi):
            for s1 in (lo, hi):
                t = np.zeros(3)
                t[e[0]], t[e[1]] = s0[e[0]], s1[e[1]]
                free = 3 - e[0] - e[1]
                t[free] = (700.0 - cut[e] @ t[e]) / cut[free]
                if lo[free] <= t[free] <= hi[free]:
                    V = np.vstack([V, t])
    F1 = polytope_faces(V)
    F2 = polytope_faces(V, (A, b))
    assert [g.count for g in F1.groups] == [g.count for g in F2.groups]
    n1 = {tuple(np.round(n, 9)) for n in F1.facet_normals}
    n2 = {tuple(np.round(n, 9)) for n in F2.facet_normals}
    assert n1 == n2 and len(n1) == 7


def test_flat_polygon_segment_point_and_empty():
    square = np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1], [0.5, 0.5, 1]], float)
    F = polytope_faces(square)
    assert F.dimension == 2 and len(F.vertices) == 4
    assert [g.count for g in F.groups] == [4, 1]
    assert F.groups[0].dirs.shape[0] == 2                    # two classes of parallel edges
    # Edge check: the in-plane outward normal.
    for dirs, checks, mask in zip(F.groups[0].dirs, F.groups[0].checks, F.groups[0].mask):
        for i in np.flatnonzero(mask):
            m = checks[i, 0]
            assert abs(m @ dirs[0]) < 1e-12 and abs(m[2]) < 1e-12
            assert len(maximisers(square[:4], m)) == 2
    seg = np.array([[0, 0, 0], [1, 2, 3], [0.5, 1, 1.5]], float)
    F = polytope_faces(seg)
    assert F.dimension == 1 and len(F.vertices) == 2
    np.testing.assert_allclose(np.abs(F.groups[0].dirs[0, 0]), np.array([1, 2, 3]) / 14 ** 0.5)
    F = polytope_faces(np.array([[1.0, 2.0, 3.0]] * 3))
    assert F.dimension == 0 and F.groups == ()
    F = polytope_faces(np.zeros((0, 3)))
    assert F.dimension == -1


def test_bad_input_raises():
    with pytest.raises(InputError, match='shape'):
        polytope_faces(np.zeros((4, 2)))
    with pytest.raises(InputError, match='finite'):
        polytope_faces(np.array([[0.0, 0.0, np.nan]]))
