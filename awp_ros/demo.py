"""``awp_demo``: the main job. awp_node on HyQ, fed a recorded crawl/trot, margins live.

Steps: start ``awp_node`` as its own process (``--params-file config/<robot>.yaml``); play
the default bag (``config/hyq_gait.mcap``: 500 Hz joint states and contacts, 100 Hz IMU;
a static crawl then a trot) onto DDS at the recorded pace; print a table (time, stance
feet, FWP margin, feasibility) while the node answers; record the inputs as the node saw
them and every output of the node into ``OUT_DIR/awp_demo.mcap`` (Foxglove and RViz open
it); on exit (end of the bag or Ctrl-C) plot the AWP / FWP / FWS margins over time with the
stance phases shaded into ``OUT_DIR/awp_demo_margins.png``, and print both paths.

Log times in the output bag are bag time: the first input message's log time plus the
wall time since playback started (times ``--rate``), for inputs and outputs alike.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
import os
from pathlib import Path
import shlex
import shutil
import signal
import subprocess
import sys
import threading
import time

import numpy as np

from awp_ros.bag_io import BagMessage, BagWriter, bag_info, default_bag_path, INPUT_TOPICS
from awp_ros.errors import AwpError, BagError, ConfigError
from awp_ros.replay import play_bag, summarize_reports

__all__ = ['main', 'MarginSeries', 'plot_margins', 'format_row', 'TABLE_HEADER']

PROG = 'awp_demo'
REPORT_TYPE = 'awp_ros_msgs/msg/FeasibilityReport'
STANCE_COLOURS = {4: '#e6f2e6', 3: '#fff2c2', 2: '#fadcd7', 1: '#f4c7c3', 0: '#dddddd'}
STANCE_LABELS = {4: '4 feet down', 3: '3 feet (crawl swing)', 2: '2 feet (trot)',
                 1: '1 foot', 0: 'no contact'}
TABLE_HEADER = f'{"t [s]":>7}  {"stance":<12}  {"FWP margin":>10}  {"in FWP":<6}  ' \
               f'{"off hull":>8}  feasible (FWS)'


# -- the table --------------------------------------------------------------------------------


def _stamp_ns(stamp) -> int:
    return int(stamp.sec) * 10**9 + int(stamp.nanosec)


def format_row(report, feet, t0_ns: int) -> str:
    """Return one table row: time [s] since ``t0_ns``, stance (``--`` = swing), FWP margin
    [N, N.m], FWP membership, distance off the FWP hull, and the report's ``feasible``."""
    t = (_stamp_ns(report.header.stamp) - t0_ns) * 1e-9
    stance = ' '.join(f.split('_')[0].upper()[:2] if f in report.stance_feet else '--'
                      for f in feet)
    if int(report.status) > 1:
        return f'{t:7.2f}  {stance:<12}  {"-":>10}  {"-":<6}  {"-":>8}  ' \
               f'not evaluated: {report.status_message}'
    return (f'{t:7.2f}  {stance:<12}  {report.fwp_margin:10.2f}  '
            f'{"yes" if report.fwp_feasible else "no":<6}  '
            f'{report.fwp_affine_residual:8.2f}  {"yes" if report.feasible else "no"}')


# -- the plot ---------------------------------------------------------------------------------


@dataclass
class MarginSeries:
    """Per-report time series: ``t`` [s] from the first report, margins [N, N.m] (NaN when
    not evaluated; ``fws`` NaN also where it was not computed for that very cycle)."""

    feet: tuple[str, ...]
    t: np.ndarray
    stance: np.ndarray
    awp: np.ndarray
    fwp: np.ndarray
    fws: np.ndarray
    fwp_residual: np.ndarray
    fwp_feasible: np.ndarray
    valid: np.ndarray

    @classmethod
    def from_reports(cls, reports, feet) -> MarginSeries:
        """Build from ``FeasibilityReport`` messages (rclpy or rosbags objects)."""
        reports = list(reports)
        feet = tuple(feet)
        stamp = np.array([_stamp_ns(r.header.stamp) for r in reports], dtype=np.int64)
        fws_stamp = np.array([_stamp_ns(r.fws_stamp) for r in reports], dtype=np.int64)
        t = (stamp - stamp[0]) * 1e-9 if reports else np.zeros(0)
        stance = np.array([[f in r.stance_feet for f in feet] for r in reports],
                          dtype=bool).reshape(len(reports), len(feet))
        valid = np.array([int(r.status) <= 1 for r in reports], dtype=bool)

        def values(name):
            x = np.array([getattr(r, name) for r in reports], dtype=float)
            x[~valid] = np.nan
            return x

        fws = np.where(fws_stamp == stamp, values('fws_margin'), np.nan)
        fwp_in = np.array([bool(r.fwp_feasible) for r in reports], dtype=bool)
        return cls(feet, t, stance, values('awp_margin'), values('fwp_margin'), fws,
                   values('fwp_affine_residual'), fwp_in & valid, valid)


