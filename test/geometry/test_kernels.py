"""The compiled kernels against their numpy reference and against the definitions."""

from itertools import combinations

import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.spatial import ConvexHull

from awp_ros.geometry import kernels
from awp_ros.geometry.linalg import subset_cross_products, subset_tree
from awp_ros.geometry.zonotope import _combinations, _facets as zonotope_reference, zonotope
from awp_ros.wrench import contact_wrench_cone as cwc_module
from awp_ros.wrench.contact_wrench_cone import (_cached_rays, _candidates, contact_wrench_cone,
                                                lift_rays)

pytestmark = pytest.mark.skipif(not kernels.ENABLED, reason='numba kernels disabled')


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_cross_products_equal_the_numpy_reference_and_are_orthogonal(seed):
    d = 6
    rng = np.random.default_rng(seed)
    V = rng.normal(size=(d, d + 4))
    S = np.array(list(combinations(range(d + 4), d - 1)), dtype=np.int64)
    n = kernels.cross_products(V, S)
    ref = subset_cross_products(V / np.linalg.norm(V, axis=0), subset_tree(S), unit=True)
    scaled = kernels.cross_products(V / np.linalg.norm(V, axis=0), S)
    np.testing.assert_allclose(scaled, ref, atol=1e-13)
    # the definition: n_i = (-1)^i det V_{-i, S}, orthogonal to each vector of the subset
    for s in range(0, len(S), max(1, len(S) // 7)):
        M = V[:, S[s]]
        det = [(-1) ** i * np.linalg.det(np.delete(M, i, axis=0)) for i in range(d)]
        np.testing.assert_allclose(n[s], det, atol=1e-10)
        np.testing.assert_allclose(M.T @ n[s], 0.0, atol=1e-10)


def test_unrolled_wedges_are_the_tables():
    """Every line of the unrolled R^6 wedge is the Laplace expansion of ``wedge_tables(6)``."""
    import inspect
    src, row, sign, _ = kernels.wedge_tables(6)
    code = inspect.getsource(kernels._wedge6.py_func)
    lines = {line.strip() for line in code.splitlines()}
    count = 0
    for k, outputs in ((1, 15), (2, 20), (3, 15), (4, 6)):
        for o in range(outputs):
            terms = [(sign[k, o, t], f'W[{k - 1}, {src[k, o, t]}] * v{row[k, o, t]}')
                     for t in range(k + 1)]
            expr = ('-' if terms[0][0] < 0 else '') + terms[0][1]
            for sg, term in terms[1:]:
                expr += f' {"-" if sg < 0 else "+"} {term}'
            assert f'W[{k}, {o}] = {expr}' in lines, (k, o, expr)
            count += 1
    assert count == 56 and sum(line.startswith('W[') for line in lines) == 56


def _awp_generators(rng, K=4):
    """Lifted parallelepiped generators of K legs: the AWP's structure (shared 5D spans)."""
    p = rng.normal(size=(K, 3)) * 0.3
    p[:, 2] = -0.5 + 0.02 * rng.normal(size=K)
    cols = []
    for k in range(K):
        for u in rng.normal(size=(3, 3)) * 100.0:
            cols.append(np.concatenate([u, np.cross(p[k], u)]))
    return np.array(cols).T


@pytest.mark.parametrize('seed', range(6))
def test_zonotope_facets_equal_the_numpy_reference(seed):
    rng = np.random.default_rng(seed)
    G = _awp_generators(rng) if seed % 2 else rng.normal(size=(6, 9))
    if seed == 4:                       # parallel and repeated generators
        G = np.concatenate([G, 2.0 * G[:, :2]], axis=1)
    norms = np.linalg.norm(G, axis=0)
    subsets, tree = _combinations(G.shape[1], 5)
    a, h = kernels.zonotope_facets(G, norms, subsets, 1e-9, 1e-9)
    a_ref, h_ref, _ = zonotope_reference(G, norms, subsets, tree, 6, 1e-9, 1e-9, False)
    assert a.shape == a_ref.shape
    np.testing.assert_allclose(a, a_ref, atol=1e-12)
    np.testing.assert_allclose(h, h_ref, rtol=1e-12, atol=1e-9)


def test_zonotope_h_rep_matches_qhull_of_its_vertices():
    rng = np.random.default_rng(7)
    G = _awp_generators(rng, K=2)[:, :5]
    G = np.concatenate([G, rng.normal(size=(6, 2)) * 50.0], axis=1)      # 7 in R^6
    c = rng.normal(size=6)
    Z = zonotope(c, G)
    signs = np.array(np.meshgrid(*[[-1.0, 1.0]] * G.shape[1])).reshape(G.shape[1], -1)
    hull = ConvexHull((c[:, None] + G @ signs).T)
    # every qhull facet is a row of Z (same unit normal and offset), and no extra rows
    eq = hull.equations / np.linalg.norm(hull.equations[:, :6], axis=1)[:, None]
    for row in np.unique(np.round(eq, 6), axis=0):
        d = np.abs(Z.A - row[:6]).max(axis=1) + np.abs(Z.b + row[6]) / max(1.0, abs(row[6]))
        assert d.min() < 1e-5
    assert Z.A.shape[0] == np.unique(np.round(eq, 6), axis=0).shape[0]


def _cwc_rays(rng, K=4, sides=4, tilt=0.0):
    n = np.tile([0.0, 0.0, 1.0], (K, 1)) + tilt * rng.normal(size=(K, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    mu = rng.uniform(0.3, 1.0, size=K)
    p = rng.normal(size=(K, 3)) * 0.3
    p[:, 2] = -0.5
    return p, n, mu


@pytest.mark.parametrize('seed,K,sides,tilt', [(0, 4, 4, 0.0), (1, 4, 4, 0.2), (2, 3, 6, 0.1),
                                               (3, 4, 3, 0.0), (4, 3, 4, 0.0)])
def test_cone_facets_equal_the_numpy_reference(seed, K, sides, tilt):
    rng = np.random.default_rng(seed)
    p, n, mu = _cwc_rays(rng, K, sides, tilt)
    rays = _cached_rays(np.ascontiguousarray(n).tobytes(), mu.tobytes(), sides)
    lifted = lift_rays(p, rays).reshape(K * sides, 6)
    lifted /= np.linalg.norm(lifted, axis=1)[:, None]
    r = 6
    assert np.linalg.matrix_rank(lifted) == 6
    subsets, tree = _candidates(K, sides, r, (False,) * K)
    A, spans, masks = kernels.cone_facets(lifted, subsets, 1e-9, 1e-9)
    ref = cwc_module._facets(lifted, tree, r, 1e-9, 1e-9)
    assert A.shape == ref.shape and A.shape[0] > 0
    np.testing.assert_allclose(A, ref, atol=1e-12)
    # the certificate: spans lie on their facets, masks are exactly the rays on them
    assert np.all(np.abs(lifted @ A.T) <= 1e-9 + (lifted @ A.T <= 1e-9) * np.inf)
    for k in range(A.shape[0]):
        on = np.flatnonzero(np.abs(lifted @ A[k]) <= 1e-9)
        assert set(spans[k]) <= set(on.tolist())
        assert masks[k] == sum(1 << int(j) for j in on)


def _same_rows(A, B, tol=1e-9):
    """Return whether A and B hold the same rows (any order) up to ``tol``."""
    D = np.abs(A[:, None, :] - B[None, :, :]).max(axis=2)
    return A.shape == B.shape and D.min(axis=1).max() <= tol and D.min(axis=0).max() <= tol


def _lifted_cwc_rays(p, n, mu, sides):
    rays = _cached_rays(np.ascontiguousarray(n).tobytes(), mu.tobytes(), sides)
    lifted = lift_rays(p, rays).reshape(len(p) * sides, 6)
    return lifted / np.linalg.norm(lifted, axis=1)[:, None]


@pytest.mark.parametrize('seed', range(8))
@pytest.mark.parametrize('K,sides', [(3, 4), (4, 4), (4, 3), (3, 6), (5, 4)])
def test_cone_double_description_equals_the_candidate_search(seed, K, sides):
    """Same facets, masks and valid spans as every candidate subset; flat-ground cases too."""
    rng = np.random.default_rng(100 * seed + 10 * K + sides)
    p, n, mu = _cwc_rays(rng, K, sides, tilt=(0.0, 0.2, 0.05, 0.0)[seed % 4])
    if seed % 4 == 3:                      # flat ground, one mu: friction planes shared
        mu[:] = 0.7
    lifted = _lifted_cwc_rays(p, n, mu, sides)
    subsets, _ = _candidates(K, sides, 6, (False,) * K)
    A, spans, masks = kernels.cone_facets(lifted, subsets, 1e-9, 1e-9)
    found = kernels.cone_double_description(lifted, 1e-9, 1e-9)
    assert found is not None
    A2, spans2, masks2 = found
    assert _same_rows(A2, A, tol=1e-9)
    assert sorted(masks2.tolist()) == sorted(masks.tolist())
    s = lifted @ A2.T
    assert s.max() <= 1e-9
    for k in range(A2.shape[0]):
        on = np.flatnonzero(np.abs(s[:, k]) <= 1e-9)
        assert masks2[k] == sum(1 << int(j) for j in on)
        assert set(spans2[k]) <= set(on.tolist())
        assert np.linalg.matrix_rank(lifted[spans2[k]], tol=1e-7) == 5


def test_cone_double_description_matches_qhull():
    """The facets through the apex of conv(0, rays) by qhull, an independent hull."""
    for seed in range(5):
        rng = np.random.default_rng(seed)
        p, n, mu = _cwc_rays(rng, 4, 4, tilt=0.1)
        lifted = _lifted_cwc_rays(p, n, mu, 4)
        A, _, _ = kernels.cone_double_description(lifted, 1e-9, 1e-9)
        hull = ConvexHull(np.vstack([np.zeros(6), lifted]))
        eq = hull.equations[np.abs(hull.equations[:, -1]) < 1e-10, :-1]
        ref = np.unique(np.round(eq / np.linalg.norm(eq, axis=1)[:, None], 7), axis=0)
        assert _same_rows(np.round(A, 7), ref, tol=2e-7)


def test_cone_double_description_refuses_rays_short_of_full_rank():
    rng = np.random.default_rng(3)
    flat = rng.normal(size=(12, 6))
    flat[:, 5] = 0.0
    flat /= np.linalg.norm(flat, axis=1)[:, None]
    assert kernels.cone_double_description(flat, 1e-9, 1e-9) is None


def test_cone_recheck_takes_the_spans_of_the_double_description():
    """Along a walk, the recheck of its facets equals a full search, as often as the search's."""
    rng = np.random.default_rng(12)
    p, n, mu = _cwc_rays(rng)
    subsets, _ = _candidates(4, 4, 6, (False,) * 4)
    reused = {'search': 0, 'double description': 0}
    last = {}
    for _ in range(200):
        p = p + 0.004 * rng.normal(size=p.shape)
        lifted = _lifted_cwc_rays(p, n, mu, 4)
        full, spans, masks = kernels.cone_facets(lifted, subsets, 1e-9, 1e-9)
        for name, (s, m) in last.items():
            again = kernels.cone_recheck(lifted, s, m, 1e-9, 1e-9)
            if again is not None:
                reused[name] += 1
                assert _same_rows(again, full)
        A, spans2, masks2 = kernels.cone_double_description(lifted, 1e-9, 1e-9)
        assert _same_rows(A, full)
        last = {'search': (spans, masks), 'double description': (spans2, masks2)}
    assert reused['double description'] == reused['search'] > 20


def test_cone_recheck_equals_full_computation_along_a_random_walk():
    """The reused facets equal a full search at every step; structure changes are caught."""
    rng = np.random.default_rng(11)
    p, n, mu = _cwc_rays(rng)
    reused = rebuilt = 0
    last = None
    for step in range(600):
        p = p + 0.004 * rng.normal(size=p.shape)
        p[:, 2] = np.clip(p[:, 2], -0.7, -0.3)
        rays = _cached_rays(np.ascontiguousarray(n).tobytes(), mu.tobytes(), 4)
        lifted = lift_rays(p, rays).reshape(16, 6)
        lifted /= np.linalg.norm(lifted, axis=1)[:, None]
        subsets, _ = _candidates(4, 4, 6, (False,) * 4)
        full, spans, masks = kernels.cone_facets(lifted, subsets, 1e-9, 1e-9)
        if last is not None:
            again = kernels.cone_recheck(lifted, last[1], last[2], 1e-9, 1e-9)
            if again is None:
                rebuilt += 1
            else:
                reused += 1
                assert again.shape == full.shape
                assert _same_rows(again, full)
        last = (full, spans, masks)
    assert reused > 400 and rebuilt > 0       # mostly reused, and changes were detected


@pytest.mark.parametrize('seed', range(4))
def test_flat_sets_equal_the_numpy_code(seed):
    """
    Two stance legs span a 5D cone and AWP (one leg: 3D): the flat kernels, same rows.

    Two legs' hull basis is the closed-form one (not the SVD's): the same rows, in another
    order and sign (the orientation of the basis), and the same hull.
    """
    from awp_ros.wrench.wrench_polytope import actuation_wrench_polytope
    rng = np.random.default_rng(seed)
    for K, dim in ((2, 5), (1, 3)):
        p, n, mu = _cwc_rays(rng, K=K, tilt=0.1 * seed)
        fast = contact_wrench_cone(p, n, mu, 4 + seed % 2)
        slow = _numpy(contact_wrench_cone, p, n, mu, 4 + seed % 2)
        assert fast.dimension == slow.dimension == dim
        C, H = rng.normal(size=(K, 3)) * 50.0, rng.normal(size=(K, 3, 3)) * 100.0
        fast_awp = actuation_wrench_polytope(p, C, H)
        slow_awp = _numpy(actuation_wrench_polytope, p, C, H)
        assert fast_awp.dimension == slow_awp.dimension == (5 if K == 2 else 3)
        if K == 2:
            _same_hrep(fast, slow)
            _same_hrep(fast_awp, slow_awp)
            continue
        np.testing.assert_allclose(fast.A, slow.A, atol=1e-12)
        np.testing.assert_allclose(fast_awp.A, slow_awp.A, atol=1e-12)
        np.testing.assert_allclose(fast_awp.b, slow_awp.b, rtol=1e-12, atol=1e-8)


def test_contact_wrench_cone_with_reuse_equals_the_numpy_code_on_a_walk():
    rng = np.random.default_rng(3)
    p, n, mu = _cwc_rays(rng, tilt=0.1)
    for _ in range(200):
        p = p + 0.01 * rng.normal(size=p.shape)
        fast = contact_wrench_cone(p, n, mu, 4)
        kernels.ENABLED = False
        try:
            slow = contact_wrench_cone(p, n, mu, 4)
        finally:
            kernels.ENABLED = True
        assert fast.A.shape == slow.A.shape
        assert _same_rows(fast.A, slow.A)


def test_sigma_ratio_in_closed_form_equals_the_svd():
    """sigma_min / sigma_max of 3x3 matrices: LAPACK's SVD is the reference."""
    import numba
    ratio = numba.njit(lambda M: kernels._sigma_ratio3(M))
    rng = np.random.default_rng(21)
    for i in range(4000):
        M = rng.normal(size=(3, 3)) * 10.0 ** rng.uniform(-3, 3)
        u, s, vt = np.linalg.svd(M)
        kind = i % 4
        if kind == 1:                               # one small singular value
            s[2] = s[0] * 10.0 ** rng.uniform(-14, -1)
        elif kind == 2:                             # two equal small ones
            s[1] = s[2] = s[0] * 10.0 ** rng.uniform(-6, 0)
        elif kind == 3:                             # two equal large ones
            s[1] = s[0] * (1.0 - 10.0 ** rng.uniform(-12, -1))
        M = (u * s) @ vt
        sv = np.linalg.svd(M, compute_uv=False)
        ref, got = sv[2] / sv[0], ratio(M)
        assert abs(got - ref) <= 2e-9
        assert (got > 1e-9) == (ref > 1e-9)
        if ref > 1e-3:
            assert abs(got - ref) <= (1e-5 if kind == 2 else 1e-8) * ref
    assert ratio(np.eye(3)) == 1.0 and ratio(np.zeros((3, 3))) == 0.0
    assert ratio(np.diag([1.0, 1.0, 0.0])) == 0.0 and ratio(np.diag([2.0, 1.0, 0.5])) == 0.25


def test_parallelepipeds_equal_the_numpy_reference():
    from awp_ros.wrench.force_polytope import parallelepipeds
    rng = np.random.default_rng(5)
    J = rng.normal(size=(5, 3, 3)) * 0.3
    J[3] = np.outer(J[3][:, 0], [1.0, 2.0, 0.5])              # singular: NaNs in both
    bias = rng.normal(size=(5, 3)) * 10.0
    lo, hi = -rng.uniform(20, 80, size=(5, 3)), rng.uniform(20, 80, size=(5, 3))
    fast = parallelepipeds(J, bias, lo, hi, singular_rtol=1e-9)
    kernels.ENABLED = False
    try:
        ref = parallelepipeds(J, bias, lo, hi, singular_rtol=1e-9)
    finally:
        kernels.ENABLED = True
    for key in ref:
        np.testing.assert_allclose(fast[key], ref[key], rtol=1e-10, atol=1e-9, err_msg=key)
    # the definition: every vertex maps to torques at the limits, tau = bias - J^T f
    for k in (0, 1, 2, 4):
        tau = bias[k] - fast['vertices'][k] @ J[k]
        assert np.all((np.abs(tau - lo[k]) < 1e-6) | (np.abs(tau - hi[k]) < 1e-6))


def _numpy(function, *args, **kwargs):
    """Return ``function(*args, **kwargs)`` with the kernels disabled (the numpy reference)."""
    kernels.ENABLED = False
    try:
        return function(*args, **kwargs)
    finally:
        kernels.ENABLED = True


@pytest.mark.parametrize('seed', range(4))
def test_polar_hull_is_the_convex_hull(seed):
    """Against qhull: random clouds, points on a grid (ties, collinear), points on a circle."""
    rng = np.random.default_rng(seed)
    for trial in range(150):
        m = int(rng.integers(3, 1500))
        D = rng.normal(size=(2, m))
        if trial % 3 == 1:
            D = np.round(D, 1)
        elif trial % 3 == 2:
            th = rng.uniform(0.0, 2.0 * np.pi, size=m)
            D = np.vstack([np.cos(th), np.sin(th)]) * rng.uniform(0.5, 2.0)
        chain = kernels.polar_hull(D)
        ref = ConvexHull(D.T).vertices
        assert {tuple(x) for x in D[:, chain].T} == {tuple(x) for x in D[:, ref].T}
        V = D[:, chain]
        e1, e2 = np.roll(V, -1, axis=1) - V, np.roll(V, -2, axis=1) - V
        turn = e1[0] * e2[1] - e1[1] * e2[0]
        assert np.all(turn > 0.0)                    # counter-clockwise, strictly convex


def _lines(rng, m, inside=True):
    """Return random lines ``N2^T delta <= h`` (unit normals) of a bounded polygon [m]."""
    th = rng.uniform(0.0, 2.0 * np.pi, size=m)
    N2 = np.vstack([np.cos(th), np.sin(th)])
    h = rng.uniform(0.05, 0.5, size=m) + (0.0 if inside else -0.6) * (th < 0.5)
    return N2 * rng.uniform(0.5, 3.0, size=m), h


@pytest.mark.parametrize('seed', range(3))
def test_com_region_polygons_equal_the_numpy_reference(seed):
    """The compiled polygon step of com_region against _polar / _polygon, CoM in and out."""
    from awp_ros.wrench import com_region as cr
    rng = np.random.default_rng(seed)
    for trial in range(200):
        N2, h = _lines(rng, int(rng.integers(8, 400)), inside=trial % 4 != 3)
        nn = np.hypot(*N2)
        x0 = None if np.all(h > 0.0) else cr._chebyshev((N2 / nn).T, h / nn, 100.0, 1e-9)[0]
        if x0 is not None and np.min(h - x0 @ N2) <= 1e-6:
            continue
        fast = cr._slice_polygon(N2, h, x0, 1e-9, h.size)
        slow = _numpy(cr._slice_polygon, N2, h, x0, 1e-9, h.size)
        assert fast.vertices.shape == slow.vertices.shape
        shift = int(np.argmin(np.linalg.norm(slow.vertices - fast.vertices[0], axis=1)))
        np.testing.assert_allclose(np.roll(slow.vertices, -shift, axis=0), fast.vertices,
                                   atol=1e-12)
        np.testing.assert_allclose(np.roll(slow.A, -shift, axis=0), fast.A, atol=1e-12)
        np.testing.assert_allclose(np.roll(slow.b, -shift), fast.b, atol=1e-12)
        assert fast.margin == pytest.approx(slow.margin, abs=1e-12)


@pytest.mark.parametrize('seed', range(4))
def test_lifted_zonotope_equals_the_numpy_awp(seed):
    from awp_ros.wrench.wrench_polytope import actuation_wrench_polytope
    rng = np.random.default_rng(seed)
    K = 3 + seed % 2
    p = rng.normal(size=(K, 3)) * 0.3
    p[:, 2] = -0.5
    C, H = rng.normal(size=(K, 3)) * 50.0, rng.normal(size=(K, 3, 3)) * 100.0
    fast = actuation_wrench_polytope(p, C, H)
    slow = _numpy(actuation_wrench_polytope, p, C, H)
    assert fast.dimension == slow.dimension == 6
    np.testing.assert_allclose(fast.A, slow.A, atol=1e-12)
    np.testing.assert_allclose(fast.b, slow.b, rtol=1e-12, atol=1e-8)
    np.testing.assert_allclose(fast.hull_origin, slow.hull_origin, atol=1e-10)
    # not full-dimensional (every foot at one point: the generators span 3 dimensions) or
    # a zero generator: the kernel declines, the general code gives the reference's answer
    for P, G in ((np.zeros((K, 3)), H), (p, np.concatenate([H[:1] * 0.0, H[1:]]))):
        assert kernels.lifted_zonotope(P, C, G, _combinations(3 * K, 5)[0], 1e-12, 1e-10,
                                       1e-9, 1e-9) is None
        a, b = actuation_wrench_polytope(P, C, G), _numpy(actuation_wrench_polytope, P, C, G)
        assert a.dimension == b.dimension
        np.testing.assert_allclose(a.A, b.A, atol=1e-12)
    assert actuation_wrench_polytope(np.zeros((K, 3)), C, H).dimension == 3


def _same_hrep(fast, slow):
    """Assert two H-reps have the same rows (any order) and the same hull as the reference."""
    assert fast.dimension == slow.dimension
    assert _same_rows(np.hstack([fast.A, fast.b[:, None] / 1e3]),
                      np.hstack([slow.A, slow.b[:, None] / 1e3]), tol=1e-9)
    U, V = fast.hull_basis, slow.hull_basis
    np.testing.assert_allclose(U @ U.T, V @ V.T, atol=1e-12)
    np.testing.assert_allclose(U.T @ U, np.eye(U.shape[1]), atol=1e-14)


@pytest.mark.parametrize('seed', range(6))
def test_two_leg_awp_equals_the_numpy_reference_and_its_vertices(seed):
    """K = 2: the closed-form hyperplane basis against the SVD's, rows against the 64 vertices."""
    from awp_ros.geometry.polytope import Polytope
    from awp_ros.wrench.wrench_polytope import actuation_wrench_polytope
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(2, 3)) * 0.3
    p[:, 2] = -0.5 + 0.02 * rng.normal(size=2)
    if seed == 5:
        p[1] = p[0] + [1e-3, 0.0, 0.0]                       # feet 1 mm apart
    C, H = rng.normal(size=(2, 3)) * 50.0, rng.normal(size=(2, 3, 3)) * 100.0
    fast = actuation_wrench_polytope(p, C, H)
    slow = _numpy(actuation_wrench_polytope, p, C, H)
    assert fast.dimension == 5
    _same_hrep(fast, slow)
    # the definition: every row supports the sum of the lifted parallelepipeds (a vertex on
    # it, none beyond), and the hyperplane holds every vertex
    G = np.concatenate([np.vstack([H[k], np.cross(p[k], H[k].T).T]) for k in range(2)], axis=1)
    c = sum(np.concatenate([C[k], np.cross(p[k], C[k])]) for k in range(2))
    signs = np.array(np.meshgrid(*[[-1.0, 1.0]] * 6)).reshape(6, -1)
    V = c[:, None] + G @ signs                                                  # (6, 64)
    support = (fast.A @ V).max(axis=1)
    np.testing.assert_allclose(support, fast.b, rtol=1e-10, atol=1e-7)
    E, e = fast.equalities
    np.testing.assert_allclose(E @ V - e[:, None], 0.0, atol=1e-8)
    fresh = Polytope(5, fast.vertices, fast.A, fast.b, fast.hull_origin, fast.hull_basis)
    assert abs(float((fresh.equalities[0] @ E.T)[0, 0])) == pytest.approx(1.0, abs=1e-12)


def test_two_leg_awp_kernel_declines_what_it_cannot_certify():
    """Coincident feet, a zero generator: the general code answers; a singular leg: 5D too."""
    from awp_ros.wrench.wrench_polytope import actuation_wrench_polytope
    rng = np.random.default_rng(11)
    p = np.array([[0.3, 0.2, -0.5], [-0.3, -0.2, -0.5]])
    C, H = rng.normal(size=(2, 3)) * 50.0, rng.normal(size=(2, 3, 3)) * 100.0
    singular = H.copy()
    singular[0, :, 2] = singular[0, :, 0] + singular[0, :, 1]             # rank 2 leg
    zero = H.copy()
    zero[1, :, 0] = 0.0
    subsets = _combinations(6, 4)[0]
    fast = actuation_wrench_polytope(p, C, singular)      # one leg flat, the sum still 5D
    assert fast.dimension == 5
    _same_hrep(fast, _numpy(actuation_wrench_polytope, p, C, singular))
    for P, G in ((np.zeros((2, 3)), H), (p, zero)):
        assert kernels.lifted_zonotope_pair(P, C, G, subsets, 1e-12, 1e-10, 1e-9, 1e-9,
                                            1e-9) is None
        fast, slow = actuation_wrench_polytope(P, C, G), _numpy(actuation_wrench_polytope,
                                                                P, C, G)
        assert fast.dimension == slow.dimension     # 3 (one point), 5 (five generators)
        np.testing.assert_allclose(fast.A, slow.A, atol=1e-12)


@pytest.mark.parametrize('seed,sides,tilt', [(0, 4, 0.0), (1, 4, 0.3), (2, 6, 0.1), (3, 3, 0.0)])
def test_two_leg_cwc_equals_the_numpy_reference(seed, sides, tilt):
    """K = 2: the closed-form hyperplane basis, the same facets; frictionless feet decline."""
    rng = np.random.default_rng(seed)
    p, n, mu = _cwc_rays(rng, K=2, sides=sides, tilt=tilt)
    fast = contact_wrench_cone(p, n, mu, sides)
    slow = _numpy(contact_wrench_cone, p, n, mu, sides)
    assert fast.dimension == 5
    _same_hrep(fast, slow)
    E, e = fast.equalities
    np.testing.assert_allclose(E @ fast.meta['rays'].T, 0.0, atol=1e-12)   # every ray on it
    # frictionless feet (rays along the normals only: 2 dimensions) and one foot twice
    for P, m in ((p, np.zeros(2)), (np.repeat(p[:1], 2, axis=0), mu)):
        fast = contact_wrench_cone(P, n, m, sides)
        slow = _numpy(contact_wrench_cone, P, n, m, sides)
        assert fast.dimension == slow.dimension < 5
        _same_hrep(fast, slow)


def test_lifted_rays_are_the_unit_lifts_and_certify_the_rank():
    rng = np.random.default_rng(7)
    p, n, mu = _cwc_rays(rng)
    rays = np.asarray(_cached_rays(np.ascontiguousarray(n).tobytes(), mu.tobytes(), 4))
    R, full = kernels.lifted_rays(p, rays, 1e-10)
    ref = lift_rays(p, rays).reshape(-1, 6)
    np.testing.assert_allclose(R, ref / np.linalg.norm(ref, axis=1)[:, None], atol=1e-15)
    assert full
    _, full = kernels.lifted_rays(np.zeros_like(p), rays, 1e-10)   # all feet at one point
    assert not full


@pytest.mark.parametrize('seed', [0, 1, 2, 3])
def test_leg_vertices_are_the_vertices_of_the_halfspaces(seed):
    """All plane triples, merged: qhull's hull of the halfspace intersection (another method)."""
    from scipy.spatial import HalfspaceIntersection
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(10, 3))
    A /= np.linalg.norm(A, axis=1)[:, None]
    b = rng.uniform(0.5, 2.0, size=10)               # 0 strictly inside
    V = kernels.leg_vertices(A, b)
    want = HalfspaceIntersection(np.column_stack([A, -b]), np.zeros(3)).intersections
    hull = want[ConvexHull(want).vertices]
    assert V.shape == hull.shape
    gap = np.linalg.norm(V[:, None] - hull[None], axis=2)
    assert gap.min(axis=0).max() < 1e-9 and gap.min(axis=1).max() < 1e-9
    assert kernels.leg_vertices(np.vstack([A, -A[:1]]), np.concatenate([b, [-3.0]])).size == 0


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_projected_polygon_is_the_projection_of_the_lp(seed):
    """Support values in 48 directions equal linprog's on the same LP; vertices feasible."""
    from scipy.optimize import linprog
    rng = np.random.default_rng(seed)
    K, n = 3, 5
    G = rng.normal(size=(6, K * n))
    leg = np.repeat(np.arange(K), n)
    D = rng.normal(size=(6, 2))
    lam = rng.dirichlet(np.ones(n), size=K).ravel()
    w0 = G @ lam                                     # delta = 0 is feasible
    V, status = kernels.projected_polygon(G, leg, K, w0, D, 1e-10)
    assert status == 0 and V.shape[0] >= 3
    e = np.roll(V, -1, axis=0) - V
    assert np.all(e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
                  > 0.0)                             # strictly convex, counter-clockwise
    E = np.zeros((K, K * n))
    E[leg, np.arange(K * n)] = 1.0
    A_eq = np.block([[G, -D], [E, np.zeros((K, 2))]])
    b_eq = np.concatenate([w0, np.ones(K)])
    bounds = [(0, None)] * (K * n) + [(None, None)] * 2
    for t in np.linspace(0.0, 2 * np.pi, 48, endpoint=False):
        u = np.array([np.cos(t), np.sin(t)])
        res = linprog(np.concatenate([np.zeros(K * n), -u]), A_eq=A_eq, b_eq=b_eq,
                      bounds=bounds, method='highs')
        assert res.status == 0
        assert float(np.max(V @ u)) == pytest.approx(-res.fun, abs=1e-7)
    for v in V:
        bounds_v = [(0, None)] * (K * n) + [(v[0], v[0]), (v[1], v[1])]
        assert linprog(np.zeros(K * n + 2), A_eq=A_eq, b_eq=b_eq, bounds=bounds_v,
                       method='highs').status == 0
    # No delta balances a wrench far outside: empty (status 1).
    assert kernels.projected_polygon(G, leg, K, w0 + 1e3, D, 1e-10)[1] == 1


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_the_implied_unilateral_row_is_dropped_only_when_implied(seed):
    """``-n . f <= 0`` is implied by a pyramid with mu > 0: same vertices without it."""
    from awp_ros.wrench.friction_polytope import friction_rows
    rng = np.random.default_rng(seed)
    normal = rng.normal(size=3) + np.array([0.0, 0.0, 3.0])
    normal /= np.linalg.norm(normal)
    for sides in (3, 4, 6):
        for mu in (0.05, 0.5, 1.0):
            R = friction_rows(normal[None], np.array([mu]), sides)[0]
            assert kernels._needed_rows(R) == sides       # the last row, -n, dropped
            box = np.vstack([np.eye(3), -np.eye(3)])
            A = np.vstack([box, R])
            b = np.concatenate([rng.uniform(50, 100, 6), np.zeros(R.shape[0])])
            with_row = kernels.leg_vertices(A, b)
            without = kernels.leg_vertices(A[:-1], b[:-1])
            assert with_row.shape == without.shape
            gap = np.linalg.norm(with_row[:, None] - without[None], axis=2)
            assert gap.min(axis=0).max() < 1e-9 and gap.min(axis=1).max() < 1e-9
    # A last row that the others do not imply is kept.
    R = friction_rows(normal[None], np.array([0.5]), 4)[0].copy()
    R[-1] = rng.normal(size=3)
    assert kernels._needed_rows(R) == 5
    R[-1] = -R[:-1].sum(axis=0)                      # the sum reversed: not implied
    assert kernels._needed_rows(R) == 5


def _hyq_standing() -> tuple:
    """Return HyQ's evaluator, its standing state, joint names and standing posture."""
    from awp_ros.evaluation.evaluator import FeasibilityEvaluator
    ev = FeasibilityEvaluator('hyq')
    state = ev.standing_state()
    names = list(state.joint_positions)
    return ev, state, names, np.array([state.joint_positions[n] for n in names])


def test_wrench_slice_equals_the_numpy_path_of_com_region():
    """The compiled steps (4)-(7) against com_region's numpy code: HyQ's CWC and FWP slices."""
    from awp_ros.wrench.com_region import com_region
    ev, state, names, q0 = _hyq_standing()
    rng = np.random.default_rng(4)
    fast_paths = 0
    for trial in range(30):
        state.joint_positions = dict(zip(names, (q0 + rng.uniform(-0.15, 0.15, q0.size))
                                         .tolist()))
        result = ev.evaluate(state, fws=False)
        # CoM offsets inside and outside the regions: both the fast path and the fallback.
        force = result.wrench[:3] * rng.uniform(0.5, 2.0)
        moment = result.wrench[3:] + rng.normal(scale=20.0, size=3) * (trial % 3 == 2)
        for P in (result.cwc, result.fwp.polytope):
            assert P.hull_basis.shape[1] == 6
            fast = com_region(P, force, moment)
            slow = _numpy(com_region, P, force, moment)
            assert fast.dimension == slow.dimension
            if fast.dimension == 2:
                shift = int(np.argmin(np.linalg.norm(slow.vertices - fast.vertices[0], axis=1)))
                np.testing.assert_allclose(np.roll(slow.vertices, -shift, axis=0),
                                           fast.vertices, atol=1e-9)
                assert fast.margin == pytest.approx(slow.margin, abs=1e-9)
                fast_paths += slow.margin > 1e-6
    assert fast_paths >= 20


@pytest.mark.parametrize('seed', range(3))
def test_pair_basis_decides_as_the_svd(seed):
    """Two feet's hyperplane: along-normal and rank tests against the SVD of the rays."""
    from awp_ros.geometry.linalg import GRAM_CERTIFY, orthonormal_span
    rng = np.random.default_rng(seed)
    for trial in range(60):
        P = rng.normal(size=(2, 3))
        n, U = kernels.pair_hyperplane(P)
        R = rng.normal(size=(8, 5)) @ U.T                   # rays in the hyperplane
        if trial % 4 == 1:
            R += 1e-3 * rng.normal(size=(8, 6))             # off it
        if trial % 4 == 2:
            R = rng.normal(size=(8, 2)) @ U[:, :2].T        # rank 2 in it
        R /= np.linalg.norm(R, axis=1)[:, None]
        got_n, got_U, status = kernels.pair_basis(P, R, 1e-9, max(1e-18, GRAM_CERTIFY))
        assert np.array_equal(got_n, n) and np.array_equal(got_U, U)
        off = float(np.sum((R @ n) ** 2)) > 1e-18
        assert (status == 1) == off
        if not off:
            rank5 = orthonormal_span(R @ U, rtol=1e-9).shape == (5, 5)
            assert (status == 0) <= rank5          # certified only when the SVD agrees
            assert rank5 == (np.linalg.matrix_rank(R @ U, tol=1e-9 * np.linalg.norm(
                R @ U, 2)) == 5)
            assert (status == 0) == (trial % 4 != 2)


def test_segment_slice_equals_the_numpy_path_of_com_region():
    """Two stance legs (a hyperplane of R^6): the compiled segment against com_region's numpy."""
    from awp_ros.errors import InputError
    from awp_ros.wrench.com_region import com_region
    ev, state, names, q0 = _hyq_standing()
    rng = np.random.default_rng(5)
    kinds = set()
    for trial in range(40):
        state.joint_positions = dict(zip(names, (q0 + rng.uniform(-0.15, 0.15, q0.size))
                                         .tolist()))
        state.stance = (['lf_foot', 'rh_foot'], ['rf_foot', 'lh_foot'],
                        ['lf_foot', 'rf_foot'])[trial % 3]
        result = ev.evaluate(state, fws=False)
        force = result.wrench[:3] * rng.uniform(0.5, 2.0)
        # Moments that put the CoM line through the sets and beside them (empty).
        moment = result.wrench[3:] + rng.normal(scale=(0.0, 5.0, 200.0)[trial % 3], size=3)
        for P in (result.cwc, result.fwp.polytope, result.awp.polytope):
            assert P.hull_basis.shape[1] == 5
            try:
                slow = _numpy(com_region, P, force, moment)
            except InputError:
                with pytest.raises(InputError):
                    com_region(P, force, moment)
                kinds.add('unbounded')
                continue
            fast = com_region(P, force, moment)
            assert fast.dimension == slow.dimension
            kinds.add(fast.dimension)
            np.testing.assert_allclose(fast.vertices, slow.vertices, atol=1e-9)
            np.testing.assert_allclose(fast.A, slow.A, atol=1e-9)
            np.testing.assert_allclose(fast.b, slow.b, atol=1e-9)
            if fast.dimension >= 0:
                assert fast.margin == pytest.approx(slow.margin, abs=1e-9)
    assert {1, -1} <= kinds                  # segments and empty regions were both met


def _faces_cases():
    """
    Return solid polytopes with their H-reps.

    Random boxes cut by planes, a cube (parallel classes), one with duplicated points and
    zero and redundant rows, a pyramid whose apex lies on five rows.
    """
    rng = np.random.default_rng(11)
    cases = []
    box = np.vstack([np.eye(3), -np.eye(3)])
    for _ in range(40):                               # a box cut by random planes
        A = rng.normal(size=(rng.integers(1, 8), 3))
        A = np.vstack([box, A / np.linalg.norm(A, axis=1)[:, None]])
        b = np.concatenate([2.0 * np.ones(6), rng.uniform(0.5, 2.0, size=A.shape[0] - 6)])
        scale = rng.uniform(0.5, 3.0, size=(A.shape[0], 1))
        cases.append((kernels.leg_vertices(A, b), A * scale, b * scale[:, 0]))
    cube = kernels.leg_vertices(box, np.ones(6))
    cases.append((cube, box, np.ones(6)))
    cases.append((np.vstack([cube, cube[:3] + 1e-13]), np.vstack([box, np.zeros(3), box[:2]]),
                  np.concatenate([np.ones(6), [1.0], 3.0 * np.ones(2)])))
    mu = 0.7
    pyramid = np.array([[1, 0, -mu], [-1, 0, -mu], [0, 1, -mu], [0, -1, -mu], [0, 0, -1],
                        [0, 0, 1.0]])
    h = np.array([0, 0, 0, 0, 0, 2.0])
    cases.append((kernels.leg_vertices(pyramid, h), pyramid, h))
    return cases


def test_solid_faces_equal_the_numpy_reference():
    """Same points, normals, offsets, classes, slots and masks as face_lattice's numpy code."""
    from awp_ros.geometry.face_lattice import polytope_faces
    for V, A, b in _faces_cases():
        fast = polytope_faces(V, (A, b))
        ref = _numpy(polytope_faces, V, (A, b))
        assert fast.dimension == ref.dimension == 3
        np.testing.assert_allclose(fast.origin, ref.origin, atol=1e-12)
        np.testing.assert_allclose(fast.vertices, ref.vertices, atol=1e-12)
        np.testing.assert_allclose(fast.facet_normals, ref.facet_normals, atol=1e-12)
        np.testing.assert_allclose(fast.facet_offsets, ref.facet_offsets, atol=1e-12)
        for g_fast, g_ref in zip(fast.groups, ref.groups, strict=True):
            np.testing.assert_array_equal(g_fast.mask, g_ref.mask)
            np.testing.assert_allclose(g_fast.dirs, g_ref.dirs, atol=1e-12)
            np.testing.assert_allclose(g_fast.checks, g_ref.checks, atol=1e-12)


def test_solid_faces_are_the_hull_facets_and_edges():
    """The definition, by qhull: facets (coplanar triangles merged) and the polytope's edges."""
    for V, A, b in _faces_cases():
        out = kernels.solid_faces(V, A, b, V.mean(axis=0), 1.0, 1e-9)
        extreme, N, offsets, edge_dirs, _, edge_mask, _, _, facet_mask = out
        hull = ConvexHull(np.unique(np.round(V, 9), axis=0))     # duplicates merged
        planes = hull.equations                        # triangles: each facet once or more
        assert N.shape[0] == facet_mask.sum()
        gap = np.linalg.norm(np.column_stack([N, -offsets])[:, None] - planes[None], axis=2)
        assert gap.min(axis=1).max() < 1e-6 and gap.min(axis=0).max() < 1e-6
        assert np.all(np.triu(np.linalg.norm(N[:, None] - N[None], axis=2) > 1e-6, 1)
                      | np.tri(N.shape[0], dtype=bool))          # no facet twice
        assert extreme.shape[0] == hull.vertices.size
        # Euler: V - E + F = 2 (edges counted over their classes' slots)
        assert extreme.shape[0] - edge_mask.sum() + N.shape[0] == 2
        assert np.allclose(np.linalg.norm(edge_dirs[:, 0], axis=1), 1.0)


def test_certified_solid_faces_leave_thin_sets_to_the_svd():
    """A box 1e-7 thick is not certified (det G / tr^3 tiny) but the SVD finds it solid."""
    from awp_ros.geometry.face_lattice import polytope_faces
    box = np.vstack([np.eye(3), -np.eye(3)])
    b = np.array([1.0, 1.0, 1e-7, 1.0, 1.0, 0.0])
    V = kernels.leg_vertices(box, b)
    assert kernels.certified_solid_faces(V, box, b, 1e-9, 1e-9) is None
    assert kernels.certified_solid_faces(V[:3], box, b, 1e-9, 1e-9) is None     # 3 points
    fast, ref = polytope_faces(V, (box, b)), _numpy(polytope_faces, V, (box, b))
    assert fast.dimension == ref.dimension == 3
    np.testing.assert_allclose(fast.facet_normals, ref.facet_normals, atol=1e-12)
    cube = kernels.leg_vertices(box, np.ones(6)) + 0.5
    origin, faces = kernels.certified_solid_faces(cube, box, np.repeat([1.5, 0.5], 3), 1e-9,
                                                  1e-9)
    np.testing.assert_allclose(origin, cube.mean(axis=0), atol=1e-15)
    assert faces[1].shape == (6, 3)                 # the six facet normals


def test_solid_faces_leave_large_point_sets_to_numpy():
    V = np.random.default_rng(0).normal(size=(63, 3))
    assert kernels.solid_faces(V, np.eye(3), np.ones(3), V.mean(axis=0), 1.0, 1e-9) is None


@pytest.mark.parametrize('K', [2, 3, 4])
def test_fws_facets_equal_the_numpy_reference(K):
    """
    The FWS with every kernel on (faces, slice or flat-pair search) is numpy's polytope.

    The rows of each are the other's to 1e-9, or implied by the other's rows (an LP: the
    compiled searches keep fewer redundant copies of degenerate facets). Two legs span a
    hyperplane (dimension 5): :func:`kernels.flat_pair_facet_normals`.
    """
    from cases import assert_same_polytope, hyq_feet, hyq_like_leg
    from awp_ros.wrench.feasible_wrench_set import minkowski_sum_of_lifts
    rng = np.random.default_rng(20 + K)
    for _ in range(3 if K > 2 else 12):
        feet, legs = hyq_feet(rng, K), [hyq_like_leg(rng) for _ in range(K)]
        fast = minkowski_sum_of_lifts(feet, legs)
        ref = _numpy(minkowski_sum_of_lifts, feet, legs)
        assert fast.dimension == ref.dimension == (5 if K == 2 else 6)
        assert_same_polytope(fast, ref)


@pytest.mark.parametrize('seed', range(6))
def test_ratio_test_equals_numpy_and_the_lp(seed):
    """Directional margins: the kernel, the numpy ratio test and an LP on each line agree."""
    from awp_ros.geometry.margin import directional_margins
    from awp_ros.geometry.polytope import Polytope
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(rng.integers(8, 300), 6))
    A[:3] = np.eye(6)[rng.integers(0, 6, size=3)]            # rows parallel to most axes
    A /= np.linalg.norm(A, axis=1)[:, None]
    b = rng.uniform(0.5, 2.0, size=A.shape[0])
    P = Polytope(6, np.zeros((0, 6)), A, b, np.zeros(6), np.eye(6))
    D = None if seed % 2 else rng.normal(size=(5, 6))
    for w in (rng.normal(scale=0.2, size=6), rng.normal(scale=3.0, size=6)):   # in, out
        got = directional_margins(P, w, D)
        ref = _numpy(directional_margins, P, w, D)
        for g, r in zip(got, ref):
            np.testing.assert_allclose(g, r, rtol=1e-12, atol=1e-12)
        for j, d in enumerate(np.eye(6) if D is None else D):
            for sign, t in ((1.0, got[0][j]), (-1.0, got[1][j])):
                lp = linprog(-1.0, A_ub=(sign * A @ d)[:, None], b_ub=b - A @ w,
                             bounds=[(None, None)], method='highs')
                if lp.status == 2:                  # the line misses P
                    assert np.isnan(t)
                else:
                    assert lp.status == 0 and abs(t - lp.x[0]) <= 1e-9 * max(1.0, abs(t))


@pytest.mark.parametrize('seed', range(6))
def test_slack_min_is_the_first_least_slack(seed):
    """``slack_min``: numpy's first argmin of ``b - A w`` (3 and 6 columns, ties, no rows)."""
    rng = np.random.default_rng(seed)
    n = (3, 6)[seed % 2]
    A = rng.normal(size=(rng.integers(1, 400), n))
    b = rng.uniform(-1.0, 2.0, size=A.shape[0])
    if seed >= 2:                                    # ties: repeated rows, first one wins
        A[-5:], b[-5:] = A[:5], b[:5]
    w = rng.normal(size=n)
    s = b - A @ w
    i, least = kernels.slack_min(A, b, w)
    assert i == int(np.flatnonzero(s <= s.min() + 1e-12)[0])
    assert abs(least - s[i]) <= 1e-12 * max(1.0, abs(s[i]))
    i, least = kernels.slack_min(np.zeros((0, n)), np.zeros(0), w)
    assert i == -1 and least == np.inf
    i, least = kernels.slack_min(np.ones((3, n)), np.full(3, np.inf), w)     # all +inf
    assert i == 0 and least == np.inf


def test_polytope_margin_takes_the_callers_slack_and_is_unchanged():
    """``polytope_margin(..., slack=slack_min(...))`` equals the margin it computes itself."""
    from awp_ros.geometry.margin import polytope_margin
    from awp_ros.geometry.polytope import Polytope
    rng = np.random.default_rng(3)
    A = rng.normal(size=(60, 6))
    A /= np.linalg.norm(A, axis=1)[:, None]
    P = Polytope(6, np.zeros((0, 6)), A, np.ones(60), np.zeros(6), np.eye(6))
    for w in (rng.normal(scale=0.1, size=6), rng.normal(scale=5.0, size=6)):   # in, out
        own = polytope_margin(P, w)
        given = polytope_margin(P, w, slack=kernels.slack_min(P.A, P.b, w))
        for x, y in zip((own.margin, own.normal, own.dimension, own.affine_residual,
                         own.feasible, own.margin_in_hull),
                        (given.margin, given.normal, given.dimension, given.affine_residual,
                         given.feasible, given.margin_in_hull)):
            assert np.array_equal(x, y)


@pytest.mark.parametrize('seed', range(4))
def test_first_of_equal_rows_equals_numpy_unique(seed):
    """The first index of each group of equal rounded rows, as numpy's unique finds it."""
    from awp_ros.wrench.feasible_wrench_set import _unique_rows
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(rng.integers(1, 400), 6))
    X = X[rng.integers(0, X.shape[0], size=3 * X.shape[0])]            # repeats
    X = X + rng.choice([0.0, 1e-13, -1e-13, 3e-6], size=X.shape)   # within and beyond 1e-10
    first = kernels.first_of_equal_rows(X, 10)
    _, ref = np.unique(np.rint(X * 1e10), axis=0, return_index=True)
    np.testing.assert_array_equal(first, np.sort(ref))
    np.testing.assert_array_equal(_numpy(_unique_rows, X, 10), np.sort(ref))
    assert kernels.first_of_equal_rows(np.zeros((0, 6)), 10).size == 0


