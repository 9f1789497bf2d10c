"""
Measure how ``~/evaluate`` queries delay ``awp_node``'s live reports.

::

    python -m awp_ros.soak.query_load --rate 500 --duration 30 --states 100 --period 4

Starts ``awp_node`` (namespace ``--namespace``, default ``/query_load``) and the soak's
driver (:mod:`awp_ros.soak.driver`: gait joint states at ``--rate``, each stamped with the
wall clock when published, and contacts) and subscribes to the node's reports; a caller
process (:func:`caller_main`; apart, so that building requests and reading answers does not
hold up this process's report callback) calls ``~/evaluate`` from ``--quiet`` seconds after
the drive starts, every ``--period`` seconds, with ``--states`` random postures around
standing (joint offsets uniform in +-0.1 rad, a random stance of 2 to 4 feet each, one
ContactState per joint state), one call at a time.

The latency of a report is its reception time here minus its joint state's stamp [ms]
(transport both ways included). A report is *during a query* when its joint state was
published between the call and the arrival of its response, else *baseline* (after the
first ``--quiet`` / 2 seconds, the warm-up). Printed: the latency p50 / p99 / max of both
groups, their differences (the delay attributable to the queries, at each percentile), the
queries' durations, and as the last line one JSON object. Run it on an otherwise idle
machine: the worker answering the queries, the node, the driver and this process share the
cores.

``--idle-caller`` runs the caller at ``SCHED_IDLE`` (what the queries cost the stream through
the node, without the caller's own work); ``--control S`` is the control experiment: in place of
each call the caller evaluates for ``S`` seconds at ``SCHED_IDLE`` (no call, no DDS), which shows
what the same kind of CPU work costs the stream when the node has nothing to do with it;
``--alternate`` makes every other window such a control (the previous call's states, for as long
as that call took), so that calls and controls share one run and its conditions; ``--null`` adds,
after each control, a *null* window of the same length in which nothing is done: its paired
differences are the measurement's own noise floor (what a stretch differs from the one before it
when nothing happens), against which the calls' and controls' differences are read.
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

__all__ = ['caller_main', 'main', 'query_request', 'run_query_load', 'table',
           'thread_variant_main', 'window_kind']

_THREAD_VARIANT = '--thread-variant-node'
_CALLER = '--caller'


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
                   command: list[str] | None = None, idle_caller: bool = False,
                   control_s: float = 0.0, alternate: bool = False, null: bool = False,
                   params: dict | None = None) -> dict:
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
    :param idle_caller: run the caller at the lowest CPU priority (``SCHED_IDLE``): what the
        queries cost the stream through the node alone, not through the caller's own work
        (building requests, reading 100 reports).
    :param control_s: > 0: the control experiment: instead of each call, the caller runs
        ``evaluate`` (FWS included) on the call's states for this long [s] at ``SCHED_IDLE``,
        no call and no DDS: what the same work costs the stream when the node has nothing to
        do with it.
    :param params: more node parameters (name -> value), e.g. ``{'fws_lag_s': 0.03}``.
    :param alternate: every other window is the control (the caller at ``SCHED_IDLE``, the
        previous call's states for as long as that call took): calls and controls in the same
        run, ``paired_control_ms`` the controls' paired differences.
    :param null: with ``alternate``, each control is followed by a null window (nothing done,
        as long as the control): ``paired_null_ms``, the noise floor of the paired figures.
    :return: ``latency_baseline_ms``, ``latency_during_queries_ms`` (p50, p99, max),
        ``delay_attributable_ms`` (during minus baseline at p50, p99 and max; clipped at 0),
        ``paired_difference_ms`` (per call: p50, p99 and max of the latencies during it minus
        those of the equally long stretch before it, which is robust to slow drifts),
        ``queries`` (calls answered), ``query_s`` (their durations), ``reports``, ``sent``,
        ``missing``, ``query_statuses`` (status counts of the queries' reports).
    """
    from awp_ros_msgs.msg import FeasibilityReport

    env = ros_env() if env is None else env
    domain = int(env.get('ROS_DOMAIN_ID', '0') or 0)
    ns = namespace.rstrip('/')
    n_max = int(rate_hz * duration_s) + 1000
    proc = start_node(env=env, robot=robot, namespace=ns,
                      params={'qos_depth': n_max, **(params or {})}, command=command)
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
    stamps_file = tempfile.NamedTemporaryFile(prefix='awp_qload_', suffix='.npy', delete=False)
    stamps_file.close()
    calls = {'windows': [], 'statuses': {}}
    try:
        wait_until(lambda: probe.node.count_publishers(f'{ns}/awp_node/report') > 0, 60.0,
                   'awp_node to appear')
        wait_until(lambda: probe.node.count_services(f'{ns}/awp_node/evaluate') > 0, 60.0,
                   f'{ns}/awp_node/evaluate to appear')
        time.sleep(0.5)
        cmd = driver_command(rate_hz, duration_s, robot=robot, namespace=ns,
                             stamps_out=stamps_file.name, depth=n_max)
        driver = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, text=True)
        wait_until(lambda: count[0] > 0, 60.0, 'the first report')
        caller = None
        if queries:     # a process of its own: its work is not this process's (GIL)
            caller = subprocess.Popen(
                [sys.executable, '-m', 'awp_ros.soak.query_load', _CALLER, json.dumps(
                    {'service': f'{ns}/awp_node/evaluate', 'robot': robot, 'states': states,
                     'period_s': period_s, 'quiet_s': quiet_s,
                     'until_s': duration_s - 2.0, 'seed': seed, 'domain': domain,
                     'idle': idle_caller, 'control_s': control_s,
                     'alternate': alternate, 'null': null})],
                env=env, stdout=subprocess.PIPE, text=True)
        out, _ = driver.communicate(timeout=duration_s + 180)
        if driver.returncode != 0:
            raise ProcessError(f'the driver failed (exit {driver.returncode}): {out[-2000:]}')
        if caller is not None:
            text, _ = caller.communicate(timeout=300)
            lines = [ln for ln in text.splitlines() if ln.startswith('{')]
            if caller.returncode != 0 or not lines:
                raise ProcessError(f'the caller failed (exit {caller.returncode}): {text[-2000:]}')
            calls = json.loads(lines[-1])
        sent = np.load(stamps_file.name)
        wait_until(lambda: count[0] >= sent.size, 60.0, 'every report')
    finally:
        probe.close()
        stop_node(proc)
        os.unlink(stamps_file.name)
    windows = [tuple(w[:2]) for w in calls['windows'] if w[2] == 'call']
    controls = [tuple(w[:2]) for w in calls['windows'] if w[2] == 'control']
    nulls = [tuple(w[:2]) for w in calls['windows'] if w[2] == 'null']
    statuses = {int(k): v for k, v in calls['statuses'].items()}
    n = min(count[0], n_max)
    got, latency = stamps[:n], (recv[:n] - stamps[:n]) * 1e-6
    during = np.zeros(n, dtype=bool)
    for t0, t1 in windows:
        during |= (got >= t0) & (got <= t1)
    busy_any = during.copy()
    for t0, t1 in controls:     # (null windows stay in the baseline: nothing happens)
        busy_any |= (got >= t0) & (got <= t1)
    warm = got >= int(sent[0]) + int(quiet_s / 2 * 1e9)
    base = percentiles(latency[warm & ~busy_any])
    busy = percentiles(latency[during])
    delay = {k: max(0.0, busy[k] - base[k]) for k in base} if busy and base else {}
    # Paired: each window against the equally long stretch just before it.

    def pairs(spans: list) -> list:
        out = []
        for t0, t1 in spans:
            before = (got >= 2 * t0 - t1) & (got < t0) & ~busy_any
            inside = (got >= t0) & (got <= t1)
            if before.any() and inside.any():
                a, b = latency[inside], latency[before]
                out.append({'p50': float(np.median(a) - np.median(b)),
                            'p99': float(np.percentile(a, 99) - np.percentile(b, 99)),
                            'max': float(a.max() - b.max())})
        return out
    names = {0: 'ok', 1: 'warning', 2: 'invalid_input', 3: 'stale_input', 4: 'error'}
    return {'rate_hz': rate_hz, 'duration_s': duration_s, 'states_per_query': states,
            'sent': int(sent.size), 'reports': int(count[0]),
            'missing': int(np.setdiff1d(sent, got).size),
            'queries': len(windows),
            'query_s': [round((t1 - t0) * 1e-9, 3) for t0, t1 in windows],
            'query_statuses': {names[k]: v for k, v in sorted(statuses.items())},
            'reports_baseline': int(np.sum(warm & ~busy_any)),
            'reports_during_queries': int(np.sum(during)),
            'latency_baseline_ms': base, 'latency_during_queries_ms': busy,
            'delay_attributable_ms': delay,
            'paired_difference_ms': pairs(windows),
            'paired_control_ms': pairs(controls),
            'paired_null_ms': pairs(nulls)}


