"""Soak test of ``awp_node``: drive it at a fixed rate for a while; count what it loses.

::

    python -m awp_ros.soak --rate 1000 --duration 60 [--robot hyq] [--warmup 10]

Three processes on one ROS domain (``ROS_DOMAIN_ID``; discovery kept on this machine with
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` unless set otherwise):

1. ``awp_node`` (the console script) in namespace ``--namespace`` (default ``/soak``);
2. a driver (``python -m awp_ros.soak --drive ...``) that publishes ``joint_states`` at
   ``--rate`` on a schedule (sleeps to absolute targets, so jitter does not accumulate),
   each stamped with the wall clock when it is published, and ``contacts`` on every stance
   change and at ``--contacts-rate``, stamped like the joint state they precede. Postures
   and stance come from the gait generator (:mod:`awp_ros.gait`: crawl then trot, the
   motion of the default bag), one sample per message, in a loop. It writes the stamps it
   sent to a file;
3. this process: subscribes to ``<ns>/awp_node/report`` and ``/diagnostics`` and samples
   the node's CPU time and RSS from ``/proc/<pid>/stat`` and ``/proc/<pid>/status`` every
   ``--sample-period`` seconds.

Measured: joint states sent and their rate, reports received, **missing** (a stamp sent
without a report), **duplicates**, unexpected stamps, the report statuses, the latency
from the joint-state stamp to the report's reception here (p50 / p99 / max, over the
whole run and after the warm-up), the node's CPU [% of one core] and RSS [MB] over time,
and the RSS growth from the end of the warm-up to the end of the drive (goal < 5 %).
After the drive it waits for the backlog to drain (a node slower than the input rate
answers late, from its reliable queue of ``qos_depth`` joint states, but answers). It
prints a table and, as its last line, one JSON object.

The helpers (:class:`Probe`, :func:`start_node`, :class:`ProcessMonitor`,
:func:`run_soak`) are used by the tests too.
"""

from __future__ import annotations

import argparse
from array import array
from dataclasses import asdict, dataclass, field
import json
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

__all__ = ['Probe', 'ProcessMonitor', 'SoakResult', 'drive', 'driver_command', 'main',
           'node_command', 'proc_usage', 'ros_env', 'run_soak', 'start_node', 'stop_node',
           'wait_until']

_CLK_TCK = os.sysconf('SC_CLK_TCK')


# -- processes -----------------------------------------------------------------------------


def node_command() -> list[str]:
    """Return the command of ``awp_node``.

    The console script beside this interpreter, else the one on PATH, else
    ``python -m awp_ros.node``.
    """
    beside = Path(sys.executable).parent / 'awp_node'
    if beside.is_file():
        return [str(beside)]
    found = shutil.which('awp_node')
    return [found] if found else [sys.executable, '-m', 'awp_ros.node']


def ros_env(domain_id: int | None = None) -> dict[str, str]:
    """Return ``os.environ`` with discovery on this machine (unless set) and ``domain_id``."""
    env = dict(os.environ)
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    if domain_id is not None:
        env['ROS_DOMAIN_ID'] = str(domain_id)
    env['PYTHONUNBUFFERED'] = '1'
    return env


def start_node(*, env: dict[str, str], robot: str | None = 'hyq', namespace: str = '',
               params: dict | None = None, ros_args: tuple[str, ...] = (),
               log_path: str | os.PathLike | None = None) -> subprocess.Popen:
    """Start ``awp_node`` as its own process.

    :param env: the environment (see :func:`ros_env`).
    :param robot: the ``robot`` parameter (config name or YAML path); None leaves it out.
    :param namespace: the node's namespace (``-r __ns:=...``), '' = root.
    :param params: more parameters, ``{name: value}`` (values as ``-p name:=value`` text;
        lists and strings as YAML).
    :param ros_args: more ``--ros-args`` arguments.
    :param log_path: file receiving the node's stdout and stderr (default a temporary
        file; ``proc.log_path`` holds it). A file, not a pipe: a pipe nobody reads would
        block a node that logs a lot.
    :return: the process (``proc.log_path`` set).
    """
    args = []
    if robot is not None:
        args += ['-p', f'robot:={robot}']
    for name, value in (params or {}).items():
        text = json.dumps(value) if isinstance(value, (list, bool)) else str(value)
        args += ['-p', f'{name}:={text}']
    if namespace:
        args += ['-r', f'__ns:={namespace}']
    temporary = log_path is None
    if temporary:
        fd, log_path = tempfile.mkstemp(prefix='awp_node_', suffix='.log')
        os.close(fd)
    log = open(log_path, 'w')  # noqa: SIM115 -- handed to the child, closed below
    try:
        proc = subprocess.Popen(node_command() + ['--ros-args', *args, *ros_args], env=env,
                                stdout=log, stderr=subprocess.STDOUT)
    finally:
        log.close()
    proc.log_path = str(log_path)
    proc.log_is_temporary = temporary
    return proc


