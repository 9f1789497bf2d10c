"""Tests of awp_ros.wrench.friction_polytope against the definition, LPs and qhull."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.spatial import HalfspaceIntersection

from awp_ros.wrench.force_polytope import force_polytope
from awp_ros.wrench.friction_polytope import (friction_halfspaces, friction_polytope,
                                              friction_polytopes, friction_rows, FrictionPolytopes,
                                              inside_force)

RNG_SEED = 11


def pyramid_rows(n, mu, sides):
    """Return the pyramid rows of the common definition, written out independently."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    x = np.array([1.0, 0.0, 0.0])
    if np.linalg.norm(x - (x @ n) * n) < 1e-9:
        x = np.array([0.0, 1.0, 0.0])
    t1 = x - (x @ n) * n
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(n, t1)
    th = 2 * np.pi * np.arange(sides) / sides
    rows = np.cos(th)[:, None] * t1 + np.sin(th)[:, None] * t2 \
        - mu * np.cos(np.pi / sides) * n
    return np.vstack([rows, -n])


def reference_halfspaces(J, bias, lo, hi, n, mu, sides):
    A = np.vstack([J.T, -J.T, pyramid_rows(n, mu, sides)])
    b = np.concatenate([bias - lo, hi - bias, np.zeros(sides + 1)])
    return A, b


def qhull_vertices(A, b):
    """Vertices by qhull's halfspace intersection around the LP Chebyshev centre."""
    norms = np.linalg.norm(A, axis=1)
    res = linprog(np.r_[0, 0, 0, -1.0], A_ub=np.hstack([A, norms[:, None]]), b_ub=b,
                  bounds=[(None, None)] * 3 + [(0, None)], method='highs')
    assert res.status == 0 and res.x[3] > 1e-6
    hs = HalfspaceIntersection(np.hstack([A, -b[:, None]]), res.x[:3])
    V = hs.intersections
    keep = np.ones(len(V), bool)
    for i in range(len(V)):
        if keep[i]:
            close = np.linalg.norm(V - V[i], axis=1) < 1e-7 * max(1, np.abs(V).max())
            close[: i + 1] = False
            keep &= ~close
    return V[keep]


def same_rows(X, Y, atol):
    if X.shape != Y.shape:
        return False
    if X.size == 0:
        return True
    D = np.linalg.norm(X[:, None, :] - Y[None, :, :], axis=2)
    return bool(np.all(D.min(axis=1) <= atol) and np.all(D.min(axis=0) <= atol))


def random_leg(rng):
    J = rng.normal(size=(3, 3)) * 0.3
    bias = rng.normal(size=3) * 5
    return J, bias, -np.full(3, 60.0), np.full(3, 60.0)


def test_pyramid_rows_match_the_common_definition():
    for n, mu, sides in [([0, 0, 1], 0.7, 4), ([0.3, -0.2, 1.0], 0.5, 6), ([1, 0, 0], 1.2, 3)]:
        n = np.asarray(n, float) / np.linalg.norm(n)
        mine = friction_halfspaces(n, mu, sides)
        ref = pyramid_rows(n, mu, sides)
        ref /= np.linalg.norm(ref, axis=1)[:, None]
        assert same_rows(mine, ref, 1e-12)
    # Four sides: |f.t1|, |f.t2| <= mu / sqrt(2) f.n with t1 = x, t2 = y for a level floor.
    rows = friction_halfspaces(np.array([0.0, 0, 1]), 0.7, 4)
    f_edge = np.array([0.7 / np.sqrt(2), 0.7 / np.sqrt(2), 1.0])
    assert np.max(rows @ f_edge) == pytest.approx(0.0, abs=1e-12)


def test_vertices_match_qhull_and_satisfy_torques_and_friction():
    rng = np.random.default_rng(RNG_SEED)
    checked = 0
    while checked < 10:
        J, bias, lo, hi = random_leg(rng)
        n = np.array([0.0, 0.0, 1.0]) + 0.3 * rng.normal(size=3)
        n /= np.linalg.norm(n)
        mu, sides = rng.uniform(0.3, 1.0), int(rng.integers(3, 8))
        F = force_polytope(J, bias, lo, hi)
        Q = friction_polytope(F, n, mu, sides)
        A, b = reference_halfspaces(J, bias, lo, hi, n, mu, sides)
        res = linprog(np.r_[0, 0, 0, -1.0],
                      A_ub=np.hstack([A, np.linalg.norm(A, axis=1)[:, None]]), b_ub=b,
                      bounds=[(None, None)] * 3 + [(0, 1e6)], method='highs')
        if res.x[3] < 1e-3:
            continue     # flat or empty: covered by the dedicated tests
        checked += 1
        assert Q.dimension == 3
        assert same_rows(Q.vertices, qhull_vertices(A, b), 1e-6 * max(1, np.abs(b).max()))
        tau = bias - Q.vertices @ J
        assert np.all(tau >= lo - 1e-7) and np.all(tau <= hi + 1e-7)
        assert np.all(pyramid_rows(n, mu, sides) @ Q.vertices.T <= 1e-7)
        # Support function = LP on the definition; every H-rep row is tight on a facet.
        for c in rng.normal(size=(10, 3)):
            lp = linprog(-c, A_ub=A, b_ub=b, bounds=[(None, None)] * 3, method='highs')
            assert np.max(Q.vertices @ c) == pytest.approx(-lp.fun, rel=1e-8, abs=1e-7)
        assert np.all(np.sum(np.abs(Q.vertices @ Q.A.T - Q.b) < 1e-7, axis=0) >= 3)


