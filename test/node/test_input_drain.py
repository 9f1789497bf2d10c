"""InputDrain: queued messages taken straight from real DDS subscriptions, in order."""

from __future__ import annotations

import time

from awp_ros_msgs.msg import ContactState
import pytest
import rclpy
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from awp_ros.node.input_drain import InputDrain, take

QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                 reliability=ReliabilityPolicy.RELIABLE)


@pytest.fixture
def peers(ros_env):
    """Yield a publishing node and a subscribing node in two contexts (two DDS participants)."""
    contexts, nodes = [], []
    for name in ('drain_pub', 'drain_sub'):
        ctx = rclpy.Context()
        rclpy.init(context=ctx, domain_id=int(ros_env['ROS_DOMAIN_ID']))
        contexts.append(ctx)
        nodes.append(rclpy.create_node(name, context=ctx))
    yield nodes
    for node, ctx in zip(nodes, contexts):
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def _wait(predicate, timeout=20.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not predicate():
        time.sleep(0.02)
    return predicate()


def _joint_states(peers):
    """Return a joint-state subscription of the second node and a publisher of the first."""
    pub_node, sub_node = peers
    js_sub = sub_node.create_subscription(JointState, 'joint_states', lambda m: None, QOS)
    js_pub = pub_node.create_publisher(JointState, 'joint_states', QOS)
    assert _wait(lambda: js_pub.get_subscription_count())
    return js_sub, js_pub


def test_drain_takes_contacts_before_each_joint_state_and_respects_its_budget(peers):
    pub_node, sub_node = peers
    log = []
    js_sub = sub_node.create_subscription(JointState, 'joint_states', lambda m: None, QOS)
    ct_sub = sub_node.create_subscription(ContactState, 'contacts', lambda m: None, QOS)
    js_pub = pub_node.create_publisher(JointState, 'joint_states', QOS)
    ct_pub = pub_node.create_publisher(ContactState, 'contacts', QOS)
    assert _wait(lambda: js_pub.get_subscription_count() and ct_pub.get_subscription_count())
    assert take(js_sub) is None                                        # nothing queued yet
    for i in range(200):
        if i % 10 == 0:
            msg = ContactState()
            msg.header.stamp.nanosec = i
            ct_pub.publish(msg)
        msg = JointState()
        msg.header.stamp.nanosec = i
        js_pub.publish(msg)
    time.sleep(1.0)                         # all 220 delivered (reliable, this machine)
    drain = InputDrain([(ct_sub, lambda m, info: log.append(('c', m.header.stamp.nanosec)))],
                       (js_sub, lambda m, info: log.append(
                           ('j', m.header.stamp.nanosec, info['publication_sequence_number']))),
                       sub_node.context, budget_s=5.0)
    t0 = time.monotonic()
    assert drain.run() == 200              # all 200 taken; then it waited out its budget
    assert 4.9 < time.monotonic() - t0 < 8.0
    js = [e for e in log if e[0] == 'j']
    assert [e[1] for e in js] == list(range(200))                  # in order, none lost
    assert [e[2] for e in js] == list(range(js[0][2], js[0][2] + 200))
    # Every contacts message received was handed over before the next joint state: the
    # contacts stamped i precede the joint state i in the log.
    for i in range(0, 200, 10):
        assert log.index(('c', i)) < next(k for k, e in enumerate(log) if e[:2] == ('j', i))
    # A contacts message alone is taken (handed over) while waiting, not spun on.
    n_log = len(log)
    ct_pub.publish(ContactState())
    t0 = time.monotonic()
    drain.budget_s = 1.0
    assert drain.run() == 0 and 0.9 < time.monotonic() - t0 < 3.0
    assert log[n_log:] == [('c', 0)]
    # budget 0: only what is queued, no waiting.
    drain.budget_s = 0.0
    t0 = time.monotonic()
    assert drain.run() == 0 and time.monotonic() - t0 < 0.5
    js_pub.publish(JointState())
    got = []
    assert _wait(lambda: got.append(drain.run()) or sum(got) == 1, 10.0), (got, log[-3:])
    drain.close()


def test_on_idle_is_called_once_the_queue_is_empty_not_between_queued_joint_states(peers):
    # What the node uses to continue a stopped query computation (yield_gate): once per
    # stretch of queued joint states, when the queue is empty and the drain is about to wait.
    sub_node = peers[1]
    log = []
    js_sub, js_pub = _joint_states(peers)
    for i in range(50):
        msg = JointState()
        msg.header.stamp.nanosec = i
        js_pub.publish(msg)
    time.sleep(1.0)
    drain = InputDrain([], (js_sub, lambda m, info: log.append(m.header.stamp.nanosec)),
                       sub_node.context, budget_s=0.5)
    drain.on_idle = lambda: log.append('idle')
    assert drain.run() == 50
    assert log[:50] == list(range(50)) and set(log[50:]) == {'idle'} and len(log) > 50
    drain.close()


def test_idle_work_runs_in_pieces_between_joint_states_and_never_delays_one(peers):
    # The node's FWS in steps (fws_worker false): on_idle returns True while work remains;
    # the drain then looks at its queue before the next piece, and waits only once idle work
    # is done. A joint state published during the pieces is taken after at most one piece.
    sub_node = peers[1]
    log = []
    js_sub, js_pub = _joint_states(peers)
    pieces = [40]                    # pieces of idle work left; each takes 10 ms

    def idle() -> bool:
        if pieces[0] == 0:
            log.append('nothing')
            return False
        if pieces[0] == 30:          # a joint state arrives while the idle work goes on
            js_pub.publish(JointState())
        time.sleep(0.01)
        pieces[0] -= 1
        log.append('piece')
        return pieces[0] > 0

    drain = InputDrain([], (js_sub, lambda m, info: log.append('js')), sub_node.context,
                       budget_s=1.5)
    drain.on_idle = idle
    js_pub.publish(JointState())
    time.sleep(1.0)                  # delivered
    t0 = time.monotonic()
    assert drain.run() == 2
    assert time.monotonic() - t0 > 1.5
    assert log.count('piece') == 40 and log.count('js') == 2, log
    # The second joint state came in between pieces, a piece or two after it was published.
    second = [i for i, e in enumerate(log) if e == 'js'][1]
    assert 10 <= log[:second].count('piece') <= 13, log
    # Once the work was done (the last piece said so), the drain waited out its budget.
    assert log[-1] == 'piece' and 'nothing' not in log
    drain.close()


def test_the_reader_is_emptied_into_the_node_queue_whose_oldest_beyond_its_bound_are_dropped(
        peers):
    # Each look for the next joint state moves all those waiting in the DDS reader into the
    # drain's own queue (max_queued, oldest dropped beyond it: their sequence numbers go
    # missing, which the node counts); a run that returns with some still queued says so
    # (on_pending: the node's guard condition), and a message pushed by the executor waits
    # behind them.
    sub_node = peers[1]
    log, pending = [], []
    js_sub, js_pub = _joint_states(peers)
    for i in range(100):
        msg = JointState()
        msg.header.stamp.nanosec = i
        js_pub.publish(msg)
    time.sleep(1.0)                                     # all 100 delivered
    drain = InputDrain([], (js_sub, lambda m, info: log.append(
                           (m.header.stamp.nanosec, info['publication_sequence_number']))),
                       sub_node.context, budget_s=0.0, max_queued=30)
    drain.on_pending = lambda: pending.append(len(drain.queued))
    assert drain.run() == 1                             # budget 0: one answered
    assert [s for s, _ in log] == [70] and drain.dropped == 70
    assert pending == [29] and len(drain.queued) == 29
    assert take(js_sub) is None                         # the reader holds none of them
    for i in range(100, 105):
        msg = JointState()
        msg.header.stamp.nanosec = i
        js_pub.publish(msg)
    time.sleep(1.0)
    drain.push(*take(js_sub))               # as the executor does: 100, before 101 to 104
    drain.budget_s, drain.max_queued = 0.5, 1000
    assert drain.run() == 34                            # then the queue ran empty
    assert [s for s, _ in log] == list(range(70, 105))
    assert [q for _, q in log] == list(range(log[0][1], log[0][1] + 35))
    assert pending == [29] and not drain.queued         # empty: not called again
    drain.close()