def stop_node(proc: subprocess.Popen, timeout_s: float = 10.0) -> str:
    """Stop a node started by :func:`start_node`; return its log.

    SIGINT, then SIGKILL after ``timeout_s`` [s]; a temporary log file is removed.
    """
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    path = getattr(proc, 'log_path', None)
    if not path:
        return ''
    text = Path(path).read_text(errors='replace')
    if getattr(proc, 'log_is_temporary', False):
        Path(path).unlink(missing_ok=True)
    return text


def proc_usage(pid: int) -> tuple[float, int]:
    """Return a process's CPU time (user + system) [s] and resident set size [B].

    From ``/proc/<pid>/stat`` (fields 14 and 15, in clock ticks) and the ``VmRSS`` line of
    ``/proc/<pid>/status`` [kB].
    """
    with open(f'/proc/{pid}/stat') as f:
        stat = f.read()
    rest = stat[stat.rindex(')') + 2:].split()   # fields from 3 (state) on
    cpu = (int(rest[11]) + int(rest[12])) / _CLK_TCK
    rss = 0
    with open(f'/proc/{pid}/status') as f:
        for line in f:
            if line.startswith('VmRSS:'):
                rss = int(line.split()[1]) * 1024
                break
    return cpu, rss


class ProcessMonitor:
    """Sample a process's CPU time and RSS every ``period_s`` in a background thread.

    ``samples`` rows: (wall time [s, time.monotonic], CPU time [s], RSS [B]).
    """

    def __init__(self, pid: int, period_s: float = 1.0) -> None:
        self.pid = pid
        self.period_s = period_s
        self.samples: list[tuple[float, float, int]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                cpu, rss = proc_usage(self.pid)
            except (OSError, ValueError, IndexError):     # the process ended
                return
            self.samples.append((time.monotonic(), cpu, rss))
            self._stop.wait(self.period_s)

    def stop(self) -> None:
        """Stop sampling."""
        self._stop.set()
        self._thread.join(timeout=5)

    def array(self) -> np.ndarray:
        """Return the samples as an (n, 3) array."""
        return np.array(self.samples, dtype=float).reshape(-1, 3)


# -- a DDS participant of our own ----------------------------------------------------------


def wait_until(predicate, timeout_s: float, what: str, *, poll_s: float = 0.02) -> None:
    """Poll ``predicate()`` until true; raise TimeoutError naming ``what`` after a while.

    :param timeout_s: how long to poll [s].
    """
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(poll_s)
    raise TimeoutError(f'timed out after {timeout_s} s waiting for {what}')


class Probe:
    """One DDS participant (an rclpy Context on ``domain_id``) spun in a background thread.

    Publishers and subscriptions are reliable, keep last ``depth``. Received messages are
    appended to the list :meth:`subscribe` returns (under ``lock``), or passed to a
    callback.
    """

    def __init__(self, domain_id: int, name: str = 'awp_probe') -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=int(domain_id))
        self.node = rclpy.create_node(name, context=self.context)
        self.lock = threading.Lock()
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

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

    def subscribe(self, mtype, topic: str, callback=None, depth: int = 1000) -> list:
        """Subscribe to ``topic``; return the list the messages are appended to."""
        got: list = []

        def store(msg) -> None:
            with self.lock:
                got.append(msg)
        self.node.create_subscription(mtype, topic, callback or store, self.qos(depth))
        return got

    def close(self) -> None:
        """Stop spinning and leave the domain."""
        import rclpy
        self.executor.shutdown(timeout_sec=2.0)
        self._thread.join(timeout=5)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


# -- the driver process --------------------------------------------------------------------


def _stamp(msg, ns: int):
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
    return msg


