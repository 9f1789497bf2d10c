"""
Tests of awp_ros.wrench.fws_queries: LP membership, directional margins and distance of the FWS.

Checked against an independent method, the exact H-rep of the same Minkowski sum
(:func:`awp_ros.wrench.feasible_wrench_set.minkowski_sum_of_lifts`) with the ratio test of
:func:`awp_ros.geometry.margin.directional_margins` and the least-distance program of
:func:`awp_ros.geometry.margin.polytope_margin`, against qhull's hull of the vertex sums on
small sums, and against scipy's ``linprog`` (no warm start).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from awp_ros.errors import InputError
from awp_ros.geometry.margin import directional_margins, polytope_margin
from awp_ros.geometry.polytope import Polytope
from awp_ros.wrench import fws_queries
from awp_ros.wrench.feasible_wrench_set import minkowski_sum_of_lifts
from awp_ros.wrench.fws_queries import lp_directional_margins as reexported
from awp_ros.wrench.fws_queries import lp_directional_margins
from cases import hyq_feet, hyq_like_leg, vertex_sums


def test_reexported_from_feasible_wrench_set():
    assert reexported is lp_directional_margins


@pytest.mark.parametrize('K', [1, 2, 3, 4])
def test_lp_directional_margins_match_the_hrep(K):
    """
    Warm-started LPs and the H-rep ratio test (two independent methods) agree.

    Flat sets included (a transversal axis meets the hull in one point or misses it: NaN).
    """
    rng = np.random.default_rng(20 + K)
    vertex_sets = [hyq_like_leg(rng) for _ in range(K)]
    p = hyq_feet(rng, K)
    S = minkowski_sum_of_lifts(p, vertex_sets)
    pts = vertex_sums(p, vertex_sets)
    for w in (pts.mean(axis=0), pts.mean(axis=0) + [0, 0, 0, 30.0, -20.0, 10.0],
              np.array([0.0, 0.0, 85.0 * 9.81, 0.0, 0.0, 0.0]), pts[0]):
        member, t_plus, t_minus = lp_directional_margins(p, vertex_sets, w)
        h_plus, h_minus = directional_margins(S, w)
        np.testing.assert_allclose(t_plus, h_plus, rtol=1e-7, atol=1e-5)
        np.testing.assert_allclose(t_minus, h_minus, rtol=1e-7, atol=1e-5)
        assert member == polytope_margin(S, w).feasible


def test_lp_fallback_without_highs_agrees(monkeypatch):
    """Without a HiGHS binding the same LPs go through scipy.optimize.linprog."""
    rng = np.random.default_rng(5)
    vertex_sets = [hyq_like_leg(rng) for _ in range(3)]
    p = hyq_feet(rng, 3)
    w = vertex_sums(p, vertex_sets).mean(axis=0)
    fast = lp_directional_margins(p, vertex_sets, w)
    init = fws_queries._HighsLp.__init__

    def no_highs(self, *args):
        init(self, *args)
        self.core = None
    monkeypatch.setattr(fws_queries._HighsLp, '__init__', no_highs)
    slow = lp_directional_margins(p, vertex_sets, w)
    assert fast[0] == slow[0]
    np.testing.assert_allclose(fast[1], slow[1], rtol=1e-7)
    np.testing.assert_allclose(fast[2], slow[2], rtol=1e-7)


def test_lp_directional_margins_no_leg_and_empty_leg():
    member, t_plus, t_minus = lp_directional_margins(np.zeros((0, 3)), [], np.zeros(6))
    assert member
    np.testing.assert_allclose(t_plus, 0.0)
    w = np.array([0.0, 0.0, 5.0, 0.0, 0.0, 0.0])
    member, t_plus, t_minus = lp_directional_margins(np.zeros((0, 3)), [], w)
    assert not member and t_plus[2] == pytest.approx(-5.0) and np.isnan(t_plus[0])
    rng = np.random.default_rng(3)
    legs = [hyq_like_leg(rng), np.zeros((0, 3))]
    member, t_plus, _ = lp_directional_margins(hyq_feet(rng, 2), legs, w)
    assert not member and np.all(np.isnan(t_plus))


# -- Two stance legs: the verdict every cycle (two_leg_contains) -----------------------------

def _linprog_contains(legs, rows, w_bar, tol=1e-7) -> bool:
    """Whether ``L_1 f_1 + L_2 f_2 = w_bar`` has a solution within the legs' rows (HiGHS)."""
    from scipy.optimize import linprog
    from awp_ros.wrench.wrench_polytope import lift_matrices
    L = lift_matrices(np.array([leg.position for leg in legs]))
    A_ub = np.zeros((0, 6))
    b_ub = np.zeros(0)
    for k, leg in enumerate(legs):
        block = np.zeros((0, 6))
        pyramid = (rows[k], np.zeros(len(rows[k])))
        for A, b in ((leg.force_polytope.A, leg.force_polytope.b), pyramid):
            n = np.linalg.norm(A, axis=1)
            M = np.zeros((len(A), 6))
            M[:, 3 * k:3 * k + 3] = A / n[:, None]
            block = np.vstack([block, M])
            b_ub = np.concatenate([b_ub, b / n + tol])
        A_ub = np.vstack([A_ub, block])
    res = linprog(np.zeros(6), A_ub=A_ub, b_ub=b_ub, A_eq=np.hstack(list(L)), b_eq=w_bar,
                  bounds=[(None, None)] * 6, method='highs')
    return res.status == 0


