"""FeasibilityEvaluator.evaluate_many: one result per state, equal to evaluate's."""

from __future__ import annotations

import numpy as np
import pytest

from awp_ros.errors import InputError
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.robot.state import RobotState

FEET = ('lf_foot', 'rf_foot', 'lh_foot', 'rh_foot')


@pytest.fixture(scope='module')
def evaluator():
    return FeasibilityEvaluator('hyq')


def _states(evaluator, n: int, seed: int = 0) -> list[RobotState]:
    """Random postures around standing; stances of 0-4 feet and contacts interleaved."""
    rng = np.random.default_rng(seed)
    names = list(evaluator.model.joint_names)
    q0 = evaluator.model.standing_q
    out = []
    for i in range(n):
        stance = [f for f in FEET if rng.random() < 0.75] if i % 7 else []
        kw = {}
        if i % 3 == 1:
            kw['friction_coefficients'] = {f: float(rng.uniform(0.3, 1.0)) for f in stance}
        if i % 4 == 2:
            kw['normals'] = {f: [0.1, -0.05, 1.0] for f in stance}
        if i % 5 == 3:
            kw['joint_velocities'] = dict(zip(names, rng.normal(size=q0.size).tolist()))
        out.append(RobotState(joint_positions=dict(zip(names, (
            q0 + rng.uniform(-0.1, 0.1, q0.size)).tolist())), stance=stance, **kw))
    return out


def _doc(result) -> dict:
    out = result.to_dict()
    del out['timings_ms']
    return out


@pytest.mark.parametrize('fws', [False, True])
def test_each_result_equals_evaluate_of_its_state(evaluator, fws):
    states = _states(evaluator, 30 if fws else 60)
    many = evaluator.evaluate_many(states, fws=fws)
    assert len(many) == len(states)
    for state, got in zip(states, many):
        want = evaluator.evaluate(state, fws=fws)
        assert _doc(got) == _doc(want)
        assert (got.fws is None) == (not fws)
    assert {len(r.stance) for r in many} == {0, 1, 2, 3, 4}


def test_wrenches_one_for_all_or_one_per_state(evaluator):
    states = _states(evaluator, 20, seed=1)
    rng = np.random.default_rng(2)
    W = np.array([0.0, 0.0, 850.0, 0.0, 0.0, 0.0]) + rng.normal(size=(20, 6)) * 100.0
    for wrenches, row in ((W, lambda i: W[i]), (W[3], lambda i: W[3]),
                          (W[3].tolist(), lambda i: W[3])):
        many = evaluator.evaluate_many(states, fws=True, wrenches=wrenches)
        for i, (state, got) in enumerate(zip(states, many)):
            np.testing.assert_array_equal(got.wrench, row(i))
            assert _doc(got) == _doc(evaluator.evaluate(state, fws=True, wrench=row(i)))


def test_bad_input_is_refused_naming_it(evaluator):
    states = _states(evaluator, 5, seed=3)
    assert evaluator.evaluate_many([]) == []
    with pytest.raises(InputError, match=r'\(5, 6\), got shape \(4, 6\)'):
        evaluator.evaluate_many(states, wrenches=np.zeros((4, 6)))
    with pytest.raises(InputError, match='finite'):
        evaluator.evaluate_many(states, wrenches=[0, 0, np.nan, 0, 0, 0])
    bad = RobotState(joint_positions={**states[2].joint_positions, 'arm_joint': 0.0})
    with pytest.raises(InputError, match=r"state 3: .*unknown joints \['arm_joint'\]"):
        evaluator.evaluate_many(states[:3] + [bad] + states[3:])
