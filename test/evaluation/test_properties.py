"""
Property tests of the feasibility core (hypothesis): what must hold for every posture.

- random valid postures, stance sets, orientations and mu raise nothing;
- margins are continuous under tiny posture perturbations;
- adding a stance leg whose polytopes contain the origin never shrinks the AWP or FWP
  margin of a wrench inside them (the sets can only grow: W ⊆ W ⊕ L_k F_k when 0 ∈ F_k);
- scaling every torque limit by s > 1 never decreases any margin (F_k(τ) ⊆ F_k(sτ) when
  τ_min <= 0 <= τ_max, so every set grows).
"""

from __future__ import annotations

import dataclasses
from functools import lru_cache

from hypothesis import assume, given, HealthCheck, settings, strategies as st
import numpy as np
import pinocchio as pin
import pytest

from awp_ros import FeasibilityEvaluator, InputError, load_config, RobotState
from awp_ros.robot.model import resolve_urdf

FEET = ('lf_foot', 'rf_foot', 'lh_foot', 'rh_foot')
SETTINGS = settings(max_examples=40, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])


@lru_cache(maxsize=None)
def evaluator(scale: float = 1.0) -> FeasibilityEvaluator:
    """Return a HyQ evaluator with every torque limit multiplied by ``scale``."""
    config = load_config('hyq')
    if scale != 1.0:
        model = FeasibilityEvaluator(config).model
        limits = {j: (scale * lo, scale * hi) for leg in model.legs.values()
                  for j, lo, hi in zip(leg.joints, leg.tau_min, leg.tau_max)}
        config = dataclasses.replace(config, torque_limits=limits)
    return FeasibilityEvaluator(config)


def posture(offsets) -> dict[str, float]:
    """Return HyQ's standing posture plus ``offsets`` [rad], clipped to the joint limits."""
    model = evaluator().model
    lo, hi = model.position_limits
    q = np.clip(model.standing_q + np.asarray(offsets), lo, hi)
    return dict(zip(model.joint_names, q.tolist()))


@lru_cache(maxsize=None)
def pinocchio_model():
    """Return HyQ's Pinocchio model and data, built here from the URDF (free flyer)."""
    config = load_config('hyq')
    kind, src = resolve_urdf(config.urdf, config.base_dir)
    build = pin.buildModelFromXML if kind == 'xml' else pin.buildModelFromUrdf
    model = build(src, pin.JointModelFreeFlyer())
    return model, model.createData()


def origin_in_force_polytope(joints: dict[str, float], foot: str) -> bool:
    """Return whether f = 0 is in the leg's force polytope: tau_min <= rnea(q) <= tau_max."""
    model, data = pinocchio_model()
    q = pin.neutral(model)
    for j in range(2, model.njoints):
        q[model.joints[j].idx_q] = joints[model.names[j]]
    tau = pin.rnea(model, data, q, np.zeros(model.nv), np.zeros(model.nv))
    leg = evaluator().model.legs[foot]
    idx = [model.joints[model.getJointId(n)].idx_v for n in leg.joints]
    return bool(np.all(leg.tau_min < tau[idx]) and np.all(tau[idx] < leg.tau_max))


offsets = st.lists(st.floats(-0.4, 0.4), min_size=12, max_size=12)
stances = st.lists(st.sampled_from(FEET), unique=True, max_size=4)
quaternions = st.tuples(*[st.floats(-0.15, 0.15)] * 3).map(
    lambda v: (*v, float(np.sqrt(max(0.0, 1.0 - np.dot(v, v))))))


@SETTINGS
@given(offsets, stances, quaternions, st.floats(0.05, 1.5))
def test_random_states_raise_nothing_but_input_errors(dq, stance, quat, mu):
    # Every generated state is valid (postures within the limits, unit quaternions, mu > 0):
    # nothing may raise, so a regression that raises InputError (or anything) fails here.
    state = RobotState(joint_positions=posture(dq), stance=stance, base_orientation=quat,
                       friction_coefficient=mu)
    result = evaluator().evaluate(state)
    assert result.stance == tuple(f for f in FEET if f in stance)
    for s in (result.awp, result.fwp, result.fws):
        assert np.isfinite(s.margin) and np.isfinite(s.normal).all()
    assert result.fws.margin <= result.fwp.margin + 1e-6 <= result.awp.margin + 2e-6


@SETTINGS
@given(offsets, st.lists(st.floats(-1.0, 1.0), min_size=12, max_size=12))
def test_margins_are_continuous_under_tiny_perturbations(dq, direction):
    eps = 1e-7
    base = evaluator().evaluate(RobotState(joint_positions=posture(dq)))
    moved = evaluator().evaluate(RobotState(
        joint_positions=posture(np.asarray(dq) + eps * np.asarray(direction))))
    for name in ('awp', 'fwp', 'fws'):
        a, b = getattr(base, name).margin, getattr(moved, name).margin
        # Margins move by at most a few N per milliradian here: 1e-7 rad moves them < 1e-2 N.
        assert abs(a - b) < 1e-2, (name, a, b)


@SETTINGS
@given(offsets, st.sampled_from(FEET))
def test_adding_a_leg_containing_the_origin_never_shrinks_awp_or_fwp(dq, extra):
    joints = posture(dq)
    three = [f for f in FEET if f != extra]
    r3 = evaluator().evaluate(RobotState(joint_positions=joints, stance=three), fws=False)
    r4 = evaluator().evaluate(RobotState(joint_positions=joints, stance=list(FEET)), fws=False)
    # The precondition 0 in F_k, from Pinocchio directly: the bias torques at f = 0 are
    # within the limits.
    assume(origin_in_force_polytope(joints, extra))
    assert r4.legs[extra].force_polytope.contains(np.zeros(3), tol=1e-6)
    assert r3.awp.dimension == r4.awp.dimension == 6
    for name in ('awp', 'fwp'):
        m3, m4 = getattr(r3, name).margin, getattr(r4, name).margin
        if m3 >= 0.0:
            assert m4 >= m3 - 1e-6, (name, m3, m4)


@SETTINGS
@given(offsets, stances, st.sampled_from([1.1, 1.5, 3.0]))
def test_scaling_torque_limits_up_never_decreases_margins(dq, stance, scale):
    state = RobotState(joint_positions=posture(dq), stance=stance)
    base = evaluator().evaluate(state)
    scaled = evaluator(scale).evaluate(state)
    for name in ('awp', 'fwp', 'fws'):
        m0, m1 = getattr(base, name).margin, getattr(scaled, name).margin
        assert m1 >= m0 - 1e-6 * max(1.0, abs(m0)), (name, scale, m0, m1)


def test_the_origin_assumption_is_met_at_the_standing_posture():
    # Guards the 'adding a leg' property against vacuity: at the standing posture every
    # leg's force polytope contains 0 (gravity torques are well inside the limits).
    result = evaluator().evaluate(evaluator().standing_state(), fws=False)
    for leg in result.legs.values():
        assert leg.force_polytope.contains(np.zeros(3))


@pytest.mark.parametrize('bad', [
    {'lf_haa_joint': float('nan')},
    {'lf_haa_joint': float('inf')},
    {'no_such_joint': 0.0},
])
def test_bad_joint_values_are_input_errors(bad):
    joints = posture([0.0] * 12)
    if 'no_such_joint' in bad:
        joints = dict(joints, **bad)
    else:
        joints.update(bad)
    with pytest.raises(InputError):
        evaluator().evaluate(RobotState(joint_positions=joints))
