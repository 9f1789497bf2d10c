"""
Tests of awp_ros.estimation.motion: joint states + IMU (+ odometry) -> RobotState -> wrench.

The whole chain (MotionEstimator -> RobotState -> resolve_state -> RobotModel ->
FeasibilityEvaluator) is checked against Pinocchio truth computed from the analytic
trajectory (test/estimation/motion_truth.py): the gravito-inertial wrench from finite
differences of the CoM and of the centroidal angular momentum at the true q(t), v(t), the
bias torques from ``rnea`` at the true dv/dt.
"""

from __future__ import annotations

import math

from motion_truth import Trajectory, Truth
import numpy as np
import pinocchio as pin
import pytest

from awp_ros.errors import ConfigError, InputError
from awp_ros.estimation.filters import group_delay
from awp_ros.estimation.motion import MotionEstimator
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.robot.state import resolve_state

G = 9.81
RATE_HZ = 500.0
STEP_NS = 2_000_000
START_NS = 1_700_000_000 * 1_000_000_000
SETTLE_S = 0.3
IMU = 'trunk_imu'
#: Cut-off of the chain test [Hz]. Its residual error is the lag: the parts of w fed by
#: alpha and q'' (about 80 N.m of L' here) arrive tau_g late, an error of about
#: W tau_g 80 N.m = 1.7 N.m at 100 Hz (W = 2 pi 1.5 Hz), 5.6 N.m at the default 30 Hz.
CHAIN_CUTOFF_HZ = 100.0
DEFAULT_CUTOFF_HZ = 30.0


@pytest.fixture(scope='module')
def evaluator() -> FeasibilityEvaluator:
    return FeasibilityEvaluator('hyq')


def _whole_body(model, v0=(0.0, 0.0, 0.0)) -> Trajectory:
    """Return base sway +-4 cm, rotation +-0.06 rad (3 axes), every joint +-0.15 rad."""
    n = len(model.joint_names)
    return Trajectory(q0=model.standing_q, v0=np.array(v0), amp_p=np.array([0.04, 0.04, 0.03]),
                      phase_p=np.array([0.0, 1.1, 2.3]), amp_r=np.array([0.06, 0.06, 0.06]),
                      phase_r=np.array([0.4, 1.9, 3.0]), amp_q=np.full(n, 0.15),
                      phase_q=0.3 + 2.0 * np.pi * np.arange(n) / n)


def _feed(est: MotionEstimator, truth: Truth, t: float, k: int, *, odometry: bool,
          joint_velocities: bool = True):
    """Feed one sample (odometry, IMU, joints, same stamp) and return the estimate."""
    traj = truth.traj
    stamp = START_NS + k * STEP_NS
    if odometry:
        v = traj.velocity(t)
        est.add_odometry(stamp, traj.configuration(t)[3:7], v[:3], v[3:6])
    quat, omega, force = truth.imu_reading(t)
    est.add_imu(stamp, quat, omega, force)
    return est.add_joints(stamp, traj.joints(t),
                          traj.joint_velocities(t) if joint_velocities else None)


def _legs_bias(evaluator, state):
    """Return the bias torques of the chain (resolve_state -> RobotModel.kinematics)."""
    model = evaluator.model
    s = resolve_state(state, model.joint_names, evaluator.feet)
    kin = model.kinematics(s.q, s.stance, quaternion=s.quaternion, v=s.v, a=s.a)
    return dict(zip(s.stance, kin.bias))


