"""``awp_bench``: time the feasibility pipeline stage by stage over random standing postures.

Each sample perturbs every joint of the config's standing posture by a uniform offset in
``[-spread, spread]`` [rad] (seeded), evaluates it with every foot in stance (or
``--stance``), and records :attr:`~awp_ros.evaluator.FeasibilityResult.timings_ms`. The
table gives the median, 90th percentile and maximum of each stage; the last line is one JSON
object with the medians: ``total_ms`` (per-cycle evaluation: every stage but the exact FWS
margin), ``fws_margin_ms`` (the exact FWS Euclidean margin on its H-rep), ``no_fws_ms``
(``total`` without the FWS H-rep and directional stages, i.e. ``evaluate(fws=False)``) and
``<stage>_ms`` for every stage.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from awp_ros.errors import AwpError
from awp_ros.evaluator import FeasibilityEvaluator
from awp_ros.runtime import tune_process

__all__ = ['main', 'run_benchmark']

PROG = 'awp_bench'


def run_benchmark(evaluator: FeasibilityEvaluator, samples: int, *, seed: int = 0,
                  spread: float = 0.1, warmup: int = 5,
                  stance: tuple[str, ...] | None = None,
                  fws: bool = True) -> dict[str, np.ndarray]:
    """Return the per-stage timings [ms] of ``samples`` random standing postures.

    :param evaluator: the evaluator (its config needs a standing posture).
    :param samples: number of timed evaluations.
    :param seed: seed of the posture perturbations.
    :param spread: half-width of the uniform joint offsets [rad].
    :param warmup: untimed evaluations first (caches, allocations).
    :param stance: stance feet (default all).
    :param fws: include the FWS stages.
    :return: stage name -> array (samples,) [ms], plus ``feasible`` (bool array).
    """
    rng = np.random.default_rng(seed)
    base = evaluator.standing_state(stance=stance)
    names = list(base.joint_positions)
    q0 = np.array([base.joint_positions[n] for n in names])
    rows, feasible = [], []
    for i in range(warmup + samples):
        q = q0 + rng.uniform(-spread, spread, size=q0.size)
        base.joint_positions = dict(zip(names, q.tolist()))
        result = evaluator.evaluate(base, fws=fws)
        if i >= warmup:
            rows.append(result.timings_ms)
            feasible.append(result.feasible)
    out = {name: np.array([r[name] for r in rows]) for name in rows[0]} if rows else {}
    out['feasible'] = np.array(feasible, dtype=bool)
    return out


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``awp_bench``."""
    parser = argparse.ArgumentParser(
        prog=PROG,
        description='Time the feasibility pipeline (model, leg polytopes, AWP, CWC/FWP, '
                    'margins, FWS) over random postures near the standing posture; print a '
                    'table and one JSON line with the median of each stage in ms.')
    parser.add_argument('--robot', default='hyq',
                        help='robot config name or YAML path (default: hyq)')
    parser.add_argument('-n', '--samples', type=int, default=200,
                        help='number of timed postures (default: 200)')
    parser.add_argument('--seed', type=int, default=0, help='random seed (default: 0)')
    parser.add_argument('--spread', type=float, default=0.1,
                        help='uniform joint offset half-width [rad] (default: 0.1)')
    parser.add_argument('--warmup', type=int, default=5,
                        help='untimed evaluations first (default: 5)')
    parser.add_argument('--stance', nargs='*', default=None, metavar='FOOT',
                        help='stance feet (default: all)')
    parser.add_argument('--no-fws', action='store_true', help='skip the FWS stages')
    parser.add_argument('--json-only', action='store_true',
                        help='print only the JSON line')
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``awp_bench``; return the exit status."""
    tune_process()
    args = build_parser().parse_args(argv)
    if args.samples < 1:
        sys.stderr.write(f'{PROG}: error: --samples must be >= 1, got {args.samples}\n')
        return 2
    try:
        evaluator = FeasibilityEvaluator(args.robot)
        stance = None if args.stance is None else tuple(args.stance)
        times = run_benchmark(evaluator, args.samples, seed=args.seed, spread=args.spread,
                              warmup=args.warmup, stance=stance, fws=not args.no_fws)
    except (ValueError, AwpError) as exc:
        sys.stderr.write(f'{PROG}: error: {" ".join(str(exc).split())}\n')
        return 2
    feasible = times.pop('feasible')
    stages = [s for s in times if s != 'total'] + ['total']
    if not args.json_only:
        out = [f'{PROG}: robot {evaluator.config.robot_name}, {args.samples} postures, '
               f'seed {args.seed}, spread {args.spread} rad, '
               f'{int(feasible.sum())}/{feasible.size} feasible',
               f'{"stage":<20}{"median ms":>12}{"p90 ms":>12}{"max ms":>12}']
        for s in stages:
            t = times[s]
            out.append(f'{s:<20}{np.median(t):>12.4f}{np.percentile(t, 90):>12.4f}'
                       f'{np.max(t):>12.4f}')
        sys.stdout.write('\n'.join(out) + '\n')
    summary = {'robot': evaluator.config.robot_name, 'samples': args.samples,
               'total_ms': round(float(np.median(times['total'])), 4)}
    if 'fws_margin' in times:
        summary['fws_margin_ms'] = round(float(np.median(times['fws_margin'])), 4)
        without = times['total'] - times['fws'] - times['fws_directional']
        summary['no_fws_ms'] = round(float(np.median(without)), 4)
    for s in stages:
        summary[f'{s}_ms'] = round(float(np.median(times[s])), 4)
    sys.stdout.write(json.dumps(summary) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
