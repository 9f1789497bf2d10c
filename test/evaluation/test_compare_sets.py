"""The FWP-versus-FWS comparison: a sizeable share of the FWP is outside the FWS."""

from __future__ import annotations

import numpy as np
from scipy.optimize import linprog

from awp_ros.evaluation.compare_sets import fraction_outside_fws
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.wrench.wrench_polytope import lift_matrices


def test_part_of_the_fwp_is_not_producible_by_one_force_distribution():
    evaluator = FeasibilityEvaluator('hyq')
    share = fraction_outside_fws(evaluator, samples=400, burn_in=200)
    assert 0.1 < share < 0.9


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
