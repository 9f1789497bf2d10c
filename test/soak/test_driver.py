"""The soak driver's joint states (awp_ros.soak.driver): serialized once, stamped per send."""

import numpy as np
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState

from awp_ros.ros.cdr import stamped as _stamped
from awp_ros.soak.driver import _joint_state_bytes


def test_stamped_bytes_are_the_typesupport_bytes_of_the_stamped_message():
    rng = np.random.default_rng(3)
    names = [f'joint_{i}' for i in range(12)]
    q, v = rng.normal(size=(5, 12)), rng.normal(size=(5, 12))
    messages = _joint_state_bytes(names, q, v)
    for k, ns in enumerate([0, 1, 999_999_999, 1_765_000_000_123_456_789, 2**31 * 10**9 - 1]):
        expected = JointState(name=names, position=q[k].tolist(), velocity=v[k].tolist())
        expected.header.stamp.sec, expected.header.stamp.nanosec = divmod(ns, 10**9)
        data = _stamped(messages[k], ns)
        assert data == serialize_message(expected)
        got = deserialize_message(data, JointState)
        assert (got.header.stamp.sec, got.header.stamp.nanosec) == divmod(ns, 10**9)
        assert list(got.name) == names and list(got.effort) == []
        np.testing.assert_array_equal(got.position, q[k])
        np.testing.assert_array_equal(got.velocity, v[k])
