"""
Count the reports whose ``feasible`` is not the FWS verdict of their own joint state.

The measurement behind the README's "The FWS's verdict every cycle" paragraph.

::

    PYTHONPATH=. .venv/bin/python examples/experiments/fws_verdict_age.py [--max-states N]

Runs the node's pipeline (:class:`awp_ros.ros.pipeline.Pipeline`, no DDS) over the default bag
``config/hyq_gait.mcap`` with the robot's default parameters (the FWS at ``fws_rate_hz``, 10
Hz) and, for every report, computes an FWS of its own joint state
(:meth:`~awp_ros.evaluation.evaluator.FeasibilityEvaluator.add_fws` on a copy of its result).
It prints, by number of stance legs, the reports, those whose ``feasible`` differs from the
FWP's verdict and that FWS's (``differs``), and, among the reports without an FWS of their
own, those whose ``feasible`` would differ with the verdict of the latest FWS instead (the one
computed for an earlier joint state, which two-leg reports carried before session 21: it
matters where the FWP's verdict is true) (``latest differs``).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def count(max_states: int | None = None) -> dict:
    """Return ``legs -> {'reports', 'differs', 'latest differs'}`` over the default bag."""
    from awp_ros.bags.replay import pipeline_cycles
    from awp_ros.robot.config import load_parameters
    from awp_ros.ros.pipeline import Pipeline
    params, base_dir = load_parameters('hyq')
    pipeline = Pipeline.from_parameters(params, base_dir=base_dir)
    out, latest = {}, None
    for seen, cycle in enumerate(pipeline_cycles(pipeline, REPO / 'config' / 'hyq_gait.mcap')):
        if max_states is not None and seen == max_states:
            break
        r = cycle.result
        own = r.fws if cycle.fws_computed else pipeline.evaluator.add_fws(replace(r)).fws
        if cycle.fws_computed:
            latest = own.feasible
        c = out.setdefault(len(r.stance), {'reports': 0, 'differs': 0, 'latest differs': 0})
        c['reports'] += 1
        c['differs'] += cycle.report.feasible != (r.fwp.feasible and own.feasible)
        stale = not cycle.fws_computed and r.fwp.feasible
        c['latest differs'] += stale and latest != own.feasible
    return out


def main(argv: list[str] | None = None) -> int:
    """Print the counts; return 0."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--max-states', type=int, default=None,
                        help='stop after this many joint states (default: the whole bag)')
    args = parser.parse_args(argv)
    for legs, c in sorted(count(args.max_states).items()):
        print(f'{legs} stance legs: {c["reports"]} reports, feasible differs from the own FWS '
              f'verdict on {c["differs"]}, would differ with the latest FWS verdict on '
              f'{c["latest differs"]}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
