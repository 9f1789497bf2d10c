"""Counters of the node and the ``diagnostic_msgs/DiagnosticArray`` built from them.

``diagnostic_updater`` is not among the PyPI ROS wheels, so this follows its conventions by
hand: one array per period (1 Hz) on ``/diagnostics``, statuses named ``<node>: <topic>``,
``hardware_id`` = the robot name, levels OK / WARN / ERROR, values as key-value strings with
units in the keys. Two statuses:

- ``<node>: inputs``: per input topic the receive rate [Hz] over the last period, the age of
  the last message [s] (wall time), messages lost (DDS ``message_lost`` events) and
  malformed. WARN when an input is stale (older than ``stale_timeout_s``) or messages were
  lost in the period; ERROR when no joint state arrived yet.
- ``<node>: evaluation``: reports per status in the period and in total, compute time
  p50 / p99 [ms] and latency from the joint-state stamp to the report's publication p50 /
  p99 [ms] over the period. WARN when reports in the period were not evaluated (invalid,
  stale, error) or when the p50 compute time exceeds the joint-state period of the period's
  receive rate (the node is falling behind; the queue of ``qos_depth`` absorbs bursts).

Everything here is O(1) per message (a few counters and one slot of a preallocated ring).
"""

from __future__ import annotations

from collections.abc import Sequence

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
import numpy as np
from std_msgs.msg import Header

__all__ = ['NodeDiagnostics', 'STATUS_NAMES']

#: FeasibilityReport.STATUS_* value -> name used in the diagnostics keys.
STATUS_NAMES = ('ok', 'warning', 'invalid_input', 'stale_input', 'error')


class _Ring:
    """A fixed-size ring of floats (the last ``size`` samples of the period)."""

    def __init__(self, size: int) -> None:
        self.data = np.empty(size)
        self.n = 0

    def add(self, x: float) -> None:
        self.data[self.n % self.data.size] = x
        self.n += 1

    def percentiles(self, q: Sequence[float]) -> list[float]:
        k = min(self.n, self.data.size)
        if k == 0:
            return [float('nan')] * len(q)
        return np.percentile(self.data[:k], q).tolist()

    def clear(self) -> None:
        self.n = 0


class _Input:
    """Counters of one input topic."""

    def __init__(self) -> None:
        self.total = 0
        self.period = 0
        self.last_wall: float | None = None
        self.lost = 0
        self.lost_period = 0


