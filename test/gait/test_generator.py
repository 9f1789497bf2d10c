"""The gait generator: feet where planned, no slip, crawl, lurch and trot, reproducible."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest
from scipy.spatial import ConvexHull

from awp_ros.errors import ConfigError, InputError, ModelError
from awp_ros.gait.generator import generate_gait
from awp_ros.gait.params import GaitParams, GRAVITY
from awp_ros.robot.config import load_config
from awp_ros.robot.model import RobotModel


@pytest.fixture(scope='module')
def hyq():
    config = load_config('hyq')
    return config, RobotModel(config)


@pytest.fixture(scope='module')
def gait(hyq):
    config, model = hyq
    return generate_gait(config, model=model)


def _world_feet(model: RobotModel, gait, i: int) -> np.ndarray:
    """Forward kinematics of sample i with the base pose: feet in the world [m]."""
    q = pin.neutral(model.model)
    q[:3], q[3:7], q[7:] = gait.base_position[i], gait.base_quaternion[i], gait.q[i]
    pin.framesForwardKinematics(model.model, model.data, q)
    return np.array([model.data.oMf[model.legs[f].frame_id].translation for f in gait.feet])


def test_default_gait_is_crawl_lurch_trot_at_500_hz_for_several_seconds(gait):
    assert gait.rate_hz == 500.0
    np.testing.assert_allclose(np.diff(gait.t), 1 / 500.0, atol=1e-12)
    assert gait.segments == (('crawl', 0.5, 4.9), ('lurch', 5.4, 7.6), ('trot', 8.1, 11.1))
    assert gait.infeasible == (('lurch', 6.3, 6.5),)
    assert len(gait) == 5801 and gait.t[-1] == pytest.approx(11.6)
    assert gait.q.shape == (len(gait), 12) and gait.v.shape == (len(gait), 12)
    assert len(gait.joint_names) == 12
    assert gait.feet == ('lf_foot', 'rf_foot', 'lh_foot', 'rh_foot')


def test_forward_kinematics_of_the_joint_angles_puts_the_feet_on_their_targets(hyq, gait):
    _, model = hyq
    for i in range(0, len(gait), 37):
        np.testing.assert_allclose(_world_feet(model, gait, i), gait.foot_positions[i],
                                   atol=1e-7)


def test_stance_feet_are_on_the_ground_and_swing_feet_above_it(gait):
    z = gait.foot_positions[..., 2]
    assert np.abs(z[gait.stance]).max() < 1e-9
    assert z[~gait.stance].min() >= 0.0
    assert z.max() == pytest.approx(0.08, abs=1e-3)        # swing height


def test_stance_feet_do_not_slip(hyq, gait):
    """
    Check that every stance foot's world velocity from the full model is zero.

    Joint velocities plus the base twist from the IMU rate and the differentiated base
    position.
    """
    _, model = hyq
    dt = 1.0 / gait.rate_hz
    lin_w = np.gradient(gait.base_position, dt, axis=0)
    worst = 0.0
    for i in range(5, len(gait) - 5, 7):
        q = pin.neutral(model.model)
        q[:3], q[3:7], q[7:] = gait.base_position[i], gait.base_quaternion[i], gait.q[i]
        R = pin.Quaternion(gait.base_quaternion[i][3], *gait.base_quaternion[i][:3]).matrix()
        v = np.concatenate([R.T @ lin_w[i], gait.angular_velocity[i], gait.v[i]])
        pin.forwardKinematics(model.model, model.data, q, v)
        for k, foot in enumerate(gait.feet):
            if gait.stance[i - 1:i + 2, k].all():
                vel = pin.getFrameVelocity(model.model, model.data, model.legs[foot].frame_id,
                                           pin.ReferenceFrame.LOCAL_WORLD_ALIGNED).linear
                worst = max(worst, float(np.abs(vel).max()))
    assert worst < 5e-3   # [m/s]; central differences at 500 Hz


def test_joint_angles_stay_within_the_urdf_limits(hyq, gait):
    _, model = hyq
    assert (gait.q >= model.model.lowerPositionLimit[7:]).all()
    assert (gait.q <= model.model.upperPositionLimit[7:]).all()


def _phase(gait, name):
    _, t0, t1 = next(s for s in gait.segments if s[0] == name)
    return (gait.t >= t0) & (gait.t < t1)


def test_crawl_lifts_one_foot_at_a_time_in_the_order_lh_lf_rh_rf(gait):
    crawl = _phase(gait, 'crawl')
    n_stance = gait.stance[crawl].sum(axis=1)
    assert n_stance.min() == 3 and set(np.unique(n_stance)) == {3, 4}
    lifted = gait.stance[crawl].argmin(axis=1)[n_stance == 3]
    order = [int(k) for k in lifted[np.r_[True, np.diff(lifted) != 0]]]
    assert [gait.feet[k] for k in order] == ['lh_foot', 'lf_foot', 'rh_foot', 'rf_foot']


def test_crawl_keeps_the_com_inside_the_support_triangle(hyq, gait):
    """Static stability, checked with qhull on the stance feet and Pinocchio's CoM."""
    _, model = hyq
    crawl = _phase(gait, 'crawl') & (gait.stance.sum(axis=1) == 3)
    margins = []
    for i in np.flatnonzero(crawl)[::25]:
        q = pin.neutral(model.model)
        q[:3], q[3:7], q[7:] = gait.base_position[i], gait.base_quaternion[i], gait.q[i]
        com = pin.centerOfMass(model.model, model.data, q)
        hull = ConvexHull(gait.foot_positions[i, gait.stance[i], :2])
        margins.append(-(hull.equations[:, :2] @ com[:2] + hull.equations[:, 2]).max())
    assert min(margins) > 0.05   # [m]
    np.testing.assert_allclose(gait.com[crawl][::25][:len(margins)][:, 2],
                               gait.com[crawl][0, 2], atol=0.02)


