"""
The FWP-versus-FWS comparison: the hit-and-run share against an independent estimate.

The share of the FWP outside the FWS estimated by :func:`fraction_outside_fws` (a Markov
chain: hit-and-run) is compared with plain rejection sampling of the FWP's bounding box
(computed here by LPs on its H-rep), whose error is binomial; the chain's error is estimated
from independent chains (different seeds). Seeded: the outcome is deterministic.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog

from awp_ros.evaluation.compare_sets import fraction_outside_fws
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.wrench.wrench_polytope import lift_matrices

THREE_LEGS = ['lf_foot', 'rf_foot', 'rh_foot']


@pytest.fixture(scope='module')
def evaluator():
    return FeasibilityEvaluator('hyq')


def rejection_share(fwp, fws, rng, batches: int = 20, batch: int = 100_000):
    """Return (share outside the FWS, accepted samples) of uniform samples of the FWP."""
    lo, hi = np.zeros(6), np.zeros(6)
    for i in range(6):
        for sign, out in ((1.0, lo), (-1.0, hi)):
            res = linprog(sign * np.eye(6)[i], A_ub=fwp.A, b_ub=fwp.b,
                          bounds=[(None, None)] * 6, method='highs')
            assert res.status == 0
            out[i] = sign * res.fun
    accepted = outside = 0
    for _ in range(batches):
        X = rng.uniform(lo, hi, size=(batch, 6))
        Y = X[np.all(X @ fwp.A.T <= fwp.b, axis=1)]
        accepted += len(Y)
        outside += int(np.sum(~np.all(Y @ fws.A.T <= fws.b + 1e-9, axis=1)))
    return outside / accepted, accepted


@pytest.mark.parametrize('mu', [0.7, 0.5])
def test_hit_and_run_share_agrees_with_rejection_sampling(evaluator, mu):
    r = evaluator.evaluate(evaluator.standing_state(stance=THREE_LEGS,
                                                    friction_coefficient=mu))
    assert r.fwp.dimension == 6 and r.fwp.margin > 0.0
    p, n = rejection_share(r.fwp.polytope, r.fws.polytope, np.random.default_rng(7))
    assert n > 5000
    se_rejection = np.sqrt(p * (1.0 - p) / n)
    chains = np.array([fraction_outside_fws(evaluator, stance=THREE_LEGS, mu=mu,
                                            samples=1500, burn_in=500, seed=seed)
                       for seed in range(8)])
    # The chains' own spread gives the standard error of their mean (at least that of 1500
    # independent samples per chain: a chain cannot beat independent sampling).
    se_chain = max(chains.std(ddof=1), np.sqrt(p * (1.0 - p) / 1500)) / np.sqrt(len(chains))
    tol = 4.0 * np.hypot(se_rejection, se_chain)
    assert tol < 0.05                                  # tight enough to mean something
    assert abs(chains.mean() - p) < tol, (chains.mean(), p, tol)
    # Neither set is the other: the share is far from 0 and 1 (FWS strictly inside FWP).
    assert 10 * tol < p < 1.0 - 10 * tol


def test_a_wrench_in_the_fwp_but_not_the_fws_has_no_single_distribution():
    # Independent check of one such wrench with an LP on the FWS definition.
    evaluator = FeasibilityEvaluator('hyq')
    result = evaluator.evaluate(evaluator.standing_state())
    fwp, fws = result.fwp.polytope, result.fws.polytope
    rng = np.random.default_rng(3)
    w = None
    for _ in range(2000):
        x = result.wrench + rng.normal(scale=300.0, size=6)
        if fwp.contains(x) and not fws.contains(x, tol=1e-6):
            w = x
            break
    assert w is not None
    L = lift_matrices(np.array([leg.position for leg in result.legs.values()]))
    A_eq = np.hstack(list(L))                               # sum_k L_k f_k = w
    blocks = [leg.friction_polytope for leg in result.legs.values()]
    A_ub = np.zeros((sum(len(Q.b) for Q in blocks), 12))
    row = 0
    for k, Q in enumerate(blocks):
        A_ub[row:row + len(Q.b), 3 * k:3 * k + 3] = Q.A
        row += len(Q.b)
    b_ub = np.concatenate([Q.b for Q in blocks])
    lp = linprog(np.zeros(12), A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=w,
                 bounds=[(None, None)] * 12)
    assert lp.status == 2  # infeasible: no single distribution
