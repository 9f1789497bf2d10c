"""
Time the node's pipeline, message by message, over a bag (no DDS): where a joint state goes.

::

    python -m awp_ros.cli.pipeline_bench [BAG] [--robot hyq] [--repeat 2] [-p KEY=VALUE ...]

Reads the joint states and contacts (with ``-p use_imu=true`` the IMU too) of ``BAG`` (default:
the default bag, ``config/hyq_gait.mcap``), feeds them to :class:`awp_ros.ros.pipeline.Pipeline`
in recorded order as ``awp_node`` does, with the robot's parameters and the ``-p`` overrides (as
``awp_replay``; ``-p fws_rate_hz=0``: the FWS every cycle, its cost amortised over the bag in
``fws_amortised_ms``) (the first pass warms up, the last is timed) and prints, per joint state,
the mean and median wall time of :meth:`~awp_ros.ros.pipeline.Pipeline.on_joint_state` [ms], how
often the contact wrench cone reused its last facets (``cwc_reused``, ``cwc_searched``), the
mean of each evaluation stage (:data:`awp_ros.evaluation.evaluator.STAGES`), of the FWS's
per-cycle directional margins (``fws_directional_lp``, three or more stance legs), of its
per-cycle distance when the wrench is outside it (``fws_distance``, three or more legs; the
count of those joint states and its median over them, ``fws_distance_outside`` and
``fws_distance_outside_p50_ms``), and of the FWS amortised over all joint states, the rest
(report and input conversion), and the means by number of stance legs, with the median time of
the FWS computed for a joint state of that many stance legs (``fws_ms_by_stance_legs``), and
how the FWS's (2, 1, 1, 1) facet searches went (:mod:`awp_ros.geometry.certified_search`:
``fws_search_certified``, ``fws_search_kernel``, ``fws_search_references``,
``fws_search_tested_share``). Its last line is one JSON object. Output messages other than
the report are not built (as in a node without subscribers to them).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from awp_ros.cli.replay import parse_override
from awp_ros.errors import AwpError
from awp_ros.runtime import tune_process

__all__ = ['main', 'time_pipeline']


def time_pipeline(bag: str, robot: str = 'hyq', repeat: int = 2,
                  overrides: dict | None = None) -> dict:
    """
    Return the timings [ms] of the pipeline over ``bag`` (see the module docstring).

    :param overrides: node parameters replacing the robot file's (``-p``).
    """
    from awp_ros_msgs.msg import ContactState
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import Imu, JointState

    from awp_ros.bags.reader import read_bag
    from awp_ros.evaluation.evaluator import STAGES
    from awp_ros.geometry import certified_search
    from awp_ros.robot.config import load_parameters
    from awp_ros.ros.pipeline import Pipeline
    from awp_ros.wrench.contact_wrench_cone import reuse_counts

    params, base_dir = load_parameters(robot, overrides)
    pipeline = Pipeline.from_parameters(params, base_dir=base_dir)
    types = {'/joint_states': JointState, '/contacts': ContactState}
    if pipeline.params.use_imu:
        types['/imu'] = Imu
    msgs = [(m.topic, deserialize_message(m.data, types[m.topic]))
            for m in read_bag(bag, topics=list(types))]
    for _ in range(max(1, repeat)):
        wall, legs, fws = [], [], []
        stages = {s: [] for s in STAGES + ('fws_directional_lp', 'fws_distance')}
        reuse0, certified0 = reuse_counts(), certified_search.statistics()
        for topic, msg in msgs:
            if topic == '/contacts':
                pipeline.on_contacts(msg)
                continue
            if topic == '/imu':
                pipeline.on_imu(msg)
                continue
            t0 = time.perf_counter()
            cycle = pipeline.on_joint_state(msg)
            wall.append(1e3 * (time.perf_counter() - t0))
            r = cycle.result
            legs.append(-1 if r is None else len(r.stance))
            for s in stages:
                stages[s].append(0.0 if r is None else r.timings_ms.get(s, 0.0))
            fws.append(sum(r.timings_ms.get(k, 0.0) for k in ('fws', 'fws_directional',
                                                              'fws_margin'))
                       if r is not None and cycle.fws_computed else 0.0)
    wall_a, legs_a = np.array(wall), np.array(legs)
    reused, searched = (a - b for a, b in zip(reuse_counts(), reuse0))
    certified = {k: v - certified0[k] for k, v in certified_search.statistics().items()}
    out = {'joint_states': len(wall), 'mean_ms': float(wall_a.mean()),
           'cwc_reused': reused, 'cwc_searched': searched,
           'p50_ms': float(np.median(wall_a)),
           'fws_computed': int(np.count_nonzero(fws)),
           'fws_amortised_ms': float(np.mean(fws)),
           'fws_search_certified': certified['certified'],
           'fws_search_kernel': certified['kernel'],
           'fws_search_references': certified['references'],
           'fws_search_tested_share': certified['tested'] / max(certified['choices'], 1)}
    for s, v in stages.items():
        out[f'{s}_ms'] = float(np.mean(v))
    out['rest_ms'] = out['mean_ms'] - out['fws_amortised_ms'] - sum(
        out[f'{s}_ms'] for s in stages)
    out['mean_ms_by_stance_legs'] = {int(k): float(wall_a[legs_a == k].mean())
                                     for k in np.unique(legs_a)}
    fws_a, distance = np.array(fws), np.array(stages['fws_distance'])
    out['fws_distance_outside'] = int(np.count_nonzero(distance))
    out['fws_distance_outside_p50_ms'] = float(np.median(distance[distance > 0])) \
        if distance.any() else float('nan')
    out['fws_ms_by_stance_legs'] = {int(k): float(np.median(fws_a[(legs_a == k) & (fws_a > 0)]))
                                    for k in np.unique(legs_a[fws_a > 0])}
    return out


def main(argv: list[str] | None = None) -> int:
    """Run the timing and print it; return the exit status."""
    from awp_ros.gait.bag import default_bag_path
    parser = argparse.ArgumentParser(prog='python -m awp_ros.cli.pipeline_bench',
                                     description=__doc__.split('\n\n')[0])
    parser.add_argument('bag', nargs='?', default=None,
                        help='input bag (default: the packaged config/hyq_gait.mcap)')
    parser.add_argument('--robot', default='hyq', help='robot config (default: hyq)')
    parser.add_argument('--repeat', type=int, default=2,
                        help='passes over the bag; the last is timed (default: 2)')
    parser.add_argument('-p', '--param', action='append', type=parse_override, default=[],
                        metavar='KEY=VALUE', help='parameter override, e.g. -p fws_rate_hz=0 '
                        '(the FWS every cycle); repeatable')
    args = parser.parse_args(argv)
    tune_process()
    try:
        out = time_pipeline(args.bag or str(default_bag_path()), args.robot, args.repeat,
                            dict(args.param))
    except AwpError as exc:
        parser.exit(2, f'{parser.prog}: error: {exc}\n')
    lines = [f'{out["joint_states"]} joint states: {out["mean_ms"]:.3f} ms mean, '
             f'{out["p50_ms"]:.3f} ms median per joint state; FWS computed '
             f'{out["fws_computed"]} times; contact wrench cone: facets reused '
             f'{out["cwc_reused"]} times, searched {out["cwc_searched"]}; FWS (2, 1, 1, 1) '
             f'searches: {out["fws_search_certified"]} certified ('
             f'{out["fws_search_tested_share"]:.3f} of their choices tested), '
             f'{out["fws_search_kernel"]} by the kernel, {out["fws_search_references"]} '
             f'references built']
    lines += [f'  {k[:-3]:<20} {v:.4f} ms (mean per joint state)' for k, v in out.items()
              if k.endswith('_ms')
              and k not in ('mean_ms', 'p50_ms', 'fws_distance_outside_p50_ms')]
    if out['fws_distance_outside']:
        lines.append(f'  fws_distance         {out["fws_distance_outside_p50_ms"]:.4f} ms (median '
                     f'over the {out["fws_distance_outside"]} joint states outside the FWS)')
    lines += [f'  {k} stance legs: {v:.3f} ms mean per joint state'
              + (f', its FWS {out["fws_ms_by_stance_legs"][k]:.3f} ms (median)'
                 if k in out['fws_ms_by_stance_legs'] else '')
              for k, v in out['mean_ms_by_stance_legs'].items()]
    sys.stdout.write('\n'.join(lines) + '\n' + json.dumps(out) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
