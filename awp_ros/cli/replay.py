"""
``awp_replay``: replay a rosbag2 through the node's pipeline, or play it onto DDS.

::

    awp_replay IN_BAG -o OUT_BAG [-p use_imu=true] [--outputs report markers]
    awp_replay --play IN_BAG [--rate 2.0] [--remap /joint_states:=/robot/joint_states]

Offline (``-o``): the bag's ``joint_states`` / ``contacts`` (/ ``imu``) go through exactly
the pipeline ``awp_node`` runs, with the parameters of ``--params-file`` (default
``config/<robot>.yaml``) and ``-p`` overrides; the outputs land on ``/<node-name>/<output>``
in OUT_BAG (``.mcap`` / ``.db3`` = one file, else a rosbag2 directory), logged at the log
time of the joint state they answer, with the input bag's topics copied. A progress bar
(rate, ETA) goes to stderr, the summary (counts, margin statistics) to stdout.

Live (``--play``): publishes the bag's messages at the recorded pace (``--rate``) for a
running ``awp_node``. Exit status: 0 done, 2 bad bag or arguments (one line on stderr), 1
internal error, 130 interrupted.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys

import yaml

from awp_ros.bags.player import play_bag
from awp_ros.bags.replay import replay_bag
from awp_ros.cli.support import run_main
from awp_ros.robot.config import load_parameters
from awp_ros.ros.cycle import OUTPUTS
from awp_ros.ros.pipeline import Pipeline

__all__ = ['main', 'parse_override']

PROG = 'awp_replay'


def parse_override(text: str) -> tuple[str, object]:
    """
    Parse ``key=value`` or ``key:=value``.

    The value is read as YAML (``true``, ``0.5``, ``[0, 0, 1]``), like ``ros2 run ... -p``.

    :raises argparse.ArgumentTypeError: no ``=``.
    """
    sep = ':=' if ':=' in text else '='
    key, eq, value = text.partition(sep)
    if not eq or not key:
        raise argparse.ArgumentTypeError(f'expected KEY=VALUE, got {text!r}')
    try:
        return key.strip(), yaml.safe_load(value)
    except yaml.YAMLError:
        return key.strip(), value


def _remap(text: str) -> tuple[str, str]:
    src, sep, dst = text.partition(':=')
    if not sep or not src or not dst:
        raise argparse.ArgumentTypeError(f'expected FROM:=TO, got {text!r}')
    return src, dst


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG, description='Replay a rosbag2 (mcap or sqlite3) through the awp_node '
        'pipeline into a new bag, or play it onto live DDS with --play.')
    p.add_argument('in_bag', metavar='IN_BAG', help='input bag: rosbag2 directory or '
                   '.mcap / .db3 file')
    p.add_argument('-o', '--output', metavar='OUT_BAG',
                   help='output bag (.mcap / .db3 = one file, else a directory)')
    p.add_argument('--play', action='store_true',
                   help='publish IN_BAG onto DDS at the recorded pace instead')
    g = p.add_argument_group('offline replay')
    g.add_argument('--robot', default='hyq', help='robot config name or parameters YAML '
                   'path (default: %(default)s)')
    g.add_argument('--params-file', help='node parameters YAML (default: the --robot file)')
    g.add_argument('-p', '--param', action='append', type=parse_override, default=[],
                   metavar='KEY=VALUE', help='parameter override, e.g. -p use_imu=true '
                   '(repeatable)')
    g.add_argument('--joint-states', default='/joint_states', metavar='TOPIC',
                   help='joint-state topic in IN_BAG (default: %(default)s)')
    g.add_argument('--contacts', default='/contacts', metavar='TOPIC',
                   help='contact-state topic in IN_BAG (default: %(default)s; not read with '
                   '-p contact_source=effort or all)')
    g.add_argument('--imu', default='/imu', metavar='TOPIC',
                   help='imu topic in IN_BAG (default: %(default)s)')
    g.add_argument('--node-name', default='awp_node',
                   help='outputs go to /NODE_NAME/<output> (default: %(default)s)')
    g.add_argument('--outputs', nargs='+', choices=OUTPUTS, default=list(OUTPUTS),
                   metavar='NAME', help=f'outputs to write, of {", ".join(OUTPUTS)} '
                   '(default: all; awp and fwp are ~35 kB a cycle)')
    g.add_argument('--no-inputs', action='store_true',
                   help="do not copy the input bag's topics into OUT_BAG")
    g.add_argument('--storage', choices=['mcap', 'sqlite3'], default='mcap',
                   help='storage of a directory OUT_BAG (default: %(default)s)')
    g.add_argument('--no-compress', action='store_true',
                   help='no zstd chunk compression in OUT_BAG')
    g.add_argument('--json', action='store_true', help='print the summary as JSON')
    g = p.add_argument_group('live playback (--play)')
    g.add_argument('--rate', type=float, default=1.0,
                   help='speed factor; inf = as fast as possible (default: %(default)s)')
    g.add_argument('--remap', action='append', type=_remap, default=[],
                   metavar='FROM:=TO', help='publish bag topic FROM as TO (repeatable)')
    g.add_argument('--topics', nargs='+', help='only these bag topics (default: all)')
    g.add_argument('--wait', type=float, default=0.0, metavar='SECONDS',
                   help='wait up to SECONDS for a subscriber on every topic first')
    g.add_argument('--duration', type=float, default=None, metavar='SECONDS',
                   help='play only the first SECONDS of the bag')
    p.add_argument('-q', '--quiet', action='store_true', help='no progress bar')
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    args = _parser().parse_args(argv)
    return run_main(PROG, lambda: _run(args))


def _run(args) -> int:
    if args.play:
        return _play(args)
    if not args.output:
        sys.stderr.write(f'{PROG}: error: give -o OUT_BAG (offline replay) or --play\n')
        return 2
    return _replay(args)


def _replay(args) -> int:
    params, base_dir = load_parameters(args.params_file or args.robot, dict(args.param))
    pipeline = Pipeline.from_parameters(params, base_dir=base_dir)
    topics = {'joint_states': args.joint_states, 'contacts': args.contacts, 'imu': args.imu}
    summary = replay_bag(args.in_bag, args.output, pipeline=pipeline, topics=topics,
                         node_name=args.node_name, outputs=args.outputs,
                         copy_inputs=not args.no_inputs, storage=args.storage,
                         progress=not args.quiet, compress=not args.no_compress)
    if args.json:
        print(json.dumps(summary.to_dict(), indent=2))
    else:
        print(summary.to_text())
        out = Path(args.output)
        size = sum(f.stat().st_size for f in out.rglob('*')) if out.is_dir() \
            else out.stat().st_size
        print(f'output bag: {out} ({size / 1e6:.1f} MB; topics '
              f'{", ".join(f"/{args.node_name}/{o}" for o in args.outputs)})')
    return 0


def _play(args) -> int:
    import rclpy

    rclpy.init()
    try:
        sent = play_bag(args.in_bag, rate=args.rate, remap=dict(args.remap), topics=args.topics,
                        wait_s=args.wait, progress=not args.quiet,
                        duration_s=args.duration)
    finally:
        rclpy.try_shutdown()
    sys.stderr.write(f'{PROG}: published {sent} messages\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