def test_body_sways_toward_the_stance_side_in_the_crawl(gait):
    crawl = _phase(gait, 'crawl')
    y = gait.com[crawl, 1]                         # the feet are at y = +-0.266 m
    assert y.max() > 0.03 and y.min() < -0.03      # [m], both ways
    x = gait.com[crawl, 0]
    assert x.max() - x.min() > 0.05                # and fore and aft


def test_trot_moves_diagonal_pairs_together(gait):
    trot = _phase(gait, 'trot')
    two = gait.stance[trot][gait.stance[trot].sum(axis=1) == 2]
    assert len(two) > 0.3 * trot.sum()
    pairs = {tuple(gait.feet[k] for k in np.flatnonzero(row)) for row in two}
    assert pairs == {('lf_foot', 'rh_foot'), ('rf_foot', 'lh_foot')}


def test_trot_advances_the_base_and_ends_at_rest(hyq, gait):
    _, model = hyq
    trot = _phase(gait, 'trot')
    x = gait.base_position[trot, 0]
    assert x[-1] - x[0] > 0.4
    assert np.diff(x).min() > -1e-9                # the trot never walks backwards
    _, t0, t1 = gait.segments[0]
    feet_x = gait.foot_positions[[round(t0 * gait.rate_hz), round(t1 * gait.rate_hz)], :, 0]
    assert np.ptp(feet_x.mean(axis=1)) == pytest.approx(0.10, abs=1e-9)   # 4 steps x 0.1 m
    # At rest at both ends, in the standing posture over the centre of the feet [m, rad/s].
    np.testing.assert_allclose(gait.base_position[-1, :2] - gait.base_position[0, :2],
                               gait.foot_positions[-1, :, :2].mean(axis=0)
                               - gait.foot_positions[0, :, :2].mean(axis=0), atol=1e-5)
    np.testing.assert_allclose(gait.q[[0, -1]], model.standing_q[None].repeat(2, 0), atol=1e-3)
    np.testing.assert_allclose(gait.v[[0, 1, -2, -1]], 0.0, atol=1e-5)
    assert gait.stance[-1].all() and gait.stance[0].all()


def test_imu_reads_gravity_when_standing_and_the_roll_rate_in_the_trot(gait):
    np.testing.assert_allclose(gait.specific_force[0], [0.0, 0.0, GRAVITY], atol=1e-9)
    np.testing.assert_allclose(gait.base_quaternion[0], [0, 0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(gait.base_quaternion, axis=1), 1.0, atol=1e-8)
    roll = 2.0 * np.arctan2(gait.base_quaternion[:, 0], gait.base_quaternion[:, 3])
    dt = 1.0 / gait.rate_hz
    np.testing.assert_allclose(gait.angular_velocity[1:-1, 0],
                               (roll[2:] - roll[:-2]) / (2 * dt), atol=1e-6)
    assert np.abs(roll).max() > 0.01


def test_generation_is_deterministic(hyq, gait):
    config, model = hyq
    again = generate_gait(config, model=model)
    for name in ('q', 'v', 'stance', 'foot_positions', 'base_quaternion', 'specific_force'):
        assert np.array_equal(getattr(gait, name), getattr(again, name)), name


def test_single_gaits_and_standing_alone(hyq):
    config, model = hyq
    stand = generate_gait(config, GaitParams(sequence=('stand',)), model=model)
    assert stand.stance.all()
    np.testing.assert_allclose(stand.q, np.tile(model.standing_q, (len(stand), 1)), atol=1e-9)
    trot = generate_gait(config, GaitParams(sequence=('trot',), trot_cycles=1), model=model)
    assert [s[0] for s in trot.segments] == ['trot'] and trot.infeasible == ()
    lurch = generate_gait(config, GaitParams(sequence=('lurch',), lurch_foot='rh'), model=model)
    assert lurch.segments == (('lurch', 0.5, 2.7),) and lurch.infeasible == (('lurch', 1.4, 1.6),)
    lifted = ~lurch.stance.all(axis=1)
    assert {lurch.feet[k] for k in np.flatnonzero(~lurch.stance[lifted].all(axis=0))} == {
        'rh_foot'}


def test_bad_parameters_and_unreachable_steps_raise(hyq):
    config, model = hyq
    with pytest.raises(InputError, match='unknown gaits'):
        GaitParams(sequence=('gallop',))
    with pytest.raises(InputError, match='trot_duty'):
        GaitParams(trot_duty=0.4)
    with pytest.raises(InputError, match='lurch_foot'):
        GaitParams(lurch_foot='left')
    with pytest.raises(InputError, match='before the foot is down'):
        GaitParams(lurch_delay_s=1.0, lurch_s=0.6, lurch_lift_s=1.5)
    with pytest.raises(InputError, match='balance_iterations'):
        GaitParams(balance_iterations=0)
    with pytest.raises(ModelError, match='out of reach|leaves its limits'):
        generate_gait(config, GaitParams(sequence=('crawl',), crawl_step_m=0.9), model=model)
    with pytest.raises(ConfigError, match='standing_posture'):
        generate_gait(replace(config, standing_posture={}))