def _runs(values: np.ndarray):
    """Yield ``(start, stop, value)`` of each run of equal values."""
    if values.size == 0:
        return
    edges = np.flatnonzero(values[1:] != values[:-1]) + 1
    for a, b in zip(np.r_[0, edges], np.r_[edges, values.size]):
        yield int(a), int(b), values[a]


def _caption(s: MarginSeries, count: np.ndarray) -> str:
    """Return 'outside the FWP: n of N cycles (k with 2 feet down, ...)'."""
    out = ~s.fwp_feasible & s.valid
    parts = [f'{int((out & (count == c)).sum())} with {c} feet down'
             for c in sorted(set(count[out].tolist()), reverse=True)]
    text = f'outside the FWP: {int(out.sum())} of {s.t.size} cycles'
    if parts:
        text += ' (' + ', '.join(parts) + ')'
    invalid = int((~s.valid).sum())
    return text + (f'; {invalid} not evaluated' if invalid else '')


def plot_margins(series: MarginSeries, path, *, title: str = '') -> Path:
    """Write the margins PNG and return its path.

    Top: AWP and FWP margins (and the FWS margin where computed) [N, N.m], measured inside
    each set's affine hull. Middle: distance of the wrench from the FWP's affine hull (non
    zero with 2 stance feet when the CoM is off the line between them), with the cycles
    outside the FWP marked. Bottom: which feet are in stance. Background: number of stance
    feet (4 green, 3 yellow, 2 red).
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    s = series
    dt = float(np.median(np.diff(s.t))) if s.t.size > 1 else 0.0
    fig, axes = plt.subplots(3, 1, figsize=(11, 7.5), sharex=True,
                             gridspec_kw={'height_ratios': [3.2, 1.4, 1.2]})
    ax, ax_res, ax_gait = axes
    count = s.stance.sum(axis=1)
    for a in axes:
        for i0, i1, c in _runs(count):
            a.axvspan(s.t[i0], s.t[i1 - 1] + dt, color=STANCE_COLOURS.get(int(c), '#eeeeee'),
                      lw=0, zorder=0)
    ax.plot(s.t, s.awp, color='#1f77b4', lw=1.4, label='AWP margin')
    ax.plot(s.t, s.fwp, color='#d95f02', lw=1.4, label='FWP margin')
    if np.isfinite(s.fws).any():
        ax.plot(s.t, s.fws, '.', color='#1b9e77', ms=3, label='FWS margin (when computed)')
    ax.axhline(0.0, color='k', lw=0.8)
    top = np.nanmax(np.r_[s.awp, s.fwp, 1.0]) if s.t.size else 1.0
    bottom = min(0.0, np.nanmin(np.r_[s.awp, s.fwp, 0.0])) if s.t.size else 0.0
    ax.set_ylim(bottom - 0.05 * (top - bottom), top + 0.3 * (top - bottom))
    ax.set_ylabel('margin [N, N·m]\n(inside the affine hull)')
    handles, _ = ax.get_legend_handles_labels()
    handles += [Patch(color=STANCE_COLOURS[c], label=STANCE_LABELS[c])
                for c in sorted(set(count.tolist()), reverse=True)]
    ax.legend(handles=handles, loc='upper center', fontsize=8, ncol=3, framealpha=0.95)
    ax.set_title((title or 'Feasibility margins of the gravito-inertial wrench') + '\n'
                 + _caption(s, count), fontsize=10)
    ax_res.plot(s.t, s.fwp_residual, color='#7b3294', lw=1.2,
                label='distance of the wrench from the FWP affine hull')
    out = ~s.fwp_feasible & s.valid
    peak = max(1.0, float(np.nanmax(np.r_[s.fwp_residual, 1.0])))
    spans = [(s.t[i0], s.t[i1 - 1] + dt - s.t[i0]) for i0, i1, v in _runs(out) if v]
    ax_res.broken_barh(spans, (-0.1 * peak, 0.08 * peak), color='#d62728', lw=0)
    ax_res.set_ylim(-0.12 * peak, 1.45 * peak)
    ax_res.set_ylabel('off hull\n[N, N·m]')
    handles, _ = ax_res.get_legend_handles_labels()
    handles.append(Patch(color='#d62728', label='outside the FWP'))
    ax_res.legend(handles=handles, loc='upper center', fontsize=8, ncol=2, framealpha=0.95)
    for k in range(len(s.feet)):
        spans = [(s.t[i0], s.t[i1 - 1] + dt - s.t[i0])
                 for i0, i1, down in _runs(s.stance[:, k]) if down]
        ax_gait.broken_barh(spans, (k - 0.35, 0.7), color='#444444')
    ax_gait.set_yticks(range(len(s.feet)),
                       [f.split('_')[0].upper() for f in s.feet])
    ax_gait.set_ylim(len(s.feet) - 0.5, -0.5)
    ax_gait.set_ylabel('stance')
    ax_gait.set_xlabel('time [s] (joint-state stamps, from the first)')
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


# -- recording the node's outputs -------------------------------------------------------------


class _Recorder:
    """Subscribe (serialised) to the inputs and the node's outputs, write them to a bag."""

    def __init__(self, node, writer: BagWriter, *, rate: float, depth: int) -> None:
        self.node = node
        self.writer = writer
        self.rate = rate
        self.depth = depth
        self.lock = threading.Lock()
        self.subs: dict = {}
        self.reports: list = []
        self.t0_bag: int | None = None
        self.t0_wall: float | None = None
        self.report_topic = ''

    def start_clock(self, t0_bag: int) -> None:
        """Anchor log times: now (wall) is bag time ``t0_bag`` [ns]."""
        self.t0_bag, self.t0_wall = t0_bag, time.monotonic()

    def subscribe(self, topic: str, msgtype: str) -> None:
        from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile,
                               ReliabilityPolicy)
        from awp_ros.replay import message_class

        if topic in self.subs:
            return
        infos = self.node.get_publishers_info_by_topic(topic)
        best_effort = any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
                          for i in infos)
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=self.depth,
                         reliability=(ReliabilityPolicy.BEST_EFFORT if best_effort
                                      else ReliabilityPolicy.RELIABLE),
                         durability=DurabilityPolicy.VOLATILE)
        cls = message_class(msgtype)
        is_report = msgtype == REPORT_TYPE
        if is_report:
            self.report_topic = topic

        def callback(data: bytes, topic=topic, msgtype=msgtype, cls=cls) -> None:
            now = time.monotonic()
            with self.lock:
                if self.t0_wall is None:
                    return
                stamp = self.t0_bag + int((now - self.t0_wall) * self.rate * 1e9)
                self.writer.write(BagMessage(topic, msgtype, stamp, bytes(data)))
                if is_report:
                    from rclpy.serialization import deserialize_message
                    self.reports.append(deserialize_message(data, cls))

        self.subs[topic] = self.node.create_subscription(cls, topic, callback, qos, raw=True)


