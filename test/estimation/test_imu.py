"""
Tests of awp_ros.estimation.imu: the IMU mounting from HyQ's URDF and the base motion.

The IMU readings are synthesised from Pinocchio's placement of the IMU frame along an
analytic base motion (second differences of the IMU point's world position, the log of the
IMU frame's relative rotation): they never go through the converter's formulas.
"""

from __future__ import annotations

import dataclasses
import math
import xml.etree.ElementTree as ET

from motion_truth import Trajectory, Truth
import numpy as np
import pinocchio as pin
import pytest

from awp_ros.errors import ConfigError, InputError
from awp_ros.estimation.filters import group_delay
from awp_ros.estimation.imu import ImuConverter, ImuMount
from awp_ros.robot.config import load_config
from awp_ros.robot.model import resolve_urdf, RobotModel

G = 9.81
RATE_HZ = 500.0
SETTLE_S = 0.3
#: A second IMU, rigidly on the trunk with a rotation about every axis (origin in trunk).
TILTED_RPY = (0.3, -0.5, 1.2)
TILTED_XYZ = (-0.15, 0.12, 0.08)


def _hyq_urdf() -> str:
    config = load_config('hyq')
    kind, source = resolve_urdf(config.urdf, config.base_dir)
    assert kind == 'file'
    with open(source, encoding='utf-8') as f:
        return f.read()


def _with_links(urdf: str) -> str:
    """Add the tilted IMU on the trunk and an 'IMU' on a thigh (moved by lf_hfe_joint)."""
    extra = (
        '<link name="tilted_imu"/>'
        '<joint name="tilted_imu_joint" type="fixed">'
        f'<origin rpy="{" ".join(map(str, TILTED_RPY))}" '
        f'xyz="{" ".join(map(str, TILTED_XYZ))}"/>'
        '<parent link="trunk"/><child link="tilted_imu"/></joint>'
        '<link name="thigh_imu"/>'
        '<joint name="thigh_imu_joint" type="fixed"><origin xyz="0 0 -0.1"/>'
        '<parent link="lf_upperleg"/><child link="thigh_imu"/></joint>')
    return urdf.replace('</robot>', extra + '</robot>')


@pytest.fixture(scope='module')
def hyq() -> RobotModel:
    config = dataclasses.replace(load_config('hyq'), urdf=_with_links(_hyq_urdf()))
    return RobotModel(config)


def _rotation(rpy) -> np.ndarray:
    """Return Rz(yaw) Ry(pitch) Rx(roll) (URDF rpy), from elementary rotations."""
    r, p, y = rpy
    cx, sx, cy, sy, cz, sz = (math.cos(r), math.sin(r), math.cos(p), math.sin(p),
                              math.cos(y), math.sin(y))
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def _urdf_placement(urdf: str, child: str, base: str) -> tuple[np.ndarray, np.ndarray]:
    """Return (R, p) of link ``child`` in link ``base`` by composing the joints' origins."""
    joints = {j.find('child').get('link'): j for j in ET.fromstring(urdf).findall('joint')}
    R, p = np.eye(3), np.zeros(3)
    link = child
    while link != base:
        joint = joints[link]
        assert joint.get('type') == 'fixed'
        origin = joint.find('origin')
        Rj = _rotation([float(c) for c in origin.get('rpy', '0 0 0').split()])
        pj = np.array([float(c) for c in origin.get('xyz', '0 0 0').split()])
        R, p = Rj @ R, Rj @ p + pj
        link = joint.find('parent').get('link')
    return R, p


# -- mounting ---------------------------------------------------------------------------------