def _two_leg_cases(seed: int, count: int):
    """Yield (evaluator, result with its FWS, wrenches) on random HyQ two-leg postures."""
    from awp_ros.evaluation.evaluator import FeasibilityEvaluator
    evaluator = FeasibilityEvaluator('hyq')
    rng = np.random.default_rng(seed)
    pairs = [('lf_foot', 'rh_foot'), ('rf_foot', 'lh_foot'), ('lf_foot', 'rf_foot'),
             ('lf_foot', 'lh_foot')]
    for i in range(count):
        state = evaluator.standing_state(stance=pairs[i % len(pairs)])
        for name in state.joint_positions:
            state.joint_positions[name] += rng.uniform(-0.15, 0.15)
        result = evaluator.evaluate(state)
        S = result.fws.polytope
        U, o = S.hull_basis, S.hull_origin
        nu = np.linalg.svd(U.T)[2][-1]                      # the hull's normal, from its basis
        pts = []
        for _ in range(6):                                   # points of the FWS
            x = np.zeros(6)
            for leg in result.legs.values():
                V = leg.friction_polytope.vertices
                f = V.T @ rng.dirichlet(np.ones(len(V)))
                x += np.concatenate([f, np.cross(leg.position, f)])
            pts.append(x)
        wrenches = []
        for x in pts:
            d = U @ rng.normal(size=U.shape[1])              # a direction in the hull
            t = min((S.b[j] - S.A[j] @ x) / (S.A[j] @ d) for j in range(len(S.b))
                    if S.A[j] @ d > 1e-12)                   # where x + t d leaves the FWS
            for scale in (0.5, 0.999, 1.001, 1.5):
                wrenches.append(x + scale * t * d)
            for off in (0.9, 1.1):                           # off the hull, near hull_tol
                wrenches.append(x + 0.5 * t * d + off * evaluator.hull_tol * nu)
        wrenches.append(result.wrench)
        yield evaluator, result, o, U, nu, wrenches


@pytest.mark.parametrize('compiled', [True, False])
def test_two_leg_verdict_agrees_with_the_fws_and_an_lp_on_the_definition(compiled, monkeypatch):
    """
    The one-dimensional LP, the FWS's H-rep and HiGHS on the definition give one verdict.

    Random HyQ postures on every kind of leg pair (diagonal, front, side); wrenches in the
    hull on both sides of the boundary (0.1 % from it), deep inside and far outside, and off
    the hull just inside and outside the hull tolerance; the compiled kernel and its numpy
    reference.
    """
    from awp_ros.geometry import kernels
    if compiled and not kernels.ENABLED:
        pytest.skip('the compiled kernels are off')
    monkeypatch.setattr(kernels, 'ENABLED', compiled)
    seen = {True: 0, False: 0}
    for evaluator, result, o, U, nu, wrenches in _two_leg_cases(41, 8):
        legs = list(result.legs.values())
        rows = evaluator._friction_rows(np.array([leg.normal for leg in legs]),
                                        np.array([leg.friction_coefficient for leg in legs]))
        for w in wrenches:
            verdict = evaluator.two_leg_verdict_at(legs, w)
            fws = polytope_margin(result.fws.polytope, w, hull_tol=evaluator.hull_tol,
                                  feasibility_tol=evaluator.feasibility_tol).feasible
            w_bar = o + U @ (U.T @ (w - o))
            lp = abs(nu @ (w - o)) <= evaluator.hull_tol and _linprog_contains(legs, rows, w_bar)
            assert verdict is not None and verdict == bool(fws) == bool(lp)
            seen[verdict] += 1
    assert seen[True] > 50 and seen[False] > 50


# -- Three or more stance legs: the directional margins every cycle --------------------------