def _chain(evaluator, traj, cutoffs, *, odometry, duration=1.0):
    """
    Run the chain at each cut-off; return per cut-off the per-sample errors after settling.

    ``force`` / ``moment``: |w - w_true| [N], [N.m]; ``bias``: max |b - rnea(q, v, a)| over
    joints [N.m]; ``bias_lag``: the same for the documented lag alone, rnea with alpha and
    q'' delayed by tau_g and the base acceleration moved by the lever arm, -(d alpha x r);
    ``bias_residual``: max |b - rnea(lagged a)|.
    """
    model = evaluator.model
    truth = Truth(model.model, traj, IMU)
    ests = {fc: MotionEstimator(model, imu_frame=IMU, cutoff_hz=fc) for fc in cutoffs}
    lever = ests[cutoffs[0]].imu_mount.translation
    data = model.model.createData()
    out = {fc: {key: [] for key in ('force', 'moment', 'bias', 'bias_lag', 'bias_residual')}
           for fc in cutoffs}
    for k in range(int(duration * RATE_HZ)):
        t = k / RATE_HZ
        estimates = {fc: _feed(est, truth, t, k, odometry=odometry)
                     for fc, est in ests.items()}
        if t < SETTLE_S:
            continue
        w_true = truth.wrench(t)
        q, v, a = traj.configuration(t), traj.velocity(t), traj.acceleration(t)
        b_true = pin.rnea(model.model, data, q, v, a).copy()
        for fc, e in estimates.items():
            assert e.settled and e.imu_stamp_ns == e.stamp_ns
            state = e.to_state()
            w = evaluator.evaluate(state, fws=False).wrench
            out[fc]['force'].append(np.linalg.norm(w[:3] - w_true[:3]))
            out[fc]['moment'].append(np.linalg.norm(w[3:] - w_true[3:]))
            a_lag = traj.acceleration(t - group_delay(fc))
            d_alpha = a_lag[3:6] - a[3:6]
            lagged = a.copy()
            lagged[:3] -= np.cross(d_alpha, lever)
            lagged[3:] = a_lag[3:]
            b_lag = pin.rnea(model.model, data, q, v, lagged).copy()
            bias = _legs_bias(evaluator, state)
            idx = {foot: model.legs[foot].v_idx for foot in bias}
            out[fc]['bias'].append(max(np.abs(b - b_true[idx[f]]).max()
                                       for f, b in bias.items()))
            out[fc]['bias_lag'].append(np.abs(b_lag - b_true)[6:].max())
            out[fc]['bias_residual'].append(max(np.abs(b - b_lag[idx[f]]).max()
                                                for f, b in bias.items()))
    return {fc: {key: np.array(v) for key, v in d.items()} for fc, d in out.items()}


# -- the whole chain, sinusoidal motion ---------------------------------------------------------


def test_chain_imu_only_matches_the_pinocchio_truth(evaluator):
    model = evaluator.model
    mg = model.total_mass * G
    errors = _chain(evaluator, _whole_body(model), (CHAIN_CUTOFF_HZ, DEFAULT_CUTOFF_HZ),
                    odometry=False)
    e = errors[CHAIN_CUTOFF_HZ]
    assert e['force'].max() <= 0.03 * mg
    assert e['moment'].max() <= 3.0
    # Bias torques: their error is the filters' lag (rnea with the delayed accelerations,
    # to 5 % of that lag's effect), and bounded by it.
    assert e['bias_residual'].max() <= 0.05 * e['bias_lag'].max()
    assert e['bias'].max() <= 1.1 * e['bias_lag'].max()
    # At the default cut-off the errors grow like the lag: tau_g(30) / tau_g(100) = 10 / 3.
    d = errors[DEFAULT_CUTOFF_HZ]
    ratio = group_delay(DEFAULT_CUTOFF_HZ) / group_delay(CHAIN_CUTOFF_HZ)
    for key in ('force', 'moment', 'bias'):
        assert d[key].max() / e[key].max() == pytest.approx(ratio, rel=0.15), key
    assert d['force'].max() <= 0.03 * mg
    assert d['bias_residual'].max() <= 0.05 * d['bias_lag'].max()


def test_chain_with_odometry_and_forward_velocity_matches_the_truth(evaluator):
    # Base linear velocity (odometry) and angular velocity both non-zero: the classical ->
    # spatial correction of resolve_state is exercised (2 m |omega x v| is ~ 80 N here).
    model = evaluator.model
    traj = _whole_body(model, v0=(0.5, 0.2, 0.0))
    e = _chain(evaluator, traj, (CHAIN_CUTOFF_HZ,), odometry=True, duration=0.8)
    e = e[CHAIN_CUTOFF_HZ]
    assert e['force'].max() <= 0.03 * model.total_mass * G
    assert e['moment'].max() <= 3.0
    assert e['bias_residual'].max() <= 0.05 * e['bias_lag'].max()


# -- the whole chain, uniform motion (exact) ----------------------------------------------------


@pytest.mark.parametrize('odometry', [True, False])
def test_uniform_screw_motion_with_spinning_joints_is_exact(evaluator, odometry):
    # A constant body twist (v and omega non-zero: classical base acceleration omega x v)
    # and joints at constant velocity (centripetal and Coriolis terms only): every
    # differentiated input is a ramp, which the filters differentiate exactly, so the
    # wrench and the bias torques match the truth to the finite differences' accuracy.
    # Without odometry the base's linear velocity is unknown (0): the same result.
    model = evaluator.model
    qdot = np.array([2.0, -1.5, 1.8, -2.2, 1.2, -1.6, 1.7, -2.0, 1.4, -1.3, 2.1, -1.9])
    traj = Trajectory(q0=model.standing_q, twist=np.array([0.8, -0.3, 0.1, 0.3, -0.4, 0.6]),
                      qdot0=qdot)
    truth = Truth(model.model, traj, IMU)
    est = MotionEstimator(model, imu_frame=IMU)
    data = model.model.createData()
    for k in range(12):
        t = k / RATE_HZ
        e = _feed(est, truth, t, k, odometry=odometry)
        if k < 2:
            continue
        np.testing.assert_allclose(e.joint_accelerations, 0.0, atol=1e-9)
        np.testing.assert_allclose(e.base_acceleration[3:], 0.0, atol=1e-9)
        state = e.to_state()
        w = evaluator.evaluate(state, fws=False).wrench
        np.testing.assert_allclose(w, truth.wrench(t), atol=1e-3)
        b_true = pin.rnea(model.model, data, traj.configuration(t), traj.velocity(t),
                          traj.acceleration(t))
        for foot, b in _legs_bias(evaluator, state).items():
            np.testing.assert_allclose(b, b_true[model.legs[foot].v_idx], atol=1e-4)


