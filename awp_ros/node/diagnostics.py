"""
Counters of the node and the ``diagnostic_msgs/DiagnosticArray`` built from them.

``diagnostic_updater`` is not among the PyPI ROS wheels, so this follows its conventions by
hand: one array per period (1 Hz) on ``/diagnostics``, statuses named ``<node>: <topic>``,
``hardware_id`` = the robot name, levels OK / WARN / ERROR, values as key-value strings with
units in the keys. Two statuses:

- ``<node>: inputs``: per input topic the receive rate [Hz] over the last period, the age of
  the last message [s] (wall time), the messages received, lost (DDS ``message_lost``
  events) and missing from the publisher's sequence numbers (:meth:`~NodeDiagnostics.
  sequence`: silently replaced in a full keep-last queue). WARN when an input is stale
  (older than ``stale_timeout_s``) or messages were lost or missing in the period; ERROR
  when no joint state arrived yet.
- ``<node>: evaluation``: reports per status in the period and in total, the last error and
  the last warning (the reasons of the reports), the reports per number of stance legs in
  the period (e.g. ``2:480, 4:520``; fewer than 3 legs give flat wrench sets), compute time
  p50 / p99 [ms], latency from the joint-state stamp to the report's publication p50 / p99
  [ms] over the period, and outputs that could not be built. ERROR when there is no robot
  model (``model_error``), a report of the period has ``STATUS_ERROR`` or an output failed;
  WARN when parameters were rejected at startup (``config_errors``, defaults used instead),
  reports in the period were not evaluated (invalid, stale), carried a warning,
  or when the p50 compute time exceeds the joint-state period of the period's receive rate
  (the node is falling behind; the queue of ``qos_depth`` absorbs bursts).

``<node>`` is the node's fully qualified name without the leading slash (``awp_node``,
``hyq/awp_node``), so nodes in different namespaces are told apart.

Everything here is O(1) per message (a few counters and one slot of a preallocated ring).
"""

from __future__ import annotations

from collections.abc import Sequence

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
import numpy as np
from std_msgs.msg import Header

from awp_ros.ros.conversions import STATUS_NAMES

__all__ = ['NodeDiagnostics']

#: FeasibilityReport.STATUS_* value -> name used in the diagnostics keys.
_WARNING, _ERROR = 1, 4
_MAX_LEGS = 16            # stance sizes counted per period (larger ones in the last bin)
_REASON_CHARS = 200       # characters of a reason quoted in a status message


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
        self.gaps = 0
        self.gaps_period = 0
        self.last_seq: int | None = None