def test_leg_that_cannot_push_gives_the_empty_set():
    # f_z <= (bias_z - lo_z) / 0.3 < 0: the leg cannot press on the ground.
    J = np.diag([0.5, 0.4, 0.3])
    F = force_polytope(J, np.array([0.0, 0.0, -40.0]), -np.full(3, 30.0), np.full(3, 30.0))
    Q = friction_polytope(F, np.array([0, 0, 1.0]), 0.7, 4)
    assert Q.is_empty and Q.dimension == -1


def test_force_polytope_touching_the_ground_plane_gives_a_flat_set():
    # f_z in [0, 200]... but the polytope's floor f_z >= 0 with |f_x|, |f_y| > 0 touches the
    # pyramid only at the apex -> the single point 0 when f_z <= 0 is the top face.
    J = np.diag([0.5, 0.4, 0.3])
    F = force_polytope(J, np.array([0.0, 0.0, -30.0]), -np.full(3, 30.0), np.full(3, 30.0))
    np.testing.assert_allclose(F.vertices[:, 2].max(), 0.0, atol=1e-12)
    Q = friction_polytope(F, np.array([0, 0, 1.0]), 0.7, 4)
    assert Q.dimension == 0
    np.testing.assert_allclose(Q.vertices, np.zeros((1, 3)), atol=1e-9)


def test_singular_leg_flat_polytope_is_cut_within_its_plane():
    J = np.array([[0.5, 0.0, 0.2], [0.0, 0.0, 0.0], [0.0, 0.3, 0.1]])   # f_y unconstrained
    F = force_polytope(J, np.array([0.0, 3.0, 1.0]), -np.full(3, 20.0), np.full(3, 20.0))
    assert F.meta['singular'] and F.dimension == 2
    Q = friction_polytope(F, np.array([0, 0, 1.0]), 0.7, 4)
    assert Q.dimension == 2
    np.testing.assert_allclose(Q.vertices[:, 1], 0.0, atol=1e-9)      # stays in the plane
    assert np.all(F.A @ Q.vertices.T <= F.b[:, None] + 1e-9)
    assert np.all(pyramid_rows([0, 0, 1], 0.7, 4) @ Q.vertices.T <= 1e-9)
    # Against the definition: the plane's polygon ∩ pyramid, by brute force on a grid.
    xs, zs = np.meshgrid(np.linspace(-200, 200, 161), np.linspace(-200, 200, 161))
    pts = np.column_stack([xs.ravel(), np.zeros(xs.size), zs.ravel()])
    inside = np.all(F.A @ pts.T <= F.b[:, None], axis=0) \
        & np.all(pyramid_rows([0, 0, 1], 0.7, 4) @ pts.T <= 0, axis=0)
    assert np.all(Q.A @ pts[inside].T <= Q.b[:, None] + 1e-9)