@pytest.mark.parametrize('seed', range(3))
def test_slice_search_generalised_cross_product(seed):
    """``_cross4``: x . y = det[r1; r2; c; y] for P = r1 ^ r2 (the slice search's normal)."""
    rng = np.random.default_rng(seed)
    r1, r2, c, y = rng.normal(size=(4, 4))
    P, x = np.empty(6), np.empty(4)
    norm = kernels._plucker4(r1, r2, P)
    kernels._cross4(P, c, x)
    assert x @ y == pytest.approx(np.linalg.det(np.array([r1, r2, c, y])), rel=1e-12)
    assert np.abs([x @ r1, x @ r2, x @ c]).max() < 1e-12 * np.abs(x).max()
    assert norm == pytest.approx(np.sqrt(np.linalg.det(np.array([r1, r2]) @ np.array([r1, r2]).T)))


def test_survivor_normals_are_unit_and_orthogonal_to_the_faces():
    """The definition: a unit normal orthogonal to the r - 1 lifted directions, sign flipped."""
    rng = np.random.default_rng(4)
    V = rng.normal(size=(3, 5, 6))                    # per batch, 5 vectors of R^6
    from awp_ros.geometry.exterior import wedge_rows
    P = V[:, 0]
    for i in range(1, 4):
        P = wedge_rows(P, V[:, i], 6, i, 1)           # (3, 15): the first four vectors
    X = rng.normal(size=(3, 7, 6))
    batch, row, col = np.array([0, 1, 2, 2]), np.zeros(4, dtype=int), np.array([0, 3, 6, 1])
    a = kernels.survivor_normals(P[:, None], X, batch, row, col, 4, 1, 2, 0.0)
    np.testing.assert_allclose(np.linalg.norm(a, axis=1), 1.0)
    for t in range(4):
        span = np.vstack([V[batch[t], :4], X[batch[t], col[t]]])
        assert np.abs(span @ a[t]).max() < 1e-12
        sign = np.linalg.det(np.vstack([a[t], span])) * (-1.0 if t >= 2 else 1.0)
        assert sign > 0.0                              # det[a, b_1..b_5] > 0 before the flip
    degenerate = kernels.survivor_normals(P[:, None], V[:, 3:4], np.array([0]), np.zeros(1, int),
                                          np.zeros(1, int), 4, 1, 0, 1e-9)
    assert degenerate.shape == (0, 6)                 # a vector already in the span: dropped


