"""The Fast DDS profile of the node's input queues (awp_ros.node.dds), on real DDS."""

from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest

from awp_ros.node.dds import (FASTDDS_READER_SAMPLES, PROFILE, queue_note, READER_SAMPLES,
                              use_deep_queues)

# One process, one participant: a reliable keep-last subscription of DEPTH that is not read
# while N joint states are published to it, then read dry. Prints the stamps it got.
QUEUE_PROBE = r"""
import json, sys, time
from awp_ros.node.dds import use_deep_queues
if sys.argv[3] == 'profile':
    use_deep_queues()
import rclpy
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
depth, n = int(sys.argv[1]), int(sys.argv[2])
rclpy.init()
node = rclpy.create_node('queue_probe')
qos = QoSProfile(depth=depth, history=HistoryPolicy.KEEP_LAST,
                 reliability=ReliabilityPolicy.RELIABLE)
sub = node.create_subscription(JointState, 'queue_probe', lambda msg: None, qos)
pub = node.create_publisher(JointState, 'queue_probe', qos)
end = time.monotonic() + 10.0
while pub.get_subscription_count() < 1 and time.monotonic() < end:
    time.sleep(0.01)
msg = JointState(name=['j'] * 12, position=[0.0] * 12)
for i in range(n):
    msg.header.stamp.sec = i
    pub.publish(msg)
time.sleep(1.0)
stamps = []
while True:
    with sub.handle:
        taken = sub.handle.take_message(sub.msg_type, sub.raw)
    if taken is None:
        break
    stamps.append(taken[0].header.stamp.sec)
print(json.dumps(stamps))
"""


def _queued(ros_env: dict, depth: int, n: int, mode: str) -> list[int]:
    env = {k: v for k, v in ros_env.items() if 'PROFILES_FILE' not in k
           and k not in ('RMW_IMPLEMENTATION', 'RMW_FASTRTPS_USE_QOS_FROM_XML')}
    out = subprocess.run([sys.executable, '-c', QUEUE_PROBE, str(depth), str(n), mode],
                         env=env, capture_output=True, text=True, timeout=120, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_the_profile_lets_a_keep_last_queue_hold_its_depth(ros_env):
    # 7000 joint states into a reliable keep-last queue of 8000 that nobody reads yet.
    assert _queued(ros_env, 8000, 7000, 'profile') == list(range(7000))
    # Without the profile Fast DDS holds the oldest 5000 (its default data-reader
    # max_samples), not the newest: what the profile is for.
    assert _queued(ros_env, 8000, 7000, 'default') == list(range(FASTDDS_READER_SAMPLES))
    # Below the limit keep-last keeps the newest, with or without it.
    assert _queued(ros_env, 3000, 7000, 'default') == list(range(4000, 7000))


def test_profile_raises_only_the_data_reader_limits():
    root = ET.parse(PROFILE).getroot()
    ns = {'p': 'http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles'}
    (reader,) = root.findall('p:data_reader', ns)
    assert reader.get('is_default_profile') == 'true'
    assert len(list(root)) == 1
    limits = reader.find('p:topic/p:resourceLimitsQos', ns)
    assert int(limits.find('p:max_samples', ns).text) == READER_SAMPLES
    assert int(limits.find('p:max_samples_per_instance', ns).text) == READER_SAMPLES


@pytest.mark.parametrize('env, applied', [
    ({}, True),
    ({'RMW_IMPLEMENTATION': 'rmw_fastrtps_cpp'}, True),
    ({'RMW_IMPLEMENTATION': 'rmw_fastrtps_dynamic_cpp'}, True),
    ({'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'}, False),
    ({'FASTRTPS_DEFAULT_PROFILES_FILE': '/etc/mine.xml'}, False),
    ({'FASTDDS_DEFAULT_PROFILES_FILE': '/etc/mine.xml'}, False),
    ({'RMW_FASTRTPS_USE_QOS_FROM_XML': '1'}, False),
    ({'RMW_FASTRTPS_USE_QOS_FROM_XML': '0'}, True),
])
def test_use_deep_queues_leaves_a_users_configuration_alone(env, applied):
    before = dict(env)
    assert use_deep_queues(env) is applied
    if applied:
        assert env == {**before, 'FASTRTPS_DEFAULT_PROFILES_FILE': str(PROFILE)}
        assert use_deep_queues(env) is False        # once set, kept
    else:
        assert env == before


def test_queue_note_warns_when_a_deep_queue_may_be_capped():
    ours = {'FASTRTPS_DEFAULT_PROFILES_FILE': str(PROFILE)}
    warn, text = queue_note(10000, ours)
    assert not warn and str(READER_SAMPLES) in text
    warn, text = queue_note(10000, {'FASTRTPS_DEFAULT_PROFILES_FILE': '/etc/mine.xml'})
    assert warn and '/etc/mine.xml' in text and 'max_samples' in text
    warn, text = queue_note(10000, {'RMW_FASTRTPS_USE_QOS_FROM_XML': '1'})
    assert warn and 'RMW_FASTRTPS_USE_QOS_FROM_XML' in text
    warn, text = queue_note(10000, {})
    assert warn and 'use_deep_queues was not called' in text
    assert queue_note(FASTDDS_READER_SAMPLES, {'FASTDDS_DEFAULT_PROFILES_FILE': '/x.xml'}) \
        == (False, '')
    assert queue_note(10000, {'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'}) == (False, '')