def test_batched_legs_equal_the_one_leg_path_including_degenerate_legs():
    rng = np.random.default_rng(RNG_SEED + 1)
    J = np.diag([0.5, 0.4, 0.3])
    forces = [force_polytope(*random_leg(rng)) for _ in range(4)]
    forces.append(force_polytope(J, np.array([0.0, 0.0, -40.0]), -np.full(3, 30.0),
                                 np.full(3, 30.0)))               # empty
    forces.append(force_polytope(J, np.array([0.0, 0.0, -30.0]), -np.full(3, 30.0),
                                 np.full(3, 30.0)))               # the apex only
    forces.append(force_polytope(np.array([[0.5, 0.0, 0.2], [0.0, 0.0, 0.0],
                                           [0.0, 0.3, 0.1]]), np.array([0.0, 3.0, 1.0]),
                                 -np.full(3, 20.0), np.full(3, 20.0)))   # singular, flat
    K = len(forces)
    normals = np.array([0.0, 0.0, 1.0]) + 0.2 * rng.normal(size=(K, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    normals[4:] = [0.0, 0.0, 1.0]
    mus = rng.uniform(0.4, 1.0, K)
    batch = friction_polytopes(forces, friction_rows(normals, mus, 5))
    for F, n, mu, Q in zip(forces, normals, mus, batch):
        ref = friction_polytope(F, n, mu, 5)
        assert Q.dimension == ref.dimension
        assert same_rows(Q.vertices, ref.vertices, 1e-9)
        assert same_rows(Q.halfspaces(), ref.halfspaces(), 1e-9)
    assert [Q.dimension for Q in batch[4:]] == [-1, 0, 2]


@pytest.mark.parametrize('seed', range(4))
def test_batched_kernel_equals_the_numpy_batch(seed):
    """The compiled vertex enumeration gives the numpy batch's vertices, in its order."""
    from awp_ros.geometry import kernels
    rng = np.random.default_rng(seed)
    K = 6
    forces = [force_polytope(*random_leg(rng)) for _ in range(K)]
    normals = np.array([0.0, 0.0, 1.0]) + 0.3 * rng.normal(size=(K, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    rows = friction_rows(normals, rng.uniform(0.3, 1.2, K), 4 + seed % 3)
    got = friction_polytopes(forces, rows)
    kernels.ENABLED = False
    try:
        ref = friction_polytopes(forces, rows)
    finally:
        kernels.ENABLED = True
    assert [Q.dimension for Q in got] == [Q.dimension for Q in ref]
    for Q, R in zip(got, ref):
        np.testing.assert_allclose(Q.vertices, R.vertices, rtol=1e-12, atol=1e-9)
        np.testing.assert_array_equal(Q.A, R.A)
        np.testing.assert_array_equal(Q.b, R.b)


def test_frictionless_contact_keeps_the_unilateral_row_in_the_batch():
    # mu = 0: the pyramid facets leave the normal line; n . f >= 0 must cut it in half.
    J = np.diag([0.5, 0.4, 0.3])
    F = force_polytope(J, np.array([0.0, 0.0, 2.0]), -np.full(3, 30.0), np.full(3, 30.0))
    n = np.array([0.0, 0.0, 1.0])
    rows = friction_rows(n[None], np.array([0.0]), 4)
    Q = friction_polytopes([F], rows)[0]
    assert Q.dimension == 1
    np.testing.assert_allclose(np.sort(Q.vertices[:, 2]), [0.0, (2.0 + 30.0) / 0.3])
    np.testing.assert_allclose(Q.vertices[:, :2], 0.0, atol=1e-9)


def feasible_by_lp(F, rows):
    """Return whether force polytope ∩ {rows . f <= 0} is non-empty, by an LP (HiGHS)."""
    E, e = F.equalities
    lp = linprog(np.zeros(3), A_ub=np.vstack([F.A, rows]),
                 b_ub=np.concatenate([F.b, np.zeros(rows.shape[0])]),
                 A_eq=E if E.size else None, b_eq=e if E.size else None,
                 bounds=[(None, None)] * 3, method='highs')
    return lp.status == 0


def vertex_in_pyramid(forces, rows, margin=1e-6):
    """Return, per leg, whether a vertex is strictly inside the pyramid (brute force)."""
    return np.array([any(np.all(rows[k] @ v < -margin) for v in F.vertices)
                     for k, F in enumerate(forces)])


def test_inside_force_proves_non_emptiness_and_the_lazy_batch_is_the_batch():
    # Legs pushing well, pushing a little, not at all, and sideways: the test may
    # only say True where an LP finds the friction-bounded set non-empty, and the lazily
    # computed batch is the eager one.
    rng = np.random.default_rng(RNG_SEED + 2)
    J = np.diag([0.5, 0.4, 0.3])
    forces = [force_polytope(*random_leg(rng)) for _ in range(30)]
    forces += [force_polytope(J, np.array([0.0, 0.0, bz]), -np.full(3, 30.0),
                              np.full(3, 30.0)) for bz in (-40.0, -31.0, -29.0, 0.0)]
    # A slab across the pyramid, off its axis (f_y in [40, 41]), its corners outside it
    # (|f_x| = 200): non-empty, but neither a vertex nor the axis shows it.
    forces.append(force_polytope(np.eye(3), np.array([0.0, 40.5, 50.5]),
                                 np.array([-200.0, -0.5, -0.5]), np.array([200.0, 0.5, 0.5])))
    K = len(forces)
    normals = np.array([0.0, 0.0, 1.0]) + rng.uniform(0.0, 1.5, size=(K, 3)) \
        * rng.choice([-1.0, 1.0], size=(K, 3))
    normals[-5:] = [0.0, 0.0, 1.0]
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    mus = rng.uniform(0.2, 1.0, K)
    mus[-5:] = 1.2                  # the last box's top vertices (+-60, +-75, 100) are inside
    rows = friction_rows(normals, mus, 4)
    inside = inside_force(forces, rows)
    lp = np.array([feasible_by_lp(F, rows[k]) for k, F in enumerate(forces)])
    eager = friction_polytopes(forces, rows)
    lazy = FrictionPolytopes(forces, rows)
    assert not lazy.computed and len(lazy) == K
    for k in range(K):
        assert lazy[k] is not None and lazy.computed
        assert lazy[k].dimension == eager[k].dimension
        assert same_rows(lazy[k].vertices, eager[k].vertices, 1e-9)
        assert eager[k].is_empty == (not lp[k])
    assert np.all(lp[inside])                                # True proves non-empty
    assert inside.any() and (~lp).any()                      # both kinds were drawn
    assert (lp[:-5] & inside[:-5]).sum() > (lp[:-5] & inside[:-5]
                                            & vertex_in_pyramid(forces[:-5], rows[:-5])).sum()
    assert lp[-1] and not inside[-1]   # the slab: the fallback (1) decides
    assert inside[-2] and not inside[-5] and not lp[-5]
