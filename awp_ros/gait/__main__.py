"""
``python -m awp_ros.gait``: write a gait bag.

With no arguments it regenerates the committed default bag ``config/hyq_gait.mcap``
byte-for-byte (see :func:`main`).
"""

from __future__ import annotations

import argparse
from pathlib import Path
import sys

from awp_ros.bags.writer import remove_path
from awp_ros.errors import AwpError
from awp_ros.gait.bag import DEFAULT_BAG_NAME, DEFAULT_IMU_RATE_HZ, write_gait_bag
from awp_ros.gait.generator import generate_gait
from awp_ros.gait.params import GaitParams, GAITS
from awp_ros.robot.config import load_config


def main(argv: list[str] | None = None) -> int:
    """
    Write a gait bag; with no arguments, regenerate the committed default bag.

    ``python -m awp_ros.gait`` rewrites ``config/hyq_gait.mcap`` of the source tree
    byte-for-byte (HyQ, :class:`GaitParams` defaults: crawl, lurch, trot; IMU at 500 Hz,
    one per joint state).
    """
    default_out = Path(__file__).resolve().parents[2] / 'config' / DEFAULT_BAG_NAME
    parser = argparse.ArgumentParser(
        prog='python -m awp_ros.gait',
        description='Generate a crawl/lurch/trot bag (joint states, contacts, imu) for a '
        'quadruped.')
    parser.add_argument('-o', '--output', default=str(default_out),
                        help='output bag: a .mcap/.db3 file or a rosbag2 directory '
                             '(default: %(default)s)')
    parser.add_argument('--robot', default='hyq', help='robot config name or YAML path')
    parser.add_argument('--gaits', nargs='+', default=list(GaitParams.sequence),
                        choices=GAITS, help='gaits in order (default: %(default)s)')
    parser.add_argument('--storage', choices=['mcap', 'sqlite3'], default='mcap',
                        help='storage of a rosbag2 directory output')
    parser.add_argument('--imu-rate', type=float, default=DEFAULT_IMU_RATE_HZ,
                        help='IMU rate [Hz], 0 = no imu (default: %(default)s)')
    parser.add_argument('--force', action='store_true', help='overwrite the output')
    args = parser.parse_args(argv)
    out = Path(args.output)
    try:
        samples = generate_gait(load_config(args.robot), GaitParams(sequence=tuple(args.gaits)))
        if args.force:
            remove_path(out)
        write_gait_bag(samples, out, storage=args.storage, imu_rate_hz=args.imu_rate)
    except AwpError as exc:
        sys.stderr.write(f'error: {exc}\n')
        return 2
    sys.stdout.write(f'{out} ({len(samples)} samples, {samples.t[-1]:.2f} s)\n')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
