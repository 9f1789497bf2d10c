"""
``awp_demo``: the main job. awp_node on HyQ, fed a recorded crawl/trot, margins live.

Steps: start ``awp_node`` as its own process (``--params-file config/<robot>.yaml``); play
the default bag (``config/hyq_gait.mcap``: 500 Hz joint states, contacts and IMU; a
static crawl, an intended infeasible lurch, then a trot) onto DDS at the recorded pace;
print a table (time, stance feet, FWP margin, feasibility, and beside them those of the
quasi-static wrench: the same
pipeline run offline over the bag, while the node starts) while the node answers, then
how many joint states each judges infeasible inside and outside the bag's intended
infeasible window (:mod:`awp_ros.demo.table`); record the inputs as the node saw
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
from awp_ros.demo.regions_plot import demo_regions_plot
from awp_ros.demo.table import (comparison_lines, intended_windows, QuasiStatic, ReportTable,
                                TABLE_HEADER, TABLE_LEGEND)
from awp_ros.errors import AwpError, BagError, ConfigError
from awp_ros.gait.bag import default_bag_path
from awp_ros.node.dds import use_deep_queues
from awp_ros.node.launcher import start_node, stop_node
from awp_ros.robot.config import find_parameters_file, load_config, srdf_standing_posture

__all__ = ['main']

PROG = 'awp_demo'
#: Report statuses of an evaluated joint state (FeasibilityReport STATUS_OK, STATUS_WARNING).
_EVALUATED = (0, 1)


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
    params, feet, bag = _robot_and_bag(args, say=lambda text: None if args.quiet else (
        sys.stdout.write(text + '\n'), sys.stdout.flush()))
    info = bag_info(bag)
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
    # The player's publishers and the recorder's subscriptions hold the whole bag: in this one
    # process the recorder may fall far behind the player (a CI run on a slow machine recorded
    # 4748 of 5801 joint states with 1000/2000-deep queues); readers deeper than Fast DDS's
    # default 5000 samples need its profile.
    depth = max(2000, max(t.count for t in info.topics.values()) + 1000)
    use_deep_queues()
    rclpy.init()
    node = rclpy.create_node('awp_demo_recorder')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    interrupted = False
    try:
        # While the node starts: the same pipeline offline with motion=quasi_static (no
        # accelerations), beside the node's measured-wrench margins.
        say('quasi-static reference: the same pipeline offline over the bag, while the node '
            'starts ...')
        quasi = QuasiStatic.from_bag(bag, params, overrides={'use_imu': '/imu' in inputs},
                                     duration_s=args.duration)
        windows = intended_windows(bag)
        say(f'quasi-static reference: {len(quasi.reports)} joint states through the same '
            f'pipeline offline in {quasi.wall_s:.1f} s')
        outputs = discover_outputs(node, args.node_name, args.startup_timeout, proc)
        if not outputs:
            raise _NodeFailed(proc, out_dir / 'awp_node.log')
        with BagWriter(out_bag, compress=True) as writer:
            rec = Recorder(node, writer, rate=args.rate, depth=depth)
            skip = () if args.record_all else tuple(
                f'/{args.node_name}/{name}' for name in ('awp', 'fwp', 'leg_polytopes'))
            for topic, msgtype in {**inputs, **outputs}.items():
                if topic not in skip:
                    rec.subscribe(topic, msgtype)
            spinner.start()
            table = ReportTable(rec, feet, info.start_ns, args.table_period, say,
                                quasi_static=quasi, windows=windows)
            stop = threading.Event()
            printer = threading.Thread(target=table.run, args=(stop,), daemon=True)
            say(TABLE_LEGEND)
            say(TABLE_HEADER)
            printer.start()
            rec.start_clock(info.start_ns)
            expected = _joint_states_in(bag, args.duration, info)
            try:
                play_bag(bag, rate=args.rate, topics=list(inputs), wait_s=10.0,
                         wait_topics=['/joint_states'], duration_s=args.duration,
                         progress=False, qos_depth=depth)
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
    series = MarginSeries.from_reports(reports, feet, quasi, windows)
    title = f'awp_node on {params.stem}: {bag.name}' + (' (interrupted)' if interrupted
                                                        else '')
    plot_margins(series, out_png, title=title)
    demo_regions_plot(out_bag, out_dir / 'awp_demo_regions.png', bag, args.node_name, title=title)
    print(summary.to_text())
    print('\n'.join(comparison_lines(reports, quasi, windows, info.start_ns)))
    if lost > 0 and not interrupted:
        print(f'{lost} of {expected} joint states got no report in time: the node could not '
              'keep up on this machine (try --rate 0.5)')
    print(f'output bag: {out_bag}  ({out_bag.stat().st_size / 1e6:.1f} MB; open in '
          f'Foxglove, or ros2 bag play it for RViz)')
    print(f'margin plot: {out_png}')
    if not reports:
        sys.stderr.write(f'{PROG}: no report received; see {out_dir / "awp_node.log"}\n')
        return 1
    if not interrupted and not any(r.status in _EVALUATED for r in reports):
        last = reports[-1].status_message.splitlines()[0][:300] if reports else ''
        sys.stderr.write(f'{PROG}: the node evaluated none of the {len(reports)} joint states '
                         f'(last reason: {last}); see {out_dir / "awp_node.log"}\n')
        return 1
    return 130 if interrupted else 0


def _robot_and_bag(args, say) -> tuple[Path, tuple[str, ...], Path]:
    """
    Return the robot's parameters file, its feet, and the bag to play into its node.

    The robot's model is built first, so that a bad config (unknown foot, joint, key) stops
    the demo in one line before anything starts. ``--bag``: that bag, if its joint states
    and contacts name the robot's joints and feet. Else the packaged default bag when it
    is this robot's (HyQ), or a crawl/lurch/trot bag generated for the robot into
    ``--out-dir`` (``<robot_name>_gait.mcap``, as ``python -m awp_ros.gait --robot``
    writes it; a config without ``standing_posture`` takes the SRDF's ``standing`` state).

    :raises ConfigError: a bad config, a bag of another robot, or a robot the gait
        generator cannot walk (the message says why).
    """
    from awp_ros.robot.model import RobotModel

    params = find_parameters_file(args.robot)
    config = load_config(params)
    model = RobotModel(config)
    if args.bag:
        bag = Path(args.bag)
        mismatch = _bag_mismatch(bag, model)
        if mismatch:
            raise ConfigError(f'bag {str(bag)!r} is not a bag of robot {config.robot_name!r} '
                              f'({params}): {mismatch}; leave --bag out to play a gait '
                              'generated for it')
        return params, config.feet, bag
    bag = default_bag_path()
    if not _bag_mismatch(bag, model):
        return params, config.feet, bag
    return params, config.feet, _generate_bag(config, model, Path(args.out_dir), say)


def _bag_mismatch(bag: Path, model) -> str:
    """Return why a bag's first joint state and contacts do not fit a model, or ''."""
    from awp_ros_msgs.msg import ContactState
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState

    info = bag_info(bag)
    reasons = []
    for topic, mtype in (('/joint_states', JointState), ('/contacts', ContactState)):
        if topic not in info.topics:
            continue
        first = next(iter(read_bag(bag, topics=[topic])), None)
        if first is None:
            continue
        msg = deserialize_message(first.data, mtype)
        if topic == '/joint_states':
            lacking = [j for j in model.joint_names if j not in set(msg.name)]
            if lacking:
                reasons.append(f'its joint states lack the joints {lacking[:6]}'
                               f'{" ..." if len(lacking) > 6 else ""} (they name '
                               f'{list(msg.name)[:6]}{" ..." if len(msg.name) > 6 else ""})')
        else:
            unknown = [f for f in msg.names if f not in model.config.feet]
            if unknown:
                reasons.append(f'its contacts name feet {unknown} (the feet are '
                               f'{list(model.config.feet)})')
    return '; '.join(reasons)


def _generate_bag(config, model, out_dir: Path, say) -> Path:
    """Generate the robot's gait bag into ``out_dir``; ConfigError when it cannot be."""
    from dataclasses import replace

    from awp_ros.gait.bag import DEFAULT_IMU_RATE_HZ, write_gait_bag
    from awp_ros.gait.generator import generate_gait
    from awp_ros.robot.model import resolve_urdf

    name = config.robot_name
    if model.standing_q is None:
        kind, source = resolve_urdf(config.urdf, config.base_dir)
        found = srdf_standing_posture(source, model.joint_names) if kind == 'file' else None
        if found is None:
            raise ConfigError(f'robot {name!r} has no standing_posture, and no SRDF beside '
                              "its URDF has a 'standing' state: the generated gait starts "
                              'from it; add standing_posture to the config, or give --bag')
        config = replace(config, standing_posture=found[0])
        model = None
    out_dir.mkdir(parents=True, exist_ok=True)
    out = out_dir / f'{name}_gait.mcap'
    remove_path(out)
    say(f'{PROG}: generating a crawl/lurch/trot bag for {name!r} (the default bag is of '
        f'HyQ) into {out}')
    try:
        samples = generate_gait(config, model=model)
        write_gait_bag(samples, out, imu_rate_hz=DEFAULT_IMU_RATE_HZ)
    except AwpError as exc:
        raise ConfigError(f'cannot generate a gait bag for robot {name!r}: {exc}; give a bag '
                          'of it with --bag') from exc
    return out


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
