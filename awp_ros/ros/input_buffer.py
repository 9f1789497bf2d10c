"""
Pairing of the contacts and imu inputs with joint states, by stamp.

:class:`InputBuffer` keeps the received messages of one input topic and picks the one
current at a joint state's stamp; :func:`stale_reason` says why a picked message cannot be
used with that joint state (none yet, older than its input's timeout, or more than
``stale_timeout_s`` later than the joint state). A contacts message holds until the next
one (``contacts_timeout_s`` 0, the default): publishers that publish contacts only when
they change are served as well as periodic ones.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Sequence

from awp_ros.ros.conversions import stamp_to_ns

__all__ = ['InputBuffer', 'stale_reason']


class InputBuffer:
    """
    The received messages of one input topic not yet passed by a joint state's stamp.

    Kept as parallel lists from ``head`` on (stamps [ns], messages) so that a node lagging
    behind its joint states, which holds the contacts of the whole lag, finds the one to
    pair in O(log n) (bisection while the stamps are non-decreasing, the usual case) and
    drops the passed ones in O(1) amortised. At most ``maxlen`` are kept (the oldest go
    first; a joint state that then finds only later contacts is reported stale).
    """

    def __init__(self, maxlen: int = 10000) -> None:
        self.maxlen = max(int(maxlen), 1)
        self.stamps: list[int] = []
        self.msgs: list = []
        self.head = 0
        self.sorted = True

    def __len__(self) -> int:
        return len(self.stamps) - self.head

    def add(self, msg) -> None:
        ns = stamp_to_ns(msg.header.stamp)
        if len(self) and ns < self.stamps[-1]:
            self.sorted = False
        self.stamps.append(ns)
        self.msgs.append(msg)
        if len(self) > self.maxlen:
            self.head += 1
        self._compact()

    def pick(self, ns: int):
        """
        Return the newest message stamped at or before ``ns``, else the earliest one.

        Messages older than the one returned are dropped; None when empty.
        """
        stamps, h = self.stamps, self.head
        if h == len(stamps):
            return None
        if self.sorted:
            i = bisect_right(stamps, ns, h) - 1
        else:
            i = next((i for i in range(len(stamps) - 1, h - 1, -1) if stamps[i] <= ns), -1)
        if i >= h:
            self.head = h = i
            if h == len(stamps) - 1:
                self.sorted = True
            self._compact()
        return self.msgs[self.head]

    def _compact(self) -> None:
        if self.head > 64 and 2 * self.head > len(self.stamps):
            del self.stamps[:self.head]
            del self.msgs[:self.head]
            self.head = 0


def stale_reason(ns: int, inputs: Sequence[tuple], stale_timeout_s: float) -> str:
    """
    Return why the inputs cannot be used with a joint state at ``ns`` [ns], or ''.

    :param inputs: ``(topic, picked message or None)`` or ``(topic, message, max_age_s)``
        items, checked in order; ``max_age_s`` replaces ``stale_timeout_s`` for how much
        older than the joint state that input may be (0: any age, the message holds until
        the next one).
    :param stale_timeout_s: largest stamp difference either way [s] (the inputs' default
        age and how much later than the joint state any input may be); 0 disables it.
    """
    timeout = int(stale_timeout_s * 1e9)
    for item in inputs:
        topic, msg = item[0], item[1]
        if msg is None:
            return f'no {topic} message received yet'
        age = ns - stamp_to_ns(msg.header.stamp)
        if len(item) > 2:
            max_age, name = int(item[2] * 1e9), f'{topic}_timeout_s {item[2]:g}'
        else:
            max_age, name = timeout, f'stale_timeout_s {stale_timeout_s:g}'
        if max_age > 0 and age > max_age:
            return (f'{topic} is stale: its stamp is {age * 1e-9:.3f} s older than the '
                    f'joint state ({name})')
        if timeout > 0 and -age > timeout:
            return (f'{topic} stamp is {-age * 1e-9:.3f} s later than the joint state '
                    f'(stale_timeout_s {stale_timeout_s:g}): clocks that disagree, '
                    'or joint states that went back')
    return ''
