"""The node's DiagnosticArray: rates, staleness, percentiles and levels from counters."""

from __future__ import annotations

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus
import numpy as np
import pytest

from awp_ros.node.diagnostics import NodeDiagnostics


def _values(status: DiagnosticStatus) -> dict[str, str]:
    return {kv.key: kv.value for kv in status.values}


def test_rates_percentiles_and_ok_levels():
    d = NodeDiagnostics('awp_node', 'hyq', ['joint_states', 'contacts'])
    d.build(Time(), wall=100.0)                          # opens the first period
    for i in range(500):                                  # 500 Hz joint states, 100 Hz contacts
        d.received('joint_states', 100.0 + i * 0.002)
        if i % 5 == 0:
            d.received('contacts', 100.0 + i * 0.002)
        d.evaluated(0, compute_time_s=1e-3 * (1 + i % 100) / 100, latency_s=2e-3)
    arr = d.build(Time(sec=7), wall=101.0)
    inputs, evaluation = arr.status
    assert arr.header.stamp.sec == 7
    assert inputs.name == 'awp_node: inputs' and inputs.hardware_id == 'hyq'
    assert inputs.level == DiagnosticStatus.OK, inputs.message
    v = _values(inputs)
    assert v['joint_states rate [Hz]'] == '500.0' and v['contacts rate [Hz]'] == '100.0'
    e = _values(evaluation)
    samples = 1e3 * 1e-3 * (1 + np.arange(500) % 100) / 100
    assert float(e['compute time p50 [ms]']) == round(np.percentile(samples, 50), 3)
    assert float(e['compute time p99 [ms]']) == round(np.percentile(samples, 99), 3)
    assert e['reports ok (period)'] == '500' and evaluation.level == DiagnosticStatus.OK
    # The period counters restart; totals do not.
    arr = d.build(Time(), wall=102.0)
    assert _values(arr.status[1])['reports ok (period)'] == '0'
    assert _values(arr.status[1])['reports ok (total)'] == '500'


def test_stale_lost_invalid_and_falling_behind_warn():
    d = NodeDiagnostics('n', 'hyq', ['joint_states', 'contacts'], stale_timeout_s=0.5)
    assert d.build(Time(), wall=0.0).status[0].level == DiagnosticStatus.ERROR  # nothing yet
    d.received('contacts', 0.1)
    for i in range(100):
        d.received('joint_states', 0.9 + i * 1e-3)
        d.evaluated(0, compute_time_s=20e-3, latency_s=None)  # 20 ms each at 100 Hz
    d.lost('joint_states', 3)
    arr = d.build(Time(), wall=1.0)
    inputs, evaluation = arr.status
    assert inputs.level == DiagnosticStatus.WARN
    assert 'stale: contacts' in inputs.message and 'lost: joint_states (3)' in inputs.message
    assert evaluation.level == DiagnosticStatus.WARN and 'falling behind' in evaluation.message
    assert d.falling_behind
    d.received('contacts', 1.5)
    d.received('joint_states', 1.5)
    d.evaluated(2, 1e-4, None, "joint_positions lacks joints ['x']")
    evaluation = d.build(Time(), wall=2.0).status[1]
    assert evaluation.level == DiagnosticStatus.WARN
    assert '1 of 1 reports not evaluated' in evaluation.message and "['x']" in \
        _values(evaluation)['last error']


def test_sequence_gaps_count_and_an_unknown_number_starts_over():
    d = NodeDiagnostics('n', 'hyq', ['joint_states', 'contacts'])
    assert [d.sequence('joint_states', s) for s in (1, 2, 5, 6)] == [0, 0, 2, 0]
    # A message without its number (EventsExecutor callbacks) may hide a gap: the next
    # known number starts over instead of counting the unknown message as missing.
    assert d.sequence('joint_states', None) == 0
    assert d.sequence('joint_states', 8) == 0 and d.sequence('joint_states', 10) == 1
    assert d.sequence('joint_states', 3) == 0            # a new publisher starts over
    assert d.inputs['joint_states'].gaps == 3