@pytest.mark.parametrize('frame', ['trunk_imu', 'tilted_imu', 'base_link'])
def test_mount_is_the_urdf_chain_from_the_base_link(hyq, frame):
    mount = ImuMount.from_model(hyq.model, frame)
    R, p = _urdf_placement(hyq.config.urdf, frame, 'base_link')
    assert mount.frame == frame and mount.base_frame == 'base_link'
    np.testing.assert_allclose(mount.rotation, R, atol=1e-9)
    np.testing.assert_allclose(mount.translation, p, atol=1e-9)
    np.testing.assert_allclose(pin.Quaternion(mount.quaternion).toRotationMatrix(), R,
                               atol=1e-9)
    if frame == 'trunk_imu':
        np.testing.assert_allclose(p, [0.29, 0.0, 0.0999214], atol=1e-9)


def test_unknown_frame_raises_with_close_names(hyq):
    with pytest.raises(ConfigError, match=r"'trunk_imu_link' is not in the URDF.*'trunk_imu'"):
        ImuMount.from_model(hyq.model, 'trunk_imu_link')
    with pytest.raises(ConfigError, match=r"'imu' is not in the URDF.*'tilted_imu'"):
        ImuMount.from_model(hyq.model, 'imu')


@pytest.mark.parametrize('frame,joint', [('thigh_imu', 'lf_hfe_joint'),
                                         ('lf_foot', 'lf_kfe_joint')])
def test_frame_moved_by_a_joint_is_refused(hyq, frame, joint):
    with pytest.raises(ConfigError, match=f"'{frame}' is not rigidly attached to the base: "
                                          f"joint '{joint}'"):
        ImuMount.from_model(hyq.model, frame)


# -- conversion -------------------------------------------------------------------------------


def _rigid_motion(model: RobotModel) -> Trajectory:
    """Return HyQ's trunk swaying +-4 cm and rotating +-0.06 rad about x, y, z at 1.5 Hz."""
    return Trajectory(q0=model.standing_q, amp_p=np.array([0.04, 0.04, 0.03]),
                      phase_p=np.array([0.0, 1.1, 2.3]), amp_r=np.array([0.06, 0.06, 0.06]),
                      phase_r=np.array([0.4, 1.9, 3.0]))


@pytest.mark.parametrize('frame', ['trunk_imu', 'tilted_imu'])
def test_rigid_motion_recovers_the_base_motion(hyq, frame):
    # The orientation and angular velocity are the reading's, transformed: exact up to the
    # finite differences. The angular acceleration is the documented delay of the truth
    # (tau_g), so its error is the lag error; the base acceleration's only filtered input is
    # alpha, through the lever arm: |a - a_true| <= |r| |alpha - alpha_true|.
    traj = _rigid_motion(hyq)
    truth = Truth(hyq.model, traj, frame)
    mount = ImuMount.from_model(hyq.model, frame)
    lever = float(np.linalg.norm(mount.translation))
    assert lever > 0.1
    cutoff = 30.0
    tau = group_delay(cutoff)
    conv = ImuConverter(mount, gravity=hyq.model.gravity.linear, cutoff_hz=cutoff)
    err = {'R': [], 'omega': [], 'alpha': [], 'alpha_delayed': [], 'lag': [], 'acc': [],
           'bound': []}
    for k in range(int(1.0 * RATE_HZ)):
        t = k / RATE_HZ
        quat, omega_i, force = truth.imu_reading(t)
        motion = conv.update(k * 2_000_000, quat, omega_i, force)
        if t < SETTLE_S:
            continue
        assert motion.settled and motion.orientation_source == 'imu'
        R = pin.Quaternion(motion.orientation).toRotationMatrix()
        err['R'].append(np.abs(R - traj.rotation(t)).max())
        err['omega'].append(np.abs(motion.angular_velocity - traj.angular_velocity(t)).max())
        alpha = traj.angular_acceleration(t)
        d_alpha = np.linalg.norm(motion.angular_acceleration - alpha)
        err['alpha'].append(d_alpha)
        err['alpha_delayed'].append(np.linalg.norm(
            motion.angular_acceleration - traj.angular_acceleration(t - tau)))
        err['lag'].append(np.linalg.norm(alpha - traj.angular_acceleration(t - tau)))
        err['acc'].append(np.linalg.norm(motion.linear_acceleration
                                         - traj.classical_base_acceleration(t)))
        err['bound'].append(lever * d_alpha)
    e = {key: np.array(v) for key, v in err.items()}
    assert e['R'].max() < 1e-9
    assert e['omega'].max() < 1e-6
    # alpha lags by tau_g: the residual once delayed is < 2 % of the lag error itself.
    assert e['alpha_delayed'].max() <= 0.02 * e['lag'].max()
    assert e['alpha'].max() <= 1.1 * e['lag'].max()
    assert np.all(e['acc'] <= e['bound'] + 1e-5)
    # The base acceleration is far from the IMU point's (the lever arm matters here).
    assert e['bound'].max() < 0.2 * np.abs([traj.classical_base_acceleration(t)
                                            for t in np.linspace(0, 1, 50)]).max()