def drive(*, rate_hz: float, duration_s: float, robot: str, namespace: str,
          stamps_path: str | None, contacts_rate_hz: float = 100.0, depth: int = 100000,
          match_timeout_s: float = 60.0, topics: str = 'both') -> dict:
    """Publish gait joint states at ``rate_hz`` for ``duration_s`` (the driver process).

    Waits until the node's subscriptions match, publishes, waits until every message was
    acknowledged, saves the sent stamps [ns] (``np.save``) and returns a summary.
    ``topics``: ``'both'``; ``'joint_states'`` (no contacts); ``'contacts'`` (contacts
    only, one per tick at ``rate_hz``: a stand-alone contact publisher).
    """
    import rclpy
    from awp_ros_msgs.msg import ContactState
    from sensor_msgs.msg import JointState

    from awp_ros.gait import generate_gait
    from awp_ros.robot_config import load_config

    samples = generate_gait(load_config(robot))
    names = list(samples.joint_names)
    feet = list(samples.feet)
    positions = [array('d', row.tobytes()) for row in np.ascontiguousarray(samples.q)]
    velocities = [array('d', row.tobytes()) for row in np.ascontiguousarray(samples.v)]
    stance = [tuple(bool(c) for c in row) for row in samples.stance]
    rclpy.init()
    node = rclpy.create_node('awp_soak_driver')
    ns = namespace.rstrip('/')
    qos = Probe.qos(depth)
    send_js, send_c = topics in ('both', 'joint_states'), topics in ('both', 'contacts')
    if not (send_js or send_c):
        raise ValueError(f"topics must be 'both', 'joint_states' or 'contacts', got {topics!r}")
    js_pub = node.create_publisher(JointState, f'{ns}/joint_states', qos) if send_js else None
    c_pub = node.create_publisher(ContactState, f'{ns}/contacts', qos) if send_c else None
    pubs = [p for p in (js_pub, c_pub) if p is not None]
    wait_until(lambda: all(p.get_subscription_count() for p in pubs), match_timeout_s,
               'awp_node to subscribe')
    time.sleep(0.5)                           # let the matching settle on both sides
    n = int(round(rate_hz * duration_s))
    stamps = np.zeros(n, dtype=np.int64)
    js = JointState(name=names)
    cs = ContactState(names=feet)
    contacts_period = int(1e9 / contacts_rate_hz) if contacts_rate_hz > 0 else None
    last_contacts, last_stance = None, None
    lateness = np.zeros(n)
    start = time.perf_counter()
    for i in range(n):
        target = start + i / rate_hz
        left = target - time.perf_counter()
        if left > 0:
            time.sleep(left)
        lateness[i] = time.perf_counter() - target
        k = i % len(positions)
        now = time.time_ns()
        if send_c and (not send_js or stance[k] != last_stance or last_contacts is None or (
                contacts_period is not None and now - last_contacts >= contacts_period)):
            cs.in_contact = list(stance[k])
            c_pub.publish(_stamp(cs, now))
            last_contacts, last_stance = now, stance[k]
        if send_js:
            js.position = positions[k]
            js.velocity = velocities[k]
            js_pub.publish(_stamp(js, now))
        stamps[i] = now
    elapsed = time.perf_counter() - start
    acked = all([p.wait_for_all_acked(rclpy.duration.Duration(seconds=60.0)) for p in pubs])
    if stamps_path:
        np.save(stamps_path, stamps)
    node.destroy_node()
    rclpy.try_shutdown()
    return {'sent': n, 'sent_rate_hz': n / elapsed if elapsed > 0 else float('nan'),
            'lateness_p99_ms': float(np.percentile(lateness, 99) * 1e3) if n else 0.0,
            'all_acked': bool(acked)}


def driver_command(rate_hz: float, duration_s: float, *, robot: str = 'hyq',
                   namespace: str = '', stamps_out: str | None = None,
                   contacts_rate_hz: float = 100.0, depth: int = 100000,
                   topics: str = 'both') -> list[str]:
    """Return the command of a driver process (:func:`drive`); it prints one JSON line."""
    cmd = [sys.executable, '-m', 'awp_ros.soak', '--drive', '--rate', str(rate_hz),
           '--duration', str(duration_s), '--robot', robot, '--namespace',
           namespace.rstrip('/') or '/', '--contacts-rate', str(contacts_rate_hz),
           '--depth', str(depth), '--topics', topics]
    return cmd + (['--stamps-out', str(stamps_out)] if stamps_out else [])


# -- the soak ------------------------------------------------------------------------------