@pytest.mark.parametrize('p,q', [(4, 1), (3, 2), (3, 1)])
def test_survivor_normals_equal_the_numpy_reference_and_the_general_kernel(p, q):
    """
    Every (p, q) against ``hodge_normal(wedge_rows(...))``; (6, 4, 1) has a kernel of its own.

    Its loops run over constant indices: its normals must equal the general kernel's bit for
    bit (same products, same order), and both the numpy reference's to rounding.
    """
    from math import comb
    from awp_ros.geometry.exterior import hodge_normal, wedge_rows
    r = p + q + 1
    rng = np.random.default_rng(p * 10 + q)
    P = rng.normal(size=(3, 40, comb(r, p)))
    X = rng.normal(size=(3, 9, comb(r, q)))
    n = 500
    batch, row, col = rng.integers(0, 3, n), rng.integers(0, 40, n), rng.integers(0, 9, n)
    a = kernels.survivor_normals(P, X, batch, row, col, p, q, 300, 0.0)
    first, second, sign = kernels.sparse_wedge_table(r, p, q)
    general = kernels._survivor_normals(P, X, batch, row, col, first, second, sign, r, 300, 0.0)
    assert np.array_equal(a, general)
    W = wedge_rows(P[batch, row], X[batch, col], r, p, q)
    ref = hodge_normal(W)
    ref /= np.linalg.norm(ref, axis=1)[:, None]
    ref[300:] *= -1.0
    np.testing.assert_allclose(a, ref, atol=1e-12)


