"""
What a soak test measured: :class:`SoakResult`, its table, and the figures behind it.

The ``fill_*`` functions turn the raw measurements of :func:`awp_ros.soak.soak.run_soak` (the
monitor's CPU/RSS samples, report reception times, the node's diagnostics) into the
result's fields.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from math import nan
import threading

import numpy as np

__all__ = ['fill_latency_split', 'fill_node_diagnostics', 'fill_timeline', 'fill_usage',
           'percentiles', 'SoakResult']


@dataclass
class SoakResult:
    """What a soak measured (see :mod:`awp_ros.soak.soak`). Times [s] unless the key says ms."""

    robot: str
    rate_hz: float
    duration_s: float
    qos_depth: int
    sent: int = 0
    sent_rate_hz: float = float('nan')
    reports: int = 0
    missing: int = 0
    #: Of ``missing``, the stamps sent before the first one answered: lost before the node's
    #: first take, so without an earlier sequence number the node could count them from.
    missing_before_first_report: int = 0
    duplicates: int = 0
    unexpected: int = 0
    status_counts: dict = field(default_factory=dict)
    latency_ms: dict = field(default_factory=dict)
    latency_after_warmup_ms: dict = field(default_factory=dict)
    cpu_percent: dict = field(default_factory=dict)
    workers_cpu_percent: dict = field(default_factory=dict)
    rss_mb: dict = field(default_factory=dict)
    rss_growth_percent: float = float('nan')
    drain_s: float = 0.0
    node_lost_total: int | None = None
    node_missing_from_sequence: int | None = None
    node_compute_p50_ms: float | None = None
    #: The node's FWS computed in the joint-state loop, from its /diagnostics periods:
    #: ``count``, ``max`` [ms] and ``period_max_p50`` (median of each period's longest) [ms].
    node_fws_in_loop: dict = field(default_factory=dict)
    #: The node's own view of its input queue, from its /diagnostics periods that counted
    #: joint states: ``periods``, ``falling_behind`` (periods whose evaluation status said
    #: so), ``queue_delay_max_ms`` (the longest wait of a joint state in its input queue),
    #: ``transport_delay_max_ms`` (the longest from the driver's write of a joint state to
    #: the node's DDS receiving it), ``last_falling_behind_message`` (that status's message,
    #: '' if none).
    node_queue: dict = field(default_factory=dict)
    driver: dict = field(default_factory=dict)
    timeline: list = field(default_factory=list)
    node_alive: bool = True
    outputs: dict = field(default_factory=dict)
    load_average: dict = field(default_factory=dict)
    #: The latency split at the node's publication of each report (its DDS source
    #: timestamp): ``node_publish_ms`` from the joint-state stamp to it (the joint state's
    #: way to the node, its wait and its evaluation), ``report_transport_ms`` from it to the
    #: subscriber's middleware receiving the report (p50 / p99 / max each).
    node_publish_ms: dict = field(default_factory=dict)
    report_transport_ms: dict = field(default_factory=dict)
    #: The driver's pauses: consecutive joint states sent more than ``threshold_ms`` apart
    #: (its process did not run; the joint states then come in a burst): ``count``,
    #: ``max_ms``, ``threshold_ms``.
    driver_gaps: dict = field(default_factory=dict)
    #: The report of the largest latency: ``at_s`` (its stamp, from the drive's start),
    #: ``latency_ms``, ``node_publish_ms``, ``transport_ms`` and ``driver_gap_ms`` (the
    #: longest driver pause from 1 s before its stamp until its report arrived).
    worst_report: dict = field(default_factory=dict)
    #: With ``--steal``: the emulated slower machine (:mod:`awp_ros.soak.slow_machine`),
    #: ``steal``, ``period_s`` and the measured ``slowdown`` with its reference times [ms].
    slow_machine: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """Return the result as JSON-ready builtins (without the timeline)."""
        out = asdict(self)
        out.pop('timeline')
        return out

    def table(self) -> str:
        """Return the timeline and the summary as a text table."""
        lines = [f'awp_node soak: {self.robot}, {self.rate_hz:g} Hz for {self.duration_s:g} s '
                 f'(qos_depth {self.qos_depth})']
        slow = self.slow_machine
        if slow:
            lines.append(f'on an emulated slower machine: {slow["steal"]:g} of every CPU taken '
                         f'by real-time stealers, measured {slow["slowdown"]:.2f}x slower '
                         f'(reference workload {slow["fast_ms"]:.1f} -> {slow["slow_ms"]:.1f} ms)')
        lines.append(f'{"t [s]":>7} {"reports/s":>10} {"latency p50 [ms]":>17} '
                     f'{"latency p99 [ms]":>17} {"node CPU [%]":>13} {"node RSS [MB]":>14}')
        for row in self.timeline:
            lines.append(f'{row["t"]:7.1f} {row["reports_per_s"]:10.0f} '
                         f'{row["latency_p50_ms"]:17.1f} {row["latency_p99_ms"]:17.1f} '
                         f'{row["cpu_percent"]:13.0f} {row["rss_mb"]:14.1f}')
        lat, cpu, rss = self.latency_ms, self.cpu_percent, self.rss_mb
        warm = self.latency_after_warmup_ms
        lines += [
            f'sent {self.sent} joint states at {self.sent_rate_hz:.1f} Hz; reports '
            f'{self.reports}; missing {self.missing} ({self.missing_before_first_report} before '
            f'the first report); duplicates {self.duplicates}; '
            f'unexpected {self.unexpected}; statuses {self.status_counts}',
            f'latency stamp -> report received [ms]: p50 {lat.get("p50", float("nan")):.1f}, '
            f'p99 {lat.get("p99", float("nan")):.1f}, max {lat.get("max", float("nan")):.1f}'
            f'; after warm-up p50 {warm.get("p50", float("nan")):.1f}, p99 '
            f'{warm.get("p99", float("nan")):.1f}',
            f'node CPU [% of one core] while driven: mean {cpu.get("mean", float("nan")):.0f}, '
            f'max {cpu.get("max", float("nan")):.0f}; RSS [MB]: start '
            f'{rss.get("start", float("nan")):.1f}, after warm-up '
            f'{rss.get("warm", float("nan")):.1f}, end of drive '
            f'{rss.get("end", float("nan")):.1f}, max {rss.get("max", float("nan")):.1f}; '
            f'growth after warm-up {self.rss_growth_percent:.2f} %',
            "the node's worker processes, CPU [% of one core] while driven (mean): " + (
                ', '.join(f'{name} {cpu:.0f}' for name, cpu in self.workers_cpu_percent.items())
                or 'none'),
            f'last report {self.drain_s:.2f} s after the last joint state; the node counted '
            f'{self.node_missing_from_sequence} joint states missing from the sequence and '
            f'{self.node_lost_total} lost (DDS events); its compute time p50 '
            f'{self.node_compute_p50_ms} ms',
        ]
        node, net, gaps, worst = (self.node_publish_ms, self.report_transport_ms,
                                  self.driver_gaps, self.worst_report)
        if node:
            lines.append(
                f'latency split [ms]: stamp -> the node publishes p50 {node["p50"]:.1f}, p99 '
                f'{node["p99"]:.1f}, max {node["max"]:.1f}; publication -> received by the '
                f'subscriber\'s DDS p50 {net["p50"]:.2f}, p99 {net["p99"]:.2f}, max '
                f'{net["max"]:.1f}; driver pauses over {gaps["threshold_ms"]:g} ms: '
                f'{gaps["count"]} (longest {gaps["max_ms"]:.1f})')
        if worst:
            lines.append(
                f'the slowest report: stamp {worst["at_s"]:.3f} s into the drive, '
                f'{worst["latency_ms"]:.1f} ms = {worst["node_publish_ms"]:.1f} until the node '
                f'published it + {worst["transport_ms"]:.1f} in DDS + the rest here; the '
                f'longest driver pause around it {worst["driver_gap_ms"]:.1f} ms')
        fws = self.node_fws_in_loop
        if fws.get('count'):
            lines.append("the node's FWS in the loop (its /diagnostics): "
                         f"{fws['count']} computed, longest {fws['max']:.1f} ms, each period's "
                         'longest p50 '
                         f"{fws['period_max_p50']:.1f} ms")
        queue = self.node_queue
        if queue.get('periods'):
            lines.append("the node's input queue (its /diagnostics): 'falling behind' in "
                         f"{queue['falling_behind']} of {queue['periods']} periods, the "
                         f"longest wait {queue['queue_delay_max_ms']:.1f} ms; joint states "
                         'reached its DDS up to '
                         f"{queue.get('transport_delay_max_ms', nan):.1f} ms after the driver "
                         'wrote them')
        if self.load_average:
            lines.append('machine load average (1, 5, 15 min): ' + '; '.join(
                f'{when} {" ".join(f"{x:.2f}" for x in values)}'
                for when, values in self.load_average.items()))
        if self.outputs:
            lines.append('other outputs received (subscribed with --subscribe): ' + ', '.join(
                f'{name} {count}' for name, count in self.outputs.items()))
        return '\n'.join(lines)


def percentiles(x: np.ndarray) -> dict:
    if x.size == 0:
        return {}
    p50, p99 = np.percentile(x, [50, 99])
    return {'p50': float(p50), 'p99': float(p99), 'max': float(x.max())}


def fill_usage(result: SoakResult, s: np.ndarray, t_start: float, t_end: float,
               warmup_s: float, child_samples: dict | None = None) -> None:
    """Fill CPU and RSS figures from the monitor's samples (drive window only)."""
    for name, rows in (child_samples or {}).items():
        c = np.array(rows, dtype=float).reshape(-1, 2)
        c = c[(c[:, 0] >= t_start) & (c[:, 0] <= t_end)]
        if len(c) >= 2:
            result.workers_cpu_percent[name] = float((c[-1, 1] - c[0, 1])
                                                     / (c[-1, 0] - c[0, 0]) * 100.0)
    if len(s) < 2:
        return
    drive = s[(s[:, 0] >= t_start) & (s[:, 0] <= t_end)]
    if len(drive) >= 2:
        cpu = np.diff(drive[:, 1]) / np.diff(drive[:, 0]) * 100.0
        result.cpu_percent = {'mean': float((drive[-1, 1] - drive[0, 1])
                                            / (drive[-1, 0] - drive[0, 0]) * 100.0),
                              'max': float(cpu.max())}
    mb = s[:, 2] / 2**20
    i_warm = int(np.searchsorted(s[:, 0], t_start + warmup_s))
    i_end = int(np.searchsorted(s[:, 0], t_end, side='right')) - 1
    i_warm = min(i_warm, len(s) - 1)
    i_end = max(i_end, i_warm)
    result.rss_mb = {'start': float(mb[0]), 'warm': float(mb[i_warm]),
                     'end': float(mb[i_end]), 'max': float(mb.max())}
    result.rss_growth_percent = float((mb[i_end] / mb[i_warm] - 1.0) * 100.0)