@dataclass
class SoakResult:
    """What a soak measured (see the module docstring). Times [s] unless the key says ms."""

    robot: str
    rate_hz: float
    duration_s: float
    qos_depth: int
    sent: int = 0
    sent_rate_hz: float = float('nan')
    reports: int = 0
    missing: int = 0
    duplicates: int = 0
    unexpected: int = 0
    status_counts: dict = field(default_factory=dict)
    latency_ms: dict = field(default_factory=dict)
    latency_after_warmup_ms: dict = field(default_factory=dict)
    cpu_percent: dict = field(default_factory=dict)
    rss_mb: dict = field(default_factory=dict)
    rss_growth_percent: float = float('nan')
    drain_s: float = 0.0
    node_lost_total: int | None = None
    node_missing_from_sequence: int | None = None
    node_compute_p50_ms: float | None = None
    driver: dict = field(default_factory=dict)
    timeline: list = field(default_factory=list)
    node_alive: bool = True

    def to_dict(self) -> dict:
        """Return the result as JSON-ready builtins (without the timeline)."""
        out = asdict(self)
        out.pop('timeline')
        return out

    def table(self) -> str:
        """Return the timeline and the summary as a text table."""
        lines = [f'awp_node soak: {self.robot}, {self.rate_hz:g} Hz for {self.duration_s:g} s '
                 f'(qos_depth {self.qos_depth})',
                 f'{"t [s]":>7} {"reports/s":>10} {"latency p50 [ms]":>17} '
                 f'{"latency p99 [ms]":>17} {"node CPU [%]":>13} {"node RSS [MB]":>14}']
        for row in self.timeline:
            lines.append(f'{row["t"]:7.1f} {row["reports_per_s"]:10.0f} '
                         f'{row["latency_p50_ms"]:17.1f} {row["latency_p99_ms"]:17.1f} '
                         f'{row["cpu_percent"]:13.0f} {row["rss_mb"]:14.1f}')
        lat, cpu, rss = self.latency_ms, self.cpu_percent, self.rss_mb
        warm = self.latency_after_warmup_ms
        lines += [
            f'sent {self.sent} joint states at {self.sent_rate_hz:.1f} Hz; reports '
            f'{self.reports}; missing {self.missing}; duplicates {self.duplicates}; '
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
            f'last report {self.drain_s:.2f} s after the last joint state; the node counted '
            f'{self.node_missing_from_sequence} joint states missing from the sequence and '
            f'{self.node_lost_total} lost (DDS events); its compute time p50 '
            f'{self.node_compute_p50_ms} ms',
        ]
        return '\n'.join(lines)


def _percentiles(x: np.ndarray) -> dict:
    if x.size == 0:
        return {}
    p50, p99 = np.percentile(x, [50, 99])
    return {'p50': float(p50), 'p99': float(p99), 'max': float(x.max())}


