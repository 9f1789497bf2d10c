"""
``awp_bench``: time the feasibility pipeline stage by stage over random standing postures.

Each sample perturbs every joint of the config's standing posture by a uniform offset in
``[-spread, spread]`` [rad] (seeded) with every foot in stance (or ``--stance``). Two passes
over the same states, as the node runs them (the per-cycle evaluation at the joint-state
rate, the FWS apart, possibly at a lower rate):

1. the per-cycle evaluation, ``evaluate(state, fws=False)``: its stages (``validate`` ...
   ``margins``, :data:`~awp_ros.evaluation.evaluator.STAGES`) and ``total``;
2. the FWS of each evaluated state (skipped with ``--no-fws``): ``fws_friction``, the
   friction-bounded leg polytopes both FWS methods start from (the per-cycle evaluation
   computes them only on use), then
   :meth:`~awp_ros.evaluation.evaluator.FeasibilityEvaluator.add_fws` (``fws``: the exact H-rep,
   ``fws_directional``: the 12 directional margins on it, ``fws_margin``: the Euclidean
   margin on it), and ``fws_query_lp``: membership and the 12 directional margins by
   :func:`~awp_ros.wrench.fws_queries.lp_directional_margins` (exact LPs, no H-rep).

The table gives the median, 90th percentile and maximum [ms] of each; the last line is one
JSON object with the medians: ``total_ms`` (the per-cycle evaluation without the FWS),
``fws_margin_ms`` (friction polytopes + FWS H-rep + Euclidean margin: the exact FWS margin),
``fws_query_lp_ms`` (friction polytopes + the LP queries),
and ``<stage>_ms`` for every stage, the FWS's margin step alone as ``fws_margin_step_ms``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from awp_ros.errors import AwpError
from awp_ros.evaluation.evaluator import FeasibilityEvaluator, STAGES
from awp_ros.runtime import tune_process
from awp_ros.wrench.fws_queries import lp_directional_margins

__all__ = ['main', 'run_benchmark']

PROG = 'awp_bench'
FWS_STAGES = ('fws_friction', 'fws', 'fws_directional', 'fws_margin', 'fws_query_lp')


def run_benchmark(evaluator: FeasibilityEvaluator, samples: int, *, seed: int = 0,
                  spread: float = 0.1, warmup: int = 5,
                  stance: tuple[str, ...] | None = None,
                  fws: bool = True) -> dict[str, np.ndarray]:
    """
    Return the per-stage timings [ms] of ``samples`` random standing postures.

    :param evaluator: the evaluator (its config needs a standing posture).
    :param samples: number of timed evaluations.
    :param seed: seed of the posture perturbations.
    :param spread: half-width of the uniform joint offsets [rad].
    :param warmup: untimed evaluations first (caches, allocations).
    :param stance: stance feet (default all).
    :param fws: also time the FWS stages and the LP queries, in a second pass.
    :return: stage name -> array (samples,) [ms] (:data:`~awp_ros.evaluation.evaluator.STAGES`,
        ``total`` and, with ``fws``, :data:`FWS_STAGES`), plus ``feasible`` (bool array:
        ``w`` in the FWS when computed, else in the FWP).
    """
    rng = np.random.default_rng(seed)
    base = evaluator.standing_state(stance=stance)
    names = list(base.joint_positions)
    q0 = np.array([base.joint_positions[n] for n in names])
    postures = q0 + rng.uniform(-spread, spread, size=(warmup + samples, q0.size))
    keys = list(STAGES) + ['total'] + (list(FWS_STAGES) if fws else [])
    times = {name: np.zeros(samples) for name in keys}
    feasible = np.zeros(samples, dtype=bool)
    # Pass 1, the per-cycle evaluation. Results are dropped as in the node's loop (keeping
    # them all would grow the heap and put page faults in the timings).
    for i, q in enumerate(postures):
        base.joint_positions = dict(zip(names, q.tolist()))
        result = evaluator.evaluate(base, fws=False)
        if i >= warmup:
            for name in STAGES + ('total',):
                times[name][i - warmup] = result.timings_ms[name]
            feasible[i - warmup] = result.feasible
    # Pass 2, the same states re-evaluated (untimed), then the LP queries (as a per-cycle
    # step would run them) and the FWS.
    for i, q in enumerate(postures if fws else ()):
        base.joint_positions = dict(zip(names, q.tolist()))
        result = evaluator.evaluate(base, fws=False)
        t0 = time.perf_counter()
        for leg in result.legs.values():
            leg.friction_polytope  # noqa: B018 -- computed on first use: time it here
        friction_ms = 1e3 * (time.perf_counter() - t0)
        lp_ms = _lp_query(result)
        evaluator.add_fws(result)
        if i >= warmup:
            for name in FWS_STAGES[1:4]:
                times[name][i - warmup] = result.timings_ms[name]
            times['fws_friction'][i - warmup] = friction_ms
            times['fws_query_lp'][i - warmup] = lp_ms
            feasible[i - warmup] = result.feasible
    times['feasible'] = feasible
    return times


def _lp_query(result) -> float:
    """Return the time [ms] of the LP membership and directional margins of ``result``."""
    p = np.array([leg.position for leg in result.legs.values()]).reshape(-1, 3)
    V = [leg.friction_polytope.vertices for leg in result.legs.values()]
    t0 = time.perf_counter()
    lp_directional_margins(p, V, result.wrench)
    return 1e3 * (time.perf_counter() - t0)


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``awp_bench``."""
    parser = argparse.ArgumentParser(
        prog=PROG,
        description='Time the feasibility pipeline over random postures near the standing '
                    'posture: the per-cycle evaluation (model, leg polytopes, AWP, CWC/FWP, '
                    'margins; "total") and, apart, the FWS (exact H-rep, directional and '
                    'Euclidean margins) and the LP queries of the FWS; print a table and one '
                    'JSON line of medians in ms (total_ms, fws_margin_ms = FWS H-rep + '
                    'margin, fws_query_lp_ms, <stage>_ms).')
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
    parser.add_argument('--no-fws', action='store_true',
                        help='time the per-cycle evaluation only (no FWS, no LP queries)')
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
    median = {s: float(np.median(t)) for s, t in times.items()}
    if not args.json_only:
        out = [f'{PROG}: robot {evaluator.config.robot_name}, {args.samples} postures, '
               f'seed {args.seed}, spread {args.spread} rad, '
               f'{int(feasible.sum())}/{feasible.size} feasible',
               f'{"stage":<20}{"median ms":>12}{"p90 ms":>12}{"max ms":>12}']
        for s, t in times.items():
            out.append(f'{s:<20}{median[s]:>12.4f}{np.percentile(t, 90):>12.4f}'
                       f'{np.max(t):>12.4f}')
        sys.stdout.write('\n'.join(out) + '\n')
    summary = {'robot': evaluator.config.robot_name, 'samples': args.samples,
               'total_ms': round(median['total'], 4)}
    if 'fws' in times:
        friction = times['fws_friction']
        summary['fws_margin_ms'] = round(float(np.median(
            friction + times['fws'] + times['fws_margin'])), 4)
        summary['fws_query_lp_ms'] = round(float(np.median(friction + times['fws_query_lp'])),
                                           4)
    for s in times:
        if s not in ('total', 'fws_query_lp'):
            key = 'fws_margin_step' if s == 'fws_margin' else s
            summary[f'{key}_ms'] = round(median[s], 4)
    sys.stdout.write(json.dumps(summary) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
