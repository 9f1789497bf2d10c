"""
The driver process of the soak test (``python -m awp_ros.soak --drive ...``).

:func:`drive` publishes gait joint states (and contacts) at a fixed rate on a schedule,
stamped with the wall clock when published, and saves the stamps it sent;
:func:`driver_command` is the command line that runs it.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from awp_ros.errors import InputError
from awp_ros.soak.probe import Probe, wait_until

__all__ = ['drive', 'driver_command']


def _stamp(msg, ns: int):
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
    return msg


def _joint_state_bytes(names: list[str], q: np.ndarray, v: np.ndarray) -> list[bytearray]:
    """
    Return the serialized JointState of each gait sample (name, position, velocity).

    Serialized once, before the drive: at 2 kHz, building and converting a message per
    publish cost the driver about a fifth of a core, taken from the node under test.
    :func:`awp_ros.ros.cdr.stamped` then writes each one's stamp into its bytes.
    """
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState
    js = JointState(name=names)
    out = []
    for qk, vk in zip(q, v):
        js.position, js.velocity = qk.tolist(), vk.tolist()
        out.append(bytearray(serialize_message(js)))
    return out


def drive(*, rate_hz: float, duration_s: float, robot: str, namespace: str,
          stamps_path: str | None, contacts_rate_hz: float = 100.0, depth: int = 100000,
          match_timeout_s: float = 60.0, topics: str = 'both') -> dict:
    """
    Publish gait joint states at ``rate_hz`` for ``duration_s`` (the driver process).

    Waits until the node's subscriptions match, publishes, waits until every message was
    acknowledged, saves the sent stamps [ns] (``np.save``) and returns a summary.
    ``topics``: ``'both'``; ``'joint_states'`` (no contacts); ``'contacts'`` (contacts
    only, one per tick at ``rate_hz``: a stand-alone contact publisher).
    """
    import rclpy
    from awp_ros_msgs.msg import ContactState
    from rclpy.qos import DurabilityPolicy
    from sensor_msgs.msg import JointState

    from awp_ros.gait.generator import generate_gait
    from awp_ros.robot.config import load_config
    from awp_ros.ros.cdr import stamped

    send_js, send_c = topics in ('both', 'joint_states'), topics in ('both', 'contacts')
    if not (send_js or send_c):
        raise InputError(f"topics must be 'both', 'joint_states' or 'contacts', got {topics!r}")
    samples = generate_gait(load_config(robot))
    names = list(samples.joint_names)
    feet = list(samples.feet)
    messages = _joint_state_bytes(names, np.asarray(samples.q, dtype=float),
                                  np.asarray(samples.v, dtype=float))
    stance = [tuple(bool(c) for c in row) for row in samples.stance]
    rclpy.init()
    node = rclpy.create_node('awp_soak_driver')
    ns = namespace.rstrip('/')
    qos = Probe.qos(depth)
    js_pub = node.create_publisher(JointState, f'{ns}/joint_states', qos) if send_js else None
    # Transient local: matches the node's contacts subscription whether it is volatile or
    # transient local (contacts_durability); a volatile one would not match the latter.
    c_qos = Probe.qos(depth)
    c_qos.durability = DurabilityPolicy.TRANSIENT_LOCAL
    c_pub = node.create_publisher(ContactState, f'{ns}/contacts', c_qos) if send_c else None
    pubs = [p for p in (js_pub, c_pub) if p is not None]
    wait_until(lambda: all(p.get_subscription_count() for p in pubs), match_timeout_s,
               'awp_node to subscribe')
    time.sleep(0.5)                           # let the matching settle on both sides
    n = int(round(rate_hz * duration_s))
    stamps = np.zeros(n, dtype=np.int64)
    cs = ContactState(names=feet)
    contacts_period = int(1e9 / contacts_rate_hz) if contacts_rate_hz > 0 else None
    last_contacts, last_stance = None, None
    lateness = np.zeros(n)
    start = time.perf_counter()
    for i in range(n):
        target = start + i / rate_hz
        left = target - time.perf_counter()
        if left > 0:
            time.sleep(left)
        lateness[i] = time.perf_counter() - target
        k = i % len(messages)
        now = time.time_ns()
        if send_c and (not send_js or stance[k] != last_stance or last_contacts is None or (
                contacts_period is not None and now - last_contacts >= contacts_period)):
            cs.in_contact = list(stance[k])
            c_pub.publish(_stamp(cs, now))
            last_contacts, last_stance = now, stance[k]
        if send_js:
            js_pub.publish(stamped(messages[k], now))
        stamps[i] = now
    elapsed = time.perf_counter() - start
    # Every publisher waits for its acknowledgements (a list, not a short-circuiting generator).
    acks = [p.wait_for_all_acked(rclpy.duration.Duration(seconds=60.0)) for p in pubs]
    acked = all(acks)
    if stamps_path:
        np.save(stamps_path, stamps)
    node.destroy_node()
    rclpy.try_shutdown()
    return {'sent': n, 'sent_rate_hz': n / elapsed if elapsed > 0 else float('nan'),
            'lateness_p99_ms': float(np.percentile(lateness, 99) * 1e3) if n else 0.0,
            'all_acked': bool(acked)}


def driver_command(rate_hz: float, duration_s: float, *, robot: str = 'hyq',
                   namespace: str = '', stamps_out: str | None = None,
                   contacts_rate_hz: float = 100.0, depth: int = 100000,
                   topics: str = 'both') -> list[str]:
    """Return the command of a driver process (:func:`drive`); it prints one JSON line."""
    cmd = [sys.executable, '-m', 'awp_ros.soak', '--drive', '--rate', str(rate_hz),
           '--duration', str(duration_s), '--robot', robot, '--namespace',
           namespace.rstrip('/') or '/', '--contacts-rate', str(contacts_rate_hz),
           '--depth', str(depth), '--topics', topics]
    return cmd + (['--stamps-out', str(stamps_out)] if stamps_out else [])
