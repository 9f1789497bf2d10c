"""
Measure how ``~/evaluate`` queries delay ``awp_node``'s live reports.

::

    python -m awp_ros.soak.query_load --rate 500 --duration 30 --states 100 --period 4

Starts ``awp_node`` (namespace ``--namespace``, default ``/query_load``) and the soak's
driver (:mod:`awp_ros.soak.driver`: gait joint states at ``--rate``, each stamped with the
wall clock when published, and contacts), subscribes to the node's reports, and from
``--quiet`` seconds after the drive starts calls ``~/evaluate`` every ``--period`` seconds
with ``--states`` random postures around standing (joint offsets uniform in +-0.1 rad, a
random stance of 2 to 4 feet each, one ContactState per joint state), one call at a time.

The latency of a report is its reception time here minus its joint state's stamp [ms]
(transport both ways included). A report is *during a query* when its joint state was
published between the call and the arrival of its response, else *baseline* (after the
first ``--quiet`` / 2 seconds, the warm-up). Printed: the latency p50 / p99 / max of both
groups, their differences (the delay attributable to the queries, at each percentile), the
queries' durations, and as the last line one JSON object. Run it on an otherwise idle
machine: the worker answering the queries, the node, the driver and this process share the
cores.

``--variant thread`` runs, for comparison, a node that answers ``~/evaluate`` the other way:
from a thread of the node process (a second executor, its own evaluator), not the worker
process (:func:`thread_variant_main`).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from awp_ros.errors import ProcessError
from awp_ros.node.launcher import ros_env, start_node, stop_node
from awp_ros.soak.driver import driver_command
from awp_ros.soak.probe import Probe, wait_until
from awp_ros.soak.result import percentiles

__all__ = ['main', 'query_request', 'run_query_load', 'thread_variant_main']

_THREAD_VARIANT = '--thread-variant-node'


def query_request(config, states: int, rng: np.random.Generator, *, spread: float = 0.1):
    """
    Return an ``Evaluate`` request of ``states`` random postures around standing.

    :param config: the robot config (its ``standing_posture`` and ``feet``).
    :param spread: half-width of the uniform joint offsets [rad].
    """
    from awp_ros_msgs.msg import ContactState
    from awp_ros_msgs.srv import Evaluate
    from sensor_msgs.msg import JointState

    names = sorted(config.standing_posture)
    q0 = np.array([config.standing_posture[n] for n in names])
    feet = list(config.feet)
    request = Evaluate.Request()
    joints, contacts = [], []
    for _ in range(states):
        q = q0 + rng.uniform(-spread, spread, size=q0.size)
        stance = set(rng.choice(feet, size=int(rng.integers(2, len(feet) + 1)),
                                replace=False).tolist())
        joints.append(JointState(name=names, position=q.tolist()))
        contacts.append(ContactState(names=feet, in_contact=[f in stance for f in feet]))
    request.joint_states = joints
    request.contacts = contacts
    return request


def run_query_load(rate_hz: float = 500.0, duration_s: float = 30.0, *, states: int = 100,
                   period_s: float = 4.0, quiet_s: float = 6.0, robot: str = 'hyq',
                   namespace: str = '/query_load', env: dict[str, str] | None = None,
                   seed: int = 0, queries: bool = True,
                   command: list[str] | None = None) -> dict:
    """
    Run one measurement (module docstring) and return its figures.

    :param rate_hz: joint-state rate [Hz].
    :param duration_s: drive duration [s].
    :param states: states per query.
    :param period_s: time from one call's start to the next [s] (at least its duration).
    :param quiet_s: drive time before the first query [s].
    :param queries: False = the baseline run alone (no query).
    :param command: the node's command (default the ``awp_node`` console script), e.g. a
        variant serving the queries another way, to compare.
    :return: ``latency_baseline_ms``, ``latency_during_queries_ms`` (p50, p99, max),
        ``delay_attributable_ms`` (during minus baseline at p50, p99 and max; clipped at 0),
        ``queries`` (calls answered), ``query_s`` (their durations), ``reports``, ``sent``,
        ``missing``, ``query_statuses`` (status counts of the queries' reports).
    """
    from awp_ros_msgs.msg import FeasibilityReport
    from awp_ros_msgs.srv import Evaluate

    from awp_ros.robot.config import load_config

    env = ros_env() if env is None else env
    domain = int(env.get('ROS_DOMAIN_ID', '0') or 0)
    ns = namespace.rstrip('/')
    n_max = int(rate_hz * duration_s) + 1000
    proc = start_node(env=env, robot=robot, namespace=ns, params={'qos_depth': n_max},
                      command=command)
    probe = Probe(domain, 'awp_query_load_probe')
    stamps = np.zeros(n_max, dtype=np.int64)
    recv = np.zeros(n_max, dtype=np.int64)
    count = [0]

    def on_report(msg) -> None:
        i = count[0]
        if i < n_max:
            stamps[i] = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            recv[i] = time.time_ns()
        count[0] = i + 1

    probe.subscribe(FeasibilityReport, f'{ns}/awp_node/report', on_report, depth=n_max)
    client = probe.node.create_client(Evaluate, f'{ns}/awp_node/evaluate')
    rng = np.random.default_rng(seed)
    config = load_config(robot)
    windows: list[tuple[int, int]] = []
    statuses: dict[int, int] = {}
    stamps_file = tempfile.NamedTemporaryFile(prefix='awp_qload_', suffix='.npy', delete=False)
    stamps_file.close()
    try:
        wait_until(lambda: probe.node.count_publishers(f'{ns}/awp_node/report') > 0, 60.0,
                   'awp_node to appear')
        if not client.wait_for_service(timeout_sec=60.0):
            raise ProcessError(f'{ns}/awp_node/evaluate did not appear')
        time.sleep(0.5)
        cmd = driver_command(rate_hz, duration_s, robot=robot, namespace=ns,
                             stamps_out=stamps_file.name, depth=n_max)
        driver = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, text=True)
        wait_until(lambda: count[0] > 0, 60.0, 'the first report')
        start = time.monotonic()
        next_call = start + quiet_s
        while queries and driver.poll() is None:
            now = time.monotonic()
            if now < next_call:
                time.sleep(min(0.05, next_call - now))
                continue
            if now - start + 2.0 > duration_s:       # leave the drive's end quiet
                break
            request = query_request(config, states, rng)
            t0 = time.time_ns()
            future = client.call_async(request)
            wait_until(future.done, 120.0, 'an ~/evaluate response', poll_s=0.001)
            windows.append((t0, time.time_ns()))
            for report in future.result().reports:
                statuses[report.status] = statuses.get(report.status, 0) + 1
            next_call += max(period_s, (windows[-1][1] - t0) * 1e-9)
        out, _ = driver.communicate(timeout=duration_s + 180)
        if driver.returncode != 0:
            raise ProcessError(f'the driver failed (exit {driver.returncode}): {out[-2000:]}')
        sent = np.load(stamps_file.name)
        wait_until(lambda: count[0] >= sent.size, 60.0, 'every report')
    finally:
        probe.close()
        stop_node(proc)
        os.unlink(stamps_file.name)
    n = min(count[0], n_max)
    got, latency = stamps[:n], (recv[:n] - stamps[:n]) * 1e-6
    during = np.zeros(n, dtype=bool)
    for t0, t1 in windows:
        during |= (got >= t0) & (got <= t1)
    warm = got >= int(sent[0]) + int(quiet_s / 2 * 1e9)
    base = percentiles(latency[warm & ~during])
    busy = percentiles(latency[during])
    delay = {k: max(0.0, busy[k] - base[k]) for k in base} if busy and base else {}
    names = {0: 'ok', 1: 'warning', 2: 'invalid_input', 3: 'stale_input', 4: 'error'}
    return {'rate_hz': rate_hz, 'duration_s': duration_s, 'states_per_query': states,
            'sent': int(sent.size), 'reports': int(count[0]),
            'missing': int(np.setdiff1d(sent, got).size),
            'queries': len(windows),
            'query_s': [round((t1 - t0) * 1e-9, 3) for t0, t1 in windows],
            'query_statuses': {names[k]: v for k, v in sorted(statuses.items())},
            'reports_baseline': int(np.sum(warm & ~during)),
            'reports_during_queries': int(np.sum(during)),
            'latency_baseline_ms': base, 'latency_during_queries_ms': busy,
            'delay_attributable_ms': delay}


def thread_variant_main() -> int:
    """Run awp_node with ``~/evaluate`` served by a thread of its process (comparison only)."""
    import threading

    from awp_ros_msgs.srv import Evaluate
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    from awp_ros.evaluation.evaluator import FeasibilityEvaluator
    from awp_ros.node.evaluate_service import evaluate_request
    from awp_ros.node.node import AwpNode

    rclpy.init(args=sys.argv)
    node = AwpNode()
    node.evaluate_service.close()            # the worker process steps aside
    evaluator = FeasibilityEvaluator(node.pipeline.config)
    evaluator.hull_tol = max(node.pipeline.params.hull_tolerance, evaluator.feasibility_tol)
    server = rclpy.create_node('_awp_node_evaluate_thread', namespace=node.get_namespace())
    server.create_service(Evaluate, node.resolve_service_name('~/evaluate'),
                          lambda req, _: evaluate_request(evaluator, node.pipeline.params, req))
    side = SingleThreadedExecutor()
    side.add_node(server)
    threading.Thread(target=side.spin, daemon=True).start()
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        side.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def table(result: dict) -> str:
    """Return the result as a few lines of text."""
    lines = [f"query_load: {result['sent']} joint states at {result['rate_hz']:g} Hz, "
             f"{result['reports']} reports ({result['missing']} missing); "
             f"{result['queries']} queries of {result['states_per_query']} states "
             f"(durations {result['query_s']} s, statuses {result['query_statuses']})",
             f"{'report latency [ms]':<28}{'n':>8}{'p50':>9}{'p99':>9}{'max':>9}"]
    for label, key, count in (('baseline', 'latency_baseline_ms', 'reports_baseline'),
                              ('during queries', 'latency_during_queries_ms',
                               'reports_during_queries'),
                              ('attributable (difference)', 'delay_attributable_ms', None)):
        values = result[key]
        if values:
            n = '' if count is None else str(result[count])
            lines.append(f'{label:<28}{n:>8}' + ''.join(f'{values[k]:>9.3f}'
                                                        for k in ('p50', 'p99', 'max')))
    return '\n'.join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the measurement; print the table and one JSON line."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == [_THREAD_VARIANT]:
        return thread_variant_main()
    parser = argparse.ArgumentParser(prog='python -m awp_ros.soak.query_load',
                                     description=__doc__.split('\n\n')[0])
    parser.add_argument('--rate', type=float, default=500.0, help='joint states [Hz]')
    parser.add_argument('--duration', type=float, default=30.0, help='drive time [s]')
    parser.add_argument('--states', type=int, default=100, help='states per query')
    parser.add_argument('--period', type=float, default=4.0, help='seconds between calls')
    parser.add_argument('--quiet', type=float, default=6.0,
                        help='drive time before the first query [s]')
    parser.add_argument('--robot', default='hyq', help='robot config name')
    parser.add_argument('--namespace', default='/query_load', help="the node's namespace")
    parser.add_argument('--seed', type=int, default=0, help='seed of the query postures')
    parser.add_argument('--no-queries', action='store_true', help='the baseline alone')
    parser.add_argument('--variant', choices=('worker', 'thread'), default='worker',
                        help='who answers ~/evaluate: the worker process (awp_node as it is) '
                        'or, for comparison, a thread of the node process')
    args = parser.parse_args(argv)
    command = None if args.variant == 'worker' else \
        [sys.executable, '-m', 'awp_ros.soak.query_load', _THREAD_VARIANT]
    result = run_query_load(args.rate, args.duration, states=args.states,
                            period_s=args.period, quiet_s=args.quiet, robot=args.robot,
                            namespace=args.namespace, seed=args.seed,
                            queries=not args.no_queries, command=command)
    result['variant'] = args.variant
    print(table(result))
    print(json.dumps(result))
    return 0 if result['missing'] == 0 else 1


if __name__ == '__main__':
    sys.exit(main())
