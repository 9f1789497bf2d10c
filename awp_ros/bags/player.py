"""
Live playback: publish a bag's messages onto DDS at the recorded pace.

For feeding a running ``awp_node`` where ``ros2 bag play`` is not installed. Messages are
published serialised (no round trip through Python objects) on reliable publishers.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
import math
import time
from typing import TextIO

from awp_ros.bags.message_types import message_class
from awp_ros.bags.progress import Progress
from awp_ros.bags.reader import bag_info, read_bag, require_topics
from awp_ros.errors import BagError

__all__ = ['play_bag', 'live_qos']


def play_bag(path, *, rate: float = 1.0, remap: Mapping[str, str] | None = None,
             topics: Iterable[str] | None = None, wait_s: float = 0.0,
             wait_topics: Iterable[str] | None = None, qos_depth: int = 1000,
             node_name: str = 'awp_replay_player', progress: bool = True,
             stream: TextIO | None = None, ack_timeout_s: float = 10.0,
             duration_s: float | None = None) -> int:
    """
    Publish a bag's messages onto live DDS at the recorded pace; return the count.

    rclpy must be initialised by the caller (``rclpy.init()``). Messages are published
    serialised (no deserialisation) on reliable, volatile, keep-last(``qos_depth``)
    publishers, which reliable and best-effort subscribers both match. The message with log
    time ``t`` goes out at ``start + (t - t_first) / rate`` (wall clock); a late player
    publishes at once, so nothing is dropped.

    :param rate: speed factor (2 = twice as fast); ``math.inf`` = as fast as possible.
    :param remap: bag topic -> published topic.
    :param topics: only these bag topics (default all).
    :param wait_s: wait up to this long before starting until every topic in
        ``wait_topics`` (default: all published topics) has a subscriber.
    :param ack_timeout_s: at the end, wait up to this long for reliable delivery.
    :param duration_s: play only messages logged less than this after the bag's start [s].
    :raises BagError: unreadable bag, missing topic, or a type without a Python interface.
    """
    import rclpy
    from rclpy.duration import Duration

    if not rate > 0.0:
        raise BagError(f'rate must be > 0, got {rate!r}')
    info = bag_info(path)
    selected = list(info.topics) if topics is None else list(topics)
    require_topics(path, selected, info.topics)
    remap = dict(remap or {})
    classes = {t: message_class(info.topics[t].msgtype) for t in selected}
    qos = live_qos(qos_depth)
    node = rclpy.create_node(node_name)
    try:
        pubs = {t: node.create_publisher(classes[t], remap.get(t, t), qos) for t in selected}
        waited = [pubs[t] for t in (wait_topics if wait_topics is not None else selected)
                  if t in pubs]
        deadline = time.monotonic() + wait_s
        while waited and time.monotonic() < deadline and \
                any(p.get_subscription_count() == 0 for p in waited):
            time.sleep(0.01)
        total = sum(info.topics[t].count for t in selected)
        stop_ns = None if duration_s is None else info.start_ns + int(duration_s * 1e9)
        bar = Progress(total, label='play', enabled=progress, stream=stream)
        sent = 0
        t_first = None
        start = time.monotonic()
        for msg in read_bag(path, topics=selected):
            if stop_ns is not None and msg.timestamp >= stop_ns:
                break
            if t_first is None:
                t_first = msg.timestamp
            if math.isfinite(rate):
                due = start + (msg.timestamp - t_first) * 1e-9 / rate
                delay = due - time.monotonic()
                if delay > 0.0:
                    time.sleep(delay)
            pubs[msg.topic].publish(msg.data)
            sent += 1
            bar.update()
        bar.close()
        for pub in pubs.values():
            pub.wait_for_all_acked(Duration(seconds=ack_timeout_s))
        return sent
    finally:
        node.destroy_node()


def live_qos(depth: int, *, best_effort: bool = False):
    """
    Return the rclpy QoS of live playback and recording.

    Keep last ``depth``, volatile, reliable (or best effort).
    """
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=(ReliabilityPolicy.BEST_EFFORT if best_effort
                                   else ReliabilityPolicy.RELIABLE),
                      durability=DurabilityPolicy.VOLATILE)
