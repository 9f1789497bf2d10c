"""
Count the reports whose ``feasible`` (FWS directional margins, margin) are not their own FWS's.

The measurement behind the README's "The FWS's verdict every cycle" paragraphs.

::

    PYTHONPATH=. .venv/bin/python examples/experiments/fws_verdict_age.py [--max-states N]
        [--use-imu]

Runs the node's pipeline (:class:`awp_ros.ros.pipeline.Pipeline`, no DDS) over the default bag
``config/hyq_gait.mcap`` with the robot's default parameters (the FWS at ``fws_rate_hz``, 10
Hz) and, for every report, computes an FWS of its own joint state
(:meth:`~awp_ros.evaluation.evaluator.FeasibilityEvaluator.add_fws` on a copy of its result).
It prints, by number of stance legs, the reports, those whose ``feasible`` differs from the
FWP's verdict and that FWS's (``differs``), and, among the reports without an FWS of their
own, those whose ``feasible`` would differ with the verdict of the latest FWS instead (the one
computed for an earlier joint state, which two-leg reports carried before session 21: it
matters where the FWP's verdict is true) (``latest differs``). With three or more stance legs
it also compares each report's ``fws_directional_plus/minus`` with that FWS's directional
margins (``directional differs``: reports where one differs by more than ``rtol 1e-7, atol
1e-5``, NaN equal to NaN), and gives how far the latest FWS's margins, which those reports
carried before session 22, were from them (``latest directional off``: the largest difference
[N or N.m] over the reports without an FWS of their own, where both are finite). With three or
more legs and the wrench outside the FWS (``outside``: reports without an FWS of their own
whose own FWS excludes the wrench), it compares each report's ``fws_margin`` with that FWS's
(``margin differs``: by more than ``1e-7 (1 + |margin|)``), and gives how far the latest FWS's
margin, which those reports carried before session 24, was from it (``latest margin off``).
``--use-imu``: the measured wrench (the bag's IMU), whose lurch leaves the FWS (the default
parameters' quasi-static wrench never does with three or more legs on this bag).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def count(max_states: int | None = None, use_imu: bool = False) -> dict:
    """
    Return ``legs -> {'reports', 'differs', 'latest differs'}`` over the default bag.

    With three or more legs also ``'directional differs'``, ``'latest directional off'``,
    ``'outside'``, ``'margin differs'`` and ``'latest margin off'``.
    """
    import numpy as np

    from awp_ros.bags.replay import pipeline_cycles
    from awp_ros.evaluation.result import AXES
    from awp_ros.robot.config import load_parameters
    from awp_ros.ros.pipeline import Pipeline
    params, base_dir = load_parameters('hyq', {'use_imu': True} if use_imu else None)
    pipeline = Pipeline.from_parameters(params, base_dir=base_dir)
    out, latest, latest_margins, latest_margin = {}, None, None, None
    for seen, cycle in enumerate(pipeline_cycles(pipeline, REPO / 'config' / 'hyq_gait.mcap')):
        if max_states is not None and seen == max_states:
            break
        r = cycle.result
        own = r.fws if cycle.fws_computed else pipeline.evaluator.add_fws(replace(r)).fws
        margins = np.array([own.directional[a] for a in AXES]).T       # (2, 6): plus, minus
        if cycle.fws_computed:
            latest, latest_margins, latest_margin = own.feasible, margins, own.margin
        c = out.setdefault(len(r.stance), {'reports': 0, 'differs': 0, 'latest differs': 0})
        c['reports'] += 1
        c['differs'] += cycle.report.feasible != (r.fwp.feasible and own.feasible)
        stale = not cycle.fws_computed and r.fwp.feasible
        c['latest differs'] += stale and latest != own.feasible
        if len(r.stance) >= 3:
            rep = np.array([cycle.report.fws_directional_plus, cycle.report.fws_directional_minus])
            close = np.isclose(rep, margins, rtol=1e-7, atol=1e-5, equal_nan=True).all()
            c['directional differs'] = c.get('directional differs', 0) + (not close)
            off = c.get('latest directional off', 0.0)
            if not cycle.fws_computed and latest_margins is not None:
                gap = np.abs(latest_margins - margins)
                off = max(off, float(np.max(gap[np.isfinite(gap)], initial=0.0)))
            c['latest directional off'] = off
            for key in ('outside', 'margin differs', 'latest margin off'):
                c.setdefault(key, 0)
            if not cycle.fws_computed and not own.feasible:
                c['outside'] += 1
                m = cycle.report.fws_margin
                c['margin differs'] += not abs(m - own.margin) <= 1e-7 * (1 + abs(own.margin))
                if latest_margin is not None:
                    c['latest margin off'] = max(c['latest margin off'],
                                                 abs(latest_margin - own.margin))
    return out


def main(argv: list[str] | None = None) -> int:
    """Print the counts; return 0."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--max-states', type=int, default=None,
                        help='stop after this many joint states (default: the whole bag)')
    parser.add_argument('--use-imu', action='store_true',
                        help='the measured wrench (use_imu: true), the lurch leaves the FWS')
    args = parser.parse_args(argv)
    for legs, c in sorted(count(args.max_states, args.use_imu).items()):
        print(f'{legs} stance legs: {c["reports"]} reports, feasible differs from the own FWS '
              f'verdict on {c["differs"]}, would differ with the latest FWS verdict on '
              f'{c["latest differs"]}')
        if 'directional differs' in c:
            off, differs = c['latest directional off'], c['directional differs']
            print(f"  directional margins differ from the own FWS's on {differs}; the latest "
                  f"FWS's were off by up to {off:.1f} [N or N.m]")
            print(f"  outside the FWS: {c['outside']} reports, the margin differs from the own "
                  f"FWS's on {c['margin differs']}; the latest FWS's was off by up to "
                  f"{c['latest margin off']:.2f} [N, N.m]")
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
