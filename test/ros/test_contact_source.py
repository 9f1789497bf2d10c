"""Stance from joint efforts: efforts made by inverse dynamics from known contact forces."""

from __future__ import annotations

import numpy as np
import pytest

from awp_ros.errors import InputError
from awp_ros.evaluation.evaluator import FeasibilityEvaluator
from awp_ros.robot.config import RobotConfig
from awp_ros.robot.state import RobotState
from awp_ros.ros.contact_source import EffortContacts
from cases import efforts_for

SOLO8 = {'urdf': 'example-robot-data://solo_description/robots/solo.urdf',
         'feet': ['FL_FOOT', 'FR_FOOT', 'HL_FOOT', 'HR_FOOT']}
SOLO8_Q = {'FL_HFE': 0.8, 'FL_KFE': -1.6, 'FR_HFE': 0.8, 'FR_KFE': -1.6,
           'HL_HFE': -0.8, 'HL_KFE': 1.6, 'HR_HFE': -0.8, 'HR_KFE': 1.6}


@pytest.fixture(scope='module')
def hyq():
    return FeasibilityEvaluator('hyq')


def test_stance_is_the_feet_pushing_harder_than_the_threshold(hyq):
    joints = dict(zip(hyq.model.joint_names, hyq.model.standing_q.tolist()))
    vel = {n: 0.3 * (-1) ** i for i, n in enumerate(hyq.model.joint_names)}
    forces = {'lf_foot': [10.0, -5.0, 300.0], 'rf_foot': [0.0, 8.0, 260.0],
              'rh_foot': [-4.0, 0.0, 250.0], 'lh_foot': [3.0, 2.0, 12.0]}   # lh barely
    det = EffortContacts(hyq, on_n=20.0, off_n=10.0)
    state = RobotState(joint_positions=joints, joint_velocities=vel,
                       joint_efforts=efforts_for(hyq, joints, forces, vel))
    assert det.update(state) == ['lf_foot', 'rf_foot', 'rh_foot']
    np.testing.assert_allclose(det.normal_forces, [300.0, 260.0, 12.0, 250.0], atol=1e-4)
    # Hysteresis: lh at 15 N stays in swing (< on); then at 25 N it touches down; at 15 N
    # it stays down (> off); at 5 N it lifts off.
    for fz, down in ((15.0, False), (25.0, True), (15.0, True), (5.0, False)):
        forces['lh_foot'] = [0.0, 0.0, fz]
        state.joint_efforts = efforts_for(hyq, joints, forces, vel)
        assert ('lh_foot' in det.update(state)) is down, fz


def test_efforts_are_required(hyq):
    det = EffortContacts(hyq, on_n=20.0, off_n=10.0)
    with pytest.raises(InputError, match="contact_source is 'effort' but joint_states carry "
                                         'no efforts'):
        det.update(hyq.standing_state())


def test_two_joint_legs_recover_their_in_plane_forces():
    ev = FeasibilityEvaluator(RobotConfig.from_dict(dict(SOLO8, torque_limits=dict.fromkeys(
        SOLO8_Q, 2.7))))
    forces = {'FL_FOOT': [0.5, 0.0, 6.0], 'HR_FOOT': [-0.3, 0.0, 5.0]}   # x-z: the leg plane
    det = EffortContacts(ev, on_n=1.0, off_n=0.5)
    state = RobotState(joint_positions=SOLO8_Q, joint_efforts=efforts_for(ev, SOLO8_Q, forces))
    assert det.update(state) == ['FL_FOOT', 'HR_FOOT']
    np.testing.assert_allclose(det.normal_forces, [6.0, 0.0, 0.0, 5.0], atol=1e-5)