def fill_timeline(result: SoakResult, s: np.ndarray, t_start: float, wall0_ns: int,
                  rcv: np.ndarray, latency: np.ndarray, step: float) -> None:
    """
    Fill the table rows, one per ``step`` [s] from the drive's start to the last report.

    ``t_start`` is the start on the monitor's clock, ``wall0_ns`` on the wall clock.
    """
    if len(s) < 2:
        return
    t_rcv = (rcv - wall0_ns) * 1e-9
    t_last = float(t_rcv.max()) if t_rcv.size else s[-1, 0] - t_start
    edges = np.arange(0.0, t_last + step, step)
    t_s = s[:, 0] - t_start
    for a, b in zip(edges[:-1], edges[1:]):
        sel = (t_rcv >= a) & (t_rcv < b)
        lat = latency[sel]
        inside = t_s[0] <= a and b <= t_s[-1]
        cpu = float((np.interp(b, t_s, s[:, 1]) - np.interp(a, t_s, s[:, 1])) / step * 100.0) \
            if inside else float('nan')
        rss = float(np.interp(b, t_s, s[:, 2]) / 2**20) if inside else float('nan')
        result.timeline.append({
            't': float(b), 'reports_per_s': float(sel.sum() / step),
            'latency_p50_ms': float(np.percentile(lat, 50)) if lat.size else float('nan'),
            'latency_p99_ms': float(np.percentile(lat, 99)) if lat.size else float('nan'),
            'cpu_percent': cpu, 'rss_mb': rss})