class NodeDiagnostics:
    """
    Counters of inputs and evaluations, and the DiagnosticArray built from them.

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
        self.stance_period = np.zeros(_MAX_LEGS + 1, dtype=np.int64)
        self.period_start: float | None = None
        self.last_reason = ''
        self.last_warning = ''
        self.model_error = ''
        self.config_errors: list[str] = []
        self.output_errors = 0
        self.output_errors_period = 0
        self.markers_skipped = 0
        self.last_output_error = ''

    # -- recording (per message) -----------------------------------------------------------

    def received(self, topic: str, wall: float) -> None:
        """Count one message received on ``topic`` at wall time ``wall`` [s]."""
        c = self.inputs[topic]
        c.total += 1
        c.period += 1
        c.last_wall = wall

    def sequence(self, topic: str, seq: int | None) -> int:
        """
        Check a message's publication sequence number; return how many are missing.

        The sequence numbers of one publisher (DDS writer) increase by one per message, so a
        jump of ``k + 1`` means ``k`` messages published but never received: dropped from a
        full keep-last queue (the node fell ``qos_depth`` behind) or by a best-effort link.
        A smaller number than the last one means a new publisher (restart) and starts over.
        Assumes one publisher per input topic (several interleaved publishers show gaps).

        :param seq: ``publication_sequence_number`` of the message info (None: unknown; the
            next known number then starts over, as a gap across it cannot be told from
            the unknown message).
        """
        c = self.inputs[topic]
        if seq is None:
            c.last_seq = None
            return 0
        missing = 0
        if c.last_seq is not None and seq > c.last_seq + 1:
            missing = seq - c.last_seq - 1
            c.gaps += missing
            c.gaps_period += missing
        c.last_seq = seq
        return missing

    def lost(self, topic: str, count: int) -> None:
        """Count ``count`` messages reported lost by the middleware on ``topic``."""
        c = self.inputs[topic]
        c.lost += count
        c.lost_period += count

    def evaluated(self, status: int, compute_time_s: float, latency_s: float | None,
                  reason: str = '', stance_legs: int | None = None) -> None:
        """
        Count one report of ``status`` (STATUS_* value), its compute time and latency.

        :param reason: the report's status message (kept as the last error or warning).
        :param stance_legs: number of stance legs of an evaluated report (None: not
            evaluated).
        """
        i = min(int(status), len(STATUS_NAMES) - 1)
        self.reports_total[i] += 1
        self.reports_period[i] += 1
        self.compute_ms.add(1e3 * compute_time_s)
        if latency_s is not None:
            self.latency_ms.add(1e3 * latency_s)
        if i >= 2 and reason:
            self.last_reason = reason
        elif i == _WARNING and reason:
            self.last_warning = reason
        if stance_legs is not None:
            self.stance_period[min(int(stance_legs), _MAX_LEGS)] += 1

    def output_failed(self, reason: str) -> None:
        """Count one output message (polytopes, markers) that could not be built."""
        self.output_errors += 1
        self.output_errors_period += 1
        self.last_output_error = reason

    # -- building (per period) -------------------------------------------------------------

    def build(self, stamp, wall: float) -> DiagnosticArray:
        """
        Return the DiagnosticArray of the period ending at wall time ``wall`` [s].

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
            c.gaps_period = 0
        self.reports_period[:] = 0
        self.stance_period[:] = 0
        self.output_errors_period = 0
        self.compute_ms.clear()
        self.latency_ms.clear()
        return msg

    def _inputs_status(self, wall: float, dt: float | None) -> DiagnosticStatus:
        values, stale, lost, gaps = [], [], [], []
        for topic, c in self.inputs.items():
            rate = float('nan') if dt is None else c.period / dt
            age = float('inf') if c.last_wall is None else wall - c.last_wall
            values += [KeyValue(key=f'{topic} rate [Hz]', value=f'{rate:.1f}'),
                       KeyValue(key=f'{topic} age [s]', value=f'{age:.3f}'),
                       KeyValue(key=f'{topic} received (total)', value=str(c.total)),
                       KeyValue(key=f'{topic} lost (total)', value=str(c.lost)),
                       KeyValue(key=f'{topic} sequence gaps (total)', value=str(c.gaps))]
            if self.stale_timeout_s > 0.0 and age > self.stale_timeout_s:
                stale.append(topic)
            if c.lost_period:
                lost.append(f'{topic} ({c.lost_period})')
            if c.gaps_period:
                gaps.append(f'{topic} ({c.gaps_period})')
        first = next(iter(self.inputs.values()), None)
        if first is not None and first.total == 0:
            level, text = DiagnosticStatus.ERROR, f'no {next(iter(self.inputs))} received yet'
        elif stale or lost or gaps:
            level = DiagnosticStatus.WARN
            text = '; '.join(([f'stale: {", ".join(stale)}'] if stale else [])
                             + ([f'lost: {", ".join(lost)}'] if lost else [])
                             + ([f'missing from sequence: {", ".join(gaps)}'] if gaps
                                else []))
        else:
            level, text = DiagnosticStatus.OK, 'inputs fresh'
        return DiagnosticStatus(level=level, name=f'{self.node_name}: inputs', message=text,
                                hardware_id=self.hardware_id, values=values)

    def _evaluation_status(self, input_rate: float) -> DiagnosticStatus:
        c50, c99 = self.compute_ms.percentiles([50, 99])
        l50, l99 = self.latency_ms.percentiles([50, 99])
        values = [KeyValue(key=f'reports {name} (period)', value=str(int(n)))
                  for name, n in zip(STATUS_NAMES.values(), self.reports_period)]
        values += [KeyValue(key=f'reports {name} (total)', value=str(int(n)))
                   for name, n in zip(STATUS_NAMES.values(), self.reports_total)]
        legs = ', '.join(f'{k}:{int(n)}' for k, n in enumerate(self.stance_period) if n)
        values += [KeyValue(key='compute time p50 [ms]', value=f'{c50:.3f}'),
                   KeyValue(key='compute time p99 [ms]', value=f'{c99:.3f}'),
                   KeyValue(key='latency stamp to publish p50 [ms]', value=f'{l50:.3f}'),
                   KeyValue(key='latency stamp to publish p99 [ms]', value=f'{l99:.3f}'),
                   KeyValue(key='reports by stance legs (period)', value=legs),
                   KeyValue(key='last error', value=self.last_reason),
                   KeyValue(key='last warning', value=self.last_warning),
                   KeyValue(key='robot model error', value=self.model_error),
                   KeyValue(key='rejected parameters', value='; '.join(self.config_errors)),
                   KeyValue(key='output errors (total)', value=str(self.output_errors)),
                   KeyValue(key='markers skipped, worker busy (total)',
                            value=str(self.markers_skipped)),
                   KeyValue(key='last output error', value=self.last_output_error)]
        period = self.reports_period
        bad = int(period[2:].sum())
        warned = int(period[_WARNING])
        n = int(period.sum())
        period_ms = 1e3 / input_rate if input_rate > 0.0 else float('inf')
        texts = []
        if self.model_error:
            texts.append(self.model_error[:_REASON_CHARS])
        if bad:
            texts.append(f'{bad} of {n} reports not evaluated; last: '
                         f'{self.last_reason[:_REASON_CHARS]}')
        if self.config_errors:
            texts.append(f'{len(self.config_errors)} parameters rejected at startup, '
                         f'defaults used: {self.config_errors[0][:_REASON_CHARS]}')
        if warned:
            texts.append(f'{warned} of {n} reports with warnings; last: '
                         f'{self.last_warning[:_REASON_CHARS]}')
        if self.output_errors_period:
            texts.append(f'{self.output_errors_period} outputs not built; last: '
                         f'{self.last_output_error[:_REASON_CHARS]}')
        if c50 > period_ms:
            texts.append(f'falling behind: compute time p50 {c50:.2f} ms > joint_states '
                         f'period {period_ms:.2f} ms')
        if self.model_error or period[_ERROR] or self.output_errors_period:
            level = DiagnosticStatus.ERROR
        elif texts:
            level = DiagnosticStatus.WARN
        else:
            level, texts = DiagnosticStatus.OK, [f'{n} reports']
        return DiagnosticStatus(level=level, name=f'{self.node_name}: evaluation',
                                message='; '.join(texts), hardware_id=self.hardware_id,
                                values=values)