# -- joint positions only -----------------------------------------------------------------------


def test_positions_only_velocities_lag_tau_and_accelerations_two_tau(evaluator):
    model = evaluator.model
    traj = _whole_body(model)
    truth = Truth(model.model, traj, IMU)
    est = MotionEstimator(model, imu_frame=IMU)
    tau = group_delay(est.cutoff_hz)
    omega = traj.omega
    amp_v, amp_a = 0.15 * omega, 0.15 * omega ** 2
    x = 1.5 / est.cutoff_hz
    small = 4.0 * (math.sqrt(2.0) / 3.0 * x ** 3 + x ** 4) + (omega / RATE_HZ) ** 2 / 6.0
    for k in range(int(0.8 * RATE_HZ)):
        t = k / RATE_HZ
        e = _feed(est, truth, t, k, odometry=False, joint_velocities=False)
        assert not e.velocities_measured
        if t < SETTLE_S:
            continue
        assert e.settled
        np.testing.assert_allclose(e.joint_positions, traj.joints(t), atol=1e-15)
        np.testing.assert_allclose(e.joint_velocities, traj.joint_velocities(t - tau),
                                   atol=small * amp_v)
        np.testing.assert_allclose(e.joint_accelerations,
                                   traj.joint_accelerations(t - 2.0 * tau),
                                   atol=small * amp_a)


# -- pairing, sources, determinism ----------------------------------------------------------


def _imu_at_rest(est, stamp, omega_z=0.0):
    """Add a level, resting IMU reading (trunk_imu is flipped: z down) with yaw rate."""
    flip = np.array([0.0, 1.0, 0.0, 0.0])       # 180 deg about y, [x, y, z, w]
    return est.add_imu(stamp, flip, [0.0, 0.0, -omega_z], [0.0, 0.0, -G])


def test_imu_paired_is_the_newest_at_or_before_the_joint_stamp(evaluator):
    model = evaluator.model
    est = MotionEstimator(model, imu_frame=IMU, max_imu_age_s=0.01)
    q = model.standing_q
    e = est.add_joints(START_NS, q, np.zeros(len(q)))
    assert e.imu_stamp_ns is None and e.orientation_source == 'level'
    for k, rate in enumerate([0.1, 0.2, 0.3]):
        _imu_at_rest(est, START_NS + k * STEP_NS, rate)
    # A joint state between the 2nd and 3rd IMU stamps uses the 2nd.
    e = est.add_joints(START_NS + STEP_NS + 1, q, np.zeros(len(q)))
    assert e.imu_stamp_ns == START_NS + STEP_NS
    assert e.base_twist[5] == pytest.approx(0.2)
    # At the 3rd IMU's stamp: the 3rd.
    e = est.add_joints(START_NS + 2 * STEP_NS, q, np.zeros(len(q)))
    assert e.imu_stamp_ns == START_NS + 2 * STEP_NS and e.orientation_source == 'imu'
    # Too old (> max_imu_age_s): not used.
    e = est.add_joints(START_NS + 2 * STEP_NS + 10_000_001, q, np.zeros(len(q)))
    assert e.imu_stamp_ns is None
    np.testing.assert_array_equal(e.base_twist, 0.0)
    np.testing.assert_array_equal(e.base_orientation, [0.0, 0.0, 0.0, 1.0])