class NodeDiagnostics:
    """Counters of inputs and evaluations, and the DiagnosticArray built from them.

    :param node_name: prefix of the status names.
    :param hardware_id: the robot name.
    :param topics: the input topics to watch (e.g. ``('joint_states', 'contacts')``).
    :param stale_timeout_s: an input older than this (wall time) is stale [s]; 0 disables.
    :param ring_size: samples kept per period for the percentiles.
    """

    def __init__(self, node_name: str, hardware_id: str, topics: Sequence[str], *,
                 stale_timeout_s: float = 0.5, ring_size: int = 8192) -> None:
        self.node_name = node_name
        self.hardware_id = hardware_id
        self.stale_timeout_s = stale_timeout_s
        self.inputs = {t: _Input() for t in topics}
        self.reports_total = np.zeros(len(STATUS_NAMES), dtype=np.int64)
        self.reports_period = np.zeros(len(STATUS_NAMES), dtype=np.int64)
        self.compute_ms = _Ring(ring_size)
        self.latency_ms = _Ring(ring_size)
        self.period_start: float | None = None
        self.last_reason = ''

    # -- recording (per message) -----------------------------------------------------------

    def received(self, topic: str, wall: float) -> None:
        """Count one message received on ``topic`` at wall time ``wall`` [s]."""
        c = self.inputs[topic]
        c.total += 1
        c.period += 1
        c.last_wall = wall

    def lost(self, topic: str, count: int) -> None:
        """Count ``count`` messages reported lost by the middleware on ``topic``."""
        c = self.inputs[topic]
        c.lost += count
        c.lost_period += count

    def evaluated(self, status: int, compute_time_s: float, latency_s: float | None,
                  reason: str = '') -> None:
        """Count one report of ``status`` (STATUS_* value), its compute time and latency."""
        i = min(int(status), len(STATUS_NAMES) - 1)
        self.reports_total[i] += 1
        self.reports_period[i] += 1
        self.compute_ms.add(1e3 * compute_time_s)
        if latency_s is not None:
            self.latency_ms.add(1e3 * latency_s)
        if i >= 2 and reason:
            self.last_reason = reason

    # -- building (per period) -------------------------------------------------------------

    def build(self, stamp, wall: float) -> DiagnosticArray:
        """Return the DiagnosticArray of the period ending at wall time ``wall`` [s].

        Resets the per-period counters. ``stamp`` is the header stamp (node clock).
        """
        dt = None if self.period_start is None else max(wall - self.period_start, 1e-9)
        self.period_start = wall
        msg = DiagnosticArray(header=Header(stamp=stamp))
        first = next(iter(self.inputs.values()), None)
        rate = first.period / dt if first is not None and dt else 0.0
        msg.status = [self._inputs_status(wall, dt), self._evaluation_status(rate)]
        for c in self.inputs.values():
            c.period = 0
            c.lost_period = 0
        self.reports_period[:] = 0
        self.compute_ms.clear()
        self.latency_ms.clear()
        return msg

    def _inputs_status(self, wall: float, dt: float | None) -> DiagnosticStatus:
        values, stale, lost = [], [], []
        for topic, c in self.inputs.items():
            rate = float('nan') if dt is None else c.period / dt
            age = float('inf') if c.last_wall is None else wall - c.last_wall
            values += [KeyValue(key=f'{topic} rate [Hz]', value=f'{rate:.1f}'),
                       KeyValue(key=f'{topic} age [s]', value=f'{age:.3f}'),
                       KeyValue(key=f'{topic} received (total)', value=str(c.total)),
                       KeyValue(key=f'{topic} lost (total)', value=str(c.lost))]
            if self.stale_timeout_s > 0.0 and age > self.stale_timeout_s:
                stale.append(topic)
            if c.lost_period:
                lost.append(f'{topic} ({c.lost_period})')
        first = next(iter(self.inputs.values()), None)
        if first is not None and first.total == 0:
            level, text = DiagnosticStatus.ERROR, f'no {next(iter(self.inputs))} received yet'
        elif stale or lost:
            level = DiagnosticStatus.WARN
            text = '; '.join(([f'stale: {", ".join(stale)}'] if stale else [])
                             + ([f'lost: {", ".join(lost)}'] if lost else []))
        else:
            level, text = DiagnosticStatus.OK, 'inputs fresh'
        return DiagnosticStatus(level=level, name=f'{self.node_name}: inputs', message=text,
                                hardware_id=self.hardware_id, values=values)

    def _evaluation_status(self, input_rate: float) -> DiagnosticStatus:
        c50, c99 = self.compute_ms.percentiles([50, 99])
        l50, l99 = self.latency_ms.percentiles([50, 99])
        values = [KeyValue(key=f'reports {name} (period)', value=str(int(n)))
                  for name, n in zip(STATUS_NAMES, self.reports_period)]
        values += [KeyValue(key=f'reports {name} (total)', value=str(int(n)))
                   for name, n in zip(STATUS_NAMES, self.reports_total)]
        values += [KeyValue(key='compute time p50 [ms]', value=f'{c50:.3f}'),
                   KeyValue(key='compute time p99 [ms]', value=f'{c99:.3f}'),
                   KeyValue(key='latency stamp to publish p50 [ms]', value=f'{l50:.3f}'),
                   KeyValue(key='latency stamp to publish p99 [ms]', value=f'{l99:.3f}'),
                   KeyValue(key='last error', value=self.last_reason)]
        bad = int(self.reports_period[2:].sum())
        n = int(self.reports_period.sum())
        period_ms = 1e3 / input_rate if input_rate > 0.0 else float('inf')
        if bad:
            level = DiagnosticStatus.WARN
            text = f'{bad} of {n} reports not evaluated; last: {self.last_reason[:120]}'
        elif c50 > period_ms:
            level = DiagnosticStatus.WARN
            text = (f'falling behind: compute time p50 {c50:.2f} ms > joint_states period '
                    f'{period_ms:.2f} ms')
        else:
            level, text = DiagnosticStatus.OK, f'{n} reports'
        return DiagnosticStatus(level=level, name=f'{self.node_name}: evaluation',
                                message=text, hardware_id=self.hardware_id, values=values)
