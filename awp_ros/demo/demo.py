"""
``awp_demo``: the main job. awp_node on HyQ, fed a recorded crawl/trot, margins live.

Steps: start ``awp_node`` as its own process (``--params-file config/<robot>.yaml``); play
the default bag (``config/hyq_gait.mcap``: 500 Hz joint states and contacts, 100 Hz IMU;
a static crawl then a trot) onto DDS at the recorded pace; print a table (time, stance
feet, FWP margin, feasibility) while the node answers; record the inputs as the node saw
them and every output of the node into ``OUT_DIR/awp_demo.mcap`` (Foxglove and RViz open
it); on exit (end of the bag or Ctrl-C) plot the AWP / FWP / FWS margins over time with the
stance phases shaded into ``OUT_DIR/awp_demo_margins.png``, and print both paths.

Log times in the output bag are bag time: the first input message's log time plus the
wall time since playback started (times ``--rate``), for inputs and outputs alike.

The pieces: :mod:`awp_ros.demo.recorder` (recording the node), :mod:`awp_ros.demo.table`
(the live table), :mod:`awp_ros.demo.plot` (the PNG), :mod:`awp_ros.bags.player` (playing
the bag). Their public names used to live here and are still importable from here.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
import shlex
import sys
import threading
import time

from awp_ros.bags.message_types import INPUT_TOPICS
from awp_ros.bags.player import play_bag
from awp_ros.bags.reader import bag_info, read_bag
from awp_ros.bags.summary import summarize_reports
from awp_ros.bags.writer import BagWriter, remove_path
from awp_ros.cli.support import run_main
from awp_ros.demo.plot import MarginSeries, plot_margins
from awp_ros.demo.recorder import discover_outputs, Recorder
from awp_ros.demo.table import ReportTable, TABLE_HEADER
from awp_ros.errors import AwpError, BagError
from awp_ros.gait.bag import default_bag_path
from awp_ros.node.launcher import start_node, stop_node
from awp_ros.robot.config import find_parameters_file, load_config

__all__ = ['main']

PROG = 'awp_demo'


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
                        '(default: the awp_node script of this Python); --ros-args '
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
    return run_main(PROG, lambda: _run(args), failures=(_NodeFailed,),
                    interrupted='interrupted before playing; the node was stopped')


def _run(args) -> int:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    if not args.rate > 0:
        raise BagError(f'--rate must be > 0, got {args.rate!r}')
    bag = Path(args.bag) if args.bag else default_bag_path()
    info = bag_info(bag)
    params = find_parameters_file(args.robot)
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
        remove_path(old)
    extra = ['-p', 'use_imu:=true'] if '/imu' in inputs else []  # the bag's IMU: base motion
    proc = start_node(robot=None, params_file=params, ros_args=(
        '-r', f'__node:={args.node_name}', *extra), log_path=out_dir / 'awp_node.log',
        command=shlex.split(args.node_command) if args.node_command else None,
        new_session=True)
    out = sys.stdout
    say = (lambda text: None) if args.quiet else (
        lambda text: (out.write(text + '\n'), out.flush()))
    say(f'{PROG}: awp_node (pid {proc.pid}) on {params.name}; input {bag} '
        f'({info.duration_s:.1f} s, {info.topics["/joint_states"].count} joint states)')
    rclpy.init()
    node = rclpy.create_node('awp_demo_recorder')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    interrupted = False
    try:
        outputs = discover_outputs(node, args.node_name, args.startup_timeout, proc)
        if not outputs:
            raise _NodeFailed(proc, out_dir / 'awp_node.log')
        with BagWriter(out_bag, compress=True) as writer:
            rec = Recorder(node, writer, rate=args.rate, depth=2000)
            skip = () if args.record_all else tuple(
                f'/{args.node_name}/{name}' for name in ('awp', 'fwp', 'leg_polytopes'))
            for topic, msgtype in {**inputs, **outputs}.items():
                if topic not in skip:
                    rec.subscribe(topic, msgtype)
            spinner.start()
            table = ReportTable(rec, feet, info.start_ns, args.table_period, say)
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
        stop_node(proc, timeout_s=5.0)
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
    stop = info.start_ns + int(duration * 1e9)
    return sum(1 for m in read_bag(bag, topics=['/joint_states']) if m.timestamp < stop)


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


if __name__ == '__main__':
    sys.exit(main())
