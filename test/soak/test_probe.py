"""The soak's DDS participant (awp_ros.soak.probe): a stream taken by a thread of its own."""

import threading
import time

from awp_ros_msgs.msg import ContactState
import pytest

from awp_ros.errors import InputError
from awp_ros.soak.probe import Probe, wait_until


@pytest.mark.parametrize('raw', [False, True])
def test_a_drained_subscription_gets_every_message_in_order_and_stops_on_close(ros_env, raw):
    domain = int(ros_env['ROS_DOMAIN_ID'])
    sender, receiver = Probe(domain, 'awp_probe_test_sender'), Probe(domain, 'awp_probe_test')
    try:
        got = receiver.subscribe(ContactState, '/probe_test/contacts', depth=2000, raw=raw,
                                 drain=True)
        pub = sender.publisher(ContactState, '/probe_test/contacts', depth=2000)
        wait_until(lambda: pub.get_subscription_count() > 0, 30.0, 'the drained subscription')
        for i in range(1000):
            pub.publish(ContactState(names=[f'foot_{i}']))
        wait_until(lambda: len(got) == 1000, 30.0, '1000 messages')
        # Not the executor's: the subscription is on a node of its own, which it does not spin.
        info = receiver.node.get_subscriptions_info_by_topic('/probe_test/contacts')
        assert {s.node_name for s in info} == {'awp_probe_test_drain0'}
        assert receiver.executor.get_nodes() == [receiver.node]
        if raw:
            from rclpy.serialization import deserialize_message
            got = [deserialize_message(m, ContactState) for m in got]
        assert [m.names[0] for m in got] == [f'foot_{i}' for i in range(1000)]
        assert receiver.drain_errors == []
    finally:
        sender.close()
        receiver.close()
    assert not [t for t in threading.enumerate() if t in receiver._drains and t.is_alive()]


def test_a_drained_handler_that_fails_is_kept_not_dropped(ros_env, capfd):
    domain = int(ros_env['ROS_DOMAIN_ID'])
    sender, receiver = Probe(domain, 'awp_probe_fail_sender'), Probe(domain, 'awp_probe_fail')
    seen = []

    def handler(msg) -> None:
        seen.append(msg)
        if len(seen) == 3:
            raise RuntimeError('a bug in the handler')
    try:
        receiver.subscribe(ContactState, '/probe_fail/contacts', handler, depth=100, drain=True)
        pub = sender.publisher(ContactState, '/probe_fail/contacts', depth=100)
        wait_until(lambda: pub.get_subscription_count() > 0, 30.0, 'the drained subscription')
        for i in range(5):
            pub.publish(ContactState(names=[f'foot_{i}']))
        wait_until(lambda: receiver.drain_errors, 30.0, 'the handler error')
    finally:
        sender.close()
        receiver.close()
    assert [repr(e) for e in receiver.drain_errors] == ["RuntimeError('a bug in the handler')"]
    assert 'a bug in the handler' in capfd.readouterr().err


def test_a_drained_subscription_with_info_gets_when_each_message_was_written_and_received(
        ros_env):
    domain = int(ros_env['ROS_DOMAIN_ID'])
    sender, receiver = Probe(domain, 'awp_probe_info_sender'), Probe(domain, 'awp_probe_info')
    try:
        with pytest.raises(InputError, match='with_info needs drain=True'):
            receiver.subscribe(ContactState, '/probe_info/contacts', with_info=True)
        got = receiver.subscribe(ContactState, '/probe_info/contacts', depth=100, raw=True,
                                 drain=True, with_info=True)
        pub = sender.publisher(ContactState, '/probe_info/contacts', depth=100)
        wait_until(lambda: pub.get_subscription_count() > 0, 30.0, 'the drained subscription')
        written = []
        for i in range(20):
            written.append(time.time_ns())
            pub.publish(ContactState(names=[f'foot_{i}']))
            time.sleep(0.01)
        wait_until(lambda: len(got) == 20, 30.0, '20 messages')
    finally:
        sender.close()
        receiver.close()
    for (data, info), t in zip(got, written):
        assert isinstance(data, bytes)
        # Written by the publisher after our clock read, received after that (one clock).
        assert t <= info['source_timestamp'] <= info['received_timestamp'] < t + 10**9
