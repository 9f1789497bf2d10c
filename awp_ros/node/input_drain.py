"""
Take queued input messages straight from their subscriptions, without the executor.

rclpy's executors spend about 0.2 ms per message on this machine (a wait set rebuilt from
every subscription, timer, guard condition and parameter service of the node, a task per
callback): a fifth of a 1 kHz joint-state budget. :class:`InputDrain` takes messages
directly from the subscriptions' queues (``take_message``, what the executor calls) and
waits for the next one on a small wait set of the input subscriptions only, so that a node
answering a stream of joint states returns to its executor (timers, parameter services)
only once per ``budget_s``.

The node's own queue: every time it looks for the next joint state, the drain first moves
*all* joint states waiting in the DDS reader into a queue of its own (a deque, oldest first,
at most ``max_queued``; beyond that the oldest are dropped, as DDS's keep-last history would,
and the node counts them from the gaps in the publishers' sequence numbers), then answers the
oldest. The DDS reader then holds only what arrived during one evaluation. Left in the
reader, a backlog makes Fast DDS's receive thread costlier as it grows (a node overloaded on
purpose at 1 kHz: 2 % of a core at 12 s, 8 % at 44 s; with this queue at most 1.7 %; README,
"Session 17: the backlog leaves the DDS reader"), CPU a node behind needs to catch up. A
joint state the executor took is queued
behind those already in the node's queue; a drain returning to the executor with joint states
still queued calls ``on_pending`` (the node triggers a guard condition, or with the
EventsExecutor, which has none, resets a timer; its callback runs the drain again), so none
waits for the next message to wake the executor.

Order: a joint state is handled after every contacts (and imu) message received up to the
moment it is handled, including those that arrived just after it: messages of different
topics travel in different DDS readers, so a contacts message published just before a joint
state may arrive just after it. The pipeline pairs each joint state with the inputs current
at its stamp (:mod:`awp_ros.ros.input_buffer`), so taking newer ones early does no harm.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence
from contextlib import ExitStack
import time

from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.subscription import Subscription

__all__ = ['InputDrain', 'take']

Handler = Callable[[object, dict], None]


def take(sub: Subscription) -> tuple[object, dict] | None:
    """Return ``(message, info)`` taken from a subscription's queue, None when it is empty."""
    with sub.handle:
        taken = sub.handle.take_message(sub.msg_type, sub.raw)
    return None if taken is None else (taken[0], taken[1])


class InputDrain:
    """
    Answer queued joint states in a loop of takes and lean waits (module docstring).

    :param inputs: ``(subscription, handler)`` of the inputs taken before each joint state
        (contacts, imu).
    :param main: ``(subscription, handler)`` of the joint states.
    :param context: the rclpy context of the node.
    :param budget_s: longest time [s] spent in one :meth:`run` before returning to the
        executor; 0 = only the messages already queued, no waiting.
    :param max_queued: most joint states the node's own queue holds (the node's
        ``qos_depth``); the oldest beyond it are dropped.
    """

    def __init__(self, inputs: Sequence[tuple[Subscription, Handler]],
                 main: tuple[Subscription, Handler], context, *,
                 budget_s: float = 0.02, max_queued: int = 10000) -> None:
        self._inputs = list(inputs)
        self._main = main
        self._subs = [sub for sub, _ in self._inputs] + [main[0]]
        self._context = context
        self.budget_s = budget_s
        self.max_queued = max(1, int(max_queued))
        #: Joint states ``(message, info)`` taken from the DDS reader, not yet answered.
        self.queued: deque[tuple[object, dict]] = deque()
        #: Joint states dropped from :attr:`queued` when it was full (total).
        self.dropped = 0
        #: Called when the joint-state queue is empty, before waiting (None = nothing); when
        #: it returns True (it did some work, more remains) the queue is looked at again
        #: and it is called again instead of waiting.
        self.on_idle: Callable[[], bool | None] | None = None
        #: Called when :meth:`run` returns with joint states still queued (None = nothing).
        self.on_pending: Callable[[], None] | None = None
        self._wait_set = None

    def push(self, message: object, info: dict) -> None:
        """
        Queue a joint state taken elsewhere (by the executor) behind those queued.

        It came out of the DDS reader before those still in it: queued before them.
        """
        self.queued.append((message, info))
        self._bound()

    def queue_joint_states(self) -> int:
        """Move the joint states waiting in the DDS reader into :attr:`queued`; return how many."""
        sub = self._main[0]
        queued = self.queued
        count = 0
        while (taken := take(sub)) is not None:
            queued.append(taken)
            count += 1
        if count:
            self._bound()
        return count

    def run(self) -> int:
        """Answer joint states until none arrives within the budget; return how many."""
        end = time.monotonic() + self.budget_s
        handler = self._main[1]
        queued = self.queued
        count = 0
        try:
            while True:
                self.queue_joint_states()
                if queued:
                    taken = queued.popleft()
                    self.take_inputs()
                    handler(*taken)
                    count += 1
                    if time.monotonic() < end:
                        continue
                    return count
                self.take_inputs()               # what woke the wait, if not a joint state
                remaining = end - time.monotonic()
                if remaining <= 0.0 or not self._context.ok():
                    return count
                if self.on_idle is not None and self.on_idle():   # queue empty: idle work
                    continue
                if not self._wait(remaining):
                    return count
        finally:
            if queued and self.on_pending is not None:
                self.on_pending()

    def _bound(self) -> None:
        """Drop the oldest queued joint states beyond :attr:`max_queued`."""
        queued = self.queued
        while len(queued) > self.max_queued:
            queued.popleft()
            self.dropped += 1

    def take_inputs(self) -> int:
        """Hand every queued contacts (and imu) message to its handler; return how many."""
        count = 0
        for input_sub, input_handler in self._inputs:
            while (taken := take(input_sub)) is not None:
                input_handler(*taken)
                count += 1
        return count

    def close(self) -> None:
        """Release the wait set (before the node's subscriptions are destroyed)."""
        if self._wait_set is not None:
            self._wait_set.destroy_when_not_in_use()
            self._wait_set = None

    def _wait(self, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` for a message on an input; return whether one is ready."""
        with ExitStack() as stack:
            for sub in self._subs:
                stack.enter_context(sub.handle)
            stack.enter_context(self._context.handle)
            if self._wait_set is None:
                self._wait_set = _rclpy.WaitSet(len(self._subs), 0, 0, 0, 0, 0,
                                                self._context.handle)
            ws = self._wait_set
            ws.clear_entities()
            for sub in self._subs:
                ws.add_subscription(sub.handle)
            ws.wait(max(1, int(timeout_s * 1e9)))
            return bool(ws.get_ready_entities('subscription'))
