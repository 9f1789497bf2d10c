"""
Soak test of ``awp_node``: drive it at a fixed rate for a while; count what it loses.

::

    python -m awp_ros.soak --rate 1000 --duration 60 [--robot hyq] [--warmup 10] [--steal 0.4]

Three processes on one ROS domain (``ROS_DOMAIN_ID``; discovery kept on this machine with
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` unless set otherwise):

1. ``awp_node`` (the console script) in namespace ``--namespace`` (default ``/soak``);
2. a driver (``python -m awp_ros.soak --drive ...``) that publishes ``joint_states`` at
   ``--rate`` on a schedule (sleeps to absolute targets, so jitter does not accumulate),
   each stamped with the wall clock when it is published, and ``contacts`` on every stance
   change and at ``--contacts-rate``, stamped like the joint state they precede. Postures
   and stance come from the gait generator (:mod:`awp_ros.gait.generator`: crawl then trot, the
   motion of the default bag), one sample per message, in a loop. It writes the stamps it
   sent to a file;
3. this process: subscribes to ``<ns>/awp_node/report`` and ``/diagnostics`` and samples
   the node's CPU time and RSS from ``/proc/<pid>/stat`` and ``/proc/<pid>/status`` every
   ``--sample-period`` seconds, and the CPU time of its worker processes. With
   ``--subscribe markers fwp ...`` it also subscribes to those outputs of the node
   (``~/<name>``, as serialized bytes, counted), like RViz or a planner would: the node only
   builds an output that has a subscriber.

Measured: joint states sent and their rate, reports received, **missing** (a stamp sent
without a report), **duplicates**, unexpected stamps, the report statuses, the latency
from the joint-state stamp to the report's reception here (p50 / p99 / max, over the
whole run and after the warm-up), the node's CPU [% of one core] and RSS [MB] over time,
the RSS growth from the end of the warm-up to the end of the drive (goal < 5 %), and the
machine's load average before the drive and at its end (``os.getloadavg``: on a shared
machine what else ran decides the figures). The latency is split where the node publishes
each report (the report's DDS source timestamp): from the stamp until the node published it
(the joint state's way to the node, its wait and evaluation), and from there until this
process's middleware received it (``node_publish_ms``, ``report_transport_ms``); with the
driver's pauses (consecutive joint states sent more than ``max(10 ms, 10 periods)`` apart:
its process did not run) and the slowest report's share of each (``worst_report``), a
latency outlier is placed in the node, in DDS or in the driver. After the drive it waits for
the backlog to drain (a node slower than the input rate answers late, from its reliable
queue of ``qos_depth`` joint states, but answers). It prints a table and, as its last line,
one JSON object.

With ``--steal 0.4`` the drive runs on an emulated slower machine (real-time threads take that
share of every CPU, :mod:`awp_ros.soak.slow_machine`, from the moment the node spins); the
slowdown (a reference workload timed before the node starts, then with the stealers) is printed
and goes to the JSON (``slow_machine``).

The helpers (:class:`Probe`, :func:`start_node`, :class:`ProcessMonitor`,
:func:`run_soak`) are used by the tests too.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import time

import numpy as np

from awp_ros.errors import InputError, ProcessError
from awp_ros.node.dds import use_deep_queues
from awp_ros.node.launcher import ros_env, start_node, stop_node
from awp_ros.ros.cdr import report_stamp_status
from awp_ros.soak.driver import drive, driver_command
from awp_ros.soak.monitor import ProcessMonitor
from awp_ros.soak.probe import Probe, wait_until
from awp_ros.soak.result import (fill_latency_split, fill_node_diagnostics, fill_timeline,
                                 fill_usage, percentiles, SoakResult)
from awp_ros.soak.slow_machine import SlowMachine

__all__ = ['main', 'report_stamp_status', 'run_soak']


def _output_types() -> dict:
    """Return the message type of each output a soak may subscribe to."""
    from awp_ros_msgs.msg import LegPolytopes, WrenchPolytope
    from visualization_msgs.msg import MarkerArray
    return {'awp': WrenchPolytope, 'fwp': WrenchPolytope, 'fws': WrenchPolytope,
            'leg_polytopes': LegPolytopes, 'markers': MarkerArray}


OUTPUT_TYPES = _output_types()


def run_soak(rate_hz: float, duration_s: float, *, robot: str = 'hyq',
             warmup_s: float | None = None, qos_depth: int | None = None,
             namespace: str = '/soak', env: dict[str, str] | None = None,
             contacts_rate_hz: float = 100.0, sample_period_s: float = 1.0,
             drain_timeout_s: float | None = None, stall_timeout_s: float = 20.0,
             params: dict | None = None, timeline_step_s: float | None = None,
             subscribe: tuple[str, ...] = (), steal: float = 0.0) -> SoakResult:
    """
    Run one soak (see the module docstring) and return what it measured.

    :param rate_hz: joint-state rate [Hz].
    :param duration_s: drive duration [s].
    :param robot: robot config name.
    :param warmup_s: start of the RSS-growth and warm latency window, after the drive
        starts [s] (default min(10, duration / 5)).
    :param qos_depth: the node's ``qos_depth`` (default: enough for the whole run,
        ``rate * (duration + 10)``, so that a node slower than ``rate`` loses nothing).
    :param env: environment of the processes (default :func:`ros_env`); its
        ``ROS_DOMAIN_ID`` is the domain of this process's participant too.
    :param drain_timeout_s: longest wait for the backlog after the drive (default
        ``2 * duration + 30``); the wait also ends after ``stall_timeout_s`` without a
        report.
    :param params: more node parameters.
    :param timeline_step_s: rows of the table (default duration / 12, at least the
        sample period).
    :param subscribe: outputs of the node to subscribe to as well (names of
        :data:`awp_ros.ros.cycle.OUTPUTS` other than ``report``); their counts go to
        ``result.outputs``.
    :param steal: > 0: the drive on an emulated slower machine, this share of every CPU
        taken by real-time stealers from the moment the node spins until it is stopped
        (:class:`awp_ros.soak.slow_machine.SlowMachine`; the slowdown, against the reference
        workload timed before the node starts and then with the stealers on the idle node,
        goes to ``result.slow_machine``).
    """
    from awp_ros_msgs.msg import FeasibilityReport
    from diagnostic_msgs.msg import DiagnosticArray

    env = ros_env() if env is None else env
    domain = int(env.get('ROS_DOMAIN_ID', '0') or 0)
    warmup_s = min(10.0, duration_s / 5) if warmup_s is None else warmup_s
    if qos_depth is None:
        qos_depth = int(rate_hz * (duration_s + 10)) + 1000
    drain_timeout_s = 2 * duration_s + 30 if drain_timeout_s is None else drain_timeout_s
    result = SoakResult(robot, rate_hz, duration_s, qos_depth)
    slow = SlowMachine(steal) if steal > 0.0 else None
    if slow is not None:
        slow.measure_fast()                # the reference without stealers, before the node
    ns = namespace.rstrip('/')
    node_params = {'qos_depth': qos_depth, **(params or {})}
    proc = start_node(env=env, robot=robot, namespace=ns, params=node_params)
    probe = Probe(domain, 'awp_soak_probe')
    n_max = int(rate_hz * duration_s) + 10
    stamps = np.zeros(n_max + 1000, dtype=np.int64)
    recv = np.zeros_like(stamps)
    published, dds_received = np.zeros_like(stamps), np.zeros_like(stamps)
    status = np.zeros(stamps.size, dtype=np.int8)
    count = [0]

    def on_report(data: bytes, info: dict) -> None:
        i = count[0]
        if i < stamps.size:
            recv[i] = time.time_ns()
            stamps[i], status[i] = report_stamp_status(data)
            published[i] = info.get('source_timestamp') or 0
            dds_received[i] = info.get('received_timestamp') or 0
        count[0] = i + 1

    probe.subscribe(FeasibilityReport, f'{ns}/awp_node/report', on_report,
                    depth=max(qos_depth, n_max + 1000), raw=True, drain=True, with_info=True)
    diag = probe.subscribe(DiagnosticArray, '/diagnostics', depth=100)
    received = {name: [0] for name in subscribe}
    for name in subscribe:
        def counter(_msg, n=received[name]) -> None:
            n[0] += 1
        probe.subscribe(OUTPUT_TYPES[name], f'{ns}/awp_node/{name}', counter, depth=100,
                        raw=True)
    monitor = None
    stamps_file = tempfile.NamedTemporaryFile(prefix='awp_soak_', suffix='.npy', delete=False)
    stamps_file.close()
    try:
        wait_until(lambda: probe.node.count_publishers(f'{ns}/awp_node/report') > 0, 60.0,
                   'awp_node to appear')
        # Drive once the node spins (its first /diagnostics comes from a timer of its running
        # executor), not when its publishers appear: it then still collects its start-up
        # garbage, and a 2 kHz drive into a short queue lost joint states it cannot count.
        wait_until(lambda: len(diag) > 0, 60.0, 'awp_node to spin (its first /diagnostics)')
        time.sleep(0.5)
        if slow is not None:
            slow.start()
            result.slow_machine = slow.summary()
        monitor = ProcessMonitor(proc.pid, sample_period_s)
        cmd = driver_command(rate_hz, duration_s, robot=robot, namespace=ns,
                             stamps_out=stamps_file.name, contacts_rate_hz=contacts_rate_hz,
                             depth=n_max + 1000)
        result.load_average['before the drive'] = list(os.getloadavg())
        driver = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, text=True)
        out, _ = driver.communicate(timeout=duration_s + 180)
        t_end = time.monotonic()
        result.load_average['at its end'] = list(os.getloadavg())
        lines = [ln for ln in out.splitlines() if ln.startswith('{')]
        if driver.returncode != 0 or not lines:
            raise ProcessError(f'the driver failed (exit {driver.returncode}): {out[-2000:]}')
        result.driver = json.loads(lines[-1])
        sent = np.load(stamps_file.name)
        result.sent = int(sent.size)
        result.sent_rate_hz = result.driver['sent_rate_hz']
        last, last_change = count[0], time.monotonic()
        while count[0] < result.sent and time.monotonic() - t_end < drain_timeout_s:
            time.sleep(0.1)
            if count[0] != last:
                last, last_change = count[0], time.monotonic()
            elif time.monotonic() - last_change > stall_timeout_s:
                break
        time.sleep(1.2)              # a duplicate, and the node's last diagnostics, arrive
        if probe.drain_errors:
            raise ProcessError(f'the report subscriber failed: {probe.drain_errors[0]!r}')
    finally:
        if slow is not None:
            slow.stop()
        if monitor is not None:
            monitor.stop()
        result.node_alive = proc.poll() is None
        probe.close()
        stop_node(proc)
        Path(stamps_file.name).unlink(missing_ok=True)
    if slow is not None and slow.calibration is not None:
        slow.confirm_fast()                # the reference again, the stealers and node gone
        result.slow_machine = slow.summary()
    n = min(count[0], stamps.size)
    got, rcv, st = stamps[:n], recv[:n], status[:n]
    result.reports = int(count[0])
    result.outputs = {name: n[0] for name, n in received.items()}
    uniq = np.unique(got)
    result.duplicates = int(n - uniq.size)
    result.missing = int(np.setdiff1d(sent, uniq).size)
    result.missing_before_first_report = int(np.count_nonzero(sent < got.min())) if n \
        else int(sent.size)
    result.unexpected = int(np.setdiff1d(uniq, sent).size)
    names = ('ok', 'warning', 'invalid_input', 'stale_input', 'error')
    result.status_counts = {names[k]: int(c) for k, c in enumerate(np.bincount(st, minlength=5))
                            if c}
    latency = (rcv - got) * 1e-6
    result.latency_ms = percentiles(latency)
    if not sent.size:
        return result
    result.drain_s = max(0.0, (int(rcv.max()) - int(sent[-1])) * 1e-9) if n else 0.0
    warm = got >= int(sent[0]) + int(warmup_s * 1e9)
    result.latency_after_warmup_ms = percentiles(latency[warm])
    fill_latency_split(result, got, published[:n], dds_received[:n], latency, sent)
    # The drive window on the monitor's clock (monotonic), from the first and last stamps.
    offset = time.time_ns() * 1e-9 - time.monotonic()
    t_start, t_stop = sent[0] * 1e-9 - offset, sent[-1] * 1e-9 - offset
    samples = monitor.array() if monitor else np.zeros((0, 3))
    fill_usage(result, samples, t_start, t_stop, warmup_s,
               monitor.child_samples if monitor else None)
    fill_timeline(result, samples, t_start, int(sent[0]), rcv, latency,
                  timeline_step_s or max(duration_s / 12, sample_period_s))
    fill_node_diagnostics(result, diag, probe.lock)
    return result

# -- command line --------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    """Run the soak (or, with ``--drive``, be its driver process)."""
    parser = argparse.ArgumentParser(
        prog='python -m awp_ros.soak', description=__doc__.split('\n\n')[0])
    parser.add_argument('--rate', type=float, default=1000.0, help='joint states [Hz]')
    parser.add_argument('--duration', type=float, default=60.0, help='drive time [s]')
    parser.add_argument('--robot', default='hyq', help='robot config name')
    parser.add_argument('--warmup', type=float, default=None,
                        help='warm-up before RSS growth is measured [s] (default '
                        'min(10, duration/5))')
    parser.add_argument('--qos-depth', type=int, default=None,
                        help="the node's qos_depth (default rate * (duration + 10) + 1000)")
    parser.add_argument('--namespace', default='/soak', help="the node's namespace")
    parser.add_argument('--contacts-rate', type=float, default=100.0,
                        help='contacts [Hz] (and on every stance change)')
    parser.add_argument('--sample-period', type=float, default=1.0,
                        help='CPU/RSS sampling period [s]')
    parser.add_argument('--param', action='append', default=[], metavar='NAME:=VALUE',
                        help='more node parameters, e.g. executor:=events')
    parser.add_argument('--subscribe', nargs='+', default=[], choices=sorted(OUTPUT_TYPES),
                        help='also subscribe to these outputs of the node (as RViz or a '
                        'planner would; the node builds an output only for subscribers)')
    parser.add_argument('--steal', type=float, default=0.0, metavar='SHARE',
                        help='run on an emulated slower machine: real-time stealers take this '
                        'share of every CPU (0.4: about 2x slower; measured and printed; '
                        'needs root or CAP_SYS_NICE; python -m awp_ros.soak.slow_machine)')
    parser.add_argument('--drive', action='store_true', help=argparse.SUPPRESS)
    parser.add_argument('--stamps-out', help=argparse.SUPPRESS)
    parser.add_argument('--depth', type=int, default=100000, help=argparse.SUPPRESS)
    parser.add_argument('--topics', default='both', help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    use_deep_queues()   # the probe reads reports through a queue as deep as the node's
    if args.drive:
        summary = drive(rate_hz=args.rate, duration_s=args.duration, robot=args.robot,
                        namespace='' if args.namespace == '/' else args.namespace,
                        stamps_path=args.stamps_out, contacts_rate_hz=args.contacts_rate,
                        depth=args.depth, topics=args.topics)
        print(json.dumps(summary), flush=True)
        return 0
    params = dict(p.split(':=', 1) for p in args.param)
    try:
        result = run_soak(args.rate, args.duration, robot=args.robot, warmup_s=args.warmup,
                          qos_depth=args.qos_depth, namespace=args.namespace,
                          contacts_rate_hz=args.contacts_rate,
                          sample_period_s=args.sample_period, params=params,
                          subscribe=tuple(args.subscribe), steal=args.steal)
    except (InputError, ProcessError) as exc:
        print(f'soak: {exc}', file=sys.stderr)
        return 2
    print(result.table())
    print(json.dumps(result.to_dict()))
    ok = result.node_alive and result.missing == 0 and result.duplicates == 0
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