def test_orientation_and_twist_sources(evaluator):
    model = evaluator.model
    q, zero = model.standing_q, np.zeros(len(model.standing_q))
    quat = pin.Quaternion(pin.rpy.rpyToMatrix(0.1, -0.2, 0.3)).coeffs().copy()
    # Odometry only: its orientation and twist, no acceleration.
    est = MotionEstimator(model, imu_frame=IMU)
    est.add_odometry(START_NS, quat, [0.5, 0.0, 0.0], [0.0, 0.0, 0.4])
    e = est.add_joints(START_NS, q, zero)
    assert e.orientation_source == 'odometry' and e.odometry_stamp_ns == START_NS
    np.testing.assert_allclose(e.base_orientation, quat)
    np.testing.assert_allclose(e.base_twist, [0.5, 0, 0, 0, 0, 0.4])
    np.testing.assert_array_equal(e.base_acceleration, 0.0)
    # An IMU without orientation uses the odometry's; its rate replaces odometry's.
    R_wi = pin.rpy.rpyToMatrix(0.1, -0.2, 0.3) @ est.imu_mount.rotation
    est.add_imu(START_NS + 1, None, [0.0, 0.0, 0.0], R_wi.T @ [0.0, 0.0, G])
    e = est.add_joints(START_NS + 1, q, zero)
    assert e.orientation_source == 'given'
    np.testing.assert_allclose(e.base_orientation, quat, atol=1e-12)
    np.testing.assert_allclose(e.base_twist, [0.5, 0, 0, 0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(e.base_acceleration, 0.0, atol=1e-12)


def test_same_inputs_give_identical_estimates(evaluator):
    # A pure function of the input sequence: two estimators (live node, replay) and one
    # reset in between give bitwise-identical estimates, with jittery stamps.
    model = evaluator.model
    traj = _whole_body(model, v0=(0.3, 0.0, 0.0))
    truth = Truth(model.model, traj, IMU)
    rng = np.random.default_rng(11)
    inputs = []
    for k in range(60):
        t = k / RATE_HZ
        stamp = START_NS + k * STEP_NS + int(rng.integers(-300_000, 300_000))
        v = traj.velocity(t)
        inputs.append(('odom', stamp, traj.configuration(t)[3:7], v[:3], v[3:6]))
        inputs.append(('imu', stamp, *truth.imu_reading(t)))
        inputs.append(('joints', stamp + 1000, traj.joints(t), traj.joint_velocities(t)))

    def replay(est):
        out = []
        for kind, stamp, *args in inputs:
            if kind == 'odom':
                est.add_odometry(stamp, *args)
            elif kind == 'imu':
                est.add_imu(stamp, *args)
            else:
                out.append(est.add_joints(stamp, *args))
        return out

    a = replay(MotionEstimator(model, imu_frame=IMU))
    est = MotionEstimator(model, imu_frame=IMU)
    replay(est)
    est.reset()
    b = replay(est)
    for x, y in zip(a, b):
        for name in ('joint_velocities', 'joint_accelerations', 'base_orientation',
                     'base_twist', 'base_acceleration'):
            np.testing.assert_array_equal(getattr(x, name), getattr(y, name))
        assert x.state_fields() == y.state_fields()


def test_configuration_and_input_errors(evaluator):
    model = evaluator.model
    est = MotionEstimator(model)
    with pytest.raises(ConfigError, match='IMU frame is known'):
        _imu_at_rest(est, START_NS)
    with pytest.raises(ConfigError, match="'imu_link' is not in the URDF.*'trunk_imu'"):
        est.set_imu_frame('imu_link')
    est.set_imu_frame(IMU)
    assert est.imu_mount.frame == IMU
    with pytest.raises(InputError, match='joint positions must be 12 numbers'):
        est.add_joints(START_NS, np.zeros(11))
    with pytest.raises(InputError, match='joint velocities are not all finite'):
        est.add_joints(START_NS, np.zeros(12), np.full(12, math.nan))
    with pytest.raises(InputError, match='zero quaternion'):
        est.add_odometry(START_NS, [0, 0, 0, 0], [0, 0, 0], [0, 0, 0])


def test_a_twist_without_base_acceleration_means_no_classical_acceleration(evaluator):
    # resolve_state: an absent base_acceleration is a classical zero even with a twist
    # (forward 1 m/s while yawing 1 rad/s); it used to be a spatial zero, i.e. a classical
    # omega x v, a spurious m |omega x v| = 85 N sideways here.
    twist = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    implicit = evaluator.evaluate(evaluator.standing_state(base_twist=twist), fws=False)
    explicit = evaluator.evaluate(evaluator.standing_state(base_twist=twist,
                                                           base_acceleration=[0.0] * 6),
                                  fws=False)
    np.testing.assert_allclose(implicit.wrench, explicit.wrench, atol=1e-9)
    # And the same as a base translating without rotating, up to the CoM's own
    # centripetal acceleration -omega^2 (c - p) (omega about z).
    still = evaluator.evaluate(evaluator.standing_state(), fws=False)
    c_xy = np.array([still.com[0], still.com[1], 0.0])
    np.testing.assert_allclose(implicit.wrench[:3], still.wrench[:3] - still.mass * c_xy,
                               atol=1e-6)
