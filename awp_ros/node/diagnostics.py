"""
Counters of the node and the ``diagnostic_msgs/DiagnosticArray`` built from them.

``diagnostic_updater`` is not among the PyPI ROS wheels, so this follows its conventions by
hand: one array per period (1 Hz) on ``/diagnostics``, statuses named ``<node>: <topic>``,
``hardware_id`` = the robot name, levels OK / WARN / ERROR, values as key-value strings with
units in the keys. Two statuses:

- ``<node>: inputs``: per input topic the receive rate [Hz] over the last period, the age of
  the last message [s] (wall time), the messages received, lost (DDS ``message_lost``
  events) and missing from the publishers' sequence numbers (:meth:`~NodeDiagnostics.
  sequence`: silently replaced in a full keep-last queue), the matched publishers, and
  what keeps a topic's messages away, named with the topic: publishers of another message
  type (from the ROS graph), publishers whose QoS does not match the subscription's (the
  incompatible-QoS events, with the policy), no publisher at all. WARN when an input is
  stale (older than ``stale_timeout_s``), messages were lost or missing in the period, or a
  topic has such a problem; ERROR when no joint state arrived yet (the message says why,
  e.g. ``no joint_states received yet: /joint_states: 1 publisher with incompatible QoS
  (RELIABILITY ...)``). Joints of ``joint_states`` that the model does not have are listed
  once (``joint_states ignored joints``), not warned about per cycle.
- ``<node>: evaluation``: reports per status in the period and in total, the last error and
  the last warning (the reasons of the reports), the reports per number of stance legs in
  the period (e.g. ``2:480, 4:520``; fewer than 3 legs give flat wrench sets), compute time
  p50 / p99 [ms], latency from the joint-state stamp to the report's publication p50 / p99
  [ms] over the period, how long the joint states waited in the input queue (from their DDS
  reception to the node taking them, on the node's clock: independent of the stamps) p50 /
  p99 / max [ms], the FWS computed in the joint-state loop (``fws_lag_s`` = 0: how many
  in the period and the longest [ms]; one longer than :data:`FWS_LOOP_PERIODS` joint-state
  periods is named in the OK message, with ``fws_lag_s`` as the way to take it off the loop:
  the reports after it wait for it), the lagged FWS jobs computed in the node because the
  worker process was late (total), and outputs that could not be built. ERROR when there is
  no robot model (``model_error``), a report of the period has ``STATUS_ERROR`` or an output
  failed; WARN when parameters were rejected at startup (``config_errors``, defaults used
  instead), reports in the period were not evaluated (invalid, stale), carried a warning,
  or when the node is falling behind: the p50 compute time exceeds the joint-state period of
  the period's receive rate, or the joint states waited more than
  :data:`FALLING_BEHIND_PERIODS` periods (and :data:`FALLING_BEHIND_MS`) in the input queue at
  the median. The second catches a node whose evaluation alone fits the period but whose
  whole answer (taking the message, evaluating, publishing the report) does not: on a machine
  2x slower than usual, 1 kHz in, the compute time p50 was 0.63 ms and the reports up to
  0.39 s late (README, "Diagnostics"). The queue of ``qos_depth`` absorbs bursts (an FWS in
  the loop), which leave the median alone.

``<node>`` is the node's fully qualified name without the leading slash (``awp_node``,
``hyq/awp_node``), so nodes in different namespaces are told apart.

Everything here is O(1) per message (a few counters and one slot of a preallocated ring).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
import numpy as np
from std_msgs.msg import Header

from awp_ros.ros.conversions import STATUS_NAMES

__all__ = ['FALLING_BEHIND_MS', 'FALLING_BEHIND_PERIODS', 'NodeDiagnostics']

#: FeasibilityReport.STATUS_* value -> name used in the diagnostics keys.
_WARNING, _ERROR = 1, 4
_MAX_LEGS = 16            # stance sizes counted per period (larger ones in the last bin)
_REASON_CHARS = 200       # characters of a reason quoted in a status message
#: An FWS in the joint-state loop longer than this many joint_states periods is named in the
#: evaluation status's message: the reports after it queue behind it (the latency tail).
FWS_LOOP_PERIODS = 2.0
#: Falling behind: the period's median input-queue delay above this many joint-state periods
#: and above :data:`FALLING_BEHIND_MS` (a node that keeps up takes a joint state within about
#: one period of its arrival; bursts raise the tail, not the median).
FALLING_BEHIND_PERIODS = 10.0
#: ... and above this [ms] (at low rates, ten periods are already long).
FALLING_BEHIND_MS = 10.0


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
    """Counters of one input topic, and what the graph and QoS events say about it."""

    def __init__(self, name: str = '', msg_type: str = '') -> None:
        self.name = name                     # the resolved topic name (remapped)
        self.msg_type = msg_type             # the type the node subscribes with
        self.publishers = 0                  # matched publishers (matched events)
        self.graph_publishers: int | None = None   # publishers in the graph, any type
        self.wrong_types: dict[str, int] = {}      # other type -> publishers of it
        self.incompatible_qos = 0            # publishers offering incompatible QoS (total)
        self.qos_policy = ''                 # the last incompatible policy
        self.incompatible_type = 0           # incompatible-type events (total)
        self.streams: list[int] = []         # last sequence number of each publisher
        self.stream_used: list[int] = []     # when each sequence was last continued (tick)
        self.ticks = 0
        self.total = 0
        self.period = 0
        self.last_wall: float | None = None
        self.lost = 0
        self.lost_period = 0
        self.gaps = 0
        self.gaps_period = 0


class NodeDiagnostics:
    """
    Counters of inputs and evaluations, and the DiagnosticArray built from them.

    :param node_name: prefix of the status names.
    :param hardware_id: the robot name.
    :param topics: the input topics to watch (e.g. ``('joint_states', 'contacts')``).
    :param stale_timeout_s: an input older than this (wall time) is stale [s]; 0 disables.
    :param ring_size: samples kept per period for the percentiles.
    :param names: topic -> resolved (remapped) name, used in the messages (default the
        topic).
    :param types: topic -> message type the node subscribes with (``pkg/msg/Name``).
    :ivar extra_joints: joints of ``joint_states`` the model does not have (the node sets
        it to the pipeline's set).
    """

    def __init__(self, node_name: str, hardware_id: str, topics: Sequence[str], *,
                 stale_timeout_s: float = 0.5, ring_size: int = 8192,
                 names: Mapping[str, str] | None = None,
                 types: Mapping[str, str] | None = None) -> None:
        self.node_name = node_name
        self.hardware_id = hardware_id
        self.stale_timeout_s = stale_timeout_s
        self.inputs = {t: _Input((names or {}).get(t, t), (types or {}).get(t, ''))
                       for t in topics}
        self.extra_joints: set[str] = set()
        #: topic -> its own staleness timeout [s] (contacts: contacts_timeout_s; 0 = never).
        self.topic_timeouts: dict[str, float] = {}
        self.reports_total = np.zeros(len(STATUS_NAMES), dtype=np.int64)
        self.reports_period = np.zeros(len(STATUS_NAMES), dtype=np.int64)
        self.compute_ms = _Ring(ring_size)
        self.latency_ms = _Ring(ring_size)
        #: How long each joint state waited in the input queue (DDS reception to take) [ms].
        self.queue_ms = _Ring(ring_size)
        #: How long each joint state took from its publisher's write to the node's DDS
        #: receiving it (its DDS source and received timestamps; with a publisher on another
        #: machine, their clocks' offset included) [ms].
        self.transport_ms = _Ring(ring_size)
        #: Wall time of each FWS computed in the joint-state loop (``fws_lag_s`` = 0) [ms].
        self.fws_loop_ms = _Ring(256)
        self.stance_period = np.zeros(_MAX_LEGS + 1, dtype=np.int64)
        self.period_start: float | None = None
        self.last_reason = ''
        self.last_warning = ''
        self.model_error = ''
        self.config_errors: list[str] = []
        self.output_errors = 0
        self.output_errors_period = 0
        self.markers_skipped = 0
        #: Lagged FWS jobs the worker process answered too late, computed in the node (total).
        self.fws_worker_late = 0
        #: Whether the last evaluation status built said the node is falling behind.
        self.falling_behind = False
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

        Several publishers on one topic (legs and arm) each number their own messages, and
        the message info does not say which publisher sent one, so one sequence is kept per
        publisher: a number that follows one of them continues it; while fewer sequences
        than matched publishers (:meth:`matched`) are known, any other number starts a new
        one (no gap counted); a number not above any of them starts a new one too (a new
        publisher, whose matched event may not have been handled yet, or a restarted one;
        the sequence used least recently goes when there are more than one beyond the
        matched publishers); else it continues the sequence with the largest number below
        it: the smallest possible gap, so that interleaved publishers never show a false
        one. With one publisher this is the plain count, and a smaller number than the last
        one starts over.

        :param seq: ``publication_sequence_number`` of the message info (None: unknown; the
            next known number then starts over, as a gap across it cannot be told from
            the unknown message).
        """
        c = self.inputs[topic]
        streams, used = c.streams, c.stream_used       # last number, last use (a tick)
        c.ticks += 1
        if seq is None:
            streams.clear()
            used.clear()
            return 0
        for i, last in enumerate(streams):
            if seq == last + 1:
                streams[i] = seq
                used[i] = c.ticks
                return 0
        n = max(c.publishers, 1)
        below = [i for i, last in enumerate(streams) if last < seq]
        if len(streams) < n or not below:
            streams.append(seq)
            used.append(c.ticks)
            while len(streams) > n + 1:             # publishers gone: the least recent go
                i = used.index(min(used))
                del streams[i], used[i]
            return 0
        i = max(below, key=streams.__getitem__)
        missing = seq - streams[i] - 1
        streams[i] = seq
        used[i] = c.ticks
        c.gaps += missing
        c.gaps_period += missing
        return missing

    def matched(self, topic: str, publishers: int) -> None:
        """Record the number of publishers matched with ``topic``'s subscription."""
        self.inputs[topic].publishers = max(int(publishers), 0)

    def incompatible_qos(self, topic: str, total: int, policy: str) -> None:
        """Record a publisher whose QoS does not match (``total`` so far, ``policy``)."""
        c = self.inputs[topic]
        c.incompatible_qos = int(total)
        c.qos_policy = policy

    def incompatible_type(self, topic: str, total: int) -> None:
        """Record a publisher of another message type (the middleware's event)."""
        self.inputs[topic].incompatible_type = int(total)

    def graph(self, topic: str, types: Sequence[str]) -> None:
        """Record the message types of every publisher of ``topic`` in the ROS graph."""
        c = self.inputs[topic]
        c.graph_publishers = len(types)
        wrong: dict[str, int] = {}
        for t in types:
            if c.msg_type and t != c.msg_type:
                wrong[t] = wrong.get(t, 0) + 1
        c.wrong_types = wrong

    def lost(self, topic: str, count: int) -> None:
        """Count ``count`` messages reported lost by the middleware on ``topic``."""
        c = self.inputs[topic]
        c.lost += count
        c.lost_period += count

    def evaluated(self, status: int, compute_time_s: float, latency_s: float | None,
                  reason: str = '', stance_legs: int | None = None,
                  queue_delay_s: float | None = None,
                  transport_delay_s: float | None = None) -> None:
        """
        Count one report of ``status`` (STATUS_* value), its compute time and latency.

        :param reason: the report's status message (kept as the last error or warning).
        :param stance_legs: number of stance legs of an evaluated report (None: not
            evaluated).
        :param queue_delay_s: how long the joint state waited in the input queue [s] (None:
            unknown, not counted).
        :param transport_delay_s: how long the joint state took from its publisher's write to
            the node's DDS receiving it [s] (None: unknown, not counted).
        """
        if queue_delay_s is not None:
            self.queue_ms.add(1e3 * queue_delay_s)
        if transport_delay_s is not None:
            self.transport_ms.add(1e3 * transport_delay_s)
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

    def fws_in_loop(self, ms: float) -> None:
        """Count one FWS computed in the joint-state loop, ``ms`` [ms] of wall time."""
        self.fws_loop_ms.add(ms)

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
        self.queue_ms.clear()
        self.transport_ms.clear()
        self.fws_loop_ms.clear()
        return msg

    def _inputs_status(self, wall: float, dt: float | None) -> DiagnosticStatus:
        values, stale, lost, gaps, problems = [], [], [], [], {}
        for topic, c in self.inputs.items():
            rate = float('nan') if dt is None else c.period / dt
            age = float('inf') if c.last_wall is None else wall - c.last_wall
            values += [KeyValue(key=f'{topic} rate [Hz]', value=f'{rate:.1f}'),
                       KeyValue(key=f'{topic} age [s]', value=f'{age:.3f}'),
                       KeyValue(key=f'{topic} received (total)', value=str(c.total)),
                       KeyValue(key=f'{topic} lost (total)', value=str(c.lost)),
                       KeyValue(key=f'{topic} sequence gaps (total)', value=str(c.gaps)),
                       KeyValue(key=f'{topic} topic', value=c.name),
                       KeyValue(key=f'{topic} publishers (matched)', value=str(c.publishers))]
            problem = self._topic_problem(c)
            values.append(KeyValue(key=f'{topic} problem', value=problem))
            if problem:
                problems[topic] = problem
            timeout = self.topic_timeouts.get(topic, self.stale_timeout_s)
            if timeout > 0.0 and age > timeout:
                stale.append(topic)
            if c.lost_period:
                lost.append(f'{topic} ({c.lost_period})')
            if c.gaps_period:
                gaps.append(f'{topic} ({c.gaps_period})')
        if 'joint_states' in self.inputs:
            extra = sorted(self.extra_joints)
            values.append(KeyValue(key='joint_states ignored joints (not in the model)',
                                   value=', '.join(extra)))
        first_topic = next(iter(self.inputs), None)
        first = self.inputs.get(first_topic)
        found = list(problems.values())
        if first is not None and first.total == 0:
            level = DiagnosticStatus.ERROR
            why = problems.pop(first_topic, '')
            text = '; '.join([f'no {first_topic} received yet' + (f': {why}' if why else '')]
                             + list(problems.values()))
        elif stale or lost or gaps or found:
            level = DiagnosticStatus.WARN
            text = '; '.join(found + ([f'stale: {", ".join(stale)}'] if stale else [])
                             + ([f'lost: {", ".join(lost)}'] if lost else [])
                             + ([f'missing from sequence: {", ".join(gaps)}'] if gaps
                                else []))
        else:
            level, text = DiagnosticStatus.OK, 'inputs fresh'
        return DiagnosticStatus(level=level, name=f'{self.node_name}: inputs', message=text,
                                hardware_id=self.hardware_id, values=values)

    @staticmethod
    def _topic_problem(c: _Input) -> str:
        """Return what keeps an input topic's messages away, naming the topic, or ''."""
        texts = []
        if c.wrong_types:
            kinds = ', '.join(f'{n} of type {t}' for t, n in sorted(c.wrong_types.items()))
            texts.append(f'{c.name} has publishers of another type ({kinds}); this node '
                         f'subscribes with {c.msg_type or "another type"}')
        elif c.incompatible_type:
            texts.append(f'{c.name} has a publisher of another type (incompatible-type '
                         f'events: {c.incompatible_type}); this node subscribes with '
                         f'{c.msg_type or "another type"}')
        if c.incompatible_qos:
            hint = {'RELIABILITY': ': a best-effort publisher and a reliable subscription '
                                   '(set qos_reliability:=best_effort)',
                    'DURABILITY': ': a volatile publisher and a transient-local '
                                  'subscription (contacts_durability)'}.get(c.qos_policy, '')
            texts.append(f'{c.name} has {c.incompatible_qos} publisher'
                         f'{"s" if c.incompatible_qos != 1 else ""} with incompatible QoS '
                         f'({c.qos_policy or "unknown policy"}{hint}); their messages are '
                         'not received')
        if c.total == 0 and not texts:
            if c.graph_publishers == 0 and c.publishers == 0:
                texts.append(f'{c.name} has no publisher')
            elif c.publishers:
                texts.append(f'{c.name} has {c.publishers} matched publisher'
                             f'{"s" if c.publishers != 1 else ""} but no message arrived')
        return '; '.join(texts)

    def _evaluation_status(self, input_rate: float) -> DiagnosticStatus:
        c50, c99 = self.compute_ms.percentiles([50, 99])
        l50, l99 = self.latency_ms.percentiles([50, 99])
        q50, q99, qmax = self.queue_ms.percentiles([50, 99, 100])
        t50, t99, tmax = self.transport_ms.percentiles([50, 99, 100])
        values = [KeyValue(key=f'reports {name} (period)', value=str(int(n)))
                  for name, n in zip(STATUS_NAMES.values(), self.reports_period)]
        values += [KeyValue(key=f'reports {name} (total)', value=str(int(n)))
                   for name, n in zip(STATUS_NAMES.values(), self.reports_total)]
        legs = ', '.join(f'{k}:{int(n)}' for k, n in enumerate(self.stance_period) if n)
        fws_n, (fws_max,) = self.fws_loop_ms.n, self.fws_loop_ms.percentiles([100])
        values += [KeyValue(key='FWS in the loop (period)', value=str(fws_n)),
                   KeyValue(key='FWS in the loop max [ms]', value=f'{fws_max:.3f}'),
                   KeyValue(key='compute time p50 [ms]', value=f'{c50:.3f}'),
                   KeyValue(key='compute time p99 [ms]', value=f'{c99:.3f}'),
                   KeyValue(key='latency stamp to publish p50 [ms]', value=f'{l50:.3f}'),
                   KeyValue(key='latency stamp to publish p99 [ms]', value=f'{l99:.3f}'),
                   KeyValue(key='input queue delay p50 [ms]', value=f'{q50:.3f}'),
                   KeyValue(key='input queue delay p99 [ms]', value=f'{q99:.3f}'),
                   KeyValue(key='input queue delay max [ms]', value=f'{qmax:.3f}'),
                   KeyValue(key='input transport delay p50 [ms]', value=f'{t50:.3f}'),
                   KeyValue(key='input transport delay p99 [ms]', value=f'{t99:.3f}'),
                   KeyValue(key='input transport delay max [ms]', value=f'{tmax:.3f}'),
                   KeyValue(key='reports by stance legs (period)', value=legs),
                   KeyValue(key='last error', value=self.last_reason),
                   KeyValue(key='last warning', value=self.last_warning),
                   KeyValue(key='robot model error', value=self.model_error),
                   KeyValue(key='rejected parameters', value='; '.join(self.config_errors)),
                   KeyValue(key='output errors (total)', value=str(self.output_errors)),
                   KeyValue(key='markers skipped, worker busy (total)',
                            value=str(self.markers_skipped)),
                   KeyValue(key='FWS computed in the node, worker late (total)',
                            value=str(self.fws_worker_late)),
                   KeyValue(key='last output error', value=self.last_output_error)]
        period = self.reports_period
        bad = int(period[2:].sum())
        warned = int(period[_WARNING])
        n = int(period.sum())
        period_ms = 1e3 / input_rate if input_rate > 0.0 else float('inf')
        cut = _REASON_CHARS
        slow = c50 > period_ms                  # each evaluation longer than the period
        queued_long = q50 > max(FALLING_BEHIND_PERIODS * period_ms, FALLING_BEHIND_MS)
        self.falling_behind = bool(slow or queued_long)
        candidates = [   # (condition, message), in order
            (self.model_error, self.model_error[:cut]),
            (bad, f'{bad} of {n} reports not evaluated; last: {self.last_reason[:cut]}'),
            (self.config_errors, f'{len(self.config_errors)} parameters rejected at startup, '
                                 f'defaults used: {(self.config_errors or [""])[0][:cut]}'),
            (warned, f'{warned} of {n} reports with warnings; last: {self.last_warning[:cut]}'),
            (self.output_errors_period, f'{self.output_errors_period} outputs not built; '
                                        f'last: {self.last_output_error[:cut]}'),
            (slow, f'falling behind: compute time p50 {c50:.2f} ms > joint_states '
                   f'period {period_ms:.2f} ms'),
            (queued_long, f'falling behind: joint states waited {q50:.1f} ms (p50), up to '
                          f'{qmax:.0f} ms, in the input queue: the node answers fewer than '
                          'arrive (max_queue_delay_s bounds the wait by load shedding; '
                          'fws_lag_s takes the FWS off the loop)'),
        ]
        texts = [text for condition, text in candidates if condition]
        if self.model_error or period[_ERROR] or self.output_errors_period:
            level = DiagnosticStatus.ERROR
        elif texts:
            level = DiagnosticStatus.WARN
        else:
            level, texts = DiagnosticStatus.OK, [f'{n} reports']
            if fws_n and fws_max > FWS_LOOP_PERIODS * period_ms:
                # Not a fault (the stream keeps up): where the latency tail comes from.
                texts.append(f'the FWS in the loop took up to {fws_max:.1f} ms, '
                             f'{fws_max / period_ms:.0f} joint_states periods: the joint states '
                             'after it wait for it (fws_lag_s > 0 computes it beside the loop)')
        return DiagnosticStatus(level=level, name=f'{self.node_name}: evaluation',
                                message='; '.join(texts), hardware_id=self.hardware_id,
                                values=values)