@pytest.mark.parametrize('seed', range(3))
def test_inside_forces_equals_the_numpy_inside_force(seed):
    """Parallelepiped legs pushing well, a little, not at all, sideways; tilted pyramids."""
    from awp_ros.wrench.force_polytope import force_polytope
    from awp_ros.wrench.friction_polytope import friction_rows, inside_force
    rng = np.random.default_rng(seed)
    K = 60
    forces = []
    for k in range(K):
        J = rng.normal(size=(3, 3)) * 0.3 + np.diag([0.4, 0.4, 0.4])
        bias = rng.normal(size=3) * 30.0 + [0.0, 0.0, (-60.0, -31.0, 0.0, 20.0)[k % 4]]
        forces.append(force_polytope(J, bias, -np.full(3, 40.0), np.full(3, 40.0)))
    assert all(F.dimension == 3 for F in forces)
    normals = np.array([0.0, 0.0, 1.0]) + rng.uniform(-0.6, 0.6, size=(K, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    rows = friction_rows(normals, rng.uniform(0.2, 1.0, K), 4 + seed)
    for chunk in range(0, K, 4):                   # the node's batches: one stance each
        legs = forces[chunk:chunk + 4]
        fast = inside_force(legs, rows[chunk:chunk + 4])
        slow = _numpy(inside_force, legs, rows[chunk:chunk + 4])
        np.testing.assert_array_equal(fast, slow)
        stacked = tuple(np.array([getattr(F, key) for F in legs]) for key in ('A', 'b',
                                                                              'vertices'))
        np.testing.assert_array_equal(inside_force(legs, rows[chunk:chunk + 4],
                                                   stacked=stacked), slow)
    both = inside_force(forces, rows)
    V = np.array([F.vertices for F in forces])
    by_vertex = (V @ rows.transpose(0, 2, 1) < -1e-6).all(axis=2).any(axis=1)
    assert by_vertex.any() and (both & ~by_vertex).any() and not both.all()   # all 3 drawn


def test_subset_complements_are_the_other_indices():
    subsets = _combinations(9, 5)[0]
    others = kernels.subset_complements(subsets, 9)
    assert others.shape == (subsets.shape[0], 4)
    for row, rest in zip(subsets, others):
        assert list(rest) == sorted(set(range(9)) - set(row.tolist()))