def run_soak(rate_hz: float, duration_s: float, *, robot: str = 'hyq',
             warmup_s: float | None = None, qos_depth: int | None = None,
             namespace: str = '/soak', env: dict[str, str] | None = None,
             contacts_rate_hz: float = 100.0, sample_period_s: float = 1.0,
             drain_timeout_s: float | None = None, stall_timeout_s: float = 20.0,
             params: dict | None = None, timeline_step_s: float | None = None
             ) -> SoakResult:
    """Run one soak (see the module docstring) and return what it measured.

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
    ns = namespace.rstrip('/')
    node_params = {'qos_depth': qos_depth, **(params or {})}
    proc = start_node(env=env, robot=robot, namespace=ns, params=node_params)
    probe = Probe(domain, 'awp_soak_probe')
    n_max = int(rate_hz * duration_s) + 10
    stamps = np.zeros(n_max + 1000, dtype=np.int64)
    recv = np.zeros_like(stamps)
    status = np.zeros(stamps.size, dtype=np.int8)
    count = [0]

    def on_report(msg) -> None:
        i = count[0]
        if i < stamps.size:
            stamps[i] = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            recv[i] = time.time_ns()
            status[i] = msg.status
        count[0] = i + 1

    probe.subscribe(FeasibilityReport, f'{ns}/awp_node/report', on_report,
                    depth=max(qos_depth, n_max + 1000))    # never the bottleneck
    diag = probe.subscribe(DiagnosticArray, '/diagnostics', depth=100)
    monitor = None
    stamps_file = tempfile.NamedTemporaryFile(prefix='awp_soak_', suffix='.npy', delete=False)
    stamps_file.close()
    try:
        wait_until(lambda: probe.node.count_publishers(f'{ns}/awp_node/report') > 0, 60.0,
                   'awp_node to appear')
        time.sleep(0.5)
        monitor = ProcessMonitor(proc.pid, sample_period_s)
        cmd = driver_command(rate_hz, duration_s, robot=robot, namespace=ns,
                             stamps_out=stamps_file.name, contacts_rate_hz=contacts_rate_hz,
                             depth=n_max + 1000)
        driver = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, text=True)
        out, _ = driver.communicate(timeout=duration_s + 180)
        t_end = time.monotonic()
        lines = [ln for ln in out.splitlines() if ln.startswith('{')]
        if driver.returncode != 0 or not lines:
            raise RuntimeError(f'the driver failed (exit {driver.returncode}): {out[-2000:]}')
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
    finally:
        if monitor is not None:
            monitor.stop()
        result.node_alive = proc.poll() is None
        probe.close()
        stop_node(proc)
        Path(stamps_file.name).unlink(missing_ok=True)
    n = min(count[0], stamps.size)
    got, rcv, st = stamps[:n], recv[:n], status[:n]
    result.reports = int(count[0])
    uniq = np.unique(got)
    result.duplicates = int(n - uniq.size)
    result.missing = int(np.setdiff1d(sent, uniq).size)
    result.unexpected = int(np.setdiff1d(uniq, sent).size)
    names = ('ok', 'warning', 'invalid_input', 'stale_input', 'error')
    result.status_counts = {names[k]: int(c) for k, c in enumerate(np.bincount(st, minlength=5))
                            if c}
    latency = (rcv - got) * 1e-6
    result.latency_ms = _percentiles(latency)
    if not sent.size:
        return result
    result.drain_s = max(0.0, (int(rcv.max()) - int(sent[-1])) * 1e-9) if n else 0.0
    warm = got >= int(sent[0]) + int(warmup_s * 1e9)
    result.latency_after_warmup_ms = _percentiles(latency[warm])
    # The drive window on the monitor's clock (monotonic), from the first and last stamps.
    offset = time.time_ns() * 1e-9 - time.monotonic()
    t_start, t_stop = sent[0] * 1e-9 - offset, sent[-1] * 1e-9 - offset
    samples = monitor.array() if monitor else np.zeros((0, 3))
    _usage(result, samples, t_start, t_stop, warmup_s)
    _timeline(result, samples, t_start, int(sent[0]), rcv, latency,
              timeline_step_s or max(duration_s / 12, sample_period_s))
    _node_diagnostics(result, diag, probe.lock)
    return result


def _usage(result: SoakResult, s: np.ndarray, t_start: float, t_end: float,
           warmup_s: float) -> None:
    """Fill CPU and RSS figures from the monitor's samples (drive window only)."""
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


def _timeline(result: SoakResult, s: np.ndarray, t_start: float, wall0_ns: int,
              rcv: np.ndarray, latency: np.ndarray, step: float) -> None:
    """Fill the table rows, one per ``step`` [s] from the drive's start to the last report.

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


def _node_diagnostics(result: SoakResult, diag: list, lock: threading.Lock) -> None:
    """Take the node's own 'lost' count and compute-time p50 from its last diagnostics."""
    with lock:
        arrays = list(diag)
    lost, gaps, p50 = None, None, []
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
    result.node_lost_total = lost
    result.node_missing_from_sequence = gaps
    result.node_compute_p50_ms = round(float(np.median(p50)), 3) if p50 else None


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
    parser.add_argument('--drive', action='store_true', help=argparse.SUPPRESS)
    parser.add_argument('--stamps-out', help=argparse.SUPPRESS)
    parser.add_argument('--depth', type=int, default=100000, help=argparse.SUPPRESS)
    parser.add_argument('--topics', default='both', help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.drive:
        summary = drive(rate_hz=args.rate, duration_s=args.duration, robot=args.robot,
                        namespace='' if args.namespace == '/' else args.namespace,
                        stamps_path=args.stamps_out, contacts_rate_hz=args.contacts_rate,
                        depth=args.depth, topics=args.topics)
        print(json.dumps(summary), flush=True)
        return 0
    params = dict(p.split(':=', 1) for p in args.param)
    result = run_soak(args.rate, args.duration, robot=args.robot, warmup_s=args.warmup,
                      qos_depth=args.qos_depth, namespace=args.namespace,
                      contacts_rate_hz=args.contacts_rate, sample_period_s=args.sample_period,
                      params=params)
    print(result.table())
    print(json.dumps(result.to_dict()))
    ok = result.node_alive and result.missing == 0 and result.duplicates == 0
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