def test_at_rest_tilted_the_base_acceleration_is_zero(hyq):
    mount = ImuMount.from_model(hyq.model, 'tilted_imu')
    conv = ImuConverter(mount, gravity=hyq.model.gravity.linear)
    R_wb = _rotation((0.2, -0.3, 2.0))
    R_wi = R_wb @ mount.rotation
    f_i = R_wi.T @ np.array([0.0, 0.0, G])      # specific force at rest: up, in the IMU frame
    quat = pin.Quaternion(R_wi).coeffs()
    for k in range(5):
        motion = conv.update(k * 1_000_000, quat, np.zeros(3), f_i)
        np.testing.assert_allclose(motion.linear_acceleration, 0.0, atol=1e-12)
        np.testing.assert_allclose(motion.angular_acceleration, 0.0, atol=1e-12)
    np.testing.assert_allclose(pin.Quaternion(motion.orientation).toRotationMatrix(), R_wb,
                               atol=1e-12)


def test_orientation_from_the_caller_or_level_when_the_imu_has_none(hyq):
    mount = ImuMount.from_model(hyq.model, 'tilted_imu')
    R_wb = _rotation((0.2, -0.3, 2.0))
    R_wi = R_wb @ mount.rotation
    f_i = R_wi.T @ np.array([0.0, 0.0, G])
    omega_i = np.array([0.1, -0.2, 0.3])
    with_imu = ImuConverter(mount).update(0, pin.Quaternion(R_wi).coeffs(), omega_i, f_i)
    given = ImuConverter(mount).update(0, None, omega_i, f_i,
                                       base_orientation=pin.Quaternion(R_wb).coeffs())
    assert given.orientation_source == 'given'
    for name in ('orientation', 'angular_velocity', 'linear_acceleration'):
        np.testing.assert_allclose(getattr(given, name), getattr(with_imu, name), atol=1e-12)
    level = ImuConverter(mount).update(0, None, omega_i, f_i)
    assert level.orientation_source == 'level'
    np.testing.assert_array_equal(level.orientation, [0.0, 0.0, 0.0, 1.0])
    # Level assumed, tilted in truth: gravity is compensated along the wrong axis.
    assert np.linalg.norm(level.linear_acceleration) > 1.0


@pytest.mark.parametrize('args,match', [
    ((None, [0.0, math.nan, 0.0], [0.0, 0.0, G]), 'angular_velocity is not finite'),
    ((None, [0.0, 0.0], [0.0, 0.0, G]), 'angular_velocity must be 3 numbers'),
    ((None, [0.0, 0.0, 0.0], [0.0, 0.0, math.inf]), 'linear_acceleration is not finite'),
    (([0.0, 0.0, 0.0, 2.0], [0.0, 0.0, 0.0], [0.0, 0.0, G]), 'not a unit quaternion'),
    (([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, G]), 'must be 4 numbers'),
])
def test_invalid_readings_raise_input_error(hyq, args, match):
    conv = ImuConverter(ImuMount.from_model(hyq.model, 'trunk_imu'))
    with pytest.raises(InputError, match=match):
        conv.update(0, *args)