def _discover_outputs(node, node_name: str, timeout_s: float, proc) -> dict[str, str]:
    """Wait for the node's report publisher; return its output topics (topic -> type)."""
    prefix = f'/{node_name}/'
    deadline = time.monotonic() + timeout_s
    found: dict[str, str] = {}
    settle = None
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            break
        found = {name: types[0] for name, types in node.get_topic_names_and_types()
                 if (name.startswith(prefix) or name == '/diagnostics') and types}
        if any(t == REPORT_TYPE for t in found.values()):
            settle = settle or time.monotonic()
            if time.monotonic() - settle > 0.5:   # let the remaining publishers appear
                return found
        time.sleep(0.05)
    return {}


# -- main -------------------------------------------------------------------------------------


def _params_file(robot: str) -> Path:
    from awp_ros.robot_config import config_dirs

    path = Path(robot)
    if path.suffix in ('.yaml', '.yml'):
        if not path.is_file():
            raise ConfigError(f'params file {robot!r} does not exist')
        return path
    for d in config_dirs():
        if (d / f'{robot}.yaml').is_file():
            return d / f'{robot}.yaml'
    raise ConfigError(f'no config/{robot}.yaml found in {[str(d) for d in config_dirs()]}')


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG, description='Run awp_node on a robot, play a bag into it, print the '
        'margins live, and write the outputs as a bag and a PNG plot.')
    p.add_argument('--bag', help='input bag (default: the packaged config/hyq_gait.mcap)')
    p.add_argument('--robot', default='hyq', help='robot config name or parameters YAML '
                   '(default: %(default)s)')
    p.add_argument('-o', '--out-dir', default='out', help='output folder (default: ./out)')
    p.add_argument('--duration', type=float, default=None,
                   help='play only the first DURATION seconds of the bag')
    p.add_argument('--rate', type=float, default=1.0, help='playback speed factor')
    p.add_argument('--table-period', type=float, default=0.2,
                   help='bag seconds between table rows (default: %(default)s)')
    p.add_argument('--node-name', default='awp_node',
                   help='node name; outputs on /NODE_NAME/... (default: %(default)s)')
    p.add_argument('--node-command', default=None,
                   help='command starting the node, e.g. "ros2 run awp_ros awp_node" '
                        '(default: this Python with -m awp_ros.node); --ros-args '
                        '--params-file and the node name are appended')
    p.add_argument('--startup-timeout', type=float, default=60.0,
                   help='seconds to wait for awp_node to come up')
    p.add_argument('--drain-timeout', type=float, default=60.0,
                   help='seconds to wait, after playing, for the remaining reports')
    p.add_argument('--record-all', action='store_true',
                   help='also record ~/awp, ~/fwp (about 35 kB each per cycle) and '
                        '~/leg_polytopes (4 kB per cycle); the node then builds them too')
    p.add_argument('--quiet', action='store_true', help='no table')
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the demo; return 0 on success, 2 on bad input, 1 if the node fails."""
    args = _parser().parse_args(argv)
    # Keep the demo's DDS traffic on this machine unless the user chose otherwise.
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    try:
        return _run(args)
    except _NodeFailed as exc:
        sys.stderr.write(f'{PROG}: error: {exc}\n')
        return 1
    except AwpError as exc:
        sys.stderr.write(f'{PROG}: error: {exc}\n')
        return 2
    except KeyboardInterrupt:
        sys.stderr.write(f'{PROG}: interrupted before playing; the node was stopped\n')
        return 130


def _run(args) -> int:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from awp_ros.robot_config import load_config

    if not args.rate > 0:
        raise BagError(f'--rate must be > 0, got {args.rate!r}')
    bag = Path(args.bag) if args.bag else default_bag_path()
    info = bag_info(bag)
    params = _params_file(args.robot)
    feet = load_config(params).feet
    inputs = {topic: msgtype for topic, msgtype in INPUT_TOPICS.values()
              if topic in info.topics}
    if '/joint_states' not in inputs:
        raise BagError(f'bag {str(bag)!r} has no /joint_states topic; its topics are '
                       f'{sorted(info.topics)}')
    out_dir = Path(args.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    out_bag = out_dir / 'awp_demo.mcap'
    out_png = out_dir / 'awp_demo_margins.png'
    for old in (out_bag, out_png):
        if old.is_dir():
            shutil.rmtree(old)
        elif old.exists():
            old.unlink()
    log = open(out_dir / 'awp_node.log', 'wb')
    base = shlex.split(args.node_command) if args.node_command else [sys.executable, '-m',
                                                                        'awp_ros.node']
    cmd = base + ['--ros-args', '--params-file', str(params), '-r',
                  f'__node:={args.node_name}']
    if '/imu' in inputs:
        cmd += ['-p', 'use_imu:=true']       # the bag's IMU gives the base orientation
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT,
                            start_new_session=True)
    out = sys.stdout
    say = (lambda text: None) if args.quiet else (lambda text: (out.write(text + '\n'),
                                                                 out.flush()))
    say(f'{PROG}: awp_node (pid {proc.pid}) on {params.name}; input {bag} '
        f'({info.duration_s:.1f} s, {info.topics["/joint_states"].count} joint states)')
    rclpy.init()
    node = rclpy.create_node('awp_demo_recorder')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    interrupted = False
    try:
        outputs = _discover_outputs(node, args.node_name, args.startup_timeout, proc)
        if not outputs:
            raise _NodeFailed(proc, out_dir / 'awp_node.log')
        with BagWriter(out_bag, compress=True) as writer:
            rec = _Recorder(node, writer, rate=args.rate, depth=2000)
            skip = () if args.record_all else tuple(
                f'/{args.node_name}/{name}' for name in ('awp', 'fwp', 'leg_polytopes'))
            for topic, msgtype in {**inputs, **outputs}.items():
                if topic not in skip:
                    rec.subscribe(topic, msgtype)
            spinner.start()
            table = _Table(rec, feet, info.start_ns, args.table_period, say)
            stop = threading.Event()
            printer = threading.Thread(target=table.run, args=(stop,), daemon=True)
            say(TABLE_HEADER)
            printer.start()
            rec.start_clock(info.start_ns)
            expected = _joint_states_in(bag, args.duration, info)
            try:
                play_bag(bag, rate=args.rate, topics=list(inputs), wait_s=10.0,
                         wait_topics=['/joint_states'], duration_s=args.duration,
                         progress=False)
                deadline = time.monotonic() + args.drain_timeout
                while len(rec.reports) < expected and time.monotonic() < deadline \
                        and proc.poll() is None:
                    time.sleep(0.05)
            except KeyboardInterrupt:
                interrupted = True
            stop.set()
            printer.join(timeout=2.0)
            table.flush()
            executor.shutdown(timeout_sec=1.0)
            with rec.lock:
                rec.t0_wall = None        # stop writing
            reports = list(rec.reports)
    finally:
        _stop(proc)
        log.close()
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    summary = summarize_reports(reports)
    lost = expected - len(reports)
    series = MarginSeries.from_reports(reports, feet)
    title = f'awp_node on {params.stem}: {bag.name}' + (' (interrupted)' if interrupted
                                                         else '')
    plot_margins(series, out_png, title=title)
    print(summary.to_text())
    if lost > 0 and not interrupted:
        print(f'{lost} of {expected} joint states got no report in time: the node could not '
              'keep up on this machine (try --rate 0.5)')
    print(f'output bag: {out_bag}  ({out_bag.stat().st_size / 1e6:.1f} MB; open in '
          f'Foxglove, or ros2 bag play it for RViz)')
    print(f'margin plot: {out_png}')
    if not reports:
        sys.stderr.write(f'{PROG}: no report received; see {out_dir / "awp_node.log"}\n')
        return 1
    return 130 if interrupted else 0


def _joint_states_in(bag, duration: float | None, info) -> int:
    if duration is None:
        return info.topics['/joint_states'].count
    from awp_ros.bag_io import read_bag

    stop = info.start_ns + int(duration * 1e9)
    return sum(1 for m in read_bag(bag, topics=['/joint_states']) if m.timestamp < stop)


class _Table:
    """Print a table row every ``period`` [s] of report stamps."""

    def __init__(self, rec: _Recorder, feet, t0_ns: int, period: float, say) -> None:
        self.rec, self.feet, self.t0_ns, self.say = rec, feet, t0_ns, say
        self.period_ns = int(period * 1e9)
        self.next_ns = t0_ns
        self.seen = 0

    def flush(self) -> None:
        with self.rec.lock:
            new = self.rec.reports[self.seen:]
        self.seen += len(new)
        for r in new:
            stamp = _stamp_ns(r.header.stamp)
            if stamp >= self.next_ns:
                self.say(format_row(r, self.feet, self.t0_ns))
                self.next_ns = stamp - (stamp - self.t0_ns) % self.period_ns + self.period_ns

    def run(self, stop: threading.Event) -> None:
        while not stop.wait(0.05):
            self.flush()


class _NodeFailed(AwpError):
    def __init__(self, proc, log_path: Path) -> None:
        code = proc.poll()
        tail = ''
        try:
            tail = log_path.read_text(errors='replace')[-2000:]
        except OSError:
            pass
        state = f'exited with code {code}' if code is not None else 'published no report'
        super().__init__(f'awp_node {state}; its log ({log_path}):\n{tail}')


def _stop(proc) -> None:
    """Stop the node process (SIGINT, then SIGTERM, then SIGKILL)."""
    for sig, wait in ((signal.SIGINT, 5.0), (signal.SIGTERM, 3.0), (signal.SIGKILL, 3.0)):
        if proc.poll() is not None:
            return
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            return
        try:
            proc.wait(timeout=wait)
        except subprocess.TimeoutExpired:
            continue


if __name__ == '__main__':
    sys.exit(main())