def test_directional_margins_every_cycle_agree_with_the_hrep_and_highs():
    """
    The compiled LPs of every cycle, the FWS's H-rep and HiGHS give the same margins.

    Random HyQ postures with three and four stance legs; at the state's own wrench and at
    wrenches inside the FWS (random force distributions), beyond its boundary and far
    outside (lines that miss it: NaN). The per-cycle margins of ``evaluate`` are those of
    ``directional_at`` at the state's wrench.
    """
    from awp_ros.evaluation.evaluator import FeasibilityEvaluator
    from awp_ros.evaluation.result import AXES
    from awp_ros.geometry import kernels
    if not kernels.ENABLED:
        pytest.skip('the compiled kernels are off')
    evaluator = FeasibilityEvaluator('hyq')
    rng = np.random.default_rng(77)
    stances = [('lf_foot', 'rf_foot', 'lh_foot', 'rh_foot'), ('lf_foot', 'rf_foot', 'rh_foot'),
               ('rf_foot', 'lh_foot', 'rh_foot'), ('lf_foot', 'rf_foot', 'lh_foot')]
    seen = {'inside': 0, 'outside': 0, 'missed': 0}
    for i in range(8):
        state = evaluator.standing_state(stance=stances[i % len(stances)])
        for name in state.joint_positions:
            state.joint_positions[name] += rng.uniform(-0.15, 0.15)
        result = evaluator.evaluate(state)
        legs = list(result.legs.values())
        np.testing.assert_array_equal(                          # NaN where NaN
            list(result.fws_directional_per_cycle.values()),
            list(evaluator.directional_at(legs, result.wrench).values()))
        P = np.array([leg.position for leg in legs])
        V = [leg.friction_polytope.vertices for leg in legs]
        wrenches = [result.wrench]
        for scale in (0.3, 0.9, 1.2, 3.0):
            x = np.zeros(6)
            for p, v in zip(P, V):
                f = v.T @ rng.dirichlet(np.ones(len(v)))
                x += np.concatenate([f, np.cross(p, f)])
            wrenches.append(result.wrench + 2.0 * scale * (x - result.wrench))
        wrenches.append(result.wrench * 40.0)
        for w in wrenches:
            got = evaluator.directional_at(legs, w)
            plus = np.array([got[a][0] for a in AXES])
            minus = np.array([got[a][1] for a in AXES])
            h_plus, h_minus = directional_margins(result.fws.polytope, w)
            _, l_plus, l_minus = lp_directional_margins(P, V, w)
            for mine, ref in ((plus, h_plus), (minus, h_minus), (plus, l_plus),
                              (minus, l_minus)):
                np.testing.assert_allclose(mine, ref, rtol=1e-7, atol=1e-5)
            other = evaluator.with_wrench(result, w)     # a planner's wrench: the same LPs
            np.testing.assert_array_equal(list(other.fws_directional_per_cycle.values()),
                                          list(got.values()))
            np.testing.assert_allclose(list(other.fws.directional.values()),
                                       list(got.values()), rtol=1e-7, atol=1e-5)
            for a, b in zip(plus, minus):                     # each axis' line
                seen['missed' if np.isnan(a) else 'inside' if min(a, b) >= 0 else 'outside'] += 1
    assert min(seen.values()) >= 20, seen


def test_directional_margins_every_cycle_only_with_three_or_more_legs():
    """Two stance legs: no per-cycle margins (the FWS's, at fws_rate_hz, answer)."""
    from awp_ros.evaluation.evaluator import FeasibilityEvaluator
    evaluator = FeasibilityEvaluator('hyq')
    result = evaluator.evaluate(evaluator.standing_state(stance=('lf_foot', 'rh_foot')),
                                fws=False)
    assert result.fws_directional_per_cycle is None
    assert evaluator.directional_at(list(result.legs.values()), result.wrench) is None


def _ray_exit(S, c, u) -> float:
    """Return where the ray ``c + t u`` leaves the H-rep ``S`` (c inside)."""
    a_u = S.A @ u
    ahead = a_u > 1e-12
    return float(np.min((S.b - S.A @ c)[ahead] / a_u[ahead]))


def _assert_distance(P, V, w, reference, S_A, S_b):
    """Assert fws_distance's answer at ``w`` against a margin on an H-rep ``S_A x <= S_b``."""
    d, nearest, bound, status = fws_queries.fws_distance(P, V, w)
    assert status == 0
    if reference.margin >= 1e-3:                  # inside: the nearest point is w itself
        assert d <= 1e-6
        return 'inside'
    assert d == pytest.approx(-reference.margin, abs=bound + 1e-9 * (1.0 + d))
    assert bound <= max(1e-6, 1e-9 * d) or d < 1e-4      # tight unless at the rounding floor
    assert np.max(S_A @ nearest - S_b) <= 1e-7 * (1.0 + np.abs(S_b).max())   # in S ...
    assert np.max(S_A @ nearest - S_b) >= -1e-6 * (1.0 + d)   # ... on its boundary
    if d > 1e-3:
        np.testing.assert_allclose((w - nearest) / d, reference.normal, atol=1e-6)
    return 'outside'


