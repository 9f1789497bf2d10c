"""
Tests of awp_ros.wrench.fws_queries: LP membership and directional margins of the FWS.

Checked against an independent method, the exact H-rep of the same Minkowski sum
(:func:`awp_ros.wrench.feasible_wrench_set.minkowski_sum_of_lifts`) with the ratio test of
:func:`awp_ros.geometry.margin.directional_margins`, and against scipy's ``linprog`` (no warm
start).
"""

from __future__ import annotations

import numpy as np
import pytest

from awp_ros.geometry.margin import directional_margins, polytope_margin
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
