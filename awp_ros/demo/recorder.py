"""
Recording a running node: its input and output topics, serialised, into a bag.

:func:`discover_outputs` waits for ``awp_node``'s publishers; :class:`Recorder` subscribes
to topics without deserialising them and writes every message to a
:class:`~awp_ros.bags.writer.BagWriter`, logged at bag time (an anchor bag time plus the wall
time since, times the playback rate), and keeps the reports for the live table and plot.
"""

from __future__ import annotations

import threading
import time

from awp_ros.bags.message_types import message_class, OUTPUT_TYPES
from awp_ros.bags.player import live_qos
from awp_ros.bags.reader import BagMessage
from awp_ros.bags.writer import BagWriter

__all__ = ['Recorder', 'discover_outputs', 'REPORT_TYPE']

REPORT_TYPE = OUTPUT_TYPES['report']


class Recorder:
    """Subscribe (serialised) to the inputs and the node's outputs, write them to a bag."""

    def __init__(self, node, writer: BagWriter, *, rate: float, depth: int) -> None:
        self.node = node
        self.writer = writer
        self.rate = rate
        self.depth = depth
        self.lock = threading.Lock()
        self.subs: dict = {}
        self.reports: list = []
        self.t0_bag: int | None = None
        self.t0_wall: float | None = None
        self.report_topic = ''

    def start_clock(self, t0_bag: int) -> None:
        """Anchor log times: now (wall) is bag time ``t0_bag`` [ns]."""
        self.t0_bag, self.t0_wall = t0_bag, time.monotonic()

    def subscribe(self, topic: str, msgtype: str) -> None:
        """Record ``topic`` (once), best effort if any of its publishers is."""
        from rclpy.qos import ReliabilityPolicy

        if topic in self.subs:
            return
        infos = self.node.get_publishers_info_by_topic(topic)
        best_effort = any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
                          for i in infos)
        qos = live_qos(self.depth, best_effort=best_effort)
        cls = message_class(msgtype)
        is_report = msgtype == REPORT_TYPE
        if is_report:
            self.report_topic = topic

        def callback(data: bytes, topic=topic, msgtype=msgtype, cls=cls) -> None:
            now = time.monotonic()
            with self.lock:
                if self.t0_wall is None:
                    return
                stamp = self.t0_bag + int((now - self.t0_wall) * self.rate * 1e9)
                self.writer.write(BagMessage(topic, msgtype, stamp, bytes(data)))
                if is_report:
                    from rclpy.serialization import deserialize_message
                    self.reports.append(deserialize_message(data, cls))

        self.subs[topic] = self.node.create_subscription(cls, topic, callback, qos, raw=True)


def discover_outputs(node, node_name: str, timeout_s: float, proc) -> dict[str, str]:
    """Wait for the node's report publisher; return its output topics (topic -> type)."""
    prefix = f'/{node_name}/'
    deadline = time.monotonic() + timeout_s
    found: dict[str, str] = {}
    settle = None
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            break
        found = {name: types[0] for name, types in node.get_topic_names_and_types()
                 if (name.startswith(prefix) or name == '/diagnostics') and types}
        if any(t == REPORT_TYPE for t in found.values()):
            settle = settle or time.monotonic()
            if time.monotonic() - settle > 0.5:   # let the remaining publishers appear
                return found
        time.sleep(0.05)
    return {}
