"""Tests of awp_ros.robot.model: URDF resolution, leg structure, kinematics and dynamics."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from awp_ros.errors import ConfigError, ModelError
from awp_ros.robot.config import load_config, RobotConfig
from awp_ros.robot.model import resolve_urdf, RobotModel
from cases import EFFORT, G, M_BASE, M_FOOT, toy_urdf


def toy_config(**kw) -> RobotConfig:
    params = {'robot_name': 'toy', 'urdf': toy_urdf(), 'feet': ['a_foot', 'b_foot']}
    params.update(kw)
    return RobotConfig.from_dict(params)


def test_toy_leg_jacobian_is_diagonal_and_bias_is_the_foot_weight():
    model = RobotModel(toy_config())
    assert model.legs['a_foot'].joints == ('a_j1', 'a_j2', 'a_j3')   # inferred chain
    np.testing.assert_array_equal(model.legs['b_foot'].tau_max, EFFORT)
    kin = model.kinematics(np.zeros(6), ('a_foot', 'b_foot'))
    assert kin.mass == pytest.approx(M_BASE + 2 * M_FOOT)
    com = np.array([M_FOOT * 1.0, 0.0, M_BASE * 0.5]) / (M_BASE + 2 * M_FOOT)
    np.testing.assert_allclose(kin.com, com, atol=1e-12)
    np.testing.assert_allclose(kin.p_foot__com, [[0, 0, 0] - com, [1, 0, 0] - com],
                               atol=1e-12)
    for k in range(2):
        np.testing.assert_allclose(kin.J[k], np.diag([0.5, 0.4, 0.3]), atol=1e-12)
        # Holding the 1 kg foot mass: tau = J^T (0, 0, m g).
        np.testing.assert_allclose(kin.bias[k], [0.0, 0.0, 0.3 * M_FOOT * G], atol=1e-9)
    np.testing.assert_allclose(kin.wrench, [0, 0, kin.mass * G, 0, 0, 0], atol=1e-9)


def test_base_orientation_rotates_feet_and_jacobians():
    model = RobotModel(toy_config())
    quat = pin.Quaternion(pin.rpy.rpyToMatrix(0.3, -0.2, 0.5))
    xyzw = np.array([quat.x, quat.y, quat.z, quat.w])
    R = quat.toRotationMatrix()
    q = np.array([0.1, -0.2, 0.3, 0.0, 0.2, -0.1])
    level = model.kinematics(q, ('a_foot', 'b_foot'))
    tilted = model.kinematics(q, ('a_foot', 'b_foot'), quaternion=xyzw)
    np.testing.assert_allclose(tilted.p_foot__com, level.p_foot__com @ R.T, atol=1e-12)
    np.testing.assert_allclose(tilted.J[1], R @ level.J[1], atol=1e-12)
    np.testing.assert_allclose(tilted.wrench, level.wrench, atol=1e-9)


def test_base_linear_acceleration_adds_to_gravity():
    # Pure translation of the base with acceleration acc: every link feels g - acc, so the
    # bias is the weight under gravity (acc + g_up) and w = [M (acc + g_up); 0].
    model = RobotModel(toy_config())
    acc = np.array([1.0, -2.0, 0.5])
    a = np.zeros(12)
    a[:3] = acc
    kin = model.kinematics(np.zeros(6), ('a_foot',), a=a)
    np.testing.assert_allclose(kin.wrench[:3], kin.mass * (acc + [0, 0, G]), atol=1e-9)
    np.testing.assert_allclose(kin.wrench[3:], 0.0, atol=1e-9)
    f_weight = M_FOOT * (acc + [0, 0, G])
    np.testing.assert_allclose(kin.bias[0], np.diag([0.5, 0.4, 0.3]) @ f_weight, atol=1e-9)


def test_all_shipped_robots_load_with_complete_legs_and_postures():
    for name in ('hyq', 'anymal_c', 'go2', 'solo12'):
        cfg = load_config(name)
        model = RobotModel(cfg)
        assert len(model.legs) == 4
        assert model.standing_q.shape == (len(model.joint_names),)
        joints = [j for leg in model.legs.values() for j in leg.joints]
        assert sorted(joints) == sorted(model.joint_names)
        for leg in model.legs.values():
            assert np.all(leg.tau_max > 0) and np.all(leg.tau_min < 0)
        kin = model.kinematics(model.standing_q, cfg.feet)
        assert np.all(kin.p_foot__com[:, 2] < -0.1)       # feet below the CoM


def test_inferred_leg_joints_match_the_explicit_hyq_config():
    cfg = load_config('hyq')
    inferred = RobotModel(RobotConfig(cfg.robot_name, cfg.urdf, cfg.feet))
    explicit = RobotModel(cfg)
    for foot in cfg.feet:
        assert inferred.legs[foot].joints == explicit.legs[foot].joints


def test_urdf_resolution():
    for name in ('hyq', 'anymal_c', 'go2', 'solo12'):
        kind, path = resolve_urdf(load_config(name).urdf)
        assert kind == 'file' and path.endswith('.urdf')
    assert resolve_urdf('  <robot name="x"/>')[0] == 'xml'
    with pytest.raises(ConfigError, match='not found in example-robot-data'):
        resolve_urdf('example-robot-data://nope/robot.urdf')
    with pytest.raises(ConfigError, match='does not exist'):
        resolve_urdf('file:///nonexistent/robot.urdf')


def test_model_errors_name_the_problem():
    with pytest.raises(ModelError, match='robot_description'):
        RobotModel(toy_config(urdf='<robot name="broken"><link name="a"></robot>'))
    with pytest.raises(ConfigError, match="foot frame 'c_foot'"):
        RobotModel(toy_config(feet=['a_foot', 'c_foot']))
    with pytest.raises(ConfigError, match="unknown joint 'zz'"):
        RobotModel(toy_config(leg_joints={'a_foot': ['a_j1', 'zz']}))
    with pytest.raises(ConfigError, match="'b_j1' is not on the chain of foot 'a_foot'"):
        RobotModel(toy_config(leg_joints={'a_foot': ['a_j1', 'b_j1', 'a_j3']}))
    with pytest.raises(ConfigError, match='no URDF effort limit; set torque_limits.a_j2'):
        RobotModel(toy_config(urdf=toy_urdf(efforts=(10.0, 0.0, 30.0))))
    with pytest.raises(ConfigError, match='standing_posture lacks'):
        RobotModel(toy_config(standing_posture={'a_j1': 0.0}))
    with pytest.raises(ConfigError, match='standing_posture names unknown joints'):
        RobotModel(toy_config(standing_posture={'zz': 0.0}))


def test_torque_limit_overrides_replace_urdf_effort():
    model = RobotModel(toy_config(urdf=toy_urdf(efforts=(10.0, 0.0, 30.0)),
                                  torque_limits={'a_j2': [-1.0, 4.0], 'b_j2': 2.0}))
    np.testing.assert_array_equal(model.legs['a_foot'].tau_min, [-10.0, -1.0, -30.0])
    np.testing.assert_array_equal(model.legs['a_foot'].tau_max, [10.0, 4.0, 30.0])
    np.testing.assert_array_equal(model.legs['b_foot'].tau_max, [10.0, 2.0, 30.0])


def test_leg_columns_are_slices_of_consecutive_joints_and_index_arrays_otherwise():
    from awp_ros.robot.model import _columns
    assert _columns(np.array([6, 7, 8])) == slice(6, 9)
    for idx in ([6, 8, 7], [9, 10, 12], []):
        out = _columns(np.array(idx, dtype=int))
        assert isinstance(out, np.ndarray) and out.tolist() == idx
    v = np.arange(20.0) * 3.0
    for idx in ([6, 7, 8], [9, 7, 12]):
        np.testing.assert_array_equal(v[_columns(np.array(idx))], v[idx])