def window_kind(index: int, *, alternate: bool, null: bool, control: bool) -> str:
    """
    Return what the caller's window ``index`` (0, 1, ...) is: ``call``, ``control`` or ``null``.

    With ``alternate`` the windows cycle through a call, a control (as long as that call) and,
    with ``null``, a null window (as long again); otherwise every window is a control when the
    caller runs controls (``control``), else a call.
    """
    if alternate:
        cycle = ('call', 'control', 'null') if null else ('call', 'control')
        return cycle[index % len(cycle)]
    return 'control' if control else 'call'


def caller_main(spec: dict) -> int:
    """
    Call ``~/evaluate`` on a schedule and print the call windows (the measurement's caller).

    ``spec``: ``service``, ``robot``, ``states``, ``period_s``, ``quiet_s`` (from now),
    ``until_s`` (no call starts later), ``seed``, ``domain``, ``idle``, ``control_s``,
    ``alternate``, ``null``. Prints one JSON object: ``windows`` ([start, end, kind]:
    wall-clock [ns] of each window, ``call``, ``control`` or ``null``) and ``statuses`` (of
    the reports).
    """
    from awp_ros_msgs.srv import Evaluate

    from awp_ros.robot.config import load_config

    alternate = bool(spec.get('alternate'))
    if spec.get('idle') or spec.get('control_s') or alternate:   # lowest priority (docstring)
        for task in os.listdir('/proc/self/task'):
            os.sched_setscheduler(int(task), os.SCHED_IDLE, os.sched_param(0))
    probe = Probe(spec['domain'], 'awp_query_load_caller')
    windows, statuses = [], {}
    control = None
    if spec.get('control_s') or alternate:
        from awp_ros.evaluation.evaluator import FeasibilityEvaluator
        from awp_ros.robot.state import RobotState
        from awp_ros.runtime import tune_process
        tune_process()
        control = FeasibilityEvaluator(spec['robot'])
    try:
        client = probe.node.create_client(Evaluate, spec['service'])
        if not client.wait_for_service(timeout_sec=60.0):
            raise ProcessError(f"{spec['service']} did not appear")
        rng = np.random.default_rng(spec['seed'])
        config = load_config(spec['robot'])
        start = time.monotonic()
        next_call = start + spec['quiet_s']
        last = None
        while True:
            request = query_request(config, spec['states'], rng)      # before the window
            left = next_call - time.monotonic()
            if left > 0:
                time.sleep(left)
            if time.monotonic() - start > spec['until_s']:
                break
            kind = window_kind(len(windows), alternate=alternate, null=bool(spec.get('null')),
                               control=control is not None)
            is_control = kind == 'control'
            if kind != 'call' and alternate and last is not None:
                request = last
            last = request
            t0 = time.time_ns()
            if kind == 'null':              # nothing at all: the noise floor
                time.sleep((windows[-1][1] - windows[-1][0]) * 1e-9)
            elif is_control:                # the same work, no call, no DDS
                states = [RobotState(joint_positions=dict(zip(js.name, js.position)),
                                     stance=[f for f, c in zip(cs.names, cs.in_contact) if c])
                          for js, cs in zip(request.joint_states, request.contacts)]
                length = (windows[-1][1] - windows[-1][0]) * 1e-9 if alternate \
                    else spec['control_s']
                end = time.monotonic() + length
                k = 0
                while time.monotonic() < end:
                    control.evaluate(states[k % len(states)])
                    k += 1
            else:
                future = client.call_async(request)
                wait_until(future.done, 120.0, 'an ~/evaluate response', poll_s=0.002)
                for report in future.result().reports:
                    statuses[report.status] = statuses.get(report.status, 0) + 1
            windows.append((t0, time.time_ns(), kind))
            next_call += max(spec['period_s'], (windows[-1][1] - t0) * 1e-9)
    finally:
        probe.close()
    print(json.dumps({'windows': windows, 'statuses': statuses}), flush=True)
    return 0


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
    for key, label in (('paired_difference_ms', 'call'), ('paired_control_ms', 'control'),
                       ('paired_null_ms', 'null window')):
        paired = result.get(key) or []
        if paired:
            parts = []
            for stat in ('p50', 'p99', 'max'):
                v = sorted(p[stat] for p in paired)
                parts.append(f'{stat} difference median {v[len(v) // 2]:.3f} ms (range '
                             f'{v[0]:.3f} .. {v[-1]:.3f})')
            lines.append(f'paired (each {label} vs the stretch before it, '
                         f'{len(paired)} windows): ' + ', '.join(parts))
    return '\n'.join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the measurement; print the table and one JSON line."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == [_THREAD_VARIANT]:
        return thread_variant_main()
    if argv[:1] == [_CALLER]:
        return caller_main(json.loads(argv[1]))
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
    parser.add_argument('--idle-caller', action='store_true',
                        help="run the caller at SCHED_IDLE (leave out the planner's own CPU use)")
    parser.add_argument('--control', type=float, default=0.0, metavar='SECONDS',
                        help='control experiment: instead of each call, evaluate for this long '
                        'at SCHED_IDLE in the caller (no call, no DDS)')
    parser.add_argument('--alternate', action='store_true',
                        help='every other window is the control (same states, as long as the '
                        'call before it): calls and controls in one run')
    parser.add_argument('--null', action='store_true',
                        help='with --alternate: after each control a window in which nothing '
                        'is done (the noise floor of the paired differences)')
    parser.add_argument('--param', action='append', default=[], metavar='NAME:=VALUE',
                        help='more node parameters, e.g. fws_lag_s:=0.03')
    parser.add_argument('--variant', choices=('worker', 'thread'), default='worker',
                        help='who answers ~/evaluate: the worker process (awp_node as it is) '
                        'or, for comparison, a thread of the node process')
    args = parser.parse_args(argv)
    command = None if args.variant == 'worker' else \
        [sys.executable, '-m', 'awp_ros.soak.query_load', _THREAD_VARIANT]
    result = run_query_load(args.rate, args.duration, states=args.states,
                            period_s=args.period, quiet_s=args.quiet, robot=args.robot,
                            namespace=args.namespace, seed=args.seed,
                            queries=not args.no_queries, command=command,
                            idle_caller=args.idle_caller, control_s=args.control,
                            alternate=args.alternate, null=args.null,
                            params=dict(p.split(':=', 1) for p in args.param))
    result.update(params=args.param, variant=args.variant, idle_caller=args.idle_caller,
                  control_s=args.control, alternate=args.alternate, null=args.null)
    print(table(result))
    print(json.dumps(result))
    return 0 if result['missing'] == 0 else 1


if __name__ == '__main__':
    sys.exit(main())