def test_two_interleaved_publishers_show_no_gaps_and_a_real_gap_is_counted_once():
    d = NodeDiagnostics('n', 'hyq', ['joint_states'])
    d.matched('joint_states', 2)
    # legs (1, 2, 3, ...) and arm (1, 2, ...) interleaved, arm starting later.
    seqs = [1, 2, 1, 3, 2, 4, 3, 5, 4]
    assert [d.sequence('joint_states', s) for s in seqs] == [0] * len(seqs)
    assert d.sequence('joint_states', 8) == 2       # legs 6 and 7 missing (5 -> 8)
    assert d.sequence('joint_states', 5) == 0       # arm continues
    assert d.sequence('joint_states', 1) == 0       # a restarted publisher starts over
    assert d.inputs['joint_states'].gaps == 2
    # One publisher left: its sequence continues, the stale one is dropped.
    d.matched('joint_states', 1)
    assert d.sequence('joint_states', 9) == 0 and d.sequence('joint_states', 11) == 1


def test_each_input_problem_names_its_topic():
    d = NodeDiagnostics('awp_node', 'a1', ['joint_states', 'contacts', 'imu'],
                        names={'joint_states': '/robot/joint_states', 'contacts': '/contacts',
                               'imu': '/imu'},
                        types={'joint_states': 'sensor_msgs/msg/JointState',
                               'contacts': 'awp_ros_msgs/msg/ContactState',
                               'imu': 'sensor_msgs/msg/Imu'})
    d.graph('joint_states', ['sensor_msgs/msg/JointState'])
    d.incompatible_qos('joint_states', 1, 'RELIABILITY')
    d.graph('contacts', [])
    d.graph('imu', ['nav_msgs/msg/Odometry'])
    inputs = d.build(Time(), wall=1.0).status[0]
    assert inputs.level == DiagnosticStatus.ERROR
    assert inputs.message.startswith('no joint_states received yet: /robot/joint_states has 1 '
                                     'publisher with incompatible QoS (RELIABILITY: a '
                                     'best-effort publisher')
    assert '/contacts has no publisher' in inputs.message
    assert ('/imu has publishers of another type (1 of type nav_msgs/msg/Odometry); this node '
            'subscribes with sensor_msgs/msg/Imu') in inputs.message
    v = _values(inputs)
    assert v['imu topic'] == '/imu' and 'Odometry' in v['imu problem']
    # Once messages arrive and the publishers match, the problems go.
    for topic in ('joint_states', 'contacts', 'imu'):
        d.received(topic, 1.5)
        d.graph(topic, [d.inputs[topic].msg_type])
    d.incompatible_qos('joint_states', 0, '')
    inputs = d.build(Time(), wall=2.0).status[0]
    assert inputs.level == DiagnosticStatus.OK, inputs.message


def test_on_change_contacts_are_not_stale_and_extra_joints_are_one_entry():
    d = NodeDiagnostics('n', 'hyq', ['joint_states', 'contacts'], stale_timeout_s=0.5)
    d.topic_timeouts['contacts'] = 0.0          # contacts_timeout_s 0: holds until the next
    d.extra_joints = {'wheel_joint', 'arm_joint'}
    d.received('contacts', 0.0)
    d.received('joint_states', 9.9)
    inputs = d.build(Time(), wall=10.0).status[0]
    assert inputs.level == DiagnosticStatus.OK, inputs.message
    assert _values(inputs)['joint_states ignored joints (not in the model)'] == \
        'arm_joint, wheel_joint'


def test_a_second_publisher_before_its_matched_event_is_no_false_gap():
    d = NodeDiagnostics('n', 'hyq', ['joint_states'])
    d.matched('joint_states', 1)                     # the second match not handled yet
    seqs = [100, 101, 1, 102, 2, 103, 3]
    assert [d.sequence('joint_states', s) for s in seqs] == [0] * len(seqs)
    assert d.sequence('joint_states', 106) == 2      # 104, 105 of the first: a real gap
    assert d.inputs['joint_states'].gaps == 2


def test_an_fws_in_the_loop_longer_than_two_periods_is_named_but_not_a_fault():
    """1 kHz joint states: a 4 ms FWS in the loop is named (with fws_lag_s), a 1.5 ms one not."""
    d = NodeDiagnostics('awp_node', 'hyq', ['joint_states'])
    d.build(Time(), wall=0.0)
    for k, (fws_ms, named) in enumerate(((4.2, True), (1.5, False), (None, False))):
        for i in range(1000):
            d.received('joint_states', k + i * 1e-3)
            d.evaluated(0, compute_time_s=3e-4, latency_s=6e-4)
            if fws_ms is not None and i % 100 == 0:
                d.fws_in_loop(fws_ms if i == 500 else 1.0)
        evaluation = d.build(Time(), wall=k + 1.0).status[1]
        v = _values(evaluation)
        assert evaluation.level == DiagnosticStatus.OK, evaluation.message
        assert v['FWS in the loop (period)'] == ('10' if fws_ms else '0')
        if fws_ms:
            assert float(v['FWS in the loop max [ms]']) == fws_ms
        assert ('the FWS in the loop took up to 4.2 ms, 4 joint_states periods'
                in evaluation.message) == named, evaluation.message
        assert ('fws_lag_s' in evaluation.message) == named