def fill_latency_split(result: SoakResult, stamps: np.ndarray, published: np.ndarray,
                       received: np.ndarray, latency_ms: np.ndarray, sent: np.ndarray
                       ) -> None:
    """
    Split each report's latency at the node's publication; find the driver's pauses.

    All times are on the machine's system clock [ns]: ``stamps`` the joint-state stamps of
    the reports (the driver's clock when it sent them), ``published`` the reports' DDS source
    timestamps (when the node wrote them), ``received`` their DDS received timestamps here
    (0: unknown, left out), ``latency_ms`` stamp -> the report's callback here; ``sent``
    the stamps the driver sent, in order. A pause is a gap between consecutive sent stamps
    above ``max(10 ms, 10 periods)``.
    """
    known = (published > 0) & (received > 0)
    node = (published[known] - stamps[known]) * 1e-6
    result.node_publish_ms = percentiles(node)
    result.report_transport_ms = percentiles((received[known] - published[known]) * 1e-6)
    gap_ms = np.diff(sent) * 1e-6
    threshold = max(10.0, 10e3 / result.rate_hz)
    pauses = gap_ms[gap_ms > threshold]
    result.driver_gaps = {'count': int(pauses.size),
                          'max_ms': float(pauses.max()) if pauses.size else 0.0,
                          'threshold_ms': threshold}
    if not latency_ms.size or not sent.size:
        return
    k = int(np.argmax(latency_ms))
    lo, hi = stamps[k] - 1_000_000_000, stamps[k] + latency_ms[k] * 1e6
    near = (sent[1:] >= lo) & (sent[:-1] <= hi)         # pauses overlapping [lo, hi]
    result.worst_report = {
        'at_s': float((stamps[k] - sent[0]) * 1e-9), 'latency_ms': float(latency_ms[k]),
        'node_publish_ms': float((published[k] - stamps[k]) * 1e-6) if known[k] else nan,
        'transport_ms': float((received[k] - published[k]) * 1e-6) if known[k] else nan,
        'driver_gap_ms': float(gap_ms[near].max()) if near.any() else 0.0}


