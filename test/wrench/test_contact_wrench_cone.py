"""Tests of awp_ros.wrench.contact_wrench_cone: pyramids by hand, the CWC against qhull and LPs."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.spatial import ConvexHull

from awp_ros.errors import InputError
from awp_ros.wrench.contact_wrench_cone import contact_wrench_cone, friction_pyramid, lift_rays

FEET = np.array([[0.37, 0.33, -0.55], [0.37, -0.33, -0.55],
                 [-0.37, 0.33, -0.55], [-0.37, -0.33, -0.55]])
UP = np.tile([0.0, 0.0, 1.0], (4, 1))


def all_rays(positions, normals, mu, sides):
    """Lifted rays (K N, 6) from independent per-leg pyramids."""
    mu = np.broadcast_to(mu, (len(positions),))
    rays = np.stack([friction_pyramid(n, m, sides)[0] for n, m in zip(normals, mu)])
    return lift_rays(np.asarray(positions), rays).reshape(-1, 6)


def qhull_cone_facets(R: np.ndarray, basis: np.ndarray) -> np.ndarray:
    """Distinct unit normals of the facets through 0 of conv(0, rays), in hull coordinates."""
    pts = np.vstack([np.zeros(basis.shape[1]), R @ basis])
    hull = ConvexHull(pts)
    eq = hull.equations[np.abs(hull.equations[:, -1]) < 1e-10, :-1]
    return np.unique(np.round(eq, 7), axis=0)


def lp_in_cone(R: np.ndarray, w: np.ndarray) -> bool:
    """Return whether w = R^T lam, lam >= 0 (LP feasibility on the definition)."""
    res = linprog(np.zeros(R.shape[0]), A_eq=R.T, b_eq=w, bounds=(0, None), method='highs')
    return res.status == 0


def test_four_sided_pyramid_by_hand():
    mu = 0.6
    rays, facets = friction_pyramid([0.0, 0.0, 2.0], mu, 4)
    c = mu / np.sqrt(2.0)
    expected = np.array([[1, 0, -c], [0, 1, -c], [-1, 0, -c], [0, -1, -c]])
    np.testing.assert_allclose(facets, expected / np.linalg.norm(expected, axis=1)[:, None],
                               atol=1e-15)
    # Rays on the cone of mu, between facets i and i+1: |f.t1|, |f.t2| <= mu/sqrt(2) f.n.
    np.testing.assert_allclose(np.linalg.norm(rays[:, :2], axis=1) / rays[:, 2], mu)
    np.testing.assert_allclose(np.abs(rays[:, :2]) / rays[:, 2:], c)
    tight = np.abs(facets @ rays.T) < 1e-12
    for i in range(4):
        assert tight[i, i] and tight[(i + 1) % 4, i] and tight.sum(axis=0)[i] == 2


def test_pyramid_tangent_from_world_x_and_fallback_to_y():
    n = np.array([0.0, 0.6, 0.8])
    rays, facets = friction_pyramid(n, 0.5, 4)
    # t1 = x projected (here x itself), t2 = n x t1: facet 0 = (t1 - mu/sqrt2 n)/|.|.
    f0 = np.array([1.0, 0.0, 0.0]) - 0.5 / np.sqrt(2) * n
    np.testing.assert_allclose(facets[0], f0 / np.linalg.norm(f0))
    rays_x, facets_x = friction_pyramid([2.0, 0.0, 0.0], 0.5, 4)
    f0 = np.array([0.0, 1.0, 0.0]) - 0.5 / np.sqrt(2) * np.array([1.0, 0.0, 0.0])
    np.testing.assert_allclose(facets_x[0], f0 / np.linalg.norm(f0))
    # Unilaterality follows: every ray has n.f > 0, every facet cuts n.f < 0 off.
    assert np.all(rays @ n > 0)


@pytest.mark.parametrize('sides', [3, 5, 8])
def test_pyramid_is_inscribed_in_the_cone(sides):
    rays, facets = friction_pyramid([0.1, -0.2, 1.0], 0.7, sides)
    n = np.array([0.1, -0.2, 1.0]) / np.linalg.norm([0.1, -0.2, 1.0])
    cos_half = 1.0 / np.sqrt(1.0 + 0.7 ** 2)
    np.testing.assert_allclose(rays @ n, cos_half)
    assert np.max(facets @ rays.T) < 1e-12


def test_frictionless_pyramid_is_the_normal():
    rays, _ = friction_pyramid([0.0, 0.0, 1.0], 0.0, 4)
    np.testing.assert_allclose(rays, np.tile([0.0, 0.0, 1.0], (4, 1)))


CASES = {
    'flat_4': (FEET, UP, 0.7, 4),
    'flat_jitter_4': (FEET + np.random.default_rng(0).normal(size=(4, 3)) * 0.03, UP, 0.7, 4),
    'terrain_4': (FEET, UP + np.random.default_rng(1).normal(size=(4, 3)) * 0.3,
                  [0.3, 0.5, 0.8, 1.0], 4),
    'flat_3': (FEET[:3], UP[:3], 0.5, 4),
    'wall_3': (FEET[:3], np.array([[0, 0, 1.0], [0, 1.0, 0.2], [-1.0, 0, 0.3]]), 0.6, 4),
    'two_legs': (FEET[1:3], UP[1:3], 0.7, 4),
    'one_leg': (FEET[:1], UP[:1], 0.7, 4),
    'hexagons_3': (FEET[:3], UP[:3], 0.6, 6),
    'triangles_4': (FEET, UP, 0.6, 3),
    'collinear_3': (np.array([[0.3, 0.0, -0.5], [0.0, 0.0, -0.5], [-0.3, 0.0, -0.5]]),
                    UP[:3], 0.7, 4),
    'frictionless_4': (FEET, UP, 0.0, 4),
    'one_frictionless': (FEET, UP, [0.7, 0.0, 0.7, 0.7], 4),
    'opposing_walls_2': (np.array([[0.3, 0.2, 0.0], [-0.3, 0.1, 0.0]]),
                         np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]), 0.5, 4),
}


@pytest.mark.parametrize('case', sorted(CASES))
def test_cwc_facets_match_qhull_and_rays(case):
    positions, normals, mu, sides = CASES[case]
    C = contact_wrench_cone(positions, normals, mu, sides)
    R = all_rays(positions, normals, mu, sides)
    r = np.linalg.matrix_rank(R, tol=1e-9)
    assert C.dimension == r
    assert np.all(C.b == 0.0) and C.meta['kind'] == 'cone'
    np.testing.assert_allclose(np.linalg.norm(C.A, axis=1), 1.0)
    # Every generator ray satisfies every row; every row is tight on r - 1 independent rays.
    Ru = R / np.linalg.norm(R, axis=1)[:, None]
    S = C.A @ Ru.T
    assert np.max(S, initial=0.0) < 1e-9
    for row in S:
        assert np.linalg.matrix_rank(Ru[np.abs(row) < 1e-9], tol=1e-7) == r - 1
    # Same facets as qhull on the truncated cone, in hull coordinates.
    if r >= 2:
        facets = qhull_cone_facets(Ru, C.hull_basis)
        ours = C.A @ C.hull_basis
        assert ours.shape[0] == facets.shape[0]
        d = np.max(np.abs(ours[:, None, :] - facets[None, :, :]), axis=2)
        assert np.all(d.min(axis=1, initial=1.0) < 1e-6)
        assert np.all(d.min(axis=0, initial=1.0) < 1e-6)
    if C.A.shape[0] == 0:
        # No facet: the cone is its whole span (squeezing with friction), check by LP.
        w = np.random.default_rng(2).normal(size=(5, r)) @ C.hull_basis.T * 100
        assert all(lp_in_cone(R, x) for x in w)


@pytest.mark.parametrize('case', ['flat_jitter_4', 'terrain_4', 'two_legs', 'collinear_3'])
def test_cwc_membership_matches_lp(case):
    positions, normals, mu, sides = CASES[case]
    C = contact_wrench_cone(positions, normals, mu, sides)
    R = all_rays(positions, normals, mu, sides)
    rng = np.random.default_rng(3)
    # Points of the hull: inside-ish (positive combinations) perturbed within the hull.
    inside = rng.exponential(size=(15, R.shape[0])) @ R
    noise = rng.normal(size=(15, C.dimension)) @ C.hull_basis.T * 300
    outcomes = []
    for w in np.vstack([inside + noise, inside]):
        ours = C.contains(w, tol=1e-7)
        margin = np.min(-C.A @ w)
        if abs(margin) < 1e-6:
            continue
        assert ours == lp_in_cone(R, w)
        outcomes.append(ours)
    assert any(outcomes) and not all(outcomes)


def test_no_legs_is_the_origin():
    C = contact_wrench_cone(np.zeros((0, 3)), np.zeros((0, 3)), 0.5)
    assert C.dimension == 0 and C.contains(np.zeros(6)) and not C.contains(np.ones(6))


def test_bad_input_raises():
    with pytest.raises(InputError, match='normal 1'):
        contact_wrench_cone(FEET[:2], np.array([[0, 0, 1.0], [0, 0, 0]]), 0.5)
    with pytest.raises(InputError, match='friction coefficient 0'):
        contact_wrench_cone(FEET[:2], UP[:2], [-0.1, 0.5])
    with pytest.raises(InputError, match='sides'):
        contact_wrench_cone(FEET[:2], UP[:2], 0.5, sides=2)
    with pytest.raises(InputError, match='positions'):
        contact_wrench_cone(FEET[:2], UP[:3], 0.5)


# -- tilted per-foot normals and mu, N sides: against an LP on the definition -------------


def definition_rows(n, mu, sides):
    """Rows ``a . f <= 0`` of the N-sided pyramid, written from eq. (1) (not the module)."""
    n = np.asarray(n, dtype=float) / np.linalg.norm(n)
    t1 = np.array([1.0, 0.0, 0.0]) - n[0] * n
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(n, t1)
    th = 2 * np.pi * np.arange(sides) / sides
    return np.cos(th)[:, None] * t1 + np.sin(th)[:, None] * t2 - mu * np.cos(np.pi / sides) * n


def lp_in_cwc(positions, normals, mus, sides, w) -> bool:
    """Return whether w = sum_k L_k f_k with every f_k in its pyramid (LP feasibility)."""
    K = len(positions)
    A = np.zeros((K * sides, 3 * K))
    for k in range(K):
        A[k * sides:(k + 1) * sides, 3 * k:3 * k + 3] = definition_rows(normals[k], mus[k],
                                                                        sides)
    L = np.hstack([np.vstack([np.eye(3), np.cross(p, np.eye(3)).T]) for p in positions])
    res = linprog(np.zeros(3 * K), A_ub=A, b_ub=np.zeros(len(A)), A_eq=L, b_eq=w,
                  bounds=[(None, None)] * 3 * K, method='highs')
    return res.status == 0


TILTED = np.array([[0.3, 0.0, 1.0], [0.0, -0.35, 1.0], [0.25, 0.25, 1.0], [-0.2, 0.1, 1.0]])
MUS = np.array([0.4, 1.0, 0.55, 0.8])


@pytest.mark.parametrize('sides', [3, 4, 6, 8])
@pytest.mark.parametrize('K', [2, 4])
def test_tilted_per_foot_cwc_membership_matches_lp_on_the_definition(sides, K):
    positions, normals, mus = FEET[:K], TILTED[:K], MUS[:K]
    C = contact_wrench_cone(positions, normals, mus, sides)
    assert C.dimension == (6 if K == 4 else 5)
    rng = np.random.default_rng(10 * K + sides)
    # Wrenches near the cone's boundary: sums of lifted forces drawn around the pyramids
    # (some inside, some outside), moved within the cone's span.
    outcomes = []
    for _ in range(60):
        w = np.zeros(6)
        for p, n, mu in zip(positions, normals, mus):
            n = n / np.linalg.norm(n)
            h = rng.uniform(50.0, 200.0)
            tangent = rng.normal(size=3)
            tangent -= (tangent @ n) * n
            tangent *= rng.uniform(0.0, 1.3) * mu * h / np.linalg.norm(tangent)
            f = h * n + tangent
            w += np.concatenate([f, np.cross(p, f)])
        u = C.hull_basis @ rng.normal(size=C.dimension)
        w += u / np.linalg.norm(u) * rng.uniform(0.0, 0.4) * np.linalg.norm(w)
        if np.min(np.abs(C.A @ w)) < 1e-6 * np.linalg.norm(w):
            continue
        ours = bool(np.all(C.A @ w <= 0.0))
        assert ours == lp_in_cwc(positions, normals, mus, sides, w)
        outcomes.append(ours)
    assert 5 <= sum(outcomes) <= len(outcomes) - 5
    # Every row is valid on the definition's cone (no lifted pyramid edge beyond it) and
    # supports it (an edge on it).
    R = np.vstack([np.concatenate([r, np.cross(p, r)])
                   for p, n, mu in zip(positions, normals, mus)
                   for r in pyramid_rays(n, mu, sides)])
    R /= np.linalg.norm(R, axis=1)[:, None]
    top = np.max(R @ C.A.T, axis=0)
    assert np.all(top <= 1e-9) and np.all(top >= -1e-9)


def pyramid_rays(n, mu, sides):
    """Edges of the pyramid: intersections of adjacent facets of ``definition_rows``."""
    rows = definition_rows(n, mu, sides)
    n = np.asarray(n, dtype=float) / np.linalg.norm(n)
    rays = np.cross(rows, np.roll(rows, -1, axis=0))
    return rays * np.sign(rays @ n)[:, None]