def test_a_growing_input_queue_is_falling_behind_even_when_each_evaluation_fits():
    """
    1 kHz joint states, 0.6 ms of compute each: the compute time fits the 1 ms period.

    Whether the node keeps up is read from how long the joint states waited in its input
    queue: a backlog growing to 0.6 s (what a 1 kHz soak on a 2x slower machine showed) is
    falling behind; a burst of waits after a 7 ms FWS in the loop, the median untouched, is
    not; and a period without reception times says nothing about the queue.
    """
    d = NodeDiagnostics('awp_node', 'hyq', ['joint_states'])
    d.build(Time(), wall=0.0)
    growing = 0.6 * np.arange(1000) / 1000                     # 0 .. 0.6 s
    burst = np.full(1000, 3e-4)
    burst[500:507] = 7e-3 - 1e-3 * np.arange(7)               # after one FWS in the loop
    for k, (delays, behind) in enumerate(((growing, True), (burst, False), (None, False))):
        for i in range(1000):
            d.received('joint_states', k + i * 1e-3)
            d.evaluated(0, compute_time_s=6e-4, latency_s=None,
                        queue_delay_s=None if delays is None else float(delays[i]))
        evaluation = d.build(Time(), wall=k + 1.0).status[1]
        v = _values(evaluation)
        if delays is None:
            assert v['input queue delay p50 [ms]'] == 'nan', v
        else:
            assert float(v['input queue delay p50 [ms]']) == round(
                1e3 * np.percentile(delays, 50), 3)
            assert float(v['input queue delay p99 [ms]']) == round(
                1e3 * np.percentile(delays, 99), 3)
            assert float(v['input queue delay max [ms]']) == round(1e3 * delays.max(), 3)
        assert float(v['compute time p50 [ms]']) == 0.6          # below the 1 ms period
        if behind:
            assert evaluation.level == DiagnosticStatus.WARN, evaluation.message
            assert evaluation.message.startswith(
                'falling behind: joint states waited 299.7 ms (p50), up to 599 ms, in the '
                'input queue'), evaluation.message
            assert 'max_queue_delay_s' in evaluation.message
        else:
            assert evaluation.level == DiagnosticStatus.OK, evaluation.message
        assert d.falling_behind == behind


def test_the_input_transport_delay_is_the_publishers_write_to_the_nodes_reception():
    """Per period: p50 / p99 / max of received - source timestamp; unknown ones not counted."""
    from awp_ros.node.node import _transport_delay
    assert _transport_delay({'source_timestamp': 1_000_000_000,
                             'received_timestamp': 1_333_000_000}) == pytest.approx(0.333)
    assert _transport_delay({'source_timestamp': 0, 'received_timestamp': 5}) is None
    assert _transport_delay({}) is None
    d = NodeDiagnostics('awp_node', 'hyq', ['joint_states'])
    d.build(Time(), wall=0.0)
    delays = np.full(1000, 6e-5)
    delays[701] = 0.333                                 # one joint state late in DDS
    for i in range(1000):
        d.received('joint_states', i * 1e-3)
        d.evaluated(0, compute_time_s=3e-4, latency_s=None, queue_delay_s=1e-4,
                    transport_delay_s=float(delays[i]) if i % 10 else None)
    v = _values(d.build(Time(), wall=1.0).status[1])
    known = delays[np.arange(1000) % 10 != 0]
    assert float(v['input transport delay p50 [ms]']) == round(1e3 * np.median(known), 3)
    assert float(v['input transport delay p99 [ms]']) == round(
        1e3 * np.percentile(known, 99), 3)
    assert float(v['input transport delay max [ms]']) == 333.0
    assert float(v['input queue delay max [ms]']) == 0.1
    # A new period starts empty.
    v = _values(d.build(Time(), wall=2.0).status[1])
    assert v['input transport delay max [ms]'] == 'nan'