def fill_node_diagnostics(result: SoakResult, diag: list, lock: threading.Lock) -> None:
    """Take the node's loss counts, compute time, in-loop FWS and queue from its diagnostics."""
    with lock:
        arrays = list(diag)
    lost, gaps, p50, fws_count, fws_max = None, None, [], 0, []
    periods, behind, queue_max, transport_max, message = 0, 0, [], [], ''
    for arr in arrays:
        for st in arr.status:
            values = {kv.key: kv.value for kv in st.values}
            if st.name.endswith(': inputs'):
                lost = sum(int(v) for k, v in values.items() if k.endswith('lost (total)'))
                gaps = int(values.get('joint_states sequence gaps (total)', 0))
            elif st.name.endswith(': evaluation'):
                x = float(values.get('compute time p50 [ms]', 'nan'))
                if np.isfinite(x):
                    p50.append(x)
                q = float(values.get('input queue delay max [ms]', 'nan'))
                if np.isfinite(q):
                    periods += 1
                    queue_max.append(q)
                    if 'falling behind' in st.message:
                        behind += 1
                        message = st.message
                t = float(values.get('input transport delay max [ms]', 'nan'))
                if np.isfinite(t):
                    transport_max.append(t)
                n = int(values.get('FWS in the loop (period)', 0))
                if n:
                    fws_count += n
                    fws_max.append(float(values['FWS in the loop max [ms]']))
    if fws_count:
        result.node_fws_in_loop = {'count': fws_count, 'max': round(max(fws_max), 3),
                                   'period_max_p50': round(float(np.median(fws_max)), 3)}
    if periods:
        result.node_queue = {'periods': periods, 'falling_behind': behind,
                             'queue_delay_max_ms': round(max(queue_max), 3),
                             'transport_delay_max_ms': round(max(transport_max), 3)
                             if transport_max else nan,
                             'last_falling_behind_message': message}
    result.node_lost_total = lost
    result.node_missing_from_sequence = gaps
    result.node_compute_p50_ms = round(float(np.median(p50)), 3) if p50 else None
