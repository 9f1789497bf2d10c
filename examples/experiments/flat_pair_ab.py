"""
Time the FWS of two stance legs: the compiled flat-pair search against the numpy grid search.

::

    PYTHONPATH=. .venv/bin/python examples/experiments/flat_pair_ab.py [--postures N] [--passes N]

The measurement behind the README's two-leg FWS figure (session 20). For each of HyQ's two
trot pairs (``lf_foot`` + ``rh_foot``, ``rf_foot`` + ``lh_foot``) it evaluates ``--postures``
random postures around standing (every joint +-0.05 rad, seeded), then times
:meth:`~awp_ros.evaluation.evaluator.FeasibilityEvaluator.add_fws` (the whole FWS: friction
polytopes, H-rep, directional and Euclidean margins) on each, alternating, pass after pass,
between the numpy grid search (:mod:`awp_ros.geometry.minkowski_facets`, (2)-(3): the code
before session 20) and the compiled search ((6),
:func:`awp_ros.geometry.kernels.flat_pair_facet_normals`), in one process. It prints the
median per pass of each and, last, one JSON object.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from awp_ros.evaluation.evaluator import FeasibilityEvaluator
import awp_ros.geometry.minkowski_facets as mf

PAIRS = (('lf_foot', 'rh_foot'), ('rf_foot', 'lh_foot'))


def postures(evaluator: FeasibilityEvaluator, stance: tuple, count: int, seed: int) -> list:
    """Return ``count`` evaluated states of ``stance`` around the standing posture."""
    rng = np.random.default_rng(seed)
    base = evaluator.standing_state(stance=list(stance))
    names = list(base.joint_positions)
    q0 = np.array([base.joint_positions[n] for n in names])
    out = []
    for _ in range(count):
        base.joint_positions = dict(zip(names, (q0 + rng.uniform(-0.05, 0.05, q0.size)).tolist()))
        out.append(evaluator.evaluate(base, fws=False))
    return out


def run(count: int = 200, passes: int = 3, seed: int = 3) -> dict:
    """Return the median ``add_fws`` time [ms] of each pass, per search and trot pair."""
    evaluator = FeasibilityEvaluator('hyq')
    compiled = mf._flat_pair
    out: dict = {}
    try:
        for pair in PAIRS:
            results = postures(evaluator, pair, count, seed)
            for r in results[:10]:
                evaluator.add_fws(r)                  # warm: kernels loaded, caches filled
            for _ in range(passes):
                for label, search in (('numpy', lambda faces, r: False), ('compiled', compiled)):
                    mf._flat_pair = search
                    times = []
                    for r in results:
                        t0 = time.perf_counter()
                        evaluator.add_fws(r)
                        times.append(time.perf_counter() - t0)
                    out.setdefault(label, []).append(round(1e3 * float(np.median(times)), 4))
    finally:
        mf._flat_pair = compiled
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--postures', type=int, default=200)
    parser.add_argument('--passes', type=int, default=3)
    args = parser.parse_args()
    out = run(args.postures, args.passes)
    for label, medians in out.items():
        print(f'{label:>8}: median add_fws per pass [ms] ' + ' '.join(f'{m:.3f}' for m in medians))
    print(json.dumps(out))


if __name__ == '__main__':
    main()