@pytest.mark.parametrize('K', [3, 4])
def test_fws_distance_is_the_least_distance_program_on_the_hrep(K):
    """
    Wolfe's nearest point and the H-rep's least-distance program give one distance.

    HyQ-like legs; wrenches on rays from a point inside, from far inside to 1e-5 N beyond
    the boundary and far outside: the distance, its witness, the nearest point in S and on
    its boundary.
    """
    rng = np.random.default_rng(40 + K)
    seen = {'inside': 0, 'outside': 0}
    for _ in range(3):
        V = [hyq_like_leg(rng) for _ in range(K)]
        P = hyq_feet(rng, K)
        S = minkowski_sum_of_lifts(P, V)
        c = vertex_sums(P, V).mean(axis=0)
        for _ in range(6):
            u = rng.normal(size=6)
            u /= np.linalg.norm(u)
            t = _ray_exit(S, c, u)
            for beyond in (-0.5 * t, 1e-5, 1e-2, 1.0, 100.0, 1e4):
                w = c + (t + beyond) * u
                seen[_assert_distance(P, V, w, polytope_margin(S, w), S.A, S.b)] += 1
    assert seen['outside'] == 5 * 18 and seen['inside'] == 18


def test_fws_distance_matches_qhull_on_small_sums():
    """Small sums (3 legs of 4-6 random points): qhull's hull of the vertex sums decides."""
    rng = np.random.default_rng(7)
    for _ in range(5):
        V = [rng.normal(scale=300.0, size=(int(rng.integers(4, 7)), 3)) + [0.0, 0.0, 200.0]
             for _ in range(3)]
        P = hyq_feet(rng, 3)
        hull = ConvexHull(vertex_sums(P, V))
        A, b = hull.equations[:, :6], -hull.equations[:, 6]
        S = Polytope(6, hull.points[hull.vertices], A, b, np.zeros(6), np.eye(6))
        c = hull.points[hull.vertices].mean(axis=0)
        for _ in range(6):
            u = rng.normal(size=6)
            u /= np.linalg.norm(u)
            w = c + (_ray_exit(S, c, u) + rng.choice([1e-3, 1.0, 300.0])) * u
            assert _assert_distance(P, V, w, polytope_margin(S, w), A, b) == 'outside'


def test_fws_distance_of_no_leg_points_and_bad_input():
    """A leg without points: status 3 (no set); shapes are checked."""
    P = np.zeros((2, 3))
    d, _, _, status = fws_queries.fws_distance(P, [np.ones((2, 3)), np.zeros((0, 3))], np.ones(6))
    assert status == 3 and d == np.inf
    with pytest.raises(InputError):
        fws_queries.fws_distance(P, [np.ones((2, 3))], np.ones(6))
    with pytest.raises(InputError):
        fws_queries.fws_distance(P, [np.ones((2, 3))] * 2, np.full(6, np.nan))


def test_outside_margin_of_points_is_polytope_margins_report():
    """The margin of a wrench outside, as polytope_margin reports it on the H-rep."""
    rng = np.random.default_rng(3)
    V = [hyq_like_leg(rng) for _ in range(4)]
    P = hyq_feet(rng, 4)
    S = minkowski_sum_of_lifts(P, V)
    c = vertex_sums(P, V).mean(axis=0)
    u = np.eye(6)[2]
    points = fws_queries.lifted_points(P, V)
    for beyond, feasible in ((20.0, False), (5e-7, True)):   # within feasibility_tol: feasible
        w = c + (_ray_exit(S, c, u) + beyond) * u
        got, problem = fws_queries.outside_margin_of_points(4, points, w, 1e-6)
        ref = polytope_margin(S, w, feasibility_tol=1e-6)
        assert problem == '' and got.feasible is feasible and ref.feasible is feasible
        assert got.margin == pytest.approx(ref.margin, abs=1e-7)
        assert got.margin_in_hull == got.margin and got.dimension == 6
        assert got.affine_residual == 0.0
        if beyond > 1.0:
            np.testing.assert_allclose(got.normal, ref.normal, atol=1e-9)
    none = (np.zeros((6, 0)), np.zeros(0, dtype=int), 1)
    assert fws_queries.outside_margin_of_points(4, none, c, 1e-6) == (None, '')
