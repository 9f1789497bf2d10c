"""Merging joint states that carry subsets of the joints (several publishers, extra joints)."""

from __future__ import annotations

from array import array

import numpy as np
import pytest
from sensor_msgs.msg import JointState

from awp_ros.errors import InputError
from awp_ros.ros.joint_merge import JointMerger, MergedJoints

JOINTS = ['a', 'b', 'c', 'd']
MS = 10**6


def _js(names, positions, velocities=(), efforts=()) -> JointState:
    return JointState(name=list(names), position=list(positions), velocity=list(velocities),
                      effort=list(efforts))


def test_subsets_from_two_publishers_merge_into_the_latest_value_of_each_joint():
    m = JointMerger(JOINTS, timeout_s=0.05)
    first = m.add(_js(['c', 'a'], [3.0, 1.0]), 0)
    assert isinstance(first, str) and "['b', 'd']" in first and 'no message' in first
    out = m.add(_js(['d', 'b', 'arm'], [4.0, 2.0, 9.0], [0.4, 0.2, 0.9]), 1 * MS)
    assert isinstance(out, MergedJoints) and out.name == JOINTS
    np.testing.assert_array_equal(out.position, [1.0, 2.0, 3.0, 4.0])
    assert len(out.velocity) == 0          # a and c came without velocities
    out = m.add(_js(['a', 'c'], [1.5, 3.5], [0.1, 0.3], [10.0, 30.0]), 2 * MS)
    np.testing.assert_array_equal(out.position, [1.5, 2.0, 3.5, 4.0])
    np.testing.assert_array_equal(out.velocity, [0.1, 0.2, 0.3, 0.4])   # every one fresh
    assert len(out.effort) == 0                                        # b and d had none
    assert m.extra == {'arm'}


def test_a_joint_older_than_the_timeout_makes_the_state_stale_until_it_comes_again():
    m = JointMerger(JOINTS, timeout_s=0.05)
    assert isinstance(m.add(_js(JOINTS, [0.0] * 4), 0), MergedJoints)
    out = m.add(_js(['a', 'b', 'c'], [1.0] * 3), 80 * MS)
    assert isinstance(out, str)
    assert "joints ['d'] were last received up to 0.080 s before" in out
    assert 'joint_states_timeout_s 0.05' in out
    out = m.add(_js(['d'], [7.0]), 81 * MS)
    np.testing.assert_array_equal(out.position, [1.0, 1.0, 1.0, 7.0])
    # Timeout 0: any age.
    m = JointMerger(JOINTS, timeout_s=0.0)
    m.add(_js(JOINTS, [0.0] * 4), 0)
    assert isinstance(m.add(_js(['a'], [1.0]), 10**12), MergedJoints)


def test_a_full_message_in_any_order_is_its_own_values_and_extra_joints_are_kept_once():
    m = JointMerger(JOINTS, timeout_s=0.05, ignored=['wheel'])
    msg = _js(['d', 'wheel', 'c', 'b', 'a', 'gripper'], [4, 0, 3, 2, 1, 0],
              [0.4, 0, 0.3, 0.2, 0.1, 0], [40, 0, 30, 20, 10, 0])
    for k in range(3):
        out = m.add(msg, k * MS)
        np.testing.assert_array_equal(out.position, [1, 2, 3, 4])
        np.testing.assert_array_equal(out.velocity, [0.1, 0.2, 0.3, 0.4])
        np.testing.assert_array_equal(out.effort, [10, 20, 30, 40])
    assert m.extra == {'gripper'}          # 'wheel' is ignored by name
    assert m.is_full(msg.name) and not m.is_full(['a', 'b'])


def test_the_model_order_message_takes_the_fast_path_with_rclpy_arrays():
    m = JointMerger(JOINTS, timeout_s=0.05)
    msg = JointState(name=JOINTS, position=array('d', [1, 2, 3, 4]),
                     velocity=array('d', [5, 6, 7, 8]))
    out = m.add(msg, 0)
    np.testing.assert_array_equal(out.position, [1, 2, 3, 4])
    np.testing.assert_array_equal(out.velocity, [5, 6, 7, 8])
    assert m._layout(tuple(JOINTS)).identity


@pytest.mark.parametrize(('msg', 'match'), [
    (_js(['a', 'a'], [1.0, 2.0]), r"names joints twice: \['a'\]"),
    (_js(['a', 'b'], [1.0]), 'has 2 names but 1 positions'),
    (_js(['a', 'b'], [1.0, 2.0], [1.0]), 'has 2 names but 1 velocities'),
    (_js(['a', 'b'], [1.0, 2.0], (), [1.0, 2.0, 3.0]), 'has 2 names but 3 efforts'),
])
def test_malformed_messages_are_input_errors_and_change_nothing(msg, match):
    m = JointMerger(JOINTS, timeout_s=0.05)
    m.add(_js(JOINTS, [0.0] * 4), 0)
    with pytest.raises(InputError, match=match):
        m.add(msg, MS)
    np.testing.assert_array_equal(m.add(_js(['a'], [9.0]), 2 * MS).position, [9, 0, 0, 0])


def test_clear_forgets_every_value():
    m = JointMerger(JOINTS, timeout_s=0.05)
    m.add(_js(JOINTS, [0.0] * 4), 0)
    m.clear()
    assert 'no message has named joints' in m.add(_js(['a'], [1.0]), MS)
