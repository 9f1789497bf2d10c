"""
A DDS participant of our own: :class:`Probe` (publish, subscribe, spun in a thread).

Used by the soak test, its driver and the node tests to talk to ``awp_node`` over real DDS;
:func:`wait_until` polls for the discovery and the messages they wait for.
"""

from __future__ import annotations

import threading
import time
import traceback

from awp_ros.errors import InputError

__all__ = ['Probe', 'wait_until']


def wait_until(predicate, timeout_s: float, what: str, *, poll_s: float = 0.02) -> None:
    """
    Poll ``predicate()`` until true; raise TimeoutError naming ``what`` after a while.

    :param timeout_s: how long to poll [s].
    """
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(poll_s)
    raise TimeoutError(f'timed out after {timeout_s} s waiting for {what}')


class Probe:
    """
    One DDS participant (an rclpy Context on ``domain_id``) spun in a background thread.

    Publishers and subscriptions are reliable, keep last ``depth``. Received messages are
    appended to the list :meth:`subscribe` returns (under ``lock``), or passed to a
    callback. A fast stream (the soak's reports) is better taken with ``drain=True``: by a
    thread of its own that takes the messages as the node takes its joint states
    (:class:`~awp_ros.node.input_drain.InputDrain`), not by rclpy's executor, which costs
    about 0.2 ms per message: at 2 kHz 43 % of a core taken from the node under test.
    """

    def __init__(self, domain_id: int, name: str = 'awp_probe') -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        self.context = rclpy.Context()
        # args=[]: not sys.argv, whose NAME:=VALUE words (the soak's --param) rcl would take
        # for remap rules of this node.
        rclpy.init(args=[], context=self.context, domain_id=int(domain_id))
        self.node = rclpy.create_node(name, context=self.context)
        self.lock = threading.Lock()
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()
        self._drains: list[threading.Thread] = []
        self._closing = threading.Event()
        #: Exceptions that ended a drained subscription's thread (its handler's, rclpy's).
        self.drain_errors: list[Exception] = []

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException
        try:
            self.executor.spin()
        except (ExternalShutdownException, Exception):  # noqa: BLE001 -- shutting down
            pass

    @staticmethod
    def qos(depth: int):
        """Return a reliable, keep-last ``depth`` QoS profile."""
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                          reliability=ReliabilityPolicy.RELIABLE)

    def publisher(self, mtype, topic: str, depth: int = 1000):
        """Return a publisher of ``mtype`` on ``topic``."""
        return self.node.create_publisher(mtype, topic, self.qos(depth))

    def subscribe(self, mtype, topic: str, callback=None, depth: int = 1000, *,
                  raw: bool = False, drain: bool = False, with_info: bool = False) -> list:
        """
        Subscribe to ``topic``; return the list the messages are appended to.

        :param raw: receive the serialized bytes (no deserialization: a consumer that only
            counts, or stores, big messages).
        :param drain: take the messages in a thread of their own (class docstring), on a
            node of their own that the executor does not spin.
        :param with_info: (with ``drain``) the callback gets ``(msg, info)``, or the list
            such pairs: ``info`` the middleware's message info, whose ``source_timestamp``
            is when the publisher wrote the message and ``received_timestamp`` when this
            participant's middleware received it [ns, system clock].
        """
        if with_info and not drain:
            raise InputError('with_info needs drain=True (the executor passes no info)')
        got: list = []

        def store(msg, info=None) -> None:
            with self.lock:
                got.append(msg if info is None else (msg, info))
        handler = callback or store
        if not drain:
            self.node.create_subscription(mtype, topic, handler, self.qos(depth), raw=raw)
            return got
        import rclpy
        from awp_ros.node.input_drain import InputDrain
        node = rclpy.create_node(f'{self.node.get_name()}_drain{len(self._drains)}',
                                 context=self.context)
        sub = node.create_subscription(mtype, topic, handler, self.qos(depth), raw=raw)
        take = handler if with_info else (lambda msg, _info: handler(msg))
        loop = InputDrain([], (sub, take), self.context, budget_s=0.1)

        def run() -> None:
            try:
                while not self._closing.is_set() and self.context.ok():
                    loop.run()
            except Exception as exc:  # noqa: BLE001 -- kept and printed, unless shutting down
                if not self._closing.is_set() and self.context.ok():
                    self.drain_errors.append(exc)
                    traceback.print_exc()
            finally:
                loop.close()
                node.destroy_node()
        thread = threading.Thread(target=run, daemon=True)
        self._drains.append(thread)
        thread.start()
        return got

    def close(self) -> None:
        """Stop spinning and leave the domain."""
        import rclpy
        self._closing.set()
        for thread in self._drains:
            thread.join(timeout=5)
        self.executor.shutdown(timeout_sec=2.0)
        self._thread.join(timeout=5)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
